//! The Delassus operator D = G M⁻¹ Gᵀ of the joints of a mechanism whose mass matrix is block
//! diagonal, formed from its sparse pieces and factorised in band form: the operator of the
//! position and velocity stages of the nonsmooth generalized-α scheme
//! ([`super::generalized_alpha`]; Brüls, Acary & Cardona 2014, the decoupled form) when only
//! joints are in them.
//!
//! In absolute or body coordinates each body's coordinates are coupled in M among themselves
//! only (A02, the N-four-bar: one 2×2 block per rocker and coupler pair), so M is block diagonal
//! — its blocks are the connected components of the graph of its nonzeros — and so is M⁻¹.
//! Column j of Y = M⁻¹ Gᵀ then lies on the blocks joint j touches, and D_jk = G_j Y_k is
//! structurally zero unless joints j and k touch a common block. For a chain that pattern has a
//! narrow band ([`BandOrder::of_pattern`], reverse Cuthill–McKee), so a step costs the Cholesky
//! factors of the blocks (Σ b³), Y on its blocks (Σ_j Σ b²), the band entries of D (each a dot
//! product over a joint's few coordinates) and a band LU (O(nb · kl · (kl + ku))): linear in the
//! length of the chain, where forming M⁻¹ Gᵀ and D densely is O(n³).
//!
//! The structure is found once, when the model is compiled ([`JointStructure::new`], from which
//! entries of M and which coordinates of each joint are nonzero by construction); a model
//! without it (few joints, a full M, no band that pays) keeps the dense operator. A step on
//! which D's band LU is singular to working precision (joints that lost rank) is left to the
//! dense path too, whose mixed LCP takes the minimum-norm impulses.

use crate::soi2::banded::{BandLu, BandOrder};
use crate::triplets::Triplets;

/// The structure of D = G M⁻¹ Gᵀ for a model's joints (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct JointStructure {
    n: usize,
    /// The coordinates of each block of M (sorted).
    blocks: Vec<Vec<usize>>,
    /// Per coordinate: its block and its place in the block.
    place: Vec<(usize, usize)>,
    /// Where each block's b×b entries start in a flat array of all blocks.
    block_start: Vec<usize>,
    /// The blocks each joint touches (sorted).
    joint_blocks: Vec<Vec<usize>>,
    /// The coordinates each joint uses (sorted): the nonzeros of its row of G.
    joint_coordinates: Vec<Vec<usize>>,
    /// Where each joint's coordinates start in [`JointRows`]' flat values.
    row_start: Vec<usize>,
    /// Where each column of Y = M⁻¹ Gᵀ starts in [`JointCompliance`]'s flat entries (column j
    /// fills the blocks joint j touches).
    column_start: Vec<usize>,
    /// For each joint k, the joints j with D_jk structurally nonzero (sorted, k among them).
    coupled: Vec<Vec<usize>>,
    /// The band order of D.
    band: BandOrder,
}

impl JointStructure {
    /// The structure of D for n coordinates, the nonzero entries (i, j) of M (either triangle,
    /// or both) and the coordinates each joint uses; `None` when D has no band order that pays
    /// ([`BandOrder::of_pattern`]: fewer than 48 joints, or a pattern too full, as when M is one
    /// block).
    pub fn new(n: usize, mass: &[(usize, usize)], joints: &[Vec<usize>]) -> Option<Self> {
        // The blocks of M: connected components, each labelled by its least coordinate.
        let mut parent: Vec<usize> = (0..n).collect();
        fn root(parent: &mut [usize], mut i: usize) -> usize {
            while parent[i] != i {
                parent[i] = parent[parent[i]];
                i = parent[i];
            }
            i
        }
        for &(i, j) in mass {
            if i >= n || j >= n {
                return None;
            }
            let (a, b) = (root(&mut parent, i), root(&mut parent, j));
            parent[a.max(b)] = a.min(b);
        }
        let mut block_of = vec![usize::MAX; n];
        let mut blocks: Vec<Vec<usize>> = Vec::new();
        for i in 0..n {
            let r = root(&mut parent, i);
            if block_of[r] == usize::MAX {
                block_of[r] = blocks.len();
                blocks.push(Vec::new());
            }
            let b = block_of[r];
            block_of[i] = b;
            blocks[b].push(i);
        }
        let mut place = vec![(0, 0); n];
        let mut block_start = Vec::with_capacity(blocks.len() + 1);
        block_start.push(0);
        for (b, block) in blocks.iter().enumerate() {
            for (k, &i) in block.iter().enumerate() {
                place[i] = (b, k);
            }
            block_start.push(block_start[b] + block.len() * block.len());
        }
        let mut joint_coordinates: Vec<Vec<usize>> = joints.to_vec();
        let mut row_start = Vec::with_capacity(joints.len() + 1);
        row_start.push(0);
        for (j, coordinates) in joint_coordinates.iter_mut().enumerate() {
            coordinates.sort_unstable();
            coordinates.dedup();
            row_start.push(row_start[j] + coordinates.len());
        }
        let mut joint_blocks = Vec::with_capacity(joints.len());
        for coordinates in joints {
            let mut touched = Vec::with_capacity(coordinates.len());
            for &i in coordinates {
                touched.push(*block_of.get(i)?);
            }
            touched.sort_unstable();
            touched.dedup();
            joint_blocks.push(touched);
        }
        let mut column_start = Vec::with_capacity(joint_blocks.len() + 1);
        column_start.push(0);
        for (j, touched) in joint_blocks.iter().enumerate() {
            let size: usize = touched.iter().map(|&b| blocks[b].len()).sum();
            column_start.push(column_start[j] + size);
        }
        let mut joints_of_block: Vec<Vec<usize>> = vec![Vec::new(); blocks.len()];
        for (j, touched) in joint_blocks.iter().enumerate() {
            for &b in touched {
                joints_of_block[b].push(j);
            }
        }
        let coupled: Vec<Vec<usize>> = joint_blocks
            .iter()
            .map(|touched| {
                let mut k: Vec<usize> = touched
                    .iter()
                    .flat_map(|&b| joints_of_block[b].iter().copied())
                    .collect();
                k.sort_unstable();
                k.dedup();
                k
            })
            .collect();
        let band = BandOrder::of_pattern(&coupled)?;
        Some(Self {
            n,
            blocks,
            place,
            block_start,
            joint_blocks,
            joint_coordinates,
            row_start,
            column_start,
            coupled,
            band,
        })
    }

    /// Number of joints.
    pub fn joints(&self) -> usize {
        self.coupled.len()
    }

    /// The rows of the nb×n matrix `c` (a joint Jacobian: its entries on the coordinates of
    /// each joint) over the coordinates each joint uses; `None` when `c` has a nonzero entry
    /// elsewhere (then the dense path decides).
    pub fn rows(&self, c: &Triplets) -> Option<JointRows> {
        let mut values = vec![0.0; self.row_start[self.joints()]];
        for &(j, i, v) in c.entries() {
            let coordinates = self.joint_coordinates.get(j)?;
            match coordinates.binary_search(&i) {
                Ok(k) => values[self.row_start[j] + k] += v,
                Err(_) if v == 0.0 => {}
                Err(_) => return None,
            }
        }
        Some(JointRows { values })
    }

    /// Joint j's coordinates and its row of `c` on them.
    fn row<'r>(&'r self, j: usize, c: &'r JointRows) -> impl Iterator<Item = (usize, f64)> + 'r {
        let values = &c.values[self.row_start[j]..self.row_start[j + 1]];
        self.joint_coordinates[j]
            .iter()
            .copied()
            .zip(values.iter().copied())
    }

    /// Σ_i |C_ji| w_i for the rows `c`, over the coordinates joint j uses.
    pub fn row_weight(&self, j: usize, c: &JointRows, w: &[f64]) -> f64 {
        self.row(j, c).map(|(i, v)| v.abs() * w[i]).sum()
    }

    /// C_j x for the rows `c`, over the coordinates joint j uses.
    pub fn row_dot(&self, j: usize, c: &JointRows, x: &[f64]) -> f64 {
        self.row(j, c).map(|(i, v)| v * x[i]).sum()
    }
}

/// An nb×n matrix with the pattern of the joint Jacobian G (each row on the coordinates its
/// joint uses, [`JointStructure::rows`]): G itself, or G at another configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct JointRows {
    /// Row j's values on joint j's coordinates, rows one after another.
    values: Vec<f64>,
}

/// Y = M⁻¹ Gᵀ of one configuration, column by column on the blocks each joint touches: the map
/// from the joints' impulses (or position multipliers) to the velocity jump (or position
/// correction) of the stage.
#[derive(Debug, Clone)]
pub struct JointCompliance<'a> {
    structure: &'a JointStructure,
    /// The joint rows G that Y was formed with.
    g: &'a JointRows,
    /// The columns of Y, each as its coordinates and values, one after another
    /// ([`JointStructure::column_start`]).
    columns: Vec<(usize, f64)>,
}

impl<'a> JointCompliance<'a> {
    /// Y for the mass matrix `mass` (n×n, its entries) and the joint rows `g`; `None` when M
    /// has a nonzero entry outside its blocks or a block of M is not positive definite to
    /// working precision (the dense path then decides).
    pub fn new(structure: &'a JointStructure, mass: &Triplets, g: &'a JointRows) -> Option<Self> {
        let s = structure;
        // The blocks of M, each b×b row-major, one after another.
        let mut blocks = vec![0.0; s.block_start[s.blocks.len()]];
        for &(i, j, v) in mass.entries() {
            let ((bi, ri), (bj, cj)) = (*s.place.get(i)?, *s.place.get(j)?);
            if bi == bj {
                blocks[s.block_start[bi] + ri * s.blocks[bi].len() + cj] += v;
            } else if v != 0.0 {
                return None;
            }
        }
        // Cholesky factor L of each block, in place (lower triangle).
        for (bk, block) in s.blocks.iter().enumerate() {
            let b = block.len();
            let l = &mut blocks[s.block_start[bk]..s.block_start[bk + 1]];
            for r in 0..b {
                let scale = l[r * b + r].abs();
                for c in 0..=r {
                    let sum =
                        l[r * b + c] - (0..c).map(|k| l[r * b + k] * l[c * b + k]).sum::<f64>();
                    if r == c {
                        if !sum.is_finite() || sum <= 4.0 * f64::EPSILON * scale {
                            return None;
                        }
                        l[r * b + r] = sum.sqrt();
                    } else {
                        l[r * b + c] = sum / l[c * b + c];
                    }
                }
            }
        }
        let mut row = vec![0.0; s.n];
        let mut columns: Vec<(usize, f64)> = Vec::with_capacity(s.column_start[s.joints()]);
        for j in 0..s.joints() {
            for (i, v) in s.row(j, g) {
                row[i] = v;
            }
            for &bk in &s.joint_blocks[j] {
                let block = &s.blocks[bk];
                let l = &blocks[s.block_start[bk]..s.block_start[bk + 1]];
                let b = block.len();
                let start = columns.len();
                // L Lᵀ y = G_j on the block: forward, then backward substitution.
                for r in 0..b {
                    let sum = row[block[r]]
                        - (0..r)
                            .map(|k| l[r * b + k] * columns[start + k].1)
                            .sum::<f64>();
                    columns.push((block[r], sum / l[r * b + r]));
                }
                for r in (0..b).rev() {
                    let sum = columns[start + r].1
                        - (r + 1..b)
                            .map(|k| l[k * b + r] * columns[start + k].1)
                            .sum::<f64>();
                    columns[start + r].1 = sum / l[r * b + r];
                }
            }
            for (i, _) in s.row(j, g) {
                row[i] = 0.0;
            }
        }
        Some(Self {
            structure,
            g,
            columns,
        })
    }

    /// The band LU of C Y for the joint rows C (with G's pattern: G itself for the velocity
    /// stage's D = G M⁻¹ Gᵀ, G at a Newton iterate for the position stage's exact
    /// derivative); `None` when it is singular to working precision (a pivot below nb ε times
    /// the largest, as for Newton's band LU of the smooth stage).
    pub fn operator(&self, c: &JointRows) -> Option<BandLu> {
        self.factor(c, false)
    }

    /// [`JointCompliance::operator`] of the joint rows Y was formed with: the symmetric
    /// D = G M⁻¹ Gᵀ, each entry below the diagonal the mirror of the one above (formed once).
    pub fn delassus(&self) -> Option<BandLu> {
        self.factor(self.g, true)
    }

    /// The band LU of C Y, with only its upper triangle formed when `symmetric`.
    fn factor(&self, c: &JointRows, symmetric: bool) -> Option<BandLu> {
        let s = self.structure;
        let mut row = vec![0.0; s.n];
        let mut entries = Vec::with_capacity(s.coupled.iter().map(Vec::len).sum());
        for j in 0..s.joints() {
            for (i, v) in s.row(j, c) {
                row[i] = v;
            }
            for &k in &s.coupled[j] {
                if symmetric && k < j {
                    continue;
                }
                let d = self.column(k).iter().map(|&(i, y)| row[i] * y).sum::<f64>();
                entries.push((j, k, d));
                if symmetric && k > j {
                    entries.push((k, j, d));
                }
            }
            for (i, _) in s.row(j, c) {
                row[i] = 0.0;
            }
        }
        let lu = BandLu::factor_entries(&s.band, entries)?;
        let (lo, hi) = lu.pivot_range();
        (lo > s.joints() as f64 * f64::EPSILON * hi).then_some(lu)
    }

    /// Column k of Y: its coordinates and values.
    fn column(&self, k: usize) -> &[(usize, f64)] {
        let start = &self.structure.column_start;
        &self.columns[start[k]..start[k + 1]]
    }

    /// out += Y z.
    pub fn apply(&self, z: &[f64], out: &mut [f64]) {
        for (k, &zj) in z.iter().enumerate().take(self.structure.joints()) {
            if zj != 0.0 {
                for &(i, y) in self.column(k) {
                    out[i] += y * zj;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    /// A chain of `bodies` 2×2 mass blocks and a joint between each pair of neighbours using
    /// three coordinates, as A02's: Y z equals the dense M⁻¹ Gᵀ z to 1e-12, and a solve with
    /// the band D has a round-off backward error against the dense G M⁻¹ Gᵀ.
    #[test]
    fn the_band_delassus_operator_of_a_chain_equals_the_dense_one() {
        let bodies = 30;
        let n = 2 * bodies;
        let nb = 2 * (bodies - 1);
        let wave = |k: usize| (0.37 * k as f64 + 0.2).sin();
        let mut mass = vec![0.0; n * n];
        let mut entries = Vec::new();
        for b in 0..bodies {
            let (i, j) = (2 * b, 2 * b + 1);
            mass[i * n + i] = 2.0 + wave(i);
            mass[j * n + j] = 1.0 + 0.5 * wave(j);
            mass[i * n + j] = 0.4 * wave(i + j);
            mass[j * n + i] = mass[i * n + j];
            entries.extend([(i, i), (i, j), (j, j)]);
        }
        let mut g = vec![0.0; nb * n];
        let mut joints = Vec::new();
        for r in 0..nb {
            let b = r / 2;
            let coordinates = vec![2 * b, 2 * b + 1, 2 * b + 2];
            for (k, &i) in coordinates.iter().enumerate() {
                g[r * n + i] = 1.0 + wave(3 * r + k);
            }
            joints.push(coordinates);
        }
        let structure = JointStructure::new(n, &entries, &joints).expect("a band");
        let mass_entries = Triplets::from_dense(n, n, &mass, false);
        let g_rows = structure
            .rows(&Triplets::from_dense(nb, n, &g, false))
            .expect("G on the joints' coordinates");
        let y =
            JointCompliance::new(&structure, &mass_entries, &g_rows).expect("M positive definite");
        let (m_d, g_d) = (
            DMatrix::from_row_slice(n, n, &mass),
            DMatrix::from_row_slice(nb, n, &g),
        );
        let y_d = m_d.lu().solve(&g_d.transpose()).expect("regular");
        let d_d = &g_d * &y_d;
        let z: Vec<f64> = (0..nb).map(|k| wave(5 * k + 1)).collect();
        let mut yz = vec![0.0; n];
        y.apply(&z, &mut yz);
        let yz_d = &y_d * DVector::from_column_slice(&z);
        for (a, b) in yz.iter().zip(yz_d.iter()) {
            assert!((a - b).abs() < 1e-12 * (1.0 + b.abs()), "{a} vs {b}");
        }
        let lu = y.operator(&g_rows).expect("regular");
        let mut x = z.clone();
        assert!(lu.solve_mut(&mut x));
        let x_d = d_d
            .clone()
            .lu()
            .solve(&DVector::from_column_slice(&z))
            .expect("regular");
        // Backward error at round-off against the dense D (a wrong or missing band entry
        // leaves an O(1) residual), and the dense solve's x to the conditioning of D.
        let x_v = DVector::from_column_slice(&x);
        let residual = (&d_d * &x_v - DVector::from_column_slice(&z)).amax();
        let d_norm = d_d.row_iter().map(|r| r.abs().sum()).fold(0.0, f64::max);
        assert!(
            residual <= 1e-13 * d_norm * x_v.amax(),
            "residual {residual:e}, ‖D‖ {d_norm}, ‖x‖ {}",
            x_v.amax()
        );
        for (a, b) in x.iter().zip(x_d.iter()) {
            assert!((a - b).abs() < 1e-9 * (1.0 + b.abs()), "{a} vs {b}");
        }
        // Two joints sharing their coordinates make D singular: left to the dense path.
        let mut twice = g.clone();
        twice.copy_within(0..n, n);
        let twice = structure
            .rows(&Triplets::from_dense(nb, n, &twice, false))
            .expect("G on the joints' coordinates");
        let y =
            JointCompliance::new(&structure, &mass_entries, &twice).expect("M positive definite");
        assert!(y.operator(&twice).is_none());
        // An entry outside a joint's coordinates, or of M outside its blocks: the dense path.
        let mut outside = Triplets::from_dense(nb, n, &g, false);
        outside.push(0, n - 1, 1.0);
        assert!(structure.rows(&outside).is_none());
        let mut coupled = mass_entries.clone();
        coupled.push(0, 2, 0.5);
        assert!(JointCompliance::new(&structure, &coupled, &g_rows).is_none());
    }

    /// A mass matrix coupling every coordinate is one block: D is full, no band.
    #[test]
    fn a_full_mass_matrix_has_no_band_structure() {
        let n = 60;
        let entries: Vec<(usize, usize)> = (0..n).map(|i| (i, (i + 1) % n)).collect();
        let joints: Vec<Vec<usize>> = (0..n - 1).map(|i| vec![i, i + 1]).collect();
        assert!(JointStructure::new(n, &entries, &joints).is_none());
        let diagonal: Vec<(usize, usize)> = (0..n).map(|i| (i, i)).collect();
        assert!(JointStructure::new(n, &diagonal, &joints).is_some());
    }
}
