//! Hand-written SVG figures (no fonts, no files): a 720 × 480 canvas, one plot area with round
//! ticks and labels, curves, reference lines and a legend. [`line_chart`] draws curves against
//! t; the primitives serve the modal-analysis figures too.

use crate::Figure;
use std::fmt::Write;

/// Canvas width (px).
pub(crate) const W: f64 = 720.0;
/// Canvas height (px).
pub(crate) const H: f64 = 480.0;
/// Left margin (px).
pub(crate) const ML: f64 = 70.0;
/// Right margin (px).
pub(crate) const MR: f64 = 20.0;
/// Top margin (px).
pub(crate) const MT: f64 = 40.0;
/// Bottom margin (px).
pub(crate) const MB: f64 = 50.0;

/// Data ranges of the plot area.
pub(crate) struct Axes {
    /// x range (data units).
    pub(crate) x: (f64, f64),
    /// y range (data units).
    pub(crate) y: (f64, f64),
}

impl Axes {
    /// Pixel abscissa of `x`.
    pub(crate) fn px(&self, x: f64) -> f64 {
        ML + (x - self.x.0) / (self.x.1 - self.x.0) * (W - ML - MR)
    }
    /// Pixel ordinate of `y`.
    pub(crate) fn py(&self, y: f64) -> f64 {
        H - MB - (y - self.y.0) / (self.y.1 - self.y.0) * (H - MT - MB)
    }
}

/// Opens the document: white background and a centred title.
pub(crate) fn header(s: &mut String, title: &str) {
    // A title wider than the canvas (about 8 px a character at 15 px) is fitted into it rather
    // than clipped at both ends.
    let fit = if 8.0 * title.chars().count() as f64 > W - 20.0 {
        format!(
            r#" textLength="{}" lengthAdjust="spacingAndGlyphs""#,
            W - 20.0
        )
    } else {
        String::new()
    };
    let _ = write!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" font-family="sans-serif" font-size="12"><rect width="100%" height="100%" fill="white"/><text x="{}" y="22" text-anchor="middle" font-size="15"{fit}>{title}</text>"#,
        W / 2.0
    );
}

/// Round tick values covering `range`: about five, spaced 1, 2 or 5 × 10ᵏ.
fn ticks(range: (f64, f64)) -> (Vec<f64>, f64) {
    let span = range.1 - range.0;
    if !(span.is_finite() && span > 0.0) {
        return (vec![range.0], 1.0);
    }
    let raw = span / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let first = (range.0 / step).ceil() as i64;
    let last = (range.1 / step).floor() as i64;
    ((first..=last).map(|i| i as f64 * step).collect(), step)
}

/// A tick label with as many decimals as the spacing needs (scientific for large or tiny).
fn tick_label(v: f64, step: f64) -> String {
    let a = v.abs().max(step);
    if !(1e-3..1e5).contains(&a) {
        return format!("{v:.1e}");
    }
    let decimals = (-step.log10().floor()).max(0.0) as usize;
    let v = if v.abs() < 0.5 * step { 0.0 } else { v };
    format!("{v:.decimals$}")
}

/// The label of a tick at log₁₀ value `v`: `1e-3` at a whole decade, the value itself
/// (`4.0e-4`) between decades.
fn log_tick_label(v: f64, step: f64) -> String {
    if (v - v.round()).abs() < 1e-9 {
        format!("1e{}", tick_label(v.round(), step.max(1.0)))
    } else {
        format!("{:.1e}", 10f64.powf(v))
    }
}

/// The plot area's box, light grid lines at round ticks on both axes, the tick labels and the
/// axis labels; `log_y` labels y as 1eN.
pub(crate) fn frame(s: &mut String, ax: &Axes, xlabel: &str, ylabel: &str, log_y: bool) {
    frame_with(s, ax, xlabel, ylabel, false, log_y);
}

/// [`frame`] for log₁₀ data on both axes (ticks labelled 1eN).
pub(crate) fn frame_log_log(s: &mut String, ax: &Axes, xlabel: &str, ylabel: &str) {
    frame_with(s, ax, xlabel, ylabel, true, true);
}

fn frame_with(s: &mut String, ax: &Axes, xlabel: &str, ylabel: &str, log_x: bool, log_y: bool) {
    let _ = write!(
        s,
        r#"<rect x="{ML}" y="{MT}" width="{}" height="{}" fill="none" stroke="black"/>"#,
        W - ML - MR,
        H - MT - MB
    );
    let (xs, xstep) = ticks(ax.x);
    for x in xs {
        let label = if log_x {
            log_tick_label(x, xstep)
        } else {
            tick_label(x, xstep)
        };
        let _ = write!(
            s,
            r##"<line x1="{0:.1}" x2="{0:.1}" y1="{MT}" y2="{1}" stroke="#e4e4e4"/><text x="{0:.1}" y="{2}" text-anchor="middle">{label}</text>"##,
            ax.px(x),
            H - MB,
            H - MB + 16.0,
        );
    }
    let (ys, ystep) = ticks(ax.y);
    for y in ys {
        let label = if log_y {
            log_tick_label(y, ystep)
        } else {
            tick_label(y, ystep)
        };
        let _ = write!(
            s,
            r##"<line x1="{ML}" x2="{0}" y1="{1:.1}" y2="{1:.1}" stroke="#e4e4e4"/><text x="{2}" y="{3:.1}" text-anchor="end">{label}</text>"##,
            W - MR,
            ax.py(y),
            ML - 4.0,
            ax.py(y) + 4.0
        );
    }
    let _ = write!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle">{xlabel}</text>"#,
        (ML + W - MR) / 2.0,
        H - 12.0
    );
    let _ = write!(
        s,
        r#"<text x="16" y="{}" text-anchor="middle" transform="rotate(-90 16 {})">{ylabel}</text>"#,
        (MT + H - MB) / 2.0,
        (MT + H - MB) / 2.0
    );
}

/// A vertical reference line at `x` (nothing when `x` is outside the plot area).
pub(crate) fn vline(s: &mut String, ax: &Axes, x: f64, color: &str, dash: &str) {
    if x > ax.x.0 && x < ax.x.1 {
        let _ = write!(
            s,
            r#"<line x1="{0:.1}" x2="{0:.1}" y1="{MT}" y2="{1}" stroke="{color}" stroke-dasharray="{dash}"/>"#,
            ax.px(x),
            H - MB
        );
    }
}

/// A curve through `points` (data units). Points that are not finite break the curve; a point
/// on the same tenth of a pixel as the previous one is left out.
pub(crate) fn polyline(
    s: &mut String,
    ax: &Axes,
    points: impl IntoIterator<Item = (f64, f64)>,
    color: &str,
    dash: &str,
) {
    let mut pieces: Vec<String> = vec![String::new()];
    let mut last = String::new();
    for (x, y) in points {
        if !(x.is_finite() && y.is_finite()) {
            if pieces.last().is_some_and(|p| !p.is_empty()) {
                pieces.push(String::new());
            }
            last.clear();
            continue;
        }
        let xy = format!("{:.1},{:.1}", ax.px(x), ax.py(y));
        if xy != last
            && let Some(p) = pieces.last_mut()
        {
            if !p.is_empty() {
                p.push(' ');
            }
            p.push_str(&xy);
            last = xy;
        }
    }
    for p in pieces.iter().filter(|p| !p.is_empty()) {
        let _ = write!(
            s,
            r#"<polyline points="{p}" fill="none" stroke="{color}" stroke-width="1.4" stroke-dasharray="{dash}"/>"#
        );
    }
}

/// A legend box in the plot area's top left corner: one line sample and label per item
/// (colour, dash pattern, label).
pub(crate) fn legend(s: &mut String, items: &[(&str, &str, String)], width: f64) {
    let _ = write!(
        s,
        r#"<rect x="{}" y="{}" width="{width}" height="{}" fill="white" fill-opacity="0.85" stroke="silver"/>"#,
        ML + 4.0,
        MT + 2.0,
        15.0 * items.len() as f64 + 4.0
    );
    for (i, (color, dash, label)) in items.iter().enumerate() {
        let y = MT + 14.0 + 15.0 * i as f64;
        let _ = write!(
            s,
            r#"<line x1="{}" x2="{}" y1="{}" y2="{}" stroke="{color}" stroke-width="2" stroke-dasharray="{dash}"/><text x="{}" y="{}">{label}</text>"#,
            ML + 8.0,
            ML + 26.0,
            y - 4.0,
            y - 4.0,
            ML + 30.0,
            y
        );
    }
}

/// `y` extended upward so that a [`legend`] of `items` lines sits above the data.
pub(crate) fn with_legend_room(y: (f64, f64), items: usize) -> (f64, f64) {
    let f = ((15.0 * items as f64 + 10.0) / (H - MT - MB)).min(0.6);
    (y.0, y.1 + (y.1 - y.0) * f / (1.0 - f))
}

/// The smallest and largest finite values, if any.
fn finite_bounds(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values.filter(|v| v.is_finite()).fold(None, |b, v| match b {
        None => Some((v, v)),
        Some((lo, hi)) => Some((f64::min(lo, v), f64::max(hi, v))),
    })
}

/// A y range for log₁₀ data: every finite value with a 5 % margin, or half a decade either side
/// when they span less than a thousandth of one.
pub(crate) fn y_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    match finite_bounds(values) {
        None => (-1.0, 1.0),
        Some((lo, hi)) if hi - lo < 1e-3 => (lo - 0.5, hi + 0.5),
        Some((lo, hi)) => (lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo)),
    }
}

/// A y range for linear data: every finite value with a 5 % margin, or half their magnitude
/// either side when they are equal to nine digits (a unit range around zero).
pub(crate) fn linear_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let Some((lo, hi)) = finite_bounds(values) else {
        return (-1.0, 1.0);
    };
    let scale = lo.abs().max(hi.abs());
    if hi - lo > 1e-9 * scale {
        (lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo))
    } else if scale > 0.0 {
        (lo - 0.5 * scale, hi + 0.5 * scale)
    } else {
        (-1.0, 1.0)
    }
}

/// A curve of a [`line_chart`].
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    /// Legend label (plain text; `<`, `>`, `&` are escaped).
    pub label: String,
    /// SVG colour.
    pub color: &'static str,
    /// SVG dash pattern (empty: solid).
    pub dash: &'static str,
    /// Points (t, y) in order; a point that is not finite breaks the curve.
    pub points: Vec<(f64, f64)>,
}

/// Escapes text for SVG.
pub(crate) fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Curves against t in one plot, with a legend; `log_y` when the values are log₁₀ of something.
pub fn line_chart(name: &str, title: &str, ylabel: &str, log_y: bool, curves: &[Curve]) -> Figure {
    let ys = || curves.iter().flat_map(|c| c.points.iter().map(|p| p.1));
    let y = if log_y {
        y_range(ys())
    } else {
        linear_range(ys())
    };
    let x = match finite_bounds(curves.iter().flat_map(|c| c.points.iter().map(|p| p.0))) {
        Some((lo, hi)) if hi > lo => (lo, hi),
        Some((lo, _)) => (lo - 0.5, lo + 0.5),
        None => (0.0, 1.0),
    };
    let ax = Axes {
        x,
        y: with_legend_room(y, curves.len()),
    };
    let mut s = String::new();
    header(&mut s, &escape(title));
    frame(&mut s, &ax, "t", &escape(ylabel), log_y);
    for c in curves {
        polyline(&mut s, &ax, c.points.iter().copied(), c.color, c.dash);
    }
    let items: Vec<(&str, &str, String)> = curves
        .iter()
        .map(|c| (c.color, c.dash, escape(&c.label)))
        .collect();
    let width = 40.0
        + 7.0
            * curves
                .iter()
                .map(|c| c.label.chars().count())
                .max()
                .unwrap_or(10) as f64;
    legend(&mut s, &items, width.clamp(120.0, W - ML - MR - 8.0));
    s.push_str("</svg>");
    Figure {
        name: name.into(),
        svg: s,
    }
}
