//! Small dense linear algebra shared by the schemes that assemble their matrices densely (the
//! nonlinear Moreau–Jean and nonsmooth generalized-α schemes, the mixed LCP): row-major dot
//! products, an LU factorisation that refuses a matrix singular
//! to working precision, and singular values that refuse a matrix holding a NaN.

use nalgebra::{DMatrix, DVector, Dyn, LU};

/// The singular values of `a`, or `None` when an entry is not finite: nalgebra sorts them
/// and panics on a NaN ("Singular value was NaN"), which a user's constraint can produce at a
/// point where its expression is undefined.
pub fn singular_values(a: DMatrix<f64>) -> Option<DVector<f64>> {
    a.iter().all(|x| x.is_finite()).then(|| a.singular_values())
}

/// Σ aᵢ bᵢ, summed in index order.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// ‖x‖_∞ (0 for an empty vector).
pub fn amax(x: &[f64]) -> f64 {
    x.iter().fold(0.0f64, |m, v| m.max(v.abs()))
}

/// LU factors of `w` (partial pivoting), or `None` when `w` is singular to working precision:
/// a pivot |U_jj| ≤ n ε max_i |w_ij| (relative to its own column of `w`, so that scaling a
/// coordinate, e.g. a mass of 1e-7 next to one of 1e3, does not make `w` look singular), or a
/// pivot that is not finite.
pub fn lu_factor(w: DMatrix<f64>) -> Option<LU<f64, Dyn, Dyn>> {
    lu_factor_with(w, &mut Vec::new())
}

/// [`lu_factor`] with the column maxima of `w` kept in `column_max`, a buffer the caller keeps
/// from one factorisation to the next (a scheme factorising at every Newton iterate).
pub fn lu_factor_with(w: DMatrix<f64>, column_max: &mut Vec<f64>) -> Option<LU<f64, Dyn, Dyn>> {
    let n = w.nrows();
    column_max.clear();
    column_max.extend(w.column_iter().map(|c| c.amax()));
    let lu = w.lu();
    // U's diagonal read in place: `LU::u()` would copy the whole upper triangle, a matrix
    // allocated per factorisation (per Newton iterate of the nonlinear schemes).
    let factors = lu.lu_internal();
    let singular = (0..n).any(|j| negligible_pivot(factors[(j, j)], n, column_max[j]));
    (!singular).then_some(lu)
}

/// Whether the pivot `p` of an n×n LU factorisation is negligible against the largest entry
/// `column_max` of its column: |p| ≤ n ε column_max, or not finite.
pub fn negligible_pivot(p: f64, n: usize, column_max: f64) -> bool {
    let p = p.abs();
    !p.is_finite() || p <= n as f64 * f64::EPSILON * column_max
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dot_and_max_norm() {
        assert_eq!(dot(&[1.0, 2.0, 3.0], &[4.0, -5.0, 6.0]), 12.0);
        assert_eq!(amax(&[1.0, -7.5, 3.0]), 7.5);
    }

    #[test]
    fn lu_factor_refuses_a_singular_matrix_relative_to_its_columns() {
        let singular = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 4.0]);
        assert!(lu_factor(singular).is_none());
        // Columns of very different scales, well conditioned once scaled: accepted, and solved.
        let scaled = DMatrix::from_row_slice(2, 2, &[1e-7, 0.0, 1e-7, 1e3]);
        let lu = lu_factor(scaled).expect("regular");
        let x = lu
            .solve(&nalgebra::DVector::from_column_slice(&[1e-7, 1e3 + 1e-7]))
            .expect("solved");
        assert!((x[0] - 1.0).abs() < 1e-12 && (x[1] - 1.0).abs() < 1e-12);
        assert!(lu_factor(DMatrix::from_row_slice(1, 1, &[f64::NAN])).is_none());
    }
}
