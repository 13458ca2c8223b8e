//! Steps per second and resident memory of the `string` scene with a contact at every node,
//! against the contact-free string of the same N (issue 19). The string: L = 1 m, T = 100 N,
//! ρ = 0.01 kg/m, N moving nodes, Moreau–Jean θ = ½ (and nonsmooth HHT α = 0.1), h = 2e-5 s,
//! energy bookkeeping on, nothing recorded. Three cases per N:
//!
//! * `free` — plucked 2 mm at x = 0.3 m, no obstacle (the reference step);
//! * `pressed` — at rest on a flat obstacle at its rest line, 1 N/m pushing it down: every node
//!   is in the index set and active at every step (the active set never changes);
//! * `plucked` — plucked 2 mm over a flat obstacle 10 µm under the rest line: the inverted
//!   wave lays the string on it node after node (the active set changes every step).
//!
//! ```text
//! cargo bench -p signorini-core --bench string_contacts            # N = 10³, 10⁴, 10⁵
//! cargo bench -p signorini-core --bench string_contacts -- 10000   # chosen N
//! cargo bench -p signorini-core --bench string_contacts -- --siconos 10 100   # Siconos' window
//! cargo bench -p signorini-core --bench string_contacts -- 100000 --scheme moreau_jean --case pressed
//! ```
//!
//! `--siconos` times only Moreau–Jean on the `plucked` string over the window of
//! `scripts/siconos/string_bench.py` (200 steps untimed, to t = 4 ms, then
//! max(20, min(2000, 2·10⁵/N)) timed, best of 3): that script's `--compare` runs it next to
//! Siconos.
//!
//! One JSON line per (N, scheme, case): steps/s, µs per step, the ratio to the free step, the
//! mean active-set iterations per step, and the process' resident memory read from
//! `/proc/self/status` after the run (`VmRSS`) and its peak so far (`VmHWM`; N ascending, so
//! the peak belongs to the largest N run yet); `load_avg_1min` from `/proc/loadavg`.

// Only the core library must stay pure (clippy.toml): a benchmark times itself and prints.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use serde_json::json;
use signorini_core::integrators::alpha::{AlphaParams, NonsmoothAlpha};
use signorini_core::integrators::moreau_jean::{MoreauJean, MoreauJeanParams};
use signorini_core::integrators::{LinearScheme, LinearState, StepReport};
use signorini_core::lcp::LcpOptions;
use signorini_core::model::LinearModel;
use signorini_core::scenes::{Obstacle, Pluck, StringScene};
use std::time::Instant;

const H: f64 = 2e-5;

fn scene(n: usize, case: &str) -> LinearModel {
    let pluck = Some(Pluck {
        position: 0.3,
        amplitude: 0.002,
    });
    let mut s = StringScene {
        nodes: n,
        ..StringScene::default()
    };
    match case {
        "free" => s.pluck = pluck,
        "pressed" => {
            s.obstacle = Some(Obstacle {
                offset: 0.0,
                curvature: 0.0,
                restitution: 0.0,
            })
        }
        _ => {
            s.pluck = pluck;
            s.obstacle = Some(Obstacle {
                offset: 1e-5,
                curvature: 0.0,
                restitution: 0.0,
            });
        }
    }
    let mut model = s.build().expect("the bench string is valid");
    if case == "pressed" {
        let dx = s.spacing();
        model.force.constant.iter_mut().for_each(|f| *f = -dx);
    }
    model
}

/// (VmRSS, VmHWM) in MB.
fn memory_mb() -> (f64, f64) {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        status
            .lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse::<f64>().ok())
            .map_or(f64::NAN, |kb| kb / 1024.0)
    };
    (field("VmRSS:"), field("VmHWM:"))
}

fn load() -> f64 {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().and_then(|v| v.parse().ok()))
        .unwrap_or(f64::NAN)
}

/// Seconds per step (best of 3 runs of `steps` steps from the initial state), mean
/// active-set iterations per step, and max |balance_residual|.
fn time_steps(
    model: &LinearModel,
    make: &dyn Fn() -> Box<dyn LinearScheme>,
    steps: u64,
) -> (f64, f64, f64) {
    let mut best = f64::INFINITY;
    let (mut iterations, mut residual) = (0usize, 0.0f64);
    for _ in 0..3 {
        let mut scheme = make();
        let mut state = LinearState::initial(model);
        let mut report = StepReport::with_contacts(model.contacts.len());
        iterations = 0;
        let start = Instant::now();
        for _ in 0..steps {
            scheme
                .step(model, &mut state, &mut report)
                .expect("the bench steps succeed");
            iterations += report.lcp.iterations;
            residual = residual.max(report.energy.balance_residual.abs());
        }
        best = best.min(start.elapsed().as_secs_f64() / steps as f64);
        std::hint::black_box(&state);
    }
    (best, iterations as f64 / steps as f64, residual)
}

/// Moreau–Jean on the `plucked` string over the window of `scripts/siconos/string_bench.py`:
/// one JSON line.
fn siconos_window(n: usize) {
    let model = scene(n, "plucked");
    let warm = 200;
    let steps = (200_000 / n).clamp(20, 2000) as u64;
    let (mut best, mut iterations) = (f64::INFINITY, 0usize);
    for _ in 0..3 {
        let mut scheme = MoreauJean::new(
            &model,
            MoreauJeanParams::default(),
            H,
            LcpOptions::default(),
        )
        .expect("Ŵ is SPD");
        let mut state = LinearState::initial(&model);
        let mut report = StepReport::with_contacts(model.contacts.len());
        for _ in 0..warm {
            scheme
                .step(&model, &mut state, &mut report)
                .expect("the bench steps succeed");
        }
        iterations = 0;
        let start = Instant::now();
        for _ in 0..steps {
            scheme
                .step(&model, &mut state, &mut report)
                .expect("the bench steps succeed");
            iterations += report.lcp.iterations;
        }
        best = best.min(start.elapsed().as_secs_f64() / steps as f64);
        std::hint::black_box(&state);
    }
    println!(
        "{}",
        json!({
            "bench": "string_contacts",
            "window": "siconos",
            "nodes": n,
            "contacts": model.contacts.len(),
            "scheme": "moreau_jean",
            "case": "plucked",
            "h": H,
            "t_start": warm as f64 * H,
            "steps": steps,
            "us_per_step": (1e8 * best).round() / 100.0,
            "iterations_per_step": (100.0 * iterations as f64 / steps as f64).round() / 100.0,
            "load_avg_1min": load(),
        })
    );
}

/// The value after `--name` on the command line, if any.
fn flag(name: &str) -> Option<String> {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

fn main() {
    let siconos = std::env::args().any(|a| a == "--siconos");
    // `--scheme moreau_jean|ns_hht` and `--case pressed|plucked` restrict the runs (for a
    // profile of one case; the free step of the scheme is always timed, for the ratio).
    let (only_scheme, only_case) = (flag("--scheme"), flag("--case"));
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    if siconos {
        for n in args {
            siconos_window(n);
        }
        return;
    }
    let ns = if args.is_empty() {
        vec![1_000, 10_000, 100_000]
    } else {
        args
    };
    for n in ns {
        // About 2·10⁷ node-steps per run: 20 000 steps at N = 10³, 200 at N = 10⁵.
        let steps = (20_000_000 / n as u64).clamp(100, 20_000);
        for scheme in ["moreau_jean", "ns_hht"] {
            if only_scheme.as_deref().is_some_and(|s| s != scheme) {
                continue;
            }
            let mut free_step = f64::NAN;
            for case in ["free", "pressed", "plucked"] {
                if case != "free" && only_case.as_deref().is_some_and(|c| c != case) {
                    continue;
                }
                let model = scene(n, case);
                let make = |m: &LinearModel| -> Box<dyn LinearScheme> {
                    if scheme == "moreau_jean" {
                        Box::new(
                            MoreauJean::new(
                                m,
                                MoreauJeanParams::default(),
                                H,
                                LcpOptions::default(),
                            )
                            .expect("Ŵ is SPD"),
                        )
                    } else {
                        Box::new(
                            NonsmoothAlpha::new(m, AlphaParams::hht(0.1), H, LcpOptions::default())
                                .expect("S is SPD"),
                        )
                    }
                };
                let (step_s, iterations, residual) = time_steps(&model, &|| make(&model), steps);
                if case == "free" {
                    free_step = step_s;
                }
                let (rss, hwm) = memory_mb();
                let e0 = {
                    let (k, s) = model.energy(&model.q0, &model.v0);
                    k + s
                };
                println!(
                    "{}",
                    json!({
                        "bench": "string_contacts",
                        "nodes": n,
                        "contacts": model.contacts.len(),
                        "scheme": scheme,
                        "case": case,
                        "h": H,
                        "steps": steps,
                        "steps_per_s": (1.0 / step_s).round(),
                        "us_per_step": (1e8 * step_s).round() / 100.0,
                        "ratio_to_free": (100.0 * step_s / free_step).round() / 100.0,
                        "iterations_per_step": (100.0 * iterations).round() / 100.0,
                        "max_abs_balance_residual": residual,
                        "energy_initial": e0,
                        "vm_rss_mb": (10.0 * rss).round() / 10.0,
                        "vm_hwm_mb": (10.0 * hwm).round() / 10.0,
                        "load_avg_1min": load(),
                    })
                );
            }
        }
    }
}
