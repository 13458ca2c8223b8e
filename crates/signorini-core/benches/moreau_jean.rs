//! Per-step cost of Moreau–Jean (θ = ½) on the `bar` scene: lumped mass, fixed left end, one
//! contact at the right end, energy bookkeeping on (every energy column of `signorini_core::energy` at every step).
//!
//! ```text
//! cargo bench -p signorini-core --bench moreau_jean
//! cargo bench -p signorini-core --bench moreau_jean -- --elements 100,1000   # chosen N only
//! ```
//!
//! Prints one JSON line per N with steps/s and ns per dof and step. The scene matches
//! `scripts/siconos/bench.py`, so the two are directly comparable. Times are the thread's on-CPU
//! time (`/proc/thread-self/schedstat`, so that other processes on a shared machine do not
//! count; wall clock where that is missing), best of 5; `wall_seconds` is the wall clock of
//! the same repetition.

// Only the core library must stay pure (clippy.toml): a benchmark times itself and prints.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::integrators::moreau_jean::{MoreauJean, MoreauJeanParams};
use signorini_core::integrators::{LinearState, OutputOptions, run_linear};
use signorini_core::lcp::LcpOptions;
use signorini_core::observer::{Observer, StepRecord};
use signorini_core::scenes::Bar;
use std::ops::ControlFlow;
use std::time::Instant;

/// On-CPU time of this thread in seconds (Linux), or `None`.
fn cpu_seconds() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: f64 = s.split_whitespace().next()?.parse().ok()?;
    Some(ns * 1e-9)
}

/// Counts records, keeps nothing (the benchmark measures the integrator, not the output).
struct Count(u64);

impl Observer for Count {
    fn observe(&mut self, _: &StepRecord<'_>) -> ControlFlow<()> {
        self.0 += 1;
        ControlFlow::Continue(())
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let quick = args.iter().any(|a| a == "--quick");
    let list = match args.iter().position(|a| a == "--elements") {
        Some(i) => args
            .get(i + 1)
            .map(|s| {
                s.split(',')
                    .map(|x| {
                        x.trim()
                            .parse::<usize>()
                            .expect("--elements N,N,... (integers)")
                    })
                    .collect()
            })
            .expect("--elements needs a list, e.g. --elements 100,1000"),
        None => vec![100usize, 1_000, 10_000, 100_000],
    };
    for elements in list {
        let bar = Bar {
            elements,
            gap: 1e-3 + 1e-7,
            initial_velocity: 1.0,
            ..Default::default()
        };
        let model = bar.build().expect("valid bar");
        let h = 1e-4;
        let scheme_params = MoreauJeanParams::default();
        // Steps per repetition chosen for roughly 0.3–1 s of work.
        let steps = (if quick { 2e6 } else { 2e7 } / elements as f64).max(50.0) as u64;
        let (mut best, mut wall_best) = (f64::INFINITY, f64::INFINITY);
        let mut impacts = 0;
        let mut residual = 0.0;
        for _ in 0..5 {
            let mut scheme =
                MoreauJean::new(&model, scheme_params, h, LcpOptions::default()).expect("SPD");
            let mut state = LinearState::initial(&model);
            let output = OutputOptions {
                every: u64::MAX,
                probes: vec![],
            };
            let mut count = Count(0);
            let (t0, c0) = (Instant::now(), cpu_seconds());
            let stats = run_linear(&model, &mut scheme, &mut state, steps, &output, &mut count)
                .expect("run");
            let wall = t0.elapsed().as_secs_f64();
            let used = match (c0, cpu_seconds()) {
                (Some(a), Some(b)) => b - a,
                _ => wall,
            };
            if used < best {
                (best, wall_best) = (used, wall);
            }
            impacts = stats.impacts;
            residual = stats.max_abs_balance_residual;
            std::hint::black_box(&state);
        }
        let steps_per_s = steps as f64 / best;
        let dofs = model.dofs() as f64;
        println!(
            "{{\"bench\":\"moreau_jean_bar\",\"elements\":{elements},\"steps\":{steps},\"h\":{h},\"impacts\":{impacts},\"max_abs_balance_residual\":{residual:.3e},\"seconds\":{best:.4},\"wall_seconds\":{wall_best:.4},\"steps_per_s\":{steps_per_s:.0},\"ns_per_dof_step\":{:.2}}}",
            1e9 / (steps_per_s * dofs)
        );
    }
}
