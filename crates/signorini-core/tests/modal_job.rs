//! Forced response (§7) and the modal/forced jobs through `signorini_core::job::run`: resonance
//! peaks, energy balance with forcing and damping, the pinned `backbone` columns, progress per
//! task and cancellation. Their figures are tested in `crates/signorini-figures/tests/figures.rs`.

use signorini_core::job::{Job, run};
use signorini_core::modal::forced::{ForcedResponseJob, respond};
use signorini_core::modal::main_asymptote;
use signorini_core::observer::{Observer, Progress, StepRecord};
use signorini_core::outcome::RunError;
use signorini_core::spec::{ForcedResponseSpec, JobSpec};
use std::ops::ControlFlow;

fn forced(excitation: &str, gap: f64, amplitude: f64) -> ForcedResponseJob {
    let text = format!(
        "cells = 40\ngap = {gap}\namplitude = {amplitude}\nexcitation = \"{excitation}\"\ntransient_periods = 100\naverage_periods = 20\n"
    );
    ForcedResponseJob::from_spec(&toml::from_str::<ForcedResponseSpec>(&text).expect("spec"))
        .expect("valid")
}

/// (ω/ω₁, mean energy) over 0.8…2.0 by 0.05.
fn sweep(job: &ForcedResponseJob, damping: f64) -> Vec<(f64, f64, f64)> {
    (0..25)
        .map(|i| {
            let w = 0.8 + 0.05 * i as f64;
            let r = respond(job, w, damping);
            (w, r.mean_energy, r.balance_residual)
        })
        .collect()
}

fn peak(s: &[(f64, f64, f64)]) -> (f64, f64) {
    s.iter()
        .map(|r| (r.0, r.1))
        .fold((0.0, 0.0), |a, b| if b.1 > a.1 { b } else { a })
}

#[test]
fn forced_response_peaks_at_the_linear_resonance_without_contact_and_below_the_asymptote_with_it() {
    // Gap 10 ≫ response: the linear fixed–free bar, resonance at ω₁.
    let linear = forced("force", 10.0, 1e-3);
    let light = sweep(&linear, 0.02);
    let heavy = sweep(&linear, 0.1);
    let (w, e) = peak(&light);
    assert!((w - 1.0).abs() < 1e-9, "linear peak at {w}");
    let off = light.iter().find(|r| (r.0 - 1.1).abs() < 1e-9).unwrap().1;
    assert!(e > 20.0 * off, "sharp resonance: {e} vs {off} at 1.1 ω₁");
    let (wh, eh) = peak(&heavy);
    assert!(
        (wh - 1.0).abs() < 1e-9 && eh < 0.2 * e,
        "damping lowers the peak: {eh} vs {e}"
    );
    // Gap 10⁻³ < forcing: the contact hardens the response; its peak lies between ω₁ and the
    // first main asymptote 4ω₁/3 (the g0 > 0 backbone, §6.1).
    for excitation in ["force", "wall"] {
        let job = forced(excitation, 1e-3, 2e-3);
        let s = sweep(&job, 0.02);
        let in_band = s
            .iter()
            .filter(|r| r.0 > 1.0 && r.0 <= main_asymptote(1) + 1e-9)
            .map(|r| (r.0, r.1))
            .fold((0.0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
        let below = s
            .iter()
            .filter(|r| r.0 <= 1.0)
            .map(|r| r.1)
            .fold(0.0, f64::max);
        assert!(
            (in_band.0 - 1.3).abs() < 1e-9 && in_band.1 > 10.0 * below,
            "{excitation}: contact peak {in_band:?}, max at ω ≤ ω₁ {below}"
        );
        // Energy balance per step with forcing, damping and (wall) contact work: round-off.
        for r in &s {
            assert!(r.2 < 1e-13, "{excitation} at {} ω₁: balance {}", r.0, r.2);
        }
    }
    // A wall amplitude below the gap never reaches the bar: exactly nothing happens.
    let r = respond(&forced("wall", 1e-3, 5e-4), 1.3, 0.02);
    assert_eq!(r.mean_energy, 0.0);
}

/// Progress calls; Break after `stop_after` of them (never if `None`).
#[derive(Default)]
struct Counter {
    calls: Vec<Progress>,
    stop_after: Option<usize>,
}

impl Observer for Counter {
    fn observe(&mut self, _: &StepRecord<'_>) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }
    fn progress(&mut self, p: Progress) -> ControlFlow<()> {
        self.calls.push(p);
        match self.stop_after {
            Some(k) if self.calls.len() >= k => ControlFlow::Break(()),
            _ => ControlFlow::Continue(()),
        }
    }
}

/// Threads granted to a job: two, so the analyses take their parallel path.
const THREADS: usize = 2;

fn job(text: &str) -> Job {
    Job::from_spec(&toml::from_str::<JobSpec>(text).expect("toml")).expect("valid job")
}

#[test]
fn modal_job_writes_the_pinned_backbone_table_with_progress_per_task() {
    let spec = "name = \"modes\"\n[analysis]\nkind = \"nonsmooth_modes\"\ncells = 20\ngaps = [1e-3, 0.0, -1e-3]\nmax_period_steps = 80\nphases = 1\nstability_periods = 50\n";
    let mut obs = Counter::default();
    let out = run(&job(spec), THREADS, &mut obs).expect("run");
    let summary = out.summary.to_map();
    // Progress: one call per task (period length × gap), counting up to the total.
    let tasks = 3 * (80 - 2 + 1) as u64;
    assert_eq!(obs.calls.len() as u64, tasks);
    assert!(
        obs.calls
            .iter()
            .enumerate()
            .all(|(i, p)| p.done == i as u64 + 1 && p.total == tasks)
    );
    let table = out
        .tables
        .iter()
        .find(|t| t.name == "backbone")
        .expect("backbone table");
    let col = |name: &str| {
        table
            .columns
            .iter()
            .position(|c| c == name)
            .unwrap_or_else(|| panic!("column {name}"))
    };
    let pinned = [
        "m",
        "p",
        "kernel_dim",
        "admissible",
        "omega_over_omega1",
        "energy_normalized",
        "period",
        "contact_duration",
    ]
    .map(col);
    assert!(table.rows.len() > 50);
    let dt = 1.0 / 20.0;
    for r in &table.rows {
        let [m, p, h, adm, w, e, t, tc] = pinned.map(|i| r[i]);
        assert!(m >= 1.0 && p >= 1.0 && h >= 1.0 && adm == 1.0, "{r:?}");
        assert!(((m + p) * dt - t).abs() < 1e-12 && (p * dt - tc).abs() < 1e-12);
        assert!((w - 4.0 / t).abs() < 1e-12, "ω/ω₁ = 4L/(cT)");
        assert!(e.is_finite() && e > 0.0);
    }
    // The grazing first mode (m, p) = (2N, N) is in the table at ω = 4ω₁/3.
    let g = col("gap");
    assert!(
        table
            .rows
            .iter()
            .any(|r| r[g] == 0.0 && r[pinned[0]] == 40.0 && r[pinned[1]] == 20.0)
    );
    assert!(summary["stability"]["relative_deviation"].as_f64().unwrap() < 1e-3);
    // Cancellation: Break on the 5th task stops the job.
    let mut obs = Counter {
        stop_after: Some(5),
        ..Counter::default()
    };
    match run(&job(spec), THREADS, &mut obs) {
        Err(RunError::Stopped { step }) => {
            assert!((5..tasks).contains(&step), "{step}");
            assert_eq!(obs.calls.len(), 5, "no progress call after Break");
        }
        other => panic!("expected Stopped, got {:?}", other.map(|o| o.summary)),
    }
}

#[test]
fn forced_response_job_runs_every_task_and_stops_on_break() {
    let spec = "name = \"forced\"\n[analysis]\nkind = \"forced_response\"\ncells = 20\ngap = 1e-3\nexcitation = \"force\"\namplitude = 2e-3\nomegas = [0.9, 1.1, 1.3, 1.5]\ndamping = [0.02, 0.1]\ntransient_periods = 40\naverage_periods = 10\n";
    let mut obs = Counter::default();
    let out = run(&job(spec), THREADS, &mut obs).expect("run");
    assert_eq!(obs.calls.len(), 8);
    assert_eq!(obs.calls.last().map(|p| (p.done, p.total)), Some((8, 8)));
    let t = out
        .tables
        .iter()
        .find(|t| t.name == "forced_response")
        .expect("table");
    assert_eq!(t.rows.len(), 8);
    let res = t
        .columns
        .iter()
        .position(|c| c == "relative_balance_residual")
        .unwrap();
    assert!(t.rows.iter().all(|r| r[res] < 1e-13));
    let mut obs = Counter {
        stop_after: Some(2),
        ..Counter::default()
    };
    // Tasks already running finish (they are short here, so all may be done); the job still
    // ends with Stopped and the observer is not called after its Break.
    assert!(
        matches!(run(&job(spec), THREADS, &mut obs), Err(RunError::Stopped { step }) if step <= 8)
    );
    assert_eq!(obs.calls.len(), 2);
}
