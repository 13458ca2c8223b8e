//! `[integrator]`: the schemes and their parameters. The field groups several schemes share
//! (the index set, the SOI2 Newton settings) are one struct each, flattened into the scheme's
//! table, with their defaults and their check in one place.

use super::SpecError;
use crate::contact::{Activation, IndexSetRule};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// `[integrator]`: the scheme and its parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "scheme", rename_all = "snake_case")]
pub enum IntegratorSpec {
    /// Moreau–Jean θ-scheme, Acary 2016 (21)–(24); θ ∈ [0, 1].
    MoreauJean(MoreauJeanSpec),
    /// Its variant (29): `q_{k+1} = q_k + h v_{k+1/2}`.
    MoreauJeanVariant(MoreauJeanSpec),
    /// Nonsmooth Newmark, Acary 2016 (25) with α_m = α_f = 0. Dissipative for 2β ≥ γ ≥ ½ (89);
    /// parameters outside are refused unless `allow_unstable = true`.
    NsNewmark(NsNewmarkSpec),
    /// Nonsmooth HHT, Acary 2016 (25) with α_m = 0, α_f = α (78); α required, β and γ default to
    /// (1 + α)²/4 and ½ + α. Dissipative for 2β ≥ γ ≥ ½, 0 ≤ α ≤ γ − ½ ≤ ½ (83).
    NsHht(NsHhtSpec),
    /// Nonsmooth generalized-α, Acary 2016 (25)–(27): `rho_inf` (default 0.8 when nothing is
    /// given), or `alpha_m`, `alpha_f` with optional `gamma` and `beta`, not both.
    NsGeneralizedAlpha(NsAlphaSpec),
    /// Nonsmooth Krenk–Høgsberg generalized-α, Acary 2016 (30); parameters as for
    /// `ns_generalized_alpha`.
    NsKhAlpha(NsAlphaSpec),
    /// Standard Newmark with contact at position level (the baseline that blows up); β default
    /// ¼, γ default ½, no α.
    NewmarkPositionContact(PositionContactSpec),
    /// Standard HHT with contact at position level (baseline); α required, β and γ defaulting
    /// as for `ns_hht`.
    HhtPositionContact(PositionContactSpec),
    /// Generalized-α-SOI2, Jay & Negrut 2008 (13): coefficients from `rho_inf` (default 0.2) or
    /// given as `alpha_m`, `alpha_f` (and optionally `beta`, `gamma`).
    Soi2GeneralizedAlpha(Soi2GeneralizedAlphaSpec),
    /// HHT-SOI2, Jay & Negrut 2008 (17); α ∈ [−⅓, 0].
    Soi2Hht(HhtSoi2Spec),
    /// HHT-I3 (index 3, position constraints only): the baseline of HHT-SOI2.
    HhtI3(HhtSoi2Spec),
    /// Wave finite elements, Yoong et al. 2018 Appendices A–B: scenes `bar`/`dep_bar`, cells = elements.
    Wfem(WfemSpec),
}

/// The families of schemes: each runs its own kind of model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SchemeFamily {
    /// Linear models with unilateral contacts (Moreau–Jean, the α-family, the baselines).
    Linear,
    /// Nonlinear constrained models (SOI2 schemes, HHT-I3).
    Soi2,
    /// Wave finite elements on the `bar` and `dep_bar` scenes.
    Wave,
}

/// Parameters of `wfem` (none: Δt = Δx/c is fixed by the bar, and `time.h` must equal it).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct WfemSpec {}

impl Default for IntegratorSpec {
    fn default() -> Self {
        IntegratorSpec::MoreauJean(MoreauJeanSpec::default())
    }
}

impl IntegratorSpec {
    /// Which family of integrators the scheme belongs to.
    pub fn family(&self) -> SchemeFamily {
        match self {
            IntegratorSpec::MoreauJean(_)
            | IntegratorSpec::MoreauJeanVariant(_)
            | IntegratorSpec::NsNewmark(_)
            | IntegratorSpec::NsHht(_)
            | IntegratorSpec::NsGeneralizedAlpha(_)
            | IntegratorSpec::NsKhAlpha(_)
            | IntegratorSpec::NewmarkPositionContact(_)
            | IntegratorSpec::HhtPositionContact(_) => SchemeFamily::Linear,
            IntegratorSpec::Soi2GeneralizedAlpha(_)
            | IntegratorSpec::Soi2Hht(_)
            | IntegratorSpec::HhtI3(_) => SchemeFamily::Soi2,
            IntegratorSpec::Wfem(_) => SchemeFamily::Wave,
        }
    }

    /// The scheme's name as written in specs.
    pub fn scheme(&self) -> &'static str {
        match self {
            IntegratorSpec::MoreauJean(_) => "moreau_jean",
            IntegratorSpec::MoreauJeanVariant(_) => "moreau_jean_variant",
            IntegratorSpec::NsNewmark(_) => "ns_newmark",
            IntegratorSpec::NsHht(_) => "ns_hht",
            IntegratorSpec::NsGeneralizedAlpha(_) => "ns_generalized_alpha",
            IntegratorSpec::NsKhAlpha(_) => "ns_kh_alpha",
            IntegratorSpec::NewmarkPositionContact(_) => "newmark_position_contact",
            IntegratorSpec::HhtPositionContact(_) => "hht_position_contact",
            IntegratorSpec::Soi2GeneralizedAlpha(_) => "soi2_generalized_alpha",
            IntegratorSpec::Soi2Hht(_) => "soi2_hht",
            IntegratorSpec::HhtI3(_) => "hht_i3",
            IntegratorSpec::Wfem(_) => "wfem",
        }
    }
}

fn half() -> f64 {
    0.5
}

/// Parameters of `moreau_jean` and `moreau_jean_variant`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MoreauJeanSpec {
    /// θ ∈ [0, 1], default ½.
    #[serde(default = "half")]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub theta: f64,
    /// Index-set rule (`activation`, `activation_gamma`).
    #[serde(flatten)]
    pub index_set: IndexSetSpec,
}

impl Default for MoreauJeanSpec {
    fn default() -> Self {
        Self {
            theta: half(),
            index_set: IndexSetSpec::default(),
        }
    }
}

/// The index set of the velocity-level schemes (Moreau–Jean and the nonsmooth α-family): which
/// contacts enter a step's LCP. Its fields sit directly in `[integrator]`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
pub struct IndexSetSpec {
    /// Index-set rule: `gap_and_velocity` ((24) of Acary 2016, the default when left out) or
    /// `predicted_gap` (Siconos' `g(q_k) + γ h U_k ≤ 0`, no sign test on U_k). A `rigid_bodies`
    /// scene takes its contacts at predicted gap ≤ `model.contact.margin` when it is left out,
    /// at ≤ 0 with `predicted_gap`, and refuses `gap_and_velocity`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub activation: Option<Activation>,
    /// γ > 0 of the predicted-gap rule, default 1 (only with `activation = "predicted_gap"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub activation_gamma: Option<f64>,
}

impl IndexSetSpec {
    /// The validated rule; errors name `integrator.activation_gamma`.
    pub fn rule(&self) -> Result<IndexSetRule, SpecError> {
        let gamma = match (self.activation, self.activation_gamma) {
            (None | Some(Activation::GapAndVelocity), Some(_)) => {
                return Err(SpecError::new(
                    "integrator.activation_gamma",
                    "only used with activation = \"predicted_gap\"",
                ));
            }
            (_, Some(g)) if !g.is_finite() || g <= 0.0 => {
                return Err(SpecError::new(
                    "integrator.activation_gamma",
                    format!("must be > 0, got {g}"),
                ));
            }
            (_, g) => g.unwrap_or(1.0),
        };
        Ok(IndexSetRule {
            activation: self.activation.unwrap_or_default(),
            gamma,
        })
    }
}

fn quarter() -> f64 {
    0.25
}

fn is_false(b: &bool) -> bool {
    !*b
}

/// Parameters of `ns_newmark` (Acary 2016 (25), α_m = α_f = 0). Dissipative for 2β ≥ γ ≥ ½ (89);
/// parameters outside are rejected unless `allow_unstable = true`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NsNewmarkSpec {
    /// β, default ¼ (with γ = ½: the trapezoidal rule, Corollary 1).
    #[serde(default = "quarter")]
    pub beta: f64,
    /// γ, default ½.
    #[serde(default = "half")]
    pub gamma: f64,
    /// Index-set rule (`activation`, `activation_gamma`), as for `moreau_jean`.
    #[serde(flatten)]
    pub index_set: IndexSetSpec,
    /// Run parameters outside the dissipation conditions anyway (default false).
    #[serde(default, skip_serializing_if = "is_false")]
    #[schemars(extend("default" = false))]
    pub allow_unstable: bool,
}

/// Parameters of `ns_hht` (Acary 2016 (78)): α, and β, γ defaulting to the second-order choice
/// γ = ½ + α, β = (1 + α)²/4. Dissipative for 2β ≥ γ ≥ ½, 0 ≤ α ≤ γ − ½ ≤ ½ (83).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NsHhtSpec {
    /// α = α_f (required); the classical range is [0, ⅓].
    pub alpha: f64,
    /// β, default (1 + α)²/4.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beta: Option<f64>,
    /// γ, default ½ + α.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gamma: Option<f64>,
    /// Index-set rule (`activation`, `activation_gamma`), as for `moreau_jean`.
    #[serde(flatten)]
    pub index_set: IndexSetSpec,
    /// Run parameters outside (83) anyway (default false).
    #[serde(default, skip_serializing_if = "is_false")]
    #[schemars(extend("default" = false))]
    pub allow_unstable: bool,
}

/// The coefficients of a generalized-α scheme (`ns_generalized_alpha`, `ns_kh_alpha`,
/// `soi2_generalized_alpha`): the spectral radius at infinity ρ∞, or α_m and α_f with optional β
/// and γ, not both. Each scheme derives the missing ones and checks them by its own conditions.
/// Its fields sit directly in `[integrator]`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
pub struct AlphaCoefficientsSpec {
    /// Spectral radius at infinity ρ∞ ∈ [0, 1]: sets α_m, α_f, β, γ.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub rho_inf: Option<f64>,
    /// α_m (with α_f, instead of rho_inf).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha_m: Option<f64>,
    /// α_f (with α_m, instead of rho_inf).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha_f: Option<f64>,
    /// β (derived from γ when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beta: Option<f64>,
    /// γ (derived from α_m, α_f when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gamma: Option<f64>,
}

/// Parameters of `ns_generalized_alpha` and `ns_kh_alpha`: `rho_inf` ∈ [0, 1] (by (26)–(27);
/// default 0.8 when nothing is given), or `alpha_m`, `alpha_f` with optional `gamma` (default
/// (26)) and `beta` (default ¼(γ + ½)²), not both.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NsAlphaSpec {
    /// The coefficients (`rho_inf`, or `alpha_m`, `alpha_f`, `beta`, `gamma`); here α_m < 1,
    /// α_f ≤ 1 and the stability conditions of Acary 2016 apply.
    #[serde(flatten)]
    pub coefficients: AlphaCoefficientsSpec,
    /// Index-set rule (`activation`, `activation_gamma`), as for `moreau_jean`.
    #[serde(flatten)]
    pub index_set: IndexSetSpec,
    /// Run parameters outside the stability conditions anyway (default false).
    #[serde(default, skip_serializing_if = "is_false")]
    #[schemars(extend("default" = false))]
    pub allow_unstable: bool,
    /// How the smooth stage's Newton iterations get their matrix, `lagrangian` models under
    /// `ns_generalized_alpha` only (refused elsewhere: a linear model's step has no Newton):
    /// `full` (the default here: formed at every iterate, quadratic convergence) or
    /// `simplified` (kept across iterates and steps while it contracts the residual tenfold
    /// per iterate).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub newton: Option<NewtonSpec>,
}

/// Parameters of `newmark_position_contact` (β default ¼, γ default ½, no α) and
/// `hht_position_contact` (α required, β and γ defaulting as for `ns_hht`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PositionContactSpec {
    /// HHT α (hht_position_contact only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha: Option<f64>,
    /// β > 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beta: Option<f64>,
    /// γ.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gamma: Option<f64>,
    /// Run parameters outside (89)/(83) anyway (default false).
    #[serde(default, skip_serializing_if = "is_false")]
    #[schemars(extend("default" = false))]
    pub allow_unstable: bool,
}

// ---------------------------------------------------------------------------------------------
// SOI2 schemes (Jay & Negrut 2008)

fn default_newton_tolerance() -> f64 {
    1e-10
}
fn default_newton_max_iterations() -> usize {
    25
}
fn default_consistency_tolerance() -> f64 {
    1e-8
}
fn default_hht_alpha() -> f64 {
    -0.2
}

/// Start value of a_α in specs: `a0` (default) or `lunk_simeon` ((8)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum StartSpec {
    /// a_α := a₀.
    #[default]
    A0,
    /// a_α from (8).
    LunkSimeon,
}

/// How the Newton iterations of each step (the nonlinear system (13), (17) or HHT-I3's) get
/// their Jacobian, in specs: `newton = "simplified"` (default) or `"full"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum NewtonSpec {
    /// `NewtonStrategy::Simplified`: the AD Jacobian and its LU factorisation are kept across
    /// iterations and steps of one size while the increments contract (by ≤ ½ per iteration),
    /// rebuilt otherwise. Fewer Jacobians, more (cheap) iterations.
    #[default]
    Simplified,
    /// `NewtonStrategy::Full`: a fresh AD Jacobian at every iterate (quadratic convergence;
    /// the iteration counts comparable with the paper's).
    Full,
}

impl NewtonSpec {
    /// The name written in specs and summaries.
    pub fn name(self) -> &'static str {
        match self {
            NewtonSpec::Simplified => "simplified",
            NewtonSpec::Full => "full",
        }
    }
}

/// The Newton settings of the SOI2 schemes (the nonlinear step systems (13), (17), HHT-I3's)
/// and the consistency check of the initial values. Its fields sit directly in `[integrator]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct Soi2NewtonSpec {
    /// Step Newton strategy: `simplified` (default) or `full`.
    #[serde(default)]
    pub newton: NewtonSpec,
    /// Newton convergence: ‖Δx‖∞ ≤ tol·(1 + ‖x‖∞), > 0, default 1e-10.
    #[serde(default = "default_newton_tolerance")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub newton_tolerance: f64,
    /// Newton iterations per step, ≥ 1, default 25.
    #[serde(default = "default_newton_max_iterations")]
    #[schemars(range(min = 1))]
    pub newton_max_iterations: usize,
    /// Largest constraint residual accepted in the initial values, > 0, default 1e-8.
    #[serde(default = "default_consistency_tolerance")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub consistency_tolerance: f64,
}

impl Default for Soi2NewtonSpec {
    fn default() -> Self {
        Self {
            newton: NewtonSpec::Simplified,
            newton_tolerance: default_newton_tolerance(),
            newton_max_iterations: default_newton_max_iterations(),
            consistency_tolerance: default_consistency_tolerance(),
        }
    }
}

/// `scheme = "soi2_generalized_alpha"`: generalized-α-SOI2 (13). Coefficients from `rho_inf`
/// (default 0.2, the paper's experiments) or given as `alpha_m`, `alpha_f` (and optionally
/// `beta`, `gamma`, which default to (1 − α)²/4 and ½ − α with α = α_m − α_f).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Soi2GeneralizedAlphaSpec {
    /// The coefficients (`rho_inf`, or `alpha_m`, `alpha_f`, `beta`, `gamma`); here α_m ≠ 1
    /// with r = |α_m/(1 − α_m)| ≤ 1, α_f ≠ 1, β ≠ 0, γ ≠ 0 (Theorem 1).
    #[serde(flatten)]
    pub coefficients: AlphaCoefficientsSpec,
    /// Use the additive-force form of (13d): default = when the model's forces are additive;
    /// `true` is refused for a model whose forces are not.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub additive: Option<bool>,
    /// Start value of a_α.
    #[serde(default)]
    pub start: StartSpec,
    /// Newton settings (`newton`, `newton_tolerance`, `newton_max_iterations`,
    /// `consistency_tolerance`).
    #[serde(flatten)]
    pub solve: Soi2NewtonSpec,
}

impl Default for Soi2GeneralizedAlphaSpec {
    fn default() -> Self {
        Self {
            coefficients: AlphaCoefficientsSpec::default(),
            additive: None,
            start: StartSpec::A0,
            solve: Soi2NewtonSpec::default(),
        }
    }
}

/// `scheme = "soi2_hht"` (HHT-SOI2 (17)) and `scheme = "hht_i3"` (the index-3 baseline):
/// HHT-α with α ∈ [−⅓, 0] (default −0.2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct HhtSoi2Spec {
    /// α ∈ [−⅓, 0].
    #[serde(default = "default_hht_alpha")]
    #[schemars(range(min = -0.3333333333333333, max = 0.0))]
    pub alpha: f64,
    /// Start value of a_α.
    #[serde(default)]
    pub start: StartSpec,
    /// Newton settings (`newton`, `newton_tolerance`, `newton_max_iterations`,
    /// `consistency_tolerance`).
    #[serde(flatten)]
    pub solve: Soi2NewtonSpec,
}

impl Default for HhtSoi2Spec {
    fn default() -> Self {
        Self {
            alpha: default_hht_alpha(),
            start: StartSpec::A0,
            solve: Soi2NewtonSpec::default(),
        }
    }
}
