//! The friction impulse's work over a step: what `work_friction` reports and what of the
//! tangential impulse's work goes to `work_contact` instead.
//!
//! Multiplying the impulse equation of a θ-scheme (Acary 2016, "Energy conservation and
//! dissipation properties of time-integration methods for nonsmooth elastodynamics with
//! contact", ZAMM 96(5), doi:10.1002/zamm.201400231, (21a); the α-family's (25b) with θ = ½;
//! the rigid bodies' (1a)) by the velocity of the works, as Lemma 1 does, turns each contact's
//! tangential impulse term into
//!
//! ```text
//! W_t = P_t · U_t,{k+θ} = θ P_t · U_t,{k+1} + (1 − θ) P_t · U_t,k
//! ```
//!
//! next to the normal term P_n U_n,{k+θ}; their sum over the contacts closes the ledger. The
//! end term is ≤ 0 always: the one-step problem imposes Coulomb's law on U_t,{k+1}, whose
//! maximal dissipation gives P_t · U_t,{k+1} = −μ P_n |U_t,{k+1}| (Moreau 1988, "Unilateral
//! contact and dry friction in finite freedom dynamics", doi:10.1007/978-3-7091-2624-0_1). The
//! start term is ≤ 0 unless P_t · U_t,k > 0: the friction impulse points along the start
//! velocity, so the tangential velocity reversed within the step. In the continuous problem
//! friction never does positive work (its power is −μ λ_n |u_t|), but at an impact with normal–
//! tangential coupling the normal impulse itself reverses U_t through the Delassus operator's
//! W_tn P_n, and friction then takes back what the normal impulse gave the sliding motion:
//! that is the setting of Kane's double-pendulum paradox, where the impulse work's split into
//! normal and tangential parts has no sign although their sum is ≤ 0 (Acary 2016, §7, citing
//! Leine & van de Wouw 2008: Coulomb's friction at the impulse level with an impact law is not
//! dissipative term by term). Hence the split, per contact:
//!
//! ```text
//! P_t · U_t,k ≤ 0:  work_friction = W_t,                 nothing moved
//! P_t · U_t,k > 0:  work_friction = θ P_t · U_t,{k+1},   work_contact += W_t − θ P_t · U_t,{k+1}
//! ```
//!
//! so that `work_friction` ≤ 0 at every step (to the friction solver's tolerance), equals the
//! scheme's W_t on every step without a reversal (a block sliding or sticking is reported as
//! before, bit for bit, and Σ work_friction stays the exact μ P_n × distance of the trapezoidal
//! rule on a constant deceleration), and work_contact + work_friction is the impulses' work of
//! the scheme's balance, so the ledger still closes. Rejected alternative: work_friction =
//! P_t · U_t,{k+1} on every step, which is ≤ 0 as well but is first order where W_t is second:
//! on a block sliding with constant deceleration it is off by ½ h μ P_n Δv per step, and the
//! difference would appear as contact work on steps without any impact.

/// One contact's tangential impulse work split into its friction part and the part the impact
/// gave back (module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TangentialWork {
    /// The friction work, ≤ 0: W_t, or θ P_t · U_t,{k+1} on a reversing step.
    pub friction: f64,
    /// What goes to `work_contact`: 0, or W_t − θ P_t · U_t,{k+1} on a reversing step.
    pub contact: f64,
}

/// Splits the tangential work `work` = W_t of a contact, as the scheme computed it, given
/// `theta` (the weight of the end velocity in the work's velocity: θ for Moreau–Jean, ½ for the
/// variant and the α-family), `at_start` = P_t · U_t,k and `at_end` = P_t · U_t,{k+1}.
pub fn split_tangential_work(work: f64, theta: f64, at_start: f64, at_end: f64) -> TangentialWork {
    if at_start > 0.0 {
        let friction = theta * at_end;
        TangentialWork {
            friction,
            contact: work - friction,
        }
    } else {
        TangentialWork {
            friction: work,
            contact: 0.0,
        }
    }
}
