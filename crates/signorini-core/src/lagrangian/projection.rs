//! The start of a user model moved onto its joints (`model.project_onto_joints`): q0 to the
//! nearest point of the constraint manifold g(q, 0) = 0 in the kinetic-energy metric, then v0
//! onto the tangent space g_q v + g_t = 0 by the velocity change of least kinetic energy.
//!
//! **Positions.** With M₀ = M(q0) at the given q0 (a fixed metric, so that radians and metres
//! are weighed by the inertia they move), the projected start is
//!
//! q* = argmin ½ (q − q0)ᵀ M₀ (q − q0)  subject to  g(q, 0) = 0,
//!
//! whose first-order conditions are M₀ (q* − q0) = g_q(q*)ᵀ λ and g(q*, 0) = 0. Each iterate
//! linearises the joints at q_k and measures the change from q0, not from q_k:
//!
//! q_{k+1} = q0 + d_k,  d_k = argmin ‖d‖_{M₀} subject to g(q_k) + g_q(q_k) (q0 + d_k − q_k) = 0,
//!
//! i.e. d_k = M₀⁻¹ G_kᵀ (G_k M₀⁻¹ G_kᵀ)⁺ (G_k (q_k − q0) − g(q_k)) with G_k = g_q(q_k). A fixed
//! point satisfies both conditions above (d = M₀⁻¹ Gᵀλ and g = 0): it is a stationary point of
//! the projection problem, not only some point on the manifold. For joints linear in q the first
//! iterate is already the closed form q0 − M₀⁻¹ aᵀ (a M₀⁻¹ aᵀ)⁻¹ g(q0). It is the Gauss–Newton
//! (constraint-curvature-free SQP) iteration of the problem: linear convergence at a rate of the
//! order of the curvature of the joints times the distance to them.
//!
//! **Velocities.** With M* = M(q*) at the projected start,
//!
//! v* = v0 + Δv,  Δv = argmin ½ Δvᵀ M* Δv subject to g_q(q*) (v0 + Δv) + g_t(q*, 0) = 0,
//!
//! Δv = −M*⁻¹ Gᵀ (G M*⁻¹ Gᵀ)⁺ (G v0 + g_t): the velocity after an impulsive enforcement of the
//! joints, M* Δv = Gᵀ P, as a perfectly inelastic joint would give.
//!
//! Every weighted solve goes through the Cholesky factor M = L Lᵀ: with y = Lᵀ d the problem is
//! the Euclidean minimum-norm one for the matrix G L⁻ᵀ, solved through its SVD (the Moore–Penrose
//! pseudo-inverse, so dependent joints are handled too).

use crate::expr::Expr;
use nalgebra::{Cholesky, DMatrix, DVector, Dyn};
use serde::Serialize;
use thiserror::Error;

/// Iterations allowed before the projection stops (and is refused if the joints are not met).
pub const PROJECTION_ITERATIONS: usize = 100;

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
    /// √((q0 − q0_given)ᵀ M(q0_given) (q0 − q0_given)): the norm the projection minimises.
    pub position_change_mass_norm: f64,
    /// √((v0 − v0_given)ᵀ M(q0) (v0 − v0_given)) at the projected q0: twice the kinetic energy
    /// of the velocity change, square-rooted; the norm the velocity projection minimises.
    pub velocity_change_mass_norm: f64,
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
    /// M is not positive definite (or not finite) where the projection needs it as a metric.
    #[error(
        "M is not positive definite at {at} {q:?}: the projection onto the joints measures changes in the M norm"
    )]
    MassNotPositiveDefinite {
        /// "the given q0" or "the projected q0".
        at: &'static str,
        /// Where M was evaluated.
        q: Vec<f64>,
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
    /// The spec field the refusal names: the worst joint's `model.constraints[i].expr`, or
    /// `model.mass`.
    pub fn field(&self) -> String {
        match self {
            ProjectionError::NotConverged { joint, .. }
            | ProjectionError::NotFinite { joint, .. } => {
                format!("model.constraints[{joint}].expr")
            }
            ProjectionError::MassNotPositiveDefinite { .. } => "model.mass".to_string(),
        }
    }
}

/// The joints with their exact derivatives and the mass matrix, evaluated at (q, v = 0,
/// t = 0) by walking the trees (validation only: a run compiles tapes).
struct Joints<'a> {
    joints: &'a [Expr],
    /// The upper triangle of M(q), (i ≤ j, M_ij).
    mass: &'a [(usize, usize, Expr)],
    n: usize,
    /// ∂g_i/∂q_k, row-major joints×n.
    jacobian: Vec<Expr>,
    /// ∂g_i/∂t.
    rates: Vec<Expr>,
}

impl Joints<'_> {
    fn vars(&self, q: &[f64]) -> Vec<f64> {
        let mut x = q.to_vec();
        x.resize(2 * self.n + 1, 0.0);
        x
    }

    fn residual(&self, q: &[f64]) -> DVector<f64> {
        let x = self.vars(q);
        DVector::from_iterator(self.joints.len(), self.joints.iter().map(|g| g.eval(&x)))
    }

    fn jacobian(&self, q: &[f64]) -> DMatrix<f64> {
        let x = self.vars(q);
        DMatrix::from_row_iterator(
            self.joints.len(),
            self.n,
            self.jacobian.iter().map(|d| d.eval(&x)),
        )
    }

    fn time_rates(&self, q: &[f64]) -> DVector<f64> {
        let x = self.vars(q);
        DVector::from_iterator(self.rates.len(), self.rates.iter().map(|d| d.eval(&x)))
    }

    /// The Cholesky factor of M(q), `None` when M is not finite or not positive definite there.
    fn metric(&self, q: &[f64]) -> Option<Cholesky<f64, Dyn>> {
        let x = self.vars(q);
        let mut m = DMatrix::zeros(self.n, self.n);
        for (i, j, e) in self.mass {
            let value = e.eval(&x);
            m[(*i, *j)] = value;
            m[(*j, *i)] = value;
        }
        if m.iter().any(|x| !x.is_finite()) {
            return None;
        }
        m.cholesky()
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

/// The x of least M-norm √(xᵀ M x) with G x = b (least squares in that norm when G is
/// rank-deficient), M = L Lᵀ: x = L⁻ᵀ (G L⁻ᵀ)⁺ b. `None` when G or b is not finite.
fn weighted_min_norm_solve(
    g: &DMatrix<f64>,
    metric: &Cholesky<f64, Dyn>,
    b: &DVector<f64>,
) -> Option<DVector<f64>> {
    let l = metric.l();
    // (G L⁻ᵀ)ᵀ = L⁻¹ Gᵀ.
    let scaled = l.solve_lower_triangular(&g.transpose())?.transpose();
    let y = min_norm_solve(scaled, b)?;
    l.transpose().solve_upper_triangular(&y)
}

/// √(xᵀ M x) for M = L Lᵀ: ‖Lᵀ x‖₂.
fn mass_norm(metric: &Cholesky<f64, Dyn>, x: &DVector<f64>) -> f64 {
    (metric.l().transpose() * x).norm()
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

/// The projected positions q* (module doc): iterates q_{k+1} = q0 + d_k until every |g_i| ≤
/// 10⁻⁴ `tolerance` and the next iterate moves by at most 10⁻⁶ `tolerance` (∞-norm), at most
/// [`PROJECTION_ITERATIONS`] times; refused unless every |g_i| ≤ `tolerance` at the end.
/// Returns q* and the iterations taken.
fn project_positions(
    system: &Joints<'_>,
    metric: &Cholesky<f64, Dyn>,
    q0: &DVector<f64>,
    tolerance: f64,
) -> Result<(DVector<f64>, usize), ProjectionError> {
    let mut position = q0.clone();
    let mut iterations = 0;
    let mut residual = system.residual(position.as_slice());
    while iterations < PROJECTION_ITERATIONS {
        let jacobian = system.jacobian(position.as_slice());
        // G_k d = G_k (q_k − q0) − g(q_k).
        let rhs = &jacobian * (&position - q0) - &residual;
        let Some(change) = weighted_min_norm_solve(&jacobian, metric, &rhs) else {
            break;
        };
        let next = q0 + change;
        let moved = (&next - &position).amax();
        position = next;
        if largest(&residual).1 <= 1e-4 * tolerance && moved <= 1e-6 * tolerance {
            // On the joints and stationary: the last move, below the tolerance, is kept
            // and not counted.
            break;
        }
        iterations += 1;
        residual = system.residual(position.as_slice());
    }
    let residual = system.residual(position.as_slice());
    let (joint, worst) = largest(&residual);
    if worst.is_nan() || worst > tolerance {
        return Err(ProjectionError::NotConverged {
            joint,
            residual: residual[joint],
            iterations,
            tolerance,
        });
    }
    Ok((position, iterations))
}

/// Moves (q0, v0) onto the `joints` g(q, t) (expressions over the variables (q, q̇, t) of a
/// model with n coordinates, no velocities) of a model with mass matrix M(q) (`mass`, its upper
/// triangle): q0 to the joints' point nearest in the M(q0) norm, then v0 to the tangent space
/// g_q v + g_t = 0 by the change of least kinetic energy at the new q0 (module doc, with the
/// formulas). Refused when M is not positive definite at either q0, or when the joints are not
/// met to `tolerance` after [`PROJECTION_ITERATIONS`] iterations.
pub fn project_start(
    joints: &[Expr],
    mass: &[(usize, usize, Expr)],
    n: usize,
    q0: &[f64],
    v0: &[f64],
    tolerance: f64,
) -> Result<StartProjection, ProjectionError> {
    let q: Vec<usize> = (0..n).collect();
    let system = Joints {
        joints,
        mass,
        n,
        jacobian: joints.iter().flat_map(|g| g.gradient(&q)).collect(),
        rates: joints.iter().map(|g| g.derivative(2 * n)).collect(),
    };
    let not_definite =
        |at, q: &[f64]| ProjectionError::MassNotPositiveDefinite { at, q: q.to_vec() };
    let given = system.residual(q0);
    let start_metric = system
        .metric(q0)
        .ok_or_else(|| not_definite("the given q0", q0))?;
    let q_given = DVector::from_column_slice(q0);
    let (position, iterations) = project_positions(&system, &start_metric, &q_given, tolerance)?;
    let worst = largest(&system.residual(position.as_slice())).1;
    let metric = system
        .metric(position.as_slice())
        .ok_or_else(|| not_definite("the projected q0", position.as_slice()))?;
    let jacobian = system.jacobian(position.as_slice());
    let velocity = DVector::from_column_slice(v0);
    let velocity_residual = &jacobian * &velocity + system.time_rates(position.as_slice());
    let change =
        weighted_min_norm_solve(&jacobian, &metric, &velocity_residual).ok_or_else(|| {
            ProjectionError::NotFinite {
                joint: 0,
                q0: position.as_slice().to_vec(),
            }
        })?;
    let projected = &velocity - &change;
    let moved = &position - &q_given;
    Ok(StartProjection {
        q0_given: q0.to_vec(),
        q0: position.as_slice().to_vec(),
        v0_given: v0.to_vec(),
        v0: projected.as_slice().to_vec(),
        newton_iterations: iterations,
        joint_residual_given: largest(&given).1,
        joint_residual: worst,
        velocity_residual_given: largest(&velocity_residual).1,
        position_change: moved.norm(),
        velocity_change: change.norm(),
        position_change_mass_norm: mass_norm(&start_metric, &moved),
        velocity_change_mass_norm: mass_norm(&metric, &change),
    })
}
