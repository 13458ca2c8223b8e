//! Figures of Signorini runs. The numerical core returns the data of its figures
//! ([`Chart`]: envelopes of the energy and residual columns, backbone points, orbit fields,
//! forced-response curves); [`render`] draws each as an SVG document (a [`Figure`]).
//!
//! The SVG is written by hand ([`plot`]: a 720 × 480 canvas, round ticks, curves, legend; no
//! fonts, no files). A plotting crate was measured against it: `plotters` 0.3.7 with
//! `default-features = false, features = ["svg_backend", "line_series", "point_series"]` builds
//! cold in 2.6 s (3.2 s CPU), draws text without a font feature (as SVG `<text>` with estimated
//! widths, font sizes scaled by 0.81), and an energy figure of 7 curves × 800 envelope points is
//! 67.7 kB against 70.1 kB here. None of the three is a reason to keep our own. We keep it because
//! the figures must stay as they are: the tests and the service compare figure text (a legend
//! entry is `>label</text>`, where plotters writes `>\nlabel\n</text>`), and the modal figures
//! (reference lines labelled above the plot area, a space–time colour map, swatch legends) are
//! custom drawing either way; moving 600 tested lines beat rewriting them.

#![warn(missing_docs)]

pub mod modal;
pub mod plot;
pub mod region;
pub mod study;
pub mod trace;

pub use plot::{Curve, line_chart};
use signorini_core::outcome::Chart;

/// A picture of a run (SVG text).
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    /// File stem, e.g. `backbone` for `backbone.svg`.
    pub name: String,
    /// SVG document.
    pub svg: String,
}

/// The figure of each chart, in order; a figure's name is its chart's [`Chart::name`].
pub fn render(charts: &[Chart]) -> Vec<Figure> {
    charts
        .iter()
        .map(|chart| match chart {
            Chart::Trace(t) => trace::trace_figure(t),
            Chart::Backbone(points) => modal::backbone_figure(points),
            Chart::SpaceTime(st) => modal::space_time_figure(st),
            Chart::ForcedResponse(f) => modal::forced_figure(f),
            Chart::BackbonePanel(b) => modal::backbone_panel_figure(b),
            Chart::ContactEnd(ends) => modal::contact_end_figure(ends),
            Chart::WorkPrecision(w) => study::work_precision_figure(w),
            Chart::ContactRegion(c) => region::contact_region_figure(c),
        })
        .collect()
}
