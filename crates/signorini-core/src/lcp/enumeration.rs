//! Enumeration of index sets: for each set S, solve `M_SS z_S = −q_S` and keep the first
//! z ≥ 0 with `M z + q ≥ 0`. Exact, exponential: for tiny problems and as a reference.

use super::{Lcp, LcpError, LcpOptions, LcpSolution};
use nalgebra::{DMatrix, DVector};

/// Largest problem enumeration accepts (2¹² index sets).
pub const ENUMERATION_MAX: usize = 12;

/// Solves the LCP by trying every index set, smallest first.
pub fn solve_enumeration(lcp: Lcp<'_>, options: &LcpOptions) -> Result<LcpSolution, LcpError> {
    let n = lcp.size();
    if n > ENUMERATION_MAX {
        return Err(LcpError::TooLarge {
            size: n,
            max: ENUMERATION_MAX,
        });
    }
    let mut sets: Vec<u32> = (0..1u32 << n).collect();
    sets.sort_by_key(|s| s.count_ones());
    let mut best: Option<(f64, Vec<f64>)> = None;
    for (tried, &s) in sets.iter().enumerate() {
        let idx: Vec<usize> = (0..n).filter(|i| s & (1 << i) != 0).collect();
        let k = idx.len();
        let mut z = vec![0.0; n];
        if k > 0 {
            let a = DMatrix::from_fn(k, k, |r, c| lcp.m[idx[r] * n + idx[c]]);
            let b = DVector::from_fn(k, |r, _| -lcp.q[idx[r]]);
            let Some(x) = a.lu().solve(&b) else { continue };
            if x.iter().any(|&v| v < -options.tolerance) {
                continue;
            }
            for (r, &i) in idx.iter().enumerate() {
                z[i] = x[r].max(0.0);
            }
        }
        let error = lcp.error(&z);
        if error <= options.tolerance {
            return Ok(LcpSolution {
                z,
                iterations: tried + 1,
                error,
            });
        }
        if best.as_ref().is_none_or(|(e, _)| error < *e) {
            best = Some((error, z));
        }
    }
    match best {
        Some((error, _)) if error.is_finite() => Err(LcpError::NotConverged {
            solver: "enum",
            iterations: sets.len(),
            error,
            tolerance: options.tolerance,
        }),
        _ => Err(LcpError::NoSolution { sets: sets.len() }),
    }
}
