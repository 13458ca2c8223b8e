//! The nonsmooth Newmark / HHT / generalized-α / Krenk–Høgsberg (KH) family, Acary 2016
//! (25)–(30), with the algorithmic energy of Lemma 2 and Propositions 2–4.
//!
//! # The scheme
//!
//! One step from (t_k, q_k, v_k, a_k) with step h (Acary 2016, (25a)–(25i)):
//!
//! ```text
//! M v̇_{k+1} + K q_{k+1} + C v_{k+1} = F_{k+1}                                    (25a)
//! M w_{k+1} = G P_{k+1}                                                         (25b)
//! U_{k+1} = Gᵀ v_{k+1} (+ ẇ)                                                     (25c)
//! 0 ≤ U^α_{k+1} + e_α U^α_k ⊥ P^α_{k+1} ≥ 0 on the index set (24), P^α = 0 elsewhere  (25d)
//! (1 − α_m) a_{k+1} + α_m a_k = (1 − α_f) v̇_{k+1} + α_f v̇_k                       (25e)
//! q̃_{k+1} = q_k + h v_k + h²(½ − β) a_k + h² β a_{k+1}                            (25f)
//! ṽ_{k+1} = v_k + h(1 − γ) a_k + h γ a_{k+1}                                     (25g)
//! v_{k+1} = ṽ_{k+1} + w_{k+1}                                                    (25h)
//! q_{k+1} = q̃_{k+1} + (h/2) w_{k+1}                                              (25i)
//! ```
//!
//! Multiplying (25e) by M and using (25a) at t_k and t_{k+1} gives the characteristic relation
//! (53), `(1−α_m) M a_{k+1} + α_m M a_k = (1−α_f)[F − Kq − Cv]_{k+1} + α_f [F − Kq − Cv]_k`,
//! which is what a step solves (v̇_k never needs storing). The KH variant replaces (25a), (25e)
//! by (30), where damping and load take the inertial weights:
//! `(1−α_m)[M a + C v − F]_{k+1} + α_m[M a + C v − F]_k = −(1−α_f) K q_{k+1} − α_f K q_k`.
//! Both are `(1−α_M) M a_{k+1} + (1−α_C) C v_{k+1} + (1−α_K) K q_{k+1} − (1−α_L) F_{k+1} =
//! −α_M M a_k − α_C C v_k − α_K K q_k + α_L F_k` with per-term weights ([`Weighting`]).
//!
//! **No splitting.** Substituting (25f)–(25i) leaves two unknowns, a_{k+1} and P_{k+1}:
//! `S a_{k+1} = b_k − [(1−α_C) C + (1−α_K)(h/2) K] M⁻¹ G P_{k+1}` with the iteration matrix
//! `S = (1−α_M) M + (1−α_C) γ h C + (1−α_K) β h² K` (factorised once per run). Then
//! `v_{k+1} = v_free + Ŵ G P` with `Ŵ = M⁻¹ − γh S⁻¹[(1−α_C) C + (1−α_K)(h/2) K] M⁻¹`, and
//! the one LCP per step is `0 ≤ Gᵀ Ŵ G P + U_free + e∘U_k ⊥ P ≥ 0` on the index set: smooth
//! acceleration and impulse come out together. `Gᵀ Ŵ G = Gᵀ S⁻¹[(1−α_M) M + (1−α_K)h²(β − γ/2) K]
//! M⁻¹ G` is symmetric positive definite when C = 0 or C commutes with K M⁻¹ (Rayleigh damping)
//! and 2β ≥ γ; otherwise it is solved by Lemke's method as a general LCP.
//!
//! # Consistent start
//!
//! `a_0 = v̇_0 = M⁻¹(F_0 − K q_0 − C v_0)` (the equation of motion at t_0, contact forces taken
//! as zero) and filters `z_0 = x_0 = y_0 = 0`: then the residual `r_k = M a_k + C v_k + K q_k − F_k`
//! equals the filter force `f^A_k = (η/ν)[K z_k + C x_k − y_k]` of (51) at k = 0, and the
//! relation (53) carries the equality to every step, so the identities hold from step 1. A scheme
//! asked to step from a state it did not produce (a resumed run) starts consistently again there.
//!
//! # Energy (Lemma 2, Propositions 2–4)
//!
//! With `ν = ½ − α_m`, `η = α_f − α_m` (50) and the filters discretised by the mid-point rule
//! (48), `(½+ν) z_{k+1} + (½−ν) z_k = ν (q_{k+1} − q_k)`, and likewise x with v and y with F (52):
//!
//! * `algorithmic_energy` H (55) `= ½vᵀMv + ½qᵀKq + (h²/4)(2β − γ) aᵀMa + (η/(2ν²))(ν − γ + ½) zᵀKz`;
//! * `work_ext` `= Δqᵀ[F_{k,γ} − (η/ν) y_{k,γ}]` — (56) for Newmark and KH (no y filter), (79) for
//!   HHT, where `2y_{k+1} = F_{k+1} − F_k` turns it into `Δqᵀ[(1−α)F_{k,γ} + αF_{k−1,γ}]` (85);
//! * `work_damping` `= −Δqᵀ C[v_{k,γ} − (η/ν) x_{k,γ}]` — (57), (80) likewise;
//! * `work_contact` `= (Gᵀv_{k+1/2})ᵀ P_{k+1}`, that is `U_{k+1/2}ᵀ P_{k+1}` for a fixed obstacle
//!   (Lemma 3: ≤ 0); with a moving obstacle it is the work on the body;
//! * `numerical_dissipation` `= −½h²(γ − ½)(2β − γ)‖Δa‖²_M − (γ − ½ − η)‖Δq‖²_K
//!   − (η/ν)(ν − γ + ½)‖Δz‖²_K`, the right-hand side of (58) without the contact term: (73) for
//!   KH, (81) for HHT, (87) for Newmark (where the paper's `h/2` before ‖Δa‖² is `h²/2`, as (62)
//!   shows);
//! * `balance_residual` `= ΔH − work_ext − work_damping − work_contact − numerical_dissipation`,
//!   zero up to round-off: Lemma 2 (58) with the x, y filter terms moved into the two works.
//!
//! ΔH is evaluated in difference form (`½(v_{k+1}+v_k)ᵀ M Δv + …`) so that it keeps its relative
//! accuracy when H is large and the step changes it little.
//!
//! **Many contacts.** With single-dof contacts and a lumped mass the columns above are not
//! formed: the impulse solves `S x = R M⁻¹ G P` on the banded S (`BandedAlpha`,
//! [`crate::banded_contact`]), the same complementarity problem with the same W.
//!
//! When ν = 0 (α_m = ½) the filters (48) vanish; the scheme then requires η = 0 (Remark 1), and
//! the filter terms are zero.

use super::{LinearScheme, LinearState, SchemeState, StepError, StepReport};
use crate::band::{BandCholesky, BandError, SymBand};
use crate::banded_contact::{BandedImpulse, restore_warm_start, uses_banded};
use crate::checkpoint::CheckpointError;
use crate::contact::{IndexSet, IndexSetRule, LcpStats};
use crate::energy::EnergyTerms;
use crate::lcp::active_set::ImpulseMap;
use crate::lcp::{self, Lcp, LcpOptions};
use crate::model::LinearModel;
use std::fmt;

/// Tolerance of the parameter conditions, so that parameters computed from ρ∞ by (27) are not
/// rejected by one ulp.
const PARAM_TOL: f64 = 1e-12;

/// Which member of the family: fixes which stability conditions apply and, for KH, the weights.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AlphaScheme {
    /// Nonsmooth Newmark: α_m = α_f = 0; dissipative for 2β ≥ γ ≥ ½ (89).
    Newmark,
    /// Nonsmooth HHT (78): α_m = 0, α_f = α; dissipative for 2β ≥ γ ≥ ½, 0 ≤ α ≤ γ − ½ ≤ ½ (83).
    Hht,
    /// Nonsmooth generalized-α (25), Chung–Hulbert weighting (53). Accepted for
    /// α_m ≤ α_f ≤ ½, γ ≥ ½ + α_f − α_m, β ≥ ¼ + ½(α_f − α_m) (Chung & Hulbert 1993); Lemma 2
    /// gives the identity but no sign.
    GeneralizedAlpha,
    /// Nonsmooth KH generalized-α (30); dissipative under (76).
    KrenkHogsberg,
}

impl AlphaScheme {
    /// The scheme's name in job specs.
    pub fn name(self) -> &'static str {
        match self {
            AlphaScheme::Newmark => "ns_newmark",
            AlphaScheme::Hht => "ns_hht",
            AlphaScheme::GeneralizedAlpha => "ns_generalized_alpha",
            AlphaScheme::KrenkHogsberg => "ns_kh_alpha",
        }
    }
}

/// Parameters of the α-family. Build them with [`AlphaParams::newmark`], [`AlphaParams::hht`],
/// [`AlphaParams::from_rho_inf`] or directly, then [`AlphaParams::validate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlphaParams {
    /// Member of the family.
    pub scheme: AlphaScheme,
    /// α_m < 1 (≤ ½ for stability).
    pub alpha_m: f64,
    /// α_f ≤ 1.
    pub alpha_f: f64,
    /// β ≥ 0.
    pub beta: f64,
    /// γ ≥ 0.
    pub gamma: f64,
    /// Index-set rule, (24) by default.
    pub index_set: IndexSetRule,
}

/// A parameter set the family cannot run, or that is outside the scheme's stability or
/// dissipation conditions. `field` is the parameter's spec name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParamError {
    /// Spec field name (`alpha_m`, `alpha_f`, `alpha`, `beta`, `gamma`, `rho_inf`).
    pub field: &'static str,
    /// What is wrong.
    pub reason: String,
    /// True when the parameters are runnable but outside the proven conditions (a spec may
    /// accept them with `allow_unstable = true`).
    pub stability: bool,
}

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.field, self.reason)
    }
}

impl std::error::Error for ParamError {}

fn hard(field: &'static str, reason: String) -> ParamError {
    ParamError {
        field,
        reason,
        stability: false,
    }
}

fn unstable(field: &'static str, reason: String) -> ParamError {
    ParamError {
        field,
        reason,
        stability: true,
    }
}

impl AlphaParams {
    /// Nonsmooth Newmark (α_m = α_f = 0). β = ¼, γ = ½ is the trapezoidal rule (Corollary 1).
    pub fn newmark(beta: f64, gamma: f64) -> Self {
        Self {
            scheme: AlphaScheme::Newmark,
            alpha_m: 0.0,
            alpha_f: 0.0,
            beta,
            gamma,
            index_set: IndexSetRule::default(),
        }
    }

    /// Nonsmooth HHT with the second-order choice γ = ½ + α, β = (1 + α)²/4.
    pub fn hht(alpha: f64) -> Self {
        Self::hht_with(alpha, 0.25 * (1.0 + alpha) * (1.0 + alpha), 0.5 + alpha)
    }

    /// Nonsmooth HHT (78) with explicit β, γ.
    pub fn hht_with(alpha: f64, beta: f64, gamma: f64) -> Self {
        Self {
            scheme: AlphaScheme::Hht,
            alpha_m: 0.0,
            alpha_f: alpha,
            beta,
            gamma,
            index_set: IndexSetRule::default(),
        }
    }

    /// Generalized-α or KH parameters from the spectral radius at infinity ρ∞ ∈ [0, 1] by (27):
    /// `α_m = (2ρ∞ − 1)/(ρ∞ + 1)`, `α_f = ρ∞/(ρ∞ + 1)`, γ by (26) `γ = ½ + α_f − α_m`,
    /// `β = ¼(γ + ½)²`.
    pub fn from_rho_inf(scheme: AlphaScheme, rho_inf: f64) -> Self {
        let alpha_m = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0);
        let alpha_f = rho_inf / (rho_inf + 1.0);
        let gamma = 0.5 + alpha_f - alpha_m;
        let beta = 0.25 * (gamma + 0.5) * (gamma + 0.5);
        Self {
            scheme,
            alpha_m,
            alpha_f,
            beta,
            gamma,
            index_set: IndexSetRule::default(),
        }
    }

    /// Filter time-scale parameter ν = ½ − α_m (50).
    pub fn nu(&self) -> f64 {
        0.5 - self.alpha_m
    }

    /// Filter strength η = α_f − α_m (50).
    pub fn eta(&self) -> f64 {
        self.alpha_f - self.alpha_m
    }

    /// The weights (α_M, α_C, α_K, α_L) on the t_k terms of M a, C v, K q, F.
    pub fn weights(&self) -> Weighting {
        let (am, af) = (self.alpha_m, self.alpha_f);
        match self.scheme {
            AlphaScheme::KrenkHogsberg => Weighting {
                mass: am,
                damping: am,
                stiffness: af,
                load: am,
            },
            _ => Weighting {
                mass: am,
                damping: af,
                stiffness: af,
                load: af,
            },
        }
    }

    /// Checks that the scheme can run (finite values, α_m < 1, α_f ≤ 1, β, γ ≥ 0, η = 0 when
    /// ν = 0) and that the parameters satisfy the scheme's stability/dissipation conditions
    /// ([`AlphaScheme`]). Errors with `stability = true` concern only the latter.
    pub fn validate(&self) -> Result<(), ParamError> {
        let hht = self.scheme == AlphaScheme::Hht;
        let f_name = if hht { "alpha" } else { "alpha_f" };
        for (field, x) in [
            ("alpha_m", self.alpha_m),
            (f_name, self.alpha_f),
            ("beta", self.beta),
            ("gamma", self.gamma),
        ] {
            if !x.is_finite() {
                return Err(hard(field, format!("must be finite, got {x}")));
            }
        }
        if self.alpha_m >= 1.0 {
            return Err(hard(
                "alpha_m",
                format!(
                    "must be < 1 (α_m = 1 leaves a_(k+1) undetermined), got {}",
                    self.alpha_m
                ),
            ));
        }
        if self.alpha_f > 1.0 {
            return Err(hard(f_name, format!("must be ≤ 1, got {}", self.alpha_f)));
        }
        if self.beta < 0.0 {
            return Err(hard("beta", format!("must be ≥ 0, got {}", self.beta)));
        }
        if self.gamma < 0.0 {
            return Err(hard("gamma", format!("must be ≥ 0, got {}", self.gamma)));
        }
        if self.nu().abs() <= PARAM_TOL && self.eta().abs() > PARAM_TOL {
            return Err(hard(
                "alpha_f",
                format!(
                    "α_m = ½ requires α_f = ½ (ν = 0 makes the filter (48) vanish, Remark 1), got α_f = {}",
                    self.alpha_f
                ),
            ));
        }
        let (am, af, b, g) = (self.alpha_m, self.alpha_f, self.beta, self.gamma);
        let tol = PARAM_TOL;
        match self.scheme {
            AlphaScheme::Newmark | AlphaScheme::Hht | AlphaScheme::KrenkHogsberg => {
                if g < 0.5 - tol {
                    return Err(unstable(
                        "gamma",
                        format!("must be ≥ ½ for dissipation ((89), (83), (76)), got {g}"),
                    ));
                }
                if 2.0 * b < g - tol {
                    return Err(unstable(
                        "beta",
                        format!("2β ≥ γ is required for dissipation, got β = {b}, γ = {g}"),
                    ));
                }
            }
            AlphaScheme::GeneralizedAlpha => {}
        }
        match self.scheme {
            AlphaScheme::Newmark => {
                if am != 0.0 || af != 0.0 {
                    return Err(hard(
                        "alpha_f",
                        "nonsmooth Newmark has α_m = α_f = 0".into(),
                    ));
                }
            }
            AlphaScheme::Hht => {
                if am != 0.0 {
                    return Err(hard("alpha_m", "nonsmooth HHT has α_m = 0".into()));
                }
                if af < -tol || af > g - 0.5 + tol || g - 0.5 > 0.5 + tol {
                    return Err(unstable(
                        "alpha",
                        format!("(83) requires 0 ≤ α ≤ γ − ½ ≤ ½, got α = {af}, γ = {g}"),
                    ));
                }
            }
            AlphaScheme::KrenkHogsberg => {
                let eta = af - am;
                if eta < -tol || eta > g - 0.5 + tol || g - 0.5 > 0.5 - am + tol {
                    return Err(unstable(
                        "alpha_f",
                        format!(
                            "(76) requires 0 ≤ α_f − α_m ≤ γ − ½ ≤ ½ − α_m, got α_m = {am}, α_f = {af}, γ = {g}"
                        ),
                    ));
                }
            }
            AlphaScheme::GeneralizedAlpha => {
                if am > af + tol || af > 0.5 + tol {
                    return Err(unstable(
                        "alpha_f",
                        format!("stability requires α_m ≤ α_f ≤ ½, got α_m = {am}, α_f = {af}"),
                    ));
                }
                if g < 0.5 + af - am - tol {
                    return Err(unstable(
                        "gamma",
                        format!("stability requires γ ≥ ½ + α_f − α_m, got γ = {g}"),
                    ));
                }
                if b < 0.25 + 0.5 * (af - am) - tol {
                    return Err(unstable(
                        "beta",
                        format!("stability requires β ≥ ¼ + ½(α_f − α_m), got β = {b}"),
                    ));
                }
            }
        }
        Ok(())
    }

    /// The coefficients the smooth part of a step needs.
    pub(crate) fn coefficients(&self) -> Coefficients {
        Coefficients {
            beta: self.beta,
            gamma: self.gamma,
            nu: self.nu(),
            eta: self.eta(),
            weights: self.weights(),
            xy_filters: self.scheme != AlphaScheme::KrenkHogsberg,
        }
    }
}

/// The weights α_M, α_C, α_K, α_L of the t_k terms of M a, C v, K q and F in the collocation
/// relation (the t_{k+1} terms take 1 − α). Chung–Hulbert (53): (α_m, α_f, α_f, α_f);
/// Krenk–Høgsberg (30): (α_m, α_m, α_f, α_m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Weighting {
    /// α_M.
    pub mass: f64,
    /// α_C.
    pub damping: f64,
    /// α_K.
    pub stiffness: f64,
    /// α_L.
    pub load: f64,
}

/// Coefficients shared by the nonsmooth family and the position-contact baselines.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Coefficients {
    pub beta: f64,
    pub gamma: f64,
    pub nu: f64,
    pub eta: f64,
    pub weights: Weighting,
    /// Whether the x (damping) and y (load) filters of (52) enter: Chung–Hulbert weighting only.
    pub xy_filters: bool,
}

/// The α_M M a_k term of a row of (53), for the const parameter `MASS` of [`predict_sweep`] and
/// [`predict_general`]: none (α_M = 0), m∘a_k with the diagonal m of a lumped mass (the product
/// `SymBand::mul_into` forms), or the stored M a_k of a consistent mass.
const NO_MASS: u8 = 0;
const LUMPED: u8 = 1;
const PRODUCT: u8 = 2;

/// Calls `$f::<MASS, DAMPED>(args)` for the runtime mass term and damping flag.
macro_rules! with_terms {
    ($mass:expr, $damped:expr, $f:ident($($arg:expr),* $(,)?)) => {
        match ($mass, $damped) {
            (NO_MASS, false) => $f::<NO_MASS, false>($($arg),*),
            (NO_MASS, true) => $f::<NO_MASS, true>($($arg),*),
            (LUMPED, false) => $f::<LUMPED, false>($($arg),*),
            (LUMPED, true) => $f::<LUMPED, true>($($arg),*),
            (_, false) => $f::<PRODUCT, false>($($arg),*),
            (_, true) => $f::<PRODUCT, true>($($arg),*),
        }
    };
}

/// Per-step history of the smooth part at t_k (one of two buffers swapped every step).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct Frame {
    pub a: Vec<f64>,
    /// M a, for a consistent mass; empty for a lumped mass, where M a = m∘a is formed where
    /// it is read (see `AlphaCore::lumped`). Checkpoints of earlier builds hold a stale copy
    /// there, which a restore drops.
    pub ma: Vec<f64>,
    pub kq: Vec<f64>,
    pub cv: Vec<f64>,
    pub f: Vec<f64>,
    pub z: Vec<f64>,
    pub kz: Vec<f64>,
    pub cx: Vec<f64>,
    pub y: Vec<f64>,
    /// Contact forces λ_k of a position-contact baseline (zero for the nonsmooth family).
    pub lambda: Vec<f64>,
    /// The λ filter (y of (52) applied to Gλ, in contact coordinates).
    pub ylam: Vec<f64>,
}

impl Frame {
    /// A frame of zeros for n dofs and m contacts; `ma` of n entries for a consistent mass,
    /// empty for a lumped one.
    fn zeros(n: usize, m: usize, lumped: bool) -> Self {
        let z = vec![0.0; n];
        Self {
            a: z.clone(),
            ma: if lumped { Vec::new() } else { z.clone() },
            kq: z.clone(),
            cv: z.clone(),
            f: z.clone(),
            z: z.clone(),
            kz: z.clone(),
            cx: z.clone(),
            y: z,
            lambda: vec![0.0; m],
            ylam: vec![0.0; m],
        }
    }
}

/// Scratch vectors of one step; after [`AlphaCore::predict`] `a`, `q`, `v` hold the free
/// (impulse- and force-free) a_{k+1}, q_{k+1}, v_{k+1}; the scheme then corrects them.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct Scratch {
    pub a: Vec<f64>,
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    tmp: Vec<f64>,
    tmp2: Vec<f64>,
}

/// The smooth part shared by [`NonsmoothAlpha`] and the position-contact baselines: predictor,
/// iteration matrix S, history, filters and the energy bookkeeping of Lemma 2.
#[derive(Debug, Clone)]
pub(crate) struct AlphaCore {
    pub h: f64,
    pub c: Coefficients,
    /// η/ν (0 when the filters are off).
    ratio: f64,
    /// Coefficient of zᵀKz in H (55).
    cz: f64,
    filters: bool,
    has_damping: bool,
    /// F has a time-varying part (else the y filter stays exactly zero and is skipped).
    varying_load: bool,
    /// `nxt.f`, `f_rhs` and `f_work` hold the (constant) load: set by the first predictor of a
    /// run with `varying_load` false, so that later steps do not evaluate F again.
    f_ready: bool,
    /// The load part of the right-hand side of (53), `(1−α_L) F_{k+1} + α_L F_k` (formed once
    /// per run for a constant load, else by each predictor).
    f_rhs: Vec<f64>,
    /// The load of the external work (56), `γ F_{k+1} + (1−γ) F_k` (likewise).
    f_work: Vec<f64>,
    /// M is diagonal (lumped): M a is formed as m∘a where it is needed, and the frames' `ma`
    /// is not kept up to date (one sweep and two history vectors fewer per step).
    lumped: bool,
    pub s_factor: BandCholesky,
    pub m_factor: BandCholesky,
    /// History at t_k and the buffer for t_{k+1}.
    pub cur: Frame,
    pub nxt: Frame,
    /// Step number `cur` describes.
    cur_step: Option<u64>,
    pub s: Scratch,
}

/// How the contact works of a step are computed by [`AlphaCore::finish`].
pub(crate) enum ContactWork {
    /// The nonsmooth family: `(Gᵀ v_{k+1/2})ᵀ P_{k+1}`, computed by the caller.
    Impulse(f64),
    /// A position-contact baseline: λ_{k+1} is in `nxt.lambda`; the work is the load work of
    /// the force Gλ, `Δqᵀ G[λ_{k,γ} − (η/ν) ỹ_{k,γ}]`.
    Force,
}

impl AlphaCore {
    pub fn new(model: &LinearModel, c: Coefficients, h: f64) -> Result<Self, BandError> {
        let w = c.weights;
        let s = SymBand::combine(&[
            (1.0 - w.mass, &model.mass),
            ((1.0 - w.damping) * c.gamma * h, &model.damping),
            ((1.0 - w.stiffness) * c.beta * h * h, &model.stiffness),
        ]);
        let s_factor = s.cholesky()?;
        let m_factor = model.mass.cholesky()?;
        let filters = c.nu.abs() > PARAM_TOL && c.eta != 0.0;
        let (ratio, cz) = if filters {
            (
                c.eta / c.nu,
                c.eta / (2.0 * c.nu * c.nu) * (c.nu - c.gamma + 0.5),
            )
        } else {
            (0.0, 0.0)
        };
        let (n, m) = (model.dofs(), model.contacts.len());
        let lumped = model.mass.kd() == 0;
        let z = vec![0.0; n];
        Ok(Self {
            h,
            c,
            ratio,
            cz,
            filters,
            has_damping: !model.damping.is_zero(),
            varying_load: !model.force.harmonic.is_empty(),
            f_ready: false,
            f_rhs: z.clone(),
            f_work: z.clone(),
            lumped,
            s_factor,
            m_factor,
            cur: Frame::zeros(n, m, lumped),
            nxt: Frame::zeros(n, m, lumped),
            cur_step: None,
            s: Scratch {
                a: z.clone(),
                q: z.clone(),
                v: z.clone(),
                tmp: z.clone(),
                tmp2: z,
            },
        })
    }

    /// Consistent start at `state` into `frame`: a = M⁻¹(F − Kq − Cv), filters and λ zero.
    fn start_frame(&self, model: &LinearModel, state: &LinearState, frame: &mut Frame) {
        model.force.eval_into(state.t, &mut frame.f);
        model.stiffness.mul_into(&state.q, &mut frame.kq);
        if self.has_damping {
            model.damping.mul_into(&state.v, &mut frame.cv);
        } else {
            frame.cv.fill(0.0);
        }
        for i in 0..frame.a.len() {
            frame.a[i] = frame.f[i] - frame.kq[i] - frame.cv[i];
        }
        self.m_factor.solve_in_place(&mut frame.a);
        if !self.lumped {
            model.mass.mul_into(&frame.a, &mut frame.ma);
        }
        for v in [
            &mut frame.z,
            &mut frame.kz,
            &mut frame.cx,
            &mut frame.y,
            &mut frame.lambda,
            &mut frame.ylam,
        ] {
            v.fill(0.0);
        }
    }

    /// Makes `cur` describe `state` (a consistent start unless the last step produced it).
    pub fn ensure_history(&mut self, model: &LinearModel, state: &LinearState) {
        if self.cur_step != Some(state.step) {
            let mut frame = std::mem::replace(&mut self.cur, Frame::zeros(0, 0, true));
            self.start_frame(model, state, &mut frame);
            self.cur = frame;
            self.cur_step = Some(state.step);
        }
    }

    /// aᵀMa of a frame (M a formed as m∘a for a lumped mass, where `frame.ma` is not kept), in
    /// the partial sums of [`dot`] and of the step's sweep.
    fn a_m_a(&self, model: &LinearModel, frame: &Frame) -> f64 {
        if self.lumped {
            let n = frame.a.len();
            let (a, m) = (&frame.a[..n], &model.mass.band(0)[..n]);
            let (ac, mc) = (a.chunks_exact(4), m.chunks_exact(4));
            let mut tail = 0.0;
            for (x, w) in ac.remainder().iter().zip(mc.remainder()) {
                tail += x * (w * x);
            }
            let mut acc = [0.0; 4];
            for (x, w) in ac.zip(mc) {
                for l in 0..4 {
                    acc[l] += x[l] * (w[l] * x[l]);
                }
            }
            (acc[0] + acc[2]) + (acc[1] + acc[3]) + tail
        } else {
            dot(&frame.a, &frame.ma)
        }
    }

    /// H (55) at `state` given its history frame.
    fn algorithmic_energy_of(
        &self,
        model: &LinearModel,
        state: &LinearState,
        frame: &Frame,
    ) -> f64 {
        let kin = 0.5 * model.mass.quad(&state.v, &state.v);
        let strain = 0.5 * dot(&state.q, &frame.kq);
        let h2 = self.h * self.h;
        kin + strain
            + 0.25 * h2 * (2.0 * self.c.beta - self.c.gamma) * self.a_m_a(model, frame)
            + self.cz * dot(&frame.z, &frame.kz)
    }

    /// H (55) at `state` (from the history when the last step produced `state`, else from a
    /// consistent start there).
    pub fn algorithmic_energy(&self, model: &LinearModel, state: &LinearState) -> f64 {
        if self.cur_step == Some(state.step) {
            self.algorithmic_energy_of(model, state, &self.cur)
        } else {
            let mut frame = Frame::zeros(model.dofs(), model.contacts.len(), self.lumped);
            self.start_frame(model, state, &mut frame);
            self.algorithmic_energy_of(model, state, &frame)
        }
    }

    /// Free step: F_{k+1} into `nxt.f`, and the solution of the collocation relation with no
    /// impulse (and, for the baselines, no new contact force) into `s.a`, `s.q`, `s.v`.
    /// Returns t_{k+1}.
    ///
    /// Every sweep runs on plain slices of equal length (no bounds checks, no reloading of the
    /// vectors through `self`), so that the compiler vectorises it; the arithmetic per dof is
    /// that of (25f), (25g) and (53) in the order written, so the result does not depend on it.
    pub fn predict(&mut self, model: &LinearModel, state: &LinearState) -> f64 {
        self.ensure_history(model, state);
        let h = self.h;
        let (beta, gamma) = (self.c.beta, self.c.gamma);
        let w = self.c.weights;
        let t_next = (state.step + 1) as f64 * h;
        // A constant load is the same at every t: evaluated once into each frame, and its
        // combinations for (53) and (56) formed once.
        if self.varying_load || !self.f_ready {
            model.force.eval_into(t_next, &mut self.nxt.f);
            let f0 = if self.varying_load {
                &self.cur.f
            } else {
                &self.nxt.f
            };
            let (g1, g0) = (gamma, 1.0 - gamma);
            for (((fr, fw), f1), f0) in self
                .f_rhs
                .iter_mut()
                .zip(&mut self.f_work)
                .zip(&self.nxt.f)
                .zip(f0)
            {
                *fr = (1.0 - w.load) * f1 + w.load * f0;
                *fw = g1 * f1 + g0 * f0;
            }
            self.f_ready = !self.varying_load;
        }
        let n = state.q.len();
        let (cur, s) = (&self.cur, &mut self.s);
        // Predictors q̂ = q_k + h v_k + h²(½ − β) a_k (in s.q), v̂ = v_k + h(1 − γ) a_k (in s.v).
        let cq = h * h * (0.5 - beta);
        let cv = h * (1.0 - gamma);
        let rows = RowCoefficients {
            cv,
            mass: w.mass,
            damping: w.damping,
            stiffness: [w.stiffness, 1.0 - w.stiffness],
        };
        // Which terms of (53) a row has: α_M M a_k (lumped: m∘a) and α_C C v_k only when they
        // are not zero.
        let (mass, m) = match (w.mass != 0.0, self.lumped) {
            (false, _) => (NO_MASS, &cur.a[..n]),
            (true, true) => (LUMPED, &model.mass.band(0)[..n]),
            (true, false) => (PRODUCT, &cur.ma[..n]),
        };
        let damped = self.has_damping && w.damping != 0.0;
        let sweep = PredictSweep {
            q: &state.q[..n],
            v: &state.v[..n],
            a: &cur.a[..n],
            f_rhs: &self.f_rhs[..n],
            cv: &cur.cv[..n],
            kq: &cur.kq[..n],
            k0: &model.stiffness.band(0)[..n],
            k1: &model.stiffness.band(1.min(model.stiffness.kd()))[..n],
            q_hat: &mut s.q[..n],
            v_hat: &mut s.v[..n],
            b: &mut s.a[..n],
        };
        let c = [h, cq];
        if model.stiffness.kd() == 1 && n >= 2 {
            // Tridiagonal K: predictors, K q̂ and b in one sweep.
            with_terms!(mass, damped, predict_sweep(sweep, m, c, rows));
        } else {
            let tmp = &mut s.tmp[..n];
            with_terms!(
                mass,
                damped,
                predict_general(sweep, m, c, rows, &model.stiffness, tmp)
            );
        }
        if self.has_damping {
            model.damping.mul_into(&s.v, &mut s.tmp);
            for (b, cvh) in s.a[..n].iter_mut().zip(&s.tmp[..n]) {
                *b -= (1.0 - w.damping) * cvh;
            }
        }
        // A baseline's contact force at t_k enters with the load weight.
        for (c, &l) in model.contacts.iter().zip(&cur.lambda) {
            if l != 0.0 {
                for &(i, g) in &c.g {
                    s.a[i] += w.load * l * g;
                }
            }
        }
        // Solve S a_{k+1} = b, with (25f), (25g) q = q̂ + h²β a, v = v̂ + hγ a in its back sweep.
        self.s_factor.solve_in_place_axpy(
            &mut s.a,
            [h * h * beta, h * gamma],
            [&mut s.q, &mut s.v],
        );
        t_next
    }

    /// Completes a step whose a_{k+1}, q_{k+1}, v_{k+1} are in `s.a`, `s.q`, `s.v` (and, for a
    /// baseline, λ_{k+1} in `nxt.lambda`): history, filters, energy terms, then the new state.
    ///
    /// The products at t_{k+1} (K q; M a for a consistent mass, C v with damping), then two
    /// passes ([`finish_sweep`]: q with the z filter, a and v) for every sum of the balance
    /// (works, quadratic terms, ΔH) and the sums of H; the new a, q, v are swapped in, not
    /// copied.
    pub fn finish(
        &mut self,
        model: &LinearModel,
        state: &mut LinearState,
        t_next: f64,
        contact: ContactWork,
        report: &mut StepReport,
    ) {
        let n = state.q.len();
        let (h, beta, gamma, nu) = (self.h, self.c.beta, self.c.gamma, self.c.nu);
        let eta = self.c.eta;
        let (cur, nxt, s) = (&self.cur, &mut self.nxt, &mut self.s);
        let lumped = self.lumped;
        if !lumped {
            model.mass.mul_into(&s.a, &mut nxt.ma);
        }
        model.stiffness.mul_into(&s.q, &mut nxt.kq);
        // Without damping C v stays zero in both frames (start_frame zeroes it).
        if self.has_damping {
            model.damping.mul_into(&s.v, &mut nxt.cv);
        }
        let ratio = self.ratio;
        let xy = self.filters && self.c.xy_filters;
        // Filters (48), (52): (½+ν) z_{k+1} + (½−ν) z_k = ν Δq (and K z, C x, y alike),
        // divided by ½+ν once per step: z_{k+1} = c_n Δq − c_m z_k. z and K z are updated in
        // the sweep below; with α_m = 0 (HHT, ν = ½) c_m = 0 and z_{k+1} = ½ Δq.
        let (cn, cm) = if self.filters {
            (nu / (0.5 + nu), (0.5 - nu) / (0.5 + nu))
        } else {
            (0.0, 0.0)
        };
        if self.filters {
            // x and y start at zero and are driven by Δ(Cv) and ΔF only: without damping or
            // without a time-varying load they stay exactly zero and are skipped.
            if xy && self.has_damping {
                for (((x1, x0), c1), c0) in nxt.cx[..n]
                    .iter_mut()
                    .zip(&cur.cx[..n])
                    .zip(&nxt.cv[..n])
                    .zip(&cur.cv[..n])
                {
                    *x1 = cn * (c1 - c0) - cm * x0;
                }
            }
            if xy && self.varying_load {
                for (((y1, y0), f1), f0) in nxt.y[..n]
                    .iter_mut()
                    .zip(&cur.y[..n])
                    .zip(&nxt.f[..n])
                    .zip(&cur.f[..n])
                {
                    *y1 = cn * (f1 - f0) - cm * y0;
                }
            }
            if xy {
                for a in 0..nxt.lambda.len() {
                    nxt.ylam[a] = cn * (nxt.lambda[a] - cur.lambda[a]) - cm * cur.ylam[a];
                }
            }
        }
        // Works (56)–(57) / (79)–(80) with the x, y filter terms of (58), and the quadratic
        // terms, all in difference form.
        let (g1, g0) = (gamma, 1.0 - gamma);
        let rx = if xy { ratio } else { 0.0 };
        let ry = if xy && self.varying_load { ratio } else { 0.0 };
        // With a lumped mass `ma` is not read (M a = m∘a), with a constant load F_k = F_{k+1}.
        let (ma1, ma0) = if lumped {
            (&s.a, &cur.a)
        } else {
            (&nxt.ma, &cur.ma)
        };
        let sweep = Sweep {
            q1: &s.q[..n],
            q0: &state.q[..n],
            v1: &s.v[..n],
            v0: &state.v[..n],
            a1: &s.a[..n],
            a0: &cur.a[..n],
            kq1: &nxt.kq[..n],
            kq0: &cur.kq[..n],
            ma1: &ma1[..n],
            ma0: &ma0[..n],
            fw: &self.f_work[..n],
            z0: &cur.z[..n],
            kz0: &cur.kz[..n],
            mass: &model.mass.band(0)[..n],
            z1: &mut nxt.z[..n],
            kz1: &mut nxt.kz[..n],
            dv: &mut s.tmp[..n],
            sv: &mut s.tmp2[..n],
            filter: [cn, cm],
        };
        let mut sweep = sweep;
        // The q part depends on the filter only, the a, v part on the mass only.
        let q_part = match (self.filters, cm != 0.0) {
            (false, _) => finish_sweep::<NO_FILTER, false, PART_Q>(&mut sweep),
            (true, false) => finish_sweep::<MEMORYLESS_FILTER, false, PART_Q>(&mut sweep),
            (true, true) => finish_sweep::<FILTER_WITH_MEMORY, false, PART_Q>(&mut sweep),
        };
        let av_part = if lumped {
            finish_sweep::<NO_FILTER, true, PART_AV>(&mut sweep)
        } else {
            finish_sweep::<NO_FILTER, false, PART_AV>(&mut sweep)
        };
        // Each sum is formed by one part (the other's entry is zero).
        let sums: [f64; SUMS] = std::array::from_fn(|s| q_part[s] + av_part[s]);
        let mut work_ext = sums[S_WORK_EXT];
        let mut work_damping = 0.0;
        if ry != 0.0 {
            for (((q1, q0), y1), y0) in s.q[..n]
                .iter()
                .zip(&state.q[..n])
                .zip(&nxt.y[..n])
                .zip(&cur.y[..n])
            {
                work_ext -= (q1 - q0) * ry * (g1 * y1 + g0 * y0);
            }
        }
        if self.has_damping {
            for (((q1, q0), (c1, c0)), (x1, x0)) in s.q[..n]
                .iter()
                .zip(&state.q[..n])
                .zip(nxt.cv[..n].iter().zip(&cur.cv[..n]))
                .zip(nxt.cx[..n].iter().zip(&cur.cx[..n]))
            {
                let cv_g = g1 * c1 + g0 * c0 - rx * (g1 * x1 + g0 * x0);
                work_damping -= (q1 - q0) * cv_g;
            }
        }
        let (d_kin, kin) = if lumped {
            (0.5 * sums[S_D_KIN], 0.5 * sums[S_KIN])
        } else {
            (
                0.5 * model.mass.quad(&s.tmp2, &s.tmp),
                0.5 * model.mass.quad(&s.v, &s.v),
            )
        };
        let h2 = h * h;
        let delta_h = d_kin
            + 0.5 * sums[S_D_STRAIN]
            + 0.25 * h2 * (2.0 * beta - gamma) * sums[S_D_ATERM]
            + self.cz * sums[S_D_ZTERM];
        let work_contact = match contact {
            ContactWork::Impulse(w) => w,
            ContactWork::Force => {
                let ry = if xy { ratio } else { 0.0 };
                let mut w = 0.0;
                for (a, c) in model.contacts.iter().enumerate() {
                    let l_g = g1 * nxt.lambda[a] + g0 * cur.lambda[a]
                        - ry * (g1 * nxt.ylam[a] + g0 * cur.ylam[a]);
                    if l_g != 0.0 {
                        w += l_g * (c.project(&s.q) - c.project(&state.q));
                    }
                }
                w
            }
        };
        let numerical_dissipation =
            -0.5 * h2 * (gamma - 0.5) * (2.0 * beta - gamma) * sums[S_DA_M_DA]
                - (gamma - 0.5 - eta) * sums[S_DQ_K_DQ]
                - ratio * (nu - gamma + 0.5) * sums[S_DZ_K_DZ];

        // The new state and history: swapped in (the scratch vectors are rewritten by the next
        // predictor before they are read).
        std::mem::swap(&mut state.q, &mut s.q);
        std::mem::swap(&mut state.v, &mut s.v);
        std::mem::swap(&mut nxt.a, &mut s.a);
        state.t = t_next;
        state.step += 1;
        std::mem::swap(&mut self.cur, &mut self.nxt);
        self.cur_step = Some(state.step);

        // H (55) from the sums of the sweep (no second pass over q, v, a, z).
        let strain = 0.5 * sums[S_STRAIN];
        let mut alg = kin + strain + 0.25 * h2 * (2.0 * beta - gamma) * sums[S_ATERM];
        if self.filters {
            alg += self.cz * sums[S_ZTERM];
        }
        report.energy = EnergyTerms {
            kinetic: kin,
            strain,
            work_ext,
            work_damping,
            work_contact,
            numerical_dissipation,
            algorithmic_energy: alg,
            balance_residual: delta_h
                - work_ext
                - work_damping
                - work_contact
                - numerical_dissipation,
        };
        report.fill_contacts(model, &state.q, &state.v, t_next);
    }
}

/// The coefficients of a predictor row ([`predict_row`]): h(1 − γ), α_M, α_C, (α_K, 1 − α_K).
#[derive(Debug, Clone, Copy)]
struct RowCoefficients {
    cv: f64,
    mass: f64,
    damping: f64,
    stiffness: [f64; 2],
}

/// One row (or two, [`F2`]) of the predictor (25g) without a_{k+1} and of the right-hand side of
/// (53) from `x` = (v_k, a_k, (1−α_L) F_{k+1} + α_L F_k, M_ii or (M a)_k, (C v)_k, (K q)_k,
/// K q̂): returns (v̂, b) with `b = F − α_M M a_k − α_C C v_k − α_K K q_k − (1−α_K) K q̂` (the
/// C v̂ term is subtracted by the caller). Terms that are zero (`MASS` = [`NO_MASS`], `DAMPED`
/// false) are left out: subtracting a zero changes no value.
#[inline(always)]
fn predict_row<const MASS: u8, const DAMPED: bool, T: Lane>(r: RowCoefficients, x: [T; 7]) -> (T, T)
where
    f64: std::ops::Mul<T, Output = T>,
{
    let [v, a, f, m, cv, kq, kqh] = x;
    let v_hat = v + r.cv * a;
    let mut b = f;
    if MASS == LUMPED {
        b = b - r.mass * (m * a);
    } else if MASS == PRODUCT {
        b = b - r.mass * m;
    }
    if DAMPED {
        b = b - r.damping * cv;
    }
    (v_hat, b - r.stiffness[0] * kq - r.stiffness[1] * kqh)
}

/// The vectors of [`predict_sweep`] and [`predict_general`], all of length n: the state and
/// history at t_k, the load part of (53), the diagonals of a tridiagonal K (`k1[i]` =
/// K[i][i−1]; not read by [`predict_general`]) and the outputs q̂, v̂, b.
struct PredictSweep<'a> {
    q: &'a [f64],
    v: &'a [f64],
    a: &'a [f64],
    f_rhs: &'a [f64],
    cv: &'a [f64],
    kq: &'a [f64],
    k0: &'a [f64],
    k1: &'a [f64],
    q_hat: &'a mut [f64],
    v_hat: &'a mut [f64],
    b: &'a mut [f64],
}

/// The predictors (25f), (25g) without a_{k+1} and the right-hand side of (53) for a tridiagonal
/// K (n ≥ 2) in one sweep, `c` = (h, h²(½ − β)), `m` the diagonal of M or M a_k as `MASS` says
/// (not read for [`NO_MASS`]). The rows 1 … n − 2 go in pairs (i, i + 1) on two lanes ([`F2`]):
/// q̂ of a pair is formed once and kept for the next pair, which reads its upper value as
/// q̂_{i−1}, and the pair after gives q̂_{i+2}; K q̂ is formed row by row with the arithmetic of
/// [`SymBand::mul_into`] and b with that of [`predict_row`], so every value is the one a
/// stored q̂ and a separate product give.
fn predict_sweep<const MASS: u8, const DAMPED: bool>(
    p: PredictSweep<'_>,
    m: &[f64],
    c: [f64; 2],
    r: RowCoefficients,
) {
    let n = p.q.len();
    let [h, cq] = c;
    let (q, v, a, m) = (&p.q[..n], &p.v[..n], &p.a[..n], &m[..n]);
    let (f, cv, kq) = (&p.f_rhs[..n], &p.cv[..n], &p.kq[..n]);
    let (k0, k1) = (&p.k0[..n], &p.k1[..n]);
    let (q_hat, v_hat, b) = (&mut p.q_hat[..n], &mut p.v_hat[..n], &mut p.b[..n]);
    let qh = [0, 1, n - 2, n - 1].map(|j| q[j] + h * v[j] + cq * a[j]);
    let row = |i: usize, kqh: f64| {
        predict_row::<MASS, DAMPED, f64>(r, [v[i], a[i], f[i], m[i], cv[i], kq[i], kqh])
    };
    // Rows 0 and n − 1: two terms of K q̂.
    for (i, kqh, qi) in [
        (0, k0[0] * qh[0] + k1[1] * qh[1], qh[0]),
        (n - 1, k1[n - 1] * qh[2] + k0[n - 1] * qh[3], qh[3]),
    ] {
        q_hat[i] = qi;
        (v_hat[i], b[i]) = row(i, kqh);
    }
    let pairs = (n - 2) / 2;
    // The pairs (1, 2), (3, 4), …: every chunk slice has `pairs` elements (K[i+1][i] from
    // `k1[2..]`), so the loop indexes without bounds checks.
    fn two(x: &[f64], from: usize, pairs: usize) -> &[[f64; 2]] {
        &x[from..].as_chunks::<2>().0[..pairs]
    }
    let (qc, vc, ac, mc) = (
        two(q, 1, pairs),
        two(v, 1, pairs),
        two(a, 1, pairs),
        two(m, 1, pairs),
    );
    let (fc, cvc, kqc) = (two(f, 1, pairs), two(cv, 1, pairs), two(kq, 1, pairs));
    let (k0c, klc, kuc) = (two(k0, 1, pairs), two(k1, 1, pairs), two(k1, 2, pairs));
    let (qhc, vhc, bc) = (
        &mut q_hat[1..].as_chunks_mut::<2>().0[..pairs],
        &mut v_hat[1..].as_chunks_mut::<2>().0[..pairs],
        &mut b[1..].as_chunks_mut::<2>().0[..pairs],
    );
    let pair_at = |c: usize| Fx(qc[c]) + h * Fx(vc[c]) + cq * Fx(ac[c]);
    // q̂ below the pair, of the pair, and above it (the first row of the next pair, or for
    // the last pair q̂_{n−1} (n even) or q̂_{n−2} (n odd)).
    let mut below = qh[0];
    let mut cur = if pairs > 0 { pair_at(0) } else { Fx::default() };
    let last_above = if n.is_multiple_of(2) { qh[3] } else { qh[2] };
    for c in 0..pairs {
        let (next, above) = if c + 1 < pairs {
            let x = pair_at(c + 1);
            (x, x.0[0])
        } else {
            (Fx::default(), last_above)
        };
        let [lo, hi] = cur.0;
        let kqh = Fx(klc[c]) * Fx([below, lo]) + Fx(k0c[c]) * cur + Fx(kuc[c]) * Fx([hi, above]);
        let x = [
            Fx(vc[c]),
            Fx(ac[c]),
            Fx(fc[c]),
            Fx(mc[c]),
            Fx(cvc[c]),
            Fx(kqc[c]),
            kqh,
        ];
        let (vh, bb) = predict_row::<MASS, DAMPED, F2>(r, x);
        (qhc[c], vhc[c], bc[c]) = (cur.0, vh.0, bb.0);
        below = hi;
        cur = next;
    }
    if !n.is_multiple_of(2) && n >= 3 {
        // Row n − 2 of an odd n, after the pairs.
        let i = n - 2;
        let kqh = k1[i] * below + k0[i] * qh[2] + k1[i + 1] * qh[3];
        q_hat[i] = qh[2];
        (v_hat[i], b[i]) = row(i, kqh);
    }
}

/// The predictors and the right-hand side of (53) for any banded K (what [`predict_sweep`]
/// does for a tridiagonal one): q̂ stored, K q̂ formed by [`SymBand::mul_into`] into `tmp`.
fn predict_general<const MASS: u8, const DAMPED: bool>(
    p: PredictSweep<'_>,
    m: &[f64],
    c: [f64; 2],
    r: RowCoefficients,
    stiffness: &SymBand,
    tmp: &mut [f64],
) {
    let n = p.q.len();
    let [h, cq] = c;
    for ((qh, q), (v, a)) in p.q_hat[..n]
        .iter_mut()
        .zip(&p.q[..n])
        .zip(p.v[..n].iter().zip(&p.a[..n]))
    {
        *qh = q + h * v + cq * a;
    }
    stiffness.mul_into(p.q_hat, tmp);
    let (v, a, m, f) = (&p.v[..n], &p.a[..n], &m[..n], &p.f_rhs[..n]);
    let (cv, kq, kqh) = (&p.cv[..n], &p.kq[..n], &tmp[..n]);
    for (i, (vh, b)) in p.v_hat[..n].iter_mut().zip(&mut p.b[..n]).enumerate() {
        (*vh, *b) =
            predict_row::<MASS, DAMPED, f64>(r, [v[i], a[i], f[i], m[i], cv[i], kq[i], kqh[i]]);
    }
}

/// The vectors [`finish_sweep`] reads (t_{k+1}: `…1`, t_k: `…0`) and writes, all of length n.
struct Sweep<'a> {
    q1: &'a [f64],
    q0: &'a [f64],
    v1: &'a [f64],
    v0: &'a [f64],
    a1: &'a [f64],
    a0: &'a [f64],
    kq1: &'a [f64],
    kq0: &'a [f64],
    ma1: &'a [f64],
    ma0: &'a [f64],
    /// γ F_{k+1} + (1 − γ) F_k.
    fw: &'a [f64],
    z0: &'a [f64],
    kz0: &'a [f64],
    /// Diagonal of M (read for a lumped mass only, where `ma1`, `ma0` are not).
    mass: &'a [f64],
    z1: &'a mut [f64],
    kz1: &'a mut [f64],
    /// v_{k+1} − v_k and v_{k+1} + v_k (written for a consistent mass only).
    dv: &'a mut [f64],
    sv: &'a mut [f64],
    /// c_n = ν/(½ + ν), c_m = (½ − ν)/(½ + ν).
    filter: [f64; 2],
}

const S_WORK_EXT: usize = 0;
const S_DQ_K_DQ: usize = 1;
const S_D_STRAIN: usize = 2;
const S_DA_M_DA: usize = 3;
const S_D_ATERM: usize = 4;
const S_STRAIN: usize = 5;
const S_ATERM: usize = 6;
const S_D_KIN: usize = 7;
const S_KIN: usize = 8;
const S_DZ_K_DZ: usize = 9;
const S_D_ZTERM: usize = 10;
const S_ZTERM: usize = 11;
const SUMS: usize = 12;

/// Which sums a pass of [`finish_sweep`] forms: those of q (with the z filter), or of a and v.
const PART_Q: u8 = 0;
const PART_AV: u8 = 1;

/// The z filter of a [`finish_sweep`]: none (ν = 0 or η = 0), z_{k+1} = c_n Δq (c_m = 0, α_m = 0),
/// or z_{k+1} = c_n Δq − c_m z_k.
const NO_FILTER: u8 = 0;
const MEMORYLESS_FILTER: u8 = 1;
const FILTER_WITH_MEMORY: u8 = 2;

/// One pass over the dofs for part of the sums of a step (Lemma 2). `PART_Q`: the z filter (48),
/// `Δqᵀ F_{k,γ}`, `‖Δq‖²_K`, `(q_{k+1} + q_k)ᵀ K Δq`, `qᵀKq` (at t_{k+1}) and, with the
/// filters, `‖Δz‖²_K`, `(z_{k+1} + z_k)ᵀ K Δz` and `zᵀKz`. `PART_AV`: `‖Δa‖²_M`,
/// `(a_{k+1} + a_k)ᵀ M Δa`, `aᵀMa` and, with a lumped mass, `(v_{k+1} + v_k)ᵀ M Δv` and `vᵀMv`
/// (with a consistent mass Δv and v_{k+1} + v_k for `SymBand::quad`). The two parts read
/// disjoint vectors, so splitting them costs no memory traffic, and each keeps its sums in
/// registers (all twelve in one loop did not fit the sixteen vector registers and were kept
/// in memory). The sums of H run in four interleaved partial sums (by dof index mod 4, the
/// order of `dot` and `SymBand::quad`, so H agrees bit for bit with
/// [`AlphaCore::algorithmic_energy`]), the others in two: round-off differences only from the
/// sequential sums. Returns the part's sums (the others zero).
fn finish_sweep<const FILTER: u8, const LUMPED: bool, const PART: u8>(
    w: &mut Sweep<'_>,
) -> [f64; SUMS] {
    let n = w.q1.len();
    let m = n / 4;
    let k = SweepCoefficients { filter: w.filter };
    // The dofs 0..4m as chunks of four (one lane per dof index mod 4): every chunk slice has
    // the same length m, so the loop below indexes without bounds checks and vectorises.
    fn quads(x: &[f64], m: usize) -> &[[f64; 4]] {
        &x.as_chunks::<4>().0[..m]
    }
    let ins = [
        quads(w.q1, m),
        quads(w.q0, m),
        quads(w.v1, m),
        quads(w.v0, m),
        quads(w.a1, m),
        quads(w.a0, m),
        quads(w.kq1, m),
        quads(w.kq0, m),
        quads(w.ma1, m),
        quads(w.ma0, m),
        quads(w.fw, m),
        quads(w.z0, m),
        quads(w.kz0, m),
        quads(w.mass, m),
    ];
    let (z1, kz1, dvs, svs) = (&mut *w.z1, &mut *w.kz1, &mut *w.dv, &mut *w.sv);
    let (z1q, kz1q, dvq, svq) = (
        &mut z1[..n].as_chunks_mut::<4>().0[..m],
        &mut kz1[..n].as_chunks_mut::<4>().0[..m],
        &mut dvs[..n].as_chunks_mut::<4>().0[..m],
        &mut svs[..n].as_chunks_mut::<4>().0[..m],
    );
    // The sums of H in four lanes (the order of `dot` and `SymBand::quad`), the others in two
    // (lanes l and l + 2 added first).
    let mut lanes = [F4::default(); SUMS];
    let mut pairs = [[0.0; 2]; SUMS];
    for c in 0..m {
        let x = std::array::from_fn(|j| Fx(ins[j][c]));
        let (t, out) = dof::<FILTER, LUMPED, PART, F4>(&k, x);
        for s in 0..SUMS {
            if !used::<FILTER, LUMPED, PART>(s) {
                continue;
            }
            if of_h(s) {
                lanes[s] = lanes[s] + t[s];
            } else {
                let u = t[s].0;
                pairs[s] = [pairs[s][0] + (u[0] + u[2]), pairs[s][1] + (u[1] + u[3])];
            }
        }
        if FILTER != NO_FILTER && PART == PART_Q {
            z1q[c] = out[0].0;
            kz1q[c] = out[1].0;
        }
        if !LUMPED && PART == PART_AV {
            dvq[c] = out[2].0;
            svq[c] = out[3].0;
        }
    }
    let mut tail = [0.0; SUMS];
    let all = [
        w.q1, w.q0, w.v1, w.v0, w.a1, w.a0, w.kq1, w.kq0, w.ma1, w.ma0, w.fw, w.z0, w.kz0, w.mass,
    ];
    for i in 4 * m..n {
        let x = std::array::from_fn(|j| all[j][i]);
        let (t, out) = dof::<FILTER, LUMPED, PART, f64>(&k, x);
        for (s, acc) in tail.iter_mut().enumerate() {
            if used::<FILTER, LUMPED, PART>(s) {
                *acc += t[s];
            }
        }
        if FILTER != NO_FILTER && PART == PART_Q {
            z1[i] = out[0];
            kz1[i] = out[1];
        }
        if !LUMPED && PART == PART_AV {
            dvs[i] = out[2];
            svs[i] = out[3];
        }
    }
    std::array::from_fn(|s| {
        if !used::<FILTER, LUMPED, PART>(s) {
            0.0
        } else if of_h(s) {
            let l = lanes[s].0;
            (l[0] + l[2]) + (l[1] + l[3]) + tail[s]
        } else {
            (pairs[s][0] + pairs[s][1]) + tail[s]
        }
    })
}

/// Whether sum `s` is one of H (55): qᵀKq, aᵀMa, vᵀMv, zᵀKz.
#[inline(always)]
const fn of_h(s: usize) -> bool {
    matches!(s, S_STRAIN | S_ATERM | S_KIN | S_ZTERM)
}

/// L dofs at once, lane l for the l-th dof of a chunk: element-wise arithmetic that the
/// compiler maps to vector instructions (each lane computes exactly what a scalar would).
#[derive(Debug, Clone, Copy)]
struct Fx<const L: usize>([f64; L]);

/// Four dofs (lane l for the dof index ≡ l mod 4), the finish sweep's unit.
type F4 = Fx<4>;
/// Two dofs, the predictor sweep's unit.
type F2 = Fx<2>;

impl<const L: usize> Default for Fx<L> {
    fn default() -> Self {
        Fx([0.0; L])
    }
}

impl<const L: usize> std::ops::Add for Fx<L> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Fx(std::array::from_fn(|l| self.0[l] + o.0[l]))
    }
}

impl<const L: usize> std::ops::Sub for Fx<L> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Fx(std::array::from_fn(|l| self.0[l] - o.0[l]))
    }
}

impl<const L: usize> std::ops::Mul for Fx<L> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Fx(std::array::from_fn(|l| self.0[l] * o.0[l]))
    }
}

impl<const L: usize> std::ops::Mul<Fx<L>> for f64 {
    type Output = Fx<L>;
    #[inline(always)]
    fn mul(self, o: Fx<L>) -> Fx<L> {
        Fx(o.0.map(|x| self * x))
    }
}

/// What [`dof`] and [`predict_row`] compute with: one dof (f64) or several ([`Fx`]).
trait Lane:
    Copy
    + Default
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
where
    f64: std::ops::Mul<Self, Output = Self>,
{
}

impl Lane for f64 {}
impl<const L: usize> Lane for Fx<L> {}

/// The coefficients of [`dof`]: c_n = ν/(½ + ν), c_m = (½ − ν)/(½ + ν).
struct SweepCoefficients {
    filter: [f64; 2],
}

/// Whether sum `s` is formed by the variant and the part (the filter sums with filters, the
/// kinetic sums with a lumped mass).
#[inline(always)]
const fn used<const FILTER: u8, const LUMPED: bool, const PART: u8>(s: usize) -> bool {
    match s {
        S_WORK_EXT | S_DQ_K_DQ | S_D_STRAIN | S_STRAIN => PART == PART_Q,
        S_DZ_K_DZ | S_D_ZTERM | S_ZTERM => FILTER != NO_FILTER && PART == PART_Q,
        S_D_KIN | S_KIN => LUMPED && PART == PART_AV,
        _ => PART == PART_AV,
    }
}

/// The terms of one dof (or four, [`F4`]) of one part (`PART`) for [`finish_sweep`] from
/// `x` = (q, q_k, v, v_k, a, a_k, Kq, (Kq)_k, Ma, (Ma)_k, γF + (1 − γ)F_k, z_k, (Kz)_k, M_ii)
/// (no index: t_{k+1}); returns the terms of the part's sums and (z, Kz, Δv, v + v_k) at
/// t_{k+1} (the part's entries; the others zero).
#[inline(always)]
fn dof<const FILTER: u8, const LUMPED: bool, const PART: u8, T: Lane>(
    k: &SweepCoefficients,
    x: [T; 14],
) -> ([T; SUMS], [T; 4])
where
    f64: std::ops::Mul<T, Output = T>,
{
    let [
        q1,
        q0,
        v1,
        v0,
        a1,
        a0,
        kq1,
        kq0,
        ma1,
        ma0,
        fw,
        z0,
        kz0,
        mass,
    ] = x;
    let mut t = [T::default(); SUMS];
    let mut out = [T::default(); 4];
    if PART == PART_Q {
        let [cn, cm] = k.filter;
        let dq = q1 - q0;
        t[S_WORK_EXT] = dq * fw;
        let dkq = kq1 - kq0;
        t[S_DQ_K_DQ] = dq * dkq;
        t[S_D_STRAIN] = (q1 + q0) * dkq;
        t[S_STRAIN] = q1 * kq1;
        if FILTER != NO_FILTER {
            let (z, kz) = if FILTER == FILTER_WITH_MEMORY {
                (cn * dq - cm * z0, cn * dkq - cm * kz0)
            } else {
                (cn * dq, cn * dkq)
            };
            let dkz = kz - kz0;
            t[S_DZ_K_DZ] = (z - z0) * dkz;
            t[S_D_ZTERM] = (z + z0) * dkz;
            t[S_ZTERM] = z * kz;
            out[0] = z;
            out[1] = kz;
        }
    } else {
        // A lumped mass: M a = m∘a (the product `SymBand::mul_into` forms), `ma` not read.
        let (ma1, ma0) = if LUMPED {
            (mass * a1, mass * a0)
        } else {
            (ma1, ma0)
        };
        let dma = ma1 - ma0;
        t[S_DA_M_DA] = (a1 - a0) * dma;
        t[S_D_ATERM] = (a1 + a0) * dma;
        t[S_ATERM] = a1 * ma1;
        let (dv, sv) = (v1 - v0, v1 + v0);
        if LUMPED {
            t[S_D_KIN] = mass * sv * dv;
            t[S_KIN] = mass * v1 * v1;
        }
        out[2] = dv;
        out[3] = sv;
    }
    (t, out)
}

fn dot(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len());
    let (xc, yc) = (x[..n].chunks_exact(4), y[..n].chunks_exact(4));
    let mut tail = 0.0;
    for (a, b) in xc.remainder().iter().zip(yc.remainder()) {
        tail += a * b;
    }
    // Four interleaved partial sums: consecutive additions do not wait for each other (one
    // running sum is bound by the latency of one addition per dof); round-off differences only.
    let mut acc = [0.0; 4];
    for (a, b) in xc.zip(yc) {
        for l in 0..4 {
            acc[l] += a[l] * b[l];
        }
    }
    (acc[0] + acc[2]) + (acc[1] + acc[3]) + tail
}

/// The nonsmooth α-family scheme (25) / (30) for one model and one step size.
#[derive(Debug, Clone)]
pub struct NonsmoothAlpha {
    params: AlphaParams,
    lcp: LcpOptions,
    core: AlphaCore,
    /// Per contact α (n entries each): the change of a_{k+1}, v_{k+1}, q_{k+1} per unit P^α.
    a_cols: Vec<f64>,
    v_cols: Vec<f64>,
    q_cols: Vec<f64>,
    /// Delassus operator `W = Gᵀ Ŵ G`, row-major m×m (not symmetric in general).
    w: Vec<f64>,
    index_set: IndexSet,
    lcp_m: Vec<f64>,
    /// The banded path (many single-dof contacts, lumped mass), instead of the dense columns.
    banded: Option<BandedAlpha>,
}

/// The α-family's impulse on the banded S: with `y = M⁻¹ G P` (the w_{k+1} of (25b)) and
/// `z = S⁻¹ B y`, `B = (1−α_C) C + (1−α_K)(h/2) K`, the impulse changes a_{k+1} by −z,
/// v_{k+1} by `y − γh z = S⁻¹ R y` and q_{k+1} by `(h/2) y − βh² z`, where
/// `R = S − γh B = (1−α_M) M + (1−α_K) h²(β − γ/2) K`: the problem is `S x = R M⁻¹ G P`
/// ([`ImpulseMap::Filtered`]), x the change of v_{k+1}.
#[derive(Debug, Clone)]
struct BandedAlpha {
    impulse: BandedImpulse,
    /// B.
    b: SymBand,
    /// Diagonal of M.
    mass: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
}

impl NonsmoothAlpha {
    /// Prepares the scheme: factorises S and M, precomputes the impulse columns and the
    /// Delassus operator. `params` should have passed [`AlphaParams::validate`].
    pub fn new(
        model: &LinearModel,
        params: AlphaParams,
        h: f64,
        lcp: LcpOptions,
    ) -> Result<Self, BandError> {
        let core = AlphaCore::new(model, params.coefficients(), h)?;
        let w8 = params.weights();
        let (beta, gamma) = (params.beta, params.gamma);
        if uses_banded(model, lcp.kind, true) {
            let n = model.dofs();
            let s = SymBand::combine(&[
                (1.0 - w8.mass, &model.mass),
                ((1.0 - w8.damping) * gamma * h, &model.damping),
                ((1.0 - w8.stiffness) * beta * h * h, &model.stiffness),
            ]);
            let r = SymBand::combine(&[
                (1.0 - w8.mass, &model.mass),
                (
                    (1.0 - w8.stiffness) * h * h * (beta - 0.5 * gamma),
                    &model.stiffness,
                ),
            ]);
            let mass: Vec<f64> = (0..n).map(|i| model.mass.get(i, i)).collect();
            let d = mass.iter().map(|m| 1.0 / m).collect();
            let b = SymBand::combine(&[
                (1.0 - w8.damping, &model.damping),
                ((1.0 - w8.stiffness) * 0.5 * h, &model.stiffness),
            ]);
            return Ok(Self {
                params,
                lcp,
                core,
                a_cols: Vec::new(),
                v_cols: Vec::new(),
                q_cols: Vec::new(),
                w: Vec::new(),
                index_set: IndexSet::new(model.contacts.len()),
                lcp_m: Vec::new(),
                banded: Some(BandedAlpha {
                    impulse: BandedImpulse::new(model, s, ImpulseMap::Filtered { r, d }),
                    b,
                    mass,
                    y: vec![0.0; n],
                    z: vec![0.0; n],
                }),
            });
        }
        let (n, m) = (model.dofs(), model.contacts.len());
        let mut a_cols = vec![0.0; n * m];
        let mut v_cols = vec![0.0; n * m];
        let mut q_cols = vec![0.0; n * m];
        let mut x = vec![0.0; n];
        let mut y = vec![0.0; n];
        let mut t = vec![0.0; n];
        for (a, c) in model.contacts.iter().enumerate() {
            // x = M⁻¹ G_α (w per unit impulse), y = S⁻¹[(1−α_C) C + (1−α_K)(h/2) K] x.
            x.fill(0.0);
            for &(i, g) in &c.g {
                x[i] += g;
            }
            core.m_factor.solve_in_place(&mut x);
            model.stiffness.mul_into(&x, &mut y);
            model.damping.mul_into(&x, &mut t);
            for i in 0..n {
                y[i] = (1.0 - w8.stiffness) * 0.5 * h * y[i] + (1.0 - w8.damping) * t[i];
            }
            core.s_factor.solve_in_place(&mut y);
            for i in 0..n {
                a_cols[a * n + i] = -y[i];
                v_cols[a * n + i] = x[i] - gamma * h * y[i];
                q_cols[a * n + i] = 0.5 * h * x[i] - beta * h * h * y[i];
            }
        }
        let mut w = vec![0.0; m * m];
        for (a, c) in model.contacts.iter().enumerate() {
            for b in 0..m {
                w[a * m + b] = c.project(&v_cols[b * n..(b + 1) * n]);
            }
        }
        Ok(Self {
            params,
            lcp,
            core,
            a_cols,
            v_cols,
            q_cols,
            w,
            index_set: IndexSet::new(model.contacts.len()),
            lcp_m: Vec::new(),
            banded: None,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &AlphaParams {
        &self.params
    }

    /// The smooth acceleration a_k of the last state this scheme produced (or of a consistent
    /// start at `state`).
    pub fn acceleration(&mut self, model: &LinearModel, state: &LinearState) -> &[f64] {
        self.core.ensure_history(model, state);
        &self.core.cur.a
    }
}

impl LinearScheme for NonsmoothAlpha {
    fn step_size(&self) -> f64 {
        self.core.h
    }

    fn save_state(&self) -> SchemeState {
        SchemeState::Alpha(Box::new(AlphaState {
            core: self.core.checkpoint_state(),
            index_set: self.index_set.clone(),
            lcp_m: self.lcp_m.clone(),
            banded_warm: self.banded.as_ref().map(|b| b.impulse.warm_start()),
        }))
    }

    fn restore_state(&mut self, state: SchemeState) -> Result<(), CheckpointError> {
        match state {
            SchemeState::Alpha(s) => {
                let AlphaState {
                    core,
                    index_set,
                    lcp_m,
                    banded_warm,
                } = *s;
                restore_warm_start(self.banded.as_mut().map(|b| &mut b.impulse), banded_warm)?;
                self.core.restore_checkpoint_state(core)?;
                self.index_set = index_set;
                self.lcp_m = lcp_m;
                Ok(())
            }
            other => Err(other.mismatch("the nonsmooth α-family")),
        }
    }

    fn algorithmic_energy(&self, model: &LinearModel, state: &LinearState) -> f64 {
        self.core.algorithmic_energy(model, state)
    }

    fn step(
        &mut self,
        model: &LinearModel,
        state: &mut LinearState,
        report: &mut StepReport,
    ) -> Result<(), StepError> {
        let h = self.core.h;
        let t_k = state.t;
        let step = state.step + 1;
        let t_next = self.core.predict(model, state);
        let n = state.q.len();
        let m = model.contacts.len();

        // Index set (24) and the LCP on the combined system (25c)–(25d).
        let v_free = &self.core.s.v;
        self.index_set.assemble(
            &self.params.index_set,
            &model.contacts,
            state.step,
            &state.q,
            &state.v,
            t_k,
            h,
            |c| c.local_velocity(v_free, t_next),
        );
        report.impulse.fill(0.0);
        report.lcp = LcpStats::default();
        if let Some(banded) = self.banded.as_mut() {
            report.lcp = banded
                .impulse
                .apply(&mut self.index_set, &self.lcp, &mut report.impulse, step)
                .map_err(|source| StepError::Lcp {
                    step,
                    t: t_next,
                    source,
                })?;
            if report.lcp.size > 0 {
                // y = M⁻¹ G P, z = S⁻¹ B y; a −= z, v += y − γh z, q += (h/2) y − βh² z.
                banded.y.fill(0.0);
                for &a in &self.index_set.active {
                    let (dof, coef) = banded.impulse.unit(a);
                    banded.y[dof] = coef * report.impulse[a] / banded.mass[dof];
                }
                banded.b.mul_into(&banded.y, &mut banded.z);
                self.core.s_factor.solve_in_place(&mut banded.z);
                let (beta, gamma) = (self.params.beta, self.params.gamma);
                let s = &mut self.core.s;
                for i in 0..n {
                    let (y, z) = (banded.y[i], banded.z[i]);
                    s.a[i] -= z;
                    s.v[i] += y - gamma * h * z;
                    s.q[i] += 0.5 * h * y - beta * h * h * z;
                }
            }
        } else if !self.index_set.active.is_empty() {
            self.lcp_m.clear();
            for &a in &self.index_set.active {
                for &b in &self.index_set.active {
                    self.lcp_m.push(self.w[a * m + b]);
                }
            }
            let sol = lcp::solve(
                Lcp {
                    m: &self.lcp_m,
                    q: &self.index_set.rhs,
                },
                &self.lcp,
            )
            .map_err(|source| StepError::Lcp {
                step,
                t: t_next,
                source,
            })?;
            report.lcp = LcpStats {
                size: self.index_set.active.len(),
                iterations: sol.iterations,
                error: sol.error,
            };
            let s = &mut self.core.s;
            for (r, &a) in self.index_set.active.iter().enumerate() {
                let p = sol.z[r];
                report.impulse[a] = p;
                if p != 0.0 {
                    let (ac, vc, qc) = (
                        &self.a_cols[a * n..(a + 1) * n],
                        &self.v_cols[a * n..(a + 1) * n],
                        &self.q_cols[a * n..(a + 1) * n],
                    );
                    for (((sa, sv), sq), ((ac, vc), qc)) in s.a[..n]
                        .iter_mut()
                        .zip(&mut s.v[..n])
                        .zip(&mut s.q[..n])
                        .zip(ac.iter().zip(vc).zip(qc))
                    {
                        *sa += p * ac;
                        *sv += p * vc;
                        *sq += p * qc;
                    }
                }
            }
        }
        if self.banded.is_none() {
            self.index_set
                .record_roundoff(&self.w, &report.impulse, step);
        }
        // work_contact = (Gᵀ v_{k+1/2})ᵀ P_{k+1} (Lemma 2; U_{k+1/2}ᵀP for a fixed obstacle).
        let mut work_contact = 0.0;
        for &a in &self.index_set.active {
            let p = report.impulse[a];
            if p != 0.0 {
                let c = &model.contacts[a];
                work_contact += p * 0.5 * (c.project(&self.core.s.v) + c.project(&state.v));
            }
        }
        self.core.finish(
            model,
            state,
            t_next,
            ContactWork::Impulse(work_contact),
            report,
        );
        Ok(())
    }
}

/// What [`AlphaCore`] carries between steps: the history frames (accelerations a_k, the filters
/// z, x, y and their products, λ_k of a baseline), the step they describe and the scratch
/// vectors.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct AlphaCoreState {
    cur: Frame,
    nxt: Frame,
    cur_step: Option<u64>,
    s: Scratch,
}

/// What [`NonsmoothAlpha`] carries between steps: its core's state and the index set with its
/// round-off levels.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct AlphaState {
    core: AlphaCoreState,
    index_set: IndexSet,
    lcp_m: Vec<f64>,
    /// The banded solver's warm start (the banded contact path only).
    banded_warm: Option<Vec<bool>>,
}

impl AlphaCore {
    pub(crate) fn checkpoint_state(&self) -> AlphaCoreState {
        AlphaCoreState {
            cur: self.cur.clone(),
            nxt: self.nxt.clone(),
            cur_step: self.cur_step,
            s: self.s.clone(),
        }
    }

    pub(crate) fn restore_checkpoint_state(
        &mut self,
        s: AlphaCoreState,
    ) -> Result<(), CheckpointError> {
        // M a is kept for a consistent mass only; a lumped-mass checkpoint of an earlier build
        // holds a stale copy, dropped here so that the state is the one a run keeps.
        let lumped = self.lumped;
        let fits = |f: &Frame, g: &Frame| {
            f.a.len() == g.a.len()
                && f.lambda.len() == g.lambda.len()
                && (lumped || f.ma.len() == g.ma.len())
        };
        if !fits(&s.cur, &self.cur) || !fits(&s.nxt, &self.nxt) || s.s.a.len() != self.s.a.len() {
            return Err(CheckpointError::Mismatch(format!(
                "α-family state of {} dofs, the model has {}",
                s.cur.a.len(),
                self.cur.a.len()
            )));
        }
        let (mut cur, mut nxt) = (s.cur, s.nxt);
        if lumped {
            cur.ma = Vec::new();
            nxt.ma = Vec::new();
        }
        self.cur = cur;
        self.nxt = nxt;
        self.cur_step = s.cur_step;
        self.s = s.s;
        self.f_ready = false;
        Ok(())
    }
}
