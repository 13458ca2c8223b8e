//! A stored result sent at any size in bounded memory: the cuts a client asks for ([`Cut`]:
//! columns, every N-th row, a range of steps), applied while the series is read from the store
//! one chunk at a time, and the encoders of the HTTP body (JSON, CSV, NPZ, optionally gzip) and
//! of the gRPC `StreamResult` messages. A whole series is never held: at most one stored chunk
//! (about 1 MiB), the kept values of a group of columns ([`GROUP_VALUES`]) and a few buffers of
//! the encoded body.
//!
//! The binary format is NPZ (numpy's zip of `.npy` arrays, one per column): numpy reads it in one
//! line (`numpy.load("result.npz")`) with nothing else installed, and it is written here by hand
//! (a stored zip with data descriptors, ZIP64 when large, crc32 from flate2, already built for
//! zenoh), so it adds no crate to the build; Arrow IPC and Parquet need pyarrow on the reading
//! side and the arrow crates (a large share of a build) on this one.

use crate::engine::Series;
use crate::error::ApiError;
use crate::store::{ChunkMeta, StoredResult};
use signorini_core::outcome::Table;
use signorini_core::spec::SpecError;
use std::io::{self, Write};

/// What a client asks of a series: these value columns (all when empty), rows whose step is in
/// `from..=to`, and of those every `every`-th plus the last.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CutRequest {
    /// Column names.
    pub columns: Vec<String>,
    /// Keep every N-th row (0 or 1: all).
    pub every: u64,
    /// First step number kept.
    pub from: Option<u64>,
    /// Last step number kept.
    pub to: Option<u64>,
}

/// A cut resolved against one stored series: which columns, which rows.
#[derive(Debug, Clone, PartialEq)]
pub struct Cut {
    /// Indices of the kept value columns in the stored rows.
    pub at: Vec<usize>,
    /// Their names.
    pub names: Vec<String>,
    /// Stored value columns.
    pub stored_columns: usize,
    /// First row of the range.
    pub first: u64,
    /// One past the last row of the range.
    pub end: u64,
    /// Every N-th row of the range (≥ 1), plus its last.
    pub every: u64,
}

/// Rows of one stored chunk that a [`Cut`] keeps, with only its columns.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Rows {
    /// Index of the first of these rows among the kept rows.
    pub first_kept: u64,
    /// Step numbers.
    pub steps: Vec<u64>,
    /// Times.
    pub t: Vec<f64>,
    /// Values, row-major over the cut's columns (those asked for, with [`Cut::for_each_in`]).
    pub values: Vec<f64>,
}

/// Values of one column-by-column encoding (JSON, NPZ) held at once: the columns are read in
/// groups that fit, with the steps and times, one pass over the stored series a group; when a
/// column's rows do not fit with them, each column is streamed alone. A result of many columns (a rigid scene's pose and twist of every
/// body: 13 079 columns for 1 005 bodies) took one pass a column, each reading every stored
/// chunk: 10 s for 21 rows.
pub const GROUP_VALUES: usize = 1 << 20;

impl Cut {
    /// Resolves `req` against the result `head` and its `series`: an unknown column is an error
    /// naming `columns` (`step` and `t` are always part of a cut, and accepted in `columns`),
    /// `from > to` one naming `from`.
    pub fn new(head: &StoredResult, series: &Series, req: &CutRequest) -> Result<Cut, ApiError> {
        let at: Vec<usize> = if req.columns.is_empty() {
            (0..head.columns.len()).collect()
        } else {
            // `step` and `t` come with every cut: asking for them is not an error.
            req.columns
                .iter()
                .filter(|name| !matches!(name.as_str(), "step" | "t"))
                .map(|name| {
                    head.columns.iter().position(|c| c == name).ok_or_else(|| {
                        SpecError::new(
                            "columns",
                            format!(
                                "no column {name:?} (the result has step, t, {})",
                                head.columns.join(", ")
                            ),
                        )
                    })
                })
                .collect::<Result<_, _>>()?
        };
        if let (Some(from), Some(to)) = (req.from, req.to)
            && from > to
        {
            return Err(SpecError::new("from", format!("{from} is after to = {to}")).into());
        }
        let first = match req.from {
            Some(step) => first_row_at_or_after(series, step)?,
            None => 0,
        };
        let end = match req.to {
            Some(step) => first_row_after(series, step)?,
            None => series.rows(),
        };
        Ok(Cut {
            names: at.iter().map(|&c| head.columns[c].clone()).collect(),
            at,
            stored_columns: head.columns.len(),
            first,
            end: end.max(first),
            every: req.every.max(1),
        })
    }

    /// Rows kept in all.
    pub fn rows(&self) -> u64 {
        if self.end <= self.first {
            return 0;
        }
        let span = self.end - self.first;
        let regular = (span - 1) / self.every + 1;
        regular + u64::from(!(span - 1).is_multiple_of(self.every))
    }

    /// Whether row `i` of the series is kept.
    pub fn keeps(&self, i: u64) -> bool {
        i >= self.first
            && i < self.end
            && ((i - self.first).is_multiple_of(self.every) || i + 1 == self.end)
    }

    /// Index among the kept rows of the first kept row at or after row `i`.
    fn kept_before(&self, i: u64) -> u64 {
        if i <= self.first {
            return 0;
        }
        if i >= self.end {
            return self.rows();
        }
        // The rows first + k·every below i (the irregular last row is at end - 1 ≥ i).
        (i - self.first - 1) / self.every + 1
    }

    /// Calls `f` with the kept rows of each stored chunk that has any, in order, reading one
    /// chunk at a time (blocking).
    pub fn for_each(
        &self,
        series: &Series,
        f: impl FnMut(&Rows) -> io::Result<()>,
    ) -> io::Result<()> {
        self.for_each_in(series, 0..self.at.len(), f)
    }

    /// [`Self::for_each`] with only the cut's columns `columns` in the rows' values.
    pub fn for_each_in(
        &self,
        series: &Series,
        columns: std::ops::Range<usize>,
        mut f: impl FnMut(&Rows) -> io::Result<()>,
    ) -> io::Result<()> {
        let at = &self.at[columns];
        for meta in series.chunks() {
            if meta.first_row + meta.rows <= self.first || meta.first_row >= self.end {
                continue;
            }
            let chunk = series.read(meta).map_err(io::Error::other)?;
            let n = self.stored_columns;
            let mut rows = Rows {
                first_kept: self.kept_before(meta.first_row),
                ..Rows::default()
            };
            for (k, (&step, &t)) in chunk.steps.iter().zip(&chunk.t).enumerate() {
                if !self.keeps(meta.first_row + k as u64) {
                    continue;
                }
                rows.steps.push(step);
                rows.t.push(t);
                let row = &chunk.values[k * n..(k + 1) * n];
                rows.values.extend(at.iter().map(|&c| row[c]));
            }
            if !rows.steps.is_empty() {
                f(&rows)?;
            }
        }
        Ok(())
    }
}

/// The chunk holding the first row whose step is ≥ `step` (steps increase along a series).
fn first_row_at_or_after(series: &Series, step: u64) -> Result<u64, ApiError> {
    row_by(series, |s| s >= step, |m| m.step_last >= step)
}

/// The first row whose step is > `step`.
fn first_row_after(series: &Series, step: u64) -> Result<u64, ApiError> {
    row_by(series, |s| s > step, |m| m.step_last > step)
}

/// The first row whose step satisfies `row_ok`, given `chunk_ok` tells a chunk holds one; the
/// series' row count when none does.
fn row_by(
    series: &Series,
    row_ok: impl Fn(u64) -> bool,
    chunk_ok: impl Fn(&ChunkMeta) -> bool,
) -> Result<u64, ApiError> {
    let Some(meta) = series.chunks().iter().find(|m| chunk_ok(m)) else {
        return Ok(series.rows());
    };
    if row_ok(meta.step_first) {
        return Ok(meta.first_row);
    }
    let chunk = series.read(meta)?;
    let k = chunk
        .steps
        .iter()
        .position(|&s| row_ok(s))
        .unwrap_or(chunk.steps.len());
    Ok(meta.first_row + k as u64)
}

/// The body formats of `GET /v1/jobs/{id}/result`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// `{"id", "state", "partial", "summary", "columns", "steps": {column: […]}, "tables",
    /// "figures"}`.
    Json,
    /// `steps.csv`: the header `step,t,…`, one line per kept row, the bytes `signorini run`
    /// writes.
    Csv,
    /// numpy's `.npz`: one array per column (`step` as uint64, the rest float64).
    Npz,
}

impl Format {
    /// Parses `?format=`.
    pub fn parse(s: &str) -> Result<Format, ApiError> {
        match s {
            "json" => Ok(Format::Json),
            "csv" => Ok(Format::Csv),
            "npz" => Ok(Format::Npz),
            other => Err(SpecError::new(
                "format",
                format!("{other:?} is not one of json, csv, npz"),
            )
            .into()),
        }
    }

    /// The body's content type.
    pub fn content_type(self) -> &'static str {
        match self {
            Format::Json => "application/json",
            Format::Csv => "text/csv; charset=utf-8",
            Format::Npz => "application/octet-stream",
        }
    }
}

/// Writes the CSV of the kept rows (header `step,t,…`; values as `signorini run` writes them).
pub fn write_csv(w: &mut dyn Write, cut: &Cut, series: &Series) -> io::Result<()> {
    let mut header = String::from("step,t");
    for c in &cut.names {
        header.push(',');
        header.push_str(c);
    }
    writeln!(w, "{header}")?;
    let n = cut.names.len();
    cut.for_each(series, |rows| {
        for (i, (&step, &t)) in rows.steps.iter().zip(&rows.t).enumerate() {
            write!(w, "{step},{t:?}")?;
            for v in &rows.values[i * n..(i + 1) * n] {
                write!(w, ",{v:?}")?;
            }
            writeln!(w)?;
        }
        Ok(())
    })
}

/// A result table as CSV: its columns, then a row per table row (shortest round-trip text; an
/// empty cell for NaN, a value the run did not have).
pub fn write_table_csv(w: &mut dyn Write, table: &Table) -> io::Result<()> {
    writeln!(w, "{}", table.columns.join(","))?;
    for row in &table.rows {
        let cells: Vec<String> = row
            .iter()
            .map(|v| {
                if v.is_nan() {
                    String::new()
                } else {
                    format!("{v:?}")
                }
            })
            .collect();
        writeln!(w, "{}", cells.join(","))?;
    }
    Ok(())
}

/// The series' columns as the stream reads them: `step`, `t`, then the cut's value columns.
#[derive(Debug, Clone, Copy)]
enum Col {
    Step,
    T,
    Value(usize),
}

impl Col {
    fn all(cut: &Cut) -> impl Iterator<Item = (Col, &str)> {
        [(Col::Step, "step"), (Col::T, "t")].into_iter().chain(
            cut.names
                .iter()
                .enumerate()
                .map(|(c, n)| (Col::Value(c), n.as_str())),
        )
    }
}

/// The kept values of a cut, column after column: `step`, `t` and the value columns read in
/// groups of [`GROUP_VALUES`] values (the steps and times with the first group), one pass over
/// the series a group; when one column's rows do not fit with the steps and times, each column
/// is streamed in a pass of its own.
struct Columns<'a> {
    cut: &'a Cut,
    series: &'a Series,
    /// Value columns a group holds (0: each column streamed alone).
    width: usize,
    /// The kept steps and times, once read.
    steps: Option<(Vec<u64>, Vec<f64>)>,
    /// The cut's columns `group_start..group_start + group.len()`, read.
    group_start: usize,
    group: Vec<Vec<f64>>,
}

impl<'a> Columns<'a> {
    fn new(cut: &'a Cut, series: &'a Series) -> Self {
        let rows = usize::try_from(cut.rows()).unwrap_or(usize::MAX).max(1);
        Self {
            cut,
            series,
            width: (GROUP_VALUES / rows).saturating_sub(2),
            steps: None,
            group_start: 0,
            group: Vec::new(),
        }
    }

    /// Calls `f` with each value of `col` in the kept rows.
    fn each(&mut self, col: Col, mut f: impl FnMut(Value) -> io::Result<()>) -> io::Result<()> {
        if self.width == 0 {
            return self
                .cut
                .for_each_in(self.series, col.range(), |rows| match col {
                    Col::Step => rows.steps.iter().try_for_each(|&s| f(Value::U64(s))),
                    Col::T => rows.t.iter().try_for_each(|&t| f(Value::F64(t))),
                    Col::Value(_) => rows.values.iter().try_for_each(|&v| f(Value::F64(v))),
                });
        }
        match col {
            Col::Step | Col::T if self.steps.is_none() => self.read_group(0)?,
            Col::Value(c)
                if !(self.group_start..self.group_start + self.group.len()).contains(&c) =>
            {
                self.read_group(c)?
            }
            _ => {}
        }
        let (steps, t) = self.steps.as_ref().expect("read with the first group");
        match col {
            Col::Step => steps.iter().try_for_each(|&s| f(Value::U64(s))),
            Col::T => t.iter().try_for_each(|&t| f(Value::F64(t))),
            Col::Value(c) => self.group[c - self.group_start]
                .iter()
                .try_for_each(|&v| f(Value::F64(v))),
        }
    }

    /// Reads the value columns `c..c + width` (fewer at the end), and the steps and times on
    /// the first read, in one pass over the series.
    fn read_group(&mut self, c: usize) -> io::Result<()> {
        let end = (c + self.width).min(self.cut.at.len());
        let rows = usize::try_from(self.cut.rows()).unwrap_or(0);
        self.group_start = c;
        self.group = vec![Vec::with_capacity(rows); end - c];
        let mut steps = self
            .steps
            .is_none()
            .then(|| (Vec::with_capacity(rows), Vec::with_capacity(rows)));
        let group = &mut self.group;
        self.cut.for_each_in(self.series, c..end, |rows| {
            if let Some((s, t)) = &mut steps {
                s.extend_from_slice(&rows.steps);
                t.extend_from_slice(&rows.t);
            }
            if end > c {
                for row in rows.values.chunks_exact(end - c) {
                    for (column, &v) in group.iter_mut().zip(row) {
                        column.push(v);
                    }
                }
            }
            Ok(())
        })?;
        if steps.is_some() {
            self.steps = steps;
        }
        Ok(())
    }
}

impl Col {
    /// The cut's value columns a pass for this column alone reads.
    fn range(self) -> std::ops::Range<usize> {
        match self {
            Col::Step | Col::T => 0..0,
            Col::Value(c) => c..c + 1,
        }
    }
}

#[derive(Debug, Clone, Copy)]
enum Value {
    U64(u64),
    F64(f64),
}

/// Writes the JSON result, one column after the other (one pass over the stored series per group
/// of columns, [`Columns`]), numbers as `serde_json` writes them (shortest round trip; non-finite as `null`).
pub fn write_json(
    w: &mut dyn Write,
    view: &crate::status::JobView,
    head: &StoredResult,
    cut: &Cut,
    series: &Series,
) -> io::Result<()> {
    let columns: Vec<&str> = Col::all(cut).map(|(_, n)| n).collect();
    write!(
        w,
        "{{\"id\":{},\"state\":{},\"partial\":{},\"summary\":{},\"columns\":{},\"steps\":{{",
        serde_json::to_string(&view.id)?,
        serde_json::to_string(view.state.as_str())?,
        head.partial,
        serde_json::to_string(&head.summary)?,
        serde_json::to_string(&columns)?,
    )?;
    let mut columns = Columns::new(cut, series);
    for (k, (col, name)) in Col::all(cut).enumerate() {
        if k > 0 {
            w.write_all(b",")?;
        }
        write!(w, "{}:[", serde_json::to_string(name)?)?;
        let mut first = true;
        columns.each(col, |v| {
            if !first {
                w.write_all(b",")?;
            }
            first = false;
            match v {
                Value::U64(s) => write!(w, "{s}"),
                Value::F64(x) => serde_json::to_writer(&mut *w, &x).map_err(io::Error::other),
            }
        })?;
        w.write_all(b"]")?;
    }
    let tables: Vec<serde_json::Value> = head
        .tables
        .iter()
        .map(|t| serde_json::json!({ "name": t.name, "columns": t.columns, "rows": t.rows }))
        .collect();
    let figures: Vec<&str> = head.figures.iter().map(|f| f.name.as_str()).collect();
    write!(
        w,
        "}},\"tables\":{},\"figures\":{}}}",
        serde_json::to_string(&tables)?,
        serde_json::to_string(&figures)?
    )
}

/// A zip archive written front to back (stored entries, sizes and CRC in a data descriptor after
/// each entry and in the central directory; ZIP64 records where a size or offset needs them), as
/// numpy's `.npz` is read by Python's `zipfile`.
struct ZipOut<'a> {
    w: &'a mut dyn Write,
    offset: u64,
    entries: Vec<(String, u32, u64, u64)>,
}

const U32_MAX: u64 = 0xFFFF_FFFF;

impl<'a> ZipOut<'a> {
    fn new(w: &'a mut dyn Write) -> Self {
        Self {
            w,
            offset: 0,
            entries: Vec::new(),
        }
    }

    fn put(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.w.write_all(bytes)?;
        self.offset += bytes.len() as u64;
        Ok(())
    }

    /// Writes one entry whose bytes `body` produces through the writer it is given.
    fn entry(
        &mut self,
        name: &str,
        body: impl FnOnce(&mut dyn FnMut(&[u8]) -> io::Result<()>) -> io::Result<()>,
    ) -> io::Result<()> {
        let start = self.offset;
        let mut h = Vec::with_capacity(30 + name.len());
        h.extend_from_slice(&0x0403_4b50u32.to_le_bytes());
        h.extend_from_slice(&45u16.to_le_bytes()); // version needed (ZIP64)
        h.extend_from_slice(&0x0808u16.to_le_bytes()); // data descriptor, UTF-8 name
        h.extend_from_slice(&0u16.to_le_bytes()); // stored
        h.extend_from_slice(&0u16.to_le_bytes()); // time
        h.extend_from_slice(&0x21u16.to_le_bytes()); // date: 1980-01-01
        h.extend_from_slice(&[0; 12]); // crc, sizes: in the descriptor
        h.extend_from_slice(&(name.len() as u16).to_le_bytes());
        h.extend_from_slice(&0u16.to_le_bytes());
        h.extend_from_slice(name.as_bytes());
        self.put(&h)?;
        let mut crc = flate2::Crc::new();
        let mut size = 0u64;
        {
            let w = &mut *self.w;
            body(&mut |bytes: &[u8]| {
                crc.update(bytes);
                size += bytes.len() as u64;
                w.write_all(bytes)
            })?;
        }
        self.offset += size;
        let crc = crc.sum();
        let mut d = Vec::with_capacity(24);
        d.extend_from_slice(&0x0807_4b50u32.to_le_bytes());
        d.extend_from_slice(&crc.to_le_bytes());
        if size >= U32_MAX {
            d.extend_from_slice(&size.to_le_bytes());
            d.extend_from_slice(&size.to_le_bytes());
        } else {
            d.extend_from_slice(&(size as u32).to_le_bytes());
            d.extend_from_slice(&(size as u32).to_le_bytes());
        }
        self.put(&d)?;
        self.entries.push((name.to_string(), crc, size, start));
        Ok(())
    }

    /// The central directory and the end records.
    fn finish(mut self) -> io::Result<()> {
        let cd_start = self.offset;
        let entries = std::mem::take(&mut self.entries);
        for (name, crc, size, start) in &entries {
            let mut extra = Vec::new();
            let big_size = *size >= U32_MAX;
            let big_start = *start >= U32_MAX;
            if big_size {
                extra.extend_from_slice(&size.to_le_bytes());
                extra.extend_from_slice(&size.to_le_bytes());
            }
            if big_start {
                extra.extend_from_slice(&start.to_le_bytes());
            }
            let mut c = Vec::with_capacity(46 + name.len() + extra.len() + 4);
            c.extend_from_slice(&0x0201_4b50u32.to_le_bytes());
            c.extend_from_slice(&45u16.to_le_bytes()); // made by
            c.extend_from_slice(&45u16.to_le_bytes()); // needed
            c.extend_from_slice(&0x0808u16.to_le_bytes());
            c.extend_from_slice(&0u16.to_le_bytes());
            c.extend_from_slice(&0u16.to_le_bytes());
            c.extend_from_slice(&0x21u16.to_le_bytes());
            c.extend_from_slice(&crc.to_le_bytes());
            let s32 = if big_size { U32_MAX } else { *size } as u32;
            c.extend_from_slice(&s32.to_le_bytes());
            c.extend_from_slice(&s32.to_le_bytes());
            c.extend_from_slice(&(name.len() as u16).to_le_bytes());
            let extra_len = if extra.is_empty() { 0 } else { extra.len() + 4 };
            c.extend_from_slice(&(extra_len as u16).to_le_bytes());
            c.extend_from_slice(&[0; 6]); // comment length, disk, internal attributes
            c.extend_from_slice(&0u32.to_le_bytes()); // external attributes
            let o32 = if big_start { U32_MAX } else { *start } as u32;
            c.extend_from_slice(&o32.to_le_bytes());
            c.extend_from_slice(name.as_bytes());
            if !extra.is_empty() {
                c.extend_from_slice(&1u16.to_le_bytes());
                c.extend_from_slice(&(extra.len() as u16).to_le_bytes());
                c.extend_from_slice(&extra);
            }
            self.put(&c)?;
        }
        let cd_size = self.offset - cd_start;
        let n = entries.len() as u64;
        let zip64 = cd_start >= U32_MAX || cd_size >= U32_MAX || n >= 0xFFFF;
        if zip64 {
            let eocd64 = self.offset;
            let mut e = Vec::with_capacity(76);
            e.extend_from_slice(&0x0606_4b50u32.to_le_bytes());
            e.extend_from_slice(&44u64.to_le_bytes());
            e.extend_from_slice(&45u16.to_le_bytes());
            e.extend_from_slice(&45u16.to_le_bytes());
            e.extend_from_slice(&[0; 8]); // this disk, disk of the directory
            e.extend_from_slice(&n.to_le_bytes());
            e.extend_from_slice(&n.to_le_bytes());
            e.extend_from_slice(&cd_size.to_le_bytes());
            e.extend_from_slice(&cd_start.to_le_bytes());
            e.extend_from_slice(&0x0706_4b50u32.to_le_bytes());
            e.extend_from_slice(&0u32.to_le_bytes());
            e.extend_from_slice(&eocd64.to_le_bytes());
            e.extend_from_slice(&1u32.to_le_bytes());
            self.put(&e)?;
        }
        let mut e = Vec::with_capacity(22);
        e.extend_from_slice(&0x0605_4b50u32.to_le_bytes());
        e.extend_from_slice(&[0; 4]);
        let n16 = n.min(0xFFFF) as u16;
        e.extend_from_slice(&n16.to_le_bytes());
        e.extend_from_slice(&n16.to_le_bytes());
        e.extend_from_slice(&(cd_size.min(U32_MAX) as u32).to_le_bytes());
        e.extend_from_slice(&(cd_start.min(U32_MAX) as u32).to_le_bytes());
        e.extend_from_slice(&0u16.to_le_bytes());
        self.put(&e)
    }
}

/// The header of a one-dimensional `.npy` array of `rows` values of type `descr`
/// (format version 1.0, padded to a multiple of 64 bytes).
fn npy_header(descr: &str, rows: u64) -> Vec<u8> {
    let dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': ({rows},), }}");
    let unpadded = 10 + dict.len() + 1;
    let len = unpadded.div_ceil(64) * 64;
    let mut h = Vec::with_capacity(len);
    h.extend_from_slice(b"\x93NUMPY\x01\x00");
    h.extend_from_slice(&((len - 10) as u16).to_le_bytes());
    h.extend_from_slice(dict.as_bytes());
    h.resize(len - 1, b' ');
    h.push(b'\n');
    h
}

/// Writes the kept rows as an `.npz`: `step.npy` (uint64), `t.npy` and one `NAME.npy` per
/// column (float64), read a group of columns a pass over the stored series ([`Columns`]).
pub fn write_npz(w: &mut dyn Write, cut: &Cut, series: &Series) -> io::Result<()> {
    let rows = cut.rows();
    let mut zip = ZipOut::new(w);
    let mut columns = Columns::new(cut, series);
    for (col, name) in Col::all(cut) {
        let descr = if matches!(col, Col::Step) {
            "<u8"
        } else {
            "<f8"
        };
        zip.entry(&format!("{name}.npy"), |out| {
            out(&npy_header(descr, rows))?;
            let mut buf = Vec::with_capacity(64 << 10);
            columns.each(col, |v| {
                match v {
                    Value::U64(s) => buf.extend_from_slice(&s.to_le_bytes()),
                    Value::F64(x) => buf.extend_from_slice(&x.to_le_bytes()),
                }
                if buf.len() >= 64 << 10 {
                    out(&buf)?;
                    buf.clear();
                }
                Ok(())
            })?;
            out(&buf)
        })?;
    }
    zip.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cut(first: u64, end: u64, every: u64) -> Cut {
        Cut {
            at: Vec::new(),
            names: Vec::new(),
            stored_columns: 0,
            first,
            end,
            every,
        }
    }

    /// The count, the membership test and the index of the first kept row of a chunk agree
    /// with a plain filter over the rows, for ranges ending on and off the `every` grid.
    #[test]
    fn kept_rows_are_counted_and_indexed_as_a_filter_would() {
        for (first, end, every) in [
            (0, 10, 1),
            (0, 10, 3),
            (2, 11, 3),
            (5, 5, 2),
            (4, 5, 7),
            (3, 100, 10),
        ] {
            let c = cut(first, end, every);
            let kept: Vec<u64> = (0..120).filter(|&i| c.keeps(i)).collect();
            assert_eq!(c.rows(), kept.len() as u64, "{first} {end} {every}");
            for i in 0..120 {
                let before = kept.iter().filter(|&&k| k < i).count() as u64;
                assert_eq!(c.kept_before(i), before, "{first} {end} {every} at {i}");
            }
        }
    }

    #[test]
    fn npy_headers_are_aligned_and_say_the_shape() {
        let h = npy_header("<f8", 5_000_001);
        assert_eq!(h.len() % 64, 0);
        assert_eq!(&h[..8], b"\x93NUMPY\x01\x00");
        assert_eq!(u16::from_le_bytes([h[8], h[9]]) as usize, h.len() - 10);
        let text = std::str::from_utf8(&h[10..]).expect("ascii header");
        assert!(
            text.starts_with("{'descr': '<f8', 'fortran_order': False, 'shape': (5000001,), }")
        );
        assert!(text.ends_with('\n'));
    }
}
