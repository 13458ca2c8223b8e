//! `[check]`: bounds a run must meet, read by `signorini check` (the CI gate); `run` and the
//! service ignore the section.

use super::error::SpecError;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// `[check]`: each bound given is checked against the run's measured value; absent bounds are
/// not checked. A spec whose run cannot measure a bound it gives (e.g. `max_balance_residual`
/// for a scheme that reports `energy_error`) is refused by `signorini check` as a bad spec.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CheckSpec {
    /// Largest |balance_residual| over the recorded steps (the energy identity of the linear
    /// schemes, at round-off for Moreau–Jean).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0))]
    pub max_balance_residual: Option<f64>,
    /// Largest |energy_error| over the recorded steps (the nonlinear and SOI2 schemes' energy
    /// error E − E₀ − works).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0))]
    pub max_energy_error: Option<f64>,
    /// Largest energy growth E − E₀ − works over the recorded steps, relative to
    /// max(|E₀|, max |E|): positive means the scheme created energy.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_energy_growth: Option<f64>,
    /// Largest global error against the scene's exact solution (scenes that have one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0))]
    pub max_error: Option<f64>,
    /// Smallest observed order of convergence (studies only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_order: Option<f64>,
    /// Largest `position_residual` (‖g‖∞ of the joints) over the recorded steps (SOI2 schemes):
    /// the positions stay on the constraint manifold.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0))]
    pub max_position_residual: Option<f64>,
    /// Recorded values against a reference (an exact solution, or a published reference
    /// solution), each `{ column, t, value, tolerance }`: |column(t) − value| ≤ tolerance, at
    /// the recorded step nearest to t.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub reference: Vec<ReferenceValue>,
}

/// One reference value a run must reproduce.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ReferenceValue {
    /// A recorded column (`q_0`, `energy`, …).
    pub column: String,
    /// The instant; the recorded step nearest to it is compared.
    pub t: f64,
    /// The reference value there.
    pub value: f64,
    /// Largest |recorded − value| accepted.
    #[schemars(range(min = 0.0))]
    pub tolerance: f64,
}

impl CheckSpec {
    /// The bounds given, by name, in a fixed order.
    pub fn bounds(&self) -> Vec<(&'static str, f64)> {
        [
            ("max_balance_residual", self.max_balance_residual),
            ("max_energy_error", self.max_energy_error),
            ("max_energy_growth", self.max_energy_growth),
            ("max_error", self.max_error),
            ("min_order", self.min_order),
            ("max_position_residual", self.max_position_residual),
        ]
        .into_iter()
        .filter_map(|(name, b)| b.map(|b| (name, b)))
        .collect()
    }

    /// Every bound finite; the magnitudes ≥ 0.
    pub fn validate(&self) -> Result<(), SpecError> {
        for (name, bound) in self.bounds() {
            let signed = matches!(name, "max_energy_growth" | "min_order");
            if !bound.is_finite() || (!signed && bound < 0.0) {
                return Err(SpecError::new(
                    format!("check.{name}"),
                    format!(
                        "must be a finite number{}, got {bound}",
                        if signed { "" } else { " ≥ 0" }
                    ),
                ));
            }
        }
        for (i, r) in self.reference.iter().enumerate() {
            let field = |f: &str| format!("check.reference[{i}].{f}");
            if r.column.is_empty() {
                return Err(SpecError::new(
                    field("column"),
                    "must name a recorded column",
                ));
            }
            if !(r.t.is_finite() && r.value.is_finite()) {
                return Err(SpecError::new(
                    field("t"),
                    "t and value must be finite numbers",
                ));
            }
            if !(r.tolerance.is_finite() && r.tolerance >= 0.0) {
                return Err(SpecError::new(
                    field("tolerance"),
                    format!("must be a finite number ≥ 0, got {}", r.tolerance),
                ));
            }
        }
        Ok(())
    }
}
