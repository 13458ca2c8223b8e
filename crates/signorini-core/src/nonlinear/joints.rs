//! Bilateral holonomic joints g(q, t) = 0 of a nonlinear Lagrangian system: the interface both
//! nonlinear time-steppings read ([`super::moreau_jean`] as equality rows of its mixed LCP,
//! [`super::generalized_alpha`] in its smooth, velocity and position stages), and its
//! implementation by the user models of `scene = "lagrangian"`.

use super::LagrangianSystem;
use crate::lagrangian::UserModel;
use crate::soi2::{ConstrainedModel, Dual64};

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
}
