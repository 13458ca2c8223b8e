//! Symmetric banded matrices and their Cholesky factorisation.
//!
//! Mass, damping and stiffness matrices of 1D finite elements and chains are banded (bandwidth 1
//! for linear elements, 0 for a lumped mass); storing only the lower band makes products and
//! solves O(n · bandwidth). A dense symmetric matrix is the special case bandwidth = n − 1.

use std::sync::OnceLock;
use thiserror::Error;

/// Symmetric matrix stored by its lower band, one diagonal after the other: diagonal k
/// (k = 0 ..= kd) holds `A[i][i−k]` at position i (positions i < k unused). Products and quadratic
/// forms then run along contiguous diagonals, which the compiler vectorises.
#[derive(Debug, Clone, PartialEq)]
pub struct SymBand {
    n: usize,
    kd: usize,
    /// Diagonal k at `[k n, (k+1) n)`.
    data: Vec<f64>,
    /// Row sums s_i = Σ_j A_ij, computed on first use by [`SymBand::quad`].
    row_sums: OnceLock<Vec<f64>>,
}

/// Why a symmetric band matrix could not be built or factorised.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum BandError {
    /// The matrix is not symmetric positive definite: pivot `row` was `pivot` ≤ 0.
    #[error("not positive definite (pivot {pivot:e} at row {row})")]
    NotPositiveDefinite {
        /// Row where the factorisation broke down.
        row: usize,
        /// The non-positive pivot.
        pivot: f64,
    },
    /// Entry (i, j) differs from entry (j, i).
    #[error("not symmetric: entry ({i},{j}) = {a:e} but ({j},{i}) = {b:e}")]
    NotSymmetric {
        /// Row.
        i: usize,
        /// Column.
        j: usize,
        /// Entry (i, j).
        a: f64,
        /// Entry (j, i).
        b: f64,
    },
    /// An entry is NaN or infinite.
    #[error("entry ({i},{j}) is not finite")]
    NotFinite {
        /// Row.
        i: usize,
        /// Column.
        j: usize,
    },
    /// A row has the wrong length, or a triplet is out of range.
    #[error("expected a {n}×{n} matrix: {what}")]
    Shape {
        /// Expected order.
        n: usize,
        /// What was wrong.
        what: String,
    },
    /// Order and bandwidth need more stored entries than [`MAX_STORED_ENTRIES`].
    #[error(
        "order {n} with half-bandwidth {kd} needs {entries:.2e} stored entries, more than the {max:.2e} allowed (1 GiB)",
        entries = (*n as f64) * (*kd as f64 + 1.0),
        max = MAX_STORED_ENTRIES as f64
    )]
    TooLarge {
        /// Order.
        n: usize,
        /// Half-bandwidth.
        kd: usize,
    },
}

/// Most entries a matrix given as triplets may need in band storage, n · (kd + 1): 2²⁷ (1 GiB of
/// f64). Checked before anything is allocated: a three-triplet spec naming row 10⁵ and column 0
/// would otherwise ask for 80 GB.
pub const MAX_STORED_ENTRIES: usize = 1 << 27;

impl SymBand {
    /// The n×n zero matrix with half-bandwidth `kd`.
    pub fn zeros(n: usize, kd: usize) -> Self {
        let kd = kd.min(n.saturating_sub(1));
        Self {
            n,
            kd,
            data: vec![0.0; n * (kd + 1)],
            row_sums: OnceLock::new(),
        }
    }

    /// Diagonal matrix.
    pub fn diagonal(d: &[f64]) -> Self {
        Self {
            n: d.len(),
            kd: 0,
            data: d.to_vec(),
            row_sums: OnceLock::new(),
        }
    }

    /// From dense rows; the bandwidth is found from the non-zeros. Checks shape, finiteness and
    /// symmetry (to a relative tolerance of 1e-12 of the largest entry).
    pub fn from_dense_rows(rows: &[Vec<f64>]) -> Result<Self, BandError> {
        let n = rows.len();
        let mut kd = 0;
        let mut scale = 0.0f64;
        for (i, r) in rows.iter().enumerate() {
            if r.len() != n {
                return Err(BandError::Shape {
                    n,
                    what: format!("row {i} has {} entries", r.len()),
                });
            }
            for (j, &a) in r.iter().enumerate() {
                if !a.is_finite() {
                    return Err(BandError::NotFinite { i, j });
                }
                if a != 0.0 {
                    kd = kd.max(i.abs_diff(j));
                }
                scale = scale.max(a.abs());
            }
        }
        for (i, row) in rows.iter().enumerate() {
            for (j, &a) in row.iter().enumerate().take(i) {
                let b = rows[j][i];
                if (a - b).abs() > 1e-12 * scale {
                    return Err(BandError::NotSymmetric { i, j, a, b });
                }
            }
        }
        let mut m = Self::zeros(n, kd);
        for (i, row) in rows.iter().enumerate() {
            for (j, &a) in row
                .iter()
                .enumerate()
                .take(i + 1)
                .skip(i.saturating_sub(kd))
            {
                m.set(i, j, a);
            }
        }
        Ok(m)
    }

    /// From (row, column, value) triplets; repeated entries add up (finite-element assembly).
    /// Both triangles may be given, and must then agree; a triplet in one triangle only stands
    /// for both.
    pub fn from_triplets(n: usize, triplets: &[(usize, usize, f64)]) -> Result<Self, BandError> {
        let mut lower = std::collections::BTreeMap::<(usize, usize), f64>::new();
        let mut upper = std::collections::BTreeMap::<(usize, usize), f64>::new();
        for &(i, j, a) in triplets {
            if i >= n || j >= n {
                return Err(BandError::Shape {
                    n,
                    what: format!("triplet ({i},{j}) is out of range"),
                });
            }
            if !a.is_finite() {
                return Err(BandError::NotFinite { i, j });
            }
            if j <= i {
                *lower.entry((i, j)).or_default() += a;
            } else {
                *upper.entry((j, i)).or_default() += a;
            }
        }
        let scale = lower
            .values()
            .chain(upper.values())
            .fold(0.0f64, |s, a| s.max(a.abs()));
        let mut merged = lower.clone();
        for (&(i, j), &b) in &upper {
            match lower.get(&(i, j)) {
                Some(&a) if (a - b).abs() > 1e-12 * scale => {
                    return Err(BandError::NotSymmetric { i, j, a, b });
                }
                Some(_) => {}
                None => {
                    merged.insert((i, j), b);
                }
            }
        }
        let kd = merged
            .iter()
            .filter(|(_, a)| **a != 0.0)
            .map(|(&(i, j), _)| i - j)
            .max()
            .unwrap_or(0);
        if n.saturating_mul(kd + 1) > MAX_STORED_ENTRIES {
            return Err(BandError::TooLarge { n, kd });
        }
        let mut m = Self::zeros(n, kd);
        for (&(i, j), &a) in &merged {
            if a != 0.0 {
                m.set(i, j, a);
            }
        }
        Ok(m)
    }

    /// Order n.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Half-bandwidth.
    pub fn kd(&self) -> usize {
        self.kd
    }

    /// Diagonal k: entry i is A[i][i−k] (entries i < k are zero).
    fn diag(&self, k: usize) -> &[f64] {
        &self.data[k * self.n..(k + 1) * self.n]
    }

    /// Entry (i, j) (either triangle).
    pub fn get(&self, i: usize, j: usize) -> f64 {
        let (i, j) = if j > i { (j, i) } else { (i, j) };
        if i - j > self.kd {
            0.0
        } else {
            self.data[(i - j) * self.n + i]
        }
    }

    /// Sets entry (i, j) and its mirror. Panics if (i, j) is outside the band (a programming
    /// error: builders size the band first).
    pub fn set(&mut self, i: usize, j: usize, a: f64) {
        let (i, j) = if j > i { (j, i) } else { (i, j) };
        assert!(i - j <= self.kd, "entry ({i},{j}) outside band {}", self.kd);
        self.data[(i - j) * self.n + i] = a;
        self.row_sums = OnceLock::new();
    }

    /// Adds `a` to entry (i, j) (and its mirror).
    pub fn add(&mut self, i: usize, j: usize, a: f64) {
        let v = self.get(i, j);
        self.set(i, j, v + a);
    }

    /// Σ c_t A_t with the largest bandwidth (e.g. Ŵ = M + θhC + θ²h²K).
    pub fn combine(terms: &[(f64, &SymBand)]) -> SymBand {
        let n = terms.first().map_or(0, |t| t.1.n);
        let kd = terms
            .iter()
            .filter(|t| t.0 != 0.0)
            .map(|t| t.1.kd)
            .max()
            .unwrap_or(0);
        let mut out = SymBand::zeros(n, kd);
        for &(c, m) in terms {
            if c == 0.0 {
                continue;
            }
            for k in 0..=m.kd {
                for (o, a) in out.data[k * n..(k + 1) * n].iter_mut().zip(m.diag(k)) {
                    *o += c * a;
                }
            }
        }
        out
    }

    /// True when every entry is zero.
    pub fn is_zero(&self) -> bool {
        self.data.iter().all(|&a| a == 0.0)
    }

    /// y = A x, O(n · kd); a tridiagonal matrix in one sweep.
    pub fn mul_into(&self, x: &[f64], y: &mut [f64]) {
        let n = self.n;
        let (x, y) = (&x[..n], &mut y[..n]);
        if self.kd == 1 && n >= 2 {
            tridiagonal_mul(self.diag(0), self.diag(1), x, y);
            return;
        }
        for ((yi, a), xi) in y.iter_mut().zip(self.diag(0)).zip(x) {
            *yi = a * xi;
        }
        for k in 1..=self.kd {
            let d = &self.diag(k)[k..];
            for ((yi, a), xj) in y[k..].iter_mut().zip(d).zip(&x[..n - k]) {
                *yi += a * xj;
            }
            for ((yj, a), xi) in y[..n - k].iter_mut().zip(d).zip(&x[k..]) {
                *yj += a * xi;
            }
        }
    }

    /// xᵀ A y, O(n · kd), without a temporary, in the difference form
    ///
    /// ```text
    /// xᵀ A y = Σ_i s_i x_i y_i − Σ_{i>j} A_ij (x_i − x_j)(y_i − y_j),   s_i = Σ_j A_ij,
    /// ```
    ///
    /// algebraically equal to the plain sum but free of the cancellation the plain sum suffers
    /// when a stiffness matrix (small row sums) meets a large rigid-body displacement: a free
    /// bar translated by 5 m would otherwise lose 8 digits of its strain energy.
    pub fn quad(&self, x: &[f64], y: &[f64]) -> f64 {
        let n = self.n;
        let (x, y) = (&x[..n], &y[..n]);
        let sums = self.row_sums();
        if self.kd == 1 && n >= 2 {
            return tridiagonal_quad(sums, self.diag(1), x, y);
        }
        let mut total = sum_products(sums, x, y);
        for k in 1..=self.kd {
            total -= sum_difference_products(&self.diag(k)[k..], x, y, k);
        }
        total
    }

    /// Row sums s_i = Σ_j A_ij (the weights of the difference form of [`SymBand::quad`]),
    /// computed once.
    pub fn row_sums(&self) -> &[f64] {
        let n = self.n;
        self.row_sums.get_or_init(|| {
            let mut s = self.diag(0).to_vec();
            for k in 1..=self.kd {
                let d = &self.diag(k)[k..];
                for (si, a) in s[k..].iter_mut().zip(d) {
                    *si += a;
                }
                for (sj, a) in s[..n - k].iter_mut().zip(d) {
                    *sj += a;
                }
            }
            s
        })
    }

    /// Sub-diagonal k ≤ kd as a slice of length n: entry i is A[i][i−k] (entries i < k are zero).
    /// Diagonal 0 is the main diagonal.
    pub fn band(&self, k: usize) -> &[f64] {
        self.diag(k)
    }

    /// Factorisation A = L D Lᵀ (L unit lower triangular with the same band, D > 0).
    /// Fails with [`BandError::NotPositiveDefinite`] when a pivot is not positive.
    pub fn cholesky(&self) -> Result<BandCholesky, BandError> {
        let (n, kd) = (self.n, self.kd);
        let mut l = vec![0.0; n * (kd + 1)];
        let mut d = vec![0.0; n];
        for i in 0..n {
            let j0 = i.saturating_sub(kd);
            for j in j0..i {
                // L[i][j] = (A[i][j] − Σ_{m<j} L[i][m] D[m] L[j][m]) / D[j]
                let mut s = self.data[(i - j) * n + i];
                for m in j0.max(j.saturating_sub(kd))..j {
                    s -= l[(i - m) * n + i] * d[m] * l[(j - m) * n + j];
                }
                l[(i - j) * n + i] = s / d[j];
            }
            let mut p = self.data[i];
            for m in j0..i {
                let lim = l[(i - m) * n + i];
                p -= lim * lim * d[m];
            }
            if p <= 0.0 || !p.is_finite() {
                return Err(BandError::NotPositiveDefinite { row: i, pivot: p });
            }
            d[i] = p;
        }
        let inv_d = d.iter().map(|p| 1.0 / p).collect();
        let twisted = (kd == 1).then(|| Twisted::new(self)).flatten();
        Ok(BandCholesky {
            n,
            kd,
            l,
            inv_d,
            twisted,
        })
    }
}

/// y = A x for a tridiagonal A (diagonal `a0`, sub-diagonal `a1`, `a1[i]` = A[i][i−1]), n ≥ 2,
/// in one sweep: y_i = a1_i x_{i−1} + a0_i x_i + a1_{i+1} x_{i+1}.
fn tridiagonal_mul(a0: &[f64], a1: &[f64], x: &[f64], y: &mut [f64]) {
    let n = x.len();
    y[0] = a0[0] * x[0] + a1[1] * x[1];
    y[n - 1] = a1[n - 1] * x[n - 2] + a0[n - 1] * x[n - 1];
    for (((((yi, lo), di), up), xl), (xi, xu)) in y[1..n - 1]
        .iter_mut()
        .zip(&a1[1..n - 1])
        .zip(&a0[1..n - 1])
        .zip(&a1[2..])
        .zip(&x[..n - 2])
        .zip(x[1..n - 1].iter().zip(&x[2..]))
    {
        *yi = lo * xl + di * xi + up * xu;
    }
}

/// Σ_i s_i x_i y_i in four interleaved partial sums: consecutive additions do not wait for each
/// other (a single running sum is bound by the latency of one addition per term). Differs from
/// the plain sum by round-off only.
fn sum_products(s: &[f64], x: &[f64], y: &[f64]) -> f64 {
    let n = s.len().min(x.len()).min(y.len());
    let (sc, xc, yc) = (
        s[..n].chunks_exact(4),
        x[..n].chunks_exact(4),
        y[..n].chunks_exact(4),
    );
    let mut tail = 0.0;
    for ((a, b), c) in sc
        .remainder()
        .iter()
        .zip(xc.remainder())
        .zip(yc.remainder())
    {
        tail += a * b * c;
    }
    let mut acc = [0.0; 4];
    for ((a, b), c) in sc.zip(xc).zip(yc) {
        for l in 0..4 {
            acc[l] += a[l] * b[l] * c[l];
        }
    }
    (acc[0] + acc[2]) + (acc[1] + acc[3]) + tail
}

/// The difference form of [`SymBand::quad`] for a tridiagonal matrix in one sweep:
/// `s_0 x_0 y_0 + Σ_{i ≥ 1} [s_i x_i y_i − a1_i (x_i − x_{i−1})(y_i − y_{i−1})]`, four partial
/// sums.
fn tridiagonal_quad(s: &[f64], a1: &[f64], x: &[f64], y: &[f64]) -> f64 {
    let n = x.len();
    let term = |s: f64, a: f64, xi: f64, xj: f64, yi: f64, yj: f64| {
        s * xi * yi - a * (xi - xj) * (yi - yj)
    };
    let m = n - 1;
    let (sc, ac, xh, xl, yh, yl) = (
        s[1..n].chunks_exact(4),
        a1[1..n].chunks_exact(4),
        x[1..n].chunks_exact(4),
        x[..m].chunks_exact(4),
        y[1..n].chunks_exact(4),
        y[..m].chunks_exact(4),
    );
    let mut tail = s[0] * x[0] * y[0];
    for (((((s, a), xi), xj), yi), yj) in sc
        .remainder()
        .iter()
        .zip(ac.remainder())
        .zip(xh.remainder())
        .zip(xl.remainder())
        .zip(yh.remainder())
        .zip(yl.remainder())
    {
        tail += term(*s, *a, *xi, *xj, *yi, *yj);
    }
    let mut acc = [0.0; 4];
    for (((((s, a), xi), xj), yi), yj) in sc.zip(ac).zip(xh).zip(xl).zip(yh).zip(yl) {
        for l in 0..4 {
            acc[l] += term(s[l], a[l], xi[l], xj[l], yi[l], yj[l]);
        }
    }
    (acc[0] + acc[2]) + (acc[1] + acc[3]) + tail
}

/// Σ_{i ≥ k} d_{i−k} (x_i − x_{i−k})(y_i − y_{i−k}) (`d` = diagonal k from row k on), in four
/// partial sums like [`sum_products`].
fn sum_difference_products(d: &[f64], x: &[f64], y: &[f64], k: usize) -> f64 {
    let m = d.len();
    let (dc, xh, xl, yh, yl) = (
        d.chunks_exact(4),
        x[k..k + m].chunks_exact(4),
        x[..m].chunks_exact(4),
        y[k..k + m].chunks_exact(4),
        y[..m].chunks_exact(4),
    );
    let mut tail = 0.0;
    for ((((a, xi), xj), yi), yj) in dc
        .remainder()
        .iter()
        .zip(xh.remainder())
        .zip(xl.remainder())
        .zip(yh.remainder())
        .zip(yl.remainder())
    {
        tail += a * (xi - xj) * (yi - yj);
    }
    let mut acc = [0.0; 4];
    for ((((a, xi), xj), yi), yj) in dc.zip(xh).zip(xl).zip(yh).zip(yl) {
        for l in 0..4 {
            acc[l] += a[l] * (xi[l] - xj[l]) * (yi[l] - yj[l]);
        }
    }
    (acc[0] + acc[2]) + (acc[1] + acc[3]) + tail
}

/// Twisted ("burn at both ends") factorisation of a tridiagonal SPD matrix, A = N Γ Nᵀ with
/// twist index m = ⌊n/2⌋: rows above m are those of the L D Lᵀ factor from the top, rows below m
/// those of the U Δ Uᵀ factor from the bottom, and row m joins them (Parlett & Dhillon, *Fernando's
/// solution to Wilkinson's problem*, Linear Algebra Appl. 267:247–279, 1997, §3,
/// doi:10.1016/S0024-3795(97)80053-2). A solve then runs two independent recurrences per sweep,
/// one from each end towards m and back, so each sweep waits for n/2 dependent steps instead of
/// n: the triangular solves are latency-bound, so this halves their cost.
#[derive(Debug, Clone)]
struct Twisted {
    m: usize,
    /// l_i = A[i][i−1]/d_{i−1} for 1 ≤ i ≤ m, 0 elsewhere.
    lo: Vec<f64>,
    /// u_i = A[i+1][i]/δ_{i+1} for m ≤ i ≤ n−2, 0 elsewhere.
    up: Vec<f64>,
    /// 1/d_i (i < m), 1/γ_m (i = m), 1/δ_i (i > m).
    inv: Vec<f64>,
}

impl Twisted {
    /// Factorises a tridiagonal matrix; `None` if a pivot is not positive and finite (the
    /// caller then keeps the one-sided L D Lᵀ factor).
    fn new(a: &SymBand) -> Option<Self> {
        let n = a.n;
        if n == 0 {
            return None;
        }
        let (diag, sub) = (a.diag(0), a.diag(1));
        let ok = |p: f64| p > 0.0 && p.is_finite();
        let m = n / 2;
        let (mut lo, mut up, mut inv) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        // From the top: d_0 = a_0, l_i = e_i/d_{i−1}, d_i = a_i − l_i e_i (e_i = A[i][i−1]).
        let mut d = diag[0];
        for i in 1..=m {
            if !ok(d) {
                return None;
            }
            inv[i - 1] = 1.0 / d;
            lo[i] = sub[i] / d;
            d = diag[i] - lo[i] * sub[i];
        }
        // From the bottom: δ_{n−1} = a_{n−1}, u_j = e_{j+1}/δ_{j+1}, δ_j = a_j − u_j e_{j+1}.
        let mut delta = diag[n - 1];
        for j in (m..n - 1).rev() {
            if !ok(delta) {
                return None;
            }
            inv[j + 1] = 1.0 / delta;
            up[j] = sub[j + 1] / delta;
            delta = diag[j] - up[j] * sub[j + 1];
        }
        // γ_m = a_m − l_m e_m − u_m e_{m+1}.
        let gamma = if m + 1 < n { d - up[m] * sub[m + 1] } else { d };
        if !ok(gamma) {
            return None;
        }
        inv[m] = 1.0 / gamma;
        Some(Self { m, lo, up, inv })
    }

    /// Solves A x = b in place: N w = b from both ends, scaled by Γ⁻¹ on the way, then Nᵀ x = Γ⁻¹w
    /// from m outwards. The two chains of each sweep are interleaved in one loop; the back sweep
    /// also adds `c[j] x_i` to `y[j][i]` as it finds x_i (a corrector such as q += c x, work that
    /// hides in the latency of the chains). `y[j]` has at least n elements.
    ///
    /// The back sweep runs on sub-slices of one length, indexed by one counter, so that the
    /// loop holds no bounds checks and no iterator state (with the updates, a chain of zipped,
    /// reversed and enumerated iterators left its state on the stack and doubled the sweep).
    fn solve_axpy<const K: usize>(&self, b: &mut [f64], c: [f64; K], y: [&mut [f64]; K]) {
        let m = self.m;
        let n = b.len();
        let (top, rest) = b.split_at_mut(m);
        let Some((mid, bot)) = rest.split_first_mut() else {
            return;
        };
        let (lo_t, inv_t) = (&self.lo[..m], &self.inv[..m]);
        let (up_b, inv_b) = (&self.up[m + 1..], &self.inv[m + 1..]);
        // w_i = b_i − l_i w_{i−1} (top, l_0 = 0) and w_j = b_j − u_j w_{j+1} (bottom,
        // u_{n−1} = 0), stored as Γ⁻¹ w.
        // (Both chains run min(m, n − 1 − m) steps together; `take` keeps zip from consuming
        // an element of the longer one.)
        let k = top.len().min(bot.len());
        let (mut y0, mut z0) = (0.0, 0.0);
        let mut ti = top.iter_mut().zip(lo_t).zip(inv_t);
        let mut bi = bot.iter_mut().zip(up_b).zip(inv_b).rev();
        for (((bt, l), wt), ((bb, u), wb)) in (&mut ti).take(k).zip((&mut bi).take(k)) {
            y0 = *bt - l * y0;
            z0 = *bb - u * z0;
            *bt = y0 * wt;
            *bb = z0 * wb;
        }
        for ((bt, l), wt) in ti {
            y0 = *bt - l * y0;
            *bt = y0 * wt;
        }
        for ((bb, u), wb) in bi {
            z0 = *bb - u * z0;
            *bb = z0 * wb;
        }
        // Twist row: x_m = (b_m − l_m w_{m−1} − u_m w_{m+1}) / γ_m.
        let xm = (*mid - self.lo[m] * y0 - self.up[m] * z0) * self.inv[m];
        *mid = xm;
        // The updated vectors split like b: dofs below m (`yt`), m, above m (`yb`).
        let mut split = y.map(|v| {
            let (t, r) = v[..n].split_at_mut(m);
            let (v_m, b) = r.split_first_mut().expect("m < n");
            (t, v_m, b)
        });
        for (j, (_, v_m, _)) in split.iter_mut().enumerate() {
            **v_m += c[j] * xm;
        }
        let (mut yt, mut yb) = (
            split.each_mut().map(|(t, _, _)| std::mem::take(t)),
            split.map(|(_, _, b)| b),
        );
        // x_i = Γ⁻¹w_i − l_{i+1} x_{i+1} upwards (i = m − 1 − s) and x_j = Γ⁻¹w_j − u_{j−1} x_{j−1}
        // downwards (j = m + 1 + s), s = 0, 1, …: the first k rows of each side together on
        // slices of length k (the top one read backwards), then what is left of the longer side.
        let (mut xt, mut xb) = (xm, xm);
        {
            let (tt, lt) = (&mut top[m - k..], &self.lo[m - k + 1..=m]);
            let (bb, ub) = (&mut bot[..k], &self.up[m..m + k]);
            let yt: [&mut [f64]; K] = yt.each_mut().map(|v| &mut v[m - k..]);
            let yb: [&mut [f64]; K] = yb.each_mut().map(|v| &mut v[..k]);
            for s in 0..k {
                let i = k - 1 - s;
                xt = tt[i] - lt[i] * xt;
                xb = bb[s] - ub[s] * xb;
                tt[i] = xt;
                bb[s] = xb;
                for j in 0..K {
                    yt[j][i] += c[j] * xt;
                    yb[j][s] += c[j] * xb;
                }
            }
        }
        let r = m - k;
        let (tt, lt) = (&mut top[..r], &self.lo[1..=r]);
        let yt: [&mut [f64]; K] = yt.map(|v| &mut v[..r]);
        for i in (0..r).rev() {
            xt = tt[i] - lt[i] * xt;
            tt[i] = xt;
            for j in 0..K {
                yt[j][i] += c[j] * xt;
            }
        }
        let r = bot.len() - k;
        let (bb, ub) = (&mut bot[k..], &self.up[m + k..m + k + r]);
        let yb: [&mut [f64]; K] = yb.map(|v| &mut v[k..k + r]);
        for s in 0..r {
            xb = bb[s] - ub[s] * xb;
            bb[s] = xb;
            for j in 0..K {
                yb[j][s] += c[j] * xb;
            }
        }
    }
}

/// L D Lᵀ factor of a [`SymBand`]: solves in O(n · kd) with no division (the inverse pivots are
/// stored), a forward and a backward sweep along the band.
#[derive(Debug, Clone)]
pub struct BandCholesky {
    n: usize,
    kd: usize,
    /// Sub-diagonals of L in the storage of [`SymBand`] (diagonal 0 unused: L is unit).
    l: Vec<f64>,
    inv_d: Vec<f64>,
    /// The twisted factor of a tridiagonal matrix, used by the solves (same solution, two
    /// independent recurrences per sweep).
    twisted: Option<Twisted>,
}

impl BandCholesky {
    /// Order n.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Solves A x = b in place (b becomes x).
    pub fn solve_in_place(&self, b: &mut [f64]) {
        self.solve_in_place_axpy(b, [], []);
    }

    /// Solves A x = b in place and adds `c[j] x` to `y[j]` (each of at least n elements): with
    /// the twisted factor in the back sweep, as x_i is found, so that a corrector such as
    /// q += c x costs no sweep of its own.
    pub fn solve_in_place_axpy<const K: usize>(
        &self,
        b: &mut [f64],
        c: [f64; K],
        y: [&mut [f64]; K],
    ) {
        let (n, kd) = (self.n, self.kd);
        let b = &mut b[..n];
        if let Some(t) = &self.twisted {
            t.solve_axpy(b, c, y);
            return;
        }
        match kd {
            0 => {}
            1 => {
                // Tridiagonal: one recurrence each way, no bounds checks.
                let l1 = &self.l[n..2 * n];
                let mut prev = b[0];
                for (bi, li) in b[1..].iter_mut().zip(&l1[1..]) {
                    prev = *bi - li * prev;
                    *bi = prev;
                }
            }
            _ => {
                for i in 1..n {
                    let mut s = b[i];
                    for k in 1..=kd.min(i) {
                        s -= self.l[k * n + i] * b[i - k];
                    }
                    b[i] = s;
                }
            }
        }
        for (bi, w) in b.iter_mut().zip(&self.inv_d) {
            *bi *= w;
        }
        match kd {
            0 => {}
            1 => {
                let l1 = &self.l[n..2 * n];
                let mut next = b[n - 1];
                for (bi, li) in b[..n - 1].iter_mut().rev().zip(l1[1..].iter().rev()) {
                    next = *bi - li * next;
                    *bi = next;
                }
            }
            _ => {
                for i in (0..n.saturating_sub(1)).rev() {
                    let mut s = b[i];
                    for k in 1..=kd.min(n - 1 - i) {
                        s -= self.l[k * n + i + k] * b[i + k];
                    }
                    b[i] = s;
                }
            }
        }
        for (cj, yj) in c.iter().zip(y) {
            for (yi, x) in yj[..n].iter_mut().zip(&*b) {
                *yi += cj * x;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dense(a: &SymBand) -> Vec<Vec<f64>> {
        (0..a.n())
            .map(|i| (0..a.n()).map(|j| a.get(i, j)).collect())
            .collect()
    }

    #[test]
    fn band_solve_matches_dense_product() {
        // Pentadiagonal SPD matrix.
        let n = 9;
        let mut a = SymBand::zeros(n, 2);
        for i in 0..n {
            a.set(i, i, 6.0 + i as f64);
            if i >= 1 {
                a.set(i, i - 1, -1.5);
            }
            if i >= 2 {
                a.set(i, i - 2, 0.5);
            }
        }
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).sin()).collect();
        let mut b = vec![0.0; n];
        a.mul_into(&x, &mut b);
        let d = dense(&a);
        for i in 0..n {
            let bi: f64 = (0..n).map(|j| d[i][j] * x[j]).sum();
            assert!((bi - b[i]).abs() < 1e-13);
        }
        assert!((a.quad(&x, &x) - x.iter().zip(&b).map(|(p, q)| p * q).sum::<f64>()).abs() < 1e-12);
        let f = a.cholesky().unwrap();
        f.solve_in_place(&mut b);
        for i in 0..n {
            assert!((b[i] - x[i]).abs() < 1e-13, "{} vs {}", b[i], x[i]);
        }
    }

    #[test]
    fn twisted_tridiagonal_solve_matches_dense_product() {
        // Every twist position parity and the degenerate orders 1 and 2; a diagonally weak
        // matrix (a Laplacian plus a small shift) so that the factors are far from diagonal.
        for n in [1usize, 2, 3, 4, 5, 8, 33] {
            let mut a = SymBand::zeros(n, 1);
            for i in 0..n {
                a.set(i, i, 2.0 + 1e-3 * (i as f64 + 1.0));
                if i >= 1 {
                    a.set(i, i - 1, -1.0 + 0.01 * i as f64);
                }
            }
            let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).sin() + 0.3).collect();
            let mut b = vec![0.0; n];
            a.mul_into(&x, &mut b);
            let d = dense(&a);
            for i in 0..n {
                let bi: f64 = (0..n).map(|j| d[i][j] * x[j]).sum();
                assert!(
                    (bi - b[i]).abs() < 1e-14,
                    "n = {n}, row {i}: {} vs {bi}",
                    b[i]
                );
            }
            let f = a.cholesky().unwrap();
            assert_eq!(f.twisted.is_some(), n >= 2);
            f.solve_in_place(&mut b);
            for i in 0..n {
                assert!((b[i] - x[i]).abs() < 1e-11, "n = {n}: {} vs {}", b[i], x[i]);
            }
            let xx: f64 = x.iter().zip(&x).map(|(p, q)| p * q).sum();
            let dx: Vec<f64> = (0..n)
                .map(|i| (0..n).map(|j| d[i][j] * x[j]).sum())
                .collect();
            let plain: f64 = x.iter().zip(&dx).map(|(p, q)| p * q).sum();
            assert!((a.quad(&x, &x) - plain).abs() < 1e-13 * xx.max(1.0));
        }
    }

    #[test]
    fn rejects_indefinite_and_asymmetric() {
        let a = SymBand::from_dense_rows(&[vec![1.0, 2.0], vec![2.0, 1.0]]).unwrap();
        assert!(matches!(
            a.cholesky(),
            Err(BandError::NotPositiveDefinite { row: 1, .. })
        ));
        let e = SymBand::from_dense_rows(&[vec![1.0, 2.0], vec![2.5, 1.0]]).unwrap_err();
        assert!(matches!(e, BandError::NotSymmetric { i: 1, j: 0, .. }));
        let t = SymBand::from_triplets(3, &[(0, 0, 1.0), (2, 0, 0.5), (1, 1, 2.0), (2, 2, 3.0)])
            .unwrap();
        assert_eq!(t.kd(), 2);
        assert_eq!(t.get(0, 2), 0.5);
    }
}
