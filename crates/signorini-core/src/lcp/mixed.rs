//! The mixed LCP of a step with bilateral and unilateral rows (Siconos' numerics calls it an
//! MLCP): with the first `equalities` rows B free and the rest I complementary,
//!
//! ```text
//! 0 = D_BB z_B + D_BI z_I + b_B,
//! 0 ≤ w_I = D_IB z_B + D_II z_I + b_I ⊥ z_I ≥ 0.
//! ```
//!
//! The equality rows are eliminated by their Schur complement, z_B = −D_BB⁻¹(b_B + D_BI z_I),
//! which leaves the LCP `0 ≤ (D_II − D_IB D_BB⁻¹ D_BI) z_I + b_I − D_IB D_BB⁻¹ b_B ⊥ z_I ≥ 0`
//! for [`super::solve`]. D_BB is factorised by LU when regular; when it is singular because
//! the equality rows are dependent (joints at a singular position, redundant joints: D_BB =
//! G M⁻¹ Gᵀ loses the rank G loses, docs/soi2.md), D_BB⁻¹ is read as the minimum-norm
//! least-squares solve of the rank-revealing factorisation of [`crate::soi2::factor`], which
//! gives the minimum-norm z_B (the redundant part of a joint impulse is not determined by the
//! physics). Nothing else is asked of D beyond what the chosen LCP solver asks of the Schur
//! complement.

use super::{Lcp, LcpError, LcpOptions};
use crate::dense::lu_factor;
use crate::soi2::factor::NewtonFactor;
use nalgebra::{DMatrix, DVector};
use thiserror::Error;

/// A mixed LCP: `d` square of size `b.len()`, its first `equalities` rows the equalities.
#[derive(Debug, Clone, Copy)]
pub struct MixedLcp<'a> {
    /// The matrix D.
    pub d: &'a DMatrix<f64>,
    /// The vector b.
    pub b: &'a [f64],
    /// Number of equality rows (the first ones), 0 ≤ equalities ≤ b.len().
    pub equalities: usize,
}

/// A solution: z = (z_B, z_I) with the diagnostics of the LCP on the complementarity rows.
#[derive(Debug, Clone, PartialEq)]
pub struct MixedSolution {
    /// z_B then z_I.
    pub z: Vec<f64>,
    /// Complementarity rows (the LCP's size; 0 when there are none).
    pub size: usize,
    /// Iterations of the LCP solver.
    pub iterations: usize,
    /// Complementarity error of the LCP solve ([`super`] module documentation).
    pub error: f64,
}

/// Why a mixed LCP failed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MixedLcpError {
    /// D_BB is singular to working precision and not for want of rank of its rows (a NaN, or
    /// a matrix the rank-revealing factorisation finds regular).
    #[error("the block of the {equalities} equality rows is singular")]
    Singular {
        /// Number of equality rows.
        equalities: usize,
    },
    /// The LCP on the complementarity rows failed.
    #[error(transparent)]
    Lcp(#[from] LcpError),
}

/// The equality rows of a [`MixedLcp`] eliminated (module documentation): `y = D_BB⁻¹ b_B`,
/// `x = D_BB⁻¹ D_BI`, and what is left on the other rows, the Schur complement
/// `D_II − D_IB x` and the free vector `b_I − D_IB y`, whatever law those rows obey (the
/// complementarity of [`solve_mixed`], or Coulomb's law when they are a friction problem's
/// normal and tangent rows: the joints condensed out of a step with friction). D_BB⁻¹ is the
/// LU solve, or the minimum-norm least-squares one (D_BB⁺) when the equalities are dependent.
#[derive(Debug, Clone)]
pub struct EqualityElimination {
    /// D_BB⁻¹ b_B (nb).
    y: DVector<f64>,
    /// D_BB⁻¹ D_BI (nb × nu; empty when nu = 0).
    x: DMatrix<f64>,
    /// D_II − D_IB D_BB⁻¹ D_BI (nu × nu).
    pub schur: DMatrix<f64>,
    /// b_I − D_IB D_BB⁻¹ b_B (nu).
    pub free: DVector<f64>,
}

impl EqualityElimination {
    /// Eliminates the first `problem.equalities` rows (at least one) of `problem`; refused
    /// with [`MixedLcpError::Singular`] when D_BB is singular and not for want of rank.
    pub fn new(problem: MixedLcp<'_>) -> Result<Self, MixedLcpError> {
        let MixedLcp { d, b, equalities } = problem;
        let nb = equalities;
        let k = b.len();
        let nu = k - nb;
        let singular = MixedLcpError::Singular { equalities: nb };
        let d_bb = d.view((0, 0), (nb, nb)).into_owned();
        let lu = lu_factor(d_bb.clone());
        // D_BB⁻¹ of the module documentation: LU, or the minimum-norm solve when D_BB is singular.
        let deficient = match lu {
            Some(_) => None,
            // Singular to working precision (lu_factor): the SVD whatever LU's pivot ratio
            // says, unless an entry is not a number.
            None if d_bb.iter().all(|v| v.is_finite()) => {
                Some(NewtonFactor::least_squares(&d_bb)).filter(NewtonFactor::deficient)
            }
            None => None,
        };
        let solve = |rhs: DMatrix<f64>| -> Option<DMatrix<f64>> {
            match (&lu, &deficient) {
                (Some(lu), _) => lu.solve(&rhs),
                (None, Some(factor)) => {
                    let mut x = rhs;
                    for mut column in x.column_iter_mut() {
                        let mut c = column.clone_owned();
                        if !factor.solve_mut(&mut c) {
                            return None;
                        }
                        column.copy_from(&c);
                    }
                    Some(x)
                }
                (None, None) => None,
            }
        };
        let b_b = DMatrix::from_column_slice(nb, 1, &b[..nb]);
        let y = DVector::from_column_slice(solve(b_b).ok_or(singular.clone())?.as_slice());
        if nu == 0 {
            return Ok(Self {
                y,
                x: DMatrix::zeros(nb, 0),
                schur: DMatrix::zeros(0, 0),
                free: DVector::zeros(0),
            });
        }
        let d_bi = d.view((0, nb), (nb, nu)).into_owned();
        let x = solve(d_bi).ok_or(singular)?;
        let d_ib = d.view((nb, 0), (nu, nb));
        let schur = d.view((nb, nb), (nu, nu)) - d_ib * &x;
        let free = DVector::from_column_slice(&b[nb..]) - d_ib * &y;
        Ok(Self { y, x, schur, free })
    }

    /// The equality rows' unknowns z_B = −(y + x z_I) for the other rows' z_I.
    pub fn equality_part(&self, z_i: &[f64]) -> Vec<f64> {
        if z_i.is_empty() {
            return (-&self.y).as_slice().to_vec();
        }
        let z_i = DVector::from_column_slice(z_i);
        (-(&self.y + &self.x * &z_i)).as_slice().to_vec()
    }
}

/// Solves `problem` (module documentation) with the LCP solver of `options`.
pub fn solve_mixed(
    problem: MixedLcp<'_>,
    options: &LcpOptions,
) -> Result<MixedSolution, MixedLcpError> {
    let MixedLcp { d, b, equalities } = problem;
    let nb = equalities;
    let k = b.len();
    let nu = k - nb;
    if nb == 0 {
        let data: Vec<f64> = (0..k * k).map(|r| d[(r / k, r % k)]).collect();
        let sol = super::solve(Lcp { m: &data, q: b }, options)?;
        return Ok(MixedSolution {
            z: sol.z,
            size: k,
            iterations: sol.iterations,
            error: sol.error,
        });
    }
    let elimination = EqualityElimination::new(problem)?;
    if nu == 0 {
        return Ok(MixedSolution {
            z: elimination.equality_part(&[]),
            size: 0,
            iterations: 0,
            error: 0.0,
        });
    }
    let schur = &elimination.schur;
    let data: Vec<f64> = (0..nu * nu).map(|r| schur[(r / nu, r % nu)]).collect();
    let sol = super::solve(
        Lcp {
            m: &data,
            q: elimination.free.as_slice(),
        },
        options,
    )?;
    let mut z = elimination.equality_part(&sol.z);
    z.extend_from_slice(&sol.z);
    Ok(MixedSolution {
        z,
        size: nu,
        iterations: sol.iterations,
        error: sol.error,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One equality and one unilateral row, solved by hand: D = [[2, 1], [1, 2]], b = (−1, −3).
    /// Elimination: z_B = (1 − z_I)/2; the Schur complement is 2 − ½ = 3/2 and its right-hand
    /// side −3 + ½ = −5/2, so z_I = 5/3 > 0 with w_I = 0, and z_B = −1/3.
    #[test]
    fn one_equality_and_one_active_contact() {
        let d = DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0, 2.0]);
        let sol = solve_mixed(
            MixedLcp {
                d: &d,
                b: &[-1.0, -3.0],
                equalities: 1,
            },
            &LcpOptions::default(),
        )
        .unwrap();
        assert!((sol.z[0] + 1.0 / 3.0).abs() < 1e-14, "{:?}", sol.z);
        assert!((sol.z[1] - 5.0 / 3.0).abs() < 1e-14, "{:?}", sol.z);
        assert_eq!(sol.size, 1);
        // Both rows hold: the equality to round-off, the contact with w_I = 0.
        let w0 = 2.0 * sol.z[0] + sol.z[1] - 1.0;
        let w1 = sol.z[0] + 2.0 * sol.z[1] - 3.0;
        assert!(w0.abs() < 1e-14 && w1.abs() < 1e-14, "{w0} {w1}");
    }

    /// The same rows with b_I ≥ 0 after elimination: the contact stays open (z_I = 0) and the
    /// equality alone fixes z_B = −b_B / D_BB.
    #[test]
    fn an_open_contact_leaves_the_equality_alone() {
        let d = DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0, 2.0]);
        let sol = solve_mixed(
            MixedLcp {
                d: &d,
                b: &[-1.0, 3.0],
                equalities: 1,
            },
            &LcpOptions::default(),
        )
        .unwrap();
        assert_eq!(sol.z, vec![0.5, 0.0]);
    }

    /// Dependent equality rows (a joint written twice: D_BB of rank 1) are not an error: the
    /// minimum-norm z_B, here z₁ = z₂ = −½ for z₁ + z₂ = −1 written twice. A D_BB that is not
    /// a number is still refused.
    #[test]
    fn dependent_equalities_get_the_minimum_norm_solution() {
        let d = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0]);
        let sol = solve_mixed(
            MixedLcp {
                d: &d,
                b: &[1.0, 1.0],
                equalities: 2,
            },
            &LcpOptions::default(),
        )
        .unwrap();
        for z in &sol.z {
            assert!((z + 0.5).abs() <= 1e-15, "{:?}", sol.z);
        }
        let nan = DMatrix::from_row_slice(2, 2, &[f64::NAN, 1.0, 1.0, 1.0]);
        let err = solve_mixed(
            MixedLcp {
                d: &nan,
                b: &[1.0, 1.0],
                equalities: 2,
            },
            &LcpOptions::default(),
        )
        .unwrap_err();
        assert_eq!(err, MixedLcpError::Singular { equalities: 2 });
    }
}
