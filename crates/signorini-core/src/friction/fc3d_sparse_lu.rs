//! A sparse direct solve of the semismooth Newton system `J d = −Φ` of [`super::fc3d_newton`],
//! `J = (I − G) + ρ G W` with G block diagonal (3×3 per contact) and W the block-sparse Delassus
//! operator: J has W's block pattern (plus the diagonal blocks), is unsymmetric, and is never
//! formed densely.
//!
//! J is assembled row by row from W's stored blocks (block row a of J is `(I − G_a) δ_ab +
//! ρ_a G_a W_ab` over the blocks W_ab stored in row a; every entry of a stored block is kept,
//! zeros included, so the pattern is W's and does not change from one Newton iteration to the
//! next). Its compressed rows are the compressed columns of Jᵀ, which is factored as
//! `P Jᵀ Q = L U` by faer's left-looking simplicial LU with partial pivoting (J. R. Gilbert,
//! T. Peierls, *Sparse partial pivoting in time proportional to arithmetic operations*, SIAM J.
//! Sci. Stat. Comput. 9(5):862–874, 1988, doi:10.1137/0909058), the columns ordered once per
//! Newton solve by COLAMD (T. A. Davis, J. R. Gilbert, S. I. Larimore, E. G. Ng, *A column
//! approximate minimum degree ordering algorithm*, ACM Trans. Math. Softw. 30(3):353–376, 2004,
//! doi:10.1145/1024074.1024079); then `J d = −Φ` is solved as `(Jᵀ)ᵀ d = −Φ`.
//!
//! **The work it is charged** (in products by a 3×3 block of W, 18 flops, the unit of
//! [`super::fc3d_newton`]'s budget): assembling J costs 3 block products per stored block of W
//! (`G_a W_ab` is 27 multiply-adds); the factorisation costs the flops of its elimination,
//! counted exactly from the factors after the fact (the multiply-adds of each column update and
//! the divisions by the pivot), and the two triangular solves theirs, over 18:
//!
//! ```text
//! Σ_j Σ_{k ∈ U(:, j), k ≠ j} 2 (|L(:, k)| − 1)  +  Σ_j (|L(:, j)| − 1)  +  2 (nnz L + nnz U)
//! ```
//!
//! The ordering and the symbolic work (the depth-first searches of Gilbert and Peierls'
//! algorithm, proportional to the flops) are not charged.

use super::block_csr::BlockCsr;
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::perm::PermRef;
use faer::sparse::linalg::colamd;
use faer::sparse::linalg::lu::simplicial::{
    SimplicialLu, factorize_simplicial_numeric_lu, factorize_simplicial_numeric_lu_scratch,
    solve_transpose_in_place_scratch,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par};

/// The pattern of J (compressed rows, which are the compressed columns of Jᵀ), built from W's
/// block pattern with every diagonal block, and the COLAMD ordering of Jᵀ's columns. It serves
/// every W of the same pattern or a sub-pattern (the proximal point method's `W + α I`).
pub(crate) struct SparseNewton {
    n: usize,
    row_ptr: Vec<usize>,
    col_idx: Vec<usize>,
    /// The block columns of each block row, increasing.
    blocks: Vec<Vec<usize>>,
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
}

/// Why the sparse LU gave no direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum SparseLuFailure {
    /// faer's ordering or factorisation refused (out of memory, structurally singular).
    Factorisation,
    /// The direction has an entry that is not a number (a numerically singular J).
    NotFinite,
    /// W has a block outside the pattern ([`SparseNewton::fits`]).
    Pattern,
}

impl SparseNewton {
    /// The pattern of J for Delassus operators of `w`'s pattern (3×3 blocks) and its ordering.
    pub(crate) fn new(w: &BlockCsr) -> Result<Self, SparseLuFailure> {
        let m = w.blocks();
        let n = 3 * m;
        let blocks: Vec<Vec<usize>> = (0..m)
            .map(|a| {
                let mut row: Vec<usize> = w.row(a).map(|(b, _)| b).collect();
                if let Err(k) = row.binary_search(&a) {
                    row.insert(k, a);
                }
                row
            })
            .collect();
        let mut row_ptr = Vec::with_capacity(n + 1);
        let mut col_idx = Vec::new();
        row_ptr.push(0);
        for row in &blocks {
            for _ in 0..3 {
                for &b in row {
                    col_idx.extend([3 * b, 3 * b + 1, 3 * b + 2]);
                }
                row_ptr.push(col_idx.len());
            }
        }
        let mut perm = vec![0usize; n];
        let mut perm_inv = vec![0usize; n];
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, &row_ptr, None, &col_idx);
        let mut memory = MemBuffer::try_new(colamd::order_scratch::<usize>(n, n, col_idx.len()))
            .map_err(|_| SparseLuFailure::Factorisation)?;
        colamd::order(
            &mut perm,
            &mut perm_inv,
            pattern,
            colamd::Control::default(),
            MemStack::new(&mut memory),
        )
        .map_err(|_| SparseLuFailure::Factorisation)?;
        Ok(Self {
            n,
            row_ptr,
            col_idx,
            blocks,
            perm,
            perm_inv,
        })
    }

    /// Whether every stored block of `w` has its place in this pattern.
    pub(crate) fn fits(&self, w: &BlockCsr) -> bool {
        w.size() == self.n
            && w.dim() == 3
            && (0..w.blocks()).all(|a| {
                w.row(a)
                    .all(|(b, _)| self.blocks[a].binary_search(&b).is_ok())
            })
    }

    /// Solves `J d = rhs` for `J = (I − G) + ρ G W` (G row-major 3×3 per contact, `w` of this
    /// pattern: [`SparseNewton::fits`]), adding the work (module documentation) to `work` and
    /// returning the factorisation's share of it with the direction.
    pub(crate) fn solve(
        &self,
        w: &BlockCsr,
        gs: &[[f64; 9]],
        rho: &[f64],
        rhs: &[f64],
        work: &mut usize,
    ) -> Result<(Vec<f64>, usize), SparseLuFailure> {
        let n = self.n;
        let mut values = vec![0.0; self.col_idx.len()];
        for (a, row) in self.blocks.iter().enumerate() {
            let g = &gs[a];
            let width = 3 * row.len();
            let first = self.row_ptr[3 * a];
            let mut slot = 0;
            for (b, block) in w.row(a) {
                while slot < row.len() && row[slot] != b {
                    slot += 1;
                }
                if slot == row.len() {
                    return Err(SparseLuFailure::Pattern);
                }
                for i in 0..3 {
                    let at = first + i * width + 3 * slot;
                    for k in 0..3 {
                        let gw = g[3 * i] * block[k]
                            + g[3 * i + 1] * block[3 + k]
                            + g[3 * i + 2] * block[6 + k];
                        values[at + k] = rho[a] * gw;
                    }
                }
            }
            // Every row of the pattern has its diagonal block (`new`).
            let diagonal = row.binary_search(&a).unwrap_or_else(|k| k);
            for i in 0..3 {
                let at = first + i * width + 3 * diagonal;
                for k in 0..3 {
                    values[at + k] += f64::from(i == k) - g[3 * i + k];
                }
            }
        }
        *work += 3 * w.stored_blocks();
        let transpose = SparseColMatRef::new(
            SymbolicSparseColMatRef::new_checked(n, n, &self.row_ptr, None, &self.col_idx),
            &values,
        );
        let col_perm = PermRef::new_checked(&self.perm, &self.perm_inv, n);
        let mut row_perm = vec![0usize; n];
        let mut row_perm_inv = vec![0usize; n];
        let mut lu = SimplicialLu::<usize, f64>::new();
        let scratch = StackReq::or(
            factorize_simplicial_numeric_lu_scratch::<usize, f64>(n, n),
            solve_transpose_in_place_scratch::<usize, f64>(n, 1, Par::Seq),
        );
        let mut memory = MemBuffer::try_new(scratch).map_err(|_| SparseLuFailure::Factorisation)?;
        let stack = MemStack::new(&mut memory);
        factorize_simplicial_numeric_lu(
            &mut row_perm,
            &mut row_perm_inv,
            &mut lu,
            transpose,
            col_perm,
            stack,
        )
        .map_err(|_| SparseLuFailure::Factorisation)?;
        let factorisation = factorisation_work(&lu);
        *work += factorisation;
        let mut d = rhs.to_vec();
        lu.solve_transpose_in_place_with_conj(
            PermRef::new_checked(&row_perm, &row_perm_inv, n),
            col_perm,
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut d, n, 1),
            Par::Seq,
            stack,
        );
        if d.iter().all(|x| x.is_finite()) {
            Ok((d, factorisation))
        } else {
            Err(SparseLuFailure::NotFinite)
        }
    }
}

/// The work of a factorisation and of one solve with it (module documentation), in products by
/// a 3×3 block (18 flops).
fn factorisation_work(lu: &SimplicialLu<usize, f64>) -> usize {
    let l = lu.l_factor_unsorted();
    let u = lu.u_factor_unsorted();
    let l_len: Vec<usize> = (0..l.ncols())
        .map(|k| l.row_idx_of_col_raw(k).len())
        .collect();
    let mut flops = 0usize;
    for j in 0..u.ncols() {
        for &k in u.row_idx_of_col_raw(j) {
            if k != j {
                flops += 2 * l_len[k].saturating_sub(1);
            }
        }
        flops += l_len[j].saturating_sub(1);
    }
    let solves = 2 * (l.col_ptr()[l.ncols()] + u.col_ptr()[u.ncols()]);
    (flops + solves).div_ceil(18)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::friction::fc3d_newton::alart_curnier;
    use nalgebra::{DMatrix, DVector};

    /// A deterministic sequence in [−1, 1) (xorshift64).
    struct Sequence(u64);

    impl Sequence {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
    }

    /// A Newton system `J d = rhs` on a chain of 40 contacts whose J mixes take-off (G = 0),
    /// stick and slide blocks, with one contact that W does not couple to itself (its diagonal
    /// block missing from W): W, the G blocks, the weights, the right-hand side, and d by a
    /// dense LU with partial pivoting.
    pub(crate) struct MixedNewtonSystem {
        pub(crate) w: BlockCsr,
        pub(crate) gs: Vec<[f64; 9]>,
        pub(crate) rho: Vec<f64>,
        pub(crate) rhs: Vec<f64>,
        pub(crate) expected: DVector<f64>,
    }

    impl MixedNewtonSystem {
        /// Asserts that `d` is the dense LU's direction, entry by entry, to 1e-12 of its
        /// largest entry.
        pub(crate) fn assert_dense_direction(&self, d: &[f64]) {
            let scale = self.expected.amax();
            for (x, y) in d.iter().zip(self.expected.iter()) {
                assert!((x - y).abs() <= 1e-12 * scale, "{x} against {y}");
            }
        }
    }

    pub(crate) fn mixed_newton_system() -> MixedNewtonSystem {
        let m = 40;
        let n = 3 * m;
        let mut random = Sequence(0x9e37_79b9_7f4a_7c15);
        let mut entries = Vec::new();
        for a in 0..m {
            // Contact 7's own block is left out of W.
            let coupled: &[usize] = if a == 7 {
                &[8]
            } else {
                &[a, (a + 1) % m, (a + 5) % m]
            };
            for &b in coupled {
                for i in 0..3 {
                    for k in 0..3 {
                        let diagonal = if a == b && i == k { 4.0 } else { 0.0 };
                        entries.push((3 * a + i, 3 * b + k, diagonal + random.next()));
                    }
                }
            }
        }
        let w = BlockCsr::from_triplets(3, n, entries).unwrap();
        let r: Vec<f64> = (0..n).map(|_| random.next()).collect();
        let u = w.affine(&r, &(0..n).map(|_| random.next()).collect::<Vec<_>>());
        let mut kinds = [0usize; 3];
        let (rho, gs): (Vec<f64>, Vec<[f64; 9]>) = (0..m)
            .map(|a| {
                let k = 3 * a;
                let rho = 0.25;
                // A wide cone on every other contact, so that some of them stick.
                let (_, g) = alart_curnier(
                    if a % 2 == 0 { 0.5 } else { 4.0 },
                    rho,
                    [r[k], r[k + 1], r[k + 2]],
                    [u[k], u[k + 1], u[k + 2]],
                );
                kinds[if g[0] == 0.0 {
                    0
                } else if g[3] == 0.0 {
                    1
                } else {
                    2
                }] += 1;
                (rho, g)
            })
            .unzip();
        assert!(
            kinds.iter().all(|&c| c > 0),
            "take-off, stick, slide: {kinds:?}"
        );
        let rhs: Vec<f64> = (0..n).map(|_| random.next()).collect();
        let mut dense = DMatrix::<f64>::identity(n, n);
        for a in 0..m {
            let g = &gs[a];
            for i in 0..3 {
                for k in 0..3 {
                    dense[(3 * a + i, 3 * a + k)] -= g[3 * i + k];
                }
            }
            for (b, block) in w.row(a) {
                for i in 0..3 {
                    for k in 0..3 {
                        let gw: f64 = (0..3).map(|l| g[3 * i + l] * block[3 * l + k]).sum();
                        dense[(3 * a + i, 3 * b + k)] += rho[a] * gw;
                    }
                }
            }
        }
        let expected = dense.lu().solve(&DVector::from_column_slice(&rhs)).unwrap();
        MixedNewtonSystem {
            w,
            gs,
            rho,
            rhs,
            expected,
        }
    }

    /// The sparse LU's direction is the dense LU's on the mixed system, and the work charged is
    /// more than the assembly alone.
    #[test]
    fn sparse_lu_solves_the_newton_system_as_the_dense_lu_does() {
        let system = mixed_newton_system();
        let MixedNewtonSystem {
            w, gs, rho, rhs, ..
        } = &system;
        let factors = SparseNewton::new(w).unwrap();
        assert!(factors.fits(w));
        let mut work = 0;
        let (d, factorisation) = factors.solve(w, gs, rho, rhs, &mut work).unwrap();
        assert_eq!(work, 3 * w.stored_blocks() + factorisation);
        system.assert_dense_direction(&d);
        assert!(factorisation > 0);
        // W + α I has the diagonal block of contact 7 that W lacks: the pattern has it.
        assert!(factors.fits(&w.with_diagonal_shift(0.5).unwrap()));
    }
}
