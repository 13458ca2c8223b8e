//! The `[analysis]` sections validated into the modal jobs ([`ModalJob`],
//! [`ForcedResponseJob`]); the analyses themselves take only these parameters.

use crate::modal::{ForcedResponseJob, ModalJob};
use crate::spec::{ForcedResponseSpec, ModalSpec, SpecError};
use crate::wfem::WaveBar;

fn positive(field: &str, x: f64) -> Result<f64, SpecError> {
    if x.is_finite() && x > 0.0 {
        Ok(x)
    } else {
        Err(SpecError::new(
            field,
            format!("must be a finite number > 0, got {x}"),
        ))
    }
}

/// Validates a `nonsmooth_modes` analysis; errors name the field.
pub(crate) fn modal_job(s: &ModalSpec) -> Result<ModalJob, SpecError> {
    if s.cells < 2 || s.cells > 1_000_000 {
        return Err(SpecError::new(
            "analysis.cells",
            format!("must be in [2, 10⁶], got {}", s.cells),
        ));
    }
    let gaps = match (&s.gap, &s.gaps) {
        (Some(_), Some(_)) => {
            return Err(SpecError::new(
                "analysis.gaps",
                "give gap or gaps, not both",
            ));
        }
        (Some(g), None) => vec![*g],
        (None, Some(g)) if g.is_empty() => {
            return Err(SpecError::new("analysis.gaps", "must not be empty"));
        }
        (None, Some(g)) => g.clone(),
        (None, None) => vec![1e-3, 0.0, -1e-3],
    };
    if let Some(g) = gaps.iter().find(|g| !g.is_finite()) {
        return Err(SpecError::new(
            "analysis.gap",
            format!("must be finite, got {g}"),
        ));
    }
    let max = s.max_period_steps.unwrap_or(4 * s.cells);
    let min = s.min_period_steps.unwrap_or(2).max(2);
    if max < min || max > 100 * s.cells {
        return Err(SpecError::new(
            "analysis.max_period_steps",
            format!(
                "must be in [{min}, {}] (min_period_steps … 100·cells), got {max}",
                100 * s.cells
            ),
        ));
    }
    if !(s.phases == 1 || s.phases == 2) {
        return Err(SpecError::new(
            "analysis.phases",
            format!("must be 1 or 2, got {}", s.phases),
        ));
    }
    let mut bar = WaveBar::unit(s.cells, 0.0);
    bar.length = positive("analysis.length", s.length)?;
    bar.young = positive("analysis.young", s.young)?;
    bar.density = positive("analysis.density", s.density)?;
    bar.area = positive("analysis.area", s.area)?;
    Ok(ModalJob {
        cells: s.cells,
        gaps,
        period_steps: (min, max),
        phases: s.phases,
        bar,
        stability_periods: s.stability_periods,
        all_candidates: s.all_candidates,
    })
}

/// Validates a `forced_response` analysis; errors name the field.
pub(crate) fn forced_response_job(s: &ForcedResponseSpec) -> Result<ForcedResponseJob, SpecError> {
    if s.cells < 2 || s.cells > 100_000 {
        return Err(SpecError::new(
            "analysis.cells",
            format!("must be in [2, 10⁵], got {}", s.cells),
        ));
    }
    let mut bar = WaveBar::unit(s.cells, s.gap);
    for (field, x, dst) in [
        ("analysis.length", s.length, &mut bar.length),
        ("analysis.young", s.young, &mut bar.young),
        ("analysis.density", s.density, &mut bar.density),
        ("analysis.area", s.area, &mut bar.area),
    ] {
        *dst = positive(field, x)?;
    }
    if !s.gap.is_finite() {
        return Err(SpecError::new(
            "analysis.gap",
            format!("must be finite, got {}", s.gap),
        ));
    }
    if !s.amplitude.is_finite() || s.amplitude == 0.0 {
        return Err(SpecError::new(
            "analysis.amplitude",
            format!("must be finite and ≠ 0, got {}", s.amplitude),
        ));
    }
    let omegas = s
        .omegas
        .clone()
        .unwrap_or_else(|| (0..29).map(|i| 0.8 + 0.05 * i as f64).collect());
    if omegas.is_empty() || omegas.iter().any(|w| !(w.is_finite() && *w > 0.0)) {
        return Err(SpecError::new(
            "analysis.omegas",
            "must be a non-empty list of finite numbers > 0",
        ));
    }
    if s.damping.is_empty() || s.damping.iter().any(|g| !(g.is_finite() && *g >= 0.0)) {
        return Err(SpecError::new(
            "analysis.damping",
            "must be a non-empty list of finite numbers ≥ 0",
        ));
    }
    if s.average_periods == 0 {
        return Err(SpecError::new("analysis.average_periods", "must be ≥ 1"));
    }
    Ok(ForcedResponseJob {
        cells: s.cells,
        bar,
        excitation: s.excitation,
        amplitude: s.amplitude,
        omegas,
        damping: s.damping.clone(),
        transient_periods: s.transient_periods,
        average_periods: s.average_periods,
        backbone: s.backbone,
    })
}

impl ModalJob {
    /// [`modal_job`]: the validated `nonsmooth_modes` analysis of `s`.
    pub fn from_spec(s: &ModalSpec) -> Result<Self, SpecError> {
        modal_job(s)
    }
}

impl ForcedResponseJob {
    /// [`forced_response_job`]: the validated `forced_response` analysis of `s`.
    pub fn from_spec(s: &ForcedResponseSpec) -> Result<Self, SpecError> {
        forced_response_job(s)
    }
}
