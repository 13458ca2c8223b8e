//! Hand-written SVG figures (no fonts or files needed): frequency–energy backbones with the
//! linear frequencies and the main-branch asymptotes, space–time displacement of an orbit, and
//! forced-response curves over the backbones.

use crate::Figure;
use crate::plot::{
    Axes, H, MB, ML, MR, MT, W, frame, header, legend, polyline, vline, with_legend_room, y_range,
};
use signorini_core::modal::main_asymptote;
use signorini_core::outcome::{BackbonePanel, EndHistory, ForcedChart, ModePoint, SpaceTime};
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

/// Admissible points off the main branches, faint (Fig. 17's "clouds").
fn draw_backbone_points(s: &mut String, ax: &Axes, points: &[ModePoint]) {
    for pt in points.iter().filter(|p| p.branch.is_none()) {
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
            r#"<circle cx="{:.1}" cy="{:.1}" r="1.3" fill="{}" fill-opacity="0.22"/>"#,
            ax.px(x),
            ax.py(y),
            gap_color(pt.gap)
        );
    }
}

/// Each main branch k of each gap as a line through its points in increasing ω (a single
/// point, as at g0 = 0, as a dot), labelled `k = K` at its highest-energy end.
fn draw_main_branches(s: &mut String, ax: &Axes, points: &[ModePoint]) {
    let mut keys: Vec<(u64, usize)> = points
        .iter()
        .filter_map(|p| p.branch.map(|k| (p.gap.to_bits(), k)))
        .collect();
    keys.sort_unstable();
    keys.dedup();
    for (gap_bits, k) in keys {
        let gap = f64::from_bits(gap_bits);
        let mut branch: Vec<(f64, f64)> = points
            .iter()
            .filter(|p| p.gap.to_bits() == gap_bits && p.branch == Some(k))
            .filter(|p| p.energy_normalized > 0.0)
            .map(|p| (p.omega_over_omega1, p.energy_normalized.log10()))
            .filter(|&(x, y)| x >= ax.x.0 && x <= ax.x.1 && y >= ax.y.0 && y <= ax.y.1)
            .collect();
        branch.sort_by(|a, b| a.0.total_cmp(&b.0));
        let color = gap_color(gap);
        if branch.len() == 1 {
            let (x, y) = branch[0];
            let _ = write!(
                s,
                r#"<circle cx="{:.1}" cy="{:.1}" r="3" fill="{color}"/>"#,
                ax.px(x),
                ax.py(y)
            );
        } else {
            polyline_width(s, ax, branch.iter().copied(), color, 2.2);
        }
        if let Some(&(x, y)) = branch.iter().max_by(|a, b| a.1.total_cmp(&b.1)) {
            let anchor = if gap < 0.0 { "start" } else { "end" };
            let dx = if gap < 0.0 { 5.0 } else { -5.0 };
            let _ = write!(
                s,
                r#"<text x="{:.1}" y="{:.1}" text-anchor="{anchor}" font-size="11" fill="{color}">k = {k}</text>"#,
                ax.px(x) + dx,
                ax.py(y) + 4.0
            );
        }
    }
}

/// A solid curve of the given width (the main branches stand out of [`polyline`]'s 1.4 px).
fn polyline_width(
    s: &mut String,
    ax: &Axes,
    points: impl Iterator<Item = (f64, f64)>,
    color: &str,
    width: f64,
) {
    let pts: Vec<String> = points
        .map(|(x, y)| format!("{:.1},{:.1}", ax.px(x), ax.py(y)))
        .collect();
    let _ = write!(
        s,
        r#"<polyline points="{}" fill="none" stroke="{color}" stroke-width="{width}"/>"#,
        pts.join(" ")
    );
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
        ("#1f77b4", "g₀ &gt; 0 (hardening); line: main branch k"),
        ("#2ca02c", "g₀ = 0"),
        ("#d62728", "g₀ &lt; 0 (softening); faint: other orbits"),
        ("#888", "ωₖ = (2k−1)ω₁ (fixed–free)"),
        ("#bbb", "Ωₖ = 2kω₁ (fixed–fixed)"),
        ("#8c564b", "g₀ = 0 asymptotes ω₁(ωₖ/ω₁+1)²/(ωₖ/ω₁+2)"),
    ];
    let _ = write!(
        s,
        r#"<rect x="{}" y="{}" width="300" height="{}" fill="white" fill-opacity="0.85" stroke="silver"/>"#,
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

/// Frequency–energy plot (Figs. 5–6, 17): the main branches of every gap as labelled lines, the
/// other admissible points faint, log₁₀ of the normalised energy against ω/ω₁, with ω_k, Ω_k
/// and the main-branch asymptotes.
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
    draw_main_branches(&mut s, &ax, pts);
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
    draw_main_branches(&mut s, &ax, bb);
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

/// Subharmonic frequency (15) of §6.2, `(2k(n + 1) − 1)/(n + 1)` ω₁, and its asymptote (16),
/// `(n + 1)(ω_k/ω₁ + 1)²/((ω_k/ω₁)(n + 1) + n + 2)` ω₁, as multiples of ω₁.
pub fn subharmonic(k: usize, n: usize) -> (f64, f64) {
    let (k, n) = (k as f64, n as f64);
    let r = 2.0 * k - 1.0;
    (
        (2.0 * k * (n + 1.0) - 1.0) / (n + 1.0),
        (n + 1.0) * (r + 1.0) * (r + 1.0) / (r * (n + 1.0) + n + 2.0),
    )
}

/// The frequency–energy plot of one nonsmooth mode K over [ω_K, Ω_K] (Fig. 5 for K = 1, Fig. 6
/// for K = 2): the main branch K of each gap as a labelled line, the other admissible orbits
/// faint, ω_K, Ω_K and the asymptote of §6.1, the subharmonics (15) and their asymptotes (16) of
/// §6.2 that fall in the range (n ≤ 6, as the paper's six), and the marked points (the shown
/// orbits, with the stability run's result).
pub fn backbone_panel_figure(panel: &BackbonePanel) -> Figure {
    let k = panel.mode;
    let x = ((2 * k) as f64 - 1.1, (2 * k) as f64 + 0.1);
    let pts = &panel.points;
    let y = y_range(
        pts.iter()
            .filter(|p| p.energy_normalized > 0.0)
            .map(|p| p.energy_normalized.log10()),
    );
    let ax = Axes {
        x,
        y: with_legend_room(y, 7),
    };
    let mut s = String::new();
    header(
        &mut s,
        &format!(
            "Nonsmooth mode {k}: frequency–energy over [ω{0}, Ω{0}]",
            sub(k)
        ),
    );
    frame(&mut s, &ax, "ω / ω₁", "energy / E_lin (log₁₀)", true);
    let top = |s: &mut String, xv: f64, row: f64, color: &str, text: &str| {
        if xv > ax.x.0 && xv < ax.x.1 {
            let _ = write!(
                s,
                r#"<text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="10" fill="{color}">{text}</text>"#,
                ax.px(xv),
                MT - 3.0 - 11.0 * row
            );
        }
    };
    for j in 1..=8 {
        for n in 1..=6 {
            let (w, a) = subharmonic(j, n);
            if w > x.0 && w < x.1 {
                vline(&mut s, &ax, w, "#c7c7c7", "3 3");
            }
            if a > x.0 && a < x.1 {
                vline(&mut s, &ax, a, "#d2b48c", "2 4");
            }
        }
    }
    let (wk, big_wk, asym) = ((2 * k - 1) as f64, (2 * k) as f64, main_asymptote(k));
    vline(&mut s, &ax, wk, "#555", "6 3");
    vline(&mut s, &ax, big_wk, "#555", "2 2");
    vline(&mut s, &ax, asym, "#8c564b", "6 2 1 2");
    top(&mut s, wk, 0.0, "#333", &format!("ω{}", sub(k)));
    top(&mut s, big_wk, 0.0, "#333", &format!("Ω{}", sub(k)));
    top(
        &mut s,
        asym,
        0.0,
        "#8c564b",
        &format!("{}/{}", 4 * k * k, 2 * k + 1),
    );
    draw_backbone_points(&mut s, &ax, pts);
    draw_main_branches(&mut s, &ax, pts);
    // Marked points: a ring and the label's letter (the text before its colon) at the point,
    // the whole labels listed at the right, under the legend's seven lines.
    let marked: Vec<_> = panel
        .marked
        .iter()
        .filter(|m| m.point.energy_normalized > 0.0)
        .collect();
    if let Some(chars) = marked.iter().map(|m| m.label.chars().count()).max() {
        let (w, h) = (6.2 * chars as f64 + 10.0, 14.0 * marked.len() as f64 + 6.0);
        let _ = write!(
            s,
            r#"<rect x="{:.1}" y="{:.1}" width="{w:.1}" height="{h:.1}" fill="white" fill-opacity="0.85" stroke="silver"/>"#,
            W - MR - 4.0 - w,
            MT + 118.0
        );
    }
    for (i, m) in marked.iter().enumerate() {
        let p = m.point;
        let (px, py) = (
            ax.px(p.omega_over_omega1),
            ax.py(p.energy_normalized.log10()),
        );
        let letter = m.label.split(':').next().unwrap_or("");
        let _ = write!(
            s,
            r#"<circle cx="{px:.1}" cy="{py:.1}" r="5" fill="none" stroke="black" stroke-width="1.5"/><text x="{:.1}" y="{:.1}" font-size="12" font-weight="bold">{letter}</text>"#,
            px - 3.0,
            py + 18.0
        );
        let _ = write!(
            s,
            r#"<text x="{:.1}" y="{:.1}" text-anchor="end" font-size="11">{}</text>"#,
            W - MR - 8.0,
            MT + 132.0 + 14.0 * i as f64,
            m.label
        );
    }
    let items: Vec<(&str, &str, String)> = vec![
        ("#1f77b4", "", "g₀ &gt; 0, main branch (hardening)".into()),
        ("#2ca02c", "", "g₀ = 0 (on the asymptote)".into()),
        ("#d62728", "", "g₀ &lt; 0, main branch (softening)".into()),
        (
            "#555",
            "6 3",
            format!("ω{0} (fixed–free), Ω{0} (fixed–fixed) (10)", sub(k)),
        ),
        (
            "#8c564b",
            "6 2 1 2",
            "asymptote ω₁(ωₖ/ω₁+1)²/(ωₖ/ω₁+2) (§6.1)".into(),
        ),
        ("#c7c7c7", "3 3", "subharmonics (15), n ≤ 6".into()),
        (
            "#d2b48c",
            "2 4",
            "their asymptotes (16); dots: other orbits".into(),
        ),
    ];
    legend(&mut s, &items, 330.0);
    s.push_str("</svg>");
    Figure {
        name: panel.name.clone(),
        svg: s,
    }
}

/// A small plot area inside the canvas, for the stacked panels of [`contact_end_figure`].
struct Panel {
    x0: f64,
    y0: f64,
    w: f64,
    h: f64,
    y: (f64, f64),
}

impl Panel {
    fn px(&self, t: f64) -> f64 {
        self.x0 + t * self.w
    }
    fn py(&self, v: f64) -> f64 {
        self.y0 + self.h - (v - self.y.0) / (self.y.1 - self.y.0) * self.h
    }
    /// Box, zero line, y extremes as labels, a title above.
    fn frame(&self, s: &mut String, title: &str) {
        let _ = write!(
            s,
            r#"<rect x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="none" stroke="black"/>"#,
            self.x0, self.y0, self.w, self.h
        );
        if self.y.0 < 0.0 && self.y.1 > 0.0 {
            let _ = write!(
                s,
                r##"<line x1="{:.1}" x2="{:.1}" y1="{2:.1}" y2="{2:.1}" stroke="#bbb"/>"##,
                self.x0,
                self.x0 + self.w,
                self.py(0.0)
            );
        }
        for v in [self.y.0, self.y.1] {
            let _ = write!(
                s,
                r#"<text x="{:.1}" y="{:.1}" text-anchor="end" font-size="10">{v:.2e}</text>"#,
                self.x0 - 3.0,
                self.py(v) + 4.0
            );
        }
        let _ = write!(
            s,
            r#"<text x="{:.1}" y="{:.1}" font-size="11">{title}</text>"#,
            self.x0 + 4.0,
            self.y0 - 4.0
        );
    }
    fn curve(&self, s: &mut String, values: &[f64], steps: usize, color: &str) {
        let pts: Vec<String> = values
            .iter()
            .enumerate()
            .map(|(n, &v)| format!("{:.1},{:.1}", self.px(n as f64 / steps as f64), self.py(v)))
            .collect();
        let _ = write!(
            s,
            r#"<polyline points="{}" fill="none" stroke="{color}" stroke-width="1.6"/>"#,
            pts.join(" ")
        );
    }
}

/// u(L, t) and the contact force r(t) over one period of the shown orbit of each gap (Fig. 8:
/// unstressed "a", grazing "b", prestressed "c"), t/T on the abscissa; the dashed line is u = g0.
pub fn contact_end_figure(ends: &[EndHistory]) -> Figure {
    let rows = ends.len().max(1) as f64;
    let (top, bottom, gapx) = (MT + 8.0, 12.0, 80.0);
    let row_h = (H - top - bottom) / rows;
    let col_w = (W - ML - MR - gapx) / 2.0;
    let mut s = String::new();
    header(
        &mut s,
        "Shown orbits over one period: u(L, t) (left), contact force r(t) = S a_N (right)",
    );
    for (i, e) in ends.iter().enumerate() {
        let steps = e.u.len().saturating_sub(1).max(1);
        let color = gap_color(e.gap);
        let bounds = |v: &[f64], extra: f64| {
            let (lo, hi) = v
                .iter()
                .fold((extra, extra), |(a, b), &x| (a.min(x), b.max(x)));
            let pad = 0.08 * (hi - lo).max(1e-300);
            (lo - pad, hi + pad)
        };
        let y0 = top + i as f64 * row_h + 8.0;
        let h = row_h - 36.0;
        let left = Panel {
            x0: ML,
            y0,
            w: col_w,
            h,
            y: bounds(&e.u, e.gap),
        };
        let letter = if e.gap > 0.0 {
            "a"
        } else if e.gap < 0.0 {
            "c"
        } else {
            "b"
        };
        left.frame(
            &mut s,
            &format!(
                "{letter}: g₀ = {:e}, (m, p) = ({}, {}); u(L, t)",
                e.gap, e.m, e.p
            ),
        );
        let _ = write!(
            s,
            r##"<line x1="{:.1}" x2="{:.1}" y1="{2:.1}" y2="{2:.1}" stroke="#444" stroke-dasharray="5 3"/>"##,
            left.x0,
            left.x0 + left.w,
            left.py(e.gap)
        );
        left.curve(&mut s, &e.u, steps, color);
        let right = Panel {
            x0: ML + col_w + gapx,
            y0,
            w: col_w,
            h,
            y: bounds(&e.force, 0.0),
        };
        right.frame(
            &mut s,
            &format!(
                "ω/ω₁ = {:.4}, E/E_lin = {:.4}; r(t) ≤ 0",
                e.omega_over_omega1, e.energy_normalized
            ),
        );
        right.curve(&mut s, &e.force, steps, color);
        for p in [&left, &right] {
            for (f, text) in [(0.0, "0"), (0.5, "t/T = 0.5"), (1.0, "1")] {
                let _ = write!(
                    s,
                    r#"<text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="10">{text}</text>"#,
                    p.px(f),
                    p.y0 + p.h + 12.0
                );
            }
        }
    }
    s.push_str("</svg>");
    Figure {
        name: "contact_end".into(),
        svg: s,
    }
}
