//! 3×3 blocks (row-major `[f64; 9]`), the unit of the FC3D problem's Delassus operator W and of
//! its Newton matrices: products, the inverse by the adjugate, and a solve with partial
//! pivoting, written out (nalgebra's general LU costs several times as much at this size, and
//! the Gauss–Seidel sweeps solve one local problem per contact and sweep).

/// Smallest |det P| of a block P relative to `max |P_ij|³` for which [`inverse`] inverts it;
/// below it the block counts as singular.
const PIVOT_DETERMINANT: f64 = 1e-24;

/// A 3×3 block, row-major.
pub(crate) type Block = [f64; 9];

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

/// Solves `a x = b` by Gaussian elimination with partial pivoting; None when a pivot is 0 or
/// the answer is not a number (as nalgebra's LU, which this replaces on the local solves).
pub(crate) fn solve(a: &Block, b: [f64; 3]) -> Option<[f64; 3]> {
    let mut m = [
        [a[0], a[1], a[2], b[0]],
        [a[3], a[4], a[5], b[1]],
        [a[6], a[7], a[8], b[2]],
    ];
    for k in 0..3 {
        let pivot = (k..3)
            .max_by(|&i, &j| m[i][k].abs().total_cmp(&m[j][k].abs()))
            .unwrap_or(k);
        m.swap(k, pivot);
        if m[k][k] == 0.0 {
            return None;
        }
        let (upper, lower) = m.split_at_mut(k + 1);
        let pivot_row = &upper[k];
        for row in lower {
            let f = row[k] / pivot_row[k];
            for (x, p) in row[k..].iter_mut().zip(&pivot_row[k..]) {
                *x -= f * p;
            }
        }
    }
    let mut x = [0.0; 3];
    for k in (0..3).rev() {
        let s: f64 = (k + 1..3).map(|c| m[k][c] * x[c]).sum();
        x[k] = (m[k][3] - s) / m[k][k];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}
