//! The contact region of a distributed obstacle over time (the `contact_region` chart): an
//! observer in front of the run's observer reads the `gap_α` and `p_α` columns of each record
//! and keeps, on a grid of at most [`MAX_CELLS`] × [`MAX_CELLS`] cells (time buckets × groups of
//! neighbouring contacts), the strongest state seen in each cell: free, touching
//! (`gap ≤ δ`) or pushed (`P > 0`). Memory is bounded by the grid, whatever the run's length
//! and the number of contacts.

use crate::observer::{Columns, Observer, Progress, StepRecord};
use crate::outcome::{Chart, ContactRegionChart};
use std::ops::ControlFlow;

/// Most time buckets and most contact groups of the grid.
pub const MAX_CELLS: usize = 400;

/// The contact-region observer: passes every call on to `inner`.
pub struct ContactRegion<'a> {
    inner: &'a mut dyn Observer,
    x: Vec<f64>,
    delta: f64,
    /// Records per time bucket and contacts per group.
    per_bucket: usize,
    per_group: usize,
    /// The first contact shown (contacts before it, e.g. a bar's end contact, are left out).
    first: usize,
    /// Column of gap_first (gap_α at that + 3(α − first), p_α two columns after gap_α).
    gap0: Option<usize>,
    records: usize,
    t: Vec<f64>,
    states: Vec<Vec<u8>>,
}

impl<'a> ContactRegion<'a> {
    /// An observer over `inner` for the contacts `first, first + 1, …` at increasing abscissae
    /// `x`, marking a contact as touching when its gap is ≤ `delta`; `records` is how many
    /// records the run will make (it sizes the time buckets).
    pub fn new(
        inner: &'a mut dyn Observer,
        first: usize,
        x: Vec<f64>,
        delta: f64,
        records: u64,
    ) -> Self {
        let records = usize::try_from(records).unwrap_or(usize::MAX).max(1);
        let per_bucket = records.div_ceil(MAX_CELLS).max(1);
        let per_group = x.len().div_ceil(MAX_CELLS).max(1);
        Self {
            inner,
            x,
            delta,
            per_bucket,
            per_group,
            first,
            gap0: None,
            records: 0,
            t: Vec::new(),
            states: Vec::new(),
        }
    }

    /// The chart of what was observed.
    pub fn chart(self) -> Chart {
        let x = self
            .x
            .chunks(self.per_group)
            .map(|c| 0.5 * (c[0] + c[c.len() - 1]))
            .collect();
        Chart::ContactRegion(ContactRegionChart {
            x,
            t: self.t,
            states: self.states,
            delta: self.delta,
        })
    }
}

impl Observer for ContactRegion<'_> {
    fn start(&mut self, columns: &Columns) {
        self.gap0 = columns.index(&format!("gap_{}", self.first));
        self.inner.start(columns);
    }

    fn observe(&mut self, record: &StepRecord<'_>) -> ControlFlow<()> {
        if let Some(g0) = self.gap0 {
            if self.records.is_multiple_of(self.per_bucket) {
                self.t.push(record.t);
                self.states
                    .push(vec![0; self.x.len().div_ceil(self.per_group)]);
            }
            self.records += 1;
            if let Some(row) = self.states.last_mut() {
                for (a, cell) in (0..self.x.len()).map(|a| (a, a / self.per_group)) {
                    let (gap, p) = (record.values[g0 + 3 * a], record.values[g0 + 3 * a + 2]);
                    let state = if p > 0.0 {
                        2
                    } else {
                        u8::from(gap <= self.delta)
                    };
                    row[cell] = row[cell].max(state);
                }
            }
        }
        self.inner.observe(record)
    }

    fn progress(&mut self, progress: Progress) -> ControlFlow<()> {
        self.inner.progress(progress)
    }
}
