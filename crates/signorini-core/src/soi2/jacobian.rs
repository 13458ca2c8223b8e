//! A step's residual F(x) and Newton's matrix J = ∂F/∂x, built by forward-mode AD and
//! factorised.
//!
//! A residual whose pattern has a band order (a large mechanism, [`super::banded`]) keeps only
//! the values of its pattern's entries and goes to the band LU from them: no n×n array is
//! allocated, zeroed or read (allocating and zeroing one per step that builds a Jacobian was
//! 13 % of A02's time at N = 160, 1 282 unknowns, 13 MB). The dense matrix is formed only for
//! the SVD of a singular matrix with rank-deficient joints. Any other residual is built densely.

use super::banded::BandLu;
use super::factor::NewtonFactor;
use super::sparsity::Pattern;
use super::{Dual64, Scalar};
use nalgebra::{DMatrix, DVector};

/// A residual function F(x) written for any scalar, so that its Jacobian comes from AD.
pub trait Residual {
    /// Number of unknowns (= of equations).
    fn size(&self) -> usize;
    /// F(x).
    fn eval<T: Scalar>(&self, x: &[T], r: &mut [T]);
    /// Size of the increments that round-off alone produces (0 when negligible): Newton stops
    /// when its increments stop shrinking below this floor.
    fn noise_floor(&self) -> f64 {
        0.0
    }
    /// The rounding of the data the residual is evaluated from, as a change of the unknowns
    /// (0 when negligible): the residual test's bound ‖J‖∞ · (tolerance · (1 + ‖x‖∞) + this)
    /// accepts the residual such a change produces (see [`NewtonOptions`]).
    fn rounding(&self) -> f64 {
        0.0
    }
    /// Whether the constraint Jacobian (g_y; k_z) has lost rank at the iterate `x` (then a
    /// singular Newton matrix is solved in the least-squares sense).
    fn joints_deficient(&self, x: &[f64]) -> bool {
        let _ = x;
        false
    }
    /// The structure of the Jacobian, when known (then it is built one dual evaluation per
    /// group of structurally orthogonal columns); `None`: one per column.
    fn pattern(&self) -> Option<&Pattern> {
        None
    }
}

/// Newton's matrix as built.
pub(super) enum Jacobian {
    /// Every entry.
    Dense(DMatrix<f64>),
    /// The entries of the residual's pattern, column by column in the pattern's row order;
    /// `starts[j]` is where column j begins (`starts[n]` = the number of entries).
    Entries {
        /// The values.
        values: Vec<f64>,
        /// Where each column begins in `values`.
        starts: Vec<usize>,
    },
}

/// The residual's pattern when it describes an n-unknown matrix.
fn pattern_of<R: Residual>(res: &R, n: usize) -> Option<&Pattern> {
    res.pattern().filter(|p| p.size() == n && n > 0)
}

impl Jacobian {
    /// Room for the Jacobian of `res`: its pattern's entries when the pattern has a band
    /// order, else an n×n zero matrix.
    pub(super) fn for_residual<R: Residual>(res: &R) -> Jacobian {
        let n = res.size();
        match pattern_of(res, n).filter(|p| p.band().is_some()) {
            Some(pattern) => {
                let mut starts = Vec::with_capacity(n + 1);
                let mut count = 0;
                for j in 0..n {
                    starts.push(count);
                    count += pattern.rows_of(j).len();
                }
                starts.push(count);
                Jacobian::Entries {
                    values: vec![0.0; count],
                    starts,
                }
            }
            None => Jacobian::Dense(DMatrix::zeros(n, n)),
        }
    }

    /// The dense matrix (formed from the entries when it is not kept dense).
    fn dense<R: Residual>(&self, res: &R) -> DMatrix<f64> {
        match self {
            Jacobian::Dense(j) => j.clone(),
            Jacobian::Entries { values, starts } => {
                let n = starts.len() - 1;
                let mut j = DMatrix::zeros(n, n);
                if let Some(pattern) = pattern_of(res, n) {
                    for c in 0..n {
                        for (&i, &v) in pattern.rows_of(c).iter().zip(&values[starts[c]..]) {
                            j[(i, c)] = v;
                        }
                    }
                }
                j
            }
        }
    }

    /// Fills the Jacobian of `res` at `x`, and `r` with F(x): one dual evaluation per group of
    /// structurally orthogonal columns when the residual knows its pattern, one per column
    /// otherwise. With a pattern only its entries are written: a dense matrix must be zero
    /// outside it, as allocated and as every earlier build of the same residual left it.
    pub(super) fn build<R: Residual>(
        &mut self,
        res: &R,
        x: &[f64],
        xd: &mut [Dual64],
        rd: &mut [Dual64],
        r: &mut DVector<f64>,
    ) {
        let n = x.len();
        for (d, &v) in xd.iter_mut().zip(x.iter()) {
            *d = Dual64::from_re(v);
        }
        if let Some(pattern) = pattern_of(res, n) {
            for group in pattern.groups() {
                for &j in group {
                    xd[j].eps = 1.0;
                }
                res.eval(xd, rd);
                for &j in group {
                    xd[j].eps = 0.0;
                    let rows = pattern.rows_of(j);
                    match self {
                        Jacobian::Dense(jac) => {
                            for &i in rows {
                                jac[(i, j)] = rd[i].eps;
                            }
                        }
                        Jacobian::Entries { values, starts } => {
                            for (v, &i) in values[starts[j]..].iter_mut().zip(rows) {
                                *v = rd[i].eps;
                            }
                        }
                    }
                }
            }
            for (ri, d) in r.iter_mut().zip(rd.iter()) {
                *ri = d.re;
            }
            return;
        }
        let Jacobian::Dense(jac) = self else {
            unreachable!("entries are kept only for a residual with a pattern")
        };
        for j in 0..n {
            xd[j].eps = 1.0;
            res.eval(xd, rd);
            for i in 0..n {
                jac[(i, j)] = rd[i].eps;
                r[i] = rd[i].re;
            }
            xd[j].eps = 0.0;
        }
    }

    /// ‖J‖∞, the largest row sum of |J| (the scale of the residual test), over the entries of
    /// the pattern when the residual has one (the others are zero), each row's sum in the
    /// order of its columns. Over the whole dense matrix it was 9 % of A02's time at N = 160.
    pub(super) fn row_sum_norm<R: Residual>(&self, res: &R) -> f64 {
        let n = res.size();
        let mut sums = vec![0.0; n];
        match (self, pattern_of(res, n)) {
            (Jacobian::Entries { values, starts }, Some(pattern)) => {
                for j in 0..n {
                    for (&i, v) in pattern.rows_of(j).iter().zip(&values[starts[j]..]) {
                        sums[i] += v.abs();
                    }
                }
            }
            (Jacobian::Dense(jac), Some(pattern)) => {
                for j in 0..n {
                    for &i in pattern.rows_of(j) {
                        sums[i] += jac[(i, j)].abs();
                    }
                }
            }
            (Jacobian::Dense(jac), None) => {
                for column in jac.column_iter() {
                    for (sum, v) in sums.iter_mut().zip(column.iter()) {
                        *sum += v.abs();
                    }
                }
            }
            (Jacobian::Entries { .. }, None) => {
                unreachable!("entries are kept only for a residual with a pattern")
            }
        }
        sums.into_iter().fold(0.0, f64::max)
    }

    /// The factorisation at `x`: band LU in the band order of the residual's pattern when it
    /// has one, else dense LU; the SVD when singular with rank-deficient joints
    /// ([`NewtonFactor::choose`]).
    pub(super) fn factor<R: Residual>(&self, res: &R, x: &[f64]) -> NewtonFactor {
        let n = res.size();
        match self {
            Jacobian::Dense(jac) => {
                let band = pattern_of(res, n).and_then(Pattern::band);
                NewtonFactor::with_band(jac, band, || res.joints_deficient(x))
            }
            Jacobian::Entries { values, starts } => {
                let Some((pattern, band)) = pattern_of(res, n).and_then(|p| Some((p, p.band()?)))
                else {
                    unreachable!("entries are kept only for a residual with a band order")
                };
                let entries = (0..n).flat_map(|j| {
                    pattern
                        .rows_of(j)
                        .iter()
                        .zip(&values[starts[j]..])
                        .map(move |(&i, &v)| (i, j, v))
                });
                let Some(lu) = BandLu::factor_entries(band, entries) else {
                    unreachable!("the band order is the pattern's")
                };
                let finite = || values.iter().all(|v| v.is_finite());
                NewtonFactor::choose(
                    NewtonFactor::Banded(lu),
                    finite,
                    || res.joints_deficient(x),
                    || self.dense(res),
                )
            }
        }
    }
}
