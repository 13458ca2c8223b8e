//! The start of a user model moved onto its joints (`model.project_onto_joints`): q0 by Newton's
//! method on the constraint manifold g(q, 0) = 0 with minimum-norm steps, then v0 onto the
//! tangent space g_q v + g_t = 0 by the minimum-norm change.
//!
//! Each Newton step solves the underdetermined linearisation g(q) + g_q(q) Δq = 0 for the Δq of
//! least Euclidean norm, Δq = −g_q⁺ g (the Moore–Penrose pseudo-inverse, from the SVD of g_q, so
//! dependent joints are handled too): the Gauss–Newton projection onto the manifold. The
//! velocity is then moved by Δv = −g_q⁺ (g_q v0 + g_t), the orthogonal projection of v0 onto
//! the affine tangent space at the projected q.

use crate::expr::Expr;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;
use thiserror::Error;

/// Newton iterations allowed before the projection is refused.
pub const PROJECTION_ITERATIONS: usize = 50;

/// Relative cut-off of the singular values of g_q in the pseudo-inverse.
const RANK_CUTOFF: f64 = 1e-10;

/// A start moved onto the joints, as reported in the summary (`start_projection`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StartProjection {
    /// q0 as given (numbers or expressions of the parameters, evaluated).
    pub q0_given: Vec<f64>,
    /// q0 on the joints: what the run starts from.
    pub q0: Vec<f64>,
    /// v0 as given.
    pub v0_given: Vec<f64>,
    /// v0 on the tangent space of the joints at q0: what the run starts from.
    pub v0: Vec<f64>,
    /// Newton iterations on the positions.
    pub newton_iterations: usize,
    /// max_i |g_i(q0_given, 0)|.
    pub joint_residual_given: f64,
    /// max_i |g_i(q0, 0)| after the projection.
    pub joint_residual: f64,
    /// max_i |(g_q v + g_t)_i| at (q0, v0_given): the velocity residual before its projection.
    pub velocity_residual_given: f64,
    /// ‖q0 − q0_given‖₂.
    pub position_change: f64,
    /// ‖v0 − v0_given‖₂.
    pub velocity_change: f64,
}

/// Why a start could not be moved onto the joints.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ProjectionError {
    /// Newton did not bring every joint within the tolerance.
    #[error(
        "q0 could not be projected onto the joints: after {iterations} Newton iterations this joint is still {residual:e} (tolerance {tolerance:e}); the joints may have no solution near q0 — give a q0 closer to them"
    )]
    NotConverged {
        /// The joint with the largest residual.
        joint: usize,
        /// Its residual.
        residual: f64,
        /// Newton iterations done.
        iterations: usize,
        /// The tolerance it had to reach.
        tolerance: f64,
    },
    /// g_q or g_t is not finite at the projected q0, so v0 cannot be projected.
    #[error(
        "the joints' Jacobian or time derivative is not finite at the projected q0 {q0:?}: v0 cannot be projected onto them"
    )]
    NotFinite {
        /// The joint named in the refusal (the first one).
        joint: usize,
        /// The projected q0.
        q0: Vec<f64>,
    },
}

impl ProjectionError {
    /// The joint the refusal names.
    pub fn joint(&self) -> usize {
        match self {
            ProjectionError::NotConverged { joint, .. }
            | ProjectionError::NotFinite { joint, .. } => *joint,
        }
    }
}

/// The joints with their exact derivatives, evaluated at (q, v, t = 0) by walking the trees
/// (validation only: a run compiles tapes).
struct Joints<'a> {
    joints: &'a [Expr],
    n: usize,
    /// ∂g_i/∂q_k, row-major joints×n.
    jacobian: Vec<Expr>,
    /// ∂g_i/∂t.
    rates: Vec<Expr>,
}

impl Joints<'_> {
    fn vars(&self, q: &[f64], v: &[f64]) -> Vec<f64> {
        let mut x = q.to_vec();
        x.extend_from_slice(v);
        x.push(0.0);
        x
    }

    fn residual(&self, q: &[f64]) -> DVector<f64> {
        let x = self.vars(q, &vec![0.0; self.n]);
        DVector::from_iterator(self.joints.len(), self.joints.iter().map(|g| g.eval(&x)))
    }

    fn jacobian(&self, q: &[f64]) -> DMatrix<f64> {
        let x = self.vars(q, &vec![0.0; self.n]);
        DMatrix::from_row_iterator(
            self.joints.len(),
            self.n,
            self.jacobian.iter().map(|d| d.eval(&x)),
        )
    }

    fn time_rates(&self, q: &[f64]) -> DVector<f64> {
        let x = self.vars(q, &vec![0.0; self.n]);
        DVector::from_iterator(self.rates.len(), self.rates.iter().map(|d| d.eval(&x)))
    }
}

/// The minimum-norm solution x of G x = b (least squares when G is rank-deficient); `None`
/// when G holds a NaN or an infinity.
fn min_norm_solve(g: DMatrix<f64>, b: &DVector<f64>) -> Option<DVector<f64>> {
    if g.iter().chain(b.iter()).any(|x| !x.is_finite()) {
        return None;
    }
    let svd = g.svd(true, true);
    let cutoff = RANK_CUTOFF * svd.singular_values.max();
    svd.solve(b, cutoff).ok()
}

fn largest(r: &DVector<f64>) -> (usize, f64) {
    r.iter().enumerate().fold((0, 0.0), |(i, m), (j, x)| {
        // A NaN counts as the largest.
        if x.abs() > m || (x.is_nan() && !m.is_nan()) {
            (j, x.abs())
        } else {
            (i, m)
        }
    })
}

/// Moves (q0, v0) onto the `joints` g(q, t) (expressions over the variables (q, q̇, t) of a
/// model with n coordinates, no velocities): Newton's minimum-norm steps until every |g_i| ≤
/// 10⁻⁴ `tolerance` (at most [`PROJECTION_ITERATIONS`]), accepted when every |g_i| ≤
/// `tolerance`, then v0 projected onto g_q v + g_t = 0 at the new q0.
pub fn project_start(
    joints: &[Expr],
    n: usize,
    q0: &[f64],
    v0: &[f64],
    tolerance: f64,
) -> Result<StartProjection, ProjectionError> {
    let q: Vec<usize> = (0..n).collect();
    let system = Joints {
        joints,
        n,
        jacobian: joints.iter().flat_map(|g| g.gradient(&q)).collect(),
        rates: joints.iter().map(|g| g.derivative(2 * n)).collect(),
    };
    let given = system.residual(q0);
    let mut position = DVector::from_column_slice(q0);
    let mut residual = given.clone();
    let mut iterations = 0;
    while largest(&residual).1 > 1e-4 * tolerance && iterations < PROJECTION_ITERATIONS {
        let Some(step) = min_norm_solve(system.jacobian(position.as_slice()), &residual) else {
            break;
        };
        position -= step;
        iterations += 1;
        residual = system.residual(position.as_slice());
    }
    let (joint, worst) = largest(&residual);
    if worst.is_nan() || worst > tolerance {
        return Err(ProjectionError::NotConverged {
            joint,
            residual: residual[joint],
            iterations,
            tolerance,
        });
    }
    let jacobian = system.jacobian(position.as_slice());
    let velocity = DVector::from_column_slice(v0);
    let velocity_residual = &jacobian * &velocity + system.time_rates(position.as_slice());
    let change =
        min_norm_solve(jacobian, &velocity_residual).ok_or_else(|| ProjectionError::NotFinite {
            joint: 0,
            q0: position.as_slice().to_vec(),
        })?;
    let projected = &velocity - &change;
    Ok(StartProjection {
        q0_given: q0.to_vec(),
        q0: position.as_slice().to_vec(),
        v0_given: v0.to_vec(),
        v0: projected.as_slice().to_vec(),
        newton_iterations: iterations,
        joint_residual_given: largest(&given).1,
        joint_residual: worst,
        velocity_residual_given: largest(&velocity_residual).1,
        position_change: (position - DVector::from_column_slice(q0)).norm(),
        velocity_change: change.norm(),
    })
}
