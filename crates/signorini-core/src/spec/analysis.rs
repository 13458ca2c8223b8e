//! `[analysis]`: the jobs that are not a time integration (nonsmooth modal analysis and
//! forced-response sweeps of the bar on wave finite elements, Yoong et al. 2018 §§4–7).

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// `[analysis]`: a job kind that is not a time integration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum AnalysisSpec {
    /// Backbone curves of the nonsmooth modes.
    NonsmoothModes(ModalSpec),
    /// Forced-response sweep over forcing frequency.
    ForcedResponse(ForcedResponseSpec),
}

impl AnalysisSpec {
    /// The analysis' `kind`, as spelled in the spec (`nonsmooth_modes`, `forced_response`).
    pub fn kind(&self) -> &'static str {
        match self {
            AnalysisSpec::NonsmoothModes(_) => "nonsmooth_modes",
            AnalysisSpec::ForcedResponse(_) => "forced_response",
        }
    }
}

fn default_cells() -> usize {
    100
}
fn one_f() -> f64 {
    1.0
}
fn one_u() -> usize {
    1
}

/// `kind = "nonsmooth_modes"`: the unit-free bar of §6 (fixed left end) and the scan ranges.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ModalSpec {
    /// Cells N ≥ 2 (default 100).
    #[serde(default = "default_cells")]
    #[schemars(range(min = 2, max = 1_000_000))]
    pub cells: usize,
    /// Gap g0 (any sign). Give `gap` or `gaps`; default `gaps = [1e-3, 0, −1e-3]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gap: Option<f64>,
    /// Several gaps, one backbone each.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gaps: Option<Vec<f64>>,
    /// Longest period scanned, in steps (default 4N: down to ω₁).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_period_steps: Option<usize>,
    /// Shortest period scanned, in steps (default 2: every period).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_period_steps: Option<usize>,
    /// Contact phases per period: 1 ((9), default) or 2 ((18), equal contact durations).
    #[serde(default = "one_u")]
    #[schemars(range(min = 1, max = 2))]
    pub phases: usize,
    /// Length L (default 1).
    #[serde(default = "one_f")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub length: f64,
    /// Young's modulus E (default 1).
    #[serde(default = "one_f")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub young: f64,
    /// Density ρ (default 1).
    #[serde(default = "one_f")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub density: f64,
    /// Section S (default 1).
    #[serde(default = "one_f")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub area: f64,
    /// Periods of the stability run of the first-mode orbit (0 = none, default 0; §6.5 uses 1000).
    #[serde(default)]
    pub stability_periods: usize,
    /// Also list the potential (non-admissible) points with a kernel in `backbone.csv`.
    #[serde(default)]
    pub all_candidates: bool,
}

/// How the bar is driven.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Excitation {
    /// Harmonically moving wall (f0 = 0, w0 ≠ 0).
    #[default]
    Wall,
    /// Harmonic distributed force (f0 ≠ 0, w0 = 0).
    Force,
}

fn d_cells() -> usize {
    100
}
fn d_one() -> f64 {
    1.0
}
fn d_gap() -> f64 {
    1e-3
}
fn d_amp() -> f64 {
    2e-3
}
fn d_damping() -> Vec<f64> {
    vec![0.02, 0.05, 0.1]
}
fn d_transient() -> usize {
    150
}
fn d_average() -> usize {
    20
}

/// `kind = "forced_response"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ForcedResponseSpec {
    /// Cells N ≥ 2 (default 100).
    #[serde(default = "d_cells")]
    #[schemars(range(min = 2, max = 100_000))]
    pub cells: usize,
    /// Length (default 1).
    #[serde(default = "d_one")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub length: f64,
    /// Young's modulus (default 1).
    #[serde(default = "d_one")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub young: f64,
    /// Density (default 1).
    #[serde(default = "d_one")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub density: f64,
    /// Section (default 1).
    #[serde(default = "d_one")]
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub area: f64,
    /// Gap g0 (default 10⁻³).
    #[serde(default = "d_gap")]
    pub gap: f64,
    /// `wall` (default) or `force`.
    #[serde(default)]
    pub excitation: Excitation,
    /// w0 (wall) or f0 per unit length (force); default 2·10⁻³.
    #[serde(default = "d_amp")]
    pub amplitude: f64,
    /// Forcing frequencies as multiples of ω₁ (default 29 values from 0.8 to 2.2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub omegas: Option<Vec<f64>>,
    /// Viscous damping values γ (1/s), default [0.02, 0.05, 0.1].
    #[serde(default = "d_damping")]
    pub damping: Vec<f64>,
    /// Forcing periods skipped before averaging (default 150).
    #[serde(default = "d_transient")]
    pub transient_periods: usize,
    /// Forcing periods averaged (default 20).
    #[serde(default = "d_average")]
    pub average_periods: usize,
    /// Overlay the backbone of the same bar on the figure (default true).
    #[serde(default = "d_true")]
    pub backbone: bool,
}

fn d_true() -> bool {
    true
}
