//! A `scheme = "wfem"` run and the wave finite elements' `[analysis]` sections validated into a
//! [`WaveJob`]; the WFEM numerics take only the validated bar and counts.

use crate::scenes::Bar;
use crate::spec::support::{self, Feature, ModelFamily};
use crate::spec::{AnalysisSpec, JobSpec, ModelSpec, Probes, SpecError};
use crate::wfem::job::WaveJob;
use crate::wfem::{WaveBar, WfemError};

/// The job of an `[analysis]` section.
pub(crate) fn analysis(analysis: &AnalysisSpec) -> Result<WaveJob, SpecError> {
    Ok(match analysis {
        AnalysisSpec::NonsmoothModes(m) => WaveJob::Modes(Box::new(super::analysis::modal_job(m)?)),
        AnalysisSpec::ForcedResponse(f) => {
            WaveJob::Forced(Box::new(super::analysis::forced_response_job(f)?))
        }
    })
}

/// Time integration (`scheme = "wfem"`) of the `bar` or `dep_bar` scene `model`.
pub(crate) fn integration(model: &ModelSpec, spec: &JobSpec) -> Result<WaveJob, SpecError> {
    if let ModelSpec::Bar(b) | ModelSpec::DepBar(b) = model
        && b.obstacle.is_some()
    {
        return Err(SpecError::new(
            "model.obstacle",
            "scheme \"wfem\" takes the bar's end contact only: run a distributed obstacle with moreau_jean or the nonsmooth α-family",
        ));
    }
    let bar = match model {
        ModelSpec::Bar(b) => b.resolve(Bar::default()),
        ModelSpec::DepBar(b) => b.resolve(Bar::doyen_ern_piperno(100)),
        other => {
            return Err(SpecError::new(
                "model.scene",
                format!(
                    "scheme \"wfem\" runs the scenes \"bar\" and \"dep_bar\", not \"{}\"",
                    other.scene()
                ),
            ));
        }
    };
    let bar = WaveBar::from_bar(&bar).map_err(|e| match e {
        WfemError::OutOfRange { field, .. } | WfemError::Unsupported { field, .. } => {
            SpecError::new(format!("model.{field}"), e.to_string())
        }
    })?;
    let time = spec.time_section()?;
    let dt = bar.dt();
    if !(time.h.is_finite() && (time.h - dt).abs() <= 1e-6 * dt) {
        return Err(SpecError::new(
            "time.h",
            format!(
                "wave finite elements step by Δt = Δx/c = {dt:e} exactly (cells = elements), got {}",
                time.h
            ),
        ));
    }
    let steps = time
        .steps(support::refusal(
            "wfem",
            ModelFamily::Linear,
            Feature::VariableStep,
            "",
        ))?
        .count();
    let output = spec.output.options(Probes::Unsupported(
        "wave finite elements record the contact end; probes are not supported",
    ))?;
    Ok(WaveJob::Integrate {
        bar,
        steps,
        every: output.every,
    })
}
