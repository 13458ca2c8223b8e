//! Nonsmooth modal analysis of the elastic bar (Yoong, Thorin & Legrand 2018, §§4–6).
//!
//! A periodic orbit with one free phase of m steps and one contact phase of p steps is a kernel
//! vector of `S_T = A_c^p A_f^m − I` (9) satisfying COND1–COND3; with two contact phases, of
//! `A_c^p A_f^k A_c^p A_f^m − I` (18). Families of admissible orbits over (m, p) are nonsmooth
//! modes, drawn as frequency–energy backbone curves: frequency ω = 2π/T normalised by
//! ω₁ = πc/(2L) (10), energy normalised by the grazing first linear mode (11),
//! `E_lin = E S π² g0² / (16 L)`.

pub mod fast;
pub mod forced;
pub mod kernel;
pub mod orbit;

use crate::observer::{Observer, Progress};
use crate::outcome::{
    Chart, GapScan, ModePoint, ModesSummary, RunError, RunOutput, RunSummary, StabilityRun,
    SummaryBody, SummaryHeader, Table,
};
use crate::spec::{ModalSpec, SpecError};
use crate::wfem::{EndCondition, WaveBar};
pub use forced::ForcedResponseJob;
use kernel::{SignedPermutation, kernel_dim_closed_form};
use orbit::{Orbit, admissible_orbit};
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// A validated modal analysis.
#[derive(Debug, Clone, PartialEq)]
pub struct ModalJob {
    /// N.
    pub cells: usize,
    /// Gaps scanned.
    pub gaps: Vec<f64>,
    /// Period range in steps.
    pub period_steps: (usize, usize),
    /// 1 or 2 contact phases.
    pub phases: usize,
    /// Bar with `gap = 0` (the scan sets the gap).
    pub bar: WaveBar,
    /// Stability periods.
    pub stability_periods: usize,
    /// List potential points too.
    pub all_candidates: bool,
}

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

impl ModalJob {
    /// Validates the spec.
    pub fn from_spec(s: &ModalSpec) -> Result<Self, SpecError> {
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

    /// Tasks (period lengths × gaps), for progress.
    pub fn tasks(&self) -> u64 {
        ((self.period_steps.1 - self.period_steps.0 + 1) * self.gaps.len()) as u64
    }
}

/// One point of a backbone scan.
#[derive(Debug, Clone, PartialEq)]
pub struct BackbonePoint {
    /// Gap g0.
    pub gap: f64,
    /// Free-phase steps (first free phase).
    pub m: usize,
    /// Contact-phase steps (each contact phase).
    pub p: usize,
    /// Second free-phase steps (two-phase orbits (18); 0 otherwise).
    pub k: usize,
    /// dim ker S_T.
    pub kernel_dim: usize,
    /// The orbit, when admissible.
    pub orbit: Option<Orbit>,
    /// Period T = (m + p [+ k + p]) Δt.
    pub period: f64,
    /// Total contact duration per period.
    pub contact_duration: f64,
    /// ω/ω₁ = 4L/(cT).
    pub omega_over_omega1: f64,
    /// Energy / E_lin (11) (for g0 = 0, with 10⁻³ L in place of |g0|).
    pub energy_normalized: f64,
}

/// Energy of the grazing first linear mode (11): `u = A sin(πx/2L) cos ω₁t` with A = |g0|
/// (10⁻³ L when g0 = 0) has `E S π² A² / (16 L)`.
pub fn linear_grazing_energy(bar: &WaveBar) -> f64 {
    let amp = if bar.gap == 0.0 {
        1e-3 * bar.length
    } else {
        bar.gap.abs()
    };
    bar.young * bar.area * std::f64::consts::PI.powi(2) * amp * amp / (16.0 * bar.length)
}

/// Phases of a candidate: one contact phase `[(Free, m), (Contact, p)]` (8), or two
/// `[(Free, m), (Contact, p), (Free, k), (Contact, p)]` (18).
pub fn candidate_phases(m: usize, p: usize, k: usize) -> Vec<(EndCondition, usize)> {
    let mut ph = vec![(EndCondition::Free, m), (EndCondition::Contact, p)];
    if k > 0 {
        ph.extend([(EndCondition::Free, k), (EndCondition::Contact, p)]);
    }
    ph
}

/// Examines one candidate (m, p[, k]) of a bar with gap g0: kernel from the cycle structure,
/// admissibility when it is not trivial. `None` when the kernel is trivial. This is the
/// straightforward path (signed permutation, kernel basis and one trajectory per basis vector,
/// all allocated); the scans use [`fast::examine_one_contact`] for one contact phase.
pub fn examine(bar: &WaveBar, m: usize, p: usize, k: usize) -> Option<BackbonePoint> {
    let n = bar.cells;
    let phases = candidate_phases(m, p, k);
    let perm = SignedPermutation::product(n, bar.left, &phases);
    let h = if k == 0 && bar.left == crate::scenes::LeftEnd::Fixed {
        kernel_dim_closed_form(n, m, p)
    } else {
        perm.kernel_dim()
    };
    if h == 0 {
        return None;
    }
    let basis = perm.kernel_basis();
    let orbit = admissible_orbit(bar, &phases, &basis);
    Some(point(bar, m, p, k, h, orbit))
}

/// The backbone point of candidate (m, p, k) with kernel dimension `h` and its orbit, if any.
pub(crate) fn point(
    bar: &WaveBar,
    m: usize,
    p: usize,
    k: usize,
    h: usize,
    orbit: Option<Orbit>,
) -> BackbonePoint {
    let dt = bar.dt();
    let steps = m + p + k + if k > 0 { p } else { 0 };
    let period = steps as f64 * dt;
    let contact = (if k > 0 { 2 * p } else { p }) as f64 * dt;
    let omega1 = std::f64::consts::PI * bar.wave_speed() / (2.0 * bar.length);
    let e_norm = orbit
        .as_ref()
        .map_or(f64::NAN, |o| o.energy / linear_grazing_energy(bar));
    BackbonePoint {
        gap: bar.gap,
        m,
        p,
        k,
        kernel_dim: h,
        orbit,
        period,
        contact_duration: contact,
        omega_over_omega1: 2.0 * std::f64::consts::PI / period / omega1,
        energy_normalized: e_norm,
    }
}

/// Scans every period T ∈ [t_min, t_max] (in steps) and every split into phases: (m, p) with
/// m + p = T for one contact phase, (m, p, k) with m + 2p + k = T, m ≤ k for two. Runs the
/// periods on `threads` threads; `on_period` is called after each period (progress) and stops
/// the scan when it returns `Break`. Returns the points with a nontrivial kernel (admissible only
/// unless `all_candidates`), sorted by (period, m, p).
pub fn scan(
    bar: &WaveBar,
    periods: (usize, usize),
    phases: usize,
    all_candidates: bool,
    threads: usize,
    on_period: &(dyn Fn() -> ControlFlow<()> + Sync),
) -> Result<Vec<BackbonePoint>, u64> {
    let (t_min, t_max) = periods;
    let next = AtomicU64::new(t_min as u64);
    let stop = AtomicBool::new(false);
    let done = AtomicU64::new(0);
    let mut all: Vec<BackbonePoint> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads.max(1))
            .map(|_| {
                s.spawn(|| {
                    let mut out = Vec::new();
                    let mut scratch = fast::Scratch::default();
                    loop {
                        if stop.load(Ordering::Relaxed) {
                            break;
                        }
                        let t = next.fetch_add(1, Ordering::Relaxed) as usize;
                        if t > t_max {
                            break;
                        }
                        if phases == 1 {
                            for p in 1..t {
                                if let Some(pt) =
                                    fast::examine_one_contact(bar, t - p, p, &mut scratch)
                                    && (all_candidates || pt.orbit.is_some())
                                {
                                    out.push(pt);
                                }
                            }
                        } else {
                            for p in 1..t / 2 {
                                let rest = t - 2 * p;
                                for m in 1..=rest / 2 {
                                    let k = rest - m;
                                    if k == 0 {
                                        continue;
                                    }
                                    if let Some(pt) = examine(bar, m, p, k)
                                        && (all_candidates || pt.orbit.is_some())
                                    {
                                        out.push(pt);
                                    }
                                }
                            }
                        }
                        done.fetch_add(1, Ordering::Relaxed);
                        if on_period().is_break() {
                            stop.store(true, Ordering::Relaxed);
                        }
                    }
                    out
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| {
                h.join()
                    .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
            })
            .collect()
    });
    if stop.load(Ordering::Relaxed) {
        return Err(done.load(Ordering::Relaxed));
    }
    all.sort_by_key(|pt| {
        (
            pt.m + pt.p + pt.k + if pt.k > 0 { pt.p } else { 0 },
            pt.m,
            pt.p,
            pt.k,
        )
    });
    Ok(all)
}

/// Main-branch asymptote of the k-th nonsmooth mode (§6.1): `ω₁ (ω_k/ω₁ + 1)² / (ω_k/ω₁ + 2)`,
/// returned as a multiple of ω₁ (ω_k/ω₁ = 2k − 1).
pub fn main_asymptote(k: usize) -> f64 {
    let r = (2 * k - 1) as f64;
    (r + 1.0) * (r + 1.0) / (r + 2.0)
}

/// Columns of `backbone.csv`.
pub const BACKBONE_COLUMNS: [&str; 12] = [
    "gap",
    "m",
    "p",
    "k",
    "kernel_dim",
    "admissible",
    "omega_over_omega1",
    "energy",
    "energy_normalized",
    "period",
    "contact_duration",
    "phases",
];

/// One row of `backbone.csv` ([`BACKBONE_COLUMNS`]).
pub fn backbone_row(pt: &BackbonePoint) -> Vec<f64> {
    vec![
        pt.gap,
        pt.m as f64,
        pt.p as f64,
        pt.k as f64,
        pt.kernel_dim as f64,
        if pt.orbit.is_some() { 1.0 } else { 0.0 },
        pt.omega_over_omega1,
        pt.orbit.as_ref().map_or(f64::NAN, |o| o.energy),
        pt.energy_normalized,
        pt.period,
        pt.contact_duration,
        if pt.k > 0 { 2.0 } else { 1.0 },
    ]
}

/// The orbit of the first main mode with the median energy among the admissible points with
/// ω/ω₁ ∈ (1, 2) and one contact phase (the "point a" of Fig. 5), if any.
pub fn first_mode_orbit(points: &[BackbonePoint]) -> Option<&BackbonePoint> {
    let mut first: Vec<&BackbonePoint> = points
        .iter()
        .filter(|p| {
            p.orbit.is_some() && p.k == 0 && p.omega_over_omega1 > 1.0 && p.omega_over_omega1 < 2.0
        })
        .collect();
    first.sort_by(|a, b| a.energy_normalized.total_cmp(&b.energy_normalized));
    first.get(first.len() / 2).copied()
}

/// Runs a modal analysis job: one scan per gap on `threads` threads (the caller's grant), the
/// `backbone` table, its charts, stability. The points do not depend on `threads`.
pub fn run_modes(
    job: &ModalJob,
    header: SummaryHeader,
    threads: usize,
    observer: &mut dyn Observer,
) -> Result<RunOutput, RunError> {
    let total = job.tasks();
    let mut rows = Vec::new();
    let mut all_points = Vec::new();
    let mut per_gap = Vec::new();
    let mut done_before = 0u64;
    for &gap in &job.gaps {
        let mut bar = job.bar.clone();
        bar.gap = gap;
        // Progress per task (one period length of one gap): the scan threads send a message
        // after each period; the calling thread, which owns the (non-Sync) observer, reports it
        // and raises `stop` on Break, which the scan threads see after their current period.
        let stop = AtomicBool::new(false);
        let (tx, rx) = std::sync::mpsc::channel::<()>();
        let mut cancelled = false;
        let scanned = std::thread::scope(|s| {
            let (stop, bar) = (&stop, &bar);
            let worker = s.spawn(move || {
                let on_period = move || {
                    let _ = tx.send(());
                    if stop.load(Ordering::Relaxed) {
                        ControlFlow::Break(())
                    } else {
                        ControlFlow::Continue(())
                    }
                };
                scan(
                    bar,
                    job.period_steps,
                    job.phases,
                    job.all_candidates,
                    threads,
                    &on_period,
                )
            });
            for () in rx.iter() {
                done_before += 1;
                if !cancelled
                    && observer
                        .progress(Progress {
                            done: done_before,
                            total,
                            t: 0.0,
                        })
                        .is_break()
                {
                    cancelled = true;
                    stop.store(true, Ordering::Relaxed);
                }
            }
            worker.join()
        });
        let points = match scanned {
            Err(panic) => std::panic::resume_unwind(panic),
            Ok(Ok(points)) if !cancelled => points,
            Ok(_) => return Err(RunError::Stopped { step: done_before }),
        };
        let admissible = points.iter().filter(|p| p.orbit.is_some()).count();
        per_gap.push(GapScan {
            gap,
            admissible,
            candidates: points.len(),
        });
        rows.extend(points.iter().map(backbone_row));
        all_points.push((bar, points));
    }
    let mut charts = vec![Chart::Backbone(mode_points(
        all_points.iter().flat_map(|(_, p)| p),
    ))];
    let mut stability = None;
    for (bar, points) in &all_points {
        if let Some(pt) = first_mode_orbit(points)
            && let Some(orbit) = &pt.orbit
        {
            let name = format!("orbit_gap_{}", gap_label(bar.gap));
            charts.push(Chart::SpaceTime(orbit::space_time(&name, bar, orbit)));
            if job.stability_periods > 0 && bar.gap > 0.0 && stability.is_none() {
                let st = orbit::stability(bar, orbit, job.stability_periods, 1e-6);
                stability = Some(StabilityRun {
                    gap: bar.gap,
                    m: pt.m,
                    p: pt.p,
                    periods: st.periods,
                    perturbation: st.perturbation,
                    relative_deviation: st.relative_deviation,
                    orbit_drift: st.orbit_drift,
                });
            }
        }
    }
    let body = SummaryBody::NonsmoothModes(ModesSummary {
        cells: job.cells,
        phases: job.phases,
        period_steps: [job.period_steps.0, job.period_steps.1],
        gaps: per_gap,
        points: rows.len(),
        stability,
    });
    Ok(RunOutput {
        summary: RunSummary::new(header, body),
        tables: vec![Table {
            name: "backbone".into(),
            columns: BACKBONE_COLUMNS.iter().map(|s| s.to_string()).collect(),
            rows,
        }],
        charts,
    })
}

/// The admissible points of a scan, for the backbone figures.
pub(crate) fn mode_points<'a>(points: impl Iterator<Item = &'a BackbonePoint>) -> Vec<ModePoint> {
    points
        .filter(|p| p.orbit.is_some())
        .map(|p| ModePoint {
            gap: p.gap,
            omega_over_omega1: p.omega_over_omega1,
            energy_normalized: p.energy_normalized,
        })
        .collect()
}

fn gap_label(g: f64) -> &'static str {
    if g > 0.0 {
        "positive"
    } else if g < 0.0 {
        "negative"
    } else {
        "zero"
    }
}
