//! The contact region of a distributed obstacle over time (the `contact_region` chart): an
//! observer in front of the run's observer reads the `gap_α` and `p_α` columns of each record
//! and keeps, on a grid of at most [`MAX_CELLS`] × [`MAX_CELLS`] cells (time buckets × groups of
//! neighbouring contacts), the strongest state seen in each cell: free, touching
//! (`gap ≤ δ`) or pushed (`P > 0`). Memory is bounded by the grid, whatever the run's length
//! and the number of contacts.

use crate::checkpoint::{Checkpoint, CheckpointError};
use crate::observer::{Columns, Observer, Progress, StepRecord};
use crate::outcome::{Chart, ContactRegionChart};
use serde::{Deserialize, Serialize};
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

    /// Continues the grid of a checkpoint (`state`, from [`Checkpoint`]'s region section) of a
    /// run of the same spec; refused when its shape does not fit this one's.
    pub(crate) fn restore(&mut self, state: RegionState) -> Result<(), CheckpointError> {
        let groups = self.x.len().div_ceil(self.per_group);
        let buckets = usize::try_from(state.records)
            .unwrap_or(usize::MAX)
            .div_ceil(self.per_bucket);
        if state.t.len() != state.states.len()
            || state.states.len() != buckets
            || state.states.iter().any(|row| row.len() != groups)
        {
            return Err(CheckpointError::Mismatch(format!(
                "a contact-region grid of {} time buckets, {} records and {} contact groups at most, this job's has {groups} groups and {buckets} buckets for those records",
                state.states.len(),
                state.records,
                state.states.iter().map(Vec::len).max().unwrap_or(0),
            )));
        }
        self.records = state.records as usize;
        self.t = state.t;
        self.states = state.states;
        Ok(())
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

    fn checkpoint_due(&mut self, progress: Progress) -> bool {
        self.inner.checkpoint_due(progress)
    }

    fn checkpoint(&mut self, checkpoint: &mut Checkpoint) {
        let state = RegionState {
            records: self.records as u64,
            t: self.t.clone(),
            states: self.states.clone(),
        };
        // Plain numbers always encode; should they not, the checkpoint goes without the grid
        // and its resume is refused (the job then reruns whole).
        let _ = checkpoint.set_region(&state);
        self.inner.checkpoint(checkpoint);
    }
}

/// What a [`ContactRegion`] keeps across a checkpoint: the records seen, the time of each
/// bucket and the cells (0 free, 1 touching, 2 pushed).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct RegionState {
    records: u64,
    t: Vec<f64>,
    #[serde(with = "cells")]
    states: Vec<Vec<u8>>,
}

/// The cells as byte strings (one per time bucket): 1 byte per cell in MessagePack.
mod cells {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(rows: &[Vec<u8>], s: S) -> Result<S::Ok, S::Error> {
        let rows: Vec<&serde_bytes::Bytes> =
            rows.iter().map(|r| serde_bytes::Bytes::new(r)).collect();
        rows.serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Vec<u8>>, D::Error> {
        let rows = Vec::<serde_bytes::ByteBuf>::deserialize(d)?;
        Ok(rows
            .into_iter()
            .map(serde_bytes::ByteBuf::into_vec)
            .collect())
    }
}
