//! The impulsive part of a step, shared by every velocity-level scheme: the index set of
//! contacts to enforce, the Delassus operator `W = Gᵀ Ŵ⁻¹ G`, and the LCP for the impulse
//! `0 ≤ U_{k+1} + e ∘ U_k ⊥ P_{k+1} ≥ 0` on the index set (Acary 2016, (21c)–(21d), (25c)–(25d)).

use crate::band::BandCholesky;
use crate::friction::{self, FrictionError, FrictionProblem};
use crate::lcp::{self, Lcp, LcpError, LcpOptions};
use crate::model::{Contact, ContactFriction};
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
        self.is_active_within_gap(c, q, v, t, h, u_roundoff, 0.0)
    }

    /// [`IndexSetRule::is_active_within`] with the gap test of (24) read as
    /// `g(q_k + h v_k) ≤ g_roundoff` too (models with friction, [`IndexSet::friction`]).
    #[allow(clippy::too_many_arguments)]
    pub fn is_active_within_gap(
        &self,
        c: &Contact,
        q: &[f64],
        v: &[f64],
        t: f64,
        h: f64,
        u_roundoff: f64,
        g_roundoff: f64,
    ) -> bool {
        let u = c.local_velocity(v, t);
        match self.activation {
            Activation::GapAndVelocity => {
                c.project(q) + h * c.project(v) + c.w(t + h) <= g_roundoff && u <= u_roundoff
            }
            Activation::PredictedGap => c.gap(q, t) + self.gamma * h * u <= 0.0,
        }
    }
}

/// The index set of a step and the right-hand side of its impulse LCP, `U_free + e ∘ U_k` on
/// the active contacts ((21c)–(21d), (25c)–(25d)), together with the round-off level of the
/// local velocities the previous step's LCP produced, which the sign test of (24) reads
/// ([`IndexSetRule::is_active_within`]). One per scheme; reused from step to step.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct IndexSet {
    /// Contacts of 𝓘¹_k, in increasing order.
    pub active: Vec<usize>,
    /// `U_free^α + e_α U_k^α` for each active contact, in the order of `active`.
    pub rhs: Vec<f64>,
    /// Step whose end state `roundoff` belongs to (`u64::MAX`: none yet).
    roundoff_step: u64,
    /// Round-off level of U^α at the end of that step, per contact (zero when inactive).
    roundoff: Vec<f64>,
    /// A model with friction: the gap test of (24) reads `g(q_k + h v_k) ≤ t_{k+1} u_ro` for a
    /// contact of the last LCP (u_ro its velocity round-off level). A lasting contact whose
    /// U_n is zero only to round-off drifts off the obstacle by up to h u_ro per step, by
    /// t u_ro since t = 0; dropped for one step, it would lose its friction for that step
    /// (see [`crate::nonlinear::moreau_jean`]). False (the strict test) without friction.
    pub friction: bool,
}

impl IndexSet {
    /// An empty index set for `contacts` contacts.
    pub fn new(contacts: usize) -> Self {
        Self {
            active: Vec::new(),
            rhs: Vec::new(),
            roundoff_step: u64::MAX,
            roundoff: vec![0.0; contacts],
            friction: false,
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
            let g_tol = if self.friction { (t + h) * u_tol } else { 0.0 };
            if rule.is_active_within_gap(c, q, v, t, h, u_tol, g_tol) {
                self.active.push(a);
                let u_k = c.local_velocity(v, t);
                self.rhs.push(u_free(c) + c.restitution * u_k);
            }
        }
    }

    /// [`IndexSet::assemble`] for [`UnitContacts`], in one pass: the index set of the step from
    /// step `k` (state `q`, `v` at time `t`, step `h`) by `rule`, with the free local velocity
    /// `U_free = Gᵀ(v + dv)` (Moreau–Jean: dv the free velocity change). The same values, bit
    /// for bit, as `assemble` with `u_free = c.project(v) + c.project(dv) + c.w_rate(t + h)`.
    #[allow(clippy::too_many_arguments)]
    pub fn assemble_unit(
        &mut self,
        rule: &IndexSetRule,
        contacts: &UnitContacts,
        k: u64,
        q: &[f64],
        v: &[f64],
        dv: &[f64],
        t: f64,
        h: f64,
    ) {
        self.active.clear();
        self.rhs.clear();
        let fresh = self.roundoff_step == k;
        let gamma_h = rule.gamma * h;
        for a in 0..contacts.len() {
            let (d, c, w) = (contacts.dof[a], contacts.coef[a], contacts.w[a]);
            let u_tol = if fresh { self.roundoff[a] } else { 0.0 };
            let g_tol = if self.friction { (t + h) * u_tol } else { 0.0 };
            let cv = c * v[d];
            // U_k = (Gᵀv)_α + ẇ_α (ẇ = 0).
            let u_k = cv + 0.0;
            let on = match rule.activation {
                Activation::GapAndVelocity => c * q[d] + h * cv + w <= g_tol && u_k <= u_tol,
                Activation::PredictedGap => c * q[d] + w + gamma_h * u_k <= 0.0,
            };
            if on {
                self.active.push(a);
                self.rhs
                    .push((cv + c * dv[d]) + 0.0 + contacts.restitution[a] * u_k);
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

    /// Records the round-off level `level(r, b_r)` of each active contact's local velocity at
    /// the end of step `step` (r its place in `active`, b_r its right-hand side).
    pub fn record_levels_by(&mut self, step: u64, mut level: impl FnMut(usize, f64) -> f64) {
        self.roundoff.fill(0.0);
        for (r, (&a, &b)) in self.active.iter().zip(&self.rhs).enumerate() {
            self.roundoff[a] = level(r, b);
        }
        self.roundoff_step = step;
    }

    /// Records given round-off levels of the local velocities of step `step`, one per active
    /// contact in the order of `active` (the friction problem's, [`FrictionDelassus`]).
    pub fn record_levels(&mut self, levels: &[f64], step: u64) {
        self.roundoff.fill(0.0);
        for (&a, &l) in self.active.iter().zip(levels) {
            self.roundoff[a] = l;
        }
        self.roundoff_step = step;
    }
}

/// Contacts whose column of G is one entry and whose obstacle does not move (a string or a bar
/// against a distributed obstacle), in arrays: what the per-contact passes of a step read
/// without the indirection of each [`Contact`]'s own list. Every value they give is the one
/// [`Contact`]'s methods give, operation for operation: a one-term projection is its term
/// (`Sum` starts from −0), `w = offset + 0` and `ẇ = 0` without motion.
#[derive(Debug, Clone)]
pub struct UnitContacts {
    dof: Vec<usize>,
    coef: Vec<f64>,
    /// w_α (constant).
    w: Vec<f64>,
    restitution: Vec<f64>,
}

impl UnitContacts {
    /// The arrays of `contacts`, or `None` when one has a column of more than one entry or a
    /// moving obstacle.
    pub fn of(contacts: &[Contact]) -> Option<Self> {
        let single = |c: &Contact| (c.g.len() == 1 && c.motion.is_none()).then(|| c.g[0]);
        let columns: Vec<(usize, f64)> = contacts.iter().map(single).collect::<Option<_>>()?;
        Some(Self {
            dof: columns.iter().map(|&(d, _)| d).collect(),
            coef: columns.iter().map(|&(_, c)| c).collect(),
            w: contacts.iter().map(|c| c.w(0.0)).collect(),
            restitution: contacts.iter().map(|c| c.restitution).collect(),
        })
    }

    /// Number of contacts.
    pub fn len(&self) -> usize {
        self.dof.len()
    }

    /// True without contacts.
    pub fn is_empty(&self) -> bool {
        self.dof.is_empty()
    }

    /// Contact α's column of G, `(dof, coefficient)`.
    pub fn column(&self, alpha: usize) -> (usize, f64) {
        (self.dof[alpha], self.coef[alpha])
    }

    /// Gaps [`Contact::gap`] and local velocities [`Contact::local_velocity`] of every contact
    /// at (q, v), in one pass.
    pub fn fill(&self, q: &[f64], v: &[f64], gap: &mut [f64], velocity: &mut [f64]) {
        let m = self.len();
        for ((((g, u), &d), &c), &w) in gap[..m]
            .iter_mut()
            .zip(&mut velocity[..m])
            .zip(&self.dof)
            .zip(&self.coef)
            .zip(&self.w)
        {
            *g = c * q[d] + w;
            *u = c * v[d] + 0.0;
        }
    }

    /// `Σ_{α ∈ active} P_α (Gᵀ x)_α`, summed in the order of `active` (the contact work of a
    /// step, as the sum over [`Contact::project`] gives it).
    pub fn work(&self, active: &[usize], impulse: &[f64], x: &[f64]) -> f64 {
        active
            .iter()
            .map(|&a| impulse[a] * (self.coef[a] * x[self.dof[a]]))
            .sum()
    }
}

/// Diagnostics of the LCP solved in one step.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
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

/// The Delassus operator of a model with friction, with the tangent rows: `Ŵ⁻¹[G T]` (dense
/// columns) and `W = [G T]ᵀ Ŵ⁻¹ [G T]` (2m×2m, rows and columns in the order
/// `(n_1, t_1, n_2, t_2, …)` of [`crate::friction`]), computed once per run.
#[derive(Debug, Clone)]
pub struct FrictionDelassus {
    n: usize,
    /// Column r of Ŵ⁻¹[G T] at `[r n, (r+1) n)`, r = 2α (normal) or 2α + 1 (tangent).
    columns: Vec<f64>,
    /// Row-major 2m×2m.
    w: Vec<f64>,
    /// Scratch: the problem on the index set.
    sub: FrictionSubproblem,
}

/// The planar friction problem of a step on its index set, cut from the Delassus operator of
/// every contact's rows (G_α, T_α) (2m×2m, rows and columns in the order (n_1, t_1, n_2, …)):
/// its W, free local velocities and μ, kept between steps only as buffers.
#[derive(Debug, Clone)]
pub(crate) struct FrictionSubproblem {
    /// Contacts m of the whole operator.
    contacts: usize,
    w: Vec<f64>,
    q: Vec<f64>,
    mu: Vec<f64>,
}

impl FrictionSubproblem {
    /// The buffers for an operator of `contacts` contacts.
    pub(crate) fn new(contacts: usize) -> Self {
        Self {
            contacts,
            w: Vec::new(),
            q: Vec::new(),
            mu: Vec::new(),
        }
    }

    /// Solves the problem on `active` of the operator `w` (2m×2m) with free local velocities
    /// `b_n` (`U_free + e U_k`, the normal rows) and `b_t` (the tangent rows), in the order of
    /// `active`, and friction coefficients `mu[α]`.
    pub(crate) fn solve(
        &mut self,
        w: &[f64],
        active: &[usize],
        b_n: &[f64],
        b_t: &[f64],
        mu: impl Fn(usize) -> f64,
        options: &LcpOptions,
    ) -> Result<friction::FrictionSolution, FrictionError> {
        let mm = 2 * self.contacts;
        self.w.clear();
        self.q.clear();
        self.mu.clear();
        for (r, &a) in active.iter().enumerate() {
            for row in [2 * a, 2 * a + 1] {
                for &c in active {
                    self.w
                        .extend_from_slice(&w[row * mm + 2 * c..row * mm + 2 * c + 2]);
                }
            }
            self.q.extend([b_n[r], b_t[r]]);
            self.mu.push(mu(a));
        }
        friction::solve_friction(
            FrictionProblem {
                w: &self.w,
                q: &self.q,
                mu: &self.mu,
            },
            options,
        )
    }

    /// The round-off level of the normal local velocity of the `r`-th active contact at the
    /// solution `p`, `64 ε Σ_rows (|b| + Σ |W P|)` over its two rows (the solver couples them).
    pub(crate) fn level(&self, r: usize, p: &[f64]) -> f64 {
        let kk = self.q.len();
        let mut level = 0.0;
        for row in [2 * r, 2 * r + 1] {
            let wp: f64 = (0..kk).map(|c| (self.w[row * kk + c] * p[c]).abs()).sum();
            level += self.q[row].abs() + wp;
        }
        64.0 * f64::EPSILON * level
    }
}

impl FrictionDelassus {
    /// Precomputes Ŵ⁻¹[G T] and W from the factorised iteration matrix Ŵ.
    pub fn new(factor: &BandCholesky, contacts: &[Contact], friction: &[ContactFriction]) -> Self {
        let n = factor.n();
        let m = contacts.len();
        let mut columns = vec![0.0; 2 * m * n];
        for (a, (c, f)) in contacts.iter().zip(friction).enumerate() {
            for (r, row) in [&c.g, &f.t].into_iter().enumerate() {
                let col = &mut columns[(2 * a + r) * n..(2 * a + r + 1) * n];
                for &(i, coef) in row {
                    col[i] += coef;
                }
                factor.solve_in_place(col);
            }
        }
        let mut w = vec![0.0; 4 * m * m];
        for (a, (c, f)) in contacts.iter().zip(friction).enumerate() {
            for b in 0..2 * m {
                let col = &columns[b * n..(b + 1) * n];
                w[2 * a * 2 * m + b] = c.project(col);
                w[(2 * a + 1) * 2 * m + b] = f.project(col);
            }
        }
        Self {
            n,
            columns,
            w,
            sub: FrictionSubproblem::new(m),
        }
    }

    /// W, row-major 2m×2m.
    pub fn matrix(&self) -> &[f64] {
        &self.w
    }

    /// Solves the friction problem on the index set `active` with free local velocities
    /// `b_n` (`U_free + e U_k`, the normal rows) and `b_t` (`T v_free`, the tangent rows), both
    /// in the order of `active`, and friction coefficients `friction[α].mu`; writes P_n and P_t
    /// (zero off the set) into `impulse` and `tangent_impulse`, adds `Ŵ⁻¹(G P_n + T P_t)` to
    /// `v`, and writes into `levels` the round-off level of each active contact's normal local
    /// velocity, `64 ε Σ_rows (|b| + Σ |W P|)` over its two rows (the solver couples them).
    #[allow(clippy::too_many_arguments)]
    pub fn apply_impulse(
        &mut self,
        active: &[usize],
        b_n: &[f64],
        b_t: &[f64],
        friction: &[ContactFriction],
        options: &LcpOptions,
        impulse: &mut [f64],
        tangent_impulse: &mut [f64],
        v: &mut [f64],
        levels: &mut Vec<f64>,
    ) -> Result<LcpStats, FrictionError> {
        impulse.fill(0.0);
        tangent_impulse.fill(0.0);
        levels.clear();
        if active.is_empty() {
            return Ok(LcpStats::default());
        }
        let k = active.len();
        let sol = self
            .sub
            .solve(&self.w, active, b_n, b_t, |a| friction[a].mu, options)?;
        let n = self.n;
        for (r, &a) in active.iter().enumerate() {
            let (pn, pt) = (sol.p[2 * r], sol.p[2 * r + 1]);
            impulse[a] = pn;
            tangent_impulse[a] = pt;
            for (p, col) in [(pn, 2 * a), (pt, 2 * a + 1)] {
                if p != 0.0 {
                    for (vi, ci) in v.iter_mut().zip(&self.columns[col * n..(col + 1) * n]) {
                        *vi += p * ci;
                    }
                }
            }
            levels.push(self.sub.level(r, &sol.p));
        }
        Ok(LcpStats {
            size: k,
            iterations: sol.iterations,
            error: sol.error,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The arrays give the index set, its right-hand side and the contact columns of the
    /// record bit for bit as the generic passes over [`Contact`] do, under both rules.
    #[test]
    fn unit_contacts_equal_the_generic_passes_bit_for_bit() {
        let n = 40;
        let f = |i: usize, a: f64| ((i as f64) * a).sin() * 1e-3;
        let contacts: Vec<Contact> = (0..n)
            .map(|i| Contact {
                g: vec![(n - 1 - i, if i % 3 == 0 { -1.0 } else { 0.7 })],
                offset: if i % 5 == 0 { -0.0 } else { f(i, 0.3) },
                motion: None,
                restitution: (i % 4) as f64 / 4.0,
            })
            .collect();
        let units = UnitContacts::of(&contacts).unwrap();
        let (q, v, dv): (Vec<f64>, Vec<f64>, Vec<f64>) = (
            (0..n).map(|i| f(i, 1.1)).collect(),
            (0..n)
                .map(|i| if i % 7 == 0 { -0.0 } else { f(i, 2.3) })
                .collect(),
            (0..n).map(|i| f(i, 0.7)).collect(),
        );
        let (t, h) = (0.25, 1e-2);
        for activation in [Activation::GapAndVelocity, Activation::PredictedGap] {
            let rule = IndexSetRule {
                activation,
                gamma: 0.8,
            };
            let u_free = |c: &Contact| c.project(&v) + c.project(&dv) + c.w_rate(t + h);
            // Round-off levels of a last step on the first index set, which the sign test reads.
            let mut generic = IndexSet::new(n);
            generic.assemble(&rule, &contacts, 3, &q, &v, t, h, u_free);
            let levels: Vec<f64> = (0..generic.active.len()).map(|r| f(r, 0.5).abs()).collect();
            generic.record_levels(&levels, 3);
            let mut unit = generic.clone();
            generic.assemble(&rule, &contacts, 3, &q, &v, t, h, u_free);
            unit.assemble_unit(&rule, &units, 3, &q, &v, &dv, t, h);
            assert!(!generic.active.is_empty() && generic.active.len() < n);
            assert_eq!(generic.active, unit.active);
            let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&generic.rhs), bits(&unit.rhs));
        }
        let (mut gap, mut vel) = (vec![0.0; n], vec![0.0; n]);
        units.fill(&q, &v, &mut gap, &mut vel);
        for (a, c) in contacts.iter().enumerate() {
            assert_eq!(gap[a].to_bits(), c.gap(&q, t).to_bits());
            assert_eq!(vel[a].to_bits(), c.local_velocity(&v, t).to_bits());
        }
        let active: Vec<usize> = (0..n).step_by(3).collect();
        let impulse: Vec<f64> = (0..n).map(|i| f(i, 0.9).abs()).collect();
        let generic: f64 = active
            .iter()
            .map(|&a| impulse[a] * contacts[a].project(&v))
            .sum();
        assert_eq!(
            units.work(&active, &impulse, &v).to_bits(),
            generic.to_bits()
        );
    }
}
