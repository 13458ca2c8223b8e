//! Nonlinear constrained mechanical systems and the generalized-α-SOI2 family of Jay & Negrut
//! (2008), "A second order extension of the generalized-α method for constrained systems in
//! mechanics" (`papers/jay-negrut-generalized-alpha-soi2.md`). Equation numbers refer to it.
//!
//! The systems are the overdetermined index-2 DAEs (11):
//!
//! ```text
//! y' = z,  M(t, y) z' = f(t, y, z, λ, ψ),  0 = g(t, y),  0 = g_t + g_y z,  0 = k(t, y, z)   (11a–e)
//! ```
//!
//! * [`ConstrainedModel`] is the model interface: M, f, g, k, written once for any scalar type
//!   ([`Scalar`]), so that every Jacobian the Newton iterations need comes from forward-mode
//!   automatic differentiation (`num-dual`'s [`Dual`] numbers). g_y, g_t + g_y z and k_z have
//!   AD defaults; a model may give them in closed form instead.
//! * [`method`]: one step of generalized-α-SOI2 (13a)–(13i), its additive-force form, HHT-SOI2
//!   (17), the HHT-I3 baseline, start values of a_α, and the step-size adjustments (14a)–(14b).
//! * [`models`]: the test problem (15) with its exact solution, the pendulum (16) of Fig. 3, and a
//!   slider-crank.
//! * [`factor`]: Newton's matrix factorised by LU, or by SVD (minimum-norm solve) when the
//!   constraint Jacobian has lost rank.
//! * [`banded`]: the band order (reverse Cuthill–McKee) and band LU of a large mechanism's
//!   Newton matrix.
//! * [`sparsity`]: which coordinates each equation touches, and the groups of columns that
//!   build a sparse Newton matrix from a few dual evaluations.
//! * `stored_factor`: Newton's factorisations read back from a checkpoint, checked before a
//!   solve follows their indices.
//! * [`run`]: the time loop over a step-size pattern, with energy and constraint streams.

pub mod banded;
pub mod factor;
mod jacobian;
pub mod method;
pub mod models;
pub mod run;
pub mod sparsity;
mod stored_factor;

use nalgebra::{DMatrix, DVector};
pub use num_dual::{Dual, Dual64, DualNum};
use thiserror::Error;

/// A real scalar the model functions are written for: `f64`, or a (nested) dual number that
/// carries derivatives along.
pub trait Scalar: DualNum<Primitive = f64> + Copy {}
impl<T: DualNum<Primitive = f64> + Copy> Scalar for T {}

/// Sizes of a constrained model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Dims {
    /// Generalized coordinates n (= size of y, z, a).
    pub n: usize,
    /// Holonomic constraints m_g (= size of g and λ).
    pub holonomic: usize,
    /// Nonholonomic constraints m_k (= size of k and ψ).
    pub nonholonomic: usize,
}

/// Initial values at t₀: y₀ and z₀ must be consistent; λ₀, ψ₀ are first guesses that the
/// consistent-acceleration solve ([`method::consistent_acceleration`]) refines.
#[derive(Debug, Clone, PartialEq)]
pub struct InitialValues {
    /// t₀.
    pub t: f64,
    /// y₀.
    pub y: Vec<f64>,
    /// z₀.
    pub z: Vec<f64>,
    /// Guess of λ₀.
    pub lambda: Vec<f64>,
    /// Guess of ψ₀.
    pub psi: Vec<f64>,
}

/// An exact solution at one time.
#[derive(Debug, Clone, PartialEq)]
pub struct ExactValues {
    /// y(t).
    pub y: Vec<f64>,
    /// z(t).
    pub z: Vec<f64>,
    /// a(t) = z'(t).
    pub a: Vec<f64>,
    /// λ(t).
    pub lambda: Vec<f64>,
    /// ψ(t).
    pub psi: Vec<f64>,
}

/// The terms of a step's residual at its new state ([`ConstrainedModel::state_terms`]).
#[derive(Debug, Clone, PartialEq)]
pub struct StateTerms<T> {
    /// f(t, y, z, λ_k, ψ_k) for each multiplier set asked for, n entries each.
    pub forces: Vec<Vec<T>>,
    /// g(t, y), m_g entries (11c).
    pub g: Vec<T>,
    /// g_t + g_y z, m_g entries (11d).
    pub g_dot: Vec<T>,
    /// g_y's structural nonzeros (row, column, value) when asked for, else empty.
    pub g_y: Vec<(usize, usize, T)>,
}

/// A nonlinear constrained mechanical system (11). Matrices are row-major slices.
///
/// Every function is generic in the scalar so that Newton's Jacobians come from forward-mode AD.
pub trait ConstrainedModel {
    /// Sizes.
    fn dims(&self) -> Dims;

    /// Mass matrix M(t, y), n×n row-major, nonsingular.
    fn mass<T: Scalar>(&self, t: T, y: &[T], m: &mut [T]);

    /// M(t, y) as its structural nonzeros (row, column, value) in row-major order, appended
    /// to `out`: what the schemes multiply with. Default: the nonzero entries of
    /// [`Self::mass`] (an n×n array per call, which a large model overrides).
    fn mass_entries_at(&self, t: f64, y: &[f64], out: &mut Vec<(usize, usize, f64)>) {
        let n = y.len();
        let mut m = vec![0.0; n * n];
        self.mass(t, y, &mut m);
        out.extend(
            m.into_iter()
                .enumerate()
                .filter(|&(_, v)| v != 0.0)
                .map(|(k, v)| (k / n, k % n, v)),
        );
    }

    /// Forces f(t, y, z, λ, ψ), n entries (reaction forces included).
    fn force<T: Scalar>(&self, t: T, y: &[T], z: &[T], lambda: &[T], psi: &[T], f: &mut [T]);

    /// Holonomic constraints g(t, y), m_g entries (11c). Default: none.
    fn g<T: Scalar>(&self, t: T, y: &[T], out: &mut [T]) {
        let _ = (t, y, out);
    }

    /// g_y(t, y), m_g×n row-major. Default: forward-mode AD of [`Self::g`].
    fn g_y<T: Scalar>(&self, t: T, y: &[T], out: &mut [T]) {
        let (n, m) = (y.len(), self.dims().holonomic);
        let td = Dual::from_re(t);
        let mut yd: Vec<Dual<T>> = y.iter().map(|&v| Dual::from_re(v)).collect();
        let mut gd = vec![Dual::from_re(T::zero()); m];
        for j in 0..n {
            yd[j].eps = T::one();
            self.g(td, &yd, &mut gd);
            for i in 0..m {
                out[i * n + j] = gd[i].eps;
            }
            yd[j].eps = T::zero();
        }
    }

    /// g_y(t, y) as its structural nonzeros (row, column, value), appended to `out`: what the
    /// schemes multiply with. Default: every entry of [`Self::g_y`].
    fn g_y_entries<T: Scalar>(&self, t: T, y: &[T], out: &mut Vec<(usize, usize, T)>) {
        let (n, m) = (y.len(), self.dims().holonomic);
        let mut g = vec![T::zero(); m * n];
        self.g_y(t, y, &mut g);
        out.extend(g.into_iter().enumerate().map(|(k, v)| (k / n, k % n, v)));
    }

    /// Velocity constraints g_t(t, y) + g_y(t, y) z (11d). Default: the derivative of g along
    /// (1, z) by forward-mode AD.
    fn g_dot<T: Scalar>(&self, t: T, y: &[T], z: &[T], out: &mut [T]) {
        let m = self.dims().holonomic;
        let td = Dual::new(t, T::one());
        let yd: Vec<Dual<T>> = y.iter().zip(z).map(|(&v, &w)| Dual::new(v, w)).collect();
        let mut gd = vec![Dual::from_re(T::zero()); m];
        self.g(td, &yd, &mut gd);
        for (o, v) in out.iter_mut().zip(&gd) {
            *o = v.eps;
        }
    }

    /// At one (t, y, z): f(t, y, z, λ_k, ψ_k) for each (λ_k, ψ_k) of `multipliers`, g(t, y),
    /// g_t + g_y z and, when `with_g_y`, g_y's entries: the terms a step's residual takes at its
    /// new state, asked for at once so that a model can share their work (a `lagrangian`
    /// model runs one tape, which computes the sines and cosines of y once instead of once per
    /// term). Default: [`Self::force`], [`Self::g`], [`Self::g_dot`], [`Self::g_y_entries`].
    fn state_terms<T: Scalar>(
        &self,
        t: T,
        (y, z): (&[T], &[T]),
        multipliers: &[(&[T], &[T])],
        with_g_y: bool,
    ) -> StateTerms<T> {
        let m = self.dims().holonomic;
        let forces = multipliers
            .iter()
            .map(|(lambda, psi)| {
                let mut f = vec![T::zero(); y.len()];
                self.force(t, y, z, lambda, psi, &mut f);
                f
            })
            .collect();
        let mut terms = StateTerms {
            forces,
            g: vec![T::zero(); m],
            g_dot: vec![T::zero(); m],
            g_y: Vec::new(),
        };
        self.g(t, y, &mut terms.g);
        self.g_dot(t, y, z, &mut terms.g_dot);
        if with_g_y {
            self.g_y_entries(t, y, &mut terms.g_y);
        }
        terms
    }

    /// Nonholonomic constraints k(t, y, z), m_k entries (11e). Default: none.
    fn k<T: Scalar>(&self, t: T, y: &[T], z: &[T], out: &mut [T]) {
        let _ = (t, y, z, out);
    }

    /// k_z(t, y, z), m_k×n row-major. Default: forward-mode AD of [`Self::k`].
    fn k_z<T: Scalar>(&self, t: T, y: &[T], z: &[T], out: &mut [T]) {
        let (n, m) = (y.len(), self.dims().nonholonomic);
        let td = Dual::from_re(t);
        let yd: Vec<Dual<T>> = y.iter().map(|&v| Dual::from_re(v)).collect();
        let mut zd: Vec<Dual<T>> = z.iter().map(|&v| Dual::from_re(v)).collect();
        let mut kd = vec![Dual::from_re(T::zero()); m];
        for j in 0..n {
            zd[j].eps = T::one();
            self.k(td, &yd, &zd, &mut kd);
            for i in 0..m {
                out[i * n + j] = kd[i].eps;
            }
            zd[j].eps = T::zero();
        }
    }

    /// True when f = f₀(t, y, z) − g_yᵀ λ − k_zᵀ ψ (the additive form of §6), which allows the
    /// simplified (13d) and HHT-SOI2 (17).
    fn additive(&self) -> bool {
        false
    }

    /// The names of the probed state columns, positions then velocities: `("y", "z")`, the
    /// paper's (Jay & Negrut 2008, (11)), for the built-in scenes. A model whose coordinates
    /// are named by its family otherwise says so (a `lagrangian` model: `("q", "v")`, the
    /// names its probes have under every scheme).
    fn state_names(&self) -> (&'static str, &'static str) {
        ("y", "z")
    }

    /// Potential energy (gravity and springs), 0 when the model has none.
    fn potential(&self, t: f64, y: &[f64]) -> f64 {
        let _ = (t, y);
        0.0
    }

    /// The damping part of f (its work is `work_damping`). Default: none.
    fn damping_force(&self, t: f64, y: &[f64], z: &[f64], out: &mut [f64]) {
        let _ = (t, y, z);
        out.fill(0.0);
    }

    /// The structure of Newton's matrix with `blocks` coordinate and joint blocks
    /// ([`sparsity::Pattern`]), when the model knows which coordinates its equations touch;
    /// the Jacobian is then built one dual evaluation per group of structurally orthogonal
    /// columns. Default: `None`, one dual evaluation per column. A model with nonholonomic
    /// constraints must return `None`.
    fn newton_pattern(&self, blocks: usize) -> Option<&sparsity::Pattern> {
        let _ = blocks;
        None
    }

    /// Initial values at t₀.
    fn initial(&self) -> InitialValues;

    /// The exact solution at t, when known.
    fn exact(&self, t: f64) -> Option<ExactValues> {
        let _ = t;
        None
    }
}

/// Acceleration-level holonomic constraints
/// g_tt + 2 g_ty z + g_yy(z, z) + g_y a (§6, consistent initial conditions): the derivative of
/// g_t + g_y z along (1, z, a), by forward-mode AD of [`ConstrainedModel::g_dot`].
pub fn g_ddot<M: ConstrainedModel + ?Sized, T: Scalar>(
    model: &M,
    t: T,
    y: &[T],
    z: &[T],
    a: &[T],
    out: &mut [T],
) {
    let m = model.dims().holonomic;
    let td = Dual::new(t, T::one());
    let yd: Vec<Dual<T>> = y.iter().zip(z).map(|(&v, &w)| Dual::new(v, w)).collect();
    let zd: Vec<Dual<T>> = z.iter().zip(a).map(|(&v, &w)| Dual::new(v, w)).collect();
    let mut gd = vec![Dual::from_re(T::zero()); m];
    model.g_dot(td, &yd, &zd, &mut gd);
    for (o, v) in out.iter_mut().zip(&gd) {
        *o = v.eps;
    }
}

/// Acceleration-level nonholonomic constraints k_t + k_y z + k_z a (§6): the derivative of k
/// along (1, z, a), by forward-mode AD.
pub fn k_dot<M: ConstrainedModel + ?Sized, T: Scalar>(
    model: &M,
    t: T,
    y: &[T],
    z: &[T],
    a: &[T],
    out: &mut [T],
) {
    let m = model.dims().nonholonomic;
    let td = Dual::new(t, T::one());
    let yd: Vec<Dual<T>> = y.iter().zip(z).map(|(&v, &w)| Dual::new(v, w)).collect();
    let zd: Vec<Dual<T>> = z.iter().zip(a).map(|(&v, &w)| Dual::new(v, w)).collect();
    let mut kd = vec![Dual::from_re(T::zero()); m];
    model.k(td, &yd, &zd, &mut kd);
    for (o, v) in out.iter_mut().zip(&kd) {
        *o = v.eps;
    }
}

/// Why a SOI2 run (or its set-up) failed. Every variant names the cause and where it happened.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum Soi2Error {
    /// The checkpoint to resume from does not fit the run.
    #[error(transparent)]
    Checkpoint(#[from] crate::checkpoint::CheckpointError),
    /// The constraint Jacobian (g_y; k_z) has dependent rows: the multipliers are not unique.
    #[error(
        "singular constraint Jacobian (g_y; k_z) at t = {t}: rank {rank} < {constraints} constraints \
         (smallest singular value {sigma_min:e})"
    )]
    SingularConstraintJacobian {
        /// Time.
        t: f64,
        /// Numerical rank found.
        rank: usize,
        /// m_g + m_k.
        constraints: usize,
        /// Smallest singular value.
        sigma_min: f64,
    },
    /// The initial values violate a constraint beyond the tolerance.
    #[error(
        "inconsistent initial conditions: {level} constraint residual {residual:e} > tolerance {tolerance:e}"
    )]
    InconsistentInitialConditions {
        /// `position` (g), `velocity` (g_t + g_y z) or `nonholonomic` (k).
        level: &'static str,
        /// Max-norm of the residual.
        residual: f64,
        /// Largest residual accepted.
        tolerance: f64,
    },
    /// A Newton matrix (the step's, or (12) at the initial acceleration solve) is singular.
    #[error("step {step} (t = {t}): singular Newton matrix ({context})")]
    SingularNewtonMatrix {
        /// Step being computed (0: the initial acceleration solve).
        step: u64,
        /// Time t₁ of the step.
        t: f64,
        /// Which system.
        context: &'static str,
    },
    /// Newton did not converge (a fixed-step run stops here; a variable-step run first retries
    /// with h/2).
    #[error(
        "step {step} (t = {t}): Newton did not converge in {iterations} iterations \
         (scaled residual {residual:e}, last increment {increment:e}; constraint Jacobian of \
         rank {rank} for {constraints} constraints)"
    )]
    NewtonDiverged {
        /// Step being computed (0: the initial acceleration solve).
        step: u64,
        /// Time t₁ of the step.
        t: f64,
        /// Iterations done.
        iterations: usize,
        /// Max-norm of the scaled residual at the last iterate.
        residual: f64,
        /// Max-norm of the last Newton increment.
        increment: f64,
        /// Numerical rank of (g_y; k_z) at the last iterate.
        rank: usize,
        /// m_g + m_k.
        constraints: usize,
    },
    /// The observer stopped the run.
    #[error("stopped after {step} steps")]
    Stopped {
        /// Steps done.
        step: u64,
    },
}

/// Evaluates an n×n (row-major, f64) matrix from the model's mass at (t, y).
pub(crate) fn mass_matrix<M: ConstrainedModel + ?Sized>(
    model: &M,
    t: f64,
    y: &[f64],
) -> DMatrix<f64> {
    let n = y.len();
    let mut m = vec![0.0; n * n];
    model.mass(t, y, &mut m);
    DMatrix::from_row_slice(n, n, &m)
}

/// Max-norm of a slice (0 for an empty one).
pub(crate) fn max_norm(v: &[f64]) -> f64 {
    v.iter().fold(0.0_f64, |m, x| m.max(x.abs()))
}

/// Euclidean norm of a − b.
pub(crate) fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

/// Checks that (g_y; k_z) has full row rank at (t, y, z).
pub fn check_constraint_rank<M: ConstrainedModel + ?Sized>(
    model: &M,
    t: f64,
    y: &[f64],
    z: &[f64],
) -> Result<(), Soi2Error> {
    let d = model.dims();
    let rows = d.holonomic + d.nonholonomic;
    if rows == 0 {
        return Ok(());
    }
    let jac = DMatrix::from_row_slice(rows, d.n, &constraint_jacobian(model, t, y, z));
    // Not finite: no rank to speak of (as `factor::range_projection` says).
    let sv = crate::dense::singular_values(jac).unwrap_or_else(|| DVector::zeros(rows));
    let smax = sv.max();
    let smin = sv.min();
    let tol = 1e-10 * smax.max(1.0);
    let rank = sv.iter().filter(|&&s| s > tol).count();
    if rows > d.n || rank < rows {
        return Err(Soi2Error::SingularConstraintJacobian {
            t,
            rank,
            constraints: rows,
            sigma_min: smin,
        });
    }
    Ok(())
}

/// Numerical rank of (g_y; k_z) at (t, y, z) (singular values above
/// [`factor::RANK_TOLERANCE`] · max(σ_max, 1)) and the orthogonal projector onto its column
/// space (see [`factor::range_projection`]).
pub fn constraint_rank<M: ConstrainedModel + ?Sized>(
    model: &M,
    t: f64,
    y: &[f64],
    z: &[f64],
) -> (usize, DMatrix<f64>) {
    let d = model.dims();
    let jac = constraint_jacobian(model, t, y, z);
    factor::range_projection(&jac, d.holonomic + d.nonholonomic, d.n)
}

/// Numerical rank of (g_y; k_z) at (t, y, z), as [`constraint_rank`] counts it, without the
/// projector ([`factor::numerical_rank`]).
pub fn constraint_numerical_rank<M: ConstrainedModel + ?Sized>(
    model: &M,
    t: f64,
    y: &[f64],
    z: &[f64],
) -> usize {
    let d = model.dims();
    let jac = constraint_jacobian(model, t, y, z);
    factor::numerical_rank(&jac, d.holonomic + d.nonholonomic, d.n)
}

/// (g_y; k_z) at (t, y, z): the holonomic rows, then the nonholonomic ones, row-major.
fn constraint_jacobian<M: ConstrainedModel + ?Sized>(
    model: &M,
    t: f64,
    y: &[f64],
    z: &[f64],
) -> Vec<f64> {
    let d = model.dims();
    let mut jac = vec![0.0; d.holonomic * d.n];
    model.g_y(t, y, &mut jac);
    let mut kz = vec![0.0; d.nonholonomic * d.n];
    model.k_z(t, y, z, &mut kz);
    jac.extend_from_slice(&kz);
    jac
}

/// Max-norms of the position, velocity and nonholonomic constraint residuals at (t, y, z).
pub fn constraint_residuals<M: ConstrainedModel + ?Sized>(
    model: &M,
    t: f64,
    y: &[f64],
    z: &[f64],
) -> [f64; 3] {
    let d = model.dims();
    let mut g = vec![0.0; d.holonomic];
    model.g(t, y, &mut g);
    let mut gd = vec![0.0; d.holonomic];
    model.g_dot(t, y, z, &mut gd);
    let mut k = vec![0.0; d.nonholonomic];
    model.k(t, y, z, &mut k);
    [max_norm(&g), max_norm(&gd), max_norm(&k)]
}

/// Checks (g, g_t + g_y z, k) at the initial values against `tolerance` (max-norm).
pub fn check_consistency<M: ConstrainedModel + ?Sized>(
    model: &M,
    tolerance: f64,
) -> Result<(), Soi2Error> {
    let iv = model.initial();
    let r = constraint_residuals(model, iv.t, &iv.y, &iv.z);
    for (level, residual) in ["position", "velocity", "nonholonomic"].into_iter().zip(r) {
        if residual.is_nan() || residual > tolerance {
            return Err(Soi2Error::InconsistentInitialConditions {
                level,
                residual,
                tolerance,
            });
        }
    }
    Ok(())
}

/// Kinetic energy ½ zᵀ M(t, y) z, over M's entries ([`ConstrainedModel::mass_entries_at`]:
/// a recorded step of a long chain formed an n × n array).
pub fn kinetic_energy<M: ConstrainedModel + ?Sized>(
    model: &M,
    t: f64,
    y: &[f64],
    z: &[f64],
) -> f64 {
    let mut m = Vec::new();
    model.mass_entries_at(t, y, &mut m);
    let mut mz = vec![0.0; z.len()];
    for (i, j, mij) in m {
        mz[i] += mij * z[j];
    }
    0.5 * z.iter().zip(&mz).map(|(a, b)| a * b).sum::<f64>()
}

/// Global errors ‖·‖₂ at the end of a run against the exact solution: y_N, z_N, λ_N, ψ_N at
/// t_N, and a_{N+α} at t_N + α h_{N−1} (§2, §7).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct GlobalErrors {
    /// ‖y_N − y(t_N)‖₂.
    pub y: f64,
    /// ‖z_N − z(t_N)‖₂.
    pub z: f64,
    /// ‖a_{N+α} − a(t_N + α h_{N−1})‖₂.
    pub a: f64,
    /// ‖λ_N − λ(t_N)‖₂.
    pub lambda: f64,
    /// ‖ψ_N − ψ(t_N)‖₂.
    pub psi: f64,
}
