//! Lemke's complementary pivoting method with covering vector d = 1
//! (Cottle, Pang & Stone, *The Linear Complementarity Problem*, §4.4).

use super::{Lcp, LcpError, LcpOptions, LcpSolution};

/// Largest tableau [`solve_lemke`] builds: 1 GiB. Lemke's dense tableau of an LCP of size n
/// holds n × (2n + 2) numbers (8 n (2n + 2) bytes: 12.6 GB for the 28 008 unknowns of a
/// 7 002-contact planar friction problem), so a large problem is refused before anything is
/// allocated rather than aborting the process when the allocation fails.
pub const DEFAULT_TABLEAU_LIMIT: usize = 1 << 30;

/// Bytes of Lemke's tableau for an LCP of size n (saturating).
pub fn tableau_bytes(n: usize) -> usize {
    n.saturating_mul(n.saturating_mul(2).saturating_add(2))
        .saturating_mul(std::mem::size_of::<f64>())
}

/// Solves `0 ≤ M z + q ⊥ z ≥ 0` by Lemke's method on the tableau `w − M z − d z₀ = q`, within
/// [`DEFAULT_TABLEAU_LIMIT`] bytes of tableau ([`solve_lemke_within`]).
pub fn solve_lemke(lcp: Lcp<'_>, options: &LcpOptions) -> Result<LcpSolution, LcpError> {
    solve_lemke_within(lcp, options, DEFAULT_TABLEAU_LIMIT)
}

/// Solves `0 ≤ M z + q ⊥ z ≥ 0` by Lemke's method on the tableau `w − M z − d z₀ = q`; a
/// tableau of more than `limit` bytes ([`tableau_bytes`]) is refused with
/// [`LcpError::TooLargeForMemory`] before it is allocated.
///
/// Ties in the ratio test prefer the artificial variable z₀ (ending the method), then the
/// lowest row. Succeeds for P-matrices and for copositive-plus M when a solution exists.
pub fn solve_lemke_within(
    lcp: Lcp<'_>,
    options: &LcpOptions,
    limit: usize,
) -> Result<LcpSolution, LcpError> {
    let n = lcp.size();
    let bytes = tableau_bytes(n);
    if bytes > limit {
        return Err(LcpError::TooLargeForMemory {
            solver: "lemke",
            size: n,
            bytes,
            limit,
        });
    }
    let z0 = 2 * n; // column of the artificial variable; columns 0..n are w, n..2n are z
    let cols = 2 * n + 2;
    let rhs = 2 * n + 1;
    let mut t = vec![0.0; n * cols];
    for i in 0..n {
        t[i * cols + i] = 1.0;
        for j in 0..n {
            t[i * cols + n + j] = -lcp.m[i * n + j];
        }
        t[i * cols + z0] = -1.0;
        t[i * cols + rhs] = lcp.q[i];
    }
    let mut basis: Vec<usize> = (0..n).collect();
    let scale = lcp.q.iter().fold(1.0f64, |s, a| s.max(a.abs()));
    let eps = 1e-13;

    // First pivot: z₀ enters at the most negative q.
    let mut row = (0..n).fold(0, |r, i| if lcp.q[i] < lcp.q[r] { i } else { r });
    let mut entering = z0;
    let mut pivots = 0;
    loop {
        pivot(&mut t, cols, n, row, entering);
        let leaving = std::mem::replace(&mut basis[row], entering);
        pivots += 1;
        if leaving == z0 {
            break;
        }
        if pivots > options.max_iterations {
            let z = extract(&t, &basis, cols, n);
            return Err(LcpError::NotConverged {
                solver: "lemke",
                iterations: pivots,
                error: lcp.error(&z),
                tolerance: options.tolerance,
            });
        }
        // The complement of the variable that left enters.
        entering = if leaving < n {
            leaving + n
        } else {
            leaving - n
        };
        // Ratio test.
        let mut best: Option<(usize, f64)> = None;
        for i in 0..n {
            let a = t[i * cols + entering];
            if a > eps {
                let ratio = t[i * cols + rhs] / a;
                let better = match best {
                    None => true,
                    Some((r, b)) => {
                        ratio < b - eps * scale
                            || (ratio <= b + eps * scale && basis[i] == z0 && basis[r] != z0)
                    }
                };
                if better {
                    best = Some((i, ratio));
                }
            }
        }
        match best {
            Some((r, _)) => row = r,
            None => return Err(LcpError::RayTermination { pivots }),
        }
    }
    let z = extract(&t, &basis, cols, n);
    let error = lcp.error(&z);
    if error > options.tolerance {
        return Err(LcpError::NotConverged {
            solver: "lemke",
            iterations: pivots,
            error,
            tolerance: options.tolerance,
        });
    }
    Ok(LcpSolution {
        z,
        iterations: pivots,
        error,
    })
}

fn pivot(t: &mut [f64], cols: usize, n: usize, row: usize, col: usize) {
    let p = t[row * cols + col];
    for k in 0..cols {
        t[row * cols + k] /= p;
    }
    for i in 0..n {
        if i == row {
            continue;
        }
        let f = t[i * cols + col];
        if f != 0.0 {
            for k in 0..cols {
                t[i * cols + k] -= f * t[row * cols + k];
            }
        }
    }
}

fn extract(t: &[f64], basis: &[usize], cols: usize, n: usize) -> Vec<f64> {
    let mut z = vec![0.0; n];
    for (i, &b) in basis.iter().enumerate() {
        if (n..2 * n).contains(&b) {
            z[b - n] = t[i * cols + 2 * n + 1].max(0.0);
        }
    }
    z
}
