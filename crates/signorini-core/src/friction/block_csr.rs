//! The Delassus operator of a friction problem as a square block-sparse matrix: block compressed
//! sparse rows (block CSR) with d×d blocks, one block row and one block column per contact
//! (d = 3: `(n, t1, t2)`; d = 2: `(n, t)`). Only the blocks two contacts share (through a body
//! they both touch) are stored, so a problem of thousands of contacts costs memory and time per
//! product in its number of nonzero blocks, never the square of its contacts.

use thiserror::Error;

/// A square block-sparse matrix of `blocks × blocks` blocks of `dim × dim` entries each.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockCsr {
    dim: usize,
    blocks: usize,
    /// Block row `a` holds the stored blocks `row_start[a]..row_start[a + 1]`.
    row_start: Vec<usize>,
    /// Block column of each stored block, increasing within a block row.
    column: Vec<usize>,
    /// The stored blocks, `dim²` entries each, row-major inside a block.
    values: Vec<f64>,
    /// Index in the stored blocks of each diagonal block (`None`: a zero diagonal block).
    diagonal: Vec<Option<usize>>,
}

/// Why a block-sparse matrix could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum BlockCsrError {
    /// The block size is not 2 or 3.
    #[error("block size {dim} is not 2 or 3")]
    BlockSize {
        /// Block size given.
        dim: usize,
    },
    /// The matrix size is not a whole number of blocks.
    #[error("a {rows}×{columns} matrix is not made of square {dim}×{dim} blocks on its diagonal")]
    Shape {
        /// Rows.
        rows: usize,
        /// Columns.
        columns: usize,
        /// Block size.
        dim: usize,
    },
    /// An entry lies outside the matrix.
    #[error("entry ({row}, {column}) lies outside the {size}×{size} matrix")]
    OutOfRange {
        /// Row of the entry.
        row: usize,
        /// Column of the entry.
        column: usize,
        /// Size of the matrix.
        size: usize,
    },
    /// An entry is not finite.
    #[error("entry ({row}, {column}) is {value}: entries must be finite")]
    NotFinite {
        /// Row of the entry.
        row: usize,
        /// Column of the entry.
        column: usize,
        /// The value.
        value: f64,
    },
}

impl BlockCsr {
    /// Builds the matrix of size `size` (= `dim` × contacts) from entries `(row, column, value)`
    /// in any order; entries given twice are summed (the triplet convention of CSparse). Blocks
    /// whose entries are all zero are not stored.
    pub fn from_triplets(
        dim: usize,
        size: usize,
        entries: impl IntoIterator<Item = (usize, usize, f64)>,
    ) -> Result<Self, BlockCsrError> {
        if !(dim == 2 || dim == 3) {
            return Err(BlockCsrError::BlockSize { dim });
        }
        if !size.is_multiple_of(dim) {
            return Err(BlockCsrError::Shape {
                rows: size,
                columns: size,
                dim,
            });
        }
        let blocks = size / dim;
        // Collect per block row a list of (block column, offset in block, value).
        let mut per_row: Vec<Vec<(usize, usize, f64)>> = vec![Vec::new(); blocks];
        for (row, column, value) in entries {
            if row >= size || column >= size {
                return Err(BlockCsrError::OutOfRange { row, column, size });
            }
            if !value.is_finite() {
                return Err(BlockCsrError::NotFinite { row, column, value });
            }
            per_row[row / dim].push((column / dim, (row % dim) * dim + column % dim, value));
        }
        let mut row_start = Vec::with_capacity(blocks + 1);
        let mut column = Vec::new();
        let mut values = Vec::new();
        let mut diagonal = vec![None; blocks];
        row_start.push(0);
        for (a, mut entries) in per_row.into_iter().enumerate() {
            entries.sort_by_key(|&(b, _, _)| b);
            let mut k = 0;
            while k < entries.len() {
                let b = entries[k].0;
                let mut block = vec![0.0; dim * dim];
                while k < entries.len() && entries[k].0 == b {
                    block[entries[k].1] += entries[k].2;
                    k += 1;
                }
                if block.iter().any(|&x| x != 0.0) {
                    if a == b {
                        diagonal[a] = Some(column.len());
                    }
                    column.push(b);
                    values.extend_from_slice(&block);
                }
            }
            row_start.push(column.len());
        }
        Ok(Self {
            dim,
            blocks,
            row_start,
            column,
            values,
            diagonal,
        })
    }

    /// Builds the matrix from a dense row-major `size × size` array (zero blocks not stored).
    pub fn from_dense_row_major(dim: usize, size: usize, w: &[f64]) -> Result<Self, BlockCsrError> {
        if w.len() != size * size {
            return Err(BlockCsrError::Shape {
                rows: size,
                columns: w.len().checked_div(size).unwrap_or(0),
                dim,
            });
        }
        Self::from_triplets(
            dim,
            size,
            w.iter()
                .enumerate()
                .filter(|(_, x)| **x != 0.0)
                .map(|(k, &x)| (k / size, k % size, x)),
        )
    }

    /// Block size d.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Number of block rows (contacts).
    pub fn blocks(&self) -> usize {
        self.blocks
    }

    /// Size of the matrix, d × contacts.
    pub fn size(&self) -> usize {
        self.dim * self.blocks
    }

    /// Number of stored blocks.
    pub fn stored_blocks(&self) -> usize {
        self.column.len()
    }

    /// The stored blocks of block row `a`: `(block column, row-major d×d entries)`.
    pub fn row(&self, a: usize) -> impl Iterator<Item = (usize, &[f64])> {
        let d2 = self.dim * self.dim;
        (self.row_start[a]..self.row_start[a + 1])
            .map(move |k| (self.column[k], &self.values[k * d2..(k + 1) * d2]))
    }

    /// The stored diagonal block of contact `a` (row-major), if it is stored.
    pub fn stored_diagonal_block(&self, a: usize) -> Option<&[f64]> {
        let d2 = self.dim * self.dim;
        self.diagonal[a].map(|k| &self.values[k * d2..(k + 1) * d2])
    }

    /// Every stored entry `(row, column, value)`, block row by block row.
    pub fn entries(&self) -> impl Iterator<Item = (usize, usize, f64)> + '_ {
        let d = self.dim;
        (0..self.blocks).flat_map(move |a| {
            self.row(a).flat_map(move |(b, block)| {
                block
                    .iter()
                    .enumerate()
                    .map(move |(k, &x)| (a * d + k / d, b * d + k % d, x))
            })
        })
    }

    /// `(W x)` restricted to block row `a`, added to `out` (length d).
    pub fn add_row_product(&self, a: usize, x: &[f64], out: &mut [f64]) {
        let d = self.dim;
        if d == 3 {
            // The 3×3 case unrolled (it is the inner loop of every FC3D solver): the same
            // products summed in the same order as the general loop below, so the same bits.
            let range = self.row_start[a]..self.row_start[a + 1];
            let (blocks, _) = self.values[9 * range.start..9 * range.end].as_chunks::<9>();
            let [mut o0, mut o1, mut o2] = [out[0], out[1], out[2]];
            for (&b, w) in self.column[range].iter().zip(blocks) {
                let xb = &x[3 * b..3 * b + 3];
                let (x0, x1, x2) = (xb[0], xb[1], xb[2]);
                o0 += w[0] * x0 + w[1] * x1 + w[2] * x2;
                o1 += w[3] * x0 + w[4] * x1 + w[5] * x2;
                o2 += w[6] * x0 + w[7] * x1 + w[8] * x2;
            }
            out[..3].copy_from_slice(&[o0, o1, o2]);
            return;
        }
        for (b, block) in self.row(a) {
            let xb = &x[b * d..(b + 1) * d];
            for (i, o) in out.iter_mut().enumerate().take(d) {
                *o += block[i * d..(i + 1) * d]
                    .iter()
                    .zip(xb)
                    .map(|(w, x)| w * x)
                    .sum::<f64>();
            }
        }
    }

    /// `W + σ I` (the proximal regularisation of the Delassus operator).
    pub fn with_diagonal_shift(&self, sigma: f64) -> Result<Self, BlockCsrError> {
        Self::from_triplets(
            self.dim,
            self.size(),
            self.entries()
                .chain((0..self.size()).map(|i| (i, i, sigma))),
        )
    }

    /// `y = W x + c` (c of the matrix's size).
    pub fn affine(&self, x: &[f64], c: &[f64]) -> Vec<f64> {
        let d = self.dim;
        let mut y = c.to_vec();
        for a in 0..self.blocks {
            self.add_row_product(a, x, &mut y[a * d..(a + 1) * d]);
        }
        y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triplets_sum_duplicates_and_skip_zero_blocks() {
        // 6×6, blocks of 3: entries in blocks (0,0), (0,1) and (1,1); (1,0) only gets a zero.
        let w = BlockCsr::from_triplets(
            3,
            6,
            [
                (0, 0, 1.0),
                (0, 0, 1.5),
                (2, 4, -1.0),
                (4, 4, 3.0),
                (3, 1, 0.0),
            ],
        )
        .unwrap();
        assert_eq!(w.stored_blocks(), 3);
        assert_eq!(w.stored_diagonal_block(0).unwrap()[0], 2.5);
        assert_eq!(w.stored_diagonal_block(1).unwrap()[4], 3.0);
        let y = w.affine(&[1.0, 0.0, 0.0, 0.0, 2.0, 0.0], &[0.0; 6]);
        assert_eq!(y, vec![2.5, 0.0, -2.0, 0.0, 6.0, 0.0]);
        let mut back: Vec<_> = w.entries().filter(|e| e.2 != 0.0).collect();
        back.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert_eq!(back, vec![(0, 0, 2.5), (2, 4, -1.0), (4, 4, 3.0)]);
    }

    #[test]
    fn bad_entries_are_refused() {
        assert_eq!(
            BlockCsr::from_triplets(3, 6, [(6, 0, 1.0)]),
            Err(BlockCsrError::OutOfRange {
                row: 6,
                column: 0,
                size: 6
            })
        );
        assert!(matches!(
            BlockCsr::from_triplets(3, 7, []),
            Err(BlockCsrError::Shape { .. })
        ));
        assert!(matches!(
            BlockCsr::from_triplets(3, 3, [(0, 0, f64::NAN)]),
            Err(BlockCsrError::NotFinite { .. })
        ));
    }
}
