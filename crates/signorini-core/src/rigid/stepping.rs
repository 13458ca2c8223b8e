//! Rigid bodies under [`crate::stepping::run`]: the rigid-body columns, one step of
//! [`RigidMoreauJean`], the record, and the memory a checkpoint holds (the bodies' states, the
//! running statistics, the last impulses and the `contacts` table's rows so far; the contact
//! points and the solver's buffers are scratch, detected again from the restored poses).

use super::body::BodyState;
use super::detector::ContactDetector;
use super::moreau_jean::{
    ContactImpulse, RigidMoreauJean, RigidScratch, RigidStepError, StepReport,
};
use super::scene::RigidScene;
use crate::checkpoint::{CheckpointError, RunKind};
use crate::observer::Columns;
use crate::stepping::{StepTime, TimeStepping};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Per-body column suffixes, in order: position, quaternion (w, x, y, z), velocity, world
/// angular velocity.
pub const BODY_COLUMNS: [&str; 13] = [
    "x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz",
];

/// The columns after the bodies'.
pub const ENERGY_COLUMNS: [&str; 12] = [
    "kinetic",
    "potential",
    "energy",
    "work_ext",
    "work_contact",
    "work_friction",
    "energy_error",
    "contacts",
    "max_penetration",
    "work_ext_total",
    "work_contact_total",
    "work_friction_total",
];

/// The columns of the `contacts` table (`contacts.csv`, `output.contacts = true`): the step k
/// and t_k of the record, the two bodies (indices in `model.bodies`), the contact point
/// ½(p_0 + p_1), the unit normal n (from body 0 to body 1), the gap g at t_{k−1} (where the
/// point was found), the impulse P_k in the contact frame (n, t_1, t_2) of
/// [`super::tangent_basis`], and the same impulse in world coordinates,
/// P_n n + P_t1 t_1 + P_t2 t_2 (the impulse body 1 receives; its force is P / h).
pub const CONTACT_COLUMNS: [&str; 17] = [
    "step", "t", "body_0", "body_1", "x", "y", "z", "nx", "ny", "nz", "gap", "p_n", "p_t1", "p_t2",
    "px", "py", "pz",
];

/// The columns a scene with joints adds after [`ENERGY_COLUMNS`]: the work of the joints'
/// impulses on (v, Ω)_{k+θ} over the step (part of `energy_error`, which keeps its definition:
/// ΔE − work_ext − work_contact − work_friction), and max|φ| of the joints after the step's projection.
pub const JOINT_COLUMNS: [&str; 2] = ["work_joint", "position_residual"];

/// The columns of a run: `NAME_x … NAME_wz` per body, then [`ENERGY_COLUMNS`], then
/// [`JOINT_COLUMNS`] when the scene has joints.
pub fn rigid_columns(scene: &RigidScene) -> Columns {
    let bodies = scene
        .names
        .iter()
        .flat_map(|n| BODY_COLUMNS.iter().map(move |c| format!("{n}_{c}")));
    let joints: &[&str] = if scene.joints.is_empty() {
        &[]
    } else {
        &JOINT_COLUMNS
    };
    Columns::new(
        bodies
            .chain(ENERGY_COLUMNS.iter().chain(joints).map(|c| c.to_string()))
            .collect(),
    )
}

/// What a run measured over all its steps; the fields of `summary.json`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct RigidRunStats {
    /// Steps done.
    pub steps: u64,
    /// Final time.
    pub t_end: f64,
    /// Energy at t = 0.
    pub energy_initial: f64,
    /// Energy at the end.
    pub energy_final: f64,
    /// max_k |energy_error|.
    pub max_abs_energy_error: f64,
    /// Largest index set of a step.
    pub max_contacts: usize,
    /// Largest penetration seen at the start of a step.
    pub max_penetration: f64,
    /// Σ work_ext.
    pub work_ext_total: f64,
    /// Σ work_contact.
    pub work_contact_total: f64,
    /// Σ work_friction.
    pub work_friction_total: f64,
    /// max_k work_friction (≤ 0 when friction never did positive work in a step).
    pub work_friction_max: f64,
    /// Most Newton iterates in a step.
    pub newton_iterations_max: usize,
    /// FC3D iterations over the run.
    pub friction_iterations_total: u64,
    /// Largest FC3D error accepted.
    pub friction_error_max: f64,
    /// Steps that accepted a friction solve above the tolerance
    /// ([`super::RigidMoreauJeanParams::accept_error`]).
    #[serde(default)]
    pub friction_steps_accepted: u64,
}

/// What the next step reads: the step number, the bodies' states, the last step's impulses per
/// contact (the next friction problem's warm start) and the statistics; and what the run has
/// output so far beyond its records: the rows of the `contacts` table, so that a resumed run
/// writes the whole table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RigidMemory {
    /// Steps done.
    pub k: u64,
    /// State of every body.
    pub bodies: Vec<BodyState>,
    /// The last step's impulse of every contact of its index set
    /// ([`RigidScratch::previous_impulses`]), filled when a checkpoint is taken.
    pub impulses: Vec<ContactImpulse>,
    /// Running statistics.
    pub stats: RigidRunStats,
    /// The rows of the `contacts` table of the records so far ([`CONTACT_COLUMNS`]), when the
    /// run keeps it ([`RigidStepping::with_contact_table`]).
    pub contact_rows: Option<Vec<Vec<f64>>>,
}

/// Why a rigid run stopped with an error.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RigidRunError {
    /// A step failed.
    #[error(transparent)]
    Step(#[from] RigidStepError),
    /// A checkpoint was refused.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
}

/// The family [`crate::stepping::run`] drives.
pub struct RigidStepping<'a> {
    scene: &'a RigidScene,
    scheme: &'a RigidMoreauJean,
    detector: Box<dyn ContactDetector + 'a>,
    steps: u64,
    memory: RigidMemory,
    scratch: RigidScratch,
    /// The last step's report and energy error (the record of that step).
    last: StepReport,
    last_energy_error: f64,
}

impl<'a> RigidStepping<'a> {
    /// A run of `steps` steps from the scene's initial states.
    pub fn new(
        scene: &'a RigidScene,
        scheme: &'a RigidMoreauJean,
        detector: Box<dyn ContactDetector + 'a>,
        steps: u64,
    ) -> Self {
        let (kinetic, potential) = RigidMoreauJean::energies(scene, &scene.initial);
        Self {
            scene,
            scheme,
            detector,
            steps,
            memory: RigidMemory {
                k: 0,
                bodies: scene.initial.clone(),
                impulses: Vec::new(),
                stats: RigidRunStats {
                    energy_initial: kinetic + potential,
                    energy_final: kinetic + potential,
                    ..RigidRunStats::default()
                },
                contact_rows: None,
            },
            scratch: RigidScratch::default(),
            last: StepReport::default(),
            last_energy_error: 0.0,
        }
    }

    /// Also keeps, at every recorded step, the rows of the `contacts` table
    /// ([`CONTACT_COLUMNS`]) of that step's index set.
    pub fn with_contact_table(mut self) -> Self {
        self.memory.contact_rows = Some(Vec::new());
        self
    }

    /// The rows of the `contacts` table so far, when asked for: those of every record of the
    /// run, a resumed run's included (the checkpoint keeps the rows before it).
    pub fn contact_rows(&self) -> Option<&[Vec<f64>]> {
        self.memory.contact_rows.as_deref()
    }

    /// The bodies' current states.
    pub fn bodies(&self) -> &[BodyState] {
        &self.memory.bodies
    }

    /// The run's statistics so far.
    pub fn stats(&self) -> &RigidRunStats {
        &self.memory.stats
    }

    /// The last step's report.
    pub fn last_report(&self) -> &StepReport {
        &self.last
    }

    /// The last step's energy error.
    pub fn last_energy_error(&self) -> f64 {
        self.last_energy_error
    }
}

impl TimeStepping for RigidStepping<'_> {
    type Memory = RigidMemory;
    type Error = RigidRunError;
    const RUN: RunKind = RunKind::Rigid;

    fn columns(&self) -> Columns {
        rigid_columns(self.scene)
    }

    fn total_steps(&self) -> u64 {
        self.steps
    }

    fn is_done(&mut self, k: u64) -> bool {
        k >= self.steps
    }

    fn step(&mut self, k: u64) -> Result<(), RigidRunError> {
        let h = self.scheme.h();
        let t = (k - 1) as f64 * h;
        let (k0, v0) = RigidMoreauJean::energies(self.scene, &self.memory.bodies);
        let penetration = {
            self.scratch
                .detect(self.scene, &self.memory.bodies, self.detector.as_mut())
                .map_err(|source| RigidStepError::Detect { step: k, t, source })?;
            self.scratch.max_penetration()
        };
        let report = self.scheme.step(
            self.scene,
            &mut self.memory.bodies,
            self.detector.as_mut(),
            &mut self.scratch,
            k,
            t,
        )?;
        let (k1, v1) = RigidMoreauJean::energies(self.scene, &self.memory.bodies);
        let work_ext = 0.0;
        let error = (k1 + v1) - (k0 + v0) - work_ext - report.work_contact - report.work_friction;
        let s = &mut self.memory.stats;
        s.steps = k;
        s.t_end = k as f64 * h;
        s.energy_final = k1 + v1;
        s.max_abs_energy_error = s.max_abs_energy_error.max(error.abs());
        s.max_contacts = s.max_contacts.max(report.contacts);
        s.max_penetration = s.max_penetration.max(penetration);
        s.work_ext_total += work_ext;
        s.work_contact_total += report.work_contact;
        s.work_friction_total += report.work_friction;
        s.work_friction_max = if k == 1 {
            report.work_friction
        } else {
            s.work_friction_max.max(report.work_friction)
        };
        s.newton_iterations_max = s.newton_iterations_max.max(report.newton_iterations);
        s.friction_iterations_total += report.friction_iterations as u64;
        s.friction_error_max = s.friction_error_max.max(report.friction_error);
        s.friction_steps_accepted += u64::from(report.friction_accepted);
        self.memory.k = k;
        self.last = report;
        self.last_energy_error = error;
        Ok(())
    }

    fn now(&self) -> StepTime {
        StepTime {
            step: self.memory.k,
            t: self.memory.k as f64 * self.scheme.h(),
        }
    }

    fn record(&mut self, row: &mut Vec<f64>) -> Result<(), RigidRunError> {
        row.clear();
        for s in &self.memory.bodies {
            row.extend(s.position);
            row.extend(s.orientation);
            row.extend(s.velocity);
            row.extend(s.world_angular_velocity());
        }
        let (kinetic, potential) = RigidMoreauJean::energies(self.scene, &self.memory.bodies);
        let t = self.now().t;
        self.scratch
            .detect(self.scene, &self.memory.bodies, self.detector.as_mut())
            .map_err(|source| RigidStepError::Detect {
                step: self.memory.k,
                t,
                source,
            })?;
        let (report, error) = if self.memory.k == 0 {
            (StepReport::default(), 0.0)
        } else {
            (self.last, self.last_energy_error)
        };
        let StepTime { step, t } = self.now();
        if let (Some(rows), true) = (&mut self.memory.contact_rows, step > 0) {
            for (point, p) in self.scratch.active_impulses() {
                let [n, t1, t2] = [point.normal, point.tangents[0], point.tangents[1]];
                let world = |i: usize| p[0] * n[i] + p[1] * t1[i] + p[2] * t2[i];
                let mid = |i: usize| 0.5 * (point.points[0][i] + point.points[1][i]);
                rows.push(vec![
                    step as f64,
                    t,
                    point.bodies[0] as f64,
                    point.bodies[1] as f64,
                    mid(0),
                    mid(1),
                    mid(2),
                    n[0],
                    n[1],
                    n[2],
                    point.gap,
                    p[0],
                    p[1],
                    p[2],
                    world(0),
                    world(1),
                    world(2),
                ]);
            }
        }
        let s = &self.memory.stats;
        row.extend([
            kinetic,
            potential,
            kinetic + potential,
            0.0,
            report.work_contact,
            report.work_friction,
            error,
            report.contacts as f64,
            self.scratch.max_penetration(),
            s.work_ext_total,
            s.work_contact_total,
            s.work_friction_total,
        ]);
        if !self.scene.joints.is_empty() {
            row.extend([report.work_joint, report.position_residual]);
        }
        Ok(())
    }

    fn memory(&self) -> RigidMemory {
        RigidMemory {
            impulses: self.scratch.previous_impulses().to_vec(),
            ..self.memory.clone()
        }
    }

    fn restore(&mut self, memory: RigidMemory) -> Result<(), RigidRunError> {
        if memory.bodies.len() != self.scene.bodies.len() {
            return Err(CheckpointError::Mismatch(format!(
                "a checkpoint of {} bodies, this scene has {}",
                memory.bodies.len(),
                self.scene.bodies.len()
            ))
            .into());
        }
        self.scratch = RigidScratch::resumed(memory.impulses.clone());
        // The job decides whether the table is kept; the checkpoint holds its rows so far.
        let wanted = self.memory.contact_rows.is_some();
        self.memory = memory;
        if !wanted {
            self.memory.contact_rows = None;
        } else if self.memory.contact_rows.is_none() {
            self.memory.contact_rows = Some(Vec::new());
        }
        Ok(())
    }
}
