//! Allocation-free admissibility of one-contact-phase candidates (m, p), for the backbone scans.
//!
//! For a fixed left end and a fixed wall, an orbit of period T = m + p is fully described by
//! the signal `y(n) = a_N^{(n)}` arriving at the contact end, n ∈ ℤ_T. A value read at the
//! contact end at step n leaves it with the sign s(n) (−1 in the free phase n mod T < m, +1 in
//! contact), runs once around the ring of 2N characteristic values (the fixed left end does
//! not change its sign) and is read again 2N steps later, so
//!
//! ```text
//! y(n + 2N) = s(n) y(n)  on ℤ_T,        Q^{(0)}[k] = y((N − 1 − k) mod 2N mod T).
//! ```
//!
//! The map n ↦ n + 2N splits ℤ_T into g = gcd(T, 2N) classes (n mod g); a class carries a
//! kernel vector of `S_T` (9) iff the product of its signs is +1, and the vector is ±1 along
//! the class: the same kernel as [`super::kernel::SignedPermutation::kernel_basis`], one class
//! per cycle. The contact-end displacement is `u(n) = u(0) − (Δt/ρc) Σ_{j<min(n,m)} y(j)` with
//! `u(0) = (Δx/2E) Σ_k Q^{(0)}[k]`, so the closure rows and every admissibility test of
//! [`super::orbit::admissible_orbit`] cost O(T + N) on flat buffers, without a ring or a
//! trajectory per basis vector.
//!
//! Before that, an exact α-independent test rejects most candidates in a few steps: a period
//! starts with the end leaving the closed gap, so COND1 needs a strictly tensile `α₀ y(0) > 0`
//! on class 0 (which must carry a kernel vector), and every contact step n of class 0 has
//! `|α₀ y(n)| = |α₀|`, so COND2 needs `y(n) = −y(0)` there. A walk along class 0 with an early
//! exit decides this (it assumes u(0) = u(T) up to round-off, which holds for every kernel
//! vector by the discrete conservation law (27)).

use super::orbit::{ADMISSIBILITY_TOLERANCE, Orbit, grazing, has_wall_force};
use super::{BackbonePoint, candidate_phases, examine, point};
use crate::scenes::LeftEnd;
use crate::wfem::WaveBar;
use nalgebra::{DMatrix, DVector};

/// Reusable buffers of [`examine_one_contact`]; one per scanning thread.
#[derive(Debug, Default, Clone)]
pub struct Scratch {
    /// y(n) on ℤ_T, then α-weighted.
    y: Vec<f64>,
    /// Column of each class in the kernel basis (`usize::MAX` without kernel vector).
    col: Vec<usize>,
    /// Per column: u(0) contribution, closure row u(m), mean free-phase displacement row.
    u0: Vec<f64>,
    r1: Vec<f64>,
    r2: Vec<f64>,
    /// u(n), n = 0..=T.
    u: Vec<f64>,
}

fn gcd(mut a: usize, mut b: usize) -> usize {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

/// Exact necessary condition on class 0 (see the module doc): class 0 carries a kernel vector
/// and, with y(0) = +1, y = −1 at each of its contact steps. O(T/g), early exit.
pub fn class_zero_can_be_admissible(cells: usize, m: usize, p: usize) -> bool {
    let t = m + p;
    let n2 = 2 * cells;
    let step = n2 % t;
    let len = t / gcd(t, n2);
    let mut y = 1i8;
    let mut k = 0usize;
    for _ in 0..len {
        if k < m {
            y = -y;
        } else if y > 0 {
            return false;
        }
        k += step;
        if k >= t {
            k -= t;
        }
    }
    y > 0
}

/// [`examine`] for one contact phase (k = 0): the same point and the same orbit (up to
/// round-off in the orbit's sums), with the buffers of `s` and the y-signal formulation of the
/// module doc. Falls back to [`examine`] for a free left end.
pub fn examine_one_contact(
    bar: &WaveBar,
    m: usize,
    p: usize,
    s: &mut Scratch,
) -> Option<BackbonePoint> {
    if bar.left != LeftEnd::Fixed {
        return examine(bar, m, p, 0);
    }
    let n = bar.cells;
    let h = super::kernel::kernel_dim_closed_form(n, m, p);
    if h == 0 {
        return None;
    }
    let orbit = if class_zero_can_be_admissible(n, m, p) {
        admissible(bar, m, p, h, s)
    } else {
        None
    };
    Some(point(bar, m, p, 0, h, orbit))
}

/// The candidate's admissible orbit (COND1–COND3 of [`super::orbit::admissible_orbit`]) on
/// the y-signal of the module doc, in four phases: the kernel basis, its closure rows, the
/// amplitudes that close the orbit, and the conditions on the resulting signal.
fn admissible(bar: &WaveBar, m: usize, p: usize, h: usize, s: &mut Scratch) -> Option<Orbit> {
    let classes = Classes::new(bar.cells, m, p);
    let cols = kernel_basis(&classes, s);
    debug_assert_eq!(cols, h);
    let ds = bar.dt() / bar.impedance();
    closure_rows(bar, &classes, h, ds, s);
    let alpha = amplitudes(bar, h, s)?;
    displacements(&classes, &alpha, ds, s);
    conditions(bar, m, p, h, s)
}

/// The classes of n ↦ n + 2N on ℤ_T (module doc): T = m + p, g = gcd(T, 2N) classes of
/// T/g steps each, walked by `step` = 2N mod T.
struct Classes {
    /// Steps of the free phase.
    m: usize,
    /// The period T = m + p.
    t: usize,
    /// 2N, the characteristic values of the ring.
    n2: usize,
    /// The number of classes, g = gcd(T, 2N).
    g: usize,
    /// One move along a class, 2N mod T.
    step: usize,
    /// Steps in one class, T/g.
    len: usize,
}

impl Classes {
    fn new(cells: usize, m: usize, p: usize) -> Self {
        let n2 = 2 * cells;
        let t = m + p;
        let g = gcd(t, n2);
        Self {
            m,
            t,
            n2,
            g,
            step: n2 % t,
            len: t / g,
        }
    }

    /// The step after k along its class.
    fn next(&self, k: usize) -> usize {
        let k = k + self.step;
        if k >= self.t { k - self.t } else { k }
    }
}

/// Kernel basis: y = ±1 along each class with sign product +1, 0 on the others; `s.col` gets
/// each class's column. Returns the number of columns (the kernel dimension).
fn kernel_basis(classes: &Classes, s: &mut Scratch) -> usize {
    let (m, t, g, len) = (classes.m, classes.t, classes.g, classes.len);
    s.y.clear();
    s.y.resize(t, 0.0);
    s.col.clear();
    s.col.resize(g, usize::MAX);
    let mut cols = 0;
    for c in 0..g {
        let mut v = 1.0;
        let mut k = c;
        for _ in 0..len {
            s.y[k] = v;
            if k < m {
                v = -v;
            }
            k = classes.next(k);
        }
        if v > 0.0 {
            s.col[c] = cols;
            cols += 1;
        } else {
            for _ in 0..len {
                s.y[k] = 0.0;
                k = classes.next(k);
            }
        }
    }
    cols
}

/// Closure rows per basis vector: `s.u0` the displacement u(0), `s.r1` the closure row u(m)
/// and `s.r2` the mean displacement over the free phase.
fn closure_rows(bar: &WaveBar, classes: &Classes, h: usize, ds: f64, s: &mut Scratch) {
    let (m, t, g) = (classes.m, classes.t, classes.g);
    let half_dx_e = bar.dx() / bar.young * 0.5;
    for b in [&mut s.u0, &mut s.r1, &mut s.r2] {
        b.clear();
        b.resize(h, 0.0);
    }
    // u(0) = (Δx/2E) Σ_k Q[k], Q[k] = y((N−1−k) mod 2N mod T): every j ∈ [0, 2N) once.
    let mut c = 0;
    let mut j_mod_t = 0;
    for _ in 0..classes.n2 {
        let col = s.col[c];
        if col != usize::MAX {
            s.u0[col] += s.y[j_mod_t];
        }
        c += 1;
        if c == g {
            c = 0;
        }
        j_mod_t += 1;
        if j_mod_t == t {
            j_mod_t = 0;
        }
    }
    for x in s.u0.iter_mut() {
        *x *= half_dx_e;
    }
    // Σ_{j<m} y(j) and Σ_{j<m} (m − j) y(j) per column.
    let mut c = 0;
    for (j, &yj) in s.y[..m].iter().enumerate() {
        let col = s.col[c];
        if col != usize::MAX {
            s.r1[col] += yj;
            s.r2[col] += (m - j) as f64 * yj;
        }
        c += 1;
        if c == g {
            c = 0;
        }
    }
    let free_count = (m + 1) as f64;
    for i in 0..h {
        let u0 = s.u0[i];
        s.r2[i] = ((m + 1) as f64 * u0 - ds * s.r2[i]) / free_count;
        s.r1[i] = u0 - ds * s.r1[i];
    }
}

/// The amplitude α per column that closes the orbit on the gap g0 (u(m) = g0), and for a
/// grazing wall (g0 = 0) also fixes the scale by a mean free-phase displacement of −10⁻³ L;
/// `None` when no amplitude closes it.
fn amplitudes(bar: &WaveBar, h: usize, s: &Scratch) -> Option<Vec<f64>> {
    let g0 = bar.gap;
    let reference = 1e-3 * bar.length;
    if g0 != 0.0 && h == 1 {
        if s.r1[0].abs() < 1e-300 {
            return None;
        }
        Some(vec![g0 / s.r1[0]])
    } else {
        let rows = if g0 == 0.0 { 2 } else { 1 };
        let cm = DMatrix::from_fn(rows, h, |i, j| if i == 0 { s.r1[j] } else { s.r2[j] });
        let rhs = if g0 == 0.0 {
            DVector::from_vec(vec![g0, -reference])
        } else {
            DVector::from_vec(vec![g0])
        };
        let sol = cm.svd(true, true).solve(&rhs, 1e-12).ok()?;
        Some(sol.iter().copied().collect())
    }
}

/// The signal Y(j) = α_{class(j)} y(j) in `s.y` and the contact-end displacement u(n),
/// n = 0..=T, in `s.u` (constant over the contact phase).
fn displacements(classes: &Classes, alpha: &[f64], ds: f64, s: &mut Scratch) {
    let (m, t, g) = (classes.m, classes.t, classes.g);
    let mut c = 0;
    for yj in s.y.iter_mut() {
        let col = s.col[c];
        *yj = if col == usize::MAX {
            0.0
        } else {
            alpha[col] * *yj
        };
        c += 1;
        if c == g {
            c = 0;
        }
    }
    let u0: f64 = s.u0.iter().zip(alpha).map(|(a, b)| a * b).sum();
    s.u.clear();
    s.u.reserve(t + 1);
    let mut u = u0;
    s.u.push(u);
    for &yj in &s.y[..m] {
        u -= ds * yj;
        s.u.push(u);
    }
    s.u.resize(t + 1, u);
}

/// COND1–COND3 on the closed signal: the gap closes at m, the end stays off the wall and
/// leaves it under tension in the free phase, the wall only pushes in the contact phase, and
/// the stress stays below E; the orbit when they hold.
fn conditions(bar: &WaveBar, m: usize, p: usize, h: usize, s: &Scratch) -> Option<Orbit> {
    let n = bar.cells;
    let n2 = 2 * n;
    let t = m + p;
    let g0 = bar.gap;
    let u_scale = g0.abs().max(s.u.iter().fold(0.0f64, |a, x| a.max(x.abs())));
    let a_scale = s.y.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    if u_scale == 0.0 || a_scale == 0.0 {
        return None;
    }
    let tol_u = ADMISSIBILITY_TOLERANCE * u_scale;
    let tol_a = ADMISSIBILITY_TOLERANCE * a_scale;
    if (s.u[m] - g0).abs() > tol_u {
        return None;
    }
    let mut opens = false;
    for i in 0..=m {
        let ui = s.u[i];
        if ui > g0 + tol_u {
            return None;
        }
        if i < m && ui >= g0 - tol_u && s.y[i] <= tol_a {
            return None;
        }
        opens |= ui < g0 - tol_u;
    }
    if !opens || s.y[m..].iter().any(|&r| r > tol_a) || !has_wall_force(&s.y[m..], tol_a) {
        return None;
    }
    let zero_force_steps = s.y[m..].iter().filter(|r| r.abs() <= tol_a).count();
    let grazing_steps = grazing(&s.u[..=m], g0, tol_u);
    let ring: Vec<f64> = (0..n2).map(|k| s.y[((n - 1 + n2 - k) % n2) % t]).collect();
    let max_abs = ring.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    if max_abs >= bar.young {
        return None;
    }
    let energy = bar.area * bar.dx() / (4.0 * bar.density * bar.wave_speed().powi(2))
        * ring.iter().map(|x| x * x).sum::<f64>();
    Some(Orbit {
        phases: candidate_phases(m, p, 0),
        ring,
        kernel_dim: h,
        energy,
        u: s.u.clone(),
        zero_force_steps,
        grazing_steps,
    })
}
