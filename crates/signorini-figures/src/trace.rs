//! `energy.svg` (the energies and the cumulative works of a run against t) and `residuals.svg`
//! (log₁₀ of the balance residual and of the constraint residuals: the checks that must sit at
//! round-off), drawn from the min/max envelopes the core keeps of its records.

use crate::Figure;
use crate::plot::{Curve, line_chart};
use signorini_core::outcome::{TraceChart, TracedSeries};

/// How a traced column is drawn: column, legend label, colour, dash pattern.
struct Style {
    column: &'static str,
    label: &'static str,
    color: &'static str,
    dash: &'static str,
}

const fn style(
    column: &'static str,
    label: &'static str,
    color: &'static str,
    dash: &'static str,
) -> Style {
    Style {
        column,
        label,
        color,
        dash,
    }
}

/// Every column the core traces ([`signorini_core::trace::ENERGY_COLUMNS`] and
/// [`signorini_core::trace::RESIDUAL_COLUMNS`]).
const STYLES: [Style; 12] = [
    style("energy", "energy", "black", ""),
    style(
        "algorithmic_energy",
        "algorithmic energy H",
        "#7f7f7f",
        "6 3",
    ),
    style("kinetic", "kinetic", "#1f77b4", ""),
    style("strain", "strain", "#ff7f0e", ""),
    style("potential", "potential", "#ff7f0e", ""),
    style("work_ext_total", "Σ work_ext", "#2ca02c", "4 2"),
    style("work_damping_total", "Σ work_damping", "#d62728", "4 2"),
    style("work_contact_total", "Σ work_contact", "#9467bd", "4 2"),
    style("balance_residual", "balance_residual", "black", ""),
    style("position_residual", "position constraint g", "#1f77b4", ""),
    style("velocity_residual", "velocity constraint", "#ff7f0e", ""),
    style(
        "nonholonomic_residual",
        "nonholonomic constraint",
        "#2ca02c",
        "",
    ),
];

/// The style of `column`: its row of [`STYLES`], or the column name in black.
fn style_of(column: &str) -> (String, &'static str, &'static str) {
    STYLES
        .iter()
        .find(|s| s.column == column)
        .map_or((column.to_string(), "black", ""), |s| {
            (s.label.to_string(), s.color, s.dash)
        })
}

/// The legend label of a series, saying so when nothing could be drawn.
fn legend_label(label: String, series: &TracedSeries, log: bool) -> String {
    if series.points.iter().any(|p| p.1.is_finite()) {
        label
    } else if log {
        format!("{label}: exactly 0 at every step")
    } else {
        format!("{label}: not finite")
    }
}

/// `energy.svg` or (for a log chart) `residuals.svg`.
pub fn trace_figure(chart: &TraceChart) -> Figure {
    let log = chart.log;
    let curves: Vec<Curve> = chart
        .series
        .iter()
        .map(|series| {
            let (label, color, dash) = style_of(&series.column);
            Curve {
                label: legend_label(label, series, log),
                color,
                dash,
                points: series.points.clone(),
            }
        })
        .collect();
    if log {
        line_chart(
            "residuals",
            "Checks: log₁₀ |residual| per recorded step (exact zeros not drawn)",
            "log₁₀ |residual|",
            true,
            &curves,
        )
    } else {
        line_chart(
            "energy",
            "Energies and cumulative works (min/max envelope of the records)",
            "energy, work",
            false,
            &curves,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use signorini_core::trace::{ENERGY_COLUMNS, RESIDUAL_COLUMNS};

    /// Every column the core traces has its own label and colour.
    #[test]
    fn every_traced_column_has_a_style() {
        for c in ENERGY_COLUMNS.iter().chain(&RESIDUAL_COLUMNS) {
            assert!(STYLES.iter().any(|s| s.column == *c), "{c}");
        }
        assert_eq!(STYLES.len(), ENERGY_COLUMNS.len() + RESIDUAL_COLUMNS.len());
    }
}
