//! A compiled user model against the hand-written one: the rigid slider-crank of
//! `soi2::models::SliderCrank` (8 coordinates, 7 joints) written as a `lagrangian` model, run by
//! HHT-SOI2 with the same steps; steps/s of each (best of 5 runs) and their ratio (the issue asks
//! for ≥ 0.5×), and the two final states' distance (the same mechanism: round-off).
//!
//! `cargo bench -p signorini-core --bench lagrangian` (plain main, harness = false). Figures in
//! docs/lagrangian.md.

// Only the core library must stay pure (clippy.toml): a benchmark times itself and prints.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::expr::Param;
use signorini_core::lagrangian::UserModel;
use signorini_core::observer::Recorder;
use signorini_core::soi2::ConstrainedModel;
use signorini_core::soi2::method::{
    Coefficients, Formulation, Method, NewtonOptions, NewtonStrategy, StartValue,
};
use signorini_core::soi2::models::SliderCrank;
use signorini_core::soi2::run::{End, Schedule, Soi2Output, integrate_with};
use signorini_core::spec::{JointSpec, LagrangianSpec, MassSpec, Term};
use std::time::Instant;

fn user_slider_crank(s: &SliderCrank) -> UserModel {
    let iv = s.initial();
    let p = |v: f64| Param::Value(v);
    let spec = LagrangianSpec {
        coordinates: ["x1", "y1", "th1", "x2", "y2", "th2", "x3", "y3"]
            .map(String::from)
            .to_vec(),
        parameters: [
            ("r", p(s.crank_length)),
            ("l", p(s.rod_length)),
            ("m1", p(s.crank_mass)),
            ("m2", p(s.rod_mass)),
            ("m3", p(s.slider_mass)),
            ("g", p(s.gravity)),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect(),
        mass: MassSpec::Dense({
            let d = ["m1", "m1", "m1*r^2/12", "m2", "m2", "m2*l^2/12", "m3", "m3"];
            (0..8)
                .map(|i| {
                    (0..8)
                        .map(|j| {
                            if i == j {
                                Term::Expr(d[i].into())
                            } else {
                                Term::Number(0.0)
                            }
                        })
                        .collect()
                })
                .collect()
        }),
        potential: Some("g*(m1*y1 + m2*y2 + m3*y3)".into()),
        forces: None,
        q0: iv.y.into_iter().map(Term::Number).collect(),
        v0: Some(iv.z.into_iter().map(Term::Number).collect()),
        constraints: [
            "x1 - r/2*cos(th1)",
            "y1 - r/2*sin(th1)",
            "x1 + r/2*cos(th1) - x2 + l/2*cos(th2)",
            "y1 + r/2*sin(th1) - y2 + l/2*sin(th2)",
            "x2 + l/2*cos(th2) - x3",
            "y2 + l/2*sin(th2) - y3",
            "y3",
        ]
        .map(|e| JointSpec { expr: e.into() })
        .to_vec(),
        project_onto_joints: false,
        redundant_joints: false,
        contacts: Vec::new(),
    };
    UserModel::new(spec.validate().expect("the slider-crank as a user model"))
}

/// Best-of-5 wall seconds of a run, and its final y.
fn time<M: ConstrainedModel>(model: &M, method: &Method, steps: u64) -> (f64, Vec<f64>, u64) {
    let sizes = Schedule {
        h: 2f64.powi(-10),
        pattern: vec![1.0],
        end: End::Steps(steps),
    };
    let output = Soi2Output {
        every: steps,
        probes: Vec::new(),
    };
    let mut best = f64::INFINITY;
    let mut last = (Vec::new(), 0);
    for _ in 0..5 {
        let t0 = Instant::now();
        let (state, stats) = integrate_with(
            model,
            method,
            NewtonStrategy::Simplified,
            StartValue::A0,
            &sizes,
            false,
            &output,
            &mut Recorder::default(),
        )
        .expect("runs");
        best = best.min(t0.elapsed().as_secs_f64());
        last = (state.y, stats.newton_iterations);
    }
    (best, last.0, last.1)
}

fn main() {
    let builtin = SliderCrank::default();
    let user = user_slider_crank(&builtin);
    let method = Method {
        formulation: Formulation::HhtSoi2,
        coefficients: Coefficients::hht(-0.2),
        newton: NewtonOptions {
            tolerance: 1e-10,
            max_iterations: 25,
        },
    };
    let steps = 2048;
    let (tb, yb, ib) = time(&builtin, &method, steps);
    let (tu, yu, iu) = time(&user, &method, steps);
    let dist = yb
        .iter()
        .zip(&yu)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    println!("slider-crank, HHT-SOI2 α = −0.2, h = 2⁻¹⁰, {steps} steps (best of 5)");
    println!(
        "built-in (closed form): {:>10.0} steps/s, {ib} Newton iterations",
        steps as f64 / tb
    );
    println!(
        "lagrangian (tapes):     {:>10.0} steps/s, {iu} Newton iterations",
        steps as f64 / tu
    );
    println!(
        "ratio user/built-in: {:.2}; final states differ by {dist:e}",
        tb / tu
    );
}
