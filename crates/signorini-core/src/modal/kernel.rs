//! Kernels of `S_T = A_c^p A_f^m − I` (9) and of the two-contact-phase product (18).
//!
//! One WFEM step is a signed permutation of the 2N characteristic values (see [`crate::wfem`]),
//! so any product of A_f and A_c is a signed permutation `x'[π(k)] = s_k x[k]`. Its fixed
//! vectors live on the cycles of π: a cycle carries a kernel vector iff the product of the signs
//! around it is +1, and the vector is then ±1 along the cycle. This gives the kernel in O(N)
//! per (m, p) ([`SignedPermutation::kernel_basis`]); for the one-phase rotation a closed form
//! gives its dimension in O(1) ([`kernel_dim_closed_form`]). A dense path builds A_f, A_c from
//! the paper's (36)–(39) and counts the zero singular values of `S_T` (nalgebra SVD).

use crate::scenes::LeftEnd;
use crate::wfem::{EndCondition, WaveBar, flux_form_step};
use nalgebra::DMatrix;

/// A signed permutation of `len` ring positions: `(P x)[target[k]] = sign[k] · x[k]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SignedPermutation {
    /// π(k).
    pub target: Vec<usize>,
    /// s_k ∈ {−1, +1}.
    pub sign: Vec<i8>,
}

/// Number of i ∈ [0, steps) with (k + i) ≡ r (mod n2).
fn hits(k: usize, steps: usize, r: usize, n2: usize) -> usize {
    let first = (r + n2 - k % n2) % n2;
    if steps > first {
        (steps - 1 - first) / n2 + 1
    } else {
        0
    }
}

impl SignedPermutation {
    /// The identity on `len` positions.
    pub fn identity(len: usize) -> Self {
        SignedPermutation {
            target: (0..len).collect(),
            sign: vec![1; len],
        }
    }

    /// `A^steps` for a bar of `cells` cells with the given left end and contact-end condition:
    /// every value moves `steps` positions along the ring, picking up the left-end sign
    /// (+1 fixed, −1 free) at each 2N−1 → 0 crossing and the right-end sign (+1 contact, −1
    /// free) at each N−1 → N crossing.
    pub fn phase(cells: usize, left: LeftEnd, end: EndCondition, steps: usize) -> Self {
        let n2 = 2 * cells;
        let s_left: i8 = if left == LeftEnd::Fixed { 1 } else { -1 };
        let s_right: i8 = if end == EndCondition::Contact { 1 } else { -1 };
        let mut target = Vec::with_capacity(n2);
        let mut sign = Vec::with_capacity(n2);
        for k in 0..n2 {
            target.push((k + steps) % n2);
            let right = hits(k, steps, cells - 1, n2);
            let left_hits = hits(k, steps, n2 - 1, n2);
            let mut s: i8 = 1;
            if right % 2 == 1 {
                s *= s_right;
            }
            if left_hits % 2 == 1 {
                s *= s_left;
            }
            sign.push(s);
        }
        SignedPermutation { target, sign }
    }

    /// `other ∘ self` (apply `self` first).
    pub fn then(&self, other: &SignedPermutation) -> SignedPermutation {
        let target = self.target.iter().map(|&t| other.target[t]).collect();
        let sign = self
            .sign
            .iter()
            .zip(&self.target)
            .map(|(&s, &t)| s * other.sign[t])
            .collect();
        SignedPermutation { target, sign }
    }

    /// The product of the phases, applied in order (e.g. `[(Free, m), (Contact, p)]` is
    /// `A_c^p A_f^m`, (8); four phases give (18)).
    pub fn product(cells: usize, left: LeftEnd, phases: &[(EndCondition, usize)]) -> Self {
        phases.iter().fold(
            SignedPermutation::identity(2 * cells),
            |acc, &(end, steps)| acc.then(&SignedPermutation::phase(cells, left, end, steps)),
        )
    }

    /// P x.
    pub fn apply(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; x.len()];
        for (k, &xk) in x.iter().enumerate() {
            y[self.target[k]] = f64::from(self.sign[k]) * xk;
        }
        y
    }

    /// A basis of ker(P − I) from the cycles of π: one ±1 vector per cycle whose sign product
    /// is +1, supported on that cycle. O(len).
    pub fn kernel_basis(&self) -> Vec<Vec<f64>> {
        let n = self.target.len();
        let mut seen = vec![false; n];
        let mut basis = Vec::new();
        for start in 0..n {
            if seen[start] {
                continue;
            }
            let mut members = Vec::new();
            let mut product: i8 = 1;
            let mut k = start;
            while !seen[k] {
                seen[k] = true;
                members.push(k);
                product *= self.sign[k];
                k = self.target[k];
            }
            if product == 1 {
                let mut x = vec![0.0; n];
                let mut value = 1.0;
                for &k in &members {
                    x[k] = value;
                    value *= f64::from(self.sign[k]);
                }
                basis.push(x);
            }
        }
        basis
    }

    /// dim ker(P − I): the number of cycles with sign product +1. O(len).
    pub fn kernel_dim(&self) -> usize {
        let n = self.target.len();
        let mut seen = vec![false; n];
        let mut dim = 0;
        for start in 0..n {
            if seen[start] {
                continue;
            }
            let mut product: i8 = 1;
            let mut k = start;
            while !seen[k] {
                seen[k] = true;
                product *= self.sign[k];
                k = self.target[k];
            }
            dim += usize::from(product == 1);
        }
        dim
    }
}

fn gcd(mut a: usize, mut b: usize) -> usize {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

/// dim ker(A_c^p A_f^m − I) for a fixed left end, in O(1).
///
/// The product rotates the ring by r = (m + p) mod 2N, so its cycles are the d = gcd(r, 2N)
/// residue classes mod d. Only right-end crossings during the free phase flip signs; the value
/// starting at position k crosses at the steps i ∈ [0, m) with k + i ≡ N − 1 (mod 2N), so the
/// flips of the cycle c add up to #{i ∈ [0, m) : i ≡ N − 1 − c (mod d)}, which is ⌊m/d⌋ + 1 for
/// m mod d residues and ⌊m/d⌋ for the others. The cycles with an even count carry the kernel.
pub fn kernel_dim_closed_form(cells: usize, m: usize, p: usize) -> usize {
    let n2 = 2 * cells;
    let r = (m + p) % n2;
    let d = if r == 0 { n2 } else { gcd(r, n2) };
    let (q, rem) = (m / d, m % d);
    if q % 2 == 0 { d - rem } else { rem }
}

/// The dense WFEM matrix A (40), (45) of one step in the ordering (σ_1…σ_N, v_1…v_N), built
/// column by column from the paper's (36)–(39).
pub fn dense_matrix(bar: &WaveBar, end: EndCondition) -> DMatrix<f64> {
    let n = bar.cells;
    let mut a = DMatrix::zeros(2 * n, 2 * n);
    for j in 0..2 * n {
        let mut sigma = vec![0.0; n];
        let mut v = vec![0.0; n];
        if j < n {
            sigma[j] = 1.0;
        } else {
            v[j - n] = 1.0;
        }
        let (s, w) = flux_form_step(bar, &sigma, &v, end);
        for i in 0..n {
            a[(i, j)] = s[i];
            a[(n + i, j)] = w[i];
        }
    }
    a
}

/// Dense kernel dimension of `S − I` by SVD: singular values below `tol` count as zero.
pub fn dense_kernel_dim(s: &DMatrix<f64>, tol: f64) -> usize {
    let n = s.nrows();
    let m = s - DMatrix::<f64>::identity(n, n);
    m.singular_values_unordered()
        .iter()
        .filter(|&&x| x < tol)
        .count()
}
