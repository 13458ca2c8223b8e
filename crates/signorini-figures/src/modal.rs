//! Hand-written SVG figures (no fonts or files needed): frequency–energy backbones with the
//! linear frequencies and the main-branch asymptotes, space–time displacement of an orbit, and
//! forced-response curves over the backbones.

use crate::Figure;
use crate::plot::{
    Axes, H, MB, ML, MR, MT, W, frame, header, polyline, vline, with_legend_room, y_range,
};
use signorini_core::modal::main_asymptote;
use signorini_core::outcome::{ForcedChart, ModePoint, SpaceTime};
use std::fmt::Write;

fn gap_color(g: f64) -> &'static str {
    if g > 0.0 {
        "#1f77b4"
    } else if g < 0.0 {
        "#d62728"
    } else {
        "#2ca02c"
    }
}

fn draw_backbone_points(s: &mut String, ax: &Axes, points: &[ModePoint]) {
    for pt in points {
        let e = pt.energy_normalized;
        if e.is_nan() || e <= 0.0 {
            continue;
        }
        let (x, y) = (pt.omega_over_omega1, e.log10());
        if x < ax.x.0 || x > ax.x.1 || y < ax.y.0 || y > ax.y.1 {
            continue;
        }
        let _ = write!(
            s,
            r#"<circle cx="{:.1}" cy="{:.1}" r="1.8" fill="{}"/>"#,
            ax.px(x),
            ax.py(y),
            gap_color(pt.gap)
        );
    }
}

/// Unicode subscript digits of `k`.
fn sub(k: usize) -> String {
    k.to_string()
        .chars()
        .map(|c| char::from_u32(0x2080 + c.to_digit(10).unwrap_or(0)).unwrap_or(c))
        .collect()
}

fn legend_and_lines(s: &mut String, ax: &Axes) {
    // Linear frequencies: ω_k = (2k−1)ω₁ (fixed–free), Ω_k = 2k ω₁ (fixed–fixed), (10).
    // Each line is labelled just above the plot area: ω_k, Ω_k and the asymptote's value as a
    // fraction (2k)²/(2k + 1) of ω₁.
    let label = |s: &mut String, x: f64, dy: f64, color: &str, text: &str| {
        if x > ax.x.0 && x < ax.x.1 {
            let _ = write!(
                s,
                r#"<text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="10" fill="{color}">{text}</text>"#,
                ax.px(x),
                MT - 3.0 - dy
            );
        }
    };
    for k in 1..=8 {
        vline(s, ax, (2 * k - 1) as f64, "#888", "4 3");
        vline(s, ax, (2 * k) as f64, "#bbb", "2 2");
        vline(s, ax, main_asymptote(k), "#8c564b", "6 2 1 2");
        label(s, (2 * k - 1) as f64, 0.0, "#555", &format!("ω{}", sub(k)));
        label(s, (2 * k) as f64, 0.0, "#777", &format!("Ω{}", sub(k)));
        label(
            s,
            main_asymptote(k),
            MT + 6.0 - (H - MB),
            "#8c564b",
            &format!("{}/{}", 4 * k * k, 2 * k + 1),
        );
    }
    let items = [
        ("#1f77b4", "g₀ &gt; 0 (hardening)"),
        ("#2ca02c", "g₀ = 0"),
        ("#d62728", "g₀ &lt; 0 (softening)"),
        ("#888", "ωₖ = (2k−1)ω₁ (fixed–free)"),
        ("#bbb", "Ωₖ = 2kω₁ (fixed–fixed)"),
        ("#8c564b", "g₀ = 0 asymptotes ω₁(ωₖ/ω₁+1)²/(ωₖ/ω₁+2)"),
    ];
    let _ = write!(
        s,
        r#"<rect x="{}" y="{}" width="290" height="{}" fill="white" fill-opacity="0.85" stroke="silver"/>"#,
        ML + 4.0,
        MT + 2.0,
        15.0 * items.len() as f64 + 4.0
    );
    for (i, (c, label)) in items.iter().enumerate() {
        let y = MT + 14.0 + 15.0 * i as f64;
        let _ = write!(
            s,
            r#"<rect x="{}" y="{}" width="10" height="10" fill="{c}"/><text x="{}" y="{}">{label}</text>"#,
            ML + 8.0,
            y - 9.0,
            ML + 22.0,
            y
        );
    }
}

/// Frequency–energy plot (Figs. 5–6): admissible points of every gap, log₁₀ of the normalised
/// energy against ω/ω₁, with ω_k, Ω_k and the main-branch asymptotes.
pub fn backbone_figure(pts: &[ModePoint]) -> Figure {
    let hi = pts
        .iter()
        .map(|p| p.omega_over_omega1)
        .fold(2.2f64, f64::max)
        .min(8.5);
    let x = (0.5, hi + 0.1);
    let y = y_range(
        pts.iter()
            .filter(|p| p.energy_normalized > 0.0)
            .map(|p| p.energy_normalized.log10()),
    );
    // Room above the points for the six-line legend.
    let ax = Axes {
        x,
        y: with_legend_room(y, 6),
    };
    let mut s = String::new();
    header(&mut s, "Nonsmooth modes: frequency–energy backbones");
    frame(&mut s, &ax, "ω / ω₁", "energy / E_lin (log₁₀)", true);
    legend_and_lines(&mut s, &ax);
    draw_backbone_points(&mut s, &ax, pts);
    s.push_str("</svg>");
    Figure {
        name: "backbone".into(),
        svg: s,
    }
}

/// Space–time displacement u(x, t) of an orbit over one period (Figs. 9, 13): a colour map
/// (blue negative, red positive), x to the right, t upward.
pub fn space_time_figure(st: &SpaceTime) -> Figure {
    let (name, field) = (&st.name, &st.field);
    let nx = field.first().map_or(1, Vec::len).max(1);
    let umax = field
        .iter()
        .flatten()
        .fold(0.0f64, |m, x| m.max(x.abs()))
        .max(1e-300);
    let ax = Axes {
        x: (0.0, st.length),
        y: (0.0, st.period),
    };
    let mut s = String::new();
    header(
        &mut s,
        &format!(
            "Space–time displacement, {} ({} + {} steps)",
            name, st.free_steps, st.contact_steps
        ),
    );
    let cw = (W - ML - MR) / nx as f64;
    let ch = (H - MT - MB) / field.len().max(1) as f64;
    for (i, row) in field.iter().enumerate() {
        for (j, &u) in row.iter().enumerate() {
            let r = u / umax;
            let (cr, cg, cb) = if r >= 0.0 {
                (255.0, 255.0 * (1.0 - r), 255.0 * (1.0 - r))
            } else {
                (255.0 * (1.0 + r), 255.0 * (1.0 + r), 255.0)
            };
            let _ = write!(
                s,
                r#"<rect x="{:.2}" y="{:.2}" width="{:.2}" height="{:.2}" fill="rgb({},{},{})"/>"#,
                ML + j as f64 * cw,
                H - MB - (i + 1) as f64 * ch,
                cw + 0.3,
                ch + 0.3,
                cr as u8,
                cg as u8,
                cb as u8
            );
        }
    }
    frame(&mut s, &ax, "x", "t", false);
    let _ = write!(
        s,
        r#"<text x="{}" y="{}" text-anchor="end">blue: u &lt; 0, red: u &gt; 0, full colour at |u| = {umax:.3e}</text>"#,
        W - MR,
        MT - 6.0
    );
    s.push_str("</svg>");
    Figure {
        name: name.clone(),
        svg: s,
    }
}

/// Forced-response curves (Figs. 23–25): mean energy per damping value against ω/ω₁, over the
/// backbone points of the same bar.
pub fn forced_figure(chart: &ForcedChart) -> Figure {
    let (results, e_lin) = (&chart.responses, chart.energy_linear_grazing);
    let palette = [
        "#9467bd", "#ff7f0e", "#17becf", "#e377c2", "#7f7f7f", "#bcbd22",
    ];
    let xs = results.iter().map(|r| r.omega_over_omega1);
    let (xlo, xhi) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    });
    let ax_x = if xlo.is_finite() {
        (xlo - 0.05, xhi + 0.05)
    } else {
        (0.5, 2.5)
    };
    let bb = &chart.backbone;
    let ys = results
        .iter()
        .map(|r| (r.mean_energy / e_lin).log10())
        .chain(
            bb.iter()
                .filter(|p| p.omega_over_omega1 >= ax_x.0 && p.omega_over_omega1 <= ax_x.1)
                .map(|p| p.energy_normalized.log10()),
        );
    let mut dampings: Vec<f64> = results.iter().map(|r| r.damping).collect();
    dampings.dedup();
    // Room above the curves for the legend: six lines and one per damping value.
    let ax = Axes {
        x: ax_x,
        y: with_legend_room(y_range(ys), 6 + dampings.len()),
    };
    let mut s = String::new();
    let what = if chart.moving_wall {
        "moving wall"
    } else {
        "distributed force"
    };
    header(
        &mut s,
        &format!("Forced response ({what}) over the backbone"),
    );
    frame(&mut s, &ax, "ω / ω₁", "mean energy / E_lin (log₁₀)", true);
    legend_and_lines(&mut s, &ax);
    draw_backbone_points(&mut s, &ax, bb);
    for (i, g) in dampings.iter().enumerate() {
        let color = palette[i % palette.len()];
        polyline(
            &mut s,
            &ax,
            results
                .iter()
                .filter(|r| r.damping == *g && r.mean_energy > 0.0)
                .map(|r| (r.omega_over_omega1, (r.mean_energy / e_lin).log10())),
            color,
            "",
        );
        let y = MT + 14.0 + 15.0 * (6 + i) as f64;
        let _ = write!(
            s,
            r#"<rect x="{}" y="{}" width="10" height="10" fill="{color}"/><text x="{}" y="{}">γ = {g}</text>"#,
            ML + 8.0,
            y - 9.0,
            ML + 22.0,
            y
        );
    }
    s.push_str("</svg>");
    Figure {
        name: "forced_response".into(),
        svg: s,
    }
}
