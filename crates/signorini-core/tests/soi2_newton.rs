//! Simplified Newton (the default: Jacobian and LU reused while the increments contract) and
//! full Newton (fresh Jacobian every iteration) solve the same step equations to the same
//! tolerance: their trajectories agree to ≤ 1e-8.

use signorini_core::observer::Recorder;
use signorini_core::soi2::ConstrainedModel;
use signorini_core::soi2::method::{
    Coefficients, Formulation, Method, NewtonOptions, NewtonStrategy, StartValue,
};
use signorini_core::soi2::models::{Pendulum, SliderCrank};
use signorini_core::soi2::run::{End, Schedule, Soi2Output, integrate_with};

/// Differences between the full- and simplified-Newton runs over all recorded steps:
/// (max |Δy|, |Δz| over every coordinate; max |Δλ| / (1 + max |λ|)), and the Jacobians each built.
fn trajectory_difference<M: ConstrainedModel>(
    model: &M,
    method: &Method,
    h: f64,
    t_end: f64,
    pattern: &[f64],
) -> (f64, f64, u64, u64) {
    let n = model.dims().n;
    let sizes = Schedule {
        h,
        pattern: pattern.to_vec(),
        end: End::Time(t_end),
    }
    .sizes();
    let output = Soi2Output {
        every: 1,
        probes: (0..n).collect(),
    };
    let go = |s: NewtonStrategy| {
        let mut rec = Recorder::default();
        let (_, stats) = integrate_with(
            model,
            method,
            s,
            StartValue::A0,
            &sizes,
            true,
            &output,
            &mut rec,
        )
        .expect("run");
        (rec, stats)
    };
    let (full, sf) = go(NewtonStrategy::Full);
    let (simp, ss) = go(NewtonStrategy::Simplified);
    assert_eq!(full.rows.len(), sizes.len() + 1);
    assert_eq!(full.steps, simp.steps);
    for (ta, tb) in full.t.iter().zip(&simp.t) {
        assert!((ta - tb).abs() <= 1e-14);
    }
    let l0 = full.columns.index("lambda_0").expect("λ column");
    let y0 = full.columns.index("y_0").expect("y column");
    let (mut dyz, mut dl, mut lmax) = (0.0_f64, 0.0_f64, 0.0_f64);
    for (a, b) in full.rows.iter().zip(&simp.rows) {
        for (x, y) in a[y0..].iter().zip(&b[y0..]) {
            dyz = dyz.max((x - y).abs());
        }
        for (x, y) in a[l0..y0].iter().zip(&b[l0..y0]) {
            dl = dl.max((x - y).abs());
            lmax = lmax.max(x.abs());
        }
    }
    (
        dyz,
        dl / (1.0 + lmax),
        sf.newton_jacobians,
        ss.newton_jacobians,
    )
}

fn methods() -> Vec<(&'static str, Method)> {
    let newton = NewtonOptions::default();
    vec![
        (
            "soi2_generalized_alpha",
            Method {
                formulation: Formulation::Additive,
                coefficients: Coefficients::from_rho_inf(0.2),
                newton,
            },
        ),
        (
            "soi2_generalized_alpha (general 13d)",
            Method {
                formulation: Formulation::General,
                coefficients: Coefficients::from_rho_inf(0.2),
                newton,
            },
        ),
        (
            "soi2_hht",
            Method {
                formulation: Formulation::HhtSoi2,
                coefficients: Coefficients::hht(-0.2),
                newton,
            },
        ),
        (
            "hht_i3",
            Method {
                formulation: Formulation::HhtI3,
                coefficients: Coefficients::hht(-0.2),
                newton,
            },
        ),
    ]
}

#[test]
fn simplified_and_full_newton_give_the_same_trajectory() {
    let p = Pendulum::default();
    let s = SliderCrank::default();
    for (name, m) in methods() {
        for (steps, pattern) in [
            ("constant h", vec![1.0]),
            ("h/3, 2h/3", vec![1.0 / 3.0, 2.0 / 3.0]),
        ] {
            for (scene, dyz, dl, jf, js) in [
                {
                    let (a, b, c, d) = trajectory_difference(&p, &m, 2f64.powi(-9), 2.0, &pattern);
                    ("pendulum", a, b, c, d)
                },
                {
                    let (a, b, c, d) = trajectory_difference(&s, &m, 2f64.powi(-10), 2.0, &pattern);
                    ("slider-crank", a, b, c, d)
                },
            ] {
                println!(
                    "{scene} {name} {steps}: max |Δy|, |Δz| = {dyz:.2e}, max |Δλ|/(1 + max |λ|) = {dl:.2e}, \
                     Jacobians full {jf} simplified {js}"
                );
                assert!(
                    dyz <= 1e-8,
                    "{scene} {name} {steps}: y, z differ by {dyz:e}"
                );
                assert!(
                    dl <= 1e-8,
                    "{scene} {name} {steps}: λ differs by {dl:e} (relative)"
                );
                assert!(
                    js < jf,
                    "{scene} {name} {steps}: no Jacobian saved ({js} vs {jf})"
                );
            }
        }
    }
}
