//! SOI2 speed: steps/s and Newton iterations per step (pendulum, slider-crank), and error
//! against CPU time (work–precision) for HHT-SOI2 and generalized-α-SOI2.
//!
//! `cargo bench -p signorini-core --bench soi2` (plain main, harness = false). Figures in docs/soi2.md.
//!
//! Arguments (after `--`), for one case under callgrind or alternating timings:
//! `--case SCENE/SCHEME` (e.g. `slider_crank/soi2_generalized_alpha`) runs only that throughput
//! case and skips the work–precision tables; `--newton full|simplified` only that strategy;
//! `--t-end T` replaces the case's end time (slider-crank 4 s = 4 096 steps of 2⁻¹⁰).

// Only the core library must stay pure (clippy.toml): a benchmark times itself and prints.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::observer::Recorder;
use signorini_core::soi2::ConstrainedModel;
use signorini_core::soi2::method::{
    Coefficients, Formulation, Method, NewtonOptions, NewtonStrategy, Soi2State, StartValue,
};
use signorini_core::soi2::models::{JayNegrutTest, Pendulum, SliderCrank};
use signorini_core::soi2::run::{End, Schedule, Soi2Output, Soi2Stats, integrate_with};
use std::time::Instant;

/// One benchmark case: runs and returns (state, stats, wall s, CPU s).
type Case<'a> = dyn Fn(NewtonStrategy) -> (Soi2State, Soi2Stats, f64, f64) + 'a;

fn cpu_seconds() -> f64 {
    // Process CPU time (the machine is shared): /proc/self/stat utime + stime in clock ticks.
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit_once(')').map(|(_, r)| r).unwrap_or("");
    let f: Vec<&str> = after.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (ticks(11) + ticks(12)) / 100.0
}

fn run<M: ConstrainedModel>(
    model: &M,
    m: &Method,
    newton: NewtonStrategy,
    h: f64,
    t_end: f64,
    pattern: &[f64],
) -> (Soi2State, Soi2Stats, f64, f64) {
    let sizes = Schedule {
        h,
        pattern: pattern.to_vec(),
        end: End::Time(t_end),
    }
    .sizes();
    let (w0, c0) = (Instant::now(), cpu_seconds());
    let (s, st) = integrate_with(
        model,
        m,
        newton,
        StartValue::A0,
        &sizes,
        true,
        &Soi2Output {
            every: u64::MAX,
            probes: vec![],
        },
        &mut Recorder::default(),
    )
    .expect("run");
    (s, st, w0.elapsed().as_secs_f64(), cpu_seconds() - c0)
}

/// The command line: `--case`, `--newton`, `--t-end` (cargo's own `--bench` is ignored).
struct Args {
    case: Option<String>,
    newton: Option<String>,
    t_end: Option<f64>,
}

fn args() -> Args {
    let mut a = Args {
        case: None,
        newton: None,
        t_end: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        match k.as_str() {
            "--case" => a.case = it.next(),
            "--newton" => a.newton = it.next(),
            "--t-end" => a.t_end = it.next().and_then(|v| v.parse().ok()),
            _ => {}
        }
    }
    a
}

fn main() {
    let a = args();
    let newton = NewtonOptions::default();
    let ga = |f| Method {
        formulation: f,
        coefficients: Coefficients::from_rho_inf(0.2),
        newton,
    };
    let hht = |f| Method {
        formulation: f,
        coefficients: Coefficients::hht(-0.2),
        newton,
    };
    println!("## Throughput (constant h, t_end as given)\n");
    println!(
        "| scene | scheme | Newton | h | steps | wall s | steps/s | Newton it/step | Jacobians/step |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    let p = Pendulum::default();
    let s = SliderCrank::default();
    let end = |t: f64| a.t_end.unwrap_or(t);
    let cases: Vec<(&str, &str, Box<Case>)> = vec![
        (
            "pendulum",
            "soi2_generalized_alpha",
            Box::new(|nw| {
                run(
                    &p,
                    &ga(Formulation::Additive),
                    nw,
                    2f64.powi(-12),
                    end(2.0),
                    &[1.0],
                )
            }),
        ),
        (
            "pendulum",
            "soi2_hht",
            Box::new(|nw| {
                run(
                    &p,
                    &hht(Formulation::HhtSoi2),
                    nw,
                    2f64.powi(-12),
                    end(2.0),
                    &[1.0],
                )
            }),
        ),
        (
            "pendulum",
            "hht_i3",
            Box::new(|nw| {
                run(
                    &p,
                    &hht(Formulation::HhtI3),
                    nw,
                    2f64.powi(-12),
                    end(2.0),
                    &[1.0],
                )
            }),
        ),
        (
            "slider_crank",
            "soi2_generalized_alpha",
            Box::new(|nw| {
                run(
                    &s,
                    &ga(Formulation::Additive),
                    nw,
                    2f64.powi(-10),
                    end(4.0),
                    &[1.0],
                )
            }),
        ),
        (
            "slider_crank",
            "soi2_hht",
            Box::new(|nw| {
                run(
                    &s,
                    &hht(Formulation::HhtSoi2),
                    nw,
                    2f64.powi(-10),
                    end(4.0),
                    &[1.0],
                )
            }),
        ),
        (
            "slider_crank",
            "hht_i3",
            Box::new(|nw| {
                run(
                    &s,
                    &hht(Formulation::HhtI3),
                    nw,
                    2f64.powi(-10),
                    end(4.0),
                    &[1.0],
                )
            }),
        ),
    ];
    for (scene, scheme, f) in &cases {
        if a.case
            .as_ref()
            .is_some_and(|c| *c != format!("{scene}/{scheme}"))
        {
            continue;
        }
        for (nw, name) in [
            (NewtonStrategy::Full, "full"),
            (NewtonStrategy::Simplified, "simplified"),
        ] {
            if a.newton.as_ref().is_some_and(|n| n != name) {
                continue;
            }
            let (_, st, wall, _) = f(nw);
            println!(
                "| {scene} | {scheme} | {name} | {:.3e} | {} | {wall:.3} | {:.0} | {:.2} | {:.2} |",
                if *scene == "pendulum" {
                    2f64.powi(-12)
                } else {
                    2f64.powi(-10)
                },
                st.steps,
                st.steps as f64 / wall,
                st.newton_iterations as f64 / st.steps as f64,
                st.newton_jacobians as f64 / st.steps as f64
            );
        }
    }

    if a.case.is_some() {
        return;
    }
    println!(
        "\n## Work–precision, pendulum (16), t = 2, error ‖y − y_ref‖₂ (reference: same scheme, h = 2⁻¹⁵)\n"
    );
    println!("| scheme | h | wall s | CPU s (10 ms ticks) | error y | error λ |");
    println!("|---|---|---|---|---|---|");
    for (name, m) in [
        ("soi2_hht", hht(Formulation::HhtSoi2)),
        ("soi2_generalized_alpha", ga(Formulation::Additive)),
    ] {
        let (r, _, _, _) = run(
            &p,
            &m,
            NewtonStrategy::Simplified,
            2f64.powi(-15),
            2.0,
            &[1.0],
        );
        for k in 6..=12 {
            let h = 2f64.powi(-k);
            let (st, _, wall, cpu) = run(&p, &m, NewtonStrategy::Simplified, h, 2.0, &[1.0]);
            let d = |a: &[f64], b: &[f64]| {
                a.iter()
                    .zip(b)
                    .map(|(x, y)| (x - y).powi(2))
                    .sum::<f64>()
                    .sqrt()
            };
            println!(
                "| {name} | 2^-{k} | {wall:.4} | {cpu:.2} | {:.3e} | {:.3e} |",
                d(&st.y, &r.y),
                d(&st.lambda, &r.lambda)
            );
        }
    }

    println!(
        "\n## Work–precision, test problem (15), t = 1, exact errors, steps h/3, 2h/3 with (14)\n"
    );
    println!("| h | wall s | error y | error z | error a | error λ | error ψ |");
    println!("|---|---|---|---|---|---|---|");
    let j = JayNegrutTest::default();
    for k in 4..=12 {
        let h = 2f64.powi(-k);
        let (_, st, wall, _) = run(
            &j,
            &ga(Formulation::General),
            NewtonStrategy::Simplified,
            h,
            1.0,
            &[1.0 / 3.0, 2.0 / 3.0],
        );
        let e = st.errors.expect("exact");
        println!(
            "| 2^-{k} | {wall:.4} | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {:.3e} |",
            e.y, e.z, e.a, e.lambda, e.psi
        );
    }
}
