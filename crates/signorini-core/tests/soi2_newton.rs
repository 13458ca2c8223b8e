//! Simplified Newton (the default: Jacobian and LU reused while the increments contract) and
//! full Newton (fresh Jacobian every iteration) solve the same step equations to the same
//! tolerance: their trajectories agree to ≤ 1e-8.

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

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

#[test]
fn slider_crank_closed_form_g_y_and_g_dot_match_ad() {
    // The slider-crank gives g_y and g_t + g_y z in closed form (so its forces do not nest AD);
    // the trait's AD defaults must agree, also through a dual number.
    use signorini_core::soi2::{Dims, Dual64, InitialValues, Scalar};
    struct AdOnly(SliderCrank);
    impl ConstrainedModel for AdOnly {
        fn dims(&self) -> Dims {
            self.0.dims()
        }
        fn mass<T: Scalar>(&self, t: T, y: &[T], m: &mut [T]) {
            self.0.mass(t, y, m)
        }
        fn force<T: Scalar>(&self, t: T, y: &[T], z: &[T], l: &[T], p: &[T], f: &mut [T]) {
            self.0.force(t, y, z, l, p, f)
        }
        fn g<T: Scalar>(&self, t: T, y: &[T], out: &mut [T]) {
            self.0.g(t, y, out)
        }
        fn initial(&self) -> InitialValues {
            self.0.initial()
        }
    }
    let s = SliderCrank::default();
    let ad = AdOnly(s.clone());
    let y = [0.1, -0.3, 2.2, 0.4, 0.05, -0.7, 0.9, 0.02];
    let z = [0.3, 1.1, -4.0, 0.2, -0.6, 2.5, -1.3, 0.4];
    let (mut a, mut b) = ([0.0f64; 56], [0.0f64; 56]);
    s.g_y(0.0, &y, &mut a);
    ad.g_y(0.0, &y, &mut b);
    for (u, v) in a.iter().zip(&b) {
        assert!((u - v).abs() < 1e-14, "g_y: {u} vs {v}");
    }
    let (mut a, mut b) = ([0.0f64; 7], [0.0f64; 7]);
    s.g_dot(0.0, &y, &z, &mut a);
    ad.g_dot(0.0, &y, &z, &mut b);
    for (u, v) in a.iter().zip(&b) {
        assert!((u - v).abs() < 1e-14, "g_dot: {u} vs {v}");
    }
    // Along a direction through both angles: derivatives of g_y and of the forces agree.
    let yd: Vec<Dual64> = y
        .iter()
        .enumerate()
        .map(|(i, &v)| Dual64::new(v, [0.2, 0.0, 1.0, -0.5, 0.0, 0.7, 0.0, 0.3][i]))
        .collect();
    let (mut a, mut b) = ([Dual64::from_re(0.0); 56], [Dual64::from_re(0.0); 56]);
    s.g_y(Dual64::from_re(0.0), &yd, &mut a);
    ad.g_y(Dual64::from_re(0.0), &yd, &mut b);
    for (u, v) in a.iter().zip(&b) {
        assert!(
            (u.eps - v.eps).abs() < 1e-14,
            "d g_y: {} vs {}",
            u.eps,
            v.eps
        );
    }
    let zd: Vec<Dual64> = z.iter().map(|&v| Dual64::from_re(v)).collect();
    let l: Vec<Dual64> = (0..7)
        .map(|q| Dual64::new(q as f64 - 2.5, 0.1 * q as f64))
        .collect();
    let (mut a, mut b) = ([Dual64::from_re(0.0); 8], [Dual64::from_re(0.0); 8]);
    s.force(Dual64::from_re(0.0), &yd, &zd, &l, &[], &mut a);
    // The default force path: gravity − (AD g_y)ᵀ λ.
    let mut gy = [Dual64::from_re(0.0); 56];
    ad.g_y(Dual64::from_re(0.0), &yd, &mut gy);
    let grav = [
        0.0,
        -s.crank_mass * s.gravity,
        0.0,
        0.0,
        -s.rod_mass * s.gravity,
        0.0,
        0.0,
        -s.slider_mass * s.gravity,
    ];
    for j in 0..8 {
        let mut v = Dual64::from_re(grav[j]);
        for q in 0..7 {
            v -= gy[q * 8 + j] * l[q];
        }
        b[j] = v;
    }
    for (u, v) in a.iter().zip(&b) {
        assert!(
            (u.re - v.re).abs() < 1e-13 && (u.eps - v.eps).abs() < 1e-13,
            "force: {u} vs {v}"
        );
    }
}
