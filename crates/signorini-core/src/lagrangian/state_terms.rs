//! The terms an SOI2 step's residual takes at its new state (Jay & Negrut (2008) (13d)–(13g),
//! (17c)–(17f); [`ConstrainedModel::state_terms`](crate::soi2::ConstrainedModel::state_terms)):
//! the force F = −∇V − c + f, the joints g, their rates g_q q̇ + g_t and g_q's entries, on one
//! tape. A mechanism's terms all take the sines and cosines of its angles, and the tape
//! computes them once: separate tapes of F, g_q (twice for the two multiplier sets of (13d),
//! (13e)), g and g_q q̇ + g_t each computed them again.

use super::newton_terms::NewtonSources;
use crate::expr::{Expr, Tape};
use crate::soi2::{Scalar, StateTerms};

/// The combined tape: outputs F (n), g (m), g_q q̇ + g_t (m), then g_q's structural nonzeros
/// at n + 2m + r·n + i, in row-major order.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct StateTape {
    tape: Tape,
    n: usize,
    joints: usize,
}

impl StateTape {
    /// Compiles the terms of a model of `n` coordinates from its force and joint expressions
    /// and the joints' derivatives in `sources`.
    pub(super) fn new(n: usize, forces: &[Expr], joints: &[Expr], sources: &NewtonSources) -> Self {
        let m = joints.len();
        let dense = forces
            .iter()
            .chain(joints)
            .chain(&sources.joint_rate)
            .enumerate()
            .map(|(k, e)| (k, e.clone()));
        let jacobian = sources
            .joint_jacobian
            .iter()
            .enumerate()
            .flat_map(|(r, row)| {
                row.iter()
                    .map(move |(i, e)| (n + 2 * m + r * n + i, e.clone()))
            });
        let entries: Vec<(usize, Expr)> = dense.chain(jacobian).collect();
        StateTape {
            tape: Tape::compile_sparse(n + 2 * m + m * n, &entries),
            n,
            joints: m,
        }
    }

    /// The terms at the tape variables `vars` (q, q̇, t): F − g_qᵀλ_k for each λ_k of
    /// `multipliers` (what [`ConstrainedModel::force`](crate::soi2::ConstrainedModel::force)
    /// computes, in its order of operations), g, g_q q̇ + g_t, and g_q's entries when
    /// `with_g_y`.
    pub(super) fn eval<T: Scalar>(
        &self,
        vars: &[T],
        multipliers: &[&[T]],
        with_g_y: bool,
    ) -> StateTerms<T> {
        let (n, m) = (self.n, self.joints);
        let mut values = vec![T::zero(); self.tape.stored()];
        self.tape
            .eval_stored_into(vars, &mut Vec::new(), &mut values);
        let (force, rest) = values.split_at(n);
        let (g, rest) = rest.split_at(m);
        let (g_dot, jacobian) = rest.split_at(m);
        let index = self.tape.stored_outputs().unwrap_or_default();
        let entries = || {
            index[n + 2 * m..].iter().zip(jacobian).map(|(&k, &v)| {
                let k = k as usize - n - 2 * m;
                (k / n, k % n, v)
            })
        };
        let forces = multipliers
            .iter()
            .map(|lambda| {
                let mut f = force.to_vec();
                for (r, i, v) in entries() {
                    f[i] -= v * lambda[r];
                }
                f
            })
            .collect();
        StateTerms {
            forces,
            g: g.to_vec(),
            g_dot: g_dot.to_vec(),
            g_y: if with_g_y {
                entries().collect()
            } else {
                Vec::new()
            },
        }
    }
}
