//! The smooth part shared by the nonsmooth α-family and the position-contact baselines
//! ([`AlphaCore`]): predictor, iteration matrix S, history frames, the filters of (48)/(52) and
//! the energy bookkeeping of Lemma 2, with what it carries between steps ([`AlphaCoreState`]).

use super::lanes::dot;
use super::params::{Coefficients, PARAM_TOL};
use super::sweeps::{
    AvPart, FilterWithMemory, General, MassTerm, MemorylessFilter, NoFilter, PredictSweep, QPart,
    RowCoefficients, S_ATERM, S_D_ATERM, S_D_KIN, S_D_STRAIN, S_D_ZTERM, S_DA_M_DA, S_DQ_K_DQ,
    S_DZ_K_DZ, S_KIN, S_STRAIN, S_WORK_EXT, S_ZTERM, SUMS, Sweep, Tridiagonal, finish_sweep,
    with_terms,
};
use crate::band::{BandCholesky, BandError, SymBand};
use crate::checkpoint::CheckpointError;
use crate::energy::EnergyTerms;
use crate::integrators::{LinearState, StepReport};
use crate::model::LinearModel;

/// Per-step history of the smooth part at t_k (one of two buffers swapped every step).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct Frame {
    pub a: Vec<f64>,
    /// M a, for a consistent mass; empty for a lumped mass, where M a = m∘a is formed where
    /// it is read (see `AlphaCore::lumped`). Checkpoints of earlier builds hold a stale copy
    /// there, which a restore drops.
    pub ma: Vec<f64>,
    pub kq: Vec<f64>,
    pub cv: Vec<f64>,
    pub f: Vec<f64>,
    pub z: Vec<f64>,
    pub kz: Vec<f64>,
    pub cx: Vec<f64>,
    pub y: Vec<f64>,
    /// Contact forces λ_k of a position-contact baseline (zero for the nonsmooth family).
    pub lambda: Vec<f64>,
    /// The λ filter (y of (52) applied to Gλ, in contact coordinates).
    pub ylam: Vec<f64>,
}

impl Frame {
    /// A frame of zeros for n dofs and m contacts; `ma` of n entries for a consistent mass,
    /// empty for a lumped one.
    fn zeros(n: usize, m: usize, lumped: bool) -> Self {
        let z = vec![0.0; n];
        Self {
            a: z.clone(),
            ma: if lumped { Vec::new() } else { z.clone() },
            kq: z.clone(),
            cv: z.clone(),
            f: z.clone(),
            z: z.clone(),
            kz: z.clone(),
            cx: z.clone(),
            y: z,
            lambda: vec![0.0; m],
            ylam: vec![0.0; m],
        }
    }
}

/// Scratch vectors of one step; after [`AlphaCore::predict`] `a`, `q`, `v` hold the free
/// (impulse- and force-free) a_{k+1}, q_{k+1}, v_{k+1}; the scheme then corrects them.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(crate) struct Scratch {
    pub a: Vec<f64>,
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    tmp: Vec<f64>,
    tmp2: Vec<f64>,
}

/// The smooth part shared by [`NonsmoothAlpha`] and the position-contact baselines: predictor,
/// iteration matrix S, history, filters and the energy bookkeeping of Lemma 2.
#[derive(Debug, Clone)]
pub(crate) struct AlphaCore {
    pub h: f64,
    pub c: Coefficients,
    /// η/ν (0 when the filters are off).
    ratio: f64,
    /// Coefficient of zᵀKz in H (55).
    cz: f64,
    filters: bool,
    has_damping: bool,
    /// F has a time-varying part (else the y filter stays exactly zero and is skipped).
    varying_load: bool,
    /// `nxt.f`, `f_rhs` and `f_work` hold the (constant) load: set by the first predictor of a
    /// run with `varying_load` false, so that later steps do not evaluate F again.
    f_ready: bool,
    /// The load part of the right-hand side of (53), `(1−α_L) F_{k+1} + α_L F_k` (formed once
    /// per run for a constant load, else by each predictor).
    f_rhs: Vec<f64>,
    /// The load of the external work (56), `γ F_{k+1} + (1−γ) F_k` (likewise).
    f_work: Vec<f64>,
    /// M is diagonal (lumped): M a is formed as m∘a where it is needed, and the frames' `ma`
    /// is not kept up to date (one sweep and two history vectors fewer per step).
    lumped: bool,
    pub s_factor: BandCholesky,
    pub m_factor: BandCholesky,
    /// History at t_k and the buffer for t_{k+1}.
    pub cur: Frame,
    pub nxt: Frame,
    /// Step number `cur` describes.
    cur_step: Option<u64>,
    pub s: Scratch,
}

/// How the contact works of a step are computed by [`AlphaCore::finish`].
pub(crate) enum ContactWork {
    /// The nonsmooth family: `(Gᵀ v_{k+1/2})ᵀ P_{k+1}`, computed by the caller.
    Impulse(f64),
    /// A position-contact baseline: λ_{k+1} is in `nxt.lambda`; the work is the load work of
    /// the force Gλ, `Δqᵀ G[λ_{k,γ} − (η/ν) ỹ_{k,γ}]`.
    Force,
}

impl AlphaCore {
    pub fn new(model: &LinearModel, c: Coefficients, h: f64) -> Result<Self, BandError> {
        let w = c.weights;
        let s = SymBand::combine(&[
            (1.0 - w.mass, &model.mass),
            ((1.0 - w.damping) * c.gamma * h, &model.damping),
            ((1.0 - w.stiffness) * c.beta * h * h, &model.stiffness),
        ]);
        let s_factor = s.cholesky()?;
        let m_factor = model.mass.cholesky()?;
        let filters = c.nu.abs() > PARAM_TOL && c.eta != 0.0;
        let (ratio, cz) = if filters {
            (
                c.eta / c.nu,
                c.eta / (2.0 * c.nu * c.nu) * (c.nu - c.gamma + 0.5),
            )
        } else {
            (0.0, 0.0)
        };
        let (n, m) = (model.dofs(), model.contacts.len());
        let lumped = model.mass.kd() == 0;
        let z = vec![0.0; n];
        Ok(Self {
            h,
            c,
            ratio,
            cz,
            filters,
            has_damping: !model.damping.is_zero(),
            varying_load: !model.force.harmonic.is_empty(),
            f_ready: false,
            f_rhs: z.clone(),
            f_work: z.clone(),
            lumped,
            s_factor,
            m_factor,
            cur: Frame::zeros(n, m, lumped),
            nxt: Frame::zeros(n, m, lumped),
            cur_step: None,
            s: Scratch {
                a: z.clone(),
                q: z.clone(),
                v: z.clone(),
                tmp: z.clone(),
                tmp2: z,
            },
        })
    }

    /// Consistent start at `state` into `frame`: a = M⁻¹(F − Kq − Cv), filters and λ zero.
    fn start_frame(&self, model: &LinearModel, state: &LinearState, frame: &mut Frame) {
        model.force.eval_into(state.t, &mut frame.f);
        model.stiffness.mul_into(&state.q, &mut frame.kq);
        if self.has_damping {
            model.damping.mul_into(&state.v, &mut frame.cv);
        } else {
            frame.cv.fill(0.0);
        }
        for i in 0..frame.a.len() {
            frame.a[i] = frame.f[i] - frame.kq[i] - frame.cv[i];
        }
        self.m_factor.solve_in_place(&mut frame.a);
        if !self.lumped {
            model.mass.mul_into(&frame.a, &mut frame.ma);
        }
        for v in [
            &mut frame.z,
            &mut frame.kz,
            &mut frame.cx,
            &mut frame.y,
            &mut frame.lambda,
            &mut frame.ylam,
        ] {
            v.fill(0.0);
        }
    }

    /// Makes `cur` describe `state` (a consistent start unless the last step produced it).
    pub fn ensure_history(&mut self, model: &LinearModel, state: &LinearState) {
        if self.cur_step != Some(state.step) {
            let mut frame = std::mem::replace(&mut self.cur, Frame::zeros(0, 0, true));
            self.start_frame(model, state, &mut frame);
            self.cur = frame;
            self.cur_step = Some(state.step);
        }
    }

    /// aᵀMa of a frame (M a formed as m∘a for a lumped mass, where `frame.ma` is not kept), in
    /// the partial sums of [`dot`] and of the step's sweep.
    fn a_m_a(&self, model: &LinearModel, frame: &Frame) -> f64 {
        if self.lumped {
            let n = frame.a.len();
            let (a, m) = (&frame.a[..n], &model.mass.band(0)[..n]);
            let (ac, mc) = (a.chunks_exact(4), m.chunks_exact(4));
            let mut tail = 0.0;
            for (x, w) in ac.remainder().iter().zip(mc.remainder()) {
                tail += x * (w * x);
            }
            let mut acc = [0.0; 4];
            for (x, w) in ac.zip(mc) {
                for l in 0..4 {
                    acc[l] += x[l] * (w[l] * x[l]);
                }
            }
            (acc[0] + acc[2]) + (acc[1] + acc[3]) + tail
        } else {
            dot(&frame.a, &frame.ma)
        }
    }

    /// H (55) at `state` given its history frame.
    fn algorithmic_energy_of(
        &self,
        model: &LinearModel,
        state: &LinearState,
        frame: &Frame,
    ) -> f64 {
        let kin = 0.5 * model.mass.quad(&state.v, &state.v);
        let strain = 0.5 * dot(&state.q, &frame.kq);
        let h2 = self.h * self.h;
        kin + strain
            + 0.25 * h2 * (2.0 * self.c.beta - self.c.gamma) * self.a_m_a(model, frame)
            + self.cz * dot(&frame.z, &frame.kz)
    }

    /// H (55) at `state` (from the history when the last step produced `state`, else from a
    /// consistent start there).
    pub fn algorithmic_energy(&self, model: &LinearModel, state: &LinearState) -> f64 {
        if self.cur_step == Some(state.step) {
            self.algorithmic_energy_of(model, state, &self.cur)
        } else {
            let mut frame = Frame::zeros(model.dofs(), model.contacts.len(), self.lumped);
            self.start_frame(model, state, &mut frame);
            self.algorithmic_energy_of(model, state, &frame)
        }
    }

    /// Free step: F_{k+1} into `nxt.f`, and the solution of the collocation relation with no
    /// impulse (and, for the baselines, no new contact force) into `s.a`, `s.q`, `s.v`.
    /// Returns t_{k+1}.
    ///
    /// Every sweep runs on plain slices of equal length (no bounds checks, no reloading of the
    /// vectors through `self`), so that the compiler vectorises it; the arithmetic per dof is
    /// that of (25f), (25g) and (53) in the order written, so the result does not depend on it.
    pub fn predict(&mut self, model: &LinearModel, state: &LinearState) -> f64 {
        self.ensure_history(model, state);
        let h = self.h;
        let (beta, gamma) = (self.c.beta, self.c.gamma);
        let w = self.c.weights;
        let t_next = (state.step + 1) as f64 * h;
        // A constant load is the same at every t: evaluated once into each frame, and its
        // combinations for (53) and (56) formed once.
        if self.varying_load || !self.f_ready {
            model.force.eval_into(t_next, &mut self.nxt.f);
            let f0 = if self.varying_load {
                &self.cur.f
            } else {
                &self.nxt.f
            };
            let (g1, g0) = (gamma, 1.0 - gamma);
            for (((fr, fw), f1), f0) in self
                .f_rhs
                .iter_mut()
                .zip(&mut self.f_work)
                .zip(&self.nxt.f)
                .zip(f0)
            {
                *fr = (1.0 - w.load) * f1 + w.load * f0;
                *fw = g1 * f1 + g0 * f0;
            }
            self.f_ready = !self.varying_load;
        }
        let n = state.q.len();
        let (cur, s) = (&self.cur, &mut self.s);
        // Predictors q̂ = q_k + h v_k + h²(½ − β) a_k (in s.q), v̂ = v_k + h(1 − γ) a_k (in s.v).
        let cq = h * h * (0.5 - beta);
        let cv = h * (1.0 - gamma);
        let rows = RowCoefficients {
            cv,
            mass: w.mass,
            damping: w.damping,
            stiffness: [w.stiffness, 1.0 - w.stiffness],
        };
        // Which terms of (53) a row has: α_M M a_k (lumped: m∘a) and α_C C v_k only when they
        // are not zero.
        let (mass, m) = match (w.mass != 0.0, self.lumped) {
            (false, _) => (MassTerm::None, &cur.a[..n]),
            (true, true) => (MassTerm::Lumped, &model.mass.band(0)[..n]),
            (true, false) => (MassTerm::Product, &cur.ma[..n]),
        };
        let damped = self.has_damping && w.damping != 0.0;
        let sweep = PredictSweep {
            q: &state.q[..n],
            v: &state.v[..n],
            a: &cur.a[..n],
            f_rhs: &self.f_rhs[..n],
            cv: &cur.cv[..n],
            kq: &cur.kq[..n],
            k0: &model.stiffness.band(0)[..n],
            k1: &model.stiffness.band(1.min(model.stiffness.kd()))[..n],
            q_hat: &mut s.q[..n],
            v_hat: &mut s.v[..n],
            b: &mut s.a[..n],
        };
        let c = [h, cq];
        if model.stiffness.kd() == 1 && n >= 2 {
            // Tridiagonal K: predictors, K q̂ and b in one sweep.
            with_terms(mass, damped, Tridiagonal { sweep, m, c, rows });
        } else {
            let pass = General {
                sweep,
                m,
                c,
                rows,
                stiffness: &model.stiffness,
                tmp: &mut s.tmp[..n],
            };
            with_terms(mass, damped, pass);
        }
        if self.has_damping {
            model.damping.mul_into(&s.v, &mut s.tmp);
            for (b, cvh) in s.a[..n].iter_mut().zip(&s.tmp[..n]) {
                *b -= (1.0 - w.damping) * cvh;
            }
        }
        // A baseline's contact force at t_k enters with the load weight.
        for (c, &l) in model.contacts.iter().zip(&cur.lambda) {
            if l != 0.0 {
                for &(i, g) in &c.g {
                    s.a[i] += w.load * l * g;
                }
            }
        }
        // Solve S a_{k+1} = b, with (25f), (25g) q = q̂ + h²β a, v = v̂ + hγ a in its back sweep.
        self.s_factor.solve_in_place_axpy(
            &mut s.a,
            [h * h * beta, h * gamma],
            [&mut s.q, &mut s.v],
        );
        t_next
    }

    /// Completes a step whose a_{k+1}, q_{k+1}, v_{k+1} are in `s.a`, `s.q`, `s.v` (and, for a
    /// baseline, λ_{k+1} in `nxt.lambda`): history, filters, energy terms, then the new state.
    ///
    /// The products at t_{k+1} (K q; M a for a consistent mass, C v with damping), then two
    /// passes ([`finish_sweep`]: q with the z filter, a and v) for every sum of the balance
    /// (works, quadratic terms, ΔH) and the sums of H; the new a, q, v are swapped in, not
    /// copied.
    pub fn finish(
        &mut self,
        model: &LinearModel,
        state: &mut LinearState,
        t_next: f64,
        contact: ContactWork,
        report: &mut StepReport,
    ) {
        self.products_at_next(model);
        let filter = self.filter_pass(state.q.len());
        let b = self.balance_terms(model, state, contact, filter);
        let (h, beta, gamma) = (self.h, self.c.beta, self.c.gamma);
        let (nxt, s) = (&mut self.nxt, &mut self.s);
        let sums = &b.sums;
        let h2 = h * h;
        // The new state and history: swapped in (the scratch vectors are rewritten by the next
        // predictor before they are read).
        std::mem::swap(&mut state.q, &mut s.q);
        std::mem::swap(&mut state.v, &mut s.v);
        std::mem::swap(&mut nxt.a, &mut s.a);
        state.t = t_next;
        state.step += 1;
        std::mem::swap(&mut self.cur, &mut self.nxt);
        self.cur_step = Some(state.step);

        // H (55) from the sums of the sweep (no second pass over q, v, a, z).
        let strain = 0.5 * sums[S_STRAIN];
        let mut alg = b.kin + strain + 0.25 * h2 * (2.0 * beta - gamma) * sums[S_ATERM];
        if self.filters {
            alg += self.cz * sums[S_ZTERM];
        }
        report.energy = EnergyTerms {
            kinetic: b.kin,
            strain,
            work_ext: b.work_ext,
            work_damping: b.work_damping,
            work_contact: b.work_contact,
            numerical_dissipation: b.numerical_dissipation,
            algorithmic_energy: alg,
            balance_residual: b.delta_h
                - b.work_ext
                - b.work_damping
                - b.work_contact
                - b.numerical_dissipation,
        };
        report.fill_contacts(model, &state.q, &state.v, t_next);
    }

    /// The products at t_{k+1}: M a_{k+1} for a consistent mass, K q_{k+1}, and C v_{k+1} with
    /// damping (without it C v stays zero in both frames: start_frame zeroes it).
    fn products_at_next(&mut self, model: &LinearModel) {
        let (nxt, s) = (&mut self.nxt, &self.s);
        if !self.lumped {
            model.mass.mul_into(&s.a, &mut nxt.ma);
        }
        model.stiffness.mul_into(&s.q, &mut nxt.kq);
        if self.has_damping {
            model.damping.mul_into(&s.v, &mut nxt.cv);
        }
    }

    /// The filter pass: x_{k+1}, y_{k+1} and the contact force's y of (48), (52); returns the
    /// coefficients [c_n, c_m] of the z filter, which the sweep of [`Self::balance_terms`]
    /// updates.
    fn filter_pass(&mut self, n: usize) -> [f64; 2] {
        let (cur, nxt) = (&self.cur, &mut self.nxt);
        let xy = self.filters && self.c.xy_filters;
        let nu = self.c.nu;
        // Filters (48), (52): (½+ν) z_{k+1} + (½−ν) z_k = ν Δq (and K z, C x, y alike),
        // divided by ½+ν once per step: z_{k+1} = c_n Δq − c_m z_k. z and K z are updated in
        // the sweep of `balance_terms`; with α_m = 0 (HHT, ν = ½) c_m = 0 and z_{k+1} = ½ Δq.
        let (cn, cm) = if self.filters {
            (nu / (0.5 + nu), (0.5 - nu) / (0.5 + nu))
        } else {
            (0.0, 0.0)
        };
        if self.filters {
            // x and y start at zero and are driven by Δ(Cv) and ΔF only: without damping or
            // without a time-varying load they stay exactly zero and are skipped.
            if xy && self.has_damping {
                for (((x1, x0), c1), c0) in nxt.cx[..n]
                    .iter_mut()
                    .zip(&cur.cx[..n])
                    .zip(&nxt.cv[..n])
                    .zip(&cur.cv[..n])
                {
                    *x1 = cn * (c1 - c0) - cm * x0;
                }
            }
            if xy && self.varying_load {
                for (((y1, y0), f1), f0) in nxt.y[..n]
                    .iter_mut()
                    .zip(&cur.y[..n])
                    .zip(&nxt.f[..n])
                    .zip(&cur.f[..n])
                {
                    *y1 = cn * (f1 - f0) - cm * y0;
                }
            }
            if xy {
                for a in 0..nxt.lambda.len() {
                    nxt.ylam[a] = cn * (nxt.lambda[a] - cur.lambda[a]) - cm * cur.ylam[a];
                }
            }
        }
        [cn, cm]
    }

    /// The balance of a step from the sums of one sweep ([`finish_sweep`]: q with the z filter,
    /// a and v): works (56)–(57) / (79)–(80) with the x, y filter terms of (58), the contact
    /// work, the quadratic terms of (73), (81), (87) and ΔH, all in difference form.
    fn balance_terms(
        &mut self,
        model: &LinearModel,
        state: &LinearState,
        contact: ContactWork,
        [cn, cm]: [f64; 2],
    ) -> Balance {
        let n = state.q.len();
        let (h, beta, gamma, nu) = (self.h, self.c.beta, self.c.gamma, self.c.nu);
        let eta = self.c.eta;
        let (cur, nxt, s) = (&self.cur, &mut self.nxt, &mut self.s);
        let lumped = self.lumped;
        let ratio = self.ratio;
        let xy = self.filters && self.c.xy_filters;
        let (g1, g0) = (gamma, 1.0 - gamma);
        let rx = if xy { ratio } else { 0.0 };
        let ry = if xy && self.varying_load { ratio } else { 0.0 };
        // With a lumped mass `ma` is not read (M a = m∘a), with a constant load F_k = F_{k+1}.
        let (ma1, ma0) = if lumped {
            (&s.a, &cur.a)
        } else {
            (&nxt.ma, &cur.ma)
        };
        let sweep = Sweep {
            q1: &s.q[..n],
            q0: &state.q[..n],
            v1: &s.v[..n],
            v0: &state.v[..n],
            a1: &s.a[..n],
            a0: &cur.a[..n],
            kq1: &nxt.kq[..n],
            kq0: &cur.kq[..n],
            ma1: &ma1[..n],
            ma0: &ma0[..n],
            fw: &self.f_work[..n],
            z0: &cur.z[..n],
            kz0: &cur.kz[..n],
            mass: &model.mass.band(0)[..n],
            z1: &mut nxt.z[..n],
            kz1: &mut nxt.kz[..n],
            dv: &mut s.tmp[..n],
            sv: &mut s.tmp2[..n],
            filter: [cn, cm],
        };
        let mut sweep = sweep;
        // The q part depends on the filter only, the a, v part on the mass only.
        let q_part = match (self.filters, cm != 0.0) {
            (false, _) => finish_sweep::<NoFilter, false, QPart>(&mut sweep),
            (true, false) => finish_sweep::<MemorylessFilter, false, QPart>(&mut sweep),
            (true, true) => finish_sweep::<FilterWithMemory, false, QPart>(&mut sweep),
        };
        let av_part = if lumped {
            finish_sweep::<NoFilter, true, AvPart>(&mut sweep)
        } else {
            finish_sweep::<NoFilter, false, AvPart>(&mut sweep)
        };
        // Each sum is formed by one part (the other's entry is zero).
        let sums: [f64; SUMS] = std::array::from_fn(|s| q_part[s] + av_part[s]);
        let mut work_ext = sums[S_WORK_EXT];
        let mut work_damping = 0.0;
        if ry != 0.0 {
            for (((q1, q0), y1), y0) in s.q[..n]
                .iter()
                .zip(&state.q[..n])
                .zip(&nxt.y[..n])
                .zip(&cur.y[..n])
            {
                work_ext -= (q1 - q0) * ry * (g1 * y1 + g0 * y0);
            }
        }
        if self.has_damping {
            for (((q1, q0), (c1, c0)), (x1, x0)) in s.q[..n]
                .iter()
                .zip(&state.q[..n])
                .zip(nxt.cv[..n].iter().zip(&cur.cv[..n]))
                .zip(nxt.cx[..n].iter().zip(&cur.cx[..n]))
            {
                let cv_g = g1 * c1 + g0 * c0 - rx * (g1 * x1 + g0 * x0);
                work_damping -= (q1 - q0) * cv_g;
            }
        }
        let (d_kin, kin) = if lumped {
            (0.5 * sums[S_D_KIN], 0.5 * sums[S_KIN])
        } else {
            (
                0.5 * model.mass.quad(&s.tmp2, &s.tmp),
                0.5 * model.mass.quad(&s.v, &s.v),
            )
        };
        let h2 = h * h;
        let delta_h = d_kin
            + 0.5 * sums[S_D_STRAIN]
            + 0.25 * h2 * (2.0 * beta - gamma) * sums[S_D_ATERM]
            + self.cz * sums[S_D_ZTERM];
        let work_contact = match contact {
            ContactWork::Impulse(w) => w,
            ContactWork::Force => {
                let ry = if xy { ratio } else { 0.0 };
                let mut w = 0.0;
                for (a, c) in model.contacts.iter().enumerate() {
                    let l_g = g1 * nxt.lambda[a] + g0 * cur.lambda[a]
                        - ry * (g1 * nxt.ylam[a] + g0 * cur.ylam[a]);
                    if l_g != 0.0 {
                        w += l_g * (c.project(&s.q) - c.project(&state.q));
                    }
                }
                w
            }
        };
        let numerical_dissipation =
            -0.5 * h2 * (gamma - 0.5) * (2.0 * beta - gamma) * sums[S_DA_M_DA]
                - (gamma - 0.5 - eta) * sums[S_DQ_K_DQ]
                - ratio * (nu - gamma + 0.5) * sums[S_DZ_K_DZ];
        Balance {
            sums,
            kin,
            delta_h,
            work_ext,
            work_damping,
            work_contact,
            numerical_dissipation,
        }
    }
}

/// The balance terms of a step ([`AlphaCore::balance_terms`]) and the sweep's sums, from which
/// [`AlphaCore::finish`] forms H.
struct Balance {
    sums: [f64; SUMS],
    kin: f64,
    delta_h: f64,
    work_ext: f64,
    work_damping: f64,
    work_contact: f64,
    numerical_dissipation: f64,
}

/// What [`AlphaCore`] carries between steps: the history frames (accelerations a_k, the filters
/// z, x, y and their products, λ_k of a baseline), the step they describe and the scratch
/// vectors.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct AlphaCoreState {
    cur: Frame,
    nxt: Frame,
    cur_step: Option<u64>,
    s: Scratch,
}

impl AlphaCore {
    pub(crate) fn checkpoint_state(&self) -> AlphaCoreState {
        AlphaCoreState {
            cur: self.cur.clone(),
            nxt: self.nxt.clone(),
            cur_step: self.cur_step,
            s: self.s.clone(),
        }
    }

    pub(crate) fn restore_checkpoint_state(
        &mut self,
        s: AlphaCoreState,
    ) -> Result<(), CheckpointError> {
        // M a is kept for a consistent mass only; a lumped-mass checkpoint of an earlier build
        // holds a stale copy, dropped here so that the state is the one a run keeps.
        let lumped = self.lumped;
        let fits = |f: &Frame, g: &Frame| {
            f.a.len() == g.a.len()
                && f.lambda.len() == g.lambda.len()
                && (lumped || f.ma.len() == g.ma.len())
        };
        if !fits(&s.cur, &self.cur) || !fits(&s.nxt, &self.nxt) || s.s.a.len() != self.s.a.len() {
            return Err(CheckpointError::Mismatch(format!(
                "α-family state of {} dofs, the model has {}",
                s.cur.a.len(),
                self.cur.a.len()
            )));
        }
        let (mut cur, mut nxt) = (s.cur, s.nxt);
        if lumped {
            cur.ma = Vec::new();
            nxt.ma = Vec::new();
        }
        self.cur = cur;
        self.nxt = nxt;
        self.cur_step = s.cur_step;
        self.s = s.s;
        self.f_ready = false;
        Ok(())
    }
}
