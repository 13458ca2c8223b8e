//! `scene = "rigid_bodies"` as a job: validation at the edge (the scene, the scheme, the contact
//! solver, the output) and the run through the one driver with a caller's contact detector.

use crate::checkpoint::Checkpoint;
use crate::contact::Activation;
use crate::friction::{Fc3dOptions, Fc3dSolverKind};
use crate::lcp::LcpSolverKind;
use crate::observer::Observer;
use crate::outcome::{RigidSummary, RunError, SummaryBody, Table};
use crate::rigid::{
    CONTACT_COLUMNS, DetectorFactory, RigidMoreauJean, RigidMoreauJeanParams, RigidScene,
    RigidStepping,
};
use crate::spec::support::{self, Feature, ModelFamily};
use crate::spec::{IntegratorSpec, JobSpec, Probes, RigidBodiesSpec, SpecError};
use crate::stepping::{StopReason, run};

/// A validated rigid-bodies job.
#[derive(Debug, Clone)]
pub(super) struct RigidJob {
    pub(super) scene: RigidScene,
    pub(super) scheme: RigidMoreauJean,
    pub(super) steps: u64,
    pub(super) every: u64,
    /// Keep the `contacts` table (`output.contacts`, or `output.vtk`, whose contact files are
    /// made from it).
    pub(super) contacts: bool,
}

/// Checks a `rigid_bodies` spec: the scene first, then the scheme's parameters
/// ([`rigid_params`]), the time and the output (no probes: the bodies' columns are recorded).
pub(super) fn rigid_job(r: &RigidBodiesSpec, spec: &JobSpec) -> Result<RigidJob, SpecError> {
    let scene = r.validate()?;
    let params = rigid_params(spec)?;
    let steps = spec.time_section()?.steps(support::refusal(
        spec.integrator.scheme(),
        ModelFamily::RigidBodies,
        Feature::VariableStep,
        "",
    ))?;
    let output = spec.output.options(Probes::Unsupported(
        "rigid bodies record every body's pose and twist: probes do not apply",
    ))?;
    Ok(RigidJob {
        scene,
        scheme: RigidMoreauJean::new(params, steps.h),
        steps: steps.count(),
        every: output.every,
        contacts: spec.output.contacts || spec.output.vtk,
    })
}

/// The Moreau–Jean parameters of a `rigid_bodies` spec, checked: `integrator.scheme` (only
/// `moreau_jean`), θ and the predicted gap's γ (`integrator.activation_gamma`, default ½; a
/// contact enters the index set at predicted gap ≤ `model.contact.margin`, or ≤ 0 with
/// `integrator.activation = "predicted_gap"`, Siconos' rule, the margin then only finding the
/// candidates), and the contact solver (`auto`: the FC3D chain of NSGS and
/// Newton–Alart–Curnier, at `contact_solver.tolerance` on Siconos' relative error, with
/// `accept_error`). A job and the rigid benchmark take their parameters from here.
pub fn rigid_params(spec: &JobSpec) -> Result<RigidMoreauJeanParams, SpecError> {
    let IntegratorSpec::MoreauJean(p) = &spec.integrator else {
        return Err(SpecError::new(
            "integrator.scheme",
            format!(
                "scene `rigid_bodies` runs with moreau_jean, got `{}`",
                spec.integrator.scheme()
            ),
        ));
    };
    if !p.theta.is_finite() || !(0.0..=1.0).contains(&p.theta) {
        return Err(SpecError::new(
            "integrator.theta",
            format!("must be in [0, 1], got {}", p.theta),
        ));
    }
    p.index_set.rule()?;
    if p.index_set.activation == Some(Activation::GapAndVelocity) {
        return Err(SpecError::new(
            "integrator.activation",
            "a rigid_bodies scene takes its contacts by their predicted gap: leave activation out (≤ model.contact.margin) or write \"predicted_gap\" (≤ 0, Siconos' rule)",
        ));
    }
    let lcp = spec.contact_solver.options()?;
    let accept_error = spec.contact_solver.accept_error()?;
    if lcp.kind != LcpSolverKind::Auto {
        return Err(SpecError::new(
            "contact_solver.kind",
            "rigid bodies solve the 3D friction problem: only `auto` (Gauss–Seidel, then Newton–Alart–Curnier) applies",
        ));
    }
    Ok(RigidMoreauJeanParams {
        theta: p.theta,
        gamma: p.index_set.activation_gamma.unwrap_or(0.5),
        activation_gap: (p.index_set.activation == Some(Activation::PredictedGap)).then_some(0.0),
        // A rigid step's own FC3D settings (first-stage sweeps, over-relaxation) come with the
        // scheme's defaults.
        fc3d: Fc3dOptions {
            kind: Fc3dSolverKind::Auto,
            tolerance: spec.contact_solver.tolerance,
            max_iterations: spec.contact_solver.max_iterations,
            ..RigidMoreauJeanParams::default().fc3d
        },
        accept_error,
        ..RigidMoreauJeanParams::default()
    })
}

impl RigidJob {
    /// Runs (or continues from `resume`) with a detector of `detectors`; the `contacts` table
    /// when the spec asks for it.
    pub(super) fn run_from(
        &self,
        observer: &mut dyn Observer,
        resume: Option<&Checkpoint>,
        detectors: Option<&dyn DetectorFactory>,
    ) -> Result<(SummaryBody, Vec<Table>), RunError> {
        let detectors = detectors.ok_or(RunError::NoDetector)?;
        let detector = detectors
            .detector(&self.scene.bodies)
            .map_err(RunError::Detector)?;
        let mut family = RigidStepping::new(&self.scene, &self.scheme, detector, self.steps);
        if self.contacts {
            family = family.with_contact_table();
        }
        if let StopReason::Observer { step } = run(&mut family, self.every, observer, resume)? {
            return Err(RunError::Stopped { step });
        }
        let tables = family
            .contact_rows()
            .map(|rows| Table {
                name: "contacts".into(),
                columns: CONTACT_COLUMNS.iter().map(|c| c.to_string()).collect(),
                rows: rows.to_vec(),
            })
            .into_iter()
            .collect();
        let body = SummaryBody::Rigid(RigidSummary {
            bodies: self.scene.bodies.len(),
            h: self.scheme.h(),
            stats: family.stats().clone(),
        });
        Ok((body, tables))
    }

    /// Columns per record (bodies' 13, the energy columns, step and t).
    pub(super) fn columns(&self) -> usize {
        crate::rigid::rigid_columns(&self.scene).len() + 2
    }
}
