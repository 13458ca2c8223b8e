//! Convergence orders of generalized-α-SOI2 (Jay & Negrut 2008, Figs. 1, 2 and 4).

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::observer::Recorder;
use signorini_core::soi2::GlobalErrors;
use signorini_core::soi2::method::{Coefficients, Formulation, Method, NewtonOptions, StartValue};
use signorini_core::soi2::models::{JayNegrutTest, Pendulum};
use signorini_core::soi2::run::{End, Schedule, Soi2Output, integrate};
use signorini_core::soi2::{ConstrainedModel, method::Soi2State};

fn method(formulation: Formulation) -> Method {
    Method {
        formulation,
        coefficients: Coefficients::from_rho_inf(0.2),
        newton: NewtonOptions {
            tolerance: 1e-10,
            max_iterations: 25,
        },
    }
}

fn run<M: ConstrainedModel>(
    model: &M,
    m: &Method,
    h: f64,
    t_end: f64,
    adjust: bool,
    start: StartValue,
) -> (Soi2State, Option<GlobalErrors>) {
    let sizes = Schedule {
        h,
        pattern: vec![1.0 / 3.0, 2.0 / 3.0],
        end: End::Time(t_end),
    }
    .sizes();
    let mut rec = Recorder::default();
    let (state, stats) = integrate(
        model,
        m,
        start,
        &sizes,
        adjust,
        &Soi2Output {
            every: 1_000_000,
            probes: vec![],
        },
        &mut rec,
    )
    .expect("run");
    (state, stats.errors)
}

/// Least-squares slope of log(error) against log(h).
fn slope(hs: &[f64], es: &[f64]) -> f64 {
    let x: Vec<f64> = hs.iter().map(|h| h.ln()).collect();
    let y: Vec<f64> = es.iter().map(|e| e.ln()).collect();
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(&y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    sxy / sxx
}

fn test_problem_orders(adjust: bool, start: StartValue) -> [f64; 5] {
    let model = JayNegrutTest::default();
    let m = method(Formulation::General);
    let hs: Vec<f64> = (4..=8).map(|k| 2f64.powi(-k)).collect();
    let errs: Vec<GlobalErrors> = hs
        .iter()
        .map(|&h| run(&model, &m, h, 1.0, adjust, start).1.expect("exact"))
        .collect();
    for (h, e) in hs.iter().zip(&errs) {
        eprintln!(
            "h = {h:.3e}: y {:.3e} z {:.3e} a {:.3e} λ {:.3e} ψ {:.3e}",
            e.y, e.z, e.a, e.lambda, e.psi
        );
    }
    let pick = |f: fn(&GlobalErrors) -> f64| slope(&hs, &errs.iter().map(f).collect::<Vec<_>>());
    let o = [
        pick(|e| e.y),
        pick(|e| e.z),
        pick(|e| e.a),
        pick(|e| e.lambda),
        pick(|e| e.psi),
    ];
    eprintln!("orders (adjust = {adjust}, {start:?}): {o:?}");
    o
}

#[test]
fn test_problem_order_two_with_adjusting_formulas_fig1() {
    let o = test_problem_orders(true, StartValue::A0);
    for (name, v) in ["y", "z", "a", "lambda", "psi"].iter().zip(o) {
        assert!((1.8..=2.2).contains(&v), "order of {name} = {v}");
    }
}

#[test]
fn test_problem_order_one_for_a_lambda_psi_without_adjusting_fig2() {
    let o = test_problem_orders(false, StartValue::A0);
    assert!((1.8..=2.2).contains(&o[0]), "y: {}", o[0]);
    assert!((1.8..=2.2).contains(&o[1]), "z: {}", o[1]);
    for (name, v) in ["a", "lambda", "psi"].iter().zip(&o[2..]) {
        assert!((0.8..=1.2).contains(v), "order of {name} = {v}");
    }
}

#[test]
fn test_problem_order_two_with_lunk_simeon_start() {
    let o = test_problem_orders(true, StartValue::LunkSimeon);
    for (name, v) in ["y", "z", "a", "lambda", "psi"].iter().zip(o) {
        assert!((1.8..=2.2).contains(&v), "order of {name} = {v}");
    }
}

#[test]
fn pendulum_order_two_fig4() {
    let model = Pendulum::default();
    let m = method(Formulation::Additive);
    let hs: Vec<f64> = (8..=11).map(|k| 2f64.powi(-k)).collect();
    let (reference, _) = run(&model, &m, 2f64.powi(-14), 2.0, true, StartValue::A0);
    let mut ey = Vec::new();
    let mut ez = Vec::new();
    let mut el = Vec::new();
    let d = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    for &h in &hs {
        let (s, _) = run(&model, &m, h, 2.0, true, StartValue::A0);
        ey.push(d(&s.y, &reference.y));
        ez.push(d(&s.z, &reference.z));
        el.push(d(&s.lambda, &reference.lambda));
        eprintln!(
            "pendulum h = {h:.3e}: y {:.3e} z {:.3e} λ {:.3e}",
            ey.last().unwrap(),
            ez.last().unwrap(),
            el.last().unwrap()
        );
    }
    let o = [slope(&hs, &ey), slope(&hs, &ez), slope(&hs, &el)];
    eprintln!("pendulum orders {o:?}");
    for (name, v) in ["y", "z", "lambda"].iter().zip(o) {
        assert!((1.8..=2.2).contains(&v), "order of {name} = {v}");
    }
}
