//! Anderson's method for fixed-point iterations: the history of the last iterates and the
//! extrapolation it gives.
//!
//! For a map `x ↦ g(x)` with residual `f = g(x) − x`, Anderson's method (D. G. Anderson,
//! *Iterative procedures for nonlinear integral equations*, J. ACM 12(4):547–560, 1965,
//! doi:10.1145/321296.321305; in the form of H. F. Walker, P. Ni, *Anderson acceleration for
//! fixed-point iterations*, SIAM J. Numer. Anal. 49(4):1715–1735, 2011, doi:10.1137/10078356X,
//! Algorithm AA) combines the last `d + 1` iterates:
//!
//! ```text
//! ΔF_k = [f_{k−d+1} − f_{k−d}, …, f_k − f_{k−1}],   ΔG_k = [g(x_{k−d+1}) − g(x_{k−d}), …]
//! γ_k = argmin_γ ‖f_k − ΔF_k γ‖₂
//! x_{k+1} = g(x_k) − ΔG_k γ_k
//! ```
//!
//! For a linear map this is GMRES on `x − g(x) = 0`. The least-squares problem is solved through
//! its d × d normal equations (singular values of ΔF_kᵀΔF_k below 10⁻¹⁴ of the largest dropped).
//! Used by the accelerated Gauss–Seidel sweeps
//! of the 3D friction problem ([`crate::friction`]) and by simplified Newton in the SOI2 schemes
//! ([`crate::soi2`]), where `g` is one iterate with a reused Jacobian.

use crate::dense::dot;
use nalgebra::{DMatrix, DVector, Matrix2, Vector2};
use std::collections::VecDeque;

/// Singular values of ΔFᵀΔF below this fraction of the largest are dropped (those of ΔF below
/// 10⁻⁷ of its largest: below that the Gram matrix holds round-off only).
const GRAM_CUT: f64 = 1e-14;

/// `a − b`, entry by entry.
fn difference(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(a, b)| a - b).collect()
}

/// The last d differences `(Δf, Δg)` (oldest first) and the Gram matrix `ΔFᵀΔF` of the Δf,
/// kept up to date as they come and go: a new difference costs d dot products, not d².
struct History {
    depth: usize,
    differences: VecDeque<(Vec<f64>, Vec<f64>)>,
    /// `gram[i][j] = Δf_i · Δf_j` for the stored differences.
    gram: VecDeque<VecDeque<f64>>,
}

impl History {
    /// An empty history that keeps the last `depth` differences.
    fn new(depth: usize) -> Self {
        Self {
            depth,
            differences: VecDeque::with_capacity(depth),
            gram: VecDeque::with_capacity(depth),
        }
    }

    fn clear(&mut self) {
        self.differences.clear();
        self.gram.clear();
    }

    /// Appends a difference, dropping the oldest beyond the depth.
    fn push(&mut self, df: Vec<f64>, dg: Vec<f64>) {
        if self.differences.len() == self.depth {
            self.differences.pop_front();
            self.gram.pop_front();
            for row in &mut self.gram {
                row.pop_front();
            }
        }
        let column: Vec<f64> = self.differences.iter().map(|(f, _)| dot(f, &df)).collect();
        for (row, &x) in self.gram.iter_mut().zip(&column) {
            row.push_back(x);
        }
        let mut row: VecDeque<f64> = column.into();
        row.push_back(dot(&df, &df));
        self.gram.push_back(row);
        self.differences.push_back((df, dg));
    }

    /// γ = argmin ‖f − ΔF γ‖₂ from the normal equations `ΔFᵀΔF γ = ΔFᵀ f` by the singular
    /// value decomposition, singular values below [`GRAM_CUT`] of the largest dropped; `None`
    /// when that solve fails. A history of depth ≤ 2 is solved in closed form and by
    /// nalgebra's static 2 × 2 SVD (the general one on a dynamic 2 × 2 matrix was 9 % of
    /// simplified Newton's time on A02). Deeper histories keep the general SVD from their first
    /// difference on: the FC3D sweeps (depth 5) hand their best iterate to a proximal stage that
    /// is sensitive to round-off, and with the closed forms for their first two extrapolations
    /// `auto` took 280 Newton iterations on FCLib's Capsules-i122-1617 instead of 131.
    fn coefficients(&self, f: &[f64]) -> Option<Vec<f64>> {
        let history = &self.differences;
        let rhs: Vec<f64> = history.iter().map(|(df, _)| dot(df, f)).collect();
        if self.depth > 2 {
            let d = history.len();
            return solve_gram(DMatrix::from_fn(d, d, |i, j| self.gram[i][j]), rhs);
        }
        match history.len() {
            1 => {
                let gram = self.gram[0][0];
                (gram > 0.0).then(|| vec![rhs[0] / gram])
            }
            2 => {
                let gram = Matrix2::new(
                    self.gram[0][0],
                    self.gram[0][1],
                    self.gram[1][0],
                    self.gram[1][1],
                );
                let svd = gram.svd(true, true);
                let cut = GRAM_CUT * svd.singular_values.max();
                let gamma = svd.solve(&Vector2::new(rhs[0], rhs[1]), cut).ok()?;
                Some(vec![gamma[0], gamma[1]])
            }
            _ => None,
        }
    }

    /// `g − ΔG γ` with γ of [`History::coefficients`]; `g` itself without history or when that
    /// solve fails.
    fn extrapolate(&self, f: &[f64], g: &[f64]) -> Vec<f64> {
        let history = &self.differences;
        if history.is_empty() {
            return g.to_vec();
        }
        let Some(gamma) = self.coefficients(f) else {
            return g.to_vec();
        };
        let mut next = g.to_vec();
        for (j, (_, dg)) in history.iter().enumerate() {
            for (x, d) in next.iter_mut().zip(dg) {
                *x -= gamma[j] * d;
            }
        }
        if next.iter().all(|x| x.is_finite()) {
            next
        } else {
            g.to_vec()
        }
    }
}

/// `gram γ = rhs` by the SVD of `gram`, singular values below [`GRAM_CUT`] of the largest
/// dropped; `None` when the solve fails.
fn solve_gram(gram: DMatrix<f64>, rhs: Vec<f64>) -> Option<Vec<f64>> {
    let svd = gram.svd(true, true);
    let cut = GRAM_CUT * svd.singular_values.max();
    let gamma = svd.solve(&DVector::from_vec(rhs), cut).ok()?;
    Some(gamma.iter().copied().collect())
}

/// Anderson's method over a run of iterates of one map: feed it each iterate `x_k` with its
/// image `g(x_k)` and it returns `x_{k+1}`.
pub(crate) struct Accelerator {
    history: History,
    /// `(f, g)` of the last iterate.
    last: Option<(Vec<f64>, Vec<f64>)>,
}

impl Accelerator {
    /// Combines the last `depth + 1` iterates.
    pub(crate) fn new(depth: usize) -> Self {
        Self {
            history: History::new(depth),
            last: None,
        }
    }

    /// Forgets the iterates so far (the map changed, or a restart).
    pub(crate) fn clear(&mut self) {
        self.history.clear();
        self.last = None;
    }

    /// Whether the next iterate will be extrapolated (not the image itself): after the first.
    pub(crate) fn extrapolates(&self) -> bool {
        self.last.is_some()
    }

    /// The next iterate after `x` whose image is `g`: `g` itself on a fresh start.
    pub(crate) fn next(&mut self, x: &[f64], g: Vec<f64>) -> Vec<f64> {
        let f = difference(&g, x);
        if let Some((f_last, g_last)) = self.last.take() {
            self.history
                .push(difference(&f, &f_last), difference(&g, &g_last));
        }
        let next = self.history.extrapolate(&f, &g);
        self.last = Some((f, g));
        next
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Gram matrix kept up to date as differences come and go past the depth is, bit for
    /// bit, the one computed afresh from the differences held.
    #[test]
    fn the_kept_gram_matrix_is_the_fresh_one() {
        let depth = 5;
        let mut history = History::new(depth);
        for k in 0..2 * depth + 3 {
            let df: Vec<f64> = (0..7).map(|i| ((k * 7 + i) as f64 * 0.37).sin()).collect();
            let dg: Vec<f64> = df.iter().map(|x| 2.0 * x).collect();
            history.push(df, dg);
            let d = history.differences.len();
            assert_eq!(d, (k + 1).min(depth));
            for i in 0..d {
                for j in 0..d {
                    let fresh = dot(&history.differences[i].0, &history.differences[j].0);
                    assert_eq!(
                        history.gram[i][j].to_bits(),
                        fresh.to_bits(),
                        "{k}: ({i}, {j})"
                    );
                }
            }
        }
        history.clear();
        assert!(history.differences.is_empty() && history.gram.is_empty());
    }

    /// Histories of one and two differences (the closed form and the 2 × 2 SVD) give the
    /// coefficients of the general SVD solve, to round-off, including two parallel differences
    /// (a Gram matrix of rank one, whose second singular value is dropped).
    #[test]
    fn small_histories_solve_as_the_general_svd_does() {
        let f: Vec<f64> = (0..9).map(|i| (i as f64 * 0.71).cos()).collect();
        let a: Vec<f64> = (0..9).map(|i| (i as f64 * 0.37).sin()).collect();
        let b: Vec<f64> = (0..9).map(|i| (i as f64 * 1.3).sin() - 0.2).collect();
        let parallel: Vec<f64> = a.iter().map(|x| -3.0 * x).collect();
        for differences in [
            vec![a.clone()],
            vec![a.clone(), b],
            vec![a.clone(), parallel],
        ] {
            let mut history = History::new(2);
            for df in &differences {
                history.push(df.clone(), df.clone());
            }
            let d = differences.len();
            let gram = DMatrix::from_fn(d, d, |i, j| history.gram[i][j]);
            let rhs = differences.iter().map(|df| dot(df, &f)).collect();
            let general = solve_gram(gram, rhs).expect("the general solve");
            let small = history.coefficients(&f).expect("the small solve");
            for (s, g) in small.iter().zip(&general) {
                assert!(
                    (s - g).abs() <= 1e-12 * (1.0 + g.abs()),
                    "{d}: {s} against {g}"
                );
            }
        }
    }
}
