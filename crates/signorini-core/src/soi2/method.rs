//! One step of the generalized-α-SOI2 family (Jay & Negrut 2008), solved by Newton's method
//! with Jacobians from forward-mode automatic differentiation.
//!
//! A step maps `(t₀, y₀, z₀, a_α, M_α a_α, λ₀, ψ₀) ↦ (t₁, y₁, z₁, a_{1+α}, M_{1+α} a_{1+α}, λ₁, ψ₁)`
//! with `t₁ = t₀ + h`, `α := α_m − α_f` (§2), and the mass matrix taken explicitly (§3, §6):
//! `M_{1+α} := M(t₀ + (1+α)h, y₀ + h(1+α)z₀)`, `M_α := M_{(1+α)−1}` (the previous step's
//! `M_{1+α}`; on the first step `M(t₀ + αh, y₀ + hαz₀)`). The state carries the product
//! `M_α a_α`, which is what (14b) adjusts.

use super::banded::BandLu;
use super::factor::NewtonFactor;
use super::jacobian::{Jacobian, Residual};
use super::sparsity::Pattern;
use super::{
    ConstrainedModel, Dims, Dual64, Scalar, Soi2Error, constraint_numerical_rank, constraint_rank,
    g_ddot, k_dot, mass_matrix, max_norm,
};
use crate::anderson::Accelerator;
use nalgebra::{DMatrix, DVector, Dyn, LU};

/// Coefficients α_m, α_f, β, γ of the generalized-α method (2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coefficients {
    /// α_m ≠ 1.
    pub alpha_m: f64,
    /// α_f ≠ 1.
    pub alpha_f: f64,
    /// β ≠ 0.
    pub beta: f64,
    /// γ ≠ 0.
    pub gamma: f64,
}

impl Coefficients {
    /// The usual choice from the spectral radius at infinity ρ∞ ∈ [0, 1] (§1):
    /// `α_m = (2ρ∞ − 1)/(1 + ρ∞)`, `α_f = ρ∞/(1 + ρ∞)`, `β = (1 − α)²/4`, `γ = ½ − α`,
    /// `α = α_m − α_f`.
    pub fn from_rho_inf(rho_inf: f64) -> Self {
        let alpha_m = (2.0 * rho_inf - 1.0) / (1.0 + rho_inf);
        let alpha_f = rho_inf / (1.0 + rho_inf);
        let alpha = alpha_m - alpha_f;
        Self {
            alpha_m,
            alpha_f,
            beta: (1.0 - alpha).powi(2) / 4.0,
            gamma: 0.5 - alpha,
        }
    }

    /// HHT-α (§1): `α_m = 0`, `α_f = −α`, `β = (1 − α)²/4`, `γ = ½ − α`, α ∈ [−⅓, 0].
    pub fn hht(alpha: f64) -> Self {
        Self {
            alpha_m: 0.0,
            alpha_f: -alpha,
            beta: (1.0 - alpha).powi(2) / 4.0,
            gamma: 0.5 - alpha,
        }
    }

    /// α = α_m − α_f (§2): a_{n+α} approximates a(t_n + αh).
    pub fn alpha(&self) -> f64 {
        self.alpha_m - self.alpha_f
    }

    /// r = |α_m/(1 − α_m)| of Theorem 1 (the a, λ, ψ start-up error decays like rⁿ).
    pub fn r(&self) -> f64 {
        (self.alpha_m / (1.0 - self.alpha_m)).abs()
    }
}

/// Which equations a step solves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Formulation {
    /// Generalized-α-SOI2 (13a)–(13i), no assumption on f.
    General,
    /// (13) with (13d) replaced by its additive-force form
    /// `(1−α_m)M_{1+α}(ã_{1+α} − a_{1+α}) = (1−α_f)g_yᵀ(t₁,y₁)(λ₁ − λ̃₁) + (1−α_f)k_zᵀ(t₁,y₁,z₁)(ψ₁ − ψ̃₁)`,
    /// valid when f = f₀ − g_yᵀλ − k_zᵀψ.
    Additive,
    /// HHT-SOI2 (17a)–(17f): α_m = 0, holonomic constraints, additive f.
    HhtSoi2,
    /// HHT-I3 (Negrut et al. 2007): (2) with α_m = 0 and the position constraints g(t₁, y₁) = 0
    /// only (index 3); the baseline HHT-SOI2 improves upon.
    HhtI3,
}

/// Start value of a_α for the first step (§2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StartValue {
    /// a_α := a₀, the consistent acceleration at t₀.
    A0,
    /// a_α from (8), `M a_α = (1−α) f(t₀,y₀,z₀) + α f(t₁,y₁,z₁)` (Lunk & Simeon), written for
    /// a configuration-dependent mass as `M_α a_α = (1−α) M(t₀,y₀)a₀ + α M(t₁,y₁)a(t₁)` with the
    /// consistent accelerations; solved by fixed-point iteration on the first step.
    LunkSimeon,
}

/// Newton settings.
///
/// Convergence (both tests on the max-norm, x the unknowns of the step, F its residual with the
/// position rows scaled by 1/(βh²) and the velocity rows by 1/(γh), so that every row is in
/// the units of an acceleration times a mass or of an acceleration):
/// * **increment test**: `‖Δx‖∞ ≤ tolerance · (1 + ‖x‖∞)`; or the error the iterate has left
///   by the measured contraction ρ = ‖Δx_k‖/‖Δx_{k−1}‖, ρ/(1 − ρ)·‖Δx_k‖, is below u/16 (u the
///   rounding of the positions below: more iterations only stir round-off; `at_rounding`);
///   or the increments stopped shrinking (`‖Δx_k‖ ≥ ½‖Δx_{k−1}‖`) below
///   `max(100 · tolerance · (1 + ‖x‖∞), noise floor)` where the noise floor is 25 u;
/// * **residual test**, when the matrix is numerically singular (rank-deficient g_y: singular
///   positions, redundant joints; see [`super::factor`]) or the increments stopped shrinking
///   (`‖Δx_k‖ ≥ ½‖Δx_{k−1}‖`, Newton no longer contracts): `‖F(x)‖∞ ≤ ‖J‖∞ · (tolerance ·
///   (1 + ‖x‖∞) + u)` (J the Newton matrix of the iterate), a normwise backward-error test: x
///   solves exactly a system whose matrix and right side differ from the step's by `tolerance`
///   relative, or whose positions differ by their own rounding. u is that rounding seen as a
///   change of the unknowns, 4ε(1 + ‖y₀‖∞)/(βh²) for a step (the position rows cannot be
///   evaluated closer: coordinates that wind up, a crank's angle at 17 rad, put it above
///   `tolerance`; see [`Residual::rounding`]). On a singular matrix the increment along the
///   lost directions cannot shrink below the conditioning's round-off, but the equations hold:
///   such a step is accepted and counted (`rank_deficient_steps` when g_y has lost rank,
///   `near_singular_steps` when it kept its numerical rank). The test is not gated by the size of the increment: near a
///   singular position the multipliers of the vanishing rows grow like 1/σ_min(g_y) and the
///   round-off of their increments like cond(J)·ε·‖x‖∞ (A02 at its first horizontal passage,
///   h = 10⁻³, ρ∞ = 0.2: ‖λ‖∞ from 40 to 1 100 over the last three steps, increments stalled
///   at 1.3·10⁻² = 1.2·10⁻⁵ ‖x‖∞ with a residual of 3·10⁻¹⁰; an earlier gate at √tolerance ·
///   (1 + ‖x‖∞) refused that step). On a singular matrix the residual test is also required of
///   a step that passed the increment test: a least-squares increment vanishes where no
///   solution is (inconsistent joints).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonOptions {
    /// Converged when `‖Δx‖∞ ≤ tolerance · (1 + ‖x‖∞)` (see above for the residual test);
    /// default 1e-10.
    pub tolerance: f64,
    /// Iteration budget per step; default 25.
    pub max_iterations: usize,
}

impl Default for NewtonOptions {
    fn default() -> Self {
        Self {
            tolerance: 1e-10,
            max_iterations: 25,
        }
    }
}

/// How the step Newton iterations get their Jacobian.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum NewtonStrategy {
    /// Simplified Newton (the default): the Jacobian and its LU factorisation are kept across
    /// iterations and across steps of the same size (one per step size, a few sizes) while the
    /// increments contract by a factor ≤ ½ per iteration; they are rebuilt (by AD, at the
    /// current iterate) when the contraction slows, for a new step size, or when the solve is
    /// singular or not finite with a reused Jacobian. The iterates are extrapolated by
    /// Anderson's method ([`ANDERSON_DEPTH`]) while the matrix is regular. If the iteration
    /// budget runs out with a reused Jacobian, the step is redone from its start value by full
    /// Newton, so failures are those of full Newton. Same convergence test as full Newton, on
    /// the plain iterate x − Δx (the round-off stall exit only with a Jacobian built in this
    /// step or one whose plain iterates contract at [`TRUSTED_RATE`] or faster).
    #[default]
    Simplified,
    /// Full Newton: a fresh AD Jacobian at every iterate.
    Full,
}

/// The Jacobian a run carries from step to step (simplified Newton): its LU factorisation, the
/// step size and the system size it was built for.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct NewtonCache {
    /// Strategy.
    pub strategy: NewtonStrategy,
    /// LU factorisations keyed by (h, system size), most recently used last; a few, so that a
    /// periodic step pattern (h/3, 2h/3) reuses one per size.
    /// Read back checked (`stored_factor.rs`).
    #[serde(deserialize_with = "super::stored_factor::lu_list")]
    lu: Vec<(LU<f64, Dyn, Dyn>, f64, usize)>,
    /// The same for band LU factorisations ([`NewtonFactor::Banded`], large mechanisms).
    #[serde(default, deserialize_with = "super::stored_factor::band_lu_list")]
    banded: Vec<(BandLu, f64, usize)>,
    /// The same for numerically singular matrices (their SVD, [`NewtonFactor::Deficient`]).
    /// Not part of a checkpoint: a resumed run rebuilds it at its first step, so a run with
    /// rank-deficient joints resumes to the Newton tolerance, not bit for bit.
    #[serde(skip)]
    deficient: Vec<(NewtonFactor, f64, usize)>,
    /// Jacobians built (AD evaluations of the full matrix), for statistics.
    pub jacobians: u64,
    /// The last step's multipliers jumped ([`MULTIPLIER_JUMP`]): the next step starts Newton
    /// from zero multipliers ([`solve_step_with`]). Part of a checkpoint (absent from older
    /// ones: false), so that a resumed run starts where the uninterrupted one does.
    #[serde(default)]
    multipliers_jumped: bool,
}

/// A step's multipliers have jumped when their max-norm exceeds this many times 1 + the last
/// step's. Next to a singular position the multipliers of the vanishing rows grow like
/// 1/σ_min(g_y): on A02 (N = 10, h = 1e-3, generalized-α-SOI2) ‖λ‖∞ went 33, 37, 47, 59, 96,
/// 235 over the steps before its eighth passage, then 5.5·10⁴ on the step that landed 9.7·10⁻⁶
/// rad from the horizontal (docs/benchmarks.md, round 18).
const MULTIPLIER_JUMP: f64 = 30.0;

/// Jacobians kept per run (one per distinct step size, least recently used dropped).
const CACHED_JACOBIANS: usize = 4;

impl NewtonCache {
    /// An empty cache for `strategy`.
    pub fn new(strategy: NewtonStrategy) -> Self {
        Self {
            strategy,
            lu: Vec::new(),
            banded: Vec::new(),
            deficient: Vec::new(),
            jacobians: 0,
            multipliers_jumped: false,
        }
    }

    /// Removes and returns the factorisation kept for (h, n).
    fn take(&mut self, h: f64, n: usize) -> Option<NewtonFactor> {
        if let Some(i) = self.lu.iter().position(|(_, hc, nc)| *hc == h && *nc == n) {
            return Some(NewtonFactor::Regular(self.lu.remove(i).0));
        }
        if let Some(i) = self
            .banded
            .iter()
            .position(|(_, hc, nc)| *hc == h && *nc == n)
        {
            return Some(NewtonFactor::Banded(self.banded.remove(i).0));
        }
        let i = self
            .deficient
            .iter()
            .position(|(_, hc, nc)| *hc == h && *nc == n)?;
        Some(self.deficient.remove(i).0)
    }

    /// Keeps `factor` for (h, n) as the most recently used.
    fn put(&mut self, factor: NewtonFactor, h: f64, n: usize) {
        match factor {
            NewtonFactor::Regular(lu) => {
                if self.lu.len() >= CACHED_JACOBIANS {
                    self.lu.remove(0);
                }
                self.lu.push((lu, h, n));
            }
            NewtonFactor::Banded(lu) => {
                if self.banded.len() >= CACHED_JACOBIANS {
                    self.banded.remove(0);
                }
                self.banded.push((lu, h, n));
            }
            deficient => {
                if self.deficient.len() >= CACHED_JACOBIANS {
                    self.deficient.remove(0);
                }
                self.deficient.push((deficient, h, n));
            }
        }
    }
}

/// A method: formulation, coefficients, Newton settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Method {
    /// Equations solved.
    pub formulation: Formulation,
    /// α_m, α_f, β, γ.
    pub coefficients: Coefficients,
    /// Newton settings.
    pub newton: NewtonOptions,
}

/// State at t_n of a SOI2 run.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Soi2State {
    /// Steps done.
    pub step: u64,
    /// t_n.
    pub t: f64,
    /// y_n.
    pub y: Vec<f64>,
    /// z_n.
    pub z: Vec<f64>,
    /// λ_n.
    pub lambda: Vec<f64>,
    /// ψ_n.
    pub psi: Vec<f64>,
    /// a_{n+α} (≈ a(t_n + α h_{n−1})), as produced by the last step (not yet adjusted).
    pub a_alpha: Vec<f64>,
    /// M_{n+α} a_{n+α}; `None` before the first step (then M(t₀ + αh, y₀ + hαz₀) a_α is used).
    pub ma_alpha: Option<Vec<f64>>,
    /// a_{n−1+α} and M_{n−1+α} a_{n−1+α} as used by the last step (after adjustment), and that
    /// step's size h_{n−1}: what (14a)–(14b) interpolate from.
    pub previous: Option<(Vec<f64>, Vec<f64>, f64)>,
}

/// What one step reports besides the new state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepInfo {
    /// Newton iterations.
    pub iterations: usize,
    /// The Newton matrix was numerically singular, or the step was accepted on its residual
    /// test (see [`NewtonOptions`]).
    pub singular: bool,
    /// Numerical rank of (g_y; k_z) at (t₁, y₁, z₁) when `singular` (its rows otherwise).
    pub rank: Option<usize>,
    /// Attempts rejected for a Newton failure and retried with h/2 (variable-step runs).
    pub rejected: u64,
}

/// Newton failures before they get a step and a time.
enum NewtonFailure {
    Singular,
    Diverged {
        iterations: usize,
        residual: f64,
        increment: f64,
    },
}

/// Newton's method on `res` from `x`; the Jacobian of each iterate by forward-mode AD
/// (one dual evaluation per column).
fn solve_newton<R: Residual>(
    res: &R,
    x: &mut [f64],
    opts: &NewtonOptions,
) -> Result<StepInfo, NewtonFailure> {
    solve_newton_full(res, x, opts).map(|(info, _)| info)
}

/// The residual test of [`NewtonOptions`]: ‖F(x)‖∞ ≤ ‖J‖∞ · (tolerance · scale + rounding),
/// `norm` = ‖J‖∞ and `scale` = 1 + ‖x‖∞, and ‖F(x)‖∞ no larger than `start`, the residual of
/// the step's start value. Both sides of the first test grow with a diverging iterate, the
/// right one faster (J's second-derivative terms g_yyᵀλ grow with the multipliers, and
/// `scale` with them): on A02 (N = 10, step 14 452 after a step 10⁻⁵ rad from a singular
/// position) Newton wandered to multipliers of 10²⁷ and a residual of 10³⁰, from 1 at its
/// start, and that test passed it.
fn residual_holds<R: Residual>(
    res: &R,
    r: &DVector<f64>,
    norm: f64,
    (tolerance, scale): (f64, f64),
    start: f64,
) -> bool {
    let residual = r.amax();
    residual <= start && residual <= norm * (tolerance * scale + res.rounding())
}

/// Full Newton; also returns the factorisation of the last Jacobian (for reuse). Convergence:
/// the increment and residual tests of [`NewtonOptions`].
fn solve_newton_full<R: Residual>(
    res: &R,
    x: &mut [f64],
    opts: &NewtonOptions,
) -> Result<(StepInfo, NewtonFactor), NewtonFailure> {
    let n = res.size();
    let mut xd: Vec<Dual64> = x.iter().map(|&v| Dual64::from_re(v)).collect();
    let mut rd = vec![Dual64::from_re(0.0); n];
    let mut jac = Jacobian::for_residual(res);
    let mut r = DVector::<f64>::zeros(n);
    let mut increment = f64::INFINITY;
    let mut previous = f64::INFINITY;
    let mut singular = false;
    let mut start = f64::INFINITY;
    for it in 1..=opts.max_iterations {
        jac.build(res, x, &mut xd, &mut rd, &mut r);
        let rnorm = r.amax();
        if !rnorm.is_finite() {
            return Err(NewtonFailure::Diverged {
                iterations: it - 1,
                residual: rnorm,
                increment,
            });
        }
        if it == 1 {
            start = rnorm;
        }
        let factor = jac.factor(res, x);
        singular |= factor.deficient();
        let mut dx = r.clone();
        if !factor.solve_mut(&mut dx) {
            return Err(NewtonFailure::Singular);
        }
        let xnorm = max_norm(x);
        increment = dx.amax();
        for (xi, d) in x.iter_mut().zip(dx.iter()) {
            *xi -= d;
        }
        if !increment.is_finite() {
            return Err(NewtonFailure::Diverged {
                iterations: it,
                residual: rnorm,
                increment,
            });
        }
        let scale = 1.0 + xnorm.max(max_norm(x));
        // Converged, at the round-off floor, or stalled just above the tolerance (the increment
        // stopped shrinking: more iterations only stir round-off).
        let slow = increment >= 0.5 * previous;
        let stalled = slow && increment <= (100.0 * opts.tolerance * scale).max(res.noise_floor());
        let at_floor = at_rounding(increment, increment / previous, res.rounding());
        previous = increment;
        if increment <= opts.tolerance * scale || stalled || at_floor {
            // A least-squares increment also vanishes where no solution is: a singular matrix
            // must also pass the residual test.
            let holds = factor.singular_norm().is_none_or(|norm| {
                res.eval(x, r.as_mut_slice());
                residual_holds(res, &r, norm, (opts.tolerance, scale), start)
            });
            if holds {
                let info = StepInfo {
                    iterations: it,
                    singular,
                    ..StepInfo::default()
                };
                return Ok((info, factor));
            }
            continue;
        }
        if slow || factor.deficient() {
            // The residual test: the equations hold although the increment cannot shrink.
            res.eval(x, r.as_mut_slice());
            if residual_holds(
                res,
                &r,
                jac.row_sum_norm(res),
                (opts.tolerance, scale),
                start,
            ) {
                let info = StepInfo {
                    iterations: it,
                    singular: true,
                    ..StepInfo::default()
                };
                return Ok((info, factor));
            }
        }
    }
    res.eval(x, r.as_mut_slice());
    Err(NewtonFailure::Diverged {
        iterations: opts.max_iterations,
        residual: r.amax(),
        increment,
    })
}

/// Whether Newton's iterate after an increment of max-norm `increment`, contracting at `rate`,
/// is as close to the solution as the data's `rounding` ([`Residual::rounding`]) lets it be:
/// the error left, ρ/(1 − ρ)·‖Δx‖ with ρ the contraction ‖Δx‖/‖Δx_prev‖ (E. Hairer, G. Wanner,
/// *Solving Ordinary Differential Equations II*, 2nd ed., Springer 1996, §IV.8,
/// doi:10.1007/978-3-642-05221-7), is below it with a margin
/// ([`ROUNDING_MARGIN`]). Iterations past that point only stir round-off: on A02 (N = 40,
/// h = 10⁻³) the increments then hover at 0.3–1.5 roundings, above the tolerance
/// 10⁻¹⁰·(1 + ‖x‖∞), and each step spent 2–4 more iterations and often a new Jacobian before
/// the stall was recognised. Never on a first increment (no contraction measured yet).
fn at_rounding(increment: f64, rate: f64, rounding: f64) -> bool {
    rate > 0.0 && rate < 1.0 && rate / (1.0 - rate) * increment <= rounding / ROUNDING_MARGIN
}

/// The margin of [`at_rounding`]: a contraction measured from increments near round-off can
/// look small by chance, and a step accepted on it carries an error of the rounding's size into
/// the velocities (γh per step). Measured against `soi2_newton`'s test that simplified and full
/// Newton give the same trajectory to 10⁻⁸ (slider-crank, 2 s, h = 2⁻¹⁰, where the crank's angle
/// winds up and the rounding is large): margins 1 and 4 gave trajectories 1.4·10⁻⁸ and
/// 3.1·10⁻⁸ apart (measured with Newton started from an extrapolation of the last steps,
/// since dropped), 16 gives ≤ 4.9·10⁻⁹ with or without it (1.5·10⁻⁹ with the other tests
/// alone).
const ROUNDING_MARGIN: f64 = 16.0;

/// Largest contraction ‖Δx_{k+1}‖/‖Δx_k‖ simplified Newton accepts before it rebuilds the
/// Jacobian.
const CONTRACTION_LIMIT: f64 = 0.5;

/// Iterates besides the last that Anderson's method combines in simplified Newton
/// ([`solve_newton_simplified`]). On A02 (N = 40, h = 10⁻³, 3 s; docs/benchmarks.md, round 19)
/// depths 1, 2, 3 gave 6.08, 5.49, 5.46 iterates a step for generalized-α-SOI2 (7.14 without
/// Anderson's method).
const ANDERSON_DEPTH: usize = 2;

/// A reused Jacobian whose plain iterates contracted at this rate or faster is trusted with the
/// round-off stall exit ([`NewtonOptions`]): increments that then stop shrinking below the noise
/// floor are round-off, not the Jacobian's age. On A02 (N = 40, h = 10⁻³, 3 s) the step's
/// increments stall at 1–10·10⁻⁸ (the multipliers' noise floor, above the tolerance
/// 10⁻¹⁰·(1 + ‖x‖∞)), and without this exit each such step rebuilt its Jacobian to leave:
/// 0.31 Jacobians a step for generalized-α-SOI2; 0.11 with a trusted rate of 0.1, 0.09 with 0.25.
const TRUSTED_RATE: f64 = 0.25;

/// Simplified Newton with the Jacobian of `cache` (see [`NewtonStrategy::Simplified`]); `h` keys
/// the cached Jacobian. Falls back to full Newton from the start value when the budget runs out
/// with a reused Jacobian.
fn solve_newton_simplified<R: Residual>(
    res: &R,
    x: &mut [f64],
    opts: &NewtonOptions,
    cache: &mut NewtonCache,
    h: f64,
) -> Result<StepInfo, NewtonFailure> {
    let n = res.size();
    let mut current = cache.take(h, n);
    let x_start = x.to_vec();
    let mut xd: Vec<Dual64> = vec![Dual64::from_re(0.0); n];
    let mut rd = vec![Dual64::from_re(0.0); n];
    // Allocated at the first Jacobian this step builds: on A02 at N = 40 it has 322² entries,
    // and a step builds 0.4 Jacobians on average; zeroing it at every step (830 kB) and M's
    // dense product below made 0.33 M of the 6.89 M instructions of a soi2_generalized_alpha
    // step (callgrind).
    let mut jac: Option<Jacobian> = None;
    let mut r = DVector::<f64>::zeros(n);
    let mut dx = DVector::<f64>::zeros(n);
    // The Jacobian in use was built during this step (not carried over from an earlier one).
    let mut built_here = false;
    let mut singular = current.as_ref().is_some_and(NewtonFactor::deficient);
    let mut iterates = Iterates::new();
    // The residual of the start value.
    let mut start = f64::INFINITY;
    let mut stopped = None;
    for it in 1..=opts.max_iterations {
        if current.is_none() {
            let jac = jac.get_or_insert_with(|| Jacobian::for_residual(res));
            jac.build(res, x, &mut xd, &mut rd, &mut r);
            cache.jacobians += 1;
            let factor = jac.factor(res, x);
            singular |= factor.deficient();
            current = Some(factor);
            built_here = true;
            iterates.restart();
        } else {
            res.eval(x, r.as_mut_slice());
        }
        let rnorm = r.amax();
        if it == 1 {
            start = rnorm;
        }
        if !built_here && rnorm > start {
            // A reused Jacobian took the iterate further from the equations than the start
            // value was: the iterate is no place to build one (on A02 next to a singular
            // position, the first increment of an old Jacobian was 2·10⁹, and Newton never
            // came back from there with Jacobians built at its iterates); full Newton starts
            // over from the start value.
            break;
        }
        let Some(factor) = current.as_ref() else {
            unreachable!("the Jacobian was just built");
        };
        // The reused factorisation of a failed iterate is dropped (not put back).
        let failure = if !rnorm.is_finite() {
            Some(NewtonFailure::Diverged {
                iterations: it - 1,
                residual: rnorm,
                increment: iterates.previous,
            })
        } else {
            dx.copy_from(&r);
            if !factor.solve_mut(&mut dx) {
                Some(NewtonFailure::Singular)
            } else if !dx.amax().is_finite() {
                Some(NewtonFailure::Diverged {
                    iterations: it,
                    residual: rnorm,
                    increment: dx.amax(),
                })
            } else {
                None
            }
        };
        if let Some(failure) = failure {
            // A Jacobian of this step fails the step; a reused one hands it to full Newton.
            stopped = Some(failure).filter(|_| built_here);
            break;
        }
        let xnorm = max_norm(x);
        let increment = dx.amax();
        let x_here = x.to_vec();
        for (xi, d) in x.iter_mut().zip(dx.iter()) {
            *xi -= d;
        }
        let scale = 1.0 + xnorm.max(max_norm(x));
        let slow = increment >= CONTRACTION_LIMIT * iterates.previous;
        let rate = iterates.rate(increment);
        let test = IterateTest {
            increment,
            rate,
            slow,
            scale,
            start,
            built_here,
            // Stalled at the round-off floor: only trusted with a Jacobian of this step, or
            // with an older one whose plain iterates contracted fast (otherwise slow
            // contraction is the Jacobian's fault).
            trusted: built_here || iterates.contract_fast(),
        };
        let (converged, on_residual) =
            test.passes(res, x, &mut r, opts.tolerance, (factor, jac.as_ref()));
        singular |= on_residual;
        if converged {
            if let Some(factor) = current {
                cache.put(factor, h, n);
            }
            return Ok(StepInfo {
                iterations: it,
                singular,
                ..StepInfo::default()
            });
        }
        // Rebuilt at the next iterate when the contraction is slow, or when a Jacobian of an
        // earlier step cannot reach the tolerance.
        let left = opts.max_iterations - it;
        let hopeless = !built_here && hopeless(increment, rate, left, opts.tolerance * scale);
        if slow || hopeless {
            current = None;
        } else if !singular {
            iterates.extrapolate(&x_here, x);
        }
        iterates.previous = increment;
        if it == opts.max_iterations && built_here {
            res.eval(x, r.as_mut_slice());
            stopped = Some(NewtonFailure::Diverged {
                iterations: opts.max_iterations,
                residual: r.amax(),
                increment: iterates.previous,
            });
        }
    }
    if let Some(failure) = stopped {
        return Err(failure);
    }
    x.copy_from_slice(&x_start);
    let (info, factor) = solve_newton_full(res, x, opts)?;
    cache.jacobians += info.iterations as u64;
    cache.put(factor, h, n);
    Ok(info)
}

/// One iterate of simplified Newton, as its convergence test sees it.
struct IterateTest {
    /// ‖Δx‖∞ and the contraction ρ of the plain iterates ([`Iterates::rate`]).
    increment: f64,
    rate: f64,
    /// ‖Δx‖ ≥ [`CONTRACTION_LIMIT`] times the last one.
    slow: bool,
    /// 1 + ‖x‖∞ over the iterate and the one before.
    scale: f64,
    /// The residual of the start value ([`residual_holds`]).
    start: f64,
    /// The Jacobian in use was built in this step.
    built_here: bool,
    /// The round-off stall exit is trusted to the Jacobian ([`TRUSTED_RATE`]).
    trusted: bool,
}

impl IterateTest {
    /// Whether the iterate `x` passes the tests of [`NewtonOptions`] (the increment test, the
    /// round-off exits, the residual test on a singular factorisation or on stalled increments
    /// with a Jacobian of this step), and whether it passed on the residual test after the
    /// increment test failed (a step then counted singular). `factor` is the factorisation in
    /// use, `jac` the Jacobian built in this step if any; `r` is scratch for the residual.
    fn passes<R: Residual>(
        &self,
        res: &R,
        x: &[f64],
        r: &mut DVector<f64>,
        tolerance: f64,
        (factor, jac): (&NewtonFactor, Option<&Jacobian>),
    ) -> (bool, bool) {
        let bound = (tolerance, self.scale);
        let stalled = self.trusted
            && self.slow
            && self.increment <= (100.0 * tolerance * self.scale).max(res.noise_floor());
        let at_floor = at_rounding(self.increment, self.rate, res.rounding());
        let mut converged = self.increment <= tolerance * self.scale || stalled || at_floor;
        if converged && let Some(norm) = factor.singular_norm() {
            // A least-squares increment also vanishes where no solution is.
            res.eval(x, r.as_mut_slice());
            converged = residual_holds(res, r, norm, bound, self.start);
        }
        if !converged
            && self.built_here
            && (self.slow || factor.deficient())
            && let Some(jac) = jac
        {
            // The residual test (the Jacobian of this step is in `jac`).
            res.eval(x, r.as_mut_slice());
            let holds = residual_holds(res, r, jac.row_sum_norm(res), bound, self.start);
            return (holds, holds);
        }
        (converged, false)
    }
}

/// Whether iterates contracting at `rate` from an increment of max-norm `increment` cannot
/// reach `tolerance` within `left` iterations, ‖Δx‖ ρ^left / (1 − ρ) > tolerance (Hairer &
/// Wanner's test for reusing a Jacobian): near a singular position an old Jacobian contracts at
/// ρ ≈ ½ for the whole budget.
fn hopeless(increment: f64, rate: f64, left: usize, tolerance: f64) -> bool {
    let left = i32::try_from(left).unwrap_or(i32::MAX);
    rate < 1.0 && increment * rate.powi(left) / (1.0 - rate) > tolerance
}

/// Simplified Newton's iterates under one Jacobian: the contraction of their increments and
/// their extrapolation by Anderson's method.
struct Iterates {
    /// ‖Δx‖∞ of the last iterate (∞ before the first).
    previous: f64,
    /// The contraction of the plain iterates x − Δx with this Jacobian, measured on its first
    /// two increments (before any extrapolation).
    plain_rate: Option<f64>,
    /// The current iterate was extrapolated.
    extrapolated: bool,
    accelerator: Accelerator,
}

impl Iterates {
    fn new() -> Self {
        Self {
            previous: f64::INFINITY,
            plain_rate: None,
            extrapolated: false,
            accelerator: Accelerator::new(ANDERSON_DEPTH),
        }
    }

    /// A new Jacobian: a new map, its contraction measured afresh.
    fn restart(&mut self) {
        self.previous = f64::INFINITY;
        self.plain_rate = None;
        self.extrapolated = false;
        self.accelerator.clear();
    }

    /// The contraction the error estimates take for an iterate of max-norm `increment`: that
    /// of the plain iterates x − Δx, the one accepted. After an extrapolation
    /// ‖Δx_k‖/‖Δx_{k−1}‖ measures Anderson's method, up to 300× faster on A02 (0.001 against
    /// 0.33), and would understate the accepted iterate's error by as much.
    fn rate(&mut self, increment: f64) -> f64 {
        let rate = increment / self.previous;
        if self.extrapolated {
            rate.max(self.plain_rate.unwrap_or(rate))
        } else {
            if self.previous.is_finite() {
                self.plain_rate = Some(rate);
            }
            rate
        }
    }

    /// The plain iterates contract at [`TRUSTED_RATE`] or faster.
    fn contract_fast(&self) -> bool {
        self.plain_rate.is_some_and(|p| p <= TRUSTED_RATE)
    }

    /// Replaces the plain iterate `x` = `x_here` − Δx by Anderson's extrapolation on the map
    /// x ↦ x − J⁻¹F(x) of the reused Jacobian J ([`crate::anderson`]): near a solution that
    /// map is linear, contracting at the rate J's age gives it, and the method is then GMRES
    /// preconditioned by J. On A02 an old Jacobian leaves the multipliers contracting at 0.33
    /// an iterate (the accelerations converge in two); extrapolated, they converge in two more.
    fn extrapolate(&mut self, x_here: &[f64], x: &mut [f64]) {
        self.extrapolated = self.accelerator.extrapolates();
        let g = x.to_vec();
        x.copy_from_slice(&self.accelerator.next(x_here, g));
    }
}

/// The error of a Newton failure at `step`, time `t`, with the numerical rank of (g_y; k_z)
/// at the last iterate and the number of constraints.
fn newton_error(
    f: NewtonFailure,
    step: u64,
    t: f64,
    context: &'static str,
    (rank, constraints): (usize, usize),
) -> Soi2Error {
    match f {
        NewtonFailure::Singular => Soi2Error::SingularNewtonMatrix { step, t, context },
        NewtonFailure::Diverged {
            iterations,
            residual,
            increment,
        } => Soi2Error::NewtonDiverged {
            step,
            t,
            iterations,
            residual,
            increment,
            rank,
            constraints,
        },
    }
}

/// Numerical rank of (g_y; k_z) at (t, y, z) and the number of constraints.
fn rank_at<M: ConstrainedModel + ?Sized>(
    model: &M,
    t: f64,
    y: &[f64],
    z: &[f64],
) -> (usize, usize) {
    let d = model.dims();
    (
        constraint_numerical_rank(model, t, y, z),
        d.holonomic + d.nonholonomic,
    )
}

/// Replaces the multipliers by their minimum-norm representatives P λ (P the projector onto the
/// column space of g_y, see [`range_projection`]): for an additive model f depends on λ through
/// g_yᵀλ only, which P keeps. Other models keep their λ.
fn minimum_norm_multipliers<M: ConstrainedModel + ?Sized>(
    model: &M,
    projector: &DMatrix<f64>,
    lambda: &mut [f64],
) {
    let mg = lambda.len();
    if !model.additive() || mg == 0 || projector.nrows() < mg {
        return;
    }
    let p = projector.view((0, 0), (mg, mg));
    let l = p * DVector::from_column_slice(lambda);
    lambda.copy_from_slice(l.as_slice());
}

fn c<T: Scalar>(v: f64) -> T {
    T::from(v)
}

/// Consistent-acceleration system at (t, y, z) (§6): unknowns (a, λ, ψ),
/// `M(t,y)a − f(t,y,z,λ,ψ) = 0`, `g_tt + 2g_ty z + g_yy(z,z) + g_y a = 0`, `k_t + k_y z + k_z a = 0`.
struct AccelerationSystem<'a, M: ?Sized> {
    model: &'a M,
    dims: Dims,
    t: f64,
    y: &'a [f64],
    z: &'a [f64],
}

impl<M: ConstrainedModel + ?Sized> Residual for AccelerationSystem<'_, M> {
    fn size(&self) -> usize {
        self.dims.n + self.dims.holonomic + self.dims.nonholonomic
    }

    fn joints_deficient(&self, _x: &[f64]) -> bool {
        let d = self.dims;
        constraint_numerical_rank(self.model, self.t, self.y, self.z) < d.holonomic + d.nonholonomic
    }

    /// Unknowns (a, λ) and rows (dynamics, joints): one block of each.
    fn pattern(&self) -> Option<&Pattern> {
        if self.dims.nonholonomic > 0 {
            return None;
        }
        self.model.newton_pattern(1)
    }

    fn eval<T: Scalar>(&self, x: &[T], r: &mut [T]) {
        let Dims {
            n,
            holonomic: mg,
            nonholonomic: mk,
        } = self.dims;
        let (a, rest) = x.split_at(n);
        let (lambda, psi) = rest.split_at(mg);
        let t: T = c(self.t);
        let y: Vec<T> = self.y.iter().map(|&v| c(v)).collect();
        let z: Vec<T> = self.z.iter().map(|&v| c(v)).collect();
        let mut m = vec![T::zero(); n * n];
        self.model.mass(t, &y, &mut m);
        let mut f = vec![T::zero(); n];
        self.model.force(t, &y, &z, lambda, psi, &mut f);
        let (r_dyn, r_rest) = r.split_at_mut(n);
        for i in 0..n {
            let mut s = -f[i];
            for j in 0..n {
                s += m[i * n + j] * a[j];
            }
            r_dyn[i] = s;
        }
        let (r_g, r_k) = r_rest.split_at_mut(mg);
        g_ddot(self.model, t, &y, &z, a, r_g);
        k_dot(self.model, t, &y, &z, a, &mut r_k[..mk]);
    }
}

/// Consistent (a, λ, ψ) at one (t, y, z).
pub type Consistent = (Vec<f64>, Vec<f64>, Vec<f64>);

/// The consistent (a, λ, ψ) at (t, y, z), by Newton from a = 0 and the given λ, ψ guesses.
#[allow(clippy::too_many_arguments)]
pub fn consistent_acceleration<M: ConstrainedModel + ?Sized>(
    model: &M,
    t: f64,
    y: &[f64],
    z: &[f64],
    lambda_guess: &[f64],
    psi_guess: &[f64],
    newton: &NewtonOptions,
    step: u64,
) -> Result<Consistent, Soi2Error> {
    let dims = model.dims();
    let sys = AccelerationSystem {
        model,
        dims,
        t,
        y,
        z,
    };
    let mut x = vec![0.0; dims.n];
    x.extend_from_slice(lambda_guess);
    x.extend_from_slice(psi_guess);
    // The consistent acceleration needs a tight solve whatever the step tolerance.
    let opts = NewtonOptions {
        tolerance: newton.tolerance.min(1e-12),
        max_iterations: newton.max_iterations.max(50),
    };
    let info = solve_newton(&sys, &mut x, &opts).map_err(|e| {
        newton_error(
            e,
            step,
            t,
            "consistent acceleration (12)",
            rank_at(model, t, y, z),
        )
    })?;
    let psi = x.split_off(dims.n + dims.holonomic);
    let mut lambda = x.split_off(dims.n);
    if info.singular {
        let (_, projector) = constraint_rank(model, t, y, z);
        minimum_norm_multipliers(model, &projector, &mut lambda);
    }
    Ok((x, lambda, psi))
}

/// (a_{1+α}, λ₁, ψ₁, ã_{1+α}) unpacked from a step's unknowns.
type StepUnknowns = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

/// The equations of one step for the Newton solver.
struct StepSystem<'a, M: ?Sized> {
    model: &'a M,
    dims: Dims,
    method: &'a Method,
    t1: f64,
    h: f64,
    y0: &'a [f64],
    z0: &'a [f64],
    a_alpha: &'a [f64],
    ma_alpha: &'a [f64],
    /// f(t₀, y₀, z₀, λ₀, ψ₀).
    f0: &'a [f64],
    /// The nonzero entries (i, j, M_ij) of M_{1+α}: every product with it runs over these
    /// (a mechanism's M couples few coordinates).
    m1: &'a [(usize, usize, f64)],
}

impl<M: ConstrainedModel + ?Sized> StepSystem<'_, M> {
    /// y₁ of (13a)/(17a) for the acceleration `at` (ã_{1+α}, or a_{1+α} + δ̃, or a_{1+α} for I3).
    fn y1<T: Scalar>(&self, at: &[T]) -> Vec<T> {
        let Coefficients { beta, .. } = self.method.coefficients;
        let h = self.h;
        (0..self.dims.n)
            .map(|i| {
                at[i] * (h * h * beta)
                    + c::<T>(
                        self.y0[i]
                            + h * self.z0[i]
                            + 0.5 * h * h * (1.0 - 2.0 * beta) * self.a_alpha[i],
                    )
            })
            .collect()
    }

    /// (a_{1+α}, λ₁, ψ₁, the acceleration of y₁) from the unknowns x of the formulation.
    fn unpack(&self, x: &[f64]) -> StepUnknowns {
        let Dims {
            n,
            holonomic: mg,
            nonholonomic: mk,
        } = self.dims;
        match self.method.formulation {
            Formulation::General | Formulation::Additive => (
                x[n..2 * n].to_vec(),
                x[2 * n + mg..2 * n + 2 * mg].to_vec(),
                x[2 * n + 2 * mg + mk..].to_vec(),
                x[..n].to_vec(),
            ),
            Formulation::HhtSoi2 => {
                let a = x[n..2 * n].to_vec();
                let at = a.iter().zip(&x[..n]).map(|(u, d)| u + d).collect();
                (a, x[2 * n + mg..].to_vec(), Vec::new(), at)
            }
            Formulation::HhtI3 => (
                x[..n].to_vec(),
                x[n..].to_vec(),
                Vec::new(),
                x[..n].to_vec(),
            ),
        }
    }

    /// z of (13b)/(13c)/(17b) for the acceleration `a`.
    fn z1<T: Scalar>(&self, a: &[T]) -> Vec<T> {
        let Coefficients { gamma, .. } = self.method.coefficients;
        let h = self.h;
        (0..self.dims.n)
            .map(|i| a[i] * (h * gamma) + c::<T>(self.z0[i] + h * (1.0 - gamma) * self.a_alpha[i]))
            .collect()
    }

    /// out = s·M_{1+α} a + w·M_α a_α − wf·f − α_f f₀ (rows of (13d), (13e), (17d)).
    fn dynamics<T: Scalar>(&self, s: f64, a: &[T], wf: f64, f: &[T], out: &mut [T]) {
        let n = self.dims.n;
        let Coefficients {
            alpha_m, alpha_f, ..
        } = self.method.coefficients;
        for i in 0..n {
            out[i] = c::<T>(alpha_m * self.ma_alpha[i] - alpha_f * self.f0[i]) - f[i] * wf;
        }
        for &(i, j, mij) in self.m1 {
            out[i] += a[j] * (s * mij);
        }
    }
}

impl<M: ConstrainedModel + ?Sized> Residual for StepSystem<'_, M> {
    fn size(&self) -> usize {
        let Dims {
            n,
            holonomic: mg,
            nonholonomic: mk,
        } = self.dims;
        match self.method.formulation {
            Formulation::General | Formulation::Additive => 2 * n + 2 * mg + 2 * mk,
            Formulation::HhtSoi2 => 2 * n + 2 * mg,
            Formulation::HhtI3 => n + mg,
        }
    }

    /// Also true when the joints were rank-deficient at the start of the step (y₀, z₀, on the
    /// manifold, where the rank is sharp): off the manifold a redundant joint's singular value
    /// is small but not below the rank threshold, and the LU of a Newton matrix whose pivots
    /// spanned 1.6e-16 (Bricard at h = 4e-3, t = 4.0 s) gave an increment that diverged.
    fn joints_deficient(&self, x: &[f64]) -> bool {
        let (a, _, _, at) = self.unpack(x);
        let (y, z) = (self.y1(&at), self.z1(&a));
        let d = self.dims;
        let rows = d.holonomic + d.nonholonomic;
        constraint_numerical_rank(self.model, self.t1, &y, &z) < rows
            || constraint_numerical_rank(self.model, self.t1 - self.h, self.y0, self.z0) < rows
    }

    /// Every formulation orders its unknowns and rows as [`Pattern`] describes: coordinate
    /// blocks (two, one for HHT-I3) then joint blocks.
    fn pattern(&self) -> Option<&Pattern> {
        if self.dims.nonholonomic > 0 {
            return None;
        }
        let blocks = match self.method.formulation {
            Formulation::HhtI3 => 1,
            Formulation::General | Formulation::Additive | Formulation::HhtSoi2 => 2,
        };
        self.model.newton_pattern(blocks)
    }

    /// Position-level rows g(t₁, y₁)/(βh²) carry round-off ε|y|/(βh²), which becomes
    /// acceleration noise of that size.
    fn noise_floor(&self) -> f64 {
        25.0 * self.rounding()
    }

    /// y₁ = y₀ + h z₀ + ½h²(1 − 2β) a_α + βh² a (13a)/(17a) is a sum of four rounded terms and
    /// g(t₁, y₁) a sum of rounded functions of it: together a few units ε(1 + ‖y‖∞) of the
    /// positions, which the position rows g/(βh²) see as the change 4ε(1 + ‖y₀‖∞)/(βh²) of the
    /// acceleration they are solved for. Coordinates that grow without bound (the angles of a
    /// rotating crank) make it dominate: A02 at t = 6.6 s has |φ| ≈ 17 rad, the position rows
    /// cannot be evaluated closer than ulp(17)/(βh²) = 1.3·10⁻⁸ at h = 10⁻³, β = 0.276, and
    /// the residual of the HHT schemes stalled there, 100× above tolerance · ‖J‖∞(1 + ‖x‖∞);
    /// with the angles reduced modulo 2π the same steps converged.
    fn rounding(&self) -> f64 {
        let beta = self.method.coefficients.beta;
        4.0 * f64::EPSILON * (1.0 + max_norm(self.y0)) / (beta * self.h * self.h)
    }

    fn eval<T: Scalar>(&self, x: &[T], r: &mut [T]) {
        let Dims {
            n,
            holonomic: mg,
            nonholonomic: mk,
        } = self.dims;
        let Coefficients {
            alpha_m,
            alpha_f,
            beta,
            gamma,
        } = self.method.coefficients;
        let t1: T = c(self.t1);
        let h = self.h;
        let sg = 1.0 / (beta * h * h); // scale of position-level rows
        let sv = 1.0 / (gamma * h); // scale of velocity-level rows
        let zero = Vec::<T>::new();
        match self.method.formulation {
            Formulation::General | Formulation::Additive => {
                // x = [ã_{1+α}, a_{1+α}, λ̃₁, λ₁, ψ̃₁, ψ₁]
                let (at, rest) = x.split_at(n);
                let (a, rest) = rest.split_at(n);
                let (lt, rest) = rest.split_at(mg);
                let (l, rest) = rest.split_at(mg);
                let (pt, p) = rest.split_at(mk);
                let y1 = self.y1(at); // (13a)
                let zt1 = self.z1(at); // (13b)
                let z1 = self.z1(a); // (13c)
                let (r_d, rest) = r.split_at_mut(n);
                let (r_e, rest) = rest.split_at_mut(n);
                let (r_f, rest) = rest.split_at_mut(mg);
                let (r_g, rest) = rest.split_at_mut(mg);
                let (r_h, r_i) = rest.split_at_mut(mk);
                let general = self.method.formulation == Formulation::General;
                let multipliers: &[(&[T], &[T])] = if general {
                    &[(l, p), (lt, pt)]
                } else {
                    &[(l, p)]
                };
                let terms = self
                    .model
                    .state_terms(t1, (&y1, &z1), multipliers, !general);
                // (13e)
                self.dynamics(1.0 - alpha_m, a, 1.0 - alpha_f, &terms.forces[0], r_e);
                if general {
                    // (13d): f at (t₁, y₁, z₁, λ̃₁, ψ̃₁).
                    self.dynamics(1.0 - alpha_m, at, 1.0 - alpha_f, &terms.forces[1], r_d);
                } else {
                    // Additive (13d): (1−α_m)M_{1+α}(ã − a) − (1−α_f)[g_yᵀ(λ₁ − λ̃₁) + k_zᵀ(ψ₁ − ψ̃₁)].
                    let mut kz = vec![T::zero(); mk * n];
                    self.model.k_z(t1, &y1, &z1, &mut kz);
                    r_d.fill(T::zero());
                    for &(i, j, mij) in self.m1 {
                        r_d[i] += (at[j] - a[j]) * ((1.0 - alpha_m) * mij);
                    }
                    for &(q, i, g) in &terms.g_y {
                        r_d[i] -= g * (l[q] - lt[q]) * (1.0 - alpha_f);
                    }
                    for (i, r) in r_d.iter_mut().enumerate() {
                        for q in 0..mk {
                            *r -= kz[q * n + i] * (p[q] - pt[q]) * (1.0 - alpha_f);
                        }
                    }
                }
                // (13f), (13g)
                r_f.copy_from_slice(&terms.g);
                r_g.copy_from_slice(&terms.g_dot);
                // (13h), (13i)
                self.model.k(t1, &y1, &zt1, r_h);
                self.model.k(t1, &y1, &z1, r_i);
                r_f.iter_mut().for_each(|v| *v *= sg);
                r_g.iter_mut()
                    .chain(r_h.iter_mut())
                    .chain(r_i.iter_mut())
                    .for_each(|v| *v *= sv);
            }
            Formulation::HhtSoi2 => {
                // x = [δ̃, a_{1+α}, μ̃, λ₁], α = −α_f.
                let alpha = -alpha_f;
                let (delta, rest) = x.split_at(n);
                let (a, rest) = rest.split_at(n);
                let (mu, l) = rest.split_at(mg);
                let at: Vec<T> = a.iter().zip(delta).map(|(&u, &d)| u + d).collect();
                let y1 = self.y1(&at); // (17a)
                let z1 = self.z1(a); // (17b)
                let (r_c, rest) = r.split_at_mut(n);
                let (r_d, rest) = rest.split_at_mut(n);
                let (r_e, r_f) = rest.split_at_mut(mg);
                let terms = self.model.state_terms(t1, (&y1, &z1), &[(l, &zero)], true);
                // (17c): M_{1+α} δ̃ − g_yᵀ(t₁, y₁) μ̃
                r_c.fill(T::zero());
                for &(i, j, mij) in self.m1 {
                    r_c[i] += delta[j] * mij;
                }
                for &(q, i, g) in &terms.g_y {
                    r_c[i] -= g * mu[q];
                }
                // (17d): M_{1+α} a − (1+α) f(t₁, y₁, z₁, λ₁) + α f₀
                self.dynamics(1.0, a, 1.0 + alpha, &terms.forces[0], r_d);
                // (17e), (17f)
                r_e.copy_from_slice(&terms.g);
                r_f.copy_from_slice(&terms.g_dot);
                r_e.iter_mut().for_each(|v| *v *= sg);
                r_f.iter_mut().for_each(|v| *v *= sv);
            }
            Formulation::HhtI3 => {
                // x = [a_{1+α}, λ₁]
                let alpha = -alpha_f;
                let (a, l) = x.split_at(n);
                let y1 = self.y1(a); // (2a)
                let z1 = self.z1(a); // (2b)
                let (r_d, r_e) = r.split_at_mut(n);
                let terms = self.model.state_terms(t1, (&y1, &z1), &[(l, &zero)], false);
                self.dynamics(1.0, a, 1.0 + alpha, &terms.forces[0], r_d); // (2c) with α_m = 0
                r_e.copy_from_slice(&terms.g); // index-3 position constraint
                r_e.iter_mut().for_each(|v| *v *= sg);
            }
        }
    }
}

/// The result of one step, before it is committed to the state.
#[derive(Debug, Clone, PartialEq)]
pub struct StepResult {
    /// y₁.
    pub y: Vec<f64>,
    /// z₁.
    pub z: Vec<f64>,
    /// a_{1+α}.
    pub a: Vec<f64>,
    /// M_{1+α} a_{1+α}.
    pub ma: Vec<f64>,
    /// λ₁.
    pub lambda: Vec<f64>,
    /// ψ₁.
    pub psi: Vec<f64>,
    /// M_α a_α the step used (what (14b) interpolates from at the next step).
    pub ma_alpha_used: Vec<f64>,
    /// Newton report.
    pub info: StepInfo,
}

/// Applies the step-size adjustments (14a)–(14b) for a new step of size `h` to the state's
/// a_{n+α} and M_{n+α} a_{n+α}:
/// `a_{n+α} := a_{n+α} + α(h_n/h_{n−1} − 1)(a_{n+α} − a_{n−1+α})` (14a), and the same for M a (14b).
/// No-op on the first step or when the size does not change.
pub fn adjust_for_step(state: &mut Soi2State, alpha: f64, h: f64) {
    let Some((a_prev, ma_prev, h_prev)) = &state.previous else {
        return;
    };
    let w = alpha * (h / h_prev - 1.0);
    if w == 0.0 {
        return;
    }
    for (a, ap) in state.a_alpha.iter_mut().zip(a_prev) {
        *a += w * (*a - ap);
    }
    if let Some(ma) = state.ma_alpha.as_mut() {
        for (v, vp) in ma.iter_mut().zip(ma_prev) {
            *v += w * (*v - vp);
        }
    }
}

/// Solves one step of size `h` from `state` (already adjusted) without changing it, by full
/// Newton.
pub fn solve_step<M: ConstrainedModel + ?Sized>(
    model: &M,
    method: &Method,
    state: &Soi2State,
    h: f64,
) -> Result<StepResult, Soi2Error> {
    solve_step_with(
        model,
        method,
        state,
        h,
        &mut NewtonCache::new(NewtonStrategy::Full),
    )
}

/// [`solve_step`] with the Newton strategy and the Jacobian carried over in `cache`.
pub fn solve_step_with<M: ConstrainedModel + ?Sized>(
    model: &M,
    method: &Method,
    state: &Soi2State,
    h: f64,
    cache: &mut NewtonCache,
) -> Result<StepResult, Soi2Error> {
    let dims = model.dims();
    let n = dims.n;
    let alpha = method.coefficients.alpha();
    let t0 = state.t;
    let t1 = t0 + h;
    let step = state.step + 1;
    // M_{1+α} := M(t_{1+α}, y₀ + h(1+α)z₀)
    let y_pred: Vec<f64> = state
        .y
        .iter()
        .zip(&state.z)
        .map(|(y, z)| y + h * (1.0 + alpha) * z)
        .collect();
    let mut m1 = Vec::new();
    model.mass_entries_at(t0 + (1.0 + alpha) * h, &y_pred, &mut m1);
    let ma_alpha = ma_used(model, method, state, h);
    let mut f0 = vec![0.0; n];
    model.force(t0, &state.y, &state.z, &state.lambda, &state.psi, &mut f0);
    let sys = StepSystem {
        model,
        dims,
        method,
        t1,
        h,
        y0: &state.y,
        z0: &state.z,
        a_alpha: &state.a_alpha,
        ma_alpha: &ma_alpha,
        f0: &f0,
        m1: &m1,
    };
    // Start from the previous values (tilded = untilded, corrections 0).
    let mut x = Vec::with_capacity(sys.size());
    match method.formulation {
        Formulation::General | Formulation::Additive => {
            x.extend_from_slice(&state.a_alpha);
            x.extend_from_slice(&state.a_alpha);
            x.extend_from_slice(&state.lambda);
            x.extend_from_slice(&state.lambda);
            x.extend_from_slice(&state.psi);
            x.extend_from_slice(&state.psi);
        }
        Formulation::HhtSoi2 => {
            x.extend(std::iter::repeat_n(0.0, n));
            x.extend_from_slice(&state.a_alpha);
            x.extend(std::iter::repeat_n(0.0, dims.holonomic));
            x.extend_from_slice(&state.lambda);
        }
        Formulation::HhtI3 => {
            x.extend_from_slice(&state.a_alpha);
            x.extend_from_slice(&state.lambda);
        }
    }
    if cache.multipliers_jumped {
        // After a step next to a singular position, its multipliers (of size 1/σ_min along the
        // vanishing rows, carrying a finite force g_yᵀλ there) are no start for this step,
        // where σ_min has grown: on A02 their force was 260× too large at the first iterate,
        // the increments 3·10⁷, and Newton then contracted at 0.4 an iterate and ran out of
        // iterations. From zero the first residual is the size of the constraint forces.
        let (a_len, lambda_len) = (n, dims.holonomic);
        let multipliers = match method.formulation {
            Formulation::General | Formulation::Additive | Formulation::HhtSoi2 => {
                2 * a_len..2 * a_len + 2 * lambda_len
            }
            Formulation::HhtI3 => a_len..a_len + lambda_len,
        };
        x[multipliers].fill(0.0);
    }
    let solved = match cache.strategy {
        NewtonStrategy::Full => solve_newton_full(&sys, &mut x, &method.newton).map(|(i, _)| {
            cache.jacobians += i.iterations as u64;
            i
        }),
        NewtonStrategy::Simplified => {
            solve_newton_simplified(&sys, &mut x, &method.newton, cache, h)
        }
    };
    let (a, mut lambda, psi, at) = sys.unpack(&x);
    cache.multipliers_jumped =
        solved.is_ok() && max_norm(&lambda) > MULTIPLIER_JUMP * (1.0 + max_norm(&state.lambda));
    let mut info = solved.map_err(|e| {
        let (y, z) = (sys.y1(&at), sys.z1(&a));
        newton_error(e, step, t1, "step", rank_at(model, t1, &y, &z))
    })?;
    let y = sys.y1(&at);
    let z = sys.z1(&a);
    if info.singular {
        // A step accepted on its residual near a singular position may still have joints of
        // full rank: their projector is the identity, and the multipliers are already the
        // minimum-norm ones (the singular values decide without the O(m³) projector).
        let rank = constraint_numerical_rank(model, t1, &y, &z);
        info.rank = Some(rank);
        if rank < dims.holonomic + dims.nonholonomic {
            let (_, projector) = constraint_rank(model, t1, &y, &z);
            minimum_norm_multipliers(model, &projector, &mut lambda);
        }
    }
    // M_{1+α} a over its nonzeros, in the dense product's order (row by row, j ascending).
    let mut ma = vec![0.0; n];
    for &(i, j, m) in sys.m1 {
        ma[i] += m * a[j];
    }
    let psi = if psi.is_empty() {
        vec![0.0; dims.nonholonomic]
    } else {
        psi
    };
    if y.iter()
        .chain(&z)
        .chain(&a)
        .chain(&lambda)
        .chain(&psi)
        .any(|v| !v.is_finite())
    {
        return Err(Soi2Error::NewtonDiverged {
            step,
            t: t1,
            iterations: info.iterations,
            residual: f64::NAN,
            increment: f64::NAN,
            rank: 0,
            constraints: dims.holonomic + dims.nonholonomic,
        });
    }
    Ok(StepResult {
        y,
        z,
        a,
        ma,
        lambda,
        psi,
        ma_alpha_used: ma_alpha,
        info,
    })
}

/// Deepest halving of a rejected step: h/2¹⁰.
pub const MAX_HALVINGS: u32 = 10;

/// One step of size `h` from `state`, committed: (14a)–(14b) first when `adjust`, then
/// [`solve_step_with`]. On a Newton failure a `variable`-step run rejects the attempt and covers
/// [t, t + h] by two steps of h/2 (each halved again when it fails, down to h/2^[`MAX_HALVINGS`];
/// the (14) adjustments carry a_α across the size changes), counting the rejections in
/// [`StepInfo::rejected`]; a fixed-step run returns the error (step, t, residual, increment and
/// the rank of the constraint Jacobian). The step counter advances by one either way.
pub fn advance<M: ConstrainedModel + ?Sized>(
    model: &M,
    method: &Method,
    state: &mut Soi2State,
    h: f64,
    cache: &mut NewtonCache,
    adjust: bool,
    variable: bool,
) -> Result<StepInfo, Soi2Error> {
    advance_halving(model, method, state, h, cache, adjust, variable, 0)
}

#[allow(clippy::too_many_arguments)]
fn advance_halving<M: ConstrainedModel + ?Sized>(
    model: &M,
    method: &Method,
    state: &mut Soi2State,
    h: f64,
    cache: &mut NewtonCache,
    adjust: bool,
    variable: bool,
    depth: u32,
) -> Result<StepInfo, Soi2Error> {
    let saved = variable.then(|| state.clone());
    if adjust {
        adjust_for_step(state, method.coefficients.alpha(), h); // (14a)–(14b)
    }
    let error = match solve_step_with(model, method, state, h, cache) {
        Ok(result) => {
            let info = result.info;
            commit(state, result, h);
            return Ok(info);
        }
        Err(e) => e,
    };
    let retry = matches!(
        error,
        Soi2Error::NewtonDiverged { .. } | Soi2Error::SingularNewtonMatrix { .. }
    );
    let Some(saved) = saved.filter(|_| retry && depth < MAX_HALVINGS) else {
        return Err(error);
    };
    *state = saved;
    let step = state.step;
    // The two halves, each of which may halve again.
    let mut half = |state: &mut Soi2State| {
        advance_halving(
            model,
            method,
            state,
            h / 2.0,
            cache,
            adjust,
            true,
            depth + 1,
        )
    };
    let first = half(state)?;
    let second = half(state)?;
    state.step = step + 1;
    Ok(StepInfo {
        iterations: first.iterations + second.iterations,
        singular: first.singular || second.singular,
        rank: match (first.rank, second.rank) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        },
        rejected: 1 + first.rejected + second.rejected,
    })
}

/// Commits a step result: the adjusted a_α, M_α a_α become "previous", the new values current.
pub fn commit(state: &mut Soi2State, result: StepResult, h: f64) {
    let a_used = std::mem::replace(&mut state.a_alpha, result.a);
    state.previous = Some((a_used, result.ma_alpha_used, h));
    state.ma_alpha = Some(result.ma);
    state.y = result.y;
    state.z = result.z;
    state.lambda = result.lambda;
    state.psi = result.psi;
    state.t += h;
    state.step += 1;
}

/// M_α a_α as the step of size `h` from `state` uses it: carried over, or
/// M(t₀ + αh, y₀ + hαz₀) a_α on the first step.
pub fn ma_used<M: ConstrainedModel + ?Sized>(
    model: &M,
    method: &Method,
    state: &Soi2State,
    h: f64,
) -> Vec<f64> {
    match &state.ma_alpha {
        Some(v) => v.clone(),
        None => {
            let alpha = method.coefficients.alpha();
            let y_a: Vec<f64> = state
                .y
                .iter()
                .zip(&state.z)
                .map(|(y, z)| y + h * alpha * z)
                .collect();
            let mut m = Vec::new();
            model.mass_entries_at(state.t + alpha * h, &y_a, &mut m);
            let mut ma = vec![0.0; y_a.len()];
            for (i, j, mij) in m {
                ma[i] += mij * state.a_alpha[j];
            }
            ma
        }
    }
}

/// The initial state: consistent (a₀, λ₀, ψ₀) at t₀, and a_α per `start` for a first step of
/// size `h0`.
pub fn initial_state<M: ConstrainedModel + ?Sized>(
    model: &M,
    method: &Method,
    start: StartValue,
    h0: f64,
) -> Result<Soi2State, Soi2Error> {
    let iv = model.initial();
    let (a0, lambda, psi) = consistent_acceleration(
        model,
        iv.t,
        &iv.y,
        &iv.z,
        &iv.lambda,
        &iv.psi,
        &method.newton,
        0,
    )?;
    let mut state = Soi2State {
        step: 0,
        t: iv.t,
        y: iv.y,
        z: iv.z,
        lambda,
        psi,
        a_alpha: a0.clone(),
        ma_alpha: None,
        previous: None,
    };
    if start == StartValue::LunkSimeon {
        let alpha = method.coefficients.alpha();
        let n = state.y.len();
        let m0a0 = mass_matrix(model, state.t, &state.y) * DVector::from_column_slice(&a0);
        let y_a: Vec<f64> = state
            .y
            .iter()
            .zip(&state.z)
            .map(|(y, z)| y + h0 * alpha * z)
            .collect();
        let m_alpha = mass_matrix(model, state.t + alpha * h0, &y_a);
        let lu = m_alpha.clone().lu();
        for _ in 0..20 {
            let trial = solve_step(model, method, &state, h0)?;
            let (a1, _, _) = consistent_acceleration(
                model,
                state.t + h0,
                &trial.y,
                &trial.z,
                &trial.lambda,
                &trial.psi,
                &method.newton,
                1,
            )?;
            let m1a1 = mass_matrix(model, state.t + h0, &trial.y) * DVector::from_column_slice(&a1);
            // (8): M_α a_α = (1−α) M₀a₀ + α M₁a₁
            let rhs = &m0a0 * (1.0 - alpha) + m1a1 * alpha;
            let Some(a_alpha) = lu.solve(&rhs) else {
                return Err(Soi2Error::SingularNewtonMatrix {
                    step: 0,
                    t: state.t,
                    context: "mass matrix M_α of (8)",
                });
            };
            let change = (0..n).fold(0.0_f64, |m, i| m.max((a_alpha[i] - state.a_alpha[i]).abs()));
            let scale = 1.0 + max_norm(a_alpha.as_slice());
            state.a_alpha = a_alpha.as_slice().to_vec();
            if change <= method.newton.tolerance * scale {
                break;
            }
        }
    }
    Ok(state)
}
