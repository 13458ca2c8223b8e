//! A run's energy terms as data for its figures. [`EnergyTrace`] passes every record on to the
//! caller's observer and keeps a bounded [`Envelope`] of each column worth looking at: the
//! energies and the cumulative works ([`ENERGY_COLUMNS`], the `energy` chart) and the balance
//! and constraint residuals, as log₁₀ ([`RESIDUAL_COLUMNS`], the `residuals` chart: the checks
//! that must sit at round-off).
//!
//! An envelope keeps, for each bucket of consecutive values, the smallest and the largest with
//! their times. When [`MAX_BUCKETS`] are full, neighbours merge pairwise and the bucket width
//! doubles: memory and figure size stay bounded for any number of steps, and a one-step spike
//! (an impact, a residual jump) is never decimated away.

use crate::checkpoint::Checkpoint;
use crate::observer::{Columns, Observer, Progress, StepRecord};
use crate::outcome::{Chart, TraceChart, TraceKind, TracedSeries};
use serde::{Deserialize, Serialize};
use std::ops::ControlFlow;

/// Buckets kept per envelope before neighbours merge (so between half this and this many).
pub const MAX_BUCKETS: usize = 400;

/// The `energy` chart's columns: the energies of the run and the works done on it so far
/// (with friction's, which a rough contact takes out of the energy).
pub const ENERGY_COLUMNS: [&str; 9] = [
    "energy",
    "algorithmic_energy",
    "kinetic",
    "strain",
    "potential",
    "work_ext_total",
    "work_damping_total",
    "work_contact_total",
    "work_friction_total",
];

/// The `residuals` chart's columns: what must stay at round-off (or at the Newton tolerance),
/// the energy error ΔE − the works of a nonlinear scheme (its measure of accuracy where there
/// is no exact discrete balance), and the deepest penetration of rigid bodies at a step's start
/// (`max_penetration`, metres: zero, or below the contact margin, when the index set works).
pub const RESIDUAL_COLUMNS: [&str; 6] = [
    "balance_residual",
    "energy_error",
    "position_residual",
    "velocity_residual",
    "nonholonomic_residual",
    "max_penetration",
];

/// Most series of a `coordinates`, `gaps` or `impulses` chart (the first probes or contacts):
/// a chart stays readable and the trace's memory bounded for a model of many contacts.
pub const MAX_MOTION_SERIES: usize = 8;

/// The motion chart a column belongs to: a probed position (`q_j`, or `y_j` of the SOI2
/// schemes), a gap (`gap_i`), an impulse (`p_i`, `pt_i`).
fn motion_kind(column: &str) -> Option<TraceKind> {
    let (prefix, index) = column.rsplit_once('_')?;
    if index.is_empty() || !index.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    match prefix {
        "q" | "y" => Some(TraceKind::Coordinates),
        "gap" => Some(TraceKind::Gaps),
        "p" | "pt" => Some(TraceKind::Impulses),
        _ => None,
    }
}

/// Smallest and largest value of a bucket, each with its time (NaN until a finite value).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
struct Extremes {
    lo: (f64, f64),
    hi: (f64, f64),
}

impl Extremes {
    fn of(t: f64, v: f64) -> Self {
        let v = if v.is_finite() { v } else { f64::NAN };
        Self {
            lo: (t, v),
            hi: (t, v),
        }
    }

    /// Keeps the extremes of both (the earlier one on ties).
    fn merge(&mut self, o: &Self) {
        if o.lo.1 < self.lo.1 || self.lo.1.is_nan() {
            self.lo = o.lo;
        }
        if o.hi.1 > self.hi.1 || self.hi.1.is_nan() {
            self.hi = o.hi;
        }
    }

    /// The bucket's two points in time order (one when they coincide).
    fn points(&self) -> impl Iterator<Item = (f64, f64)> {
        let (a, b) = if self.lo.0 <= self.hi.0 {
            (self.lo, self.hi)
        } else {
            (self.hi, self.lo)
        };
        std::iter::once(a).chain((a != b).then_some(b))
    }
}

/// The min/max envelope of a series (t, v) in at most [`MAX_BUCKETS`] buckets; with `log`, of
/// log₁₀|v| (exact zeros, whose logarithm is not finite, are left out).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Envelope {
    log: bool,
    buckets: Vec<Extremes>,
    /// Values per bucket.
    width: u64,
    /// Values in the last bucket.
    filled: u64,
}

impl Envelope {
    /// An empty envelope, of v or (with `log`) of log₁₀|v|.
    pub fn new(log: bool) -> Self {
        Self {
            log,
            buckets: Vec::new(),
            width: 1,
            filled: 0,
        }
    }

    /// Adds the value `v` at time `t` (times in increasing order).
    pub fn push(&mut self, t: f64, v: f64) {
        let v = if self.log { v.abs().log10() } else { v };
        if self.filled > 0 && self.filled < self.width {
            if let Some(b) = self.buckets.last_mut() {
                b.merge(&Extremes::of(t, v));
            }
            self.filled += 1;
            return;
        }
        if self.buckets.len() == MAX_BUCKETS {
            self.buckets = self
                .buckets
                .chunks(2)
                .map(|pair| {
                    let mut m = pair[0];
                    if let Some(b) = pair.get(1) {
                        m.merge(b);
                    }
                    m
                })
                .collect();
            self.width *= 2;
        }
        self.buckets.push(Extremes::of(t, v));
        self.filled = 1;
    }

    /// The envelope as a curve: two points per bucket (its extremes, in time order), NaN where
    /// a bucket had no finite value.
    pub fn points(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.buckets.iter().flat_map(Extremes::points)
    }

    /// Number of buckets.
    pub fn buckets(&self) -> usize {
        self.buckets.len()
    }

    /// Whether values are kept as log₁₀|v|.
    pub fn is_log(&self) -> bool {
        self.log
    }
}

/// One traced column of a run: where it is in the records, its chart, its envelope.
struct Traced {
    index: usize,
    column: String,
    kind: TraceKind,
    envelope: Envelope,
}

/// An [`Observer`] that forwards everything to `inner` and keeps the envelope of the energy and
/// residual columns of the run (energies and cumulative works; balance and constraint residuals).
pub struct EnergyTrace<'a> {
    inner: &'a mut dyn Observer,
    traced: Vec<Traced>,
    records: u64,
    /// The envelopes of a checkpoint, restored at [`Observer::start`].
    resumed: Option<TraceState>,
    /// Whether the motion charts are kept too (`coordinates`, `gaps`, `impulses`).
    motion: bool,
}

/// What an [`EnergyTrace`] keeps across a checkpoint: its record count and its envelopes, in the
/// order of its traced columns.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct TraceState {
    records: u64,
    envelopes: Vec<Envelope>,
}

impl<'a> EnergyTrace<'a> {
    /// Wraps `inner`.
    pub fn new(inner: &'a mut dyn Observer) -> Self {
        Self {
            inner,
            traced: Vec::new(),
            records: 0,
            resumed: None,
            motion: false,
        }
    }

    /// Keeps the motion charts as well: the first [`MAX_MOTION_SERIES`] probed positions, gaps
    /// and impulses (a user model's default figures of what it does).
    pub fn with_motion(self) -> Self {
        Self {
            motion: true,
            ..self
        }
    }

    /// Wraps `inner` for a run resumed from a checkpoint whose trace state was `state`.
    pub(crate) fn resumed(inner: &'a mut dyn Observer, state: Option<TraceState>) -> Self {
        Self {
            resumed: state,
            ..Self::new(inner)
        }
    }

    /// The `energy` and `residuals` charts, for the columns the run had (none for a run that
    /// recorded no step, e.g. an analysis).
    pub fn charts(&self) -> Vec<Chart> {
        let mut out = Vec::new();
        if self.records == 0 {
            return out;
        }
        for kind in TraceKind::ALL {
            let series: Vec<TracedSeries> = self
                .traced
                .iter()
                .filter(|c| c.kind == kind)
                .map(|c| TracedSeries {
                    column: c.column.clone(),
                    points: c.envelope.points().collect(),
                })
                .collect();
            if !series.is_empty() {
                out.push(Chart::Trace(TraceChart { kind, series }));
            }
        }
        out
    }
}

impl Observer for EnergyTrace<'_> {
    fn start(&mut self, columns: &Columns) {
        let picks = ENERGY_COLUMNS
            .iter()
            .map(|c| (*c, TraceKind::Energy))
            .chain(RESIDUAL_COLUMNS.iter().map(|c| (*c, TraceKind::Residuals)));
        self.traced = picks
            .filter_map(|(column, kind)| {
                Some(Traced {
                    index: columns.index(column)?,
                    column: column.to_string(),
                    kind,
                    envelope: Envelope::new(kind.is_log()),
                })
            })
            .collect();
        if self.motion {
            for (index, column) in columns.names().iter().enumerate() {
                let Some(kind) = motion_kind(column) else {
                    continue;
                };
                if self.traced.iter().filter(|c| c.kind == kind).count() < MAX_MOTION_SERIES {
                    self.traced.push(Traced {
                        index,
                        column: column.clone(),
                        kind,
                        envelope: Envelope::new(false),
                    });
                }
            }
        }
        if let Some(state) = self.resumed.take()
            && state.envelopes.len() == self.traced.len()
        {
            self.records = state.records;
            for (c, e) in self.traced.iter_mut().zip(state.envelopes) {
                c.envelope = e;
            }
        }
        self.inner.start(columns);
    }

    fn observe(&mut self, record: &StepRecord<'_>) -> ControlFlow<()> {
        if !self.traced.is_empty() {
            self.records += 1;
            for c in &mut self.traced {
                let v = record.values.get(c.index).copied().unwrap_or(f64::NAN);
                c.envelope.push(record.t, v);
            }
        }
        self.inner.observe(record)
    }

    fn progress(&mut self, progress: Progress) -> ControlFlow<()> {
        self.inner.progress(progress)
    }

    fn checkpoint_due(&mut self, progress: Progress) -> bool {
        self.inner.checkpoint_due(progress)
    }

    fn checkpoint(&mut self, checkpoint: &mut Checkpoint) {
        let state = TraceState {
            records: self.records,
            envelopes: self.traced.iter().map(|c| c.envelope.clone()).collect(),
        };
        // Envelopes are plain numbers: they always encode. Should they not, the checkpoint
        // goes without them and a resumed run draws its charts from the resumed part only.
        let _ = checkpoint.set_trace(&state);
        self.inner.checkpoint(checkpoint);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::observer::Recorder;

    /// Feeds `rows` through a trace over `inner`: its charts and the buckets it kept.
    fn feed(
        inner: &mut Recorder,
        names: &[&str],
        rows: &[(f64, Vec<f64>)],
    ) -> (Vec<Chart>, Vec<Vec<Extremes>>) {
        let mut trace = EnergyTrace::new(inner);
        trace.start(&Columns::new(names.iter().map(|s| s.to_string()).collect()));
        let mut buckets = Vec::new();
        for (k, (t, values)) in rows.iter().enumerate() {
            let r = StepRecord {
                step: k as u64,
                t: *t,
                values,
            };
            assert!(trace.observe(&r).is_continue());
            buckets.push(trace.traced.iter().map(|c| c.envelope.buckets()).max());
        }
        let bound = buckets.iter().flatten().max().copied().unwrap_or(0);
        assert!(bound <= MAX_BUCKETS, "{bound} buckets");
        let kept = trace
            .traced
            .iter()
            .map(|c| c.envelope.buckets.clone())
            .collect();
        (trace.charts(), kept)
    }

    /// A long run: the buckets stay bounded, a one-record spike and the global extremes survive
    /// with their times, and the inner observer sees every record unchanged.
    #[test]
    fn envelope_is_bounded_and_keeps_every_extreme_with_its_time() {
        let n = 100_003;
        let rows: Vec<(f64, Vec<f64>)> = (0..n)
            .map(|k| {
                let t = k as f64 * 1e-3;
                let spike = if k == 77_777 { 5.0 } else { 0.0 };
                let residual = if k % 1000 == 0 { 0.0 } else { 1e-16 * k as f64 };
                (t, vec![t.sin() + spike, residual, 42.0])
            })
            .collect();
        let mut inner = Recorder::default();
        let (figures, kept) = feed(&mut inner, &["energy", "balance_residual", "other"], &rows);
        assert_eq!(inner.rows.len(), n, "every record forwarded");
        assert!(inner.rows.iter().zip(&rows).all(|(a, b)| a == &b.1));
        assert_eq!(inner.columns.names()[2], "other");

        assert_eq!(kept.len(), 2, "only the plotted columns");
        assert!(kept[0].len() >= MAX_BUCKETS / 2);
        let energy_max = kept[0]
            .iter()
            .map(|b| b.hi)
            .fold((f64::NAN, f64::MIN), |a, b| if b.1 > a.1 { b } else { a });
        assert_eq!(energy_max, (rows[77_777].0, rows[77_777].1[0]), "the spike");
        let energy_min = kept[0]
            .iter()
            .map(|b| b.lo)
            .fold((f64::NAN, f64::MAX), |a, b| if b.1 < a.1 { b } else { a });
        let true_min = rows
            .iter()
            .map(|(t, v)| (*t, v[0]))
            .fold((f64::NAN, f64::MAX), |a, b| if b.1 < a.1 { b } else { a });
        assert_eq!(energy_min, true_min);
        // Residuals are kept as log₁₀|r|; exact zeros (−∞) are not finite and never kept.
        let residual_max = kept[1].iter().map(|b| b.hi.1).fold(f64::MIN, f64::max);
        assert_eq!(residual_max, (1e-16 * (n - 1) as f64).log10());
        assert!(kept[1].iter().all(|b| b.lo.1.is_finite()));
        // Time order inside and across buckets: the curve never goes back in t.
        let ts: Vec<f64> = kept[0]
            .iter()
            .flat_map(Extremes::points)
            .map(|p| p.0)
            .collect();
        assert!(ts.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(
            figures.iter().map(Chart::name).collect::<Vec<_>>(),
            ["energy", "residuals"]
        );
    }

    /// Fewer records than buckets: each record is its own bucket, drawn exactly.
    #[test]
    fn short_runs_keep_every_record() {
        let rows: Vec<(f64, Vec<f64>)> = (0..50)
            .map(|k| (k as f64, vec![(k * k) as f64, k as f64]))
            .collect();
        let mut inner = Recorder::default();
        let (_, kept) = feed(&mut inner, &["kinetic", "work_ext_total"], &rows);
        for (c, buckets) in kept.iter().enumerate() {
            let pts: Vec<(f64, f64)> = buckets.iter().flat_map(Extremes::points).collect();
            let exact: Vec<(f64, f64)> = rows.iter().map(|(t, v)| (*t, v[c])).collect();
            assert_eq!(pts, exact);
        }
    }

    /// A run without plotted columns, or without records, draws nothing; a Break from the
    /// inner observer reaches the integrator.
    #[test]
    fn nothing_to_draw_and_break_passes_through() {
        let mut inner = Recorder::default();
        assert!(feed(&mut inner, &["q_0"], &[(0.0, vec![1.0])]).0.is_empty());
        let mut inner = Recorder::default();
        assert!(feed(&mut inner, &["energy"], &[]).0.is_empty());

        struct Stop;
        impl Observer for Stop {
            fn observe(&mut self, _: &StepRecord<'_>) -> ControlFlow<()> {
                ControlFlow::Break(())
            }
        }
        let mut stop = Stop;
        let mut trace = EnergyTrace::new(&mut stop);
        trace.start(&Columns::new(vec!["energy".into()]));
        let r = StepRecord {
            step: 0,
            t: 0.0,
            values: &[1.0],
        };
        assert!(trace.observe(&r).is_break());
    }
}
