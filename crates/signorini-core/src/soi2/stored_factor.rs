//! Newton factorisations read back from a checkpoint ([`super::method::NewtonCache`]), checked
//! before a step uses them. A factorisation is the simplified Newton iteration's memory (the
//! next step solves with it, so that a resumed run continues bit for bit), but its serialized
//! form carries indices — the row interchanges of an LU, the band order and pivots of a band
//! LU — that a solve follows without bounds checks of its own: a damaged or hostile checkpoint
//! that passes the envelope's checksum must be refused as a checkpoint error, not panic in the
//! solve (the checkpoint fuzz target found such a payload: a row interchange out of range).

use super::banded::BandLu;
use nalgebra::{DMatrix, DVector, Dyn, LU};
use serde::de::Error as _;
use serde::{Deserialize, Deserializer, Serialize};

/// The serialized layout of nalgebra's `LU` (its matrix of factors and its permutation
/// sequence), read field by field so that the interchanges can be checked.
#[derive(Serialize, Deserialize)]
struct LuParts {
    lu: DMatrix<f64>,
    p: PermutationParts,
}

/// The serialized layout of nalgebra's `PermutationSequence`: `len` interchanges used of
/// `ipiv`'s capacity.
#[derive(Serialize, Deserialize)]
struct PermutationParts {
    len: usize,
    ipiv: DVector<(usize, usize)>,
}

/// The cache's LU factorisations: (factorisation, step size, system size).
type LuList = Vec<(LU<f64, Dyn, Dyn>, f64, usize)>;

/// Why a stored LU of a system of `n` unknowns is unusable, or `None`.
fn lu_fault(parts: &LuParts, n: usize) -> Option<String> {
    let (rows, columns) = parts.lu.shape();
    if rows != n || columns != n {
        return Some(format!("an LU of {rows}×{columns} kept for {n} unknowns"));
    }
    if parts.p.ipiv.len() != n || parts.p.len > n {
        return Some(format!(
            "an LU of {n} unknowns with {} of {} row interchanges",
            parts.p.len,
            parts.p.ipiv.len()
        ));
    }
    parts
        .p
        .ipiv
        .iter()
        .take(parts.p.len)
        .find(|&&(i, j)| i >= n || j >= n)
        .map(|&(i, j)| format!("an LU of {n} unknowns interchanging rows {i} and {j}"))
}

/// Deserializes the cache's LU factorisations `(LU, h, n)`, refusing one whose size is not
/// its `n` or whose row interchanges leave its rows.
pub(super) fn lu_list<'de, D: Deserializer<'de>>(d: D) -> Result<LuList, D::Error> {
    let stored = Vec::<(LuParts, f64, usize)>::deserialize(d)?;
    stored
        .into_iter()
        .map(|(parts, h, n)| {
            if let Some(fault) = lu_fault(&parts, n) {
                return Err(D::Error::custom(fault));
            }
            // nalgebra builds an LU only by factorising: the checked parts are read back as one.
            let bytes = rmp_serde::to_vec_named(&parts).map_err(D::Error::custom)?;
            let lu = rmp_serde::from_slice(&bytes).map_err(D::Error::custom)?;
            Ok((lu, h, n))
        })
        .collect()
}

/// Deserializes the cache's band LU factorisations `(BandLu, h, n)`, refusing one that is not
/// a consistent factorisation of `n` unknowns ([`BandLu::fault`]).
pub(super) fn band_lu_list<'de, D: Deserializer<'de>>(
    d: D,
) -> Result<Vec<(BandLu, f64, usize)>, D::Error> {
    let stored = Vec::<(BandLu, f64, usize)>::deserialize(d)?;
    for (lu, _, n) in &stored {
        if let Some(fault) = lu.fault(*n) {
            return Err(D::Error::custom(fault));
        }
    }
    Ok(stored)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize, Deserialize)]
    struct Cache {
        #[serde(deserialize_with = "lu_list")]
        lu: Vec<(LU<f64, Dyn, Dyn>, f64, usize)>,
    }

    fn a() -> DMatrix<f64> {
        DMatrix::from_row_slice(3, 3, &[0.0, 2.0, 1.0, 4.0, 1.0, 0.0, 1.0, 0.0, 3.0])
    }

    /// A stored LU reads back to the same solve, bit for bit.
    #[test]
    fn a_stored_lu_reads_back_to_the_same_solve() {
        let cache = Cache {
            lu: vec![(a().lu(), 0.1, 3)],
        };
        let bytes = rmp_serde::to_vec_named(&cache).expect("encode");
        let back: Cache = rmp_serde::from_slice(&bytes).expect("decode");
        let b = DVector::from_vec(vec![1.0, 2.0, 3.0]);
        let x0 = cache.lu[0].0.solve(&b).expect("regular");
        let x1 = back.lu[0].0.solve(&b).expect("regular");
        assert_eq!(x0, x1);
        assert!((a() * x1 - b).amax() < 1e-15);
    }

    /// A row interchange out of range, or an LU kept under another size, is refused.
    #[test]
    fn a_damaged_lu_is_refused() {
        let good = LuParts {
            lu: a(),
            p: PermutationParts {
                len: 1,
                ipiv: DVector::from_vec(vec![(0, 1), (0, 0), (0, 0)]),
            },
        };
        assert_eq!(lu_fault(&good, 3), None);
        assert!(lu_fault(&good, 4).is_some_and(|f| f.contains("3×3 kept for 4")));
        let far = LuParts {
            p: PermutationParts {
                len: 1,
                ipiv: DVector::from_vec(vec![(0, 7), (0, 0), (0, 0)]),
            },
            ..good
        };
        assert!(lu_fault(&far, 3).is_some_and(|f| f.contains("rows 0 and 7")));
        #[derive(Serialize)]
        struct Raw {
            lu: Vec<(LuParts, f64, usize)>,
        }
        let bytes = rmp_serde::to_vec_named(&Raw {
            lu: vec![(far, 0.1, 3)],
        })
        .expect("encode");
        let read: Result<Cache, _> = rmp_serde::from_slice(&bytes);
        assert!(read.is_err());
    }
}
