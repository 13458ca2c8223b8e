//! The impulsive part of a step, shared by every velocity-level scheme: the index set of
//! contacts to enforce, the Delassus operator `W = Gᵀ Ŵ⁻¹ G`, and the LCP for the impulse
//! `0 ≤ U_{k+1} + e ∘ U_k ⊥ P_{k+1} ≥ 0` on the index set (Acary 2016, (21c)–(21d), (25c)–(25d)).

use crate::band::BandCholesky;
use crate::lcp::{self, Lcp, LcpError, LcpOptions};
use crate::model::Contact;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Which contacts enter the LCP of a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Activation {
    /// Acary 2016 (24): `g_α(q_k + h v_k) ≤ 0 and U_k^α ≤ 0`.
    #[default]
    GapAndVelocity,
    /// Siconos' rule: `g_α(q_k) + γ h U_k^α ≤ 0`, no test on the sign of U_k.
    PredictedGap,
}

/// An index-set rule: the [`Activation`] and, for `PredictedGap`, its γ (default 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IndexSetRule {
    /// Which rule.
    pub activation: Activation,
    /// γ of the predicted-gap rule.
    pub gamma: f64,
}

impl Default for IndexSetRule {
    fn default() -> Self {
        Self {
            activation: Activation::GapAndVelocity,
            gamma: 1.0,
        }
    }
}

impl IndexSetRule {
    /// Is contact `c` in the index set 𝓘¹_k of the step from (t, q_k, v_k) with step h?
    pub fn is_active(&self, c: &Contact, q: &[f64], v: &[f64], t: f64, h: f64) -> bool {
        self.is_active_within(c, q, v, t, h, 0.0)
    }

    /// [`IndexSetRule::is_active`] with the sign test of (24) read as `U_k ≤ u_roundoff`: during a
    /// lasting contact with e = 0 the LCP makes U_k zero only up to its round-off, and a sign
    /// decided by round-off would drop the contact for one step and let the body sink by h·U.
    /// `u_roundoff` is the round-off level of U_k (zero for a contact that was not in the last
    /// LCP); it does not enter the predicted-gap rule, which has no sign test.
    pub fn is_active_within(
        &self,
        c: &Contact,
        q: &[f64],
        v: &[f64],
        t: f64,
        h: f64,
        u_roundoff: f64,
    ) -> bool {
        let u = c.local_velocity(v, t);
        match self.activation {
            Activation::GapAndVelocity => {
                c.project(q) + h * c.project(v) + c.w(t + h) <= 0.0 && u <= u_roundoff
            }
            Activation::PredictedGap => c.gap(q, t) + self.gamma * h * u <= 0.0,
        }
    }
}

/// The index set of a step and the right-hand side of its impulse LCP, `U_free + e ∘ U_k` on
/// the active contacts ((21c)–(21d), (25c)–(25d)), together with the round-off level of the
/// local velocities the previous step's LCP produced, which the sign test of (24) reads
/// ([`IndexSetRule::is_active_within`]). One per scheme; reused from step to step.
#[derive(Debug, Clone)]
pub struct IndexSet {
    /// Contacts of 𝓘¹_k, in increasing order.
    pub active: Vec<usize>,
    /// `U_free^α + e_α U_k^α` for each active contact, in the order of `active`.
    pub rhs: Vec<f64>,
    /// Step whose end state `roundoff` belongs to (`u64::MAX`: none yet).
    roundoff_step: u64,
    /// Round-off level of U^α at the end of that step, per contact (zero when inactive).
    roundoff: Vec<f64>,
}

impl IndexSet {
    /// An empty index set for `contacts` contacts.
    pub fn new(contacts: usize) -> Self {
        Self {
            active: Vec::new(),
            rhs: Vec::new(),
            roundoff_step: u64::MAX,
            roundoff: vec![0.0; contacts],
        }
    }

    /// The index set of the step from step `k` (state `q`, `v` at time `t`, step `h`) by
    /// `rule`, with `u_free(α, c)` the free local velocity U_free^α at the end of the step.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub fn assemble(
        &mut self,
        rule: &IndexSetRule,
        contacts: &[Contact],
        k: u64,
        q: &[f64],
        v: &[f64],
        t: f64,
        h: f64,
        mut u_free: impl FnMut(&Contact) -> f64,
    ) {
        self.active.clear();
        self.rhs.clear();
        for (a, c) in contacts.iter().enumerate() {
            let u_tol = if self.roundoff_step == k {
                self.roundoff[a]
            } else {
                0.0
            };
            if rule.is_active_within(c, q, v, t, h, u_tol) {
                self.active.push(a);
                let u_k = c.local_velocity(v, t);
                self.rhs.push(u_free(c) + c.restitution * u_k);
            }
        }
    }

    /// Records the round-off level of the local velocities the LCP of step `step` produced:
    /// `U^α_{k+1} = b_α + (W P)_α` loses `ε (|b_α| + Σ_β |W_αβ P_β|)` to cancellation; 64 times
    /// that is kept for each active contact, zero elsewhere. `w` is the scheme's contact matrix
    /// on all m contacts, row-major m×m (the Delassus operator, symmetric or not).
    pub fn record_roundoff(&mut self, w: &[f64], impulse: &[f64], step: u64) {
        let m = self.roundoff.len();
        self.roundoff.fill(0.0);
        for (r, &a) in self.active.iter().enumerate() {
            let wp: f64 = self
                .active
                .iter()
                .map(|&c| (w[a * m + c] * impulse[c]).abs())
                .sum();
            self.roundoff[a] = 64.0 * f64::EPSILON * (self.rhs[r].abs() + wp);
        }
        self.roundoff_step = step;
    }
}

/// Diagnostics of the LCP solved in one step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LcpStats {
    /// Number of contacts in the index set (size of the LCP).
    pub size: usize,
    /// Solver iterations.
    pub iterations: usize,
    /// Complementarity error.
    pub error: f64,
}

/// `Ŵ⁻¹ G` (dense columns) and the Delassus operator `W = Gᵀ Ŵ⁻¹ G`, computed once per run.
#[derive(Debug, Clone)]
pub struct Delassus {
    n: usize,
    /// Column α of Ŵ⁻¹G at `[α n, (α+1) n)`.
    winv_g: Vec<f64>,
    /// Row-major m×m.
    w: Vec<f64>,
}

impl Delassus {
    /// Precomputes Ŵ⁻¹G and W from the factorised iteration matrix Ŵ.
    pub fn new(factor: &BandCholesky, contacts: &[Contact]) -> Self {
        let n = factor.n();
        let m = contacts.len();
        let mut winv_g = vec![0.0; n * m];
        for (a, c) in contacts.iter().enumerate() {
            let col = &mut winv_g[a * n..(a + 1) * n];
            for &(i, coef) in &c.g {
                col[i] += coef;
            }
            factor.solve_in_place(col);
        }
        let mut w = vec![0.0; m * m];
        for (a, c) in contacts.iter().enumerate() {
            for b in 0..m {
                w[a * m + b] = c.project(&winv_g[b * n..(b + 1) * n]);
            }
        }
        Self { n, winv_g, w }
    }

    /// Column α of Ŵ⁻¹G.
    pub fn column(&self, alpha: usize) -> &[f64] {
        &self.winv_g[alpha * self.n..(alpha + 1) * self.n]
    }

    /// W, row-major m×m.
    pub fn matrix(&self) -> &[f64] {
        &self.w
    }

    /// Entry (α, β) of W.
    pub fn entry(&self, alpha: usize, beta: usize) -> f64 {
        let m = self.w.len().isqrt();
        self.w[alpha * m + beta]
    }

    /// Solves the impulse LCP on the index set: `0 ≤ W_AA P_A + b_A ⊥ P_A ≥ 0` with
    /// `b_α = U_free^α + e_α U_k^α`, writes P (zero off the set) into `impulse` and adds
    /// `Ŵ⁻¹ G P` to `v`. Returns the LCP diagnostics.
    pub fn apply_impulse(
        &self,
        active: &[usize],
        b: &[f64],
        options: &LcpOptions,
        impulse: &mut [f64],
        v: &mut [f64],
    ) -> Result<LcpStats, LcpError> {
        impulse.fill(0.0);
        if active.is_empty() {
            return Ok(LcpStats::default());
        }
        let k = active.len();
        let mut m = Vec::with_capacity(k * k);
        for &a in active {
            for &c in active {
                m.push(self.entry(a, c));
            }
        }
        let sol = lcp::solve(Lcp { m: &m, q: b }, options)?;
        for (r, &a) in active.iter().enumerate() {
            let p = sol.z[r];
            impulse[a] = p;
            if p != 0.0 {
                for (vi, ci) in v.iter_mut().zip(self.column(a)) {
                    *vi += p * ci;
                }
            }
        }
        Ok(LcpStats {
            size: k,
            iterations: sol.iterations,
            error: sol.error,
        })
    }
}
