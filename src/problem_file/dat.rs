//! Siconos' text format of a (local) friction problem, as `frictionContact_newFromFile`
//! (numerics/src/FrictionContact/FrictionContactProblem.c) reads it and
//! `frictionContact_printInFile` writes it:
//!
//! ```text
//! d            dimension, 2 or 3
//! nc           contacts
//! W            a NumericsMatrix (NM_new_from_file): storage, size0, size1, then
//!                0 dense:        size0 size1 again, then size0·size1 numbers, column-major
//!                1 sparse block: SBM_new_from_file: nbblocks, block rows, block columns,
//!                                cumulative block sizes of rows and columns, filled1, filled2,
//!                                index1 (block row starts), index2 (block columns), then per
//!                                block its number and its entries, column-major
//!                2 sparse:       NSM_new_from_file: origin (1 triplet, 2 CSC, 3 CSR), then
//!                                CSparse's own print (`cs_print`): a version line, a header
//!                                line, then per column `col j : locations a to b` and one
//!                                `i : value` line per entry (triplet: `i j : value` lines)
//! q            size0 numbers
//! mu           nc numbers
//! ```
//!
//! Anything after μ is ignored, as Siconos ignores it. CSparse's print has `%g` precision (six
//! significant digits): such a file holds W only to that precision, for Siconos as for us.

use super::{RawProblem, ReadError};
use signorini_core::friction::BlockCsr;

/// A cursor over the text: whitespace-separated tokens, or whole lines.
struct Cursor<'a> {
    text: &'a str,
    at: usize,
}

impl<'a> Cursor<'a> {
    fn token(&mut self, what: &'static str) -> Result<&'a str, ReadError> {
        let rest = &self.text[self.at..];
        let start = rest
            .find(|c: char| !c.is_whitespace())
            .ok_or(ReadError::UnexpectedEnd { what })?;
        let len = rest[start..]
            .find(char::is_whitespace)
            .unwrap_or(rest.len() - start);
        self.at += start + len;
        Ok(&rest[start..start + len])
    }

    fn number(&mut self, what: &'static str) -> Result<f64, ReadError> {
        let t = self.token(what)?;
        t.parse().map_err(|_| ReadError::NotANumber {
            what,
            token: t.to_string(),
        })
    }

    fn count(&mut self, what: &'static str) -> Result<usize, ReadError> {
        let t = self.token(what)?;
        t.parse().map_err(|_| ReadError::NotANumber {
            what,
            token: t.to_string(),
        })
    }

    /// The rest of the current line (what `fgets` returns after a `fscanf`).
    fn line(&mut self, what: &'static str) -> Result<&'a str, ReadError> {
        let rest = &self.text[self.at..];
        if rest.is_empty() {
            return Err(ReadError::UnexpectedEnd { what });
        }
        let len = rest.find('\n').map_or(rest.len(), |i| i + 1);
        self.at += len;
        Ok(rest[..len].trim_end_matches(['\n', '\r']))
    }
}

/// Parses the text of a `.dat` problem file.
pub fn parse(text: &str) -> Result<RawProblem, ReadError> {
    let mut c = Cursor { text, at: 0 };
    let dimension = c.count("the dimension d")?;
    if !(dimension == 2 || dimension == 3) {
        return Err(ReadError::Dimension { dimension });
    }
    let contacts = c.count("the number of contacts")?;
    let storage = c.count("the storage of W")?;
    let rows = c.count("the rows of W")?;
    let columns = c.count("the columns of W")?;
    let size = dimension
        .checked_mul(contacts)
        .ok_or(ReadError::Contacts { contacts })?;
    if rows != size || columns != size {
        return Err(ReadError::MatrixSize {
            rows,
            columns,
            size,
        });
    }
    let entries = match storage {
        0 => dense(&mut c, size)?,
        1 => sparse_block(&mut c, size)?,
        2 => csparse(&mut c, size)?,
        other => return Err(ReadError::Storage { storage: other }),
    };
    let w = BlockCsr::from_triplets(dimension, size, entries)?;
    let q = (0..size)
        .map(|_| c.number("q"))
        .collect::<Result<Vec<_>, _>>()?;
    let mu = (0..contacts)
        .map(|_| c.number("μ"))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(RawProblem {
        dimension,
        w,
        q,
        mu,
        storage: match storage {
            0 => "dense",
            1 => "sparse_block",
            _ => "csparse",
        },
    })
}

type Entries = Vec<(usize, usize, f64)>;

fn dense(c: &mut Cursor<'_>, size: usize) -> Result<Entries, ReadError> {
    let (rows, columns) = (c.count("the rows of W")?, c.count("the columns of W")?);
    if rows != size || columns != size {
        return Err(ReadError::MatrixSize {
            rows,
            columns,
            size,
        });
    }
    let mut entries = Vec::new();
    for k in 0..size * size {
        let x = c.number("an entry of W")?;
        if x != 0.0 {
            // Column-major.
            entries.push((k % size, k / size, x));
        }
    }
    Ok(entries)
}

fn sparse_block(c: &mut Cursor<'_>, size: usize) -> Result<Entries, ReadError> {
    let _stored = c.count("the number of blocks")?;
    let block_rows = c.count("the block rows")?;
    let block_columns = c.count("the block columns")?;
    let mut ends = |n: usize| -> Result<Vec<usize>, ReadError> {
        (0..n).map(|_| c.count("a block size")).collect()
    };
    let row_ends = ends(block_rows)?;
    let column_ends = ends(block_columns)?;
    let filled1 = c.count("filled1")?;
    let filled2 = c.count("filled2")?;
    let index1 = (0..filled1)
        .map(|_| c.count("index1"))
        .collect::<Result<Vec<_>, _>>()?;
    let index2 = (0..filled2)
        .map(|_| c.count("index2"))
        .collect::<Result<Vec<_>, _>>()?;
    let start = |ends: &[usize], k: usize| if k == 0 { 0 } else { ends[k - 1] };
    let mut entries = Vec::new();
    for row in 0..filled1.saturating_sub(1) {
        let (first, last) = (index1[row], index1[row + 1]);
        if row >= block_rows || last > filled2 || first > last {
            return Err(ReadError::BlockStructure {
                reason: format!("block row {row} lists blocks {first}..{last}"),
            });
        }
        for (number, &column) in index2.iter().enumerate().take(last).skip(first) {
            if column >= block_columns {
                return Err(ReadError::BlockStructure {
                    reason: format!("block {number} is in block column {column}"),
                });
            }
            let given = c.count("a block number")?;
            if given != number {
                return Err(ReadError::BlockStructure {
                    reason: format!("block {number} is numbered {given}"),
                });
            }
            let (r0, r1) = (start(&row_ends, row), row_ends[row]);
            let (c0, c1) = (start(&column_ends, column), column_ends[column]);
            if r1 < r0 || c1 < c0 || r1 > size || c1 > size {
                return Err(ReadError::BlockStructure {
                    reason: format!("block {number} spans rows {r0}..{r1}, columns {c0}..{c1}"),
                });
            }
            let height = r1 - r0;
            for k in 0..height * (c1 - c0) {
                let x = c.number("an entry of a block")?;
                if x != 0.0 {
                    // Column-major inside the block.
                    entries.push((r0 + k % height, c0 + k / height, x));
                }
            }
        }
    }
    Ok(entries)
}

fn csparse(c: &mut Cursor<'_>, size: usize) -> Result<Entries, ReadError> {
    let origin = c.count("the sparse origin")?;
    c.line("the end of the origin line")?;
    c.line("CSparse's version line")?;
    let header = c.line("CSparse's header line")?;
    let triplet = header.trim_start().starts_with("triplet:");
    let csr = header.trim_start().starts_with("csr:") || origin == 3;
    let bad = |line: &str| ReadError::CsparseLine {
        line: line.trim().to_string(),
    };
    let mut entries = Vec::new();
    if triplet {
        let nz: usize = header
            .split("nnz:")
            .nth(1)
            .and_then(|s| s.trim().split([' ', ',']).next())
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| bad(header))?;
        for _ in 0..nz {
            let line = c.line("a triplet line")?;
            let (ij, value) = line.split_once(':').ok_or_else(|| bad(line))?;
            let mut ij = ij.split_whitespace().map(str::parse::<usize>);
            let (Some(Ok(i)), Some(Ok(j)), None) = (ij.next(), ij.next(), ij.next()) else {
                return Err(bad(line));
            };
            let x: f64 = value.trim().parse().map_err(|_| bad(line))?;
            entries.push((i, j, x));
        }
        return Ok(entries);
    }
    for j in 0..size {
        let line = c.line("a column line")?;
        // "col j : locations a to b"
        let words: Vec<&str> = line.split_whitespace().collect();
        let parsed = (words.len() == 7 && words[0] == "col" && words[3] == "locations")
            .then(|| {
                Some((
                    words[1].parse::<usize>().ok()?,
                    words[4].parse::<i64>().ok()?,
                    words[6].parse::<i64>().ok()?,
                ))
            })
            .flatten();
        let Some((column, first, last)) = parsed else {
            return Err(bad(line));
        };
        if column != j {
            return Err(bad(line));
        }
        for _ in first..=last {
            let line = c.line("an entry line")?;
            let (i, value) = line.split_once(':').ok_or_else(|| bad(line))?;
            let i: usize = i.trim().parse().map_err(|_| bad(line))?;
            let x: f64 = value.trim().parse().map_err(|_| bad(line))?;
            entries.push(if csr { (j, i, x) } else { (i, j, x) });
        }
    }
    Ok(entries)
}

/// Writes a problem in the `.dat` format with W in the given storage (`dense`, `sparse_block`
/// or `csparse`: CSC with 17 significant digits, which Siconos' reader takes).
pub fn write(problem: &RawProblem, storage: &str) -> String {
    use std::fmt::Write;
    let d = problem.dimension;
    let size = problem.w.size();
    let contacts = problem.mu.len();
    let mut out = format!("{d}\n{contacts}\n");
    let mut entries: Vec<(usize, usize, f64)> = problem.w.entries().collect();
    match storage {
        "dense" => {
            let _ = write!(out, "0\n{size}\n{size}\n{size}\t{size}\n");
            let mut dense = vec![0.0; size * size];
            for (i, j, x) in entries {
                dense[i + j * size] = x;
            }
            for x in dense {
                let _ = writeln!(out, "{x:e}");
            }
        }
        "sparse_block" => {
            let blocks = problem.w.stored_blocks();
            let _ = write!(out, "1\n{size}\n{size}\n{blocks}\n{contacts}\n{contacts}\n");
            let ends: Vec<String> = (1..=contacts).map(|a| (a * d).to_string()).collect();
            let _ = writeln!(out, "{}\n{}", ends.join(" "), ends.join(" "));
            let _ = writeln!(out, "{}\n{blocks}", contacts + 1);
            let mut starts = vec![0];
            let mut columns = Vec::new();
            for a in 0..contacts {
                columns.extend(problem.w.row(a).map(|(b, _)| b.to_string()));
                starts.push(columns.len());
            }
            let starts: Vec<String> = starts.iter().map(usize::to_string).collect();
            let _ = writeln!(out, "{}\n{}", starts.join(" "), columns.join(" "));
            let mut number = 0;
            for a in 0..contacts {
                for (_, block) in problem.w.row(a) {
                    let _ = writeln!(out, "{number}");
                    number += 1;
                    for k in 0..d * d {
                        // Column-major.
                        let _ = writeln!(out, "{:e}", block[(k % d) * d + k / d]);
                    }
                }
            }
        }
        _ => {
            entries.sort_by_key(|&(i, j, _)| (j, i));
            let _ = write!(
                out,
                "2\n{size}\n{size}\n2\nCSparse written by signorini\n{size}-by-{size}, nzmax: {n} nnz: {n}, 1-norm: 0\n",
                n = entries.len()
            );
            let mut k = 0;
            for j in 0..size {
                let first = k;
                while k < entries.len() && entries[k].1 == j {
                    k += 1;
                }
                let _ = writeln!(out, "    col {j} : locations {first} to {}", k as i64 - 1);
                for &(i, _, x) in &entries[first..k] {
                    let _ = writeln!(out, "      {i} : {x:e}");
                }
            }
        }
    }
    for x in &problem.q {
        let _ = writeln!(out, "{x:e}");
    }
    for x in &problem.mu {
        let _ = writeln!(out, "{x:e}");
    }
    out
}
