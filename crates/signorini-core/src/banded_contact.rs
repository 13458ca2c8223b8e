//! The impulse of a step for many contacts, on the banded iteration matrix: which models take
//! it, and the glue between a scheme's index set and [`crate::lcp::active_set`].
//!
//! The dense path ([`crate::contact::Delassus`]) stores Ŵ⁻¹G (n × m) and W (m × m) and solves an
//! LCP of the index set's size: at n = m = 10⁴ the two operators alone are 1.6 GB. When every
//! contact's column of G is a single dof (no two on one dof) and there is no friction, the
//! banded path solves the same complementarity problem with memory O(n · bandwidth) and
//! O(n · bandwidth²) per active-set iteration, without forming either operator.

use crate::band::SymBand;
use crate::checkpoint::CheckpointError;
use crate::contact::{IndexSet, LcpStats, UnitContacts};
use crate::lcp::active_set::{BandedActiveSet, ImpulseMap, unit_columns};
use crate::lcp::{AUTO_LEMKE_MAX, LcpError, LcpOptions, LcpSolverKind};
use crate::model::LinearModel;

/// Fewest contacts for which `auto` takes the banded path (when the model allows it): above
/// [`AUTO_LEMKE_MAX`] contacts the dense `auto` leaves Lemke's exact pivoting for projected
/// Gauss–Seidel, an iterative method whose sweeps cost O(k²) on a k-contact index set and
/// whose convergence slows with the conditioning of W, on top of the O(n m + m²) memory of the
/// dense operators. Below it the dense path stays, bit for bit as before.
pub const AUTO_BANDED_MIN_CONTACTS: usize = AUTO_LEMKE_MAX + 1;

/// Why the banded path cannot take a model, or `None` when it can. `lumped_mass`: the scheme
/// needs a diagonal mass matrix (the α-family, whose impulse enters through M⁻¹).
pub fn banded_refusal(model: &LinearModel, lumped_mass: bool) -> Option<&'static str> {
    if model.has_friction() {
        return Some("the banded solver has no friction: use auto, lemke or pgs");
    }
    if lumped_mass && model.mass.kd() != 0 {
        return Some(
            "the α-family's banded impulse needs a lumped (diagonal) mass matrix: use moreau_jean, mass_matrix = \"lumped\", or a dense solver",
        );
    }
    if !unit_columns(model.dofs(), model.contacts.iter().map(|c| c.g.as_slice())) {
        return Some(
            "the banded solver needs each contact on one dof and no two contacts on the same dof",
        );
    }
    None
}

/// Whether a scheme solves its impulses on the banded path: asked for by `kind`, or `auto`
/// with at least [`AUTO_BANDED_MIN_CONTACTS`] contacts, and the model allows it.
pub fn uses_banded(model: &LinearModel, kind: LcpSolverKind, lumped_mass: bool) -> bool {
    let asked = match kind {
        LcpSolverKind::BandedActiveSet => true,
        LcpSolverKind::Auto => model.contacts.len() >= AUTO_BANDED_MIN_CONTACTS,
        _ => false,
    };
    asked && banded_refusal(model, lumped_mass).is_none()
}

/// A scheme's banded impulse solver with its per-step buffers (all O(n)).
#[derive(Debug, Clone)]
pub struct BandedImpulse {
    solver: BandedActiveSet,
    /// Column of G of each contact of the model: (dof, coefficient).
    unit: Vec<(usize, f64)>,
    /// The same contacts in arrays, when each column is one entry and no obstacle moves.
    units: Option<UnitContacts>,
    rows: Vec<(usize, f64)>,
    p: Vec<f64>,
    x: Vec<f64>,
}

impl BandedImpulse {
    /// The solver of `S x = (R D) G P` for the contacts of `model` (which [`banded_refusal`]
    /// accepted).
    pub fn new(model: &LinearModel, s: SymBand, map: ImpulseMap) -> Self {
        let unit = model
            .contacts
            .iter()
            .map(|c| {
                c.g.iter()
                    .copied()
                    .find(|&(_, coef)| coef != 0.0)
                    .unwrap_or((0, 0.0))
            })
            .collect();
        Self {
            solver: BandedActiveSet::new(s, map),
            unit,
            units: UnitContacts::of(&model.contacts),
            rows: Vec::new(),
            p: Vec::new(),
            x: vec![0.0; model.dofs()],
        }
    }

    /// Contact α's column of G, `(dof, coefficient)`.
    pub fn unit(&self, alpha: usize) -> (usize, f64) {
        self.unit[alpha]
    }

    /// The contacts in arrays ([`UnitContacts`]), when they allow it.
    pub fn units(&self) -> Option<&UnitContacts> {
        self.units.as_ref()
    }

    /// The active dofs the next solve starts from (what a checkpoint keeps of the solver:
    /// its factor is rebuilt bit for bit from them, [`BandedActiveSet::warm_start`]).
    pub fn warm_start(&self) -> Vec<bool> {
        self.solver.warm_start().to_vec()
    }

    /// Restores [`BandedImpulse::warm_start`] from a checkpoint; refused for another size.
    pub fn set_warm_start(&mut self, warm: &[bool]) -> Result<(), CheckpointError> {
        if self.solver.set_warm_start(warm) {
            Ok(())
        } else {
            Err(CheckpointError::Mismatch(format!(
                "a banded solver state of {} dofs, the model has {}",
                warm.len(),
                self.solver.n()
            )))
        }
    }

    /// x of the last solve (the velocity change the impulse makes, for Moreau–Jean).
    pub fn x(&self) -> &[f64] {
        &self.x
    }

    /// Solves the impulse problem on `index_set` (its `active` contacts and `rhs`), writes P
    /// (zero off the set) into `impulse`, x into [`BandedImpulse::x`], and records in the
    /// index set the round-off level of each active contact's local velocity for step `step`:
    /// `64 ε (|b_α| + |g_α x_α|)`, the banded counterpart of [`IndexSet::record_roundoff`]
    /// (`g_α x_α = (W P)_α` is the sum whose terms the dense level adds in absolute value).
    pub fn apply(
        &mut self,
        index_set: &mut IndexSet,
        options: &LcpOptions,
        impulse: &mut [f64],
        step: u64,
    ) -> Result<LcpStats, LcpError> {
        impulse.fill(0.0);
        self.rows.clear();
        self.rows
            .extend(index_set.active.iter().map(|&a| self.unit[a]));
        let k = self.rows.len();
        self.p.resize(k, 0.0);
        let stats = if k == 0 {
            self.x.fill(0.0);
            LcpStats::default()
        } else {
            let s = self.solver.solve(
                &self.rows,
                &index_set.rhs,
                options,
                &mut self.p,
                &mut self.x,
            )?;
            LcpStats {
                size: k,
                iterations: s.iterations,
                error: s.error,
            }
        };
        for (&a, &p) in index_set.active.iter().zip(&self.p) {
            impulse[a] = p;
        }
        let (rows, x) = (&self.rows, &self.x);
        index_set.record_levels_by(step, |r, b| {
            let (dof, coef) = rows[r];
            64.0 * f64::EPSILON * (b.abs() + (coef * x[dof]).abs())
        });
        Ok(stats)
    }
}

/// Restores the warm start of a scheme's banded solver (`banded`) from the one its checkpoint
/// saved (`warm`): both or neither.
pub(crate) fn restore_warm_start(
    banded: Option<&mut BandedImpulse>,
    warm: Option<Vec<bool>>,
) -> Result<(), CheckpointError> {
    match (banded, warm) {
        (Some(b), Some(w)) => b.set_warm_start(&w),
        (None, None) => Ok(()),
        (Some(_), None) => Err(CheckpointError::Mismatch(
            "a state without the banded solver's warm start, this job solves its contacts banded"
                .into(),
        )),
        (None, Some(_)) => Err(CheckpointError::Mismatch(
            "a state of the banded contact solver, this job solves its contacts dense".into(),
        )),
    }
}
