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

/// The structure of D = G M⁻¹ Gᵀ for a model's joints (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct JointStructure {
    n: usize,
    /// The coordinates of each block of M (sorted).
    blocks: Vec<Vec<usize>>,
    /// The blocks each joint touches (sorted).
    joint_blocks: Vec<Vec<usize>>,
    /// The coordinates each joint uses (sorted): the nonzeros of its row of G.
    joint_coordinates: Vec<Vec<usize>>,
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
            joint_blocks,
            joint_coordinates: joints.to_vec(),
            coupled,
            band,
        })
    }

    /// Number of joints.
    pub fn joints(&self) -> usize {
        self.coupled.len()
    }

    /// G_j x for the nb×n row-major G, over the coordinates joint j uses.
    pub fn row_dot(&self, j: usize, g: &[f64], x: &[f64]) -> f64 {
        let row = &g[j * self.n..(j + 1) * self.n];
        self.joint_coordinates[j]
            .iter()
            .map(|&i| row[i] * x[i])
            .sum()
    }
}

/// Y = M⁻¹ Gᵀ of one configuration, column by column on the blocks each joint touches: the map
/// from the joints' impulses (or position multipliers) to the velocity jump (or position
/// correction) of the stage.
#[derive(Debug, Clone)]
pub struct JointCompliance<'a> {
    structure: &'a JointStructure,
    /// Column j of Y: its coordinates and values.
    columns: Vec<Vec<(usize, f64)>>,
}

impl<'a> JointCompliance<'a> {
    /// Y for the mass matrix `mass` (n×n row-major) and the joint rows `g` (nb×n row-major);
    /// `None` when a block of M is not positive definite to working precision (the dense
    /// path then decides).
    pub fn new(structure: &'a JointStructure, mass: &[f64], g: &[f64]) -> Option<Self> {
        let n = structure.n;
        // Cholesky factor L of each block, row-major b×b (lower triangle).
        let mut factors: Vec<Vec<f64>> = Vec::with_capacity(structure.blocks.len());
        for block in &structure.blocks {
            let b = block.len();
            let mut l = vec![0.0; b * b];
            for r in 0..b {
                for c in 0..=r {
                    let s = mass[block[r] * n + block[c]]
                        - (0..c).map(|k| l[r * b + k] * l[c * b + k]).sum::<f64>();
                    if r == c {
                        let scale = mass[block[r] * n + block[r]].abs();
                        if !s.is_finite() || s <= 4.0 * f64::EPSILON * scale {
                            return None;
                        }
                        l[r * b + r] = s.sqrt();
                    } else {
                        l[r * b + c] = s / l[c * b + c];
                    }
                }
            }
            factors.push(l);
        }
        let columns = (0..structure.joints())
            .map(|j| {
                let row = &g[j * n..(j + 1) * n];
                let mut column: Vec<(usize, f64)> = Vec::new();
                for &bk in &structure.joint_blocks[j] {
                    let (block, l) = (&structure.blocks[bk], &factors[bk]);
                    let b = block.len();
                    let start = column.len();
                    // L Lᵀ y = G_j on the block: forward, then backward substitution.
                    for r in 0..b {
                        let s = row[block[r]]
                            - (0..r)
                                .map(|k| l[r * b + k] * column[start + k].1)
                                .sum::<f64>();
                        column.push((block[r], s / l[r * b + r]));
                    }
                    for r in (0..b).rev() {
                        let s = column[start + r].1
                            - (r + 1..b)
                                .map(|k| l[k * b + r] * column[start + k].1)
                                .sum::<f64>();
                        column[start + r].1 = s / l[r * b + r];
                    }
                }
                column
            })
            .collect();
        Some(Self { structure, columns })
    }

    /// The band LU of C Y for the joint rows C (nb×n row-major, with G's pattern: G itself
    /// for the velocity stage's D = G M⁻¹ Gᵀ, G at a Newton iterate for the position stage's
    /// exact derivative); `None` when it is singular to working precision (a pivot below
    /// nb ε times the largest, as for Newton's band LU of the smooth stage).
    pub fn operator(&self, c: &[f64]) -> Option<BandLu> {
        let s = self.structure;
        let entries = self.columns.iter().enumerate().flat_map(|(k, column)| {
            s.coupled[k].iter().map(move |&j| {
                let row = &c[j * s.n..(j + 1) * s.n];
                (j, k, column.iter().map(|&(i, y)| row[i] * y).sum::<f64>())
            })
        });
        let lu = BandLu::factor_entries(&s.band, entries)?;
        let (lo, hi) = lu.pivot_range();
        (lo > s.joints() as f64 * f64::EPSILON * hi).then_some(lu)
    }

    /// out += Y z.
    pub fn apply(&self, z: &[f64], out: &mut [f64]) {
        for (column, &zj) in self.columns.iter().zip(z) {
            if zj != 0.0 {
                for &(i, y) in column {
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
        let y = JointCompliance::new(&structure, &mass, &g).expect("M positive definite");
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
        let lu = y.operator(&g).expect("regular");
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
        let y = JointCompliance::new(&structure, &mass, &twice).expect("M positive definite");
        assert!(y.operator(&twice).is_none());
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
