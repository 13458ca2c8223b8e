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
        let mut items = Vec::new();
        for (row, column, value) in entries {
            if row >= size || column >= size {
                return Err(BlockCsrError::OutOfRange { row, column, size });
            }
            if !value.is_finite() {
                return Err(BlockCsrError::NotFinite { row, column, value });
            }
            items.push((
                row / dim,
                column / dim,
                (row % dim) * dim + column % dim,
                value,
            ));
        }
        Ok(Self::assemble(
            dim,
            blocks,
            &items,
            |&(a, b, _, _)| (a, b),
            |block, &(_, _, k, value)| block[k] += value,
        ))
    }

    /// Builds the matrix of `blocks` × `blocks` 3×3 blocks from blocks `(block row, block
    /// column, row-major entries)` in any order; blocks given twice are summed entry by entry,
    /// in the order given, so the matrix is the one [`Self::from_triplets`] builds from the
    /// blocks' entries listed in the same order, to the bit. Blocks whose entries are all zero
    /// are not stored. (A Delassus operator is a sum of 3×3 products per body: given as blocks,
    /// it is sorted in ninths of the entries.)
    pub fn from_blocks(
        blocks: usize,
        entries: &[(usize, usize, [f64; 9])],
    ) -> Result<Self, BlockCsrError> {
        let size = 3 * blocks;
        for &(a, b, ref values) in entries {
            if a >= blocks || b >= blocks {
                return Err(BlockCsrError::OutOfRange {
                    row: 3 * a,
                    column: 3 * b,
                    size,
                });
            }
            if let Some(k) = values.iter().position(|x| !x.is_finite()) {
                return Err(BlockCsrError::NotFinite {
                    row: 3 * a + k / 3,
                    column: 3 * b + k % 3,
                    value: values[k],
                });
            }
        }
        Ok(Self::assemble(
            3,
            blocks,
            entries,
            |&(a, b, _)| (a, b),
            |block, (_, _, values)| {
                for (x, v) in block.iter_mut().zip(values) {
                    *x += v;
                }
            },
        ))
    }

    /// The matrix whose block (a, b) is the sum, by `add` from zeros in the items' order, of
    /// the items whose `key` is (a, b): the items are put in block rows by a stable counting
    /// sort, then in block columns by a stable sort within each row.
    fn assemble<T>(
        dim: usize,
        blocks: usize,
        items: &[T],
        key: impl Fn(&T) -> (usize, usize),
        add: impl Fn(&mut [f64], &T),
    ) -> Self {
        let mut row_items = vec![0usize; blocks + 1];
        for item in items {
            row_items[key(item).0 + 1] += 1;
        }
        for a in 0..blocks {
            row_items[a + 1] += row_items[a];
        }
        let mut order = vec![0usize; items.len()];
        let mut next = row_items.clone();
        for (k, item) in items.iter().enumerate() {
            let a = key(item).0;
            order[next[a]] = k;
            next[a] += 1;
        }
        let mut row_start = Vec::with_capacity(blocks + 1);
        let mut column = Vec::new();
        let mut values = Vec::new();
        let mut diagonal = vec![None; blocks];
        row_start.push(0);
        let d2 = dim * dim;
        for a in 0..blocks {
            let row = &mut order[row_items[a]..row_items[a + 1]];
            row.sort_by_key(|&k| key(&items[k]).1);
            let mut k = 0;
            while k < row.len() {
                let b = key(&items[row[k]]).1;
                let mut block = [0.0; 9];
                while k < row.len() && key(&items[row[k]]).1 == b {
                    add(&mut block[..d2], &items[row[k]]);
                    k += 1;
                }
                if block.iter().any(|&x| x != 0.0) {
                    if a == b {
                        diagonal[a] = Some(column.len());
                    }
                    column.push(b);
                    values.extend_from_slice(&block[..d2]);
                }
            }
            row_start.push(column.len());
        }
        Self {
            dim,
            blocks,
            row_start,
            column,
            values,
            diagonal,
        }
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
    fn blocks_build_the_matrix_of_their_entries_to_the_bit() {
        // Blocks given twice (the diagonal block of a contact between two bodies, one product
        // per body), out of order, with entries whose sum depends on the order of the additions.
        let a = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9];
        let b = [1e16, -1.0, 0.0, 3.0, 1.0 / 3.0, 0.0, 0.0, 0.0, 2.5];
        let c = [-1e16, 1.0, 0.0, -3.0, 2.0 / 3.0, 0.0, 0.0, 0.0, 0.5];
        let zero = [0.0; 9];
        let blocks = [
            (1, 1, a),
            (0, 0, b),
            (0, 1, a),
            (0, 0, c),
            (1, 0, zero),
            (0, 0, a),
        ];
        let triplets: Vec<_> = blocks
            .iter()
            .flat_map(|&(r, k, v)| (0..9).map(move |e| (3 * r + e / 3, 3 * k + e % 3, v[e])))
            .collect();
        let w = BlockCsr::from_blocks(2, &blocks).unwrap();
        assert_eq!(w, BlockCsr::from_triplets(3, 6, triplets).unwrap());
        // (1e16 − 1e16) + 0.1 = 0.1 in that order; any other order loses it.
        assert_eq!(w.stored_diagonal_block(0).unwrap()[0], 0.1);
        assert_eq!(w.stored_blocks(), 3);
        assert_eq!(
            BlockCsr::from_blocks(2, &[(0, 2, a)]),
            Err(BlockCsrError::OutOfRange {
                row: 0,
                column: 6,
                size: 6
            })
        );
        let mut bad = a;
        bad[5] = f64::INFINITY;
        assert_eq!(
            BlockCsr::from_blocks(2, &[(1, 0, bad)]),
            Err(BlockCsrError::NotFinite {
                row: 4,
                column: 2,
                value: f64::INFINITY
            })
        );
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
