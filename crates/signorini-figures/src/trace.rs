//! `energy.svg` (the energies and the cumulative works of a run against t) and `residuals.svg`
//! (log₁₀ of the balance residual, of the constraint residuals and of rigid bodies' penetration:
//! the checks that must sit at round-off or below a margin, and a nonlinear scheme's energy
//! error), drawn from the min/max envelopes the core keeps of its records.

use crate::Figure;
use crate::plot::{Curve, line_chart};
use signorini_core::outcome::{TraceChart, TraceKind, TracedSeries};

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
const STYLES: [Style; 15] = [
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
    style("work_friction_total", "Σ work_friction", "#8c564b", "4 2"),
    style("balance_residual", "balance_residual", "black", ""),
    style("energy_error", "energy_error (ΔE − works)", "#8c564b", ""),
    style("position_residual", "position constraint g", "#1f77b4", ""),
    style("velocity_residual", "velocity constraint", "#ff7f0e", ""),
    style(
        "nonholonomic_residual",
        "nonholonomic constraint",
        "#2ca02c",
        "",
    ),
    style("max_penetration", "max_penetration (m)", "#d62728", "2 2"),
];

/// Colours of the series of a motion chart (probes, gaps, impulses), in order.
const PALETTE: [&str; 8] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
];

/// The style of `column`, the `i`-th series of its chart: its row of [`STYLES`], or (a probe,
/// gap or impulse column) its name in the `i`-th colour of [`PALETTE`], tangential impulses
/// dashed.
fn style_of(column: &str, i: usize) -> (String, &'static str, &'static str) {
    STYLES.iter().find(|s| s.column == column).map_or_else(
        || {
            let dash = if column.starts_with("pt_") { "4 2" } else { "" };
            (column.to_string(), PALETTE[i % PALETTE.len()], dash)
        },
        |s| (s.label.to_string(), s.color, s.dash),
    )
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

/// `energy.svg`, `residuals.svg` (a log chart), or a user model's `coordinates.svg`,
/// `gaps.svg`, `impulses.svg`.
pub fn trace_figure(chart: &TraceChart) -> Figure {
    let log = chart.kind.is_log();
    let curves: Vec<Curve> = chart
        .series
        .iter()
        .enumerate()
        .map(|(i, series)| {
            let (label, color, dash) = style_of(&series.column, i);
            Curve {
                label: legend_label(label, series, log),
                color,
                dash,
                points: series.points.clone(),
            }
        })
        .collect();
    let (title, ylabel) = match chart.kind {
        TraceKind::Residuals => (
            "Checks: log₁₀ |residual| per recorded step (exact zeros not drawn)",
            "log₁₀ |residual|",
        ),
        TraceKind::Energy => (
            "Energies and cumulative works (min/max envelope of the records)",
            "energy, work",
        ),
        TraceKind::Coordinates => (
            "Probed coordinates q_j (min/max envelope of the records)",
            "q_j (the coordinate's unit)",
        ),
        TraceKind::Gaps => (
            "Contact gaps g_i(q, t) ≥ 0 (min/max envelope of the records)",
            "gap (length unit of the gap)",
        ),
        TraceKind::Impulses => (
            "Contact impulses per step: normal p_i, tangential pt_i dashed",
            "impulse (N·s)",
        ),
    };
    line_chart(chart.kind.name(), title, ylabel, log, &curves)
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
