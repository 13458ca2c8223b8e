//! FCLib's layout as the arrays it stores (V. Acary, M. Brémond, T. Koziara, F. Pérignon,
//! *FCLIB: a collection of discrete 3D frictional contact problems*, INRIA technical report
//! RT-444, 2014; the reader and writer of `fclib.c`, github.com/FrictionalContactLibrary/fclib):
//!
//! ```text
//! /fclib_local/spacedim            2 or 3
//! /fclib_local/W/{m,n,nz,nzmax,p,i,x}   a sparse matrix: nz ≥ 0 triplet (p: columns, i: rows),
//!                                  nz = −1 CSC (p: n+1 column starts), nz = −2 CSR (p: m+1 row starts)
//! /fclib_local/vectors/{q,mu}
//! /fclib_global/{M,H}/…            the same sparse layout; /fclib_global/vectors/{f,w,mu}
//! /solution/{r,u}                  (and v for global problems)
//! ```
//!
//! [`Datasets`] holds those arrays as read, whatever they say; [`Datasets::assemble`] checks
//! them and makes the problem. The HDF5 file itself is read and written by [`super::fclib`]
//! (the cargo feature `hdf5`); this half needs no library, so the fuzz target `fclib` drives it
//! directly (docs/fuzzing.md).
//!
//! A global problem `M v = H r + f`, `u = Hᵀ v + w` is read through its local reduction
//! `W = Hᵀ M⁻¹ H`, `q = Hᵀ M⁻¹ f + w` (Siconos' `globalFrictionContact_reformulation_FrictionContact`),
//! done here when M is diagonal (every global problem of Siconos' test set is): a non-diagonal
//! M is refused, naming it.

use super::{RawProblem, ReadError};
use signorini_core::friction::BlockCsr;
use std::collections::BTreeMap;

/// Most entries the local reduction `Hᵀ M⁻¹ H` of a global problem may have (2²⁵, about
/// 0.8 GB as triplets). A dof touched by k columns of H adds k² entries, so a file of a few
/// kilobytes could otherwise ask for terabytes; a larger reduction is refused, naming the count.
pub const MAX_REDUCED_ENTRIES: usize = 1 << 25;

/// A sparse matrix as FCLib stores it (`fclib.c`'s `fclib_matrix`): its shape `m × n`, the
/// storage code `nz` (≥ 0: that many triplets; −1 CSC; −2 CSR), and the arrays `p`, `i`, `x`.
#[derive(Debug, Clone, PartialEq)]
pub struct SparseDatasets {
    /// Rows.
    pub m: i64,
    /// Columns.
    pub n: i64,
    /// The storage: triplet count, −1 (CSC) or −2 (CSR).
    pub nz: i64,
    /// Triplets: the columns; CSC: the column starts; CSR: the row starts.
    pub p: Vec<i64>,
    /// Triplets and CSC: the rows; CSR: the columns.
    pub i: Vec<i64>,
    /// The values.
    pub x: Vec<f64>,
}

/// The datasets of an FCLib file: a local problem (`/fclib_local`) or a global one
/// (`/fclib_global`), as stored.
#[derive(Debug, Clone, PartialEq)]
pub enum Datasets {
    /// `/fclib_local`: W, q, μ.
    Local {
        /// `spacedim`.
        spacedim: i64,
        /// The Delassus operator W.
        w: SparseDatasets,
        /// The free local velocity q.
        q: Vec<f64>,
        /// Friction coefficient per contact.
        mu: Vec<f64>,
    },
    /// `/fclib_global`: M, H, f, w, μ.
    Global {
        /// `spacedim`.
        spacedim: i64,
        /// The mass matrix M.
        m: SparseDatasets,
        /// H, dofs × (spacedim · contacts).
        h: SparseDatasets,
        /// The forces f.
        f: Vec<f64>,
        /// The constant local velocity w.
        w: Vec<f64>,
        /// Friction coefficient per contact.
        mu: Vec<f64>,
    },
}

fn fclib_error(reason: impl Into<String>) -> ReadError {
    ReadError::Fclib {
        reason: reason.into(),
    }
}

/// A sparse matrix as entries `(row, column, value)` with its shape.
struct Sparse {
    rows: usize,
    columns: usize,
    entries: Vec<(usize, usize, f64)>,
}

impl SparseDatasets {
    /// FCLib's name of the storage.
    fn storage_name(&self) -> &'static str {
        match self.nz {
            -1 => "csc",
            -2 => "csr",
            _ => "triplet",
        }
    }

    /// The entries, every index checked against the shape (`group` names the matrix).
    fn entries(&self, group: &str) -> Result<Sparse, ReadError> {
        let count = |name: &str, v: i64| {
            usize::try_from(v).map_err(|_| fclib_error(format!("{group}/{name} is {v}")))
        };
        let (rows, columns) = (count("m", self.m)?, count("n", self.n)?);
        let (p, i, x) = (&self.p, &self.i, &self.x);
        let index = |v: i64, bound: usize, what: &str| {
            usize::try_from(v)
                .ok()
                .filter(|&k| k < bound)
                .ok_or_else(|| fclib_error(format!("{group}: {what} index {v} out of 0..{bound}")))
        };
        let mut entries = Vec::new();
        match self.nz {
            nz if nz >= 0 => {
                let nz = nz as usize;
                if p.len() < nz || i.len() < nz || x.len() < nz {
                    return Err(fclib_error(format!(
                        "{group}: fewer than nz = {nz} triplets"
                    )));
                }
                for k in 0..nz {
                    entries.push((
                        index(i[k], rows, "row")?,
                        index(p[k], columns, "column")?,
                        x[k],
                    ));
                }
            }
            -1 | -2 => {
                let (outer, inner) = if self.nz == -1 {
                    (columns, rows)
                } else {
                    (rows, columns)
                };
                if p.len().checked_sub(1) != Some(outer) {
                    return Err(fclib_error(format!(
                        "{group}/p has {} entries, expected {outer} + 1",
                        p.len()
                    )));
                }
                for o in 0..outer {
                    let (a, b) = (p[o], p[o + 1]);
                    if a < 0 || b < a || b as usize > i.len() || b as usize > x.len() {
                        return Err(fclib_error(format!("{group}/p is not increasing in range")));
                    }
                    for k in a as usize..b as usize {
                        let inner_index = index(i[k], inner, "inner")?;
                        entries.push(if self.nz == -1 {
                            (inner_index, o, x[k])
                        } else {
                            (o, inner_index, x[k])
                        });
                    }
                }
            }
            other => return Err(fclib_error(format!("{group}/nz is {other}"))),
        }
        Ok(Sparse {
            rows,
            columns,
            entries,
        })
    }

    /// Triplets (`nz` = their count; `p` the columns, `i` the rows).
    fn triplets(rows: usize, columns: usize, entries: &[(usize, usize, f64)]) -> Self {
        Self {
            m: rows as i64,
            n: columns as i64,
            nz: entries.len() as i64,
            p: entries.iter().map(|t| t.1 as i64).collect(),
            i: entries.iter().map(|t| t.0 as i64).collect(),
            x: entries.iter().map(|t| t.2).collect(),
        }
    }
}

/// `spacedim`, 2 or 3.
fn dimension(spacedim: i64) -> Result<usize, ReadError> {
    match spacedim {
        2 | 3 => Ok(spacedim as usize),
        _ => usize::try_from(spacedim)
            .map_err(|_| fclib_error(format!("spacedim is {spacedim}")))
            .and_then(|dimension| Err(ReadError::Dimension { dimension })),
    }
}

fn check_sizes(
    dimension: usize,
    rows: usize,
    columns: usize,
    q: usize,
    mu: usize,
) -> Result<(), ReadError> {
    let size = dimension * mu;
    if rows != size || columns != size || q != size {
        return Err(fclib_error(format!(
            "W is {rows}×{columns} and q has {q} entries, where {mu} contacts in dimension {dimension} need {size}"
        )));
    }
    Ok(())
}

impl Datasets {
    /// A local problem stored as FCLib's writer stores it: W as CSR.
    pub fn local(problem: &RawProblem) -> Self {
        let size = problem.w.size();
        let mut entries: Vec<(usize, usize, f64)> = problem.w.entries().collect();
        // CSR: row by row (the block rows interleave the rows of their blocks).
        entries.sort_by_key(|&(i, j, _)| (i, j));
        let mut starts = vec![0];
        let mut columns = Vec::with_capacity(entries.len());
        let mut values = Vec::with_capacity(entries.len());
        let mut row = 0;
        for &(i, j, x) in &entries {
            while row < i {
                starts.push(columns.len() as i64);
                row += 1;
            }
            columns.push(j as i64);
            values.push(x);
        }
        while starts.len() < size + 1 {
            starts.push(columns.len() as i64);
        }
        Self::Local {
            spacedim: problem.dimension as i64,
            w: SparseDatasets {
                m: size as i64,
                n: size as i64,
                nz: -2,
                p: starts,
                i: columns,
                x: values,
            },
            q: problem.q.clone(),
            mu: problem.mu.clone(),
        }
    }

    /// A global problem with a diagonal M (its diagonal given) and H (dofs × dimension·contacts
    /// entries), both as triplets.
    pub fn global(
        dimension: usize,
        mass: &[f64],
        h: &[(usize, usize, f64)],
        f: &[f64],
        w: &[f64],
        mu: &[f64],
    ) -> Self {
        let diagonal: Vec<(usize, usize, f64)> =
            mass.iter().enumerate().map(|(k, &m)| (k, k, m)).collect();
        Self::Global {
            spacedim: dimension as i64,
            m: SparseDatasets::triplets(mass.len(), mass.len(), &diagonal),
            h: SparseDatasets::triplets(mass.len(), w.len(), h),
            f: f.to_vec(),
            w: w.to_vec(),
            mu: mu.to_vec(),
        }
    }

    /// The problem the datasets hold, a global one through its local reduction (module
    /// documentation); whatever is inconsistent is refused, naming the dataset.
    pub fn assemble(&self) -> Result<RawProblem, ReadError> {
        match self {
            Self::Local { spacedim, w, q, mu } => {
                let dimension = dimension(*spacedim)?;
                let storage = w.storage_name();
                let w = w.entries("fclib_local/W")?;
                check_sizes(dimension, w.rows, w.columns, q.len(), mu.len())?;
                Ok(RawProblem {
                    dimension,
                    w: BlockCsr::from_triplets(dimension, w.rows, w.entries)?,
                    q: q.clone(),
                    mu: mu.clone(),
                    storage,
                })
            }
            Self::Global {
                spacedim,
                m,
                h,
                f,
                w,
                mu,
            } => {
                let dimension = dimension(*spacedim)?;
                let m = m.entries("fclib_global/M")?;
                let h = h.entries("fclib_global/H")?;
                reduce(dimension, &m, &h, f, w, mu)
            }
        }
    }
}

/// The local reduction `W = Hᵀ M⁻¹ H`, `q = Hᵀ M⁻¹ f + w` of a global problem with a diagonal M.
fn reduce(
    dimension: usize,
    m: &Sparse,
    h: &Sparse,
    f: &[f64],
    w: &[f64],
    mu: &[f64],
) -> Result<RawProblem, ReadError> {
    let dofs = m.rows;
    if m.columns != dofs || h.rows != dofs || f.len() != dofs {
        return Err(fclib_error(format!(
            "M is {}×{}, H is {}×{} and f has {} entries: they do not make one global problem",
            m.rows,
            m.columns,
            h.rows,
            h.columns,
            f.len()
        )));
    }
    check_sizes(dimension, h.columns, h.columns, w.len(), mu.len())?;
    let mut diagonal = vec![0.0; dofs];
    for &(i, j, x) in &m.entries {
        if i != j && x != 0.0 {
            return Err(fclib_error(format!(
                "M has the off-diagonal entry ({i}, {j}): the local reduction H^T M^-1 H is done for a diagonal M only"
            )));
        }
        diagonal[i] += x;
    }
    if let Some(k) = diagonal.iter().position(|&d| d.is_nan() || d <= 0.0) {
        return Err(fclib_error(format!(
            "M[{k}][{k}] = {} is not positive",
            diagonal[k]
        )));
    }
    // Rows of H: per dof the columns touching it (entries given twice summed, as triplets are).
    let mut by_dof: Vec<BTreeMap<usize, f64>> = vec![BTreeMap::new(); dofs];
    for &(i, j, x) in &h.entries {
        *by_dof[i].entry(j).or_default() += x;
    }
    let reduced = by_dof
        .iter()
        .map(|row| row.len().saturating_mul(row.len()))
        .fold(0usize, usize::saturating_add);
    if reduced > MAX_REDUCED_ENTRIES {
        return Err(fclib_error(format!(
            "the local reduction H^T M^-1 H would have {reduced} entries, more than the {MAX_REDUCED_ENTRIES} read"
        )));
    }
    let mut entries = Vec::with_capacity(reduced);
    let mut q = w.to_vec();
    for (k, row) in by_dof.iter().enumerate() {
        for (&a, &xa) in row {
            q[a] += xa * f[k] / diagonal[k];
            for (&b, &xb) in row {
                entries.push((a, b, xa * xb / diagonal[k]));
            }
        }
    }
    Ok(RawProblem {
        dimension,
        w: BlockCsr::from_triplets(dimension, h.columns, entries)?,
        q,
        mu: mu.to_vec(),
        storage: "global",
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One dof touched by every column of H: a file of a few kilobytes whose reduction would
    /// have (6 000)² = 3.6·10⁷ entries is refused, naming the count, before anything is
    /// allocated; the same problem with each column on its own dof is read.
    #[test]
    fn a_reduction_beyond_its_bound_is_refused_naming_its_size() {
        let contacts = 2_000;
        let columns = 3 * contacts;
        let (w, mu) = (vec![0.0; columns], vec![0.5; contacts]);
        let one_dof: Vec<_> = (0..columns).map(|j| (0, j, 1.0)).collect();
        let refused = Datasets::global(3, &[1.0], &one_dof, &[0.0], &w, &mu).assemble();
        let message = refused
            .expect_err("a reduction of 3.6e7 entries")
            .to_string();
        assert!(
            message.contains("36000000 entries") && message.contains("H^T M^-1 H"),
            "{message}"
        );
        let own_dof: Vec<_> = (0..columns).map(|j| (j, j, 1.0)).collect();
        let mass = vec![2.0; columns];
        let read = Datasets::global(3, &mass, &own_dof, &vec![0.0; columns], &w, &mu)
            .assemble()
            .expect("a diagonal reduction");
        assert_eq!(read.w.entries().filter(|e| e.2 != 0.0).count(), columns);
        assert!(
            read.w
                .entries()
                .all(|(i, j, x)| x == if i == j { 0.5 } else { 0.0 })
        );
    }

    /// A negative `spacedim` is named as stored, not wrapped into a huge dimension.
    #[test]
    fn a_negative_spacedim_is_named() {
        let negative = Datasets::Local {
            spacedim: -3,
            w: SparseDatasets::triplets(3, 3, &[]),
            q: vec![0.0; 3],
            mu: vec![0.5],
        };
        let message = negative.assemble().expect_err("spacedim −3").to_string();
        assert_eq!(message, "FCLib layout: spacedim is -3");
    }
}
