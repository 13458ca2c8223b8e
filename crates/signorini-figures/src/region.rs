//! The contact region of a distributed obstacle (a string on a bridge): x to the right, t
//! upward, each cell of the chart's grid marked by the strongest state seen in it.

use crate::Figure;
use crate::plot::{Axes, H, MB, ML, MR, MT, W, frame, header};
use signorini_core::outcome::ContactRegionChart;
use std::fmt::Write;

/// Fill of a touching cell (gap ≤ δ) and of a pushed one (P > 0).
const TOUCHING: &str = "#9ecae1";
const PUSHED: &str = "#b2182b";

/// `contact_region.svg`: free cells white, touching light blue, pushed dark red.
pub fn contact_region_figure(chart: &ContactRegionChart) -> Figure {
    let nx = chart.x.len().max(1);
    let nt = chart.t.len().max(1);
    let dx = if chart.x.len() > 1 {
        (chart.x[nx - 1] - chart.x[0]) / (nx - 1) as f64
    } else {
        1.0
    };
    let dt = if chart.t.len() > 1 {
        (chart.t[nt - 1] - chart.t[0]) / (nt - 1) as f64
    } else {
        1.0
    };
    let x0 = chart.x.first().copied().unwrap_or(0.0) - 0.5 * dx;
    let t0 = chart.t.first().copied().unwrap_or(0.0);
    let ax = Axes {
        x: (x0, x0 + nx as f64 * dx),
        y: (t0, t0 + nt as f64 * dt),
    };
    let mut s = String::new();
    header(&mut s, "Contact region of the obstacle");
    let cw = (W - ML - MR) / nx as f64;
    let ch = (H - MT - MB) / nt as f64;
    for (i, row) in chart.states.iter().enumerate() {
        for (j, &state) in row.iter().enumerate() {
            let fill = match state {
                0 => continue,
                1 => TOUCHING,
                _ => PUSHED,
            };
            let _ = write!(
                s,
                r#"<rect x="{:.2}" y="{:.2}" width="{:.2}" height="{:.2}" fill="{fill}"/>"#,
                ML + j as f64 * cw,
                H - MB - (i + 1) as f64 * ch,
                cw + 0.3,
                ch + 0.3,
            );
        }
    }
    frame(&mut s, &ax, "x", "t", false);
    let _ = write!(
        s,
        r#"<text x="{}" y="{}" text-anchor="end"><tspan fill="{PUSHED}">■ impulse P &gt; 0</tspan>  <tspan fill="{TOUCHING}">■ touching, gap ≤ {:.1e}</tspan></text>"#,
        W - MR,
        MT - 6.0,
        chart.delta
    );
    s.push_str("</svg>");
    Figure {
        name: "contact_region".into(),
        svg: s,
    }
}
