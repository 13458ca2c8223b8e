//! Bilateral holonomic joints g(q, t) = 0 of a nonlinear Lagrangian system: the interface both
//! nonlinear time-steppings read ([`super::moreau_jean`] as equality rows of its mixed LCP,
//! [`super::generalized_alpha`] in its smooth, velocity and position stages), and its
//! implementation by the user models of `scene = "lagrangian"`.

use super::LagrangianSystem;
use crate::lagrangian::UserModel;
use crate::soi2::{ConstrainedModel, Dual64, g_ddot};

/// A [`LagrangianSystem`] with bilateral holonomic joints g(q, t) = 0 (nb of them). The
/// defaults describe a system without joints.
pub trait JointedSystem: LagrangianSystem {
    /// Number of joints nb.
    fn joints(&self) -> usize {
        0
    }

    /// g(q, t), nb entries.
    fn joint_values(&self, t: f64, q: &[f64], out: &mut [f64]) {
        let _ = (t, q, out);
    }

    /// G = ∂g/∂q, nb×n row-major.
    fn joint_jacobian(&self, t: f64, q: &[f64], out: &mut [f64]) {
        let _ = (t, q, out);
    }

    /// G v + g_t, nb entries.
    fn joint_rates(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
        let _ = (t, q, v, out);
    }

    /// κ = d/dt(G v + g_t) with q̈ = 0, i.e. g_qq(v, v) + 2 g_qt v + g_tt, nb entries.
    fn joint_curvature(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
        let _ = (t, q, v, out);
    }

    /// ∂(M(q) a)/∂q, n×n row-major: how the inertia forces of the acceleration `a` change with
    /// the positions (a term of Newton's exact iteration matrix). Default: zero, exact for a
    /// constant mass matrix.
    fn mass_derivative(&self, q: &[f64], a: &[f64], out: &mut [f64]) {
        let _ = (q, a);
        out.fill(0.0);
    }

    /// ∂(G(q, t)ᵀ λ)/∂q = Σ_j λ_j ∇²g_j, n×n row-major: how the joint forces change with the
    /// positions. Default: zero (no joints).
    fn joint_force_derivative(&self, t: f64, q: &[f64], lambda: &[f64], out: &mut [f64]) {
        let _ = (t, q, lambda);
        out.fill(0.0);
    }

    /// The derivatives of the joints' acceleration level g̈ = G(q, t) a + κ(t, q, v) at fixed
    /// a: ∂g̈/∂q into `dq` and ∂g̈/∂v = ∂κ/∂v into `dv`, nb×n row-major each. Default: none
    /// (no joints).
    fn joint_acceleration_derivatives(
        &self,
        t: f64,
        q: &[f64],
        v: &[f64],
        a: &[f64],
        dq: &mut [f64],
        dv: &mut [f64],
    ) {
        let _ = (t, q, v, a, dq, dv);
    }
}

/// The joints of a user model from its symbolic tapes; κ is the derivative of the tape of
/// G v + g_t along (t, q, v) → (1, v, 0), by one forward-mode dual evaluation.
impl JointedSystem for UserModel {
    fn joints(&self) -> usize {
        UserModel::joints(self)
    }

    fn joint_values(&self, t: f64, q: &[f64], out: &mut [f64]) {
        ConstrainedModel::g(self, t, q, out);
    }

    fn joint_jacobian(&self, t: f64, q: &[f64], out: &mut [f64]) {
        ConstrainedModel::g_y(self, t, q, out);
    }

    fn joint_rates(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
        ConstrainedModel::g_dot(self, t, q, v, out);
    }

    fn joint_curvature(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
        let td = Dual64::new(t, 1.0);
        let qd: Vec<Dual64> = q.iter().zip(v).map(|(&x, &w)| Dual64::new(x, w)).collect();
        let vd: Vec<Dual64> = v.iter().map(|&w| Dual64::from(w)).collect();
        let mut rd = vec![Dual64::from(0.0); out.len()];
        ConstrainedModel::g_dot(self, td, &qd, &vd, &mut rd);
        for (o, r) in out.iter_mut().zip(&rd) {
            *o = r.eps;
        }
    }

    /// One forward-mode dual evaluation of the mass tape per coordinate.
    fn mass_derivative(&self, q: &[f64], a: &[f64], out: &mut [f64]) {
        let n = q.len();
        let mut qd = duals(q);
        let mut m = vec![Dual64::from(0.0); n * n];
        for j in 0..n {
            qd[j].eps = 1.0;
            ConstrainedModel::mass(self, Dual64::from(0.0), &qd, &mut m);
            qd[j].eps = 0.0;
            for i in 0..n {
                out[i * n + j] = m[i * n..(i + 1) * n]
                    .iter()
                    .zip(a)
                    .map(|(mik, ak)| mik.eps * ak)
                    .sum();
            }
        }
    }

    /// One forward-mode dual evaluation of the tape of G per coordinate.
    fn joint_force_derivative(&self, t: f64, q: &[f64], lambda: &[f64], out: &mut [f64]) {
        let n = q.len();
        let mut qd = duals(q);
        let mut g = vec![Dual64::from(0.0); lambda.len() * n];
        for j in 0..n {
            qd[j].eps = 1.0;
            ConstrainedModel::g_y(self, Dual64::from(t), &qd, &mut g);
            qd[j].eps = 0.0;
            for i in 0..n {
                out[i * n + j] = lambda
                    .iter()
                    .enumerate()
                    .map(|(r, l)| g[r * n + i].eps * l)
                    .sum();
            }
        }
    }

    /// g̈ as the derivative of the tape of G v + g_t along (1, v, a) ([`g_ddot`]), its
    /// derivatives by one more dual evaluation per coordinate of q and of v.
    fn joint_acceleration_derivatives(
        &self,
        t: f64,
        q: &[f64],
        v: &[f64],
        a: &[f64],
        dq: &mut [f64],
        dv: &mut [f64],
    ) {
        let n = q.len();
        let (mut qd, mut vd, ad) = (duals(q), duals(v), duals(a));
        let td = Dual64::from(t);
        let mut out = vec![Dual64::from(0.0); UserModel::joints(self)];
        for j in 0..n {
            qd[j].eps = 1.0;
            g_ddot(self, td, &qd, &vd, &ad, &mut out);
            qd[j].eps = 0.0;
            for (r, o) in out.iter().enumerate() {
                dq[r * n + j] = o.eps;
            }
            vd[j].eps = 1.0;
            g_ddot(self, td, &qd, &vd, &ad, &mut out);
            vd[j].eps = 0.0;
            for (r, o) in out.iter().enumerate() {
                dv[r * n + j] = o.eps;
            }
        }
    }
}

/// Constant dual numbers of `x` (no derivative direction yet).
fn duals(x: &[f64]) -> Vec<Dual64> {
    x.iter().map(|&v| Dual64::from(v)).collect()
}
