//! The job spec: one serde schema for the three spellings (TOML for the CLI, JSON over HTTP,
//! protobuf over gRPC converts to it). The field names pinned in DESIGN.md §7 are a public
//! contract: add fields freely, rename none. Unknown fields are rejected.
//!
//! A spec is only data; [`crate::job::Job::from_spec`] validates it once and builds the model
//! and the integrator, with errors that name the field ([`SpecError`]).

use crate::contact::{Activation, IndexSetRule};
use crate::lcp::LcpSolverKind;
use crate::scenes::{BarSpec, BouncingBall, Chain};
use crate::soi2::models::{JayNegrutTest, Pendulum, SliderCrank};
use crate::soi2::run::{HhtSoi2Spec, Soi2GeneralizedAlphaSpec};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A whole job.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JobSpec {
    /// Optional label.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The model (required by time-integration jobs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<ModelSpec>,
    /// The integrator; Moreau–Jean with θ = ½ when absent.
    #[serde(default)]
    pub integrator: IntegratorSpec,
    /// Step size and duration (required by time-integration jobs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time: Option<TimeSpec>,
    /// LCP solver settings.
    #[serde(default)]
    pub contact_solver: ContactSolverSpec,
    /// What to record.
    #[serde(default)]
    pub output: OutputSpec,
    /// A job that is not a time integration (`kind = "nonsmooth_modes"` or `"forced_response"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub analysis: Option<crate::modal::AnalysisSpec>,
}

/// `[model]`: the scene and its parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "scene", rename_all = "snake_case")]
pub enum ModelSpec {
    /// A ball bouncing on the ground.
    BouncingBall(BouncingBall),
    /// Elastic bar of linear finite elements against an obstacle.
    Bar(BarSpec),
    /// The Doyen–Ern–Piperno bouncing bar (defaults from Yoong et al. 2018, Table 1).
    DepBar(BarSpec),
    /// Masses and springs, one contact per mass.
    Chain(Chain),
    /// Raw matrices.
    Linear(LinearSpec),
    /// The pendulum (16) of Jay & Negrut 2008, Fig. 3 (SOI2 schemes).
    Pendulum(Pendulum),
    /// A rigid slider-crank under gravity (SOI2 schemes).
    SliderCrank(SliderCrank),
    /// The test problem (15) of Jay & Negrut 2008, with its exact solution (SOI2 schemes).
    JayNegrutTest(JayNegrutTest),
}

impl ModelSpec {
    /// The scene's name as written in specs.
    pub fn scene(&self) -> &'static str {
        match self {
            ModelSpec::BouncingBall(_) => "bouncing_ball",
            ModelSpec::Bar(_) => "bar",
            ModelSpec::DepBar(_) => "dep_bar",
            ModelSpec::Chain(_) => "chain",
            ModelSpec::Linear(_) => "linear",
            ModelSpec::Pendulum(_) => "pendulum",
            ModelSpec::SliderCrank(_) => "slider_crank",
            ModelSpec::JayNegrutTest(_) => "jay_negrut_test",
        }
    }
}

/// One harmonic term of the force of a `linear` model: `shape · sin(omega t + phase)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HarmonicForceSpec {
    /// Amplitude per dof.
    pub shape: Vec<f64>,
    /// Angular frequency.
    pub omega: f64,
    /// Phase (default 0).
    #[serde(default)]
    pub phase: f64,
}

/// `scene = "linear"`: `M q̈ + C q̇ + K q = F(t) + G λ`, `g = g_matrix · q + g_offset ≥ 0`.
/// Each matrix is given as dense rows (`mass`) or as triplets (`mass_triplets`), not both.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinearSpec {
    /// M as dense rows.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<Vec<Vec<f64>>>,
    /// M as `[row, col, value]` triplets (repeated entries add up).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass_triplets: Option<Vec<(usize, usize, f64)>>,
    /// K as dense rows (zero when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<Vec<Vec<f64>>>,
    /// K as triplets.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness_triplets: Option<Vec<(usize, usize, f64)>>,
    /// C as dense rows (zero when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping: Option<Vec<Vec<f64>>>,
    /// C as triplets.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping_triplets: Option<Vec<(usize, usize, f64)>>,
    /// Constant force (zero when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force: Option<Vec<f64>>,
    /// Harmonic force terms.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub harmonic_force: Vec<HarmonicForceSpec>,
    /// Gᵀ: one row per contact, n entries each.
    #[serde(default)]
    pub g_matrix: Vec<Vec<f64>>,
    /// w: one offset per contact (zero when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub g_offset: Option<Vec<f64>>,
    /// Restitution per contact.
    #[serde(default)]
    pub restitution: Vec<f64>,
    /// Initial positions (zero when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub q0: Option<Vec<f64>>,
    /// Initial velocities (zero when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub v0: Option<Vec<f64>>,
}

/// `[integrator]`: the scheme and its parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "scheme", rename_all = "snake_case")]
pub enum IntegratorSpec {
    /// Moreau–Jean θ-scheme, Acary 2016 (21)–(24).
    MoreauJean(MoreauJeanSpec),
    /// Its variant (29): `q_{k+1} = q_k + h v_{k+1/2}`.
    MoreauJeanVariant(MoreauJeanSpec),
    /// Nonsmooth Newmark, Acary 2016 (25) with α_m = α_f = 0.
    NsNewmark(NsNewmarkSpec),
    /// Nonsmooth HHT, Acary 2016 (25) with α_m = 0, α_f = α (78).
    NsHht(NsHhtSpec),
    /// Nonsmooth generalized-α, Acary 2016 (25)–(27).
    NsGeneralizedAlpha(NsAlphaSpec),
    /// Nonsmooth Krenk–Høgsberg generalized-α, Acary 2016 (30).
    NsKhAlpha(NsAlphaSpec),
    /// Standard Newmark with contact at position level (the baseline that blows up).
    NewmarkPositionContact(PositionContactSpec),
    /// Standard HHT with contact at position level (baseline).
    HhtPositionContact(PositionContactSpec),
    /// Generalized-α-SOI2, Jay & Negrut 2008 (13).
    Soi2GeneralizedAlpha(Soi2GeneralizedAlphaSpec),
    /// HHT-SOI2, Jay & Negrut 2008 (17).
    Soi2Hht(HhtSoi2Spec),
    /// HHT-I3 (index 3, position constraints only): the baseline of HHT-SOI2.
    HhtI3(HhtSoi2Spec),
    /// Wave finite elements, Yoong et al. 2018 Appendices A–B: scenes `bar`/`dep_bar`, cells = elements.
    Wfem(WfemSpec),
}

/// Parameters of `wfem` (none: Δt = Δx/c is fixed by the bar, and `time.h` must equal it).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WfemSpec {}

impl Default for IntegratorSpec {
    fn default() -> Self {
        IntegratorSpec::MoreauJean(MoreauJeanSpec::default())
    }
}

impl IntegratorSpec {
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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MoreauJeanSpec {
    /// θ ∈ [0, 1], default ½.
    #[serde(default = "half")]
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
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct IndexSetSpec {
    /// Index-set rule: `gap_and_velocity` ((24) of Acary 2016, default) or `predicted_gap`
    /// (Siconos' `g(q_k) + γ h U_k ≤ 0`, no sign test on U_k).
    #[serde(default)]
    pub activation: Activation,
    /// γ > 0 of the predicted-gap rule, default 1 (only with `activation = "predicted_gap"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub activation_gamma: Option<f64>,
}

impl IndexSetSpec {
    /// The validated rule; errors name `integrator.activation_gamma`.
    pub fn rule(&self) -> Result<IndexSetRule, SpecError> {
        let gamma = match (self.activation, self.activation_gamma) {
            (Activation::GapAndVelocity, Some(_)) => {
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
            activation: self.activation,
            gamma,
        })
    }
}

/// `[time]`: step size and duration (`t_end` or `steps`, not both).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeSpec {
    /// Step size h > 0.
    pub h: f64,
    /// Final time ≥ 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t_end: Option<f64>,
    /// Number of steps.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub steps: Option<u64>,
    /// Relative step sizes repeated over the run (variable-step schemes only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pattern: Option<Vec<f64>>,
    /// Use the step-size adjusting formulas (variable-step schemes only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub adjust: Option<bool>,
}

fn default_tolerance() -> f64 {
    1e-12
}

fn default_max_iterations() -> usize {
    100_000
}

/// `[contact_solver]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSolverSpec {
    /// `auto` (default), `lemke`, `pgs` or `enum`.
    #[serde(default)]
    pub kind: LcpSolverKind,
    /// Largest complementarity error accepted, default 1e-12.
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
    /// Pivot or sweep budget, default 100 000.
    #[serde(default = "default_max_iterations")]
    pub max_iterations: usize,
}

impl Default for ContactSolverSpec {
    fn default() -> Self {
        Self {
            kind: LcpSolverKind::Auto,
            tolerance: default_tolerance(),
            max_iterations: default_max_iterations(),
        }
    }
}

fn one() -> u64 {
    1
}

/// `[output]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Record every k-th step (≥ 1, default 1); the last step is always recorded.
    #[serde(default = "one")]
    pub every: u64,
    /// Dofs whose q_j, v_j are recorded (default none).
    #[serde(default)]
    pub probes: Vec<usize>,
}

impl Default for OutputSpec {
    fn default() -> Self {
        Self {
            every: 1,
            probes: Vec::new(),
        }
    }
}

/// An invalid spec: which field, and why.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("{field}: {reason}")]
pub struct SpecError {
    /// Dotted path of the field, e.g. `model.mass` or `time.h`.
    pub field: String,
    /// What is wrong with it.
    pub reason: String,
}

impl SpecError {
    /// An error on `field`.
    pub fn new(field: impl Into<String>, reason: impl Into<String>) -> Self {
        Self {
            field: field.into(),
            reason: reason.into(),
        }
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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
    pub allow_unstable: bool,
}

/// Parameters of `ns_hht` (Acary 2016 (78)): α, and β, γ defaulting to the second-order choice
/// γ = ½ + α, β = (1 + α)²/4. Dissipative for 2β ≥ γ ≥ ½, 0 ≤ α ≤ γ − ½ ≤ ½ (83).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
    pub allow_unstable: bool,
}

/// Parameters of `ns_generalized_alpha` and `ns_kh_alpha`: `rho_inf` ∈ [0, 1] (by (26)–(27);
/// default 0.8 when nothing is given), or `alpha_m`, `alpha_f` with optional `gamma` (default
/// (26)) and `beta` (default ¼(γ + ½)²), not both.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NsAlphaSpec {
    /// Spectral radius at infinity ρ∞ ∈ [0, 1].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rho_inf: Option<f64>,
    /// α_m < 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha_m: Option<f64>,
    /// α_f ≤ 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha_f: Option<f64>,
    /// β.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beta: Option<f64>,
    /// γ.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gamma: Option<f64>,
    /// Index-set rule (`activation`, `activation_gamma`), as for `moreau_jean`.
    #[serde(flatten)]
    pub index_set: IndexSetSpec,
    /// Run parameters outside the stability conditions anyway (default false).
    #[serde(default, skip_serializing_if = "is_false")]
    pub allow_unstable: bool,
}

/// Parameters of `newmark_position_contact` (β default ¼, γ default ½, no α) and
/// `hht_position_contact` (α required, β and γ defaulting as for `ns_hht`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
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
    pub allow_unstable: bool,
}
