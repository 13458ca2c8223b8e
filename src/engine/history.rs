//! A job's history: the step batches it sent, replayed from the store (and, for a running job,
//! from the rows not yet stored), so a watcher that comes late or reconnects gets every batch
//! from a given `seq` on, with the rows, `seq` numbers and cuts it had live (the time each step
//! was computed is not kept: replayed batches carry none). Batches dropped live for a slow link
//! are in the history too.

use super::events::{ColumnGroup, StepBatch, split_columns};
use super::{Engine, Series, lock};
use crate::engine::EngineError;
use crate::status::JobView;
use crate::store::SeriesChunk;

/// Rows per replayed batch of a series stored before batches were recorded (numbered from 0).
const LEGACY_BATCH: u64 = 256;

/// What a job has sent, taken at one instant: its stored chunks and its rows not yet stored.
pub struct History {
    id: String,
    columns: Vec<String>,
    stored: Series,
    recent: SeriesChunk,
    recent_first_row: u64,
    ended: bool,
}

impl Engine {
    /// A job's status and its history, taken together: every row recorded so far is in the
    /// history exactly once (a running job's buffer and the store's chunk index are read under
    /// the buffer's lock, which its observer holds while it moves rows to the store).
    pub fn history(&self, id: &str) -> Result<(JobView, History), EngineError> {
        let mut stored = self.reader(id);
        let live = lock(&self.inner.live).get(id).cloned();
        if let Some(live) = live {
            let recent = lock(&live.recent);
            stored.columns = recent.columns.len();
            stored.chunks = self.inner.store.series_index(id)?;
            let history = History {
                id: id.to_string(),
                columns: recent.columns.clone(),
                stored,
                recent: recent.rows.clone(),
                recent_first_row: recent.first_row,
                ended: false,
            };
            drop(recent);
            return Ok((live.view(), history));
        }
        let view = self.status(id)?;
        let columns = if view.state.is_terminal() {
            self.inner
                .store
                .result_head(id)?
                .map(|h| h.columns)
                .unwrap_or_default()
        } else {
            Vec::new()
        };
        stored.columns = columns.len();
        stored.chunks = self.inner.store.series_index(id)?;
        let history = History {
            id: id.to_string(),
            stored,
            columns,
            recent: SeriesChunk::default(),
            recent_first_row: 0,
            ended: view.state.is_terminal(),
        };
        Ok((view, history))
    }
}

/// The batches (seq, start, end) of a stored chunk whose first row is `first_row`.
fn batches_of(chunk: &SeriesChunk, first_row: u64) -> Vec<(u64, u64, u64)> {
    if !chunk.batches.is_empty() || chunk.steps.is_empty() {
        return chunk.batches.clone();
    }
    // Stored before batches were recorded.
    let end = first_row + chunk.steps.len() as u64;
    (first_row..end)
        .step_by(LEGACY_BATCH as usize)
        .map(|start| (start / LEGACY_BATCH, start, (start + LEGACY_BATCH).min(end)))
        .collect()
}

impl History {
    /// The run's columns.
    pub fn columns(&self) -> &[String] {
        &self.columns
    }

    /// Whether the job had ended when the history was taken.
    pub fn ended(&self) -> bool {
        self.ended
    }

    /// The first stored chunk with a batch of `seq ≥ from_seq` (the number of chunks when none
    /// has), by bisection: `seq` grows with the rows, so a watcher asking for the last frames of
    /// a long run reads a few chunks, not all of them (it read all 1 608 batches of a
    /// 400 000-step run to answer with none, which took longer than a query's timeout on a
    /// loaded machine).
    fn first_chunk_from(&self, from_seq: u64) -> Result<usize, EngineError> {
        let chunks = self.stored.chunks();
        let (mut below, mut above) = (0, chunks.len());
        while below < above {
            let mid = below + (above - below) / 2;
            let chunk = self.stored.read(&chunks[mid])?;
            let last_seq = batches_of(&chunk, chunks[mid].first_row)
                .last()
                .map(|b| b.0);
            if last_seq.is_some_and(|s| s < from_seq) {
                below = mid + 1;
            } else {
                above = mid;
            }
        }
        Ok(below)
    }

    /// Gives `send` every batch of `seq ≥ from_seq`, in order, reading one stored chunk at a
    /// time (blocking), until `send` returns false; the last batch of an ended job is marked
    /// `last`. Returns the `seq` of the last batch given.
    pub fn replay(
        &self,
        from_seq: u64,
        mut send: impl FnMut(StepBatch) -> bool,
    ) -> Result<Option<u64>, EngineError> {
        let (energy, state) = split_columns(&self.columns);
        let n = self.columns.len();
        let make = |chunk: &SeriesChunk, first_row: u64, (seq, start, end): (u64, u64, u64)| {
            let rows = (start - first_row) as usize..(end - first_row) as usize;
            let group = |idx: &[usize]| {
                let mut values = Vec::with_capacity(rows.len() * idx.len());
                for row in chunk.values[rows.start * n..rows.end * n].chunks_exact(n.max(1)) {
                    values.extend(idx.iter().map(|&c| row[c]));
                }
                ColumnGroup {
                    columns: idx.iter().map(|&c| self.columns[c].clone()).collect(),
                    values,
                }
            };
            StepBatch {
                id: self.id.clone(),
                seq,
                step: chunk.steps[rows.clone()].to_vec(),
                t: chunk.t[rows.clone()].to_vec(),
                computed_unix_ns: Vec::new(),
                energy: group(&energy),
                state: group(&state),
                last: false,
            }
        };
        // One batch is held back so the last one can be marked.
        let mut held: Option<StepBatch> = None;
        let mut given = None;
        let mut give = |b: StepBatch, given: &mut Option<u64>| -> bool {
            match held.replace(b) {
                Some(prev) => {
                    *given = Some(prev.seq);
                    send(prev)
                }
                None => true,
            }
        };
        let chunks = self.stored.chunks();
        for meta in &chunks[self.first_chunk_from(from_seq)?..] {
            let chunk = self.stored.read(meta)?;
            for b in batches_of(&chunk, meta.first_row) {
                if b.0 >= from_seq && !give(make(&chunk, meta.first_row, b), &mut given) {
                    return Ok(given);
                }
            }
        }
        // Rows after the last batch sent are not history yet: they go out live.
        for b in self.recent.batches.iter().copied() {
            if b.0 >= from_seq && !give(make(&self.recent, self.recent_first_row, b), &mut given) {
                return Ok(given);
            }
        }
        if let Some(mut last) = held {
            last.last = self.ended;
            given = Some(last.seq);
            send(last);
        }
        Ok(given)
    }
}
