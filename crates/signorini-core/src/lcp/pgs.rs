//! Projected Gauss–Seidel: `z_i ← max(0, z_i − (M z + q)_i / M_ii)`, sweep after sweep.

use super::{Lcp, LcpError, LcpOptions, LcpSolution};

/// Solves the LCP by projected Gauss–Seidel. Converges for symmetric positive semidefinite M with
/// positive diagonal (the Delassus operators of this project); checks the error every sweep.
pub fn solve_pgs(lcp: Lcp<'_>, options: &LcpOptions) -> Result<LcpSolution, LcpError> {
    let n = lcp.size();
    for i in 0..n {
        let d = lcp.m[i * n + i];
        if d <= 0.0 || !d.is_finite() {
            return Err(LcpError::NonPositiveDiagonal { index: i, value: d });
        }
    }
    let mut z = vec![0.0; n];
    let mut error = f64::INFINITY;
    for sweep in 1..=options.max_iterations {
        for i in 0..n {
            let row = &lcp.m[i * n..(i + 1) * n];
            let wi = lcp.q[i] + row.iter().zip(&z).map(|(a, b)| a * b).sum::<f64>();
            z[i] = (z[i] - wi / row[i]).max(0.0);
        }
        error = lcp.error(&z);
        if error <= options.tolerance {
            return Ok(LcpSolution {
                z,
                iterations: sweep,
                error,
            });
        }
    }
    Err(LcpError::NotConverged {
        solver: "pgs",
        iterations: options.max_iterations,
        error,
        tolerance: options.tolerance,
    })
}
