//! The sparsity of Newton's matrix and the column groups that build it from a few dual
//! evaluations (docs/soi2.md, "Cost").
//!
//! A mechanism's equations touch few coordinates each: row i of the equations of motion only the
//! coordinates coupled to i through M and the forces, a joint only the coordinates of the
//! bodies it joins. Newton's matrix J of a step is then sparse, and two of its columns that
//! share no row can be differentiated together: seeding the dual parts of both unknowns at once
//! gives, in each row, the derivative along the one column that touches it. Columns are
//! grouped greedily, in order, into groups of structurally orthogonal columns (Curtis, Powell &
//! Reid, "On the estimation of sparse Jacobian matrices", J. Inst. Maths Applics 13:117–119,
//! 1974, doi:10.1093/imamat/13.1.117): one dual evaluation per group instead of one per
//! column. For a chain the number of groups stays bounded as it grows (A02, the N-four-bar:
//! a few dozen groups for 4N + 2 unknowns), so the cost of a Jacobian grows like the cost of
//! one residual evaluation, linearly in N.
//!
//! The pattern is structural (from which variables the model's expressions use), so a
//! derivative that happens to vanish at an iterate (a joint row at a singular position) is
//! still computed: the grouping only ever drops entries that are zero by construction.

use super::banded::BandOrder;

/// Which coordinates each equation of a model touches.
#[derive(Debug, Clone, PartialEq)]
pub struct Coupling {
    /// For each coordinate i, the coordinates j (sorted, without repeats) whose position or
    /// velocity enters row i of the equations of motion, M(t, y) z' = F(t, y, z) without the
    /// joint forces: the nonzeros of row i of M, the variables of those entries, and the
    /// variables of F_i.
    pub motion: Vec<Vec<usize>>,
    /// For each holonomic constraint, the coordinates (sorted) its expression uses.
    pub joints: Vec<Vec<usize>>,
}

impl Coupling {
    /// Number of coordinates n.
    pub fn n(&self) -> usize {
        self.motion.len()
    }
}

/// The structure of a Newton matrix whose unknowns are `blocks` vectors of the n coordinates
/// followed by `blocks` vectors of the m joints (in that order), and whose rows are `blocks`
/// sets of equations of motion followed by `blocks` sets of joint equations: row i of an
/// equation-of-motion set touches, in every coordinate block, the coordinates coupled to i
/// (its motion row and the coordinates of every joint that uses i), and in every joint block
/// the joints that use i; a joint row touches the coordinates of its joint in every coordinate
/// block. This covers every formulation of [`super::method`] (a superset of each one's
/// exact structure) and the consistent-acceleration system (`blocks` = 1).
#[derive(Debug, Clone, PartialEq)]
pub struct Pattern {
    /// Size of the square matrix.
    size: usize,
    /// For each column, the rows it touches (sorted).
    rows_of: Vec<Vec<usize>>,
    /// Groups of structurally orthogonal columns.
    groups: Vec<Vec<usize>>,
    /// A band order of the unknowns, when the band LU pays ([`BandOrder::of_pattern`]).
    band: Option<BandOrder>,
}

impl Pattern {
    /// The pattern of a Newton matrix with `blocks` coordinate and joint blocks for `coupling`,
    /// and its column groups.
    pub fn new(coupling: &Coupling, blocks: usize) -> Pattern {
        let n = coupling.n();
        let m = coupling.joints.len();
        let size = blocks * (n + m);
        // The joints that use each coordinate.
        let mut joints_of: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (q, vars) in coupling.joints.iter().enumerate() {
            for &j in vars {
                joints_of[j].push(q);
            }
        }
        // Columns of each row: coordinates first (every block), then joints.
        let mut cols_of: Vec<Vec<usize>> = Vec::with_capacity(size);
        for _ in 0..blocks {
            for (i, joints) in joints_of.iter().enumerate() {
                let mut coords = coupling.motion[i].clone();
                coords.extend(joints.iter().flat_map(|&q| coupling.joints[q].iter()));
                coords.sort_unstable();
                coords.dedup();
                let mut cols = Vec::with_capacity(blocks * (coords.len() + joints.len()));
                for b in 0..blocks {
                    cols.extend(coords.iter().map(|&j| b * n + j));
                }
                for b in 0..blocks {
                    cols.extend(joints.iter().map(|&q| blocks * n + b * m + q));
                }
                cols_of.push(cols);
            }
        }
        for _ in 0..blocks {
            for vars in &coupling.joints {
                cols_of.push(
                    (0..blocks)
                        .flat_map(|b| vars.iter().map(move |&j| b * n + j))
                        .collect(),
                );
            }
        }
        let mut rows_of: Vec<Vec<usize>> = vec![Vec::new(); size];
        for (r, cols) in cols_of.iter().enumerate() {
            for &c in cols {
                rows_of[c].push(r);
            }
        }
        // Each row once per column (rows come in order): a joint naming a coordinate twice
        // would otherwise count its entry twice in sums over the pattern.
        for rows in &mut rows_of {
            rows.dedup();
        }
        let groups = group_columns(&rows_of, &cols_of);
        let band = BandOrder::of_pattern(&rows_of);
        Pattern {
            size,
            rows_of,
            groups,
            band,
        }
    }

    /// Size of the matrix.
    pub fn size(&self) -> usize {
        self.size
    }

    /// The groups of structurally orthogonal columns (one dual evaluation each).
    pub fn groups(&self) -> &[Vec<usize>] {
        &self.groups
    }

    /// The band order of the unknowns, when a band LU costs less than a quarter of the dense
    /// one.
    pub fn band(&self) -> Option<&BandOrder> {
        self.band.as_ref()
    }

    /// The rows column `c` touches.
    pub fn rows_of(&self, c: usize) -> &[usize] {
        &self.rows_of[c]
    }
}

/// Greedy grouping of the columns, in order: each column joins the first group none of whose
/// columns shares a row with it (Curtis, Powell & Reid 1974).
fn group_columns(rows_of: &[Vec<usize>], cols_of: &[Vec<usize>]) -> Vec<Vec<usize>> {
    let mut group_of = vec![usize::MAX; rows_of.len()];
    let mut groups: Vec<Vec<usize>> = Vec::new();
    // taken[g] == c: group g has a column sharing a row with column c.
    let mut taken: Vec<usize> = Vec::new();
    for c in 0..rows_of.len() {
        for &r in &rows_of[c] {
            for &other in &cols_of[r] {
                let g = group_of[other];
                if g != usize::MAX {
                    taken[g] = c;
                }
            }
        }
        let g = (0..groups.len())
            .find(|&g| taken[g] != c)
            .unwrap_or_else(|| {
                groups.push(Vec::new());
                taken.push(usize::MAX);
                groups.len() - 1
            });
        groups[g].push(c);
        group_of[c] = g;
    }
    groups
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain of k coordinates with k − 1 joints (i–(i+1)) and a diagonal motion.
    fn chain(k: usize) -> Coupling {
        Coupling {
            motion: (0..k).map(|i| vec![i]).collect(),
            joints: (0..k - 1).map(|i| vec![i, i + 1]).collect(),
        }
    }

    /// Every column in exactly one group, and no two columns of a group share a row.
    fn assert_orthogonal_groups(p: &Pattern) {
        let mut seen = vec![false; p.size()];
        for g in p.groups() {
            for (k, &a) in g.iter().enumerate() {
                assert!(!seen[a]);
                seen[a] = true;
                for &b in &g[k + 1..] {
                    assert!(p.rows_of(a).iter().all(|r| !p.rows_of(b).contains(r)));
                }
            }
        }
        assert!(seen.iter().all(|&s| s));
    }

    #[test]
    fn a_chain_has_the_rows_its_joints_touch_and_orthogonal_groups() {
        let p = Pattern::new(&chain(3), 1);
        assert_eq!(p.size(), 5);
        // Column of coordinate 0: motion rows 0 (itself) and 1 (joint 0 uses 0 and 1), joint
        // row 0 (index 3).
        assert_eq!(p.rows_of(0), &[0, 1, 3]);
        // Column of joint 1 (index 4): the motion rows of coordinates 1 and 2.
        assert_eq!(p.rows_of(4), &[1, 2]);
        assert_orthogonal_groups(&p);
        // The number of groups does not grow with the chain: 39 and 159 unknowns take the same
        // (few) dual evaluations.
        let (short, long) = (Pattern::new(&chain(20), 1), Pattern::new(&chain(80), 1));
        assert_orthogonal_groups(&short);
        assert_orthogonal_groups(&long);
        assert_eq!(short.groups().len(), long.groups().len());
        assert!(
            short.groups().len() <= 10,
            "{} groups",
            short.groups().len()
        );
        // And its band order keeps the band narrow (a band LU for 159 unknowns).
        let band = long.band().expect("a band order");
        assert!(band.kl + band.ku <= 12, "kl {}, ku {}", band.kl, band.ku);
    }

    #[test]
    fn two_blocks_repeat_the_coupling_in_every_block() {
        let p = Pattern::new(&chain(3), 2);
        assert_eq!(p.size(), 10);
        // Coordinate 2 of the second block (column 5): motion rows 1, 2 and 4, 5 of both sets
        // of equations of motion, joint 1's rows (7 and 9).
        assert_eq!(p.rows_of(5), &[1, 2, 4, 5, 7, 9]);
    }
}
