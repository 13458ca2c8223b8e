//! What a checkpoint of a user-model run holds, for both time-steppings of the module
//! ([`super::moreau_jean`], [`super::generalized_alpha`]).

use super::LagrangianSystem;
use super::moreau_jean::NonlinearState;
use crate::checkpoint::CheckpointError;
use serde::{Deserialize, Serialize};

/// What a run of a user model carries from one step to the next, and all a checkpoint holds of
/// it: the state, the running statistics (`Stats`, the run's summary), the previous impulses
/// (the impact count), the Newton iterations summed (their mean) and the scheme's memory of the
/// end of the last step (`Memory`). The step's report is rebuilt by the next step and the
/// scheme's scratch (M, the iteration matrix, the Delassus operator) is never stored.
///
/// The fields are named as in state version 2 of both runs, whose checkpoints therefore keep
/// loading; a nonlinear Moreau–Jean checkpoint of that version also holds `work_friction_total`,
/// the sum `stats.work_friction_total` already holds, which the decoder skips.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct UserModelRun<Stats, Memory> {
    pub(crate) state: NonlinearState,
    pub(crate) stats: Stats,
    pub(crate) previous_impulse: Vec<f64>,
    pub(crate) newton_total: u64,
    pub(crate) memory: Memory,
}

impl<Stats, Memory> UserModelRun<Stats, Memory> {
    /// Refuses the run of `what` ("a nonlinear", "an ns_generalized_alpha") when its state or
    /// previous impulses do not have the sizes of `system`.
    pub(crate) fn check_fits<S: LagrangianSystem + ?Sized>(
        &self,
        what: &str,
        system: &S,
    ) -> Result<(), CheckpointError> {
        let (n, m) = (system.dofs(), system.contacts());
        if self.state.q.len() != n || self.previous_impulse.len() != m {
            return Err(CheckpointError::Mismatch(format!(
                "{what} state of {} coordinates and {} contacts, the system has {n} and {m}",
                self.state.q.len(),
                self.previous_impulse.len()
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nonlinear::moreau_jean::NonlinearRunStats;

    /// A nonlinear Moreau–Jean run's memory as state version 2 wrote it, with the friction sum
    /// kept twice.
    #[derive(Serialize)]
    struct WithSum {
        state: NonlinearState,
        stats: NonlinearRunStats,
        previous_impulse: Vec<f64>,
        newton_total: u64,
        work_friction_total: f64,
        memory: Vec<f64>,
    }

    #[test]
    fn a_memory_holding_the_friction_sum_twice_still_reads() {
        let stats = NonlinearRunStats {
            steps: 7,
            work_friction_total: Some(-0.25),
            ..Default::default()
        };
        let old = WithSum {
            state: NonlinearState {
                step: 7,
                t: 0.07,
                q: vec![1.0, 2.0],
                v: vec![-3.0, 0.5],
            },
            stats: stats.clone(),
            previous_impulse: vec![0.0, 4.0],
            newton_total: 15,
            work_friction_total: -0.25,
            memory: vec![9.0],
        };
        let bytes = rmp_serde::to_vec_named(&old).unwrap();
        let read: UserModelRun<NonlinearRunStats, Vec<f64>> =
            rmp_serde::from_slice(&bytes).unwrap();
        assert_eq!(read.state, old.state);
        assert_eq!(read.stats, stats);
        assert_eq!(read.previous_impulse, old.previous_impulse);
        assert_eq!(read.newton_total, 15);
        assert_eq!(read.memory, old.memory);
    }
}
