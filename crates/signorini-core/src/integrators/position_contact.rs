//! The smooth baselines kept on purpose, to show the energy blow-up that Acary 2016 (§1) reports
//! and the nonsmooth schemes avoid: standard Newmark and HHT with the contact enforced at
//! position level, as a general finite-element code does it — a Lagrange multiplier λ_{k+1}
//! (a force, not an impulse) on `g(q_{k+1}, t_{k+1}) ≥ 0`, no impact law.
//!
//! One step (HHT form (78) with the contact force treated as a load; Newmark is α = 0):
//!
//! ```text
//! M a_{k+1} + (1−α)[K q + C v − F − G λ]_{k+1} + α[K q + C v − F − G λ]_k = 0
//! q_{k+1} = q_k + h v_k + h²(½ − β) a_k + h² β a_{k+1}
//! v_{k+1} = v_k + h(1 − γ) a_k + h γ a_{k+1}
//! 0 ≤ g(q_{k+1}, t_{k+1}) ⊥ λ_{k+1} ≥ 0
//! ```
//!
//! With `S = M + (1−α)(γhC + βh²K)` the gap is `g_free + βh²(1−α) Gᵀ S⁻¹ G λ_{k+1}`: one LCP per
//! step on every contact, with a symmetric positive definite matrix.
//!
//! Energy: the same algorithmic energy H (55) and works as the nonsmooth HHT/Newmark (module
//! [`super::alpha`]), and `work_contact` the discrete work of the contact force by the load rule
//! (56)/(79): `Δqᵀ G[(1−α) λ_{k,γ} + α λ_{k−1,γ}]`. With these the balance of Lemma 2 closes to
//! round-off (`balance_residual`), so the energy the baseline creates shows up where it comes
//! from: `work_contact`, which a perfect unilateral constraint never makes positive (λ g = 0 in
//! continuous time, (17)), is positive here whenever the multiplier pushes a node that is
//! already moving away — the blow-up of Acary 2016 §1 and §6.4, avoided by the velocity-level
//! schemes of [`super::alpha`] (Lemma 3: their contact work is ≤ 0).

use super::alpha::{AlphaCore, AlphaParams, AlphaScheme, ContactWork, ParamError};
use super::{LinearScheme, LinearState, SchemeState, StepError, StepReport};
use crate::band::BandError;
use crate::checkpoint::CheckpointError;
use crate::contact::LcpStats;
use crate::lcp::{self, Lcp, LcpOptions};
use crate::model::LinearModel;

/// Parameters of a position-contact baseline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionContactParams {
    /// HHT α (0 for Newmark).
    pub alpha: f64,
    /// β > 0.
    pub beta: f64,
    /// γ.
    pub gamma: f64,
}

impl PositionContactParams {
    /// Standard Newmark (β = ¼, γ = ½ is the trapezoidal rule).
    pub fn newmark(beta: f64, gamma: f64) -> Self {
        Self {
            alpha: 0.0,
            beta,
            gamma,
        }
    }

    /// Standard HHT with γ = ½ + α, β = (1 + α)²/4.
    pub fn hht(alpha: f64) -> Self {
        Self {
            alpha,
            beta: 0.25 * (1.0 + alpha) * (1.0 + alpha),
            gamma: 0.5 + alpha,
        }
    }

    fn as_alpha(&self) -> AlphaParams {
        if self.alpha == 0.0 {
            AlphaParams::newmark(self.beta, self.gamma)
        } else {
            AlphaParams::hht_with(self.alpha, self.beta, self.gamma)
        }
    }

    /// The conditions of the smooth scheme ((89) for Newmark, (83) for HHT), and β > 0 (the
    /// position-level LCP needs it).
    pub fn validate(&self) -> Result<(), ParamError> {
        if self.beta.is_finite() && self.beta <= 0.0 {
            return Err(ParamError {
                field: "beta",
                reason: format!(
                    "must be > 0 for a position-level contact, got {}",
                    self.beta
                ),
                stability: false,
            });
        }
        self.as_alpha().validate()
    }
}

/// Standard Newmark/HHT with contact at position level (the baseline that blows up).
#[derive(Debug, Clone)]
pub struct PositionContact {
    core: AlphaCore,
    lcp: LcpOptions,
    /// Per contact α: (1−α) S⁻¹ G_α, the change of a_{k+1} per unit λ^α.
    s_cols: Vec<f64>,
    /// `βh² Gᵀ (1−α) S⁻¹ G`, row-major m×m.
    w: Vec<f64>,
    rhs: Vec<f64>,
}

impl PositionContact {
    /// Prepares the scheme (factorises S, precomputes the gap operator).
    pub fn new(
        model: &LinearModel,
        params: PositionContactParams,
        h: f64,
        lcp: LcpOptions,
    ) -> Result<Self, BandError> {
        let ap = params.as_alpha();
        debug_assert!(matches!(ap.scheme, AlphaScheme::Newmark | AlphaScheme::Hht));
        let core = AlphaCore::new(model, ap.coefficients(), h)?;
        let (n, m) = (model.dofs(), model.contacts.len());
        let mut s_cols = vec![0.0; n * m];
        for (a, c) in model.contacts.iter().enumerate() {
            let col = &mut s_cols[a * n..(a + 1) * n];
            for &(i, g) in &c.g {
                col[i] += (1.0 - params.alpha) * g;
            }
            core.s_factor.solve_in_place(col);
        }
        let mut w = vec![0.0; m * m];
        for (a, c) in model.contacts.iter().enumerate() {
            for b in 0..m {
                w[a * m + b] = params.beta * h * h * c.project(&s_cols[b * n..(b + 1) * n]);
            }
        }
        Ok(Self {
            core,
            lcp,
            s_cols,
            w,
            rhs: vec![0.0; m],
        })
    }
}

impl LinearScheme for PositionContact {
    fn step_size(&self) -> f64 {
        self.core.h
    }

    fn save_state(&self) -> SchemeState {
        SchemeState::PositionContact(Box::new(self.core.checkpoint_state()))
    }

    fn restore_state(&mut self, state: SchemeState) -> Result<(), CheckpointError> {
        match state {
            SchemeState::PositionContact(s) => self.core.restore_checkpoint_state(*s),
            other => Err(other.mismatch("a position-contact scheme")),
        }
    }

    fn algorithmic_energy(&self, model: &LinearModel, state: &LinearState) -> f64 {
        self.core.algorithmic_energy(model, state)
    }

    fn step(
        &mut self,
        model: &LinearModel,
        state: &mut LinearState,
        report: &mut StepReport,
    ) -> Result<(), StepError> {
        let step = state.step + 1;
        let t_next = self.core.predict(model, state);
        let (h, beta, gamma) = (self.core.h, self.core.c.beta, self.core.c.gamma);
        let n = state.q.len();
        for (a, c) in model.contacts.iter().enumerate() {
            self.rhs[a] = c.gap(&self.core.s.q, t_next);
        }
        let sol = lcp::solve(
            Lcp {
                m: &self.w,
                q: &self.rhs,
            },
            &self.lcp,
        )
        .map_err(|source| StepError::Lcp {
            step,
            t: t_next,
            source,
        })?;
        report.lcp = if sol.z.iter().any(|&l| l > 0.0) {
            LcpStats {
                size: self.rhs.len(),
                iterations: sol.iterations,
                error: sol.error,
            }
        } else {
            LcpStats::default()
        };
        let s = &mut self.core.s;
        for (a, &l) in sol.z.iter().enumerate() {
            self.core.nxt.lambda[a] = l;
            // The impulse column reports the force's impulse over the step, h λ_{k+1}.
            report.impulse[a] = h * l;
            if l != 0.0 {
                let col = &self.s_cols[a * n..(a + 1) * n];
                for (i, &ci) in col.iter().enumerate() {
                    s.a[i] += l * ci;
                    s.q[i] += beta * h * h * l * ci;
                    s.v[i] += gamma * h * l * ci;
                }
            }
        }
        self.core
            .finish(model, state, t_next, ContactWork::Force, report);
        Ok(())
    }
}
