//! Per-step cost of the nonsmooth α-family and the position-contact baselines next to
//! Moreau–Jean (θ = ½) on the `bar` scene, N = 1 000 elements, lumped mass, fixed left end, one
//! contact at the right end, energy bookkeeping on (every energy column of `signorini_core::energy` at every step).
//!
//! ```text
//! cargo bench -p signorini-core --bench alpha            # add -- --quick for a short run
//! ```
//!
//! Prints one JSON line per scheme with steps/s and the cost ratio to Moreau–Jean (issue 3: the
//! family must stay within 3×). Times are the thread's on-CPU time (`/proc/thread-self/schedstat`,
//! so that other processes on a shared machine do not count), wall clock where that is missing;
//! best of 5.

// Only the core library must stay pure (clippy.toml): a benchmark times itself and prints.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::integrators::alpha::{AlphaParams, AlphaScheme, NonsmoothAlpha};
use signorini_core::integrators::moreau_jean::{MoreauJean, MoreauJeanParams};
use signorini_core::integrators::position_contact::{PositionContact, PositionContactParams};
use signorini_core::integrators::{LinearScheme, LinearState, OutputOptions, run_linear};
use signorini_core::lcp::LcpOptions;
use signorini_core::model::LinearModel;
use signorini_core::observer::{Observer, StepRecord};
use signorini_core::scenes::Bar;
use std::ops::ControlFlow;
use std::time::Instant;

/// Counts records, keeps nothing (the benchmark measures the integrator, not the output).
struct Count(u64);

impl Observer for Count {
    fn observe(&mut self, _: &StepRecord<'_>) -> ControlFlow<()> {
        self.0 += 1;
        ControlFlow::Continue(())
    }
}

/// On-CPU time of this thread in seconds (Linux), or `None`.
fn cpu_seconds() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: f64 = s.split_whitespace().next()?.parse().ok()?;
    Some(ns * 1e-9)
}

type Make = Box<dyn Fn(&LinearModel, f64) -> Box<dyn LinearScheme>>;

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let elements = 1_000;
    let bar = Bar {
        elements,
        gap: 1e-3 + 1e-7,
        initial_velocity: 1.0,
        ..Default::default()
    };
    let model = bar.build().expect("valid bar");
    let h = 1e-4;
    let steps: u64 = if quick { 2_000 } else { 20_000 };
    let lcp = LcpOptions::default();
    let ns = move |p: AlphaParams| -> Make {
        Box::new(move |m, h| {
            Box::new(NonsmoothAlpha::new(m, p, h, lcp).expect("SPD")) as Box<dyn LinearScheme>
        })
    };
    let schemes: Vec<(&str, Make)> = vec![
        (
            "moreau_jean",
            Box::new(move |m, h| {
                Box::new(MoreauJean::new(m, MoreauJeanParams::default(), h, lcp).expect("SPD"))
                    as Box<dyn LinearScheme>
            }),
        ),
        ("ns_newmark", ns(AlphaParams::newmark(0.25, 0.5))),
        ("ns_hht", ns(AlphaParams::hht(0.1))),
        (
            "ns_generalized_alpha",
            ns(AlphaParams::from_rho_inf(
                AlphaScheme::GeneralizedAlpha,
                0.8,
            )),
        ),
        (
            "ns_kh_alpha",
            ns(AlphaParams::from_rho_inf(AlphaScheme::KrenkHogsberg, 0.8)),
        ),
        (
            "newmark_position_contact",
            Box::new(move |m, h| {
                Box::new(
                    PositionContact::new(m, PositionContactParams::newmark(0.25, 0.5), h, lcp)
                        .expect("SPD"),
                ) as Box<dyn LinearScheme>
            }),
        ),
        (
            "hht_position_contact",
            Box::new(move |m, h| {
                Box::new(
                    PositionContact::new(m, PositionContactParams::hht(0.1), h, lcp).expect("SPD"),
                ) as Box<dyn LinearScheme>
            }),
        ),
    ];
    let mut reference = None;
    for (name, make) in &schemes {
        let mut best = f64::INFINITY;
        let mut impacts = 0;
        let mut residual = 0.0;
        for _ in 0..5 {
            let mut scheme = make(&model, h);
            let mut state = LinearState::initial(&model);
            let output = OutputOptions {
                every: u64::MAX,
                probes: vec![],
            };
            let mut count = Count(0);
            let (t0, c0) = (Instant::now(), cpu_seconds());
            let stats = run_linear(
                &model,
                scheme.as_mut(),
                &mut state,
                steps,
                &output,
                &mut count,
            )
            .expect("run");
            let wall = t0.elapsed().as_secs_f64();
            let used = match (c0, cpu_seconds()) {
                (Some(a), Some(b)) => b - a,
                _ => wall,
            };
            best = best.min(used);
            impacts = stats.impacts;
            residual = stats.max_abs_balance_residual;
            std::hint::black_box(&state);
        }
        let steps_per_s = steps as f64 / best;
        let mj = *reference.get_or_insert(steps_per_s);
        println!(
            "{{\"bench\":\"alpha_bar\",\"scheme\":\"{name}\",\"elements\":{elements},\"steps\":{steps},\"h\":{h},\"impacts\":{impacts},\"max_abs_balance_residual\":{residual:.3e},\"cpu_seconds\":{best:.4},\"steps_per_s\":{steps_per_s:.0},\"cost_vs_moreau_jean\":{:.2}}}",
            mj / steps_per_s
        );
    }
}
