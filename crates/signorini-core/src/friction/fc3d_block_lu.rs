//! A block sparse LU of the semismooth Newton matrix `J = (I − G) + ρ G W` of
//! [`super::fc3d_newton`], on W's 3×3 blocks, with its pattern computed once.
//!
//! J has W's block pattern (plus the diagonal blocks), and that pattern does not change from
//! one Newton iteration to the next, nor between the proximal point method's inner solves
//! (`W + α I`). So the pattern is ordered and its fill computed once, symbolically, and each
//! factorisation only runs the arithmetic:
//!
//! - **Ordering:** approximate minimum degree on the graph of W's blocks made symmetric
//!   (P. R. Amestoy, T. A. Davis, I. S. Duff, *An approximate minimum degree ordering
//!   algorithm*, SIAM J. Matrix Anal. Appl. 17(4):886–905, 1996, doi:10.1137/S0895479894278952;
//!   faer's implementation), one node per contact.
//! - **Fill:** the pattern of the factors by the elimination tree (J. W. H. Liu, *The role of
//!   elimination trees in sparse factorization*, SIAM J. Matrix Anal. Appl. 11(1):134–172, 1990,
//!   doi:10.1137/0611010): the pattern of block column k of L is that of column k of the permuted
//!   J below the diagonal, merged with the patterns of its children's columns. The pattern is
//!   symmetric, so block row k of U has the columns of block column k of L.
//! - **Elimination:** right-looking block LU, `L` with identity diagonal blocks, the pivot of
//!   each step a 3×3 block inverted by its adjugate; no pivoting between blocks. That is exact
//!   arithmetic on the symmetric pattern, but it is stable only when the pivot blocks stay
//!   well conditioned, which J does not promise (it is unsymmetric, and W is rank-deficient on
//!   rigid sets). Two guards make it safe: a pivot block that [`super::block3::inverse`] finds
//!   singular stops the factorisation, and the
//!   direction's residual `‖J d − b‖ / ‖b‖` is measured after the solve (one product by W). The
//!   caller takes the direction as an inexact Newton direction when that residual is within the
//!   forcing term it would ask of GMRES, and falls back to the sparse LU with partial pivoting
//!   ([`super::fc3d_sparse_lu`]) otherwise.
//!
//! **Work charged** (products by a 3×3 block of W, 18 flops, the unit of
//! [`super::fc3d_newton`]'s budget), exact and known before any arithmetic: assembling J, 3
//! per stored block of W (`G_a W_ab`); step k of the elimination, with `c_k` blocks below its
//! pivot, one inverse (3 units) and `c_k` multipliers and `c_k²` updates (3×3 by 3×3 products, 3
//! units each); the two block triangular solves, one unit per stored block of L and U; the
//! residual check, one pass over W.

use super::block_csr::BlockCsr;
use super::block3::{self, Block, inverse, product, subtract_apply, subtract_product};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::SymbolicSparseColMatRef;
use faer::sparse::linalg::amd;

/// The ordered, filled pattern of J for the Delassus operators of one block pattern, and the
/// work of a factorisation with it.
pub(crate) struct BlockLu {
    /// `order[k]`: the contact eliminated k-th; `position[a]`: when contact a is eliminated.
    order: Vec<usize>,
    position: Vec<usize>,
    /// Block row k of the filled pattern (in elimination order) has the columns
    /// `columns[row_start[k]..row_start[k + 1]]`, increasing, its diagonal among them.
    row_start: Vec<usize>,
    columns: Vec<usize>,
    /// Where the diagonal block of each row is in `columns`.
    diagonal: Vec<usize>,
    /// For the stored position of (i, j), the stored position of (j, i).
    mirror: Vec<usize>,
    /// The work of one factorisation and one solve with its residual check (module
    /// documentation), assembly included.
    work: usize,
}

/// Why the block LU gave no direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum BlockLuFailure {
    /// A pivot block is (numerically) singular.
    Pivot,
    /// W has a block outside the pattern ([`BlockLu::fits`]).
    Pattern,
}

/// Up to this many contacts the block LU keeps their natural order.
const SMALL: usize = 8;

/// Merges the increasing list `from` into the increasing list `into`, leaving out `except`.
fn merge_into(into: &mut Vec<usize>, from: &[usize], except: usize) {
    let mut merged = Vec::with_capacity(into.len() + from.len());
    let (mut i, mut j) = (0, 0);
    while i < into.len() || j < from.len() {
        let next = match (into.get(i), from.get(j)) {
            (Some(&a), Some(&b)) if a == b => {
                i += 1;
                j += 1;
                a
            }
            (Some(&a), Some(&b)) if a < b => {
                i += 1;
                a
            }
            (Some(_), Some(&b)) | (None, Some(&b)) => {
                j += 1;
                b
            }
            (Some(&a), None) => {
                i += 1;
                a
            }
            (None, None) => unreachable!("the loop runs while one list has entries"),
        };
        if next != except {
            merged.push(next);
        }
    }
    *into = merged;
}

impl BlockLu {
    /// Orders the block pattern of `w` (every diagonal block included) and computes its fill;
    /// None when the ordering fails (out of memory).
    pub(crate) fn new(w: &BlockCsr) -> Option<Self> {
        let m = w.blocks();
        // The symmetric block graph, without the diagonal.
        let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); m];
        for a in 0..m {
            for (b, _) in w.row(a) {
                if a != b {
                    neighbours[a].push(b);
                    neighbours[b].push(a);
                }
            }
        }
        for list in &mut neighbours {
            list.sort_unstable();
            list.dedup();
        }
        let mut col_ptr = Vec::with_capacity(m + 1);
        col_ptr.push(0usize);
        for list in &neighbours {
            col_ptr.push(col_ptr[col_ptr.len() - 1] + list.len());
        }
        let row_idx: Vec<usize> = neighbours.concat();
        let mut order: Vec<usize> = (0..m).collect();
        let mut position: Vec<usize> = (0..m).collect();
        // Up to SMALL contacts the factors are dense or nearly so in any order: the natural
        // one costs nothing (on Siconos' Rover problems of 4–5 contacts the ordering took a
        // tenth of a Newton solve).
        if m > SMALL {
            let pattern = SymbolicSparseColMatRef::new_checked(m, m, &col_ptr, None, &row_idx);
            let mut memory =
                MemBuffer::try_new(amd::order_scratch::<usize>(m, row_idx.len())).ok()?;
            amd::order(
                &mut order,
                &mut position,
                pattern,
                amd::Control::default(),
                MemStack::new(&mut memory),
            )
            .ok()?;
        }
        // Column k of L below the diagonal (elimination order): J's own entries, merged with the
        // patterns of the columns whose parent in the elimination tree is k.
        let mut below: Vec<Vec<usize>> = Vec::with_capacity(m);
        let mut children: Vec<Vec<usize>> = vec![Vec::new(); m];
        for k in 0..m {
            let mut column: Vec<usize> = neighbours[order[k]]
                .iter()
                .map(|&b| position[b])
                .filter(|&i| i > k)
                .collect();
            column.sort_unstable();
            for &child in &children[k] {
                let from = std::mem::take(&mut below[child]);
                merge_into(&mut column, &from, k);
                below[child] = from;
            }
            if let Some(&parent) = column.first() {
                children[parent].push(k);
            }
            below.push(column);
        }
        // Block rows of the symmetric filled pattern: row i has the columns k < i whose column
        // holds i, its diagonal, and the columns of its own column below the diagonal.
        let mut rows: Vec<Vec<usize>> = vec![Vec::new(); m];
        for (k, column) in below.iter().enumerate() {
            for &i in column {
                rows[i].push(k);
            }
        }
        let mut row_start = Vec::with_capacity(m + 1);
        let mut columns = Vec::new();
        let mut diagonal = Vec::with_capacity(m);
        row_start.push(0);
        for (i, row) in rows.iter().enumerate() {
            columns.extend_from_slice(row);
            diagonal.push(columns.len());
            columns.push(i);
            columns.extend_from_slice(&below[i]);
            row_start.push(columns.len());
        }
        let mut mirror = vec![0usize; columns.len()];
        for i in 0..m {
            for p in row_start[i]..row_start[i + 1] {
                let j = columns[p];
                let row = &columns[row_start[j]..row_start[j + 1]];
                // The pattern is symmetric: (j, i) is stored.
                mirror[p] = row_start[j] + row.binary_search(&i).unwrap_or(0);
            }
        }
        let elimination: usize = below.iter().map(|c| 3 + 3 * c.len() * (c.len() + 1)).sum();
        let work = 3 * w.stored_blocks() + elimination + columns.len() + w.stored_blocks();
        Some(Self {
            order,
            position,
            row_start,
            columns,
            diagonal,
            mirror,
            work,
        })
    }

    /// Whether every stored block of `w` has its place in this pattern.
    pub(crate) fn fits(&self, w: &BlockCsr) -> bool {
        w.dim() == 3
            && w.blocks() == self.order.len()
            && (0..w.blocks()).all(|a| {
                let i = self.position[a];
                let row = &self.columns[self.row_start[i]..self.row_start[i + 1]];
                w.row(a)
                    .all(|(b, _)| row.binary_search(&self.position[b]).is_ok())
            })
    }

    /// The work of one factorisation and solve (module documentation), in block products.
    pub(crate) fn work(&self) -> usize {
        self.work
    }

    /// Solves `J d = rhs` for `J = (I − G) + ρ G W` (G row-major 3×3 per contact, `w` of this
    /// pattern: [`BlockLu::fits`]); returns d and its relative residual `‖J d − rhs‖ / ‖rhs‖`.
    pub(crate) fn solve(
        &self,
        w: &BlockCsr,
        gs: &[[f64; 9]],
        rho: &[f64],
        rhs: &[f64],
    ) -> Result<(Vec<f64>, f64), BlockLuFailure> {
        let m = self.order.len();
        let mut values: Vec<Block> = vec![[0.0; 9]; self.columns.len()];
        // Assembly: block (a, b) of J is ρ_a G_a W_ab, plus I − G_a on the diagonal.
        for (a, &i) in self.position.iter().enumerate() {
            let row = &self.columns[self.row_start[i]..self.row_start[i + 1]];
            let g = &gs[a];
            for (b, block) in w.row(a) {
                let at = row
                    .binary_search(&self.position[b])
                    .map_err(|_| BlockLuFailure::Pattern)?;
                let target = &mut values[self.row_start[i] + at];
                for r in 0..3 {
                    for c in 0..3 {
                        target[3 * r + c] = rho[a]
                            * (g[3 * r] * block[c]
                                + g[3 * r + 1] * block[3 + c]
                                + g[3 * r + 2] * block[6 + c]);
                    }
                }
            }
            let target = &mut values[self.diagonal[i]];
            for r in 0..3 {
                for c in 0..3 {
                    target[3 * r + c] += f64::from(r == c) - g[3 * r + c];
                }
            }
        }
        // Right-looking elimination; L's multipliers replace the blocks below the diagonal, the
        // pivots' inverses the diagonal blocks.
        for k in 0..m {
            let pivot = inverse(&values[self.diagonal[k]]).ok_or(BlockLuFailure::Pivot)?;
            values[self.diagonal[k]] = pivot;
            let upper = self.diagonal[k] + 1..self.row_start[k + 1];
            for p in upper.clone() {
                let below = self.mirror[p];
                let multiplier = product(&values[below], &pivot);
                values[below] = multiplier;
                // Row i = columns[p] loses multiplier · (row k right of the diagonal); its
                // pattern holds every such column, in the same increasing order.
                let i = self.columns[p];
                let mut slot = below + 1;
                for q in upper.clone() {
                    let j = self.columns[q];
                    while self.columns[slot] != j {
                        slot += 1;
                    }
                    let source = values[q];
                    subtract_product(&mut values[slot], &multiplier, &source);
                }
                debug_assert!(slot < self.row_start[i + 1]);
            }
        }
        // L y = P b, then U x = y, then d = Pᵀ x.
        let mut x = vec![0.0; 3 * m];
        for (k, &a) in self.order.iter().enumerate() {
            x[3 * k..3 * k + 3].copy_from_slice(&rhs[3 * a..3 * a + 3]);
        }
        for k in 0..m {
            let (done, rest) = x.split_at_mut(3 * k);
            let lower = self.row_start[k]..self.diagonal[k];
            for (&j, block) in self.columns[lower.clone()].iter().zip(&values[lower]) {
                subtract_apply(&mut rest[..3], block, &done[3 * j..3 * j + 3]);
            }
        }
        for k in (0..m).rev() {
            let (head, later) = x.split_at_mut(3 * k + 3);
            let own = &mut head[3 * k..];
            let upper = self.diagonal[k] + 1..self.row_start[k + 1];
            for (&j, block) in self.columns[upper.clone()].iter().zip(&values[upper]) {
                let j = j - k - 1;
                subtract_apply(own, block, &later[3 * j..3 * j + 3]);
            }
            let pivot = &values[self.diagonal[k]];
            let y = [own[0], own[1], own[2]];
            for r in 0..3 {
                own[r] = pivot[3 * r] * y[0] + pivot[3 * r + 1] * y[1] + pivot[3 * r + 2] * y[2];
            }
        }
        let mut d = vec![0.0; 3 * m];
        for (k, &a) in self.order.iter().enumerate() {
            d[3 * a..3 * a + 3].copy_from_slice(&x[3 * k..3 * k + 3]);
        }
        let residual = relative_residual(w, gs, rho, &d, rhs);
        Ok((d, residual))
    }
}

/// `J v = v − G v + ρ G (W v)`, blockwise, for `J = (I − G) + ρ G W` (module documentation):
/// GMRES's product, and the block LU's residual check.
pub(crate) fn newton_product(w: &BlockCsr, gs: &[[f64; 9]], rho: &[f64], v: &[f64]) -> Vec<f64> {
    let wv = w.affine(v, &vec![0.0; v.len()]);
    let mut out = vec![0.0; v.len()];
    for (a, (g, rho)) in gs.iter().zip(rho).enumerate() {
        let k = 3 * a;
        let gv = block3::apply(g, &v[k..k + 3]);
        let gwv = block3::apply(g, &wv[k..k + 3]);
        for i in 0..3 {
            out[k + i] = v[k + i] - gv[i] + rho * gwv[i];
        }
    }
    out
}

/// `‖J d − rhs‖ / ‖rhs‖` for `J = (I − G) + ρ G W` (0 when rhs = 0 and J d = 0; infinite when d
/// has an entry that is not a number).
fn relative_residual(w: &BlockCsr, gs: &[[f64; 9]], rho: &[f64], d: &[f64], rhs: &[f64]) -> f64 {
    let jd = newton_product(w, gs, rho, d);
    let residual = jd
        .iter()
        .zip(rhs)
        .map(|(x, b)| (x - b) * (x - b))
        .sum::<f64>()
        .sqrt();
    let scale = rhs.iter().map(|x| x * x).sum::<f64>().sqrt();
    if !residual.is_finite() {
        f64::INFINITY
    } else if scale > 0.0 {
        residual / scale
    } else if residual == 0.0 {
        0.0
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::friction::fc3d_sparse_lu::tests::mixed_newton_system;

    /// The block LU's direction is the dense LU's (partial pivoting) on a system mixing
    /// take-off, stick and slide, with a contact whose own block W lacks; its residual is at
    /// round-off; the pattern takes W + α I (which has that block).
    #[test]
    fn block_lu_solves_the_newton_system_as_the_dense_lu_does() {
        let system = mixed_newton_system();
        let lu = BlockLu::new(&system.w).unwrap();
        assert!(lu.fits(&system.w));
        assert!(lu.fits(&system.w.with_diagonal_shift(0.5).unwrap()));
        let (d, residual) = lu
            .solve(&system.w, &system.gs, &system.rho, &system.rhs)
            .unwrap();
        assert!(residual <= 1e-14, "{residual}");
        system.assert_dense_direction(&d);
    }

    /// A chain (each contact coupled to its neighbours) has no fill: the factors keep W's
    /// pattern, and a factorisation costs, step by step, one inverse, a multiplier and an
    /// update per block beyond the pivot (module documentation).
    #[test]
    fn a_chain_of_contacts_factors_without_fill() {
        let m: usize = 30;
        let mut entries = Vec::new();
        for a in 0..m {
            for b in a.saturating_sub(1)..(a + 2).min(m) {
                for i in 0..3 {
                    entries.push((3 * a + i, 3 * b + i, if a == b { 4.0 } else { 1.0 }));
                }
            }
        }
        let w = BlockCsr::from_triplets(3, 3 * m, entries).unwrap();
        let lu = BlockLu::new(&w).unwrap();
        assert_eq!(lu.columns.len(), w.stored_blocks());
        // Eliminating a chain from its ends leaves one block beyond each pivot but the last:
        // Σ (3 + 3 c (c + 1)) = 9 (m − 1) + 3.
        let elimination = 9 * (m - 1) + 3;
        assert_eq!(
            lu.work(),
            3 * w.stored_blocks() + elimination + 2 * w.stored_blocks()
        );
        // Every contact sticking: J = ρ W, symmetric positive definite here; d = W⁻¹ b / ρ.
        let identity = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let gs = vec![identity; m];
        let rho = vec![0.5; m];
        let d_expected: Vec<f64> = (0..3 * m).map(|k| (k % 7) as f64 - 3.0).collect();
        let rhs: Vec<f64> = w
            .affine(&d_expected, &vec![0.0; 3 * m])
            .iter()
            .map(|x| 0.5 * x)
            .collect();
        let (d, residual) = lu.solve(&w, &gs, &rho, &rhs).unwrap();
        assert!(residual <= 1e-15, "{residual}");
        for (x, y) in d.iter().zip(&d_expected) {
            assert!((x - y).abs() <= 1e-13, "{x} against {y}");
        }
    }

    /// A singular pivot block stops the factorisation (the caller pivots instead), and a W
    /// with a block outside the pattern is refused.
    #[test]
    fn a_singular_pivot_or_a_foreign_block_is_refused() {
        let w = BlockCsr::from_triplets(3, 6, vec![(0, 0, 1.0), (4, 4, 1.0)]).unwrap();
        let lu = BlockLu::new(&w).unwrap();
        let identity = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        // All stick: J = ρ W, whose diagonal blocks have rank 1.
        let outcome = lu.solve(&w, &[identity; 2], &[1.0; 2], &[1.0; 6]);
        assert_eq!(outcome.err(), Some(BlockLuFailure::Pivot));
        let coupled = BlockCsr::from_triplets(3, 6, vec![(0, 3, 1.0), (3, 0, 1.0)]).unwrap();
        assert!(!lu.fits(&coupled));
        let outcome = lu.solve(&coupled, &[[0.0; 9]; 2], &[1.0; 2], &[1.0; 6]);
        assert_eq!(outcome.err(), Some(BlockLuFailure::Pattern));
    }
}
