//! Exact solution of the bar under a uniform body force against a fixed obstacle (the
//! Doyen–Ern–Piperno bouncing bar of Table 1), by d'Alembert's characteristics (5).
//!
//! With the acceleration `g_b = F0/(ρS)` and `k = ρc g_b`, the characteristic variables
//! `a = σ − ρc v`, `b = σ + ρc v` of (19) obey `a_t + c a_x = −k`, `b_t − c b_x = k`, so
//! `α = a + k t` is constant along x − ct = ξ and `β = b − k t` along x + ct = η. The boundary
//! conditions give
//!
//! ```text
//! free left end  (σ = 0):  α(−ct) = −β(ct)            fixed left end (v = 0): α(−ct) = β(ct) + 2kt
//! free right end (σ = 0):  β(L + ct) = −α(L − ct)     contact (v = 0):        β(L + ct) = α(L − ct) − 2kt
//! ```
//!
//! and the initial data (σ = 0, v = V0, u = 0) `α = −ρc V0` on [0, L], `β = ρc V0` on [0, L].
//! Both functions are piecewise linear; at the contact end `a(L, t) = α(L − ct) − kt` is linear
//! between the breakpoints `j L/c` and `e + 2 j L/c` (e a closure or release time). The solver
//! marches over those pieces and finds each closure (`u(L, t) = g0`, u quadratic in t) and each
//! release (contact stress `a(L, t)` turning positive) in closed form.

use crate::scenes::LeftEnd;

/// The bar of the exact solution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExactBar {
    /// Length L.
    pub length: f64,
    /// Young's modulus E.
    pub young: f64,
    /// Density ρ.
    pub density: f64,
    /// Cross-section S.
    pub area: f64,
    /// Gap g0 > 0 (the bar starts free).
    pub gap: f64,
    /// Body force per unit length F0, toward the obstacle.
    pub body_force: f64,
    /// Uniform initial velocity V0.
    pub initial_velocity: f64,
    /// Left end.
    pub left: LeftEnd,
}

impl ExactBar {
    /// The Doyen–Ern–Piperno bar of Table 1: E = 900, ρ = 1, L = 10, g0 = 5, F0 = 10, free left end.
    pub fn doyen_ern_piperno() -> Self {
        ExactBar {
            length: 10.0,
            young: 900.0,
            density: 1.0,
            area: 1.0,
            gap: 5.0,
            body_force: 10.0,
            initial_velocity: 0.0,
            left: LeftEnd::Free,
        }
    }

    fn c(&self) -> f64 {
        (self.young / self.density).sqrt()
    }
}

/// One piece of the contact-end history on [t0, t1]: `a(L, t) = a0 + a1 (t − t0)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Piece {
    /// Start time.
    pub t0: f64,
    /// End time.
    pub t1: f64,
    /// u(L, t0).
    pub u0: f64,
    /// a(L, t0⁺).
    pub a0: f64,
    /// da(L, t)/dt on the piece.
    pub a1: f64,
    /// Contact (v(L) = 0) or free (σ(L) = 0) on the piece.
    pub contact: bool,
}

/// The exact contact-end history of an [`ExactBar`] on [0, t_end].
#[derive(Debug, Clone, PartialEq)]
pub struct ExactSolution {
    bar: ExactBar,
    /// Pieces in time order.
    pub pieces: Vec<Piece>,
    /// Contact intervals [closure, release) (release = ∞ if still in contact at t_end).
    pub contacts: Vec<(f64, f64)>,
}

struct History<'a> {
    bar: &'a ExactBar,
    c: f64,
    z: f64,
    k: f64,
    contacts: &'a [(f64, f64)],
}

impl History<'_> {
    fn in_contact(&self, t: f64) -> bool {
        self.contacts.iter().any(|&(a, b)| t >= a && t < b)
    }

    /// α(ξ) for ξ ≤ L.
    fn alpha(&self, xi: f64) -> f64 {
        if xi >= 0.0 {
            return -self.z * self.bar.initial_velocity;
        }
        let t = -xi / self.c;
        match self.bar.left {
            LeftEnd::Free => -self.beta(self.c * t),
            LeftEnd::Fixed => self.beta(self.c * t) + 2.0 * self.k * t,
        }
    }

    /// β(η) for η ≥ 0.
    fn beta(&self, eta: f64) -> f64 {
        let l = self.bar.length;
        if eta <= l {
            return self.z * self.bar.initial_velocity;
        }
        let t = (eta - l) / self.c;
        let alpha = self.alpha(l - self.c * t);
        if self.in_contact(t) {
            alpha - 2.0 * self.k * t
        } else {
            -alpha
        }
    }

    /// a(L, t) = α(L − ct) − kt.
    fn a_end(&self, t: f64) -> f64 {
        self.alpha(self.bar.length - self.c * t) - self.k * t
    }
}

impl ExactSolution {
    /// Marches the exact solution from t = 0 to `t_end`.
    pub fn solve(bar: ExactBar, t_end: f64) -> Self {
        let c = bar.c();
        let z = bar.density * c;
        let k = z * bar.body_force / (bar.density * bar.area);
        let tau = bar.length / c;
        let eps = 1e-12 * tau;
        let mut contacts: Vec<(f64, f64)> = Vec::new();
        let mut events: Vec<f64> = Vec::new();
        let mut pieces = Vec::new();
        let mut t = 0.0;
        let mut u = 0.0;
        let mut contact = false;
        while t < t_end - eps {
            // Next breakpoint of a(L, ·) after t.
            let mut next = ((t + eps) / tau).floor() * tau + tau;
            for &e in &events {
                let j = ((t + eps - e) / (2.0 * tau)).floor() + 1.0;
                let cand = e + j.max(1.0) * 2.0 * tau;
                if cand > t + eps {
                    next = next.min(cand);
                }
            }
            let seg_end = next.min(t_end);
            let len = seg_end - t;
            let h = History {
                bar: &bar,
                c,
                z,
                k,
                contacts: &contacts,
            };
            let s1 = h.a_end(t + len / 3.0);
            let s2 = h.a_end(t + 2.0 * len / 3.0);
            let a1 = (s2 - s1) / (len / 3.0);
            let a0 = s1 - a1 * len / 3.0;
            if contact {
                // Release when the contact stress a(L) becomes tensile.
                let release = if a0 > 1e-12 * k.abs().max(z) {
                    Some(0.0)
                } else if a1 > 0.0 && -a0 / a1 < len {
                    Some(-a0 / a1)
                } else {
                    None
                };
                let dur = release.unwrap_or(len);
                pieces.push(Piece {
                    t0: t,
                    t1: t + dur,
                    u0: u,
                    a0,
                    a1,
                    contact: true,
                });
                t += dur;
                if release.is_some() {
                    if let Some(last) = contacts.last_mut() {
                        last.1 = t;
                    }
                    events.push(t);
                    contact = false;
                }
            } else {
                // u(t + τ) = u − (a0 τ + a1 τ²/2)/ρc; closure at the first τ > 0 with u = g0.
                let q = |s: f64| u - (a0 * s + 0.5 * a1 * s * s) / z - bar.gap;
                let closure = first_root(q, a0, a1, z, u - bar.gap, len, eps);
                let dur = closure.unwrap_or(len);
                pieces.push(Piece {
                    t0: t,
                    t1: t + dur,
                    u0: u,
                    a0,
                    a1,
                    contact: false,
                });
                u -= (a0 * dur + 0.5 * a1 * dur * dur) / z;
                t += dur;
                if closure.is_some() {
                    u = bar.gap;
                    contacts.push((t, f64::INFINITY));
                    events.push(t);
                    contact = true;
                }
            }
        }
        ExactSolution {
            bar,
            pieces,
            contacts,
        }
    }

    fn piece(&self, t: f64) -> Option<&Piece> {
        let i = self.pieces.partition_point(|p| p.t1 <= t);
        self.pieces.get(i.min(self.pieces.len().saturating_sub(1)))
    }

    /// u(L, t).
    pub fn end_displacement(&self, t: f64) -> f64 {
        let z = self.bar.density * self.bar.c();
        match self.piece(t) {
            Some(p) if p.contact => p.u0,
            Some(p) => {
                let s = t - p.t0;
                p.u0 - (p.a0 * s + 0.5 * p.a1 * s * s) / z
            }
            None => 0.0,
        }
    }

    /// Contact force r(t) = S σ(L, t) (≤ 0; 0 when free).
    pub fn contact_force(&self, t: f64) -> f64 {
        match self.piece(t) {
            Some(p) if p.contact => self.bar.area * (p.a0 + p.a1 * (t - p.t0)),
            _ => 0.0,
        }
    }

    /// Velocity v(L, t).
    pub fn end_velocity(&self, t: f64) -> f64 {
        let z = self.bar.density * self.bar.c();
        match self.piece(t) {
            Some(p) if !p.contact => -(p.a0 + p.a1 * (t - p.t0)) / z,
            _ => 0.0,
        }
    }
}

/// First root in (eps, len] of `q(s) = q0 − (a0 s + a1 s²/2)/z` (closure of the gap).
fn first_root(
    q: impl Fn(f64) -> f64,
    a0: f64,
    a1: f64,
    z: f64,
    q0: f64,
    len: f64,
    eps: f64,
) -> Option<f64> {
    // q(s) = q0 − (a0/z) s − (a1/2z) s²: solve A s² + B s + C = 0.
    let (aa, bb, cc) = (-0.5 * a1 / z, -a0 / z, q0);
    let mut roots = Vec::new();
    if aa.abs() < 1e-300 {
        if bb != 0.0 {
            roots.push(-cc / bb);
        }
    } else {
        let disc = bb * bb - 4.0 * aa * cc;
        if disc >= 0.0 {
            let sq = disc.sqrt();
            // Numerically stable pair.
            let qq = -0.5 * (bb + bb.signum() * sq);
            if qq != 0.0 {
                roots.push(cc / qq);
                roots.push(qq / aa);
            } else {
                roots.push(0.0);
            }
        }
    }
    roots.sort_by(f64::total_cmp);
    // Accept a root where the gap closes from the open side (q goes from < 0 to ≥ 0).
    roots
        .into_iter()
        .find(|&s| s > eps && s <= len && q(0.5 * s) < 0.0)
}
