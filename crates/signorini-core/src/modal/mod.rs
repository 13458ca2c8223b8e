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
    BackbonePanel, Chart, EndHistory, GapScan, MarkedPoint, ModePoint, ModesSummary, RunError,
    RunOutput, RunSummary, StabilityRun, SummaryBody, SummaryHeader, Table,
};
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

impl ModalJob {
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
    /// What the table keeps of the admissible orbit (`None`: not admissible).
    pub admissible: Option<OrbitClass>,
    /// The admissible orbit's shape (ring state, u(L, t)), when the scan keeps shapes: [`scan`]
    /// and [`examine`] keep them, the job's scan ([`scan_with`] without shapes) does not, and
    /// recomputes the shown orbits with [`examine`].
    pub orbit: Option<Orbit>,
    /// k of the main branch (2k − 1) m + 2k p = 4N the admissible one-contact-phase orbit lies
    /// on ([`main_branch`]), if any.
    pub branch: Option<usize>,
    /// Period T = (m + p [+ k + p]) Δt.
    pub period: f64,
    /// Total contact duration per period.
    pub contact_duration: f64,
    /// ω/ω₁ = 4L/(cT).
    pub omega_over_omega1: f64,
    /// Energy / E_lin (11) (for g0 = 0, with 10⁻³ L in place of |g0|).
    pub energy_normalized: f64,
}

/// What a backbone row says of an admissible orbit; kept for every point, while the orbit's
/// shape (O(N + T) values) is kept only for the points a job shows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitClass {
    /// Cell energy (conserved).
    pub energy: f64,
    /// Contact steps with a zero force (52) to round-off ([`Orbit::zero_force_steps`]).
    pub zero_force_steps: usize,
    /// Grazing instants inside the free phases ([`Orbit::grazing_steps`]).
    pub grazing_steps: usize,
}

impl OrbitClass {
    /// The class of an admissible orbit.
    pub fn of(orbit: &Orbit) -> Self {
        OrbitClass {
            energy: orbit.energy,
            zero_force_steps: orbit.zero_force_steps,
            grazing_steps: orbit.grazing_steps,
        }
    }
}

/// The main branch k ≥ 1 a one-contact-phase candidate (m, p) lies on: (2k − 1) m + 2k p = 4N,
/// i.e. 2k (m + p) = 4N + m. Along that line T = m + p runs over (4N/2k, 4N/(2k − 1)), so
/// ω ∈ (ω_k, Ω_k) (10); at g0 = 0 it meets the asymptote ω₁(ω_k/ω₁ + 1)²/(ω_k/ω₁ + 2) (§6.1) at
/// T = 4N(2k + 1)/(2k)². The relation is that of the piecewise-linear main-branch orbits (one
/// free phase, one contact phase, §6.1, Fig. 8).
pub fn main_branch(cells: usize, m: usize, p: usize) -> Option<usize> {
    let t2 = 2 * (m + p);
    let rhs = 4 * cells + m;
    rhs.is_multiple_of(t2)
        .then_some(rhs / t2)
        .filter(|&k| k >= 1)
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
    let admissible = orbit.as_ref().map(OrbitClass::of);
    BackbonePoint {
        gap: bar.gap,
        m,
        p,
        k,
        kernel_dim: h,
        admissible,
        orbit,
        branch: if k == 0 && admissible.is_some() {
            main_branch(bar.cells, m, p)
        } else {
            None
        },
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
/// unless `all_candidates`), sorted by (period, m, p), each with its orbit's shape.
pub fn scan(
    bar: &WaveBar,
    periods: (usize, usize),
    phases: usize,
    all_candidates: bool,
    threads: usize,
    on_period: &(dyn Fn() -> ControlFlow<()> + Sync),
) -> Result<Vec<BackbonePoint>, u64> {
    scan_with(
        bar,
        periods,
        phases,
        all_candidates,
        true,
        threads,
        on_period,
    )
}

/// [`scan`], keeping each admissible orbit's shape (its ring of 2N values and u(L, t) over T + 1
/// steps) only when `keep_shapes`: without, a point holds its [`OrbitClass`] alone, so a scan
/// of N = 1000 to T = 4000 holds kilobytes per thousand orbits instead of 48 MB.
pub fn scan_with(
    bar: &WaveBar,
    periods: (usize, usize),
    phases: usize,
    all_candidates: bool,
    keep_shapes: bool,
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
                        let mut keep = |mut pt: BackbonePoint| {
                            if all_candidates || pt.admissible.is_some() {
                                if !keep_shapes {
                                    pt.orbit = None;
                                }
                                out.push(pt);
                            }
                        };
                        if phases == 1 {
                            for p in 1..t {
                                if let Some(pt) =
                                    fast::examine_one_contact(bar, t - p, p, &mut scratch)
                                {
                                    keep(pt);
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
                                    if let Some(pt) = examine(bar, m, p, k) {
                                        keep(pt);
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

/// Columns of `backbone.csv`. The last three classify an admissible orbit: `branch` (k ≥ 1 of
/// the main branch it lies on, [`main_branch`]; 0 off the main branches and for two contact
/// phases — not NaN, so that a default table stays finite, as the stored results need),
/// `zero_force_steps` and `grazing_steps` ([`OrbitClass`]; NaN when not admissible, like
/// `energy`).
pub const BACKBONE_COLUMNS: [&str; 15] = [
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
    "branch",
    "zero_force_steps",
    "grazing_steps",
];

/// One row of `backbone.csv` ([`BACKBONE_COLUMNS`]).
pub fn backbone_row(pt: &BackbonePoint) -> Vec<f64> {
    let class = pt.admissible.as_ref();
    vec![
        pt.gap,
        pt.m as f64,
        pt.p as f64,
        pt.k as f64,
        pt.kernel_dim as f64,
        if class.is_some() { 1.0 } else { 0.0 },
        pt.omega_over_omega1,
        class.map_or(f64::NAN, |c| c.energy),
        pt.energy_normalized,
        pt.period,
        pt.contact_duration,
        if pt.k > 0 { 2.0 } else { 1.0 },
        pt.branch.map_or(0.0, |k| k as f64),
        class.map_or(f64::NAN, |c| c.zero_force_steps as f64),
        class.map_or(f64::NAN, |c| c.grazing_steps as f64),
    ]
}

/// The point of the first main branch (m + 2p = 4N, [`main_branch`]) with the median energy
/// among its admissible points (the "point a" of Fig. 5 for g0 > 0, "c" for g0 < 0; the grazing
/// (2N, N) for g0 = 0), if any. It is the orbit a job shows (Figs. 8, 9) and runs for stability
/// (§6.5, Fig. 21).
pub fn first_mode_orbit(points: &[BackbonePoint]) -> Option<&BackbonePoint> {
    let mut first: Vec<&BackbonePoint> = points
        .iter()
        .filter(|p| p.admissible.is_some() && p.branch == Some(1))
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
                scan_with(
                    bar,
                    job.period_steps,
                    job.phases,
                    job.all_candidates,
                    false,
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
        let admissible = points.iter().filter(|p| p.admissible.is_some()).count();
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
    // The shown orbit of each gap lies on the first main branch; its shape is computed again
    // here (the scan kept none).
    let mut stability = None;
    let mut ends = Vec::new();
    let mut marked = Vec::new();
    for (bar, points) in &all_points {
        let Some(pt) = first_mode_orbit(points) else {
            continue;
        };
        let Some(orbit) = examine(bar, pt.m, pt.p, pt.k).and_then(|shown| shown.orbit) else {
            continue;
        };
        let name = format!("orbit_gap_{}", gap_label(bar.gap));
        charts.push(Chart::SpaceTime(orbit::space_time(&name, bar, &orbit)));
        ends.push(end_history(bar, pt, &orbit));
        let letter = point_letter(bar.gap);
        let mut label = format!(
            "{letter}: g₀ = {:e}, (m, p) = ({}, {})",
            bar.gap, pt.m, pt.p
        );
        if job.stability_periods > 0 && bar.gap > 0.0 && stability.is_none() {
            let st = orbit::stability(bar, &orbit, job.stability_periods, 1e-6);
            label = format!(
                "{label}; 1e-6 perturbation → distance {:.0e} after {} T",
                st.relative_deviation, st.periods
            );
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
        marked.push(MarkedPoint {
            point: mode_point(pt),
            label,
        });
    }
    charts.extend(mode_panels(all_points.iter().flat_map(|(_, p)| p), &marked));
    if !ends.is_empty() {
        charts.push(Chart::ContactEnd(ends));
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

/// Modes drawn one panel each (Figs. 5 and 6 draw K = 1, 2), when the scan reached them.
pub const PANEL_MODES: usize = 4;

/// One [`BackbonePanel`] per mode K ≤ [`PANEL_MODES`] whose main branch has admissible points:
/// the admissible points with ω/ω₁ ∈ [2K − 1.1, 2K + 0.1] (ω_K = (2K − 1)ω₁, Ω_K = 2Kω₁, (10)).
fn mode_panels<'a>(
    points: impl Iterator<Item = &'a BackbonePoint> + Clone,
    marked: &[MarkedPoint],
) -> Vec<Chart> {
    (1..=PANEL_MODES)
        .filter(|&k| points.clone().any(|p| p.branch == Some(k)))
        .map(|k| {
            let (lo, hi) = ((2 * k) as f64 - 1.1, (2 * k) as f64 + 0.1);
            let inside = |w: f64| w >= lo && w <= hi;
            Chart::BackbonePanel(BackbonePanel {
                name: format!("backbone_mode_{k}"),
                mode: k,
                points: mode_points(points.clone().filter(|p| inside(p.omega_over_omega1))),
                marked: marked
                    .iter()
                    .filter(|m| inside(m.point.omega_over_omega1))
                    .cloned()
                    .collect(),
            })
        })
        .collect()
}

/// The letters of Fig. 5 and 8: "a" unstressed (g0 > 0), "b" grazing, "c" prestressed.
fn point_letter(g: f64) -> &'static str {
    if g > 0.0 {
        "a"
    } else if g < 0.0 {
        "c"
    } else {
        "b"
    }
}

/// u(L, t) and the contact force (52) over one period of an admissible orbit (Fig. 8).
fn end_history(bar: &WaveBar, pt: &BackbonePoint, orbit: &Orbit) -> EndHistory {
    let traj = orbit::trajectory(bar, &orbit.phases, &orbit.ring);
    let mut force = Vec::with_capacity(traj.a_end.len());
    for &(end, steps) in &orbit.phases {
        let n = force.len();
        force.extend(traj.a_end[n..n + steps].iter().map(|&a| match end {
            EndCondition::Contact => bar.area * a,
            EndCondition::Free => 0.0,
        }));
    }
    EndHistory {
        gap: bar.gap,
        m: pt.m,
        p: pt.p,
        omega_over_omega1: pt.omega_over_omega1,
        energy_normalized: pt.energy_normalized,
        period: pt.period,
        u: traj.u,
        force,
    }
}

fn mode_point(p: &BackbonePoint) -> ModePoint {
    ModePoint {
        gap: p.gap,
        omega_over_omega1: p.omega_over_omega1,
        energy_normalized: p.energy_normalized,
        branch: p.branch,
    }
}

/// The admissible points of a scan, for the backbone figures.
pub(crate) fn mode_points<'a>(points: impl Iterator<Item = &'a BackbonePoint>) -> Vec<ModePoint> {
    points
        .filter(|p| p.admissible.is_some())
        .map(mode_point)
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
