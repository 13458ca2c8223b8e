//! `work_precision.svg`: a study's error against CPU time, log–log, a curve with markers per
//! scheme.

use crate::Figure;
use crate::plot::{
    Axes, escape, frame_log_log, header, legend, polyline, with_legend_room, y_range,
};
use signorini_core::outcome::WorkPrecisionChart;
use std::fmt::Write as _;

/// Curve colours, in order.
const COLORS: [&str; 8] = [
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf",
];

/// The diagram; runs with a zero, negative or non-finite error or CPU time are left out (and
/// counted in the legend).
pub fn work_precision_figure(chart: &WorkPrecisionChart) -> Figure {
    // Each drawable point with its h (NaN when the chart has none for it).
    let logs: Vec<Vec<(f64, f64, f64)>> = chart
        .curves
        .iter()
        .map(|c| {
            c.points
                .iter()
                .enumerate()
                .filter(|(_, (x, y))| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite())
                .map(|(i, (x, y))| {
                    (
                        x.log10(),
                        y.log10(),
                        c.h.get(i).copied().unwrap_or(f64::NAN),
                    )
                })
                .collect()
        })
        .collect();
    let x = y_range(logs.iter().flatten().map(|p| p.0));
    let y = with_legend_room(
        y_range(logs.iter().flatten().map(|p| p.1)),
        chart.curves.len(),
    );
    let ax = Axes { x, y };
    let mut s = String::new();
    header(&mut s, &escape(&chart.title));
    frame_log_log(
        &mut s,
        &ax,
        "CPU time (s)",
        "error (each compared quantity in its own unit)",
    );
    let mut items = Vec::new();
    for (i, (curve, points)) in chart.curves.iter().zip(&logs).enumerate() {
        let color = COLORS[i % COLORS.len()];
        polyline(&mut s, &ax, points.iter().map(|p| (p.0, p.1)), color, "");
        for &(px, py, h) in points {
            let _ = write!(
                s,
                r#"<circle cx="{:.1}" cy="{:.1}" r="3" fill="{color}"/>"#,
                ax.px(px),
                ax.py(py)
            );
            if h.is_finite() {
                // Each point says which run it is: its step size.
                let _ = write!(
                    s,
                    r#"<text x="{:.1}" y="{:.1}" font-size="10" fill="{color}">h={h:e}</text>"#,
                    ax.px(px) + 5.0,
                    ax.py(py) - 5.0
                );
            }
        }
        let dropped = curve.points.len() - points.len();
        let label = if dropped > 0 {
            format!(
                "{} ({dropped} runs with no finite positive error)",
                curve.label
            )
        } else {
            curve.label.clone()
        };
        items.push((color, "", escape(&label)));
    }
    let width = 40.0
        + 7.0
            * items
                .iter()
                .map(|i| i.2.chars().count())
                .max()
                .unwrap_or(10) as f64;
    legend(&mut s, &items, width.clamp(120.0, 620.0));
    s.push_str("</svg>");
    Figure {
        name: "work_precision".into(),
        svg: s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use signorini_core::outcome::WorkPrecisionCurve;

    /// Issue 30: every point says its h, and a title longer than the canvas is fitted into it
    /// (it was clipped at both ends).
    #[test]
    fn points_are_labelled_with_h_and_a_long_title_fits() {
        let chart = WorkPrecisionChart {
            title: "a rather long study name of a user's own model: max_abs error against a fine run of moreau_jean at h = 1e-6".into(),
            curves: vec![WorkPrecisionCurve {
                label: "moreau_jean, observed order 1.00".into(),
                points: vec![(0.1, 1e-2), (0.2, 5e-3), (0.4, 0.0)],
                h: vec![1e-3, 5e-4, 2.5e-4],
            }],
        };
        let svg = work_precision_figure(&chart).svg;
        assert!(svg.contains(">h=1e-3</text>"), "{svg}");
        assert!(svg.contains(">h=5e-4</text>"), "{svg}");
        // The run with a zero error is not drawn, nor labelled.
        assert!(!svg.contains(">h=2.5e-4</text>"), "{svg}");
        assert!(svg.contains(r#"textLength="700" lengthAdjust="spacingAndGlyphs">a rather long"#));
        assert!(svg.contains(
            ">moreau_jean, observed order 1.00 (1 runs with no finite positive error)</text>"
        ));
    }
}
