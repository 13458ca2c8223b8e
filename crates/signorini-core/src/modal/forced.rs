//! Forced response of the lightly damped bar (§7): a harmonically moving wall
//! `w(t) = w0 sin ωt` or a distributed force `f0 sin ωt`, swept over ω for several damping
//! values. Each (damping, ω) is an independent WFEM run of Algorithm 2 (with the source step of
//! [`crate::wfem`]): `transient_periods` forcing periods to reach the steady state, then the cell
//! energy averaged over `average_periods` periods. Tasks run in parallel on the threads the
//! caller grants.

use super::{mode_points, scan_with};
use crate::observer::{Observer, Progress};
use crate::outcome::{
    Chart, ForcedChart, ForcedPoint, ForcedSummary, RunError, RunOutput, RunSummary, SummaryBody,
    SummaryHeader, Table,
};
use crate::scenes::HarmonicSpec;
pub use crate::spec::Excitation;
use crate::wfem::{WaveBar, step};
use std::ops::ControlFlow;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// A validated forced-response sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct ForcedResponseJob {
    /// N.
    pub cells: usize,
    /// Bar without forcing or damping.
    pub bar: WaveBar,
    /// Excitation.
    pub excitation: Excitation,
    /// Amplitude.
    pub amplitude: f64,
    /// ω/ω₁ values.
    pub omegas: Vec<f64>,
    /// Damping values.
    pub damping: Vec<f64>,
    /// Transient periods.
    pub transient_periods: usize,
    /// Averaged periods.
    pub average_periods: usize,
    /// Overlay the backbone.
    pub backbone: bool,
}

impl ForcedResponseJob {
    /// Number of independent runs.
    pub fn tasks(&self) -> u64 {
        (self.omegas.len() * self.damping.len()) as u64
    }

    /// The driven bar for one task.
    pub fn driven_bar(&self, omega_over_omega1: f64, damping: f64) -> WaveBar {
        let mut bar = self.bar.clone();
        let omega1 = std::f64::consts::PI * bar.wave_speed() / (2.0 * bar.length);
        let h = HarmonicSpec {
            amplitude: self.amplitude,
            omega: omega_over_omega1 * omega1,
        };
        match self.excitation {
            Excitation::Wall => {
                bar.wall_motion = Some(HarmonicSpec {
                    amplitude: -h.amplitude,
                    omega: h.omega,
                })
            }
            Excitation::Force => bar.harmonic_force = Some(h),
        }
        bar.damping = damping;
        bar
    }
}

impl Excitation {
    /// The name written in specs and summaries.
    pub fn name(self) -> &'static str {
        match self {
            Excitation::Wall => "wall",
            Excitation::Force => "force",
        }
    }
}

/// Steady-state response of one (ω, γ) task.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Response {
    /// ω/ω₁.
    pub omega_over_omega1: f64,
    /// γ.
    pub damping: f64,
    /// Mean cell energy over the averaging periods.
    pub mean_energy: f64,
    /// Largest |balance residual| of the run, relative to the largest energy.
    pub balance_residual: f64,
}

/// Runs one task: the bar (wall pushing toward the bar first) starting at rest.
pub fn respond(job: &ForcedResponseJob, omega_over_omega1: f64, damping: f64) -> Response {
    let bar = job.driven_bar(omega_over_omega1, damping);
    let omega = omega_over_omega1 * std::f64::consts::PI * bar.wave_speed() / (2.0 * bar.length);
    let steps_per_period = 2.0 * std::f64::consts::PI / omega / bar.dt();
    let transient = (job.transient_periods as f64 * steps_per_period).round() as u64;
    let average = ((job.average_periods as f64 * steps_per_period).round() as u64).max(1);
    let mut state = bar.initial_state();
    let mut e_prev = state.energy(&bar);
    let mut sum = 0.0;
    let mut worst: f64 = 0.0;
    let mut e_max = e_prev;
    for k in 0..transient + average {
        let terms = step(&bar, &mut state);
        // The energy balance of the step (the sums are O(N), as the source step already is).
        let e = state.energy(&bar);
        worst = worst
            .max((e - e_prev - terms.work_ext - terms.work_damping - terms.work_contact).abs());
        e_max = e_max.max(e);
        e_prev = e;
        if k >= transient {
            sum += e;
        }
    }
    Response {
        omega_over_omega1,
        damping,
        mean_energy: sum / average as f64,
        balance_residual: if e_max > 0.0 { worst / e_max } else { worst },
    }
}

/// Runs the sweep: every (γ, ω) task on `threads` threads (the caller's grant), the
/// `forced_response` table and chart. The results do not depend on `threads`.
pub fn run_forced(
    job: &ForcedResponseJob,
    header: SummaryHeader,
    threads: usize,
    observer: &mut dyn Observer,
) -> Result<RunOutput, RunError> {
    let tasks: Vec<(f64, f64)> = job
        .damping
        .iter()
        .flat_map(|&g| job.omegas.iter().map(move |&w| (g, w)))
        .collect();
    let total = tasks.len() as u64;
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let results: Mutex<Vec<Response>> = Mutex::new(Vec::new());
    let (tx, rx) = std::sync::mpsc::channel::<()>();
    let mut stopped = false;
    std::thread::scope(|s| {
        for _ in 0..threads.max(1) {
            let tx = tx.clone();
            let (next, stop, results, tasks) = (&next, &stop, &results, &tasks);
            s.spawn(move || {
                loop {
                    if stop.load(Ordering::Relaxed) {
                        break;
                    }
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(&(g, w)) = tasks.get(i) else { break };
                    let r = respond(job, w, g);
                    if let Ok(mut v) = results.lock() {
                        v.push(r);
                    }
                    let _ = tx.send(());
                }
            });
        }
        drop(tx);
        // The calling thread reports progress and honours cancellation.
        for (done, ()) in rx.iter().enumerate() {
            if stopped {
                continue;
            }
            if let ControlFlow::Break(()) = observer.progress(Progress {
                done: done as u64 + 1,
                total,
                t: 0.0,
            }) {
                stop.store(true, Ordering::Relaxed);
                stopped = true;
            }
        }
    });
    // A poisoned lock means a task panicked: its panic has already propagated out of the scope.
    let mut results = results
        .into_inner()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    if stopped {
        return Err(RunError::Stopped {
            step: results.len() as u64,
        });
    }
    results.sort_by(|a, b| {
        a.damping
            .total_cmp(&b.damping)
            .then(a.omega_over_omega1.total_cmp(&b.omega_over_omega1))
    });
    let e_lin = super::linear_grazing_energy(&job.bar);
    let rows: Vec<Vec<f64>> = results
        .iter()
        .map(|r| {
            vec![
                r.damping,
                r.omega_over_omega1,
                r.mean_energy,
                r.mean_energy / e_lin,
                r.balance_residual,
            ]
        })
        .collect();
    let backbone = if job.backbone {
        let n = job.cells;
        scan_with(&job.bar, (2 * n, 4 * n), 1, false, false, threads, &|| {
            ControlFlow::Continue(())
        })
        .unwrap_or_default()
    } else {
        Vec::new()
    };
    let chart = ForcedChart {
        moving_wall: job.excitation == Excitation::Wall,
        energy_linear_grazing: e_lin,
        responses: results
            .iter()
            .map(|r| ForcedPoint {
                damping: r.damping,
                omega_over_omega1: r.omega_over_omega1,
                mean_energy: r.mean_energy,
            })
            .collect(),
        backbone: mode_points(backbone.iter()),
    };
    let worst = results
        .iter()
        .fold(0.0f64, |m, r| m.max(r.balance_residual));
    let body = SummaryBody::ForcedResponse(ForcedSummary {
        cells: job.cells,
        gap: job.bar.gap,
        excitation: job.excitation.name().to_string(),
        amplitude: job.amplitude,
        tasks: total,
        max_relative_balance_residual: worst,
        energy_linear_grazing: e_lin,
    });
    Ok(RunOutput {
        summary: RunSummary::new(header, body),
        tables: vec![Table {
            name: "forced_response".into(),
            columns: [
                "damping",
                "omega_over_omega1",
                "mean_energy",
                "energy_normalized",
                "relative_balance_residual",
            ]
            .map(String::from)
            .to_vec(),
            rows,
        }],
        charts: vec![Chart::ForcedResponse(chart)],
    })
}

#[cfg(test)]
mod tests {
    use super::Excitation;

    /// The summary's name of an excitation is its spec spelling.
    #[test]
    fn excitation_names_are_the_spec_spelling() {
        for e in [Excitation::Wall, Excitation::Force] {
            assert_eq!(serde_json::to_value(e).ok(), Some(e.name().into()));
        }
    }
}
