//! LU factorisation with partial pivoting of a band matrix, for Newton's matrix of a large
//! mechanism once its unknowns are put in a band order (docs/soi2.md, "Cost").
//!
//! The unknowns are renumbered by the reverse Cuthill–McKee ordering of the matrix's structure
//! (Cuthill & McKee, "Reducing the bandwidth of sparse symmetric matrices", Proc. 24th ACM
//! National Conference, 1969, doi:10.1145/800195.805928; reversed as George 1971 proposed), which
//! keeps the nonzeros of a chain within a band of kl sub- and ku super-diagonals. Gaussian
//! elimination with row interchanges stays inside a band of kl sub- and kl + ku
//! super-diagonals (the row interchanges of partial pivoting widen U by kl; LAPACK's `dgbtrf`
//! does the same), so the factorisation costs O(n · kl · (kl + ku)) instead of the dense n³/3,
//! and a solve O(n · (2 kl + ku)).

use crate::dense::negligible_pivot;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// The reverse Cuthill–McKee ordering of the symmetric graph `adjacent` (each vertex's
/// neighbours): `order[k]` is the vertex numbered k. Every connected component starts from a
/// vertex of least degree; neighbours are visited by increasing degree.
pub fn reverse_cuthill_mckee(adjacent: &[Vec<usize>]) -> Vec<usize> {
    let n = adjacent.len();
    let degree = |v: usize| adjacent[v].len();
    let mut by_degree: Vec<usize> = (0..n).collect();
    by_degree.sort_by_key(|&v| (degree(v), v));
    let mut seen = vec![false; n];
    let mut order = Vec::with_capacity(n);
    for &start in &by_degree {
        if seen[start] {
            continue;
        }
        seen[start] = true;
        let mut head = order.len();
        order.push(start);
        while head < order.len() {
            let v = order[head];
            head += 1;
            let mut next: Vec<usize> = adjacent[v].iter().copied().filter(|&w| !seen[w]).collect();
            next.sort_by_key(|&w| (degree(w), w));
            next.dedup();
            for w in next {
                seen[w] = true;
                order.push(w);
            }
        }
    }
    order.reverse();
    order
}

/// A band order of a square matrix's unknowns: `order[k]` is the unknown numbered k, and in
/// that numbering the nonzeros lie within kl sub- and ku super-diagonals.
#[derive(Debug, Clone, PartialEq)]
pub struct BandOrder {
    /// The unknown numbered k.
    pub order: Vec<usize>,
    /// Sub-diagonals.
    pub kl: usize,
    /// Super-diagonals.
    pub ku: usize,
}

impl BandOrder {
    /// The reverse Cuthill–McKee order of the n×n matrix with structural entries `entries`
    /// (row, column; repeats allowed), and its bandwidths; `None` when the band LU would not
    /// cost less than a quarter of the dense one, or the matrix is small (below 48 unknowns,
    /// where the dense LU is as fast and its results stay as they were).
    pub fn of_entries(
        n: usize,
        entries: impl IntoIterator<Item = (usize, usize)>,
    ) -> Option<BandOrder> {
        let mut rows_of: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (i, j) in entries {
            rows_of[j].push(i);
        }
        for rows in &mut rows_of {
            rows.sort_unstable();
            rows.dedup();
        }
        BandOrder::of_pattern(&rows_of)
    }

    /// The reverse Cuthill–McKee order of a matrix whose column c touches the rows
    /// `rows_of[c]` (see [`BandOrder::of_entries`]).
    pub fn of_pattern(rows_of: &[Vec<usize>]) -> Option<BandOrder> {
        let size = rows_of.len();
        if size < 48 {
            return None;
        }
        let mut adjacent: Vec<Vec<usize>> = vec![Vec::new(); size];
        for (c, rows) in rows_of.iter().enumerate() {
            for &r in rows {
                if r != c {
                    adjacent[c].push(r);
                    adjacent[r].push(c);
                }
            }
        }
        for a in adjacent.iter_mut() {
            a.sort_unstable();
            a.dedup();
        }
        let order = reverse_cuthill_mckee(&adjacent);
        let mut position = vec![0; size];
        for (k, &o) in order.iter().enumerate() {
            position[o] = k;
        }
        let (mut kl, mut ku) = (0, 0);
        for (c, rows) in rows_of.iter().enumerate() {
            for &r in rows {
                let (pr, pc) = (position[r], position[c]);
                kl = kl.max(pr.saturating_sub(pc));
                ku = ku.max(pc.saturating_sub(pr));
            }
        }
        let (n, l, u) = (size as f64, kl as f64, ku as f64);
        (2.0 * n * l * (l + u) < n * n * n / 6.0).then_some(BandOrder { order, kl, ku })
    }
}

/// An LU factorisation with partial pivoting of P A Pᵀ, A square and P the permutation of a
/// band order: rows stored as bands of `2 kl + ku + 1` entries (columns i − kl … i + kl + ku).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(from = "BandLuParts")]
pub struct BandLu {
    n: usize,
    kl: usize,
    ku: usize,
    /// order[k]: the original unknown numbered k.
    order: Vec<usize>,
    /// L (unit lower, below the diagonal) and U, row by row.
    ab: Vec<f64>,
    /// Row interchanged with row k at step k.
    pivots: Vec<usize>,
    /// U and L again, by columns and without their zeros, with the pivots' reciprocals: what
    /// the substitutions read ([`Columns`]). Not stored: rebuilt from `ab` when read back.
    #[serde(skip)]
    columns: Columns,
}

/// The factors of a [`BandLu`] by columns, each column's nonzeros only: the entries of U above
/// the diagonal (row, u_ij), 1/u_jj, and L's multipliers below it (row, l_ij). Both
/// substitutions then run by columns and multiply by 1/u_jj: `ab` holds a column at a stride
/// of a row's width, its back substitution by rows waited, row after row, on a dot product's
/// sum and a division, and most of the band is zero (on A02 with N = 40, a Newton matrix of
/// 322 unknowns with kl = ku = 12: 80 % of U's band and 68 % of L's; its 5–6 solves a
/// simplified-Newton step were a third of the step). Dropping exact zeros changes no result.
#[derive(Debug, Clone, Default, PartialEq)]
struct Columns {
    /// Column j's entries of U at `upper_starts[j]..upper_starts[j + 1]`.
    upper_starts: Vec<usize>,
    upper: Vec<(usize, f64)>,
    /// Column j's multipliers of L at `lower_starts[j]..lower_starts[j + 1]`.
    lower_starts: Vec<usize>,
    lower: Vec<(usize, f64)>,
    /// 1/u_jj.
    inverse_pivots: Vec<f64>,
}

/// A [`BandLu`] as stored, before its [`Columns`] are gathered.
#[derive(Deserialize)]
struct BandLuParts {
    n: usize,
    kl: usize,
    ku: usize,
    order: Vec<usize>,
    ab: Vec<f64>,
    pivots: Vec<usize>,
}

impl From<BandLuParts> for BandLu {
    /// The columns are gathered only from parts whose sizes agree ([`BandLu::fault`]
    /// refuses the others).
    fn from(p: BandLuParts) -> Self {
        let mut lu = BandLu {
            n: p.n,
            kl: p.kl,
            ku: p.ku,
            order: p.order,
            ab: p.ab,
            pivots: p.pivots,
            columns: Columns::default(),
        };
        if lu.sizes_fault(lu.n).is_none() {
            lu.gather_columns();
        }
        lu
    }
}

impl BandLu {
    /// Width of a stored row.
    fn width(&self) -> usize {
        2 * self.kl + self.ku + 1
    }

    /// Index of entry (i, j) of the permuted matrix in `ab` (i − kl ≤ j ≤ i + kl + ku).
    fn at(&self, i: usize, j: usize) -> usize {
        i * self.width() + (j + self.kl - i)
    }

    /// Why this is not a factorisation of `n` unknowns that [`BandLu::solve_mut`] can follow
    /// within its arrays (the order a permutation of 0..n, a pivot of step k in k..n, bands no
    /// wider than the matrix, `ab` holding n rows of the band's width), or `None`. A band LU
    /// read from a checkpoint is checked so (`stored_factor.rs`).
    pub(crate) fn fault(&self, n: usize) -> Option<String> {
        if self.n != n || self.order.len() != n || self.pivots.len() != n {
            return Some(format!("a band LU of {} unknowns kept for {n}", self.n));
        }
        let mut seen = vec![false; n];
        for &o in &self.order {
            if o >= n || std::mem::replace(&mut seen[o], true) {
                return Some(format!(
                    "a band order of {n} unknowns numbering {o} twice or out of range"
                ));
            }
        }
        if let Some(fault) = self.sizes_fault(n) {
            return Some(fault);
        }
        if self.columns.inverse_pivots.len() != n {
            return Some(format!("a band LU of {n} unknowns without its columns"));
        }
        None
    }

    /// [`BandLu::fault`] but for `columns`: whether the pivots and `ab` fit `n`
    /// unknowns.
    fn sizes_fault(&self, n: usize) -> Option<String> {
        if let Some((k, p)) = self
            .pivots
            .iter()
            .enumerate()
            .find(|&(k, &p)| p < k || p >= n)
        {
            return Some(format!("a band LU pivoting row {k} with row {p} of {n}"));
        }
        let rows = (self.kl < n.max(1) && self.ku < n.max(1))
            .then(|| n.checked_mul(self.width()))
            .flatten();
        if rows != Some(self.ab.len()) {
            return Some(format!(
                "a band LU of {n} unknowns, bands {} and {}, with {} stored entries",
                self.kl,
                self.ku,
                self.ab.len()
            ));
        }
        None
    }

    /// Factorises the matrix `a` in the band order `order` with kl sub- and ku super-diagonals
    /// there (entries outside the band must be zero). A zero pivot is kept (its solve fails).
    pub fn factor(a: &DMatrix<f64>, band: &BandOrder) -> BandLu {
        let mut lu = BandLu::zeros(band);
        let (n, kl, ku, order) = (lu.n, lu.kl, lu.ku, &band.order);
        for i in 0..n {
            for j in i.saturating_sub(kl)..(i + ku + 1).min(n) {
                let k = lu.at(i, j);
                lu.ab[k] = a[(order[i], order[j])];
            }
        }
        lu.eliminate();
        lu
    }

    /// Factorises the square matrix whose nonzeros are `entries` (row, column, value; a
    /// repeated position adds up) in the band order `band`, without forming it densely:
    /// O(entries + n · kl · (kl + ku)). `None` when an entry lies outside the band.
    pub fn factor_entries(
        band: &BandOrder,
        entries: impl IntoIterator<Item = (usize, usize, f64)>,
    ) -> Option<BandLu> {
        let mut lu = BandLu::zeros(band);
        let mut position = vec![0; lu.n];
        for (k, &o) in band.order.iter().enumerate() {
            position[o] = k;
        }
        for (r, c, v) in entries {
            let (i, j) = (*position.get(r)?, *position.get(c)?);
            if i > j + lu.kl || j > i + lu.ku {
                return None;
            }
            let k = lu.at(i, j);
            lu.ab[k] += v;
        }
        lu.eliminate();
        Some(lu)
    }

    /// The zero matrix of the band order `band`, ready to be filled and factorised.
    fn zeros(band: &BandOrder) -> BandLu {
        let BandOrder { order, kl, ku } = band;
        let (n, kl, ku) = (order.len(), *kl, *ku);
        BandLu {
            n,
            kl,
            ku,
            order: order.to_vec(),
            ab: vec![0.0; n * (2 * kl + ku + 1)],
            pivots: vec![0; n],
            columns: Columns::default(),
        }
    }

    /// Gathers U's and L's nonzeros from `ab` into `columns`, with the reciprocals of the
    /// pivots.
    fn gather_columns(&mut self) {
        let (n, kl, ku) = (self.n, self.kl, self.ku);
        let mut c = Columns {
            upper_starts: Vec::with_capacity(n + 1),
            lower_starts: Vec::with_capacity(n + 1),
            inverse_pivots: Vec::with_capacity(n),
            ..Columns::default()
        };
        for j in 0..n {
            c.upper_starts.push(c.upper.len());
            c.lower_starts.push(c.lower.len());
            let entry = |i: usize| (i, self.ab[self.at(i, j)]);
            let nonzero = |&(_, v): &(usize, f64)| v != 0.0;
            c.upper
                .extend((j.saturating_sub(kl + ku)..j).map(entry).filter(nonzero));
            c.inverse_pivots.push(1.0 / self.ab[self.at(j, j)]);
            c.lower
                .extend((j + 1..(j + kl + 1).min(n)).map(entry).filter(nonzero));
        }
        c.upper_starts.push(c.upper.len());
        c.lower_starts.push(c.lower.len());
        self.columns = c;
    }

    /// Gaussian elimination with partial pivoting of the stored band, in place. Row i holds
    /// columns i − kl … i + kl + ku at i·w … (i + 1)·w − 1 ([`BandLu::at`]), so a row's
    /// stretch from a given column on is one slice: the interchanges and the updates run on
    /// slices.
    fn eliminate(&mut self) {
        let (n, kl, ku) = (self.n, self.kl, self.ku);
        let w = self.width();
        let ab = &mut self.ab;
        for k in 0..n {
            let last_row = (k + kl).min(n - 1);
            let len = (k + kl + ku).min(n - 1) - k;
            // (i, k) of row i ≥ k sits at i·w + k + kl − i.
            let at_k = |i: usize| i * w + k + kl - i;
            let mut p = k;
            let mut largest = ab[at_k(k)].abs();
            for i in k + 1..=last_row {
                let a = ab[at_k(i)].abs();
                if a > largest {
                    p = i;
                    largest = a;
                }
            }
            self.pivots[k] = p;
            if p != k {
                // Columns k … k + len of rows k and p.
                let (upper, lower) = ab.split_at_mut(p * w);
                let row_k = &mut upper[at_k(k)..=at_k(k) + len];
                let start = at_k(p) - p * w;
                row_k.swap_with_slice(&mut lower[start..=start + len]);
            }
            let pivot = ab[at_k(k)];
            if pivot == 0.0 {
                continue;
            }
            let (upper, lower) = ab.split_at_mut((k + 1) * w);
            let pivot_row = &upper[at_k(k) + 1..=at_k(k) + len];
            for i in k + 1..=last_row {
                let ik = at_k(i) - (k + 1) * w;
                let l = lower[ik] / pivot;
                lower[ik] = l;
                if l != 0.0 {
                    for (a, &u) in lower[ik + 1..=ik + len].iter_mut().zip(pivot_row) {
                        *a -= l * u;
                    }
                }
            }
        }
        self.gather_columns();
    }

    /// [`BandLu::factor_entries`] of a matrix given with each position once, `None` also when
    /// it is singular to working precision: a pivot u_kk at or below n ε times the largest
    /// entry of its column of the original matrix, or not finite
    /// ([`crate::dense::negligible_pivot`], the test of the dense LU).
    pub fn factor_regular(band: &BandOrder, entries: &[(usize, usize, f64)]) -> Option<BandLu> {
        let n = band.order.len();
        let mut column_max = vec![0.0f64; n];
        for &(_, j, v) in entries {
            let c = column_max.get_mut(j)?;
            *c = c.max(v.abs());
        }
        let lu = BandLu::factor_entries(band, entries.iter().copied())?;
        let singular =
            (0..n).any(|k| negligible_pivot(lu.ab[lu.at(k, k)], n, column_max[lu.order[k]]));
        (!singular).then_some(lu)
    }

    /// Largest and smallest |u_kk|.
    pub fn pivot_range(&self) -> (f64, f64) {
        (0..self.n)
            .map(|k| self.ab[self.at(k, k)].abs())
            .fold((f64::INFINITY, 0.0_f64), |(lo, hi), d| {
                (lo.min(d), hi.max(d))
            })
    }

    /// Solves A x = b in place; false on a zero pivot.
    pub fn solve_mut(&self, b: &mut [f64]) -> bool {
        let c = &self.columns;
        let mut x: Vec<f64> = self.order.iter().map(|&o| b[o]).collect();
        for k in 0..self.n {
            x.swap(k, self.pivots[k]);
            let xk = x[k];
            if xk != 0.0 {
                for &(i, l) in &c.lower[c.lower_starts[k]..c.lower_starts[k + 1]] {
                    x[i] -= l * xk;
                }
            }
        }
        for j in (0..self.n).rev() {
            let inverse = c.inverse_pivots[j];
            if inverse.is_infinite() {
                return false;
            }
            x[j] *= inverse;
            let xj = x[j];
            if xj != 0.0 {
                for &(i, u) in &c.upper[c.upper_starts[j]..c.upper_starts[j + 1]] {
                    x[i] -= u * xj;
                }
            }
        }
        for (k, &o) in self.order.iter().enumerate() {
            b[o] = x[k];
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A saddle-point matrix of a chain (zero diagonal on the constraint rows, so pivoting is
    /// needed) solved in a scrambled order: the band solve equals the dense LU solve.
    #[test]
    fn a_band_solve_with_row_interchanges_equals_the_dense_solve() {
        let n = 6;
        let m = 5;
        let size = n + m;
        let mut a = DMatrix::<f64>::zeros(size, size);
        for i in 0..n {
            a[(i, i)] = 2.0 + i as f64 * 0.1;
            if i + 1 < n {
                a[(i, i + 1)] = 0.3;
                a[(i + 1, i)] = 0.3;
            }
        }
        for q in 0..m {
            for (j, g) in [(q, 1.0 + 0.2 * q as f64), (q + 1, -0.7)] {
                a[(n + q, j)] = g;
                a[(j, n + q)] = g;
            }
        }
        let adjacent: Vec<Vec<usize>> = (0..size)
            .map(|i| (0..size).filter(|&j| j != i && a[(i, j)] != 0.0).collect())
            .collect();
        let order = reverse_cuthill_mckee(&adjacent);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..size).collect::<Vec<_>>());
        let pos: Vec<usize> = {
            let mut p = vec![0; size];
            for (k, &o) in order.iter().enumerate() {
                p[o] = k;
            }
            p
        };
        let (mut kl, mut ku) = (0, 0);
        for i in 0..size {
            for j in 0..size {
                if a[(i, j)] != 0.0 {
                    if pos[i] > pos[j] {
                        kl = kl.max(pos[i] - pos[j]);
                    } else {
                        ku = ku.max(pos[j] - pos[i]);
                    }
                }
            }
        }
        assert!(kl < size / 2 && ku < size / 2, "kl {kl}, ku {ku}");
        let lu = BandLu::factor(&a, &BandOrder { order, kl, ku });
        let b: Vec<f64> = (0..size).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut x = b.clone();
        assert!(lu.solve_mut(&mut x));
        let dense = a
            .clone()
            .lu()
            .solve(&nalgebra::DVector::from_column_slice(&b))
            .expect("regular");
        for (u, v) in x.iter().zip(dense.iter()) {
            assert!((u - v).abs() < 1e-13, "{u} vs {v}");
        }
        // Read back as a checkpoint stores it (its columns are not stored but gathered again):
        // the same factorisation and the same solve to the last bit.
        let bytes = rmp_serde::to_vec_named(&lu).expect("serialised");
        let back: BandLu = rmp_serde::from_slice(&bytes).expect("read back");
        assert_eq!(back, lu);
        assert_eq!(back.fault(size), None);
        let mut y = b.clone();
        assert!(back.solve_mut(&mut y));
        assert_eq!(
            y.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            x.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
        // A stored band that does not fit its entries is refused, not gathered.
        let mut wrong = lu.clone();
        wrong.kl += 1;
        let bytes = rmp_serde::to_vec_named(&wrong).expect("serialised");
        let back: BandLu = rmp_serde::from_slice(&bytes).expect("read back");
        assert!(back.fault(size).is_some());
    }
}
