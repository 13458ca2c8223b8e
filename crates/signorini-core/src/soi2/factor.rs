//! Factorisation of Newton's matrix when the constraint Jacobian may lose rank (docs/soi2.md).
//!
//! A mechanism at a singular position (the N-four-bar with its rockers horizontal: N rows of
//! g_y vanish together) or with redundant joints at every configuration (Bricard's mechanism)
//! makes the Newton matrix J of a SOI2 step singular: the multipliers λ along the null space
//! of g_yᵀ do not enter the equations. J is then solved in the least-squares sense with the
//! minimum-norm increment, which leaves that part of λ untouched (and [`range_projection`]
//! removes it after the step, giving the minimum-norm multipliers).
//!
//! The choice: regular steps keep LU with partial pivoting, exactly as before (their cost grows
//! by one scan of the pivots); the SVD is used only when LU's pivots show a numerically singular
//! matrix (the ratio of the smallest to the largest below [`LU_PIVOT_RATIO`]) *and* the
//! constraint Jacobian has lost rank at the iterate, so a matrix singular for another reason (a
//! step far too large for the model) fails as it did. An SVD costs several LU factorisations,
//! but it is needed only on the rank-deficient steps; a column-pivoted QR would give a basic
//! rather than the minimum-norm increment.

use super::banded::{BandLu, BandOrder};
use nalgebra::{DMatrix, DVector, Dyn, LU, SVD};

/// Smallest ratio min|u_ii| / max|u_ii| of LU's pivots trusted as a regular matrix. Below it
/// the matrix is decomposed by SVD. Pivots estimate the singular values to within a factor of
/// the size, so 1e-9 sends every matrix with a condition number above ~1e9–1e11 to the SVD.
pub const LU_PIVOT_RATIO: f64 = 1e-9;

/// Singular values σ ≤ RANK_TOLERANCE · σ_max count as zero (numerical rank, minimum-norm
/// solve). The same threshold as the rank of (g_y; k_z) checked at validation.
pub const RANK_TOLERANCE: f64 = 1e-10;

/// A factorised Newton matrix: LU when regular, SVD with its numerical rank when not.
#[derive(Debug, Clone)]
pub enum NewtonFactor {
    /// LU with partial pivoting of a regular matrix.
    Regular(LU<f64, Dyn, Dyn>),
    /// Band LU with partial pivoting of a regular matrix in a band order (a large mechanism,
    /// [`super::banded`]).
    Banded(BandLu),
    /// SVD of a numerically singular matrix, its rank and the threshold σ_max·RANK_TOLERANCE.
    Deficient {
        /// The decomposition.
        svd: SVD<f64, Dyn, Dyn>,
        /// Numerical rank.
        rank: usize,
        /// Singular values at or below this are treated as zero.
        threshold: f64,
        /// ‖J‖∞, the scale of the residual test a least-squares solve must also pass.
        norm: f64,
    },
}

impl NewtonFactor {
    /// Factorises `j` (square). `joints_deficient` says whether the constraint Jacobian has
    /// lost rank at the iterate: only then is a numerically singular `j` decomposed by SVD (a
    /// singular matrix for another reason, a step far too large for the model, stays with LU
    /// and fails as it did).
    pub fn new(j: &DMatrix<f64>, joints_deficient: impl FnOnce() -> bool) -> NewtonFactor {
        NewtonFactor::with_band(j, None, joints_deficient)
    }

    /// [`NewtonFactor::new`], by the band LU in the order `band` when one is given (its entries
    /// outside the band must be zero); the same pivot test sends a numerically singular matrix
    /// with rank-deficient joints to the (dense) SVD.
    pub fn with_band(
        j: &DMatrix<f64>,
        band: Option<&BandOrder>,
        joints_deficient: impl FnOnce() -> bool,
    ) -> NewtonFactor {
        let regular = match band {
            Some(band) => NewtonFactor::Banded(BandLu::factor(j, band)),
            None => NewtonFactor::Regular(j.clone().lu()),
        };
        let finite = || j.iter().all(|v| v.is_finite());
        NewtonFactor::choose(regular, finite, joints_deficient, || j.clone())
    }

    /// The LU factorisation `regular` of a matrix, unless its pivots show it numerically
    /// singular while the joints have lost rank: then the SVD of the matrix (`dense` forms it).
    /// A matrix with a NaN or an infinity (`finite` says whether it has none) stays with LU,
    /// whose solve then fails or gives a non-finite increment that Newton reports.
    pub(super) fn choose(
        regular: NewtonFactor,
        finite: impl FnOnce() -> bool,
        joints_deficient: impl FnOnce() -> bool,
        dense: impl FnOnce() -> DMatrix<f64>,
    ) -> NewtonFactor {
        let (lo, hi) = match &regular {
            NewtonFactor::Regular(lu) => pivot_range(lu),
            NewtonFactor::Banded(lu) => lu.pivot_range(),
            NewtonFactor::Deficient { .. } => return regular,
        };
        if (hi > 0.0 && lo >= LU_PIVOT_RATIO * hi) || !finite() || !joints_deficient() {
            return regular;
        }
        NewtonFactor::least_squares(&dense())
    }

    /// The SVD of `j` with its numerical rank (singular values above [`RANK_TOLERANCE`] · σ_max):
    /// the minimum-norm least-squares solve, for a matrix already known to be singular with
    /// rank-deficient joints (whatever its LU pivots say).
    pub fn least_squares(j: &DMatrix<f64>) -> NewtonFactor {
        NewtonFactor::least_squares_of_rank(j, j.nrows())
    }

    /// [`NewtonFactor::least_squares`] with the rank at most `max_rank`: the singular values
    /// after the `max_rank` largest count as zero too. For a Newton matrix whose joints are
    /// known to be redundant (rank deficit d at the start of the step, on the manifold) but
    /// which is evaluated off the manifold, where the d smallest singular values are small
    /// (1e-9 σ_max on Bricard's mechanism) rather than below [`RANK_TOLERANCE`].
    pub fn least_squares_of_rank(j: &DMatrix<f64>, max_rank: usize) -> NewtonFactor {
        let norm = j
            .row_iter()
            .map(|r| r.iter().map(|v| v.abs()).sum::<f64>())
            .fold(0.0, f64::max);
        let svd = j.clone().svd(true, true);
        let mut sorted: Vec<f64> = svd.singular_values.iter().copied().collect();
        sorted.sort_by(|a, b| b.total_cmp(a));
        let mut threshold = RANK_TOLERANCE * svd.singular_values.max();
        if let Some(&first_dropped) = sorted.get(max_rank) {
            threshold = threshold.max(first_dropped);
        }
        let rank = svd.rank(threshold);
        NewtonFactor::Deficient {
            svd,
            rank,
            threshold,
            norm,
        }
    }

    /// Solves J x = b in place (the minimum-norm least-squares x for a singular J); false when
    /// the solve fails (a zero pivot or a zero matrix).
    pub fn solve_mut(&self, b: &mut DVector<f64>) -> bool {
        match self {
            NewtonFactor::Regular(lu) => lu.solve_mut(b),
            NewtonFactor::Banded(lu) => lu.solve_mut(b.as_mut_slice()),
            NewtonFactor::Deficient { svd, threshold, .. } => {
                match svd.solve(&*b, threshold.max(f64::MIN_POSITIVE)) {
                    Ok(x) => {
                        b.copy_from(&x);
                        true
                    }
                    Err(_) => false,
                }
            }
        }
    }

    /// For a numerically singular matrix, ‖J‖∞: its least-squares increments can vanish away
    /// from a solution (an inconsistent system), so Newton must also pass the residual test.
    pub fn singular_norm(&self) -> Option<f64> {
        match self {
            NewtonFactor::Deficient { norm, .. } if self.deficient() => Some(*norm),
            _ => None,
        }
    }

    /// True when the matrix was found numerically singular.
    pub fn deficient(&self) -> bool {
        matches!(self, NewtonFactor::Deficient { rank, svd, .. } if *rank < svd.singular_values.len())
    }
}

/// (min |u_ii|, max |u_ii|) over the pivots of `lu`, read in place: the diagonal of nalgebra's
/// packed factors (`lu_internal`, L below the diagonal and U on and above it) is U's. `LU::u()`
/// copied the whole upper triangle through a strided iterator at every factorisation, 8 % of
/// the instructions of a full-Newton slider-crank run (issue 26); the values, hence the
/// choice between LU and SVD, are the same.
pub(crate) fn pivot_range(lu: &LU<f64, Dyn, Dyn>) -> (f64, f64) {
    let packed = lu.lu_internal();
    (0..packed.nrows().min(packed.ncols()))
        .map(|i| packed[(i, i)].abs())
        .fold((f64::INFINITY, 0.0_f64), |(lo, hi), d| {
            (lo.min(d), hi.max(d))
        })
}

/// Numerical rank of the rows×n matrix `jac` (row-major), as [`range_projection`] counts it,
/// from its singular values alone (no singular vectors, no projector: the rank test of a
/// Newton matrix whose pivots look singular costs a few times less); `rows` without them when
/// [`certainly_full_rank`].
pub fn numerical_rank(jac: &[f64], rows: usize, n: usize) -> usize {
    if rows == 0 {
        return 0;
    }
    if certainly_full_rank(jac, rows, n) {
        return rows;
    }
    let Some(sv) = crate::dense::singular_values(DMatrix::from_row_slice(rows, n, jac)) else {
        return 0;
    };
    let threshold = RANK_TOLERANCE * sv.max().max(1.0);
    sv.iter().filter(|&&s| s > threshold).count()
}

/// Singular values certified by [`certainly_full_rank`] are above this fraction of
/// max(σ_max, 1): 10⁵ times [`RANK_TOLERANCE`], and its square (the shift of the Gram matrix)
/// 10⁵ times the rounding of a Gram matrix of a few hundred rows (rows · ε).
pub const FULL_RANK_MARGIN: f64 = 1e-5;

/// Whether every singular value of the rows×n matrix `jac` (row-major) is certainly above
/// [`FULL_RANK_MARGIN`] · max(σ_max, 1), hence above [`numerical_rank`]'s threshold: the
/// Cholesky factorisation of A Aᵀ − δI exists, with δ = (margin · s)² and s² = max(‖A Aᵀ‖∞, 1)
/// ≥ max(σ_max², 1), exactly when σ_min² > δ (in exact arithmetic; rounding moves that boundary
/// by far less than the margin to the threshold, and a failure only leaves the decision to the
/// SVD). A Aᵀ is formed over the nonzeros of A (a few per row of a mechanism's g_y), and the
/// factorisation costs rows³/3: on A02 at N = 160 (g_y of 160 × 321) the SVD it spares was two
/// thirds of an HHT-SOI2 run, on the steps accepted by the residual test, whose rank the summary
/// reports. `false` (decide by the SVD) for
/// more rows than columns or an entry that is not finite.
fn certainly_full_rank(jac: &[f64], rows: usize, n: usize) -> bool {
    if rows > n || !jac.iter().all(|v| v.is_finite()) {
        return false;
    }
    // The rows with a nonzero in each column.
    let mut in_column: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
    for (i, row) in jac.chunks_exact(n).enumerate() {
        for (c, &v) in row.iter().enumerate() {
            if v != 0.0 {
                in_column[c].push((i, v));
            }
        }
    }
    // A Aᵀ is banded: rows i and k meet only where they share a column.
    let band = in_column
        .iter()
        .filter_map(|c| Some(c.last()?.0 - c.first()?.0))
        .max()
        .unwrap_or(0);
    let mut gram = LowerBand::zeros(rows, band);
    for column in &in_column {
        for (p, &(i, a)) in column.iter().enumerate() {
            for &(k, b) in &column[..=p] {
                *gram.at_mut(i, k) += a * b;
            }
        }
    }
    let shift = FULL_RANK_MARGIN * FULL_RANK_MARGIN * gram.row_sum_norm().max(1.0);
    for i in 0..rows {
        *gram.at_mut(i, i) -= shift;
    }
    gram.cholesky()
}

/// The lower triangle of a symmetric rows × rows matrix of half-bandwidth `band`, row by row
/// (row i holds columns i − band … i).
struct LowerBand {
    rows: usize,
    band: usize,
    entries: Vec<f64>,
}

impl LowerBand {
    fn zeros(rows: usize, band: usize) -> Self {
        Self {
            rows,
            band,
            entries: vec![0.0; rows * (band + 1)],
        }
    }

    /// Entry (i, k), k ≤ i ≤ k + band.
    fn at_mut(&mut self, i: usize, k: usize) -> &mut f64 {
        &mut self.entries[i * (self.band + 1) + self.band + k - i]
    }

    /// The stored row i, columns i − band … i (the first ones zero for i < band).
    fn row(&self, i: usize) -> &[f64] {
        &self.entries[i * (self.band + 1)..(i + 1) * (self.band + 1)]
    }

    /// ‖·‖∞ of the symmetric matrix: row i sums its stored row and the column below it.
    fn row_sum_norm(&self) -> f64 {
        let mut sums = vec![0.0; self.rows];
        for i in 0..self.rows {
            for (d, v) in self.row(i).iter().rev().enumerate() {
                if d <= i {
                    sums[i] += v.abs();
                    if d > 0 {
                        sums[i - d] += v.abs();
                    }
                }
            }
        }
        sums.into_iter().fold(0.0, f64::max)
    }

    /// Whether the Cholesky factorisation L Lᵀ exists (every pivot positive), computed in place
    /// over the band (O(rows · band²)).
    fn cholesky(mut self) -> bool {
        let w = self.band + 1;
        for i in 0..self.rows {
            let first = i.saturating_sub(self.band);
            for k in first..=i {
                // Σ_{j<k} l_ij l_kj over the columns both rows store.
                let from = first.max(k.saturating_sub(self.band));
                let mut sum = self.entries[i * w + self.band + k - i];
                for j in from..k {
                    sum -= self.entries[i * w + self.band + j - i]
                        * self.entries[k * w + self.band + j - k];
                }
                if k < i {
                    let pivot = self.entries[k * w + self.band];
                    self.entries[i * w + self.band + k - i] = sum / pivot;
                } else if sum > 0.0 {
                    self.entries[i * w + self.band] = sum.sqrt();
                } else {
                    return false;
                }
            }
        }
        true
    }
}

/// Numerical rank of the rows×n matrix `jac` (row-major) and the orthogonal projector onto its
/// column space, an rows×rows matrix: λ ↦ P λ keeps g_yᵀλ and removes the part of λ that
/// g_yᵀ does not see, giving the minimum-norm multipliers.
pub fn range_projection(jac: &[f64], rows: usize, n: usize) -> (usize, DMatrix<f64>) {
    if rows == 0 || !jac.iter().all(|v| v.is_finite()) {
        // No rank to speak of at a NaN (the run reports the NaN itself).
        return (0, DMatrix::zeros(rows, rows));
    }
    let a = DMatrix::from_row_slice(rows, n, jac);
    let svd = a.svd(true, false);
    let threshold = RANK_TOLERANCE * svd.singular_values.max().max(1.0);
    let Some(u) = svd.u.as_ref() else {
        unreachable!("u was requested");
    };
    let mut p = DMatrix::zeros(rows, rows);
    let mut rank = 0;
    for (k, &s) in svd.singular_values.iter().enumerate() {
        if s > threshold {
            rank += 1;
            let col = u.column(k);
            p += col * col.transpose();
        }
    }
    (rank, p)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rank certificate answers for clearly regular matrices only, and the rank is the
    /// SVD's either way: singular values 1, 1 and 10⁻³ are certified; 10⁻⁸ (above the rank
    /// threshold, below the margin) goes to the SVD, which counts it; 10⁻¹² and a repeated row
    /// are rank losses.
    #[test]
    fn the_full_rank_certificate_spares_only_clearly_regular_matrices() {
        let with_third = |s: f64| vec![1.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, s, 0.0];
        let by_svd = |a: &[f64]| {
            let sv = DMatrix::from_row_slice(3, 4, a).singular_values();
            let threshold = RANK_TOLERANCE * sv.max().max(1.0);
            sv.iter().filter(|&&s| s > threshold).count()
        };
        for (s, certified, rank) in [(1e-3, true, 3), (1e-8, false, 3), (1e-12, false, 2)] {
            let a = with_third(s);
            assert_eq!(certainly_full_rank(&a, 3, 4), certified, "σ = {s}");
            assert_eq!(numerical_rank(&a, 3, 4), rank, "σ = {s}");
            assert_eq!(by_svd(&a), rank, "σ = {s}");
        }
        let repeated = [1.0, 2.0, 0.0, 3.0, 0.5, 0.0, 1.0, 0.0, 1.0, 2.0, 0.0, 3.0];
        assert!(!certainly_full_rank(&repeated, 3, 4));
        assert_eq!(numerical_rank(&repeated, 3, 4), 2);
        // More rows than columns, and a NaN: left to the SVD.
        assert!(!certainly_full_rank(&[1.0, 0.0, 0.0, 1.0, 1.0, 1.0], 3, 2));
        assert!(!certainly_full_rank(&[f64::NAN, 0.0, 0.0, 1.0], 2, 2));
    }

    /// The band Cholesky of the certificate decides as the dense one of nalgebra on the same
    /// shifted Gram matrix: a chain-like 12 × 20 matrix (each row touching three neighbouring
    /// columns) with one row scaled from 1 down to 10⁻¹², the certificate holding exactly while
    /// the dense factorisation exists.
    #[test]
    fn the_band_cholesky_decides_as_the_dense_one() {
        let (rows, n) = (12, 20);
        for scale in [1.0, 1e-2, 1e-4, 1e-5, 2e-6, 1e-6, 1e-8, 1e-12] {
            let mut a = vec![0.0; rows * n];
            for i in 0..rows {
                for (d, v) in [(0, 1.0), (1, -0.7), (2, 0.3)] {
                    let c = (i * (n - 3)) / (rows - 1) + d;
                    a[i * n + c] = v * (1.0 + 0.1 * i as f64) * if i == 5 { scale } else { 1.0 };
                }
            }
            let m = DMatrix::from_row_slice(rows, n, &a);
            let mut gram = &m * m.transpose();
            let norm = gram
                .row_iter()
                .map(|r| r.iter().map(|v| v.abs()).sum::<f64>())
                .fold(1.0, f64::max);
            for i in 0..rows {
                gram[(i, i)] -= FULL_RANK_MARGIN * FULL_RANK_MARGIN * norm;
            }
            assert_eq!(
                certainly_full_rank(&a, rows, n),
                gram.cholesky().is_some(),
                "row 5 scaled by {scale}"
            );
        }
    }

    #[test]
    fn a_regular_matrix_keeps_lu_and_its_solution() {
        let j = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.0, 1.0, 3.0, 1.0, 0.0, 1.0, 2.0]);
        let f = NewtonFactor::new(&j, || true);
        assert!(matches!(f, NewtonFactor::Regular(_)));
        let x = DVector::from_column_slice(&[1.0, -2.0, 3.0]);
        let mut b = &j * &x;
        assert!(f.solve_mut(&mut b));
        assert!((b - x).amax() < 1e-14);
    }

    /// The pivots read in place are U's diagonal, on a matrix whose LU interchanges rows (the
    /// packed layout is nalgebra's, not a documented API: this fails if it changes).
    #[test]
    fn the_pivot_range_is_that_of_u() {
        let j = DMatrix::from_row_slice(
            4,
            4,
            &[
                1.0, 2.0, 0.5, -1.0, //
                -3.0, 1.0, 2.0, 0.0, //
                0.25, -4.0, 1.0, 2.0, //
                2.0, 0.5, -1.5, 6.0,
            ],
        );
        let lu = j.lu();
        let u = lu.u();
        let d: Vec<f64> = u.diagonal().iter().map(|v: &f64| v.abs()).collect();
        let want = (
            d.iter().copied().fold(f64::INFINITY, f64::min),
            d.iter().copied().fold(0.0, f64::max),
        );
        assert_eq!(pivot_range(&lu), want);
        assert!(
            !lu.p().is_empty(),
            "the test matrix should interchange rows"
        );
    }

    /// The saddle-point matrix [[I, Gᵀ], [G, 0]] with G's two rows equal (a joint written twice):
    /// rank 3 of 4, and the solve gives the multipliers split evenly (minimum norm).
    #[test]
    fn a_redundant_joint_gives_the_minimum_norm_multipliers() {
        let j = DMatrix::from_row_slice(
            4,
            4,
            &[
                1.0, 0.0, 1.0, 1.0, //
                0.0, 1.0, 0.0, 0.0, //
                1.0, 0.0, 0.0, 0.0, //
                1.0, 0.0, 0.0, 0.0,
            ],
        );
        let f = NewtonFactor::new(&j, || true);
        let NewtonFactor::Deficient { rank, .. } = &f else {
            panic!("LU's pivots should show the singular matrix")
        };
        assert_eq!(*rank, 3);
        assert!(f.deficient());
        // x = 0.5, y = 2, λ₁ + λ₂ = 1.5 − 0.5 = 1 → λ = (0.5, 0.5).
        let mut b = DVector::from_column_slice(&[1.5, 2.0, 0.5, 0.5]);
        assert!(f.solve_mut(&mut b));
        let want = [0.5, 2.0, 0.5, 0.5];
        for (got, want) in b.iter().zip(want) {
            assert!((got - want).abs() < 1e-13, "{b}");
        }
    }

    #[test]
    fn the_projection_removes_what_the_transposed_jacobian_does_not_see() {
        // g_y with rows (1, 0) and (2, 0): rank 1; λ = (1, 1) and P λ = (0.6, 1.2) give the
        // same g_yᵀλ = (3, 0), and P λ is the shortest such λ.
        let (rank, p) = range_projection(&[1.0, 0.0, 2.0, 0.0], 2, 2);
        assert_eq!(rank, 1);
        let l = p * DVector::from_column_slice(&[1.0, 1.0]);
        assert!(
            (l[0] - 0.6).abs() < 1e-14 && (l[1] - 1.2).abs() < 1e-14,
            "{l}"
        );
    }
}
