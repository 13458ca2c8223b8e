//! 3×3 blocks (row-major `[f64; 9]`), the unit of the FC3D problem's Delassus operator W and of
//! its Newton matrices: products, the inverse by the adjugate, and a solve with partial
//! pivoting, written out (nalgebra's general LU costs several times as much at this size, and
//! the Gauss–Seidel sweeps solve one local problem per contact and sweep).

use super::block_csr::BlockCsr;

/// Smallest |det P| of a block P relative to `max |P_ij|³` for which [`inverse`] inverts it;
/// below it the block counts as singular.
const PIVOT_DETERMINANT: f64 = 1e-24;

/// A 3×3 block, row-major.
pub(crate) type Block = [f64; 9];

/// Contact a's diagonal block of a 3×3-block W (zeros when it is not stored).
pub(crate) fn diagonal(w: &BlockCsr, a: usize) -> Block {
    let mut block = [0.0; 9];
    if let Some(stored) = w.stored_diagonal_block(a) {
        block.copy_from_slice(stored);
    }
    block
}

/// `a · b` for 3×3 blocks.
pub(crate) fn product(a: &Block, b: &Block) -> Block {
    let mut c = [0.0; 9];
    for i in 0..3 {
        for k in 0..3 {
            c[3 * i + k] = a[3 * i] * b[k] + a[3 * i + 1] * b[3 + k] + a[3 * i + 2] * b[6 + k];
        }
    }
    c
}

/// `c ← c − a · b` for 3×3 blocks.
pub(crate) fn subtract_product(c: &mut Block, a: &Block, b: &Block) {
    for i in 0..3 {
        for k in 0..3 {
            c[3 * i + k] -= a[3 * i] * b[k] + a[3 * i + 1] * b[3 + k] + a[3 * i + 2] * b[6 + k];
        }
    }
}

/// `a · x` for a 3×3 block and a 3-vector.
pub(crate) fn apply(a: &Block, x: &[f64]) -> [f64; 3] {
    [
        a[0] * x[0] + a[1] * x[1] + a[2] * x[2],
        a[3] * x[0] + a[4] * x[1] + a[5] * x[2],
        a[6] * x[0] + a[7] * x[1] + a[8] * x[2],
    ]
}

/// `y ← y − a · x` for a 3×3 block and 3-vectors.
pub(crate) fn subtract_apply(y: &mut [f64], a: &Block, x: &[f64]) {
    for i in 0..3 {
        y[i] -= a[3 * i] * x[0] + a[3 * i + 1] * x[1] + a[3 * i + 2] * x[2];
    }
}

/// The inverse of a 3×3 block by its adjugate, or None when its determinant is below
/// [`PIVOT_DETERMINANT`] relative to the cube of its largest entry.
pub(crate) fn inverse(p: &Block) -> Option<Block> {
    let cofactor = [
        p[4] * p[8] - p[5] * p[7],
        p[5] * p[6] - p[3] * p[8],
        p[3] * p[7] - p[4] * p[6],
    ];
    let det = p[0] * cofactor[0] + p[1] * cofactor[1] + p[2] * cofactor[2];
    let scale = p.iter().fold(0.0f64, |s, x| s.max(x.abs()));
    // Also refuses a determinant that is not a number.
    if det
        .abs()
        .partial_cmp(&(PIVOT_DETERMINANT * scale * scale * scale))
        != Some(std::cmp::Ordering::Greater)
    {
        return None;
    }
    let d = 1.0 / det;
    Some([
        cofactor[0] * d,
        (p[2] * p[7] - p[1] * p[8]) * d,
        (p[1] * p[5] - p[2] * p[4]) * d,
        cofactor[1] * d,
        (p[0] * p[8] - p[2] * p[6]) * d,
        (p[2] * p[3] - p[0] * p[5]) * d,
        cofactor[2] * d,
        (p[1] * p[6] - p[0] * p[7]) * d,
        (p[0] * p[4] - p[1] * p[3]) * d,
    ])
}

/// Solves `a x = b` by the adjugate (Cramer's rule: `x = adj(a) b / det a`, the cofactors
/// shared with [`inverse`]'s), branch-free; None when the determinant is 0 or the answer is not
/// a number. The local Newton solves of the Gauss–Seidel sweeps call it once per iteration,
/// where the elimination with partial pivoting it replaces cost a third of a sweep on small
/// problems (docs/friction_benchmark.md, Round 16).
#[inline]
pub(crate) fn solve(a: &Block, b: [f64; 3]) -> Option<[f64; 3]> {
    let c00 = a[4] * a[8] - a[5] * a[7];
    let c01 = a[5] * a[6] - a[3] * a[8];
    let c02 = a[3] * a[7] - a[4] * a[6];
    let det = a[0] * c00 + a[1] * c01 + a[2] * c02;
    if det == 0.0 {
        return None;
    }
    let d = 1.0 / det;
    let x = [
        (c00 * b[0] + (a[2] * a[7] - a[1] * a[8]) * b[1] + (a[1] * a[5] - a[2] * a[4]) * b[2]) * d,
        (c01 * b[0] + (a[0] * a[8] - a[2] * a[6]) * b[1] + (a[2] * a[3] - a[0] * a[5]) * b[2]) * d,
        (c02 * b[0] + (a[1] * a[6] - a[0] * a[7]) * b[1] + (a[0] * a[4] - a[1] * a[3]) * b[2]) * d,
    ];
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Vector3};

    /// The adjugate solve agrees with nalgebra's LU with partial pivoting to round-off, on
    /// blocks of a Newton matrix's kinds: with a zero leading entry (elimination without
    /// pivoting would divide by it), unsymmetric, badly scaled; and refuses a singular one.
    #[test]
    fn the_adjugate_solve_agrees_with_a_pivoting_lu() {
        let blocks: [Block; 4] = [
            [0.0, 2.0, 1.0, 1.0, 0.5, -3.0, 4.0, 1.0, 0.0],
            [1.0, 0.0, 0.0, 0.3, 2.5, -0.7, 0.1, 0.9, 1.8],
            [1e-3, 2e-3, 0.0, -4.0, 1e3, 2.0, 0.5, -0.25, 7.0],
            [3.0, 1.0, -1.0, 1.0, 4.0, 2.0, -2.0, 0.5, 5.0],
        ];
        let b = [1.0, -2.0, 0.5];
        for a in &blocks {
            let x = solve(a, b).unwrap();
            let expected = Matrix3::from_row_slice(a)
                .lu()
                .solve(&Vector3::from_row_slice(&b))
                .unwrap();
            let size = expected.amax();
            for i in 0..3 {
                assert!((x[i] - expected[i]).abs() <= 1e-13 * size, "{a:?}: {x:?}");
            }
            let ax = apply(a, &x);
            for i in 0..3 {
                assert!((ax[i] - b[i]).abs() <= 1e-12, "{a:?}: residual {ax:?}");
            }
        }
        assert_eq!(
            solve(&[1.0, 2.0, 3.0, 2.0, 4.0, 6.0, 0.0, 1.0, 1.0], b),
            None
        );
        assert_eq!(solve(&[0.0; 9], b), None);
    }
}
