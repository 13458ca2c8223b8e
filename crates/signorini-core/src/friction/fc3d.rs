//! The three-dimensional friction problem (FC3D, Siconos' numerics) and its solvers.
//!
//! m contacts, each with a normal and two tangents `(n, t1, t2)`; unknowns the impulses
//! `r = (r_n, r_t1, r_t2)` per contact. The local velocity is
//!
//! ```text
//! u = W r + q
//! ```
//!
//! with W the 3m×3m Delassus operator, stored block-sparse ([`BlockCsr`], 3×3 blocks), and q the
//! free local velocity. Each contact obeys Coulomb's law with maximal dissipation on the cone
//! `K_μ = {r : ‖r_t‖ ≤ μ r_n}`: with De Saxcé's modified velocity `û = u + μ‖u_t‖ e_n`
//! (G. De Saxcé, Z.-Q. Feng, *New inequality and functional for contact with friction: the
//! implicit standard material approach*, Mechanics of Structures and Machines 19(3):301–325,
//! 1991, doi:10.1080/08905459108905146), the law is the second-order cone complementarity
//!
//! ```text
//! K_μ ∋ r ⊥ û ∈ K_μ*,   equivalently   r = P_{K_μ}(r − û)
//! ```
//!
//! (stick: r inside K_μ and u = 0; slide: r on the boundary, u_n = 0, r_t = −μ r_n u_t/‖u_t‖;
//! take-off: r = 0, u_n ≥ 0). Every solve reports the error Siconos' solvers report
//! (`fc3d_compute_error`):
//!
//! ```text
//! error = ‖r − P_K(r − û)‖₂ / max(‖q‖₂, ‖r‖₂, ‖u‖₂)
//! ```
//!
//! over all contacts stacked, not divided when the scale is below the machine epsilon (then it is
//! the absolute error). It is relative: a problem of tiny q is not solved by a tiny absolute
//! residual.
//!
//! Solvers ([`Fc3dSolverKind`]): the nonsmooth Gauss–Seidel over contacts
//! ([`super::solve_fc3d_nsgs`]) and the semismooth Newton method on Alart and Curnier's function
//! with a line search ([`super::solve_fc3d_newton`]), which does not depend on the contact ordering,
//! and the proximal point method with that Newton method inside ([`super::solve_fc3d_prox`]); `auto`
//! chains them and [`Fc3dSolution::solver`] names the one that answered. The formulations and
//! their comparison: V. Acary, M. Brémond, O. Huber, *On solving contact problems with Coulomb
//! friction: formulations and numerical comparisons*, in Advanced Topics in Nonsmooth Dynamics,
//! Springer, 2018, pp. 375–457, doi:10.1007/978-3-319-75972-2_10 (INRIA research report RR-9118).

use super::block_csr::{BlockCsr, BlockCsrError};
use thiserror::Error;

/// A three-dimensional friction problem with m contacts (owned: readers of problem files hand it
/// over).
#[derive(Debug, Clone, PartialEq)]
pub struct Fc3dProblem {
    /// The Delassus operator, 3×3 blocks ordered `(n, t1, t2)` per contact.
    pub w: BlockCsr,
    /// Free local velocity (3m), same order.
    pub q: Vec<f64>,
    /// Friction coefficient per contact (m), finite and ≥ 0.
    pub mu: Vec<f64>,
}

impl Fc3dProblem {
    /// Number of contacts m.
    pub fn contacts(&self) -> usize {
        self.mu.len()
    }

    /// Checks the sizes, the friction coefficients and q.
    pub fn validate(&self) -> Result<(), Fc3dError> {
        let m = self.contacts();
        if self.w.dim() != 3 || self.w.blocks() != m || self.q.len() != 3 * m {
            return Err(Fc3dError::Dimensions {
                contacts: m,
                block: self.w.dim(),
                w_blocks: self.w.blocks(),
                q_len: self.q.len(),
            });
        }
        if let Some((contact, &mu)) = self
            .mu
            .iter()
            .enumerate()
            .find(|(_, mu)| !(mu.is_finite() && **mu >= 0.0))
        {
            return Err(Fc3dError::InvalidFriction { contact, mu });
        }
        if let Some((index, &value)) = self.q.iter().enumerate().find(|(_, q)| !q.is_finite()) {
            return Err(Fc3dError::NotFiniteQ { index, value });
        }
        Ok(())
    }

    /// The problem of a planar one (2×2 blocks `(n, t)`), each contact given a second tangent
    /// that nothing couples: `W_{t2 t2} = 1`, `q_{t2} = 0`, every other entry of its row and
    /// column 0. Then `u_{t2} = r_{t2}`, so any solution has `r_{t2} = u_{t2} = 0`, the 3D cone
    /// restricted to `r_{t2} = 0` is the planar cone `|r_t| ≤ μ r_n`, ‖u_t‖ = |u_t|, and every
    /// norm of the error is the planar one: the planar problem's solutions and errors are the
    /// embedded problem's, exactly. [`Fc3dSolution::planar`] maps back.
    pub fn from_planar(w: &BlockCsr, q: &[f64], mu: &[f64]) -> Result<Self, Fc3dError> {
        let m = mu.len();
        if w.dim() != 2 || w.blocks() != m || q.len() != 2 * m {
            return Err(Fc3dError::Dimensions {
                contacts: m,
                block: w.dim(),
                w_blocks: w.blocks(),
                q_len: q.len(),
            });
        }
        let lift = |i: usize| 3 * (i / 2) + i % 2;
        let entries = w
            .entries()
            .map(|(i, j, x)| (lift(i), lift(j), x))
            .chain((0..m).map(|a| (3 * a + 2, 3 * a + 2, 1.0)));
        let w = BlockCsr::from_triplets(3, 3 * m, entries)?;
        let q = (0..3 * m)
            .map(|k| {
                if k % 3 == 2 {
                    0.0
                } else {
                    q[2 * (k / 3) + k % 3]
                }
            })
            .collect();
        Ok(Self {
            w,
            q,
            mu: mu.to_vec(),
        })
    }

    /// Local velocity u = W r + q.
    pub fn local_velocity(&self, r: &[f64]) -> Vec<f64> {
        self.w.affine(r, &self.q)
    }

    /// Siconos' relative natural-map error of `r` (module documentation).
    pub fn error(&self, r: &[f64]) -> f64 {
        ErrorMeter::new(self).error(r)
    }

    /// Work of the friction impulses on the tangential velocities, `Σ r_t · u_t` (≤ 0 at a
    /// solution: friction dissipates).
    pub fn friction_work(&self, r: &[f64]) -> f64 {
        let u = self.local_velocity(r);
        (0..self.contacts())
            .map(|c| r[3 * c + 1] * u[3 * c + 1] + r[3 * c + 2] * u[3 * c + 2])
            .sum()
    }
}

/// Checks a solve's inputs: [`check_problem`], and the start (3m finite numbers). Every public
/// solver runs it once; the stages of `auto` and the proximal point method's inner solves work
/// on checked inputs.
pub(crate) fn check_solve(
    problem: &Fc3dProblem,
    options: &Fc3dOptions,
    start: &[f64],
) -> Result<(), Fc3dError> {
    check_problem(problem, options)?;
    if start.len() != problem.q.len() {
        return Err(Fc3dError::StartLength {
            expected: problem.q.len(),
            got: start.len(),
        });
    }
    if let Some((index, &value)) = start.iter().enumerate().find(|(_, x)| !x.is_finite()) {
        return Err(Fc3dError::NotFiniteStart { index, value });
    }
    Ok(())
}

/// Checks a solve's problem ([`Fc3dProblem::validate`]), tolerance, over-relaxation and
/// stagnation window.
pub(crate) fn check_problem(problem: &Fc3dProblem, options: &Fc3dOptions) -> Result<(), Fc3dError> {
    problem.validate()?;
    if options.tolerance.is_nan() || options.tolerance <= 0.0 {
        return Err(Fc3dError::InvalidTolerance {
            tolerance: options.tolerance,
        });
    }
    options.check_relaxation()?;
    options.check_stall()
}

/// The error of successive iterates of one problem, as the iterative solvers measure it after
/// every sweep or step: [`natural_map_error`] with u = W r + q written into a buffer kept from
/// one measure to the next, the norms of r and u summed in the natural map's loop, and ‖q‖
/// computed once. The same sums in the same order as [`Fc3dProblem::local_velocity`] and
/// [`natural_map_error`], hence the same bits.
pub(crate) struct ErrorMeter<'a> {
    problem: &'a Fc3dProblem,
    q_squared: f64,
    u: Vec<f64>,
}

impl<'a> ErrorMeter<'a> {
    pub(crate) fn new(problem: &'a Fc3dProblem) -> Self {
        Self {
            problem,
            q_squared: problem.q.iter().map(|x| x * x).sum(),
            u: vec![0.0; problem.q.len()],
        }
    }

    /// The error of `r`; the local velocity u = W r + q is then [`Self::into_velocity`].
    pub(crate) fn error(&mut self, r: &[f64]) -> f64 {
        let p = self.problem;
        self.u.copy_from_slice(&p.q);
        for (a, u) in self.u.chunks_exact_mut(3).enumerate() {
            p.w.add_row_product(a, r, u);
        }
        // A loop of its own, apart from the products: fused with them it was 9 % slower on
        // FrictionContactProblem00071, the square roots of one contact no longer overlapping
        // the next contact's.
        let [map, r_squared, u_squared] = natural_map_squares(&p.mu, r, &self.u);
        super::relative_error_of_squares(map, self.q_squared, r_squared, u_squared)
    }

    /// u = W r + q at the last measured r.
    pub(crate) fn into_velocity(self) -> Vec<f64> {
        self.u
    }
}

/// `‖r − P_K(r − û)‖₂ / max(‖q‖₂, ‖r‖₂, ‖u‖₂)` over all contacts (Siconos'
/// `fc3d_compute_error`; not divided when the scale is ≤ the machine epsilon).
pub fn natural_map_error(mu: &[f64], q: &[f64], r: &[f64], u: &[f64]) -> f64 {
    let [map, r_squared, u_squared] = natural_map_squares(mu, r, u);
    let q_squared = q.iter().map(|x| x * x).sum();
    super::relative_error_of_squares(map, q_squared, r_squared, u_squared)
}

/// `‖r − P_K(r − û)‖₂²`, `‖r‖₂²` and `‖u‖₂²` over all contacts, in one loop.
fn natural_map_squares(mu: &[f64], r: &[f64], u: &[f64]) -> [f64; 3] {
    let (mut map, mut r_squared, mut u_squared) = (0.0, 0.0, 0.0);
    for ((&mu, rc), uc) in mu.iter().zip(r.chunks_exact(3)).zip(u.chunks_exact(3)) {
        let (rc, uc) = ([rc[0], rc[1], rc[2]], [uc[0], uc[1], uc[2]]);
        let d = contact_natural_map(mu, rc, uc);
        map += d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        for i in 0..3 {
            r_squared += rc[i] * rc[i];
            u_squared += uc[i] * uc[i];
        }
    }
    [map, r_squared, u_squared]
}

/// `r − P_K(r − û)` for one contact, `û = u + μ‖u_t‖ e_n`.
pub(crate) fn contact_natural_map(mu: f64, r: [f64; 3], u: [f64; 3]) -> [f64; 3] {
    // (Not `hypot`, here and in `project_cone`: its care for overflow beyond 1e154 costs a
    // tenth of an error evaluation, which Gauss–Seidel runs after every sweep.)
    let ut = (u[1] * u[1] + u[2] * u[2]).sqrt();
    let p = project_cone(mu, [r[0] - u[0] - mu * ut, r[1] - u[1], r[2] - u[2]]);
    [r[0] - p[0], r[1] - p[1], r[2] - p[2]]
}

/// Euclidean projection on `K_μ = {(n, t) : ‖t‖ ≤ μ n}` (μ = 0: the half-line t = 0, n ≥ 0).
pub(crate) fn project_cone(mu: f64, [n, t1, t2]: [f64; 3]) -> [f64; 3] {
    let t = (t1 * t1 + t2 * t2).sqrt();
    // n ≥ 0 too: for μ = 0 and t = 0, `t ≤ μ n` holds for a negative n as well (0 ≤ −0).
    if t <= mu * n && n >= 0.0 {
        [n, t1, t2]
    } else if mu * t <= -n {
        // In the polar cone {μ‖t‖ ≤ −n}.
        [0.0, 0.0, 0.0]
    } else {
        // On the boundary ray through (1, μ t/‖t‖); here t > 0.
        let a = (n + mu * t) / (1.0 + mu * mu);
        [a, mu * a * t1 / t, mu * a * t2 / t]
    }
}

/// Which FC3D solver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Fc3dSolverKind {
    /// Nonsmooth Gauss–Seidel with Anderson acceleration for a few sweeps (fast on well-posed
    /// rigid sets and on dense piles), then the
    /// proximal point method from the best iterate, then from the start, each for a bounded
    /// number of Newton iterations and a bounded work, then Gauss–Seidel again from the best
    /// iterate of all with the whole budget
    /// ([`super::solve_fc3d`]).
    #[default]
    Auto,
    /// Nonsmooth Gauss–Seidel over contacts ([`super::solve_fc3d_nsgs`]).
    Nsgs,
    /// Those sweeps with Anderson acceleration ([`super::solve_fc3d_nsgs_anderson`]).
    NsgsAnderson,
    /// Semismooth Newton on Alart–Curnier's function with a line search
    /// ([`super::solve_fc3d_newton`]).
    NewtonAlartCurnier,
    /// The proximal point method with that Newton method as inner solver
    /// ([`super::solve_fc3d_prox`]).
    Prox,
}

impl Fc3dSolverKind {
    /// The name used on the command line and in reports: `auto`, `nsgs`, `nsgs_aa`, `nsn_ac`,
    /// `prox`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Nsgs => "nsgs",
            Self::NsgsAnderson => "nsgs_aa",
            Self::NewtonAlartCurnier => "nsn_ac",
            Self::Prox => "prox",
        }
    }

    /// The kind of a name given by [`Self::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        [
            Self::Auto,
            Self::Nsgs,
            Self::NsgsAnderson,
            Self::NewtonAlartCurnier,
            Self::Prox,
        ]
        .into_iter()
        .find(|k| k.name() == name)
    }
}

/// How the semismooth Newton method (`NewtonAlartCurnier`, and `Prox`'s inner solves) solves
/// its linear systems `J d = −Φ`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Fc3dNewtonLinear {
    /// The sparse LU while its factors stay sparse (at most 50 passes over W a factorisation),
    /// then the dense LU up to [`Fc3dOptions::dense_newton_max`] unknowns and GMRES above.
    #[default]
    Auto,
    /// Dense LU with partial pivoting (J formed densely, 8·n² bytes).
    DenseLu,
    /// Sparse LU of J assembled from W's blocks: the block LU (`fc3d_block_lu`), and the LU
    /// with partial pivoting (`fc3d_sparse_lu`) where the block LU's direction falls short.
    SparseLu,
    /// Restarted GMRES(40) with a block-Jacobi preconditioner and products by the sparse W.
    Gmres,
}

impl Fc3dNewtonLinear {
    /// The name used on the command line: `auto`, `dense_lu`, `sparse_lu`, `gmres`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::DenseLu => "dense_lu",
            Self::SparseLu => "sparse_lu",
            Self::Gmres => "gmres",
        }
    }

    /// The linear solve of a name (see [`Fc3dNewtonLinear::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        [Self::Auto, Self::DenseLu, Self::SparseLu, Self::Gmres]
            .into_iter()
            .find(|k| k.name() == name)
    }
}

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fc3dOptions {
    /// Which solver. Default `Auto`.
    pub kind: Fc3dSolverKind,
    /// Largest error accepted (module documentation). Default 1e-8, > 0.
    pub tolerance: f64,
    /// Budget of sweeps (Gauss–Seidel) or Newton iterations. Default 10 000.
    pub max_iterations: usize,
    /// Sweeps `Auto` gives its first stage (Gauss–Seidel with Anderson acceleration) before it
    /// turns to Newton. Default 100.
    pub auto_sweeps: usize,
    /// Newton iterations, summed over its proximal steps, that `Auto` gives the proximal point
    /// method before it turns back to Gauss–Seidel. Default 200: on Siconos' Capsules,
    /// KaplasTower and BoxesStack problems it converges in 12–161, and each iteration costs a
    /// linear solve, so a larger budget mostly delays the fallback.
    pub auto_newton_iterations: usize,
    /// Work that `Auto` gives the proximal point method from its start, in products by a 3×3
    /// block of W (a product by W counts its stored blocks, a Gauss–Seidel sweep costs as much,
    /// a dense LU factorisation of n unknowns 2n³/54, a sparse LU the flops of its elimination
    /// over 18 plus 3 per stored block for assembling J; GMRES's Gram–Schmidt is not counted), a
    /// third of it to the attempt from the best iterate before, and then it turns back to
    /// Gauss–Seidel. Default 10⁸ (≈ 2.5–3.5 s on the benchmark's machine; 1.8× what
    /// Capsules-i122-1617 needs from r = 0, and its third 2× what Capsules-i100-889 needs from
    /// Gauss–Seidel's iterate).
    pub auto_prox_work: usize,
    /// Where the sparse LU's factors fill in (`newton_linear` = `Auto`), Newton solves its
    /// linear systems with a dense LU factorisation up to this many unknowns (3m; 8·n² bytes,
    /// 2 MB at the default 500), above it with restarted GMRES on the sparse Jacobian, which is
    /// never formed densely. Default 500: on Capsules-i101-404 (675 unknowns) an iteration of
    /// the proximal point method's Newton took 0.12 s with the dense LU and 0.027 s with GMRES,
    /// while on BoxesStack1 (156 unknowns) only the dense LU converged (Round 9, before the
    /// sparse LU).
    pub dense_newton_max: usize,
    /// Newton's linear solve. Default `Auto`: the sparse LU, unless its factors fill in
    /// (module `fc3d_newton`); on Capsules-i122-1617 the proximal point method then takes 76
    /// Newton iterations and 0.1 s where GMRES, whose block-Jacobi preconditioner is too weak
    /// there, took 104 and 1.5 s (docs/friction_benchmark.md, Round 10).
    pub newton_linear: Fc3dNewtonLinear,
    /// Outer iterations of the proximal point method (`Prox`). Default 100 (Siconos' default).
    pub prox_outer_iterations: usize,
    /// Newton iterations per proximal step (`Prox`). Default 100; the total over the steps is
    /// bounded by `max_iterations`.
    pub prox_inner_iterations: usize,
    /// Over-relaxation ω ∈ (0, 2) of the plain Gauss–Seidel sweeps (`Nsgs`, the fallback of
    /// `NsgsAnderson`, `Auto`'s first and last stages, the last followed by plain sweeps at ω = 1
    /// where it fails; never the accelerated sweeps): module `fc3d_nsgs`. Default 1 (none); a
    /// rigid time step gives 1.5 (`rigid::RELAXATION`).
    pub relaxation: f64,
    /// Stops Gauss–Seidel's sweeps, plain or accelerated (`Nsgs`, `NsgsAnderson` and `Auto`'s
    /// sweeping stages), when they stall ([`Fc3dStall`]; module `fc3d_nsgs`, *Stagnation*): the
    /// budget left goes to the next stage or ends the solve instead of replaying a cycle.
    /// Default `None` (sweeps run until the tolerance or the budget); a rigid time step that
    /// accepts errors up to a bound gives `rigid::STALL_SWEEPS` sweeps below that bound. Refused
    /// for a solver that does not sweep (`NewtonAlartCurnier`, `Prox`).
    pub stall: Option<Fc3dStall>,
}

/// The stagnation test of Gauss–Seidel's sweeps ([`Fc3dOptions::stall`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fc3dStall {
    /// The sweeps stop once this many in a row have not brought the smallest error below 0.9
    /// times what it was when they began; ≥ 1.
    pub sweeps: usize,
    /// ... and only while the smallest error is at most this (∞: at any error), > 0: a rigid step
    /// gives its `accept_error`, since only an error within it lets the step go on, and sweeps
    /// above it must keep trying.
    pub below: f64,
}

impl Fc3dOptions {
    /// Refuses a stagnation test of zero sweeps or of a bound that is not a positive number, or
    /// one given to a solver that does not sweep.
    pub fn check_stall(&self) -> Result<(), Fc3dError> {
        match (self.stall, self.kind) {
            (Some(stall), _) if stall.sweeps == 0 || stall.below.is_nan() || stall.below <= 0.0 => {
                Err(Fc3dError::InvalidStall {
                    sweeps: stall.sweeps,
                    below: stall.below,
                })
            }
            (Some(_), Fc3dSolverKind::NewtonAlartCurnier | Fc3dSolverKind::Prox) => {
                Err(Fc3dError::StallWithoutSweeps {
                    solver: self.kind.name(),
                })
            }
            _ => Ok(()),
        }
    }

    /// Refuses an over-relaxation outside (0, 2).
    pub fn check_relaxation(&self) -> Result<(), Fc3dError> {
        if self.relaxation > 0.0 && self.relaxation < 2.0 {
            Ok(())
        } else {
            Err(Fc3dError::InvalidRelaxation {
                relaxation: self.relaxation,
            })
        }
    }
}

impl Default for Fc3dOptions {
    fn default() -> Self {
        Self {
            kind: Fc3dSolverKind::Auto,
            tolerance: 1e-8,
            max_iterations: 10_000,
            auto_sweeps: 100,
            auto_newton_iterations: 200,
            auto_prox_work: 100_000_000,
            dense_newton_max: 500,
            newton_linear: Fc3dNewtonLinear::Auto,
            prox_outer_iterations: 100,
            prox_inner_iterations: 100,
            relaxation: 1.0,
            stall: None,
        }
    }
}

/// A solution with its diagnostics.
#[derive(Debug, Clone, PartialEq)]
pub struct Fc3dSolution {
    /// Impulses `(r_n, r_t1, r_t2)` per contact.
    pub r: Vec<f64>,
    /// Local velocities `u = W r + q`.
    pub u: Vec<f64>,
    /// Sweeps or Newton iterations, summed over the solvers `Auto` ran.
    pub iterations: usize,
    /// The error of `r` (module documentation).
    pub error: f64,
    /// The solver that answered: `nsgs`, `nsgs_aa`, `nsn_ac` or `prox`.
    pub solver: &'static str,
}

impl Fc3dSolution {
    /// `(r, u)` of a problem made by [`Fc3dProblem::from_planar`], back in `(n, t)` per contact.
    pub fn planar(&self) -> (Vec<f64>, Vec<f64>) {
        let drop_t2 = |v: &[f64]| {
            v.iter()
                .enumerate()
                .filter(|(k, _)| k % 3 != 2)
                .map(|(_, x)| *x)
                .collect()
        };
        (drop_t2(&self.r), drop_t2(&self.u))
    }
}

/// Why an FC3D solve failed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum Fc3dError {
    /// W, q and μ do not describe one problem.
    #[error(
        "{contacts} contacts need W of {contacts} block rows of 3×3 blocks and q of length {}, got {w_blocks} block rows of {block}×{block} blocks and q of length {q_len}",
        3 * contacts
    )]
    Dimensions {
        /// Contacts (length of μ).
        contacts: usize,
        /// Block size of W.
        block: usize,
        /// Block rows of W.
        w_blocks: usize,
        /// Length of q.
        q_len: usize,
    },
    /// A friction coefficient is negative or not finite.
    #[error("friction coefficient of contact {contact} is {mu}: it must be finite and ≥ 0")]
    InvalidFriction {
        /// Contact.
        contact: usize,
        /// The coefficient given.
        mu: f64,
    },
    /// An entry of q is not finite.
    #[error("q[{index}] is {value}: it must be finite")]
    NotFiniteQ {
        /// Index in q.
        index: usize,
        /// The value.
        value: f64,
    },
    /// W could not be built.
    #[error("W: {0}")]
    Matrix(#[from] BlockCsrError),
    /// The tolerance is not a positive number.
    #[error("tolerance {tolerance} must be > 0")]
    InvalidTolerance {
        /// The tolerance given.
        tolerance: f64,
    },
    /// The over-relaxation is not in (0, 2).
    #[error("over-relaxation {relaxation} must lie in (0, 2)")]
    InvalidRelaxation {
        /// The over-relaxation given.
        relaxation: f64,
    },
    /// A stagnation test of zero sweeps, or whose bound is not a positive number.
    #[error(
        "stagnation test of {sweeps} sweeps below {below}: the sweeps must be ≥ 1 and the bound > 0"
    )]
    InvalidStall {
        /// The sweeps given.
        sweeps: usize,
        /// The bound given.
        below: f64,
    },
    /// A stagnation test for a solver that does not sweep.
    #[error("the stagnation test applies to Gauss–Seidel's sweeps; solver {solver} does not sweep")]
    StallWithoutSweeps {
        /// The solver's name.
        solver: &'static str,
    },
    /// A start (warm start) whose length is not 3m.
    #[error("the start has {got} entries, the problem has {expected} unknowns")]
    StartLength {
        /// 3m.
        expected: usize,
        /// Entries given.
        got: usize,
    },
    /// An entry of a start is not finite.
    #[error("start[{index}] is {value}: it must be finite")]
    NotFiniteStart {
        /// Index in the start.
        index: usize,
        /// The value.
        value: f64,
    },
    /// The iteration budget ran out.
    #[error(
        "{solver} did not reach tolerance {tolerance:e} in {iterations} iterations (error {error:e})"
    )]
    NotConverged {
        /// Solver name (for `auto`, the last one tried).
        solver: &'static str,
        /// Iterations done.
        iterations: usize,
        /// Smallest error reached.
        error: f64,
        /// Tolerance asked.
        tolerance: f64,
        /// The iterate of smallest error (a warm start for another solver).
        best: Vec<f64>,
    },
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// P_K is the Euclidean projection on K_μ: the image is in K_μ, it is idempotent, and
        /// x − P_K(x) is orthogonal to P_K(x) and lies in the polar cone (Moreau's decomposition).
        #[test]
        fn cone_projection_is_moreau_decomposition(
            mu in 0.0f64..3.0,
            x in prop::array::uniform3(-5.0f64..5.0),
        ) {
            let y = project_cone(mu, x);
            prop_assert!(y[1].hypot(y[2]) <= mu * y[0] + 1e-12 && y[0] >= 0.0);
            let yy = project_cone(mu, y);
            for k in 0..3 {
                prop_assert!((yy[k] - y[k]).abs() <= 1e-12);
            }
            let d = [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
            prop_assert!((d[0] * y[0] + d[1] * y[1] + d[2] * y[2]).abs() <= 1e-10);
            prop_assert!(mu * d[1].hypot(d[2]) <= -d[0] + 1e-10);
        }
    }

    proptest! {
        /// The error meter's fused passes and kept buffer give the bits of the plain
        /// definition, measure after measure.
        #[test]
        fn error_meter_is_the_natural_map_error_to_the_bit(
            entries in prop::collection::vec(-2.0f64..2.0, 36),
            q in prop::collection::vec(-1.0f64..1.0, 6),
            r1 in prop::collection::vec(-1.0f64..1.0, 6),
            r2 in prop::collection::vec(-1.0f64..1.0, 6),
            mu in prop::collection::vec(0.0f64..1.0, 2),
        ) {
            let w = BlockCsr::from_dense_row_major(3, 6, &entries).unwrap();
            let problem = Fc3dProblem { w, q, mu };
            let mut meter = ErrorMeter::new(&problem);
            for r in [&r1, &r2] {
                let u = problem.local_velocity(r);
                let error = meter.error(r);
                prop_assert_eq!(
                    error.to_bits(),
                    natural_map_error(&problem.mu, &problem.q, r, &u).to_bits()
                );
            }
            prop_assert_eq!(meter.into_velocity(), problem.local_velocity(&r2));
        }
    }

    #[test]
    fn frictionless_projection_of_a_pure_negative_normal_is_zero() {
        // Regression (issue 29, Newton's cradle): with μ = 0 and no tangential part, a negative
        // normal lies in the polar cone; `0 ≤ μ n` read −0 as ≥ 0 and returned it unprojected.
        assert_eq!(project_cone(0.0, [-2.0, 0.0, 0.0]), [0.0, 0.0, 0.0]);
        assert_eq!(project_cone(0.0, [2.0, 0.0, 0.0]), [2.0, 0.0, 0.0]);
        assert_eq!(
            contact_natural_map(0.0, [0.0; 3], [2.0, 0.0, 0.0]),
            [0.0; 3]
        );
    }

    #[test]
    fn natural_map_vanishes_exactly_on_the_law() {
        let zero = |mu, r, u| {
            let d = contact_natural_map(mu, r, u);
            d.iter().map(|x| x * x).sum::<f64>().sqrt() <= 1e-15
        };
        // Sliding along (3, 4)/5: r_t = −μ r_n (3, 4)/5, u_n = 0.
        assert!(zero(0.5, [2.0, -0.6, -0.8], [0.0, 3.0, 4.0]));
        // Sticking inside the cone with u = 0.
        assert!(zero(0.5, [2.0, 0.3, -0.2], [0.0, 0.0, 0.0]));
        // Take-off: r = 0, u_n > 0, any u_t.
        assert!(zero(0.5, [0.0, 0.0, 0.0], [1.0, -4.0, 2.0]));
        // Friction along the sliding velocity is not a solution.
        let d = contact_natural_map(0.5, [2.0, 0.6, 0.8], [0.0, 3.0, 4.0]);
        assert!(d.iter().map(|x| x * x).sum::<f64>().sqrt() > 0.1);
    }
}
