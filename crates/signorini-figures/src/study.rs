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
    let logs: Vec<Vec<(f64, f64)>> = chart
        .curves
        .iter()
        .map(|c| {
            c.points
                .iter()
                .filter(|(x, y)| *x > 0.0 && *y > 0.0 && x.is_finite() && y.is_finite())
                .map(|(x, y)| (x.log10(), y.log10()))
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
    frame_log_log(&mut s, &ax, "CPU time (s)", "error");
    let mut items = Vec::new();
    for (i, (curve, points)) in chart.curves.iter().zip(&logs).enumerate() {
        let color = COLORS[i % COLORS.len()];
        polyline(&mut s, &ax, points.iter().copied(), color, "");
        for &(px, py) in points {
            let _ = write!(
                s,
                r#"<circle cx="{:.1}" cy="{:.1}" r="3" fill="{color}"/>"#,
                ax.px(px),
                ax.py(py)
            );
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
