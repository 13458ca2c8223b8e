//! Sparse matrices as the list of their structural nonzeros (row, column, value), the form in
//! which a model hands its matrices to an integrator that never needs them dense: the mass
//! matrix, the force and joint Jacobians and their derivatives of a `lagrangian` model are
//! evaluated from sparse tapes that store only their nonzeros ([`crate::expr::tape`]), and the
//! integrator multiplies with them or assembles its band Newton matrix from them
//! ([`crate::soi2::banded::BandLu::factor_entries`]) in time linear in the nonzeros.
//!
//! A position may appear more than once: its values add up (as when a Newton matrix is the sum
//! of several model matrices). The list is cleared and refilled at every evaluation, keeping its
//! allocation.

/// A rows×cols sparse matrix as (row, column, value) entries; repeated positions add up.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Triplets {
    rows: usize,
    cols: usize,
    entries: Vec<(usize, usize, f64)>,
}

impl Triplets {
    /// The rows×cols zero matrix (no entry).
    pub fn new(rows: usize, cols: usize) -> Self {
        Self {
            rows,
            cols,
            entries: Vec::new(),
        }
    }

    /// The nonzero entries of the row-major rows×cols matrix `a` (all of them when
    /// `structural` is true, zeros included: the structure of a model matrix that happens to
    /// vanish at this point).
    pub fn from_dense(rows: usize, cols: usize, a: &[f64], structural: bool) -> Self {
        let mut t = Self::new(rows, cols);
        t.extend_dense(a, structural);
        t
    }

    /// Appends the entries of the row-major rows×cols matrix `a`, as [`Triplets::from_dense`].
    pub fn extend_dense(&mut self, a: &[f64], structural: bool) {
        let cols = self.cols.max(1);
        self.entries.extend(
            a.iter()
                .take(self.rows * self.cols)
                .enumerate()
                .filter(|&(_, &v)| structural || v != 0.0)
                .map(|(k, &v)| (k / cols, k % cols, v)),
        );
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Number of columns.
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// The entries, in the order they were pushed.
    pub fn entries(&self) -> &[(usize, usize, f64)] {
        &self.entries
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether there is no entry.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Makes room for `additional` more entries.
    pub fn reserve(&mut self, additional: usize) {
        self.entries.reserve(additional);
    }

    /// Removes every entry, keeping the allocation and the shape.
    pub fn clear(&mut self) {
        self.entries.clear();
    }

    /// Adds `value` at (i, j).
    ///
    /// Panics if (i, j) is outside the matrix (positions come from the model's structure, not
    /// from user input).
    pub fn push(&mut self, i: usize, j: usize, value: f64) {
        assert!(
            i < self.rows && j < self.cols,
            "entry ({i}, {j}) outside a {}×{} matrix",
            self.rows,
            self.cols
        );
        self.entries.push((i, j, value));
    }

    /// y += A x.
    pub fn mul_add(&self, x: &[f64], y: &mut [f64]) {
        for &(i, j, v) in &self.entries {
            y[i] += v * x[j];
        }
    }

    /// y += Aᵀ x.
    pub fn tr_mul_add(&self, x: &[f64], y: &mut [f64]) {
        for &(i, j, v) in &self.entries {
            y[j] += v * x[i];
        }
    }

    /// xᵀ A x (A square).
    pub fn quadratic(&self, x: &[f64]) -> f64 {
        self.entries.iter().map(|&(i, j, v)| x[i] * v * x[j]).sum()
    }

    /// The matrix, row-major rows×cols.
    pub fn to_dense(&self) -> Vec<f64> {
        let mut a = vec![0.0; self.rows * self.cols];
        self.add_to_dense(1.0, &mut a);
        a
    }

    /// a += s A for the row-major rows×cols matrix `a`.
    pub fn add_to_dense(&self, s: f64, a: &mut [f64]) {
        for &(i, j, v) in &self.entries {
            a[i * self.cols + j] += s * v;
        }
    }

    /// The first entry that is not finite: its row-major index i·cols + j and its value.
    pub fn first_non_finite(&self) -> Option<(usize, f64)> {
        self.entries
            .iter()
            .find(|e| !e.2.is_finite())
            .map(|&(i, j, v)| (i * self.cols + j, v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn products_and_the_dense_form_add_repeated_positions() {
        let mut a = Triplets::new(2, 3);
        a.push(0, 0, 1.0);
        a.push(1, 2, 2.0);
        a.push(0, 0, 0.5);
        a.push(1, 1, -3.0);
        assert_eq!(a.to_dense(), vec![1.5, 0.0, 0.0, 0.0, -3.0, 2.0]);
        let mut sq = Triplets::new(2, 2);
        sq.push(0, 0, 2.0);
        sq.push(0, 1, 1.0);
        sq.push(1, 0, 1.0);
        sq.push(1, 1, 3.0);
        sq.push(1, 1, 0.5);
        // M = [[2, 1], [1, 3.5]], x = (1, −2): 2 − 4 + 14 = 12.
        assert_eq!(sq.quadratic(&[1.0, -2.0]), 12.0);
        let mut y = vec![1.0, 1.0];
        a.mul_add(&[1.0, 2.0, 3.0], &mut y);
        assert_eq!(y, vec![2.5, 1.0 - 6.0 + 6.0]);
        let mut z = vec![0.0; 3];
        a.tr_mul_add(&[2.0, -1.0], &mut z);
        assert_eq!(z, vec![3.0, 3.0, -2.0]);
        let b = Triplets::from_dense(2, 3, &a.to_dense(), false);
        assert_eq!(b.entries().len(), 3);
        assert_eq!(b.to_dense(), a.to_dense());
        assert_eq!(
            Triplets::from_dense(2, 3, &a.to_dense(), true)
                .entries()
                .len(),
            6
        );
        a.push(0, 1, f64::NAN);
        assert_eq!(a.first_non_finite().map(|(k, _)| k), Some(1));
        a.clear();
        assert_eq!((a.rows(), a.cols(), a.entries().len()), (2, 3, 0));
    }
}
