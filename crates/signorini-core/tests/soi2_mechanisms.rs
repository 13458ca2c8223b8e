//! HHT-SOI2 against HHT-I3 on the slider-crank (Jay & Negrut 2008, Figs. 6–7), the additive
//! form of (13d) against the general one, AD against closed-form Jacobians, and the streams.

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::observer::Recorder;
use signorini_core::soi2::method::{Coefficients, Formulation, Method, NewtonOptions, StartValue};
use signorini_core::soi2::models::{Pendulum, SliderCrank};
use signorini_core::soi2::run::{End, Schedule, Soi2Output, integrate};
use signorini_core::soi2::{ConstrainedModel, Dual64};

fn hht(formulation: Formulation) -> Method {
    Method {
        formulation,
        coefficients: Coefficients::hht(-0.2),
        newton: NewtonOptions::default(),
    }
}

fn run_recorded<M: ConstrainedModel>(
    model: &M,
    m: &Method,
    h: f64,
    t_end: f64,
) -> (Recorder, signorini_core::soi2::run::Soi2Stats) {
    let sizes = Schedule {
        h,
        pattern: vec![1.0],
        end: End::Time(t_end),
    }
    .sizes();
    let mut rec = Recorder::default();
    let (_, stats) = integrate(
        model,
        m,
        StartValue::A0,
        &sizes,
        false,
        &Soi2Output {
            every: 1,
            probes: vec![2],
        },
        &mut rec,
    )
    .expect("run");
    (rec, stats)
}

#[test]
fn slider_crank_hht_soi2_keeps_velocity_constraints_hht_i3_drifts() {
    let model = SliderCrank::default();
    let h = 2f64.powi(-10);
    let (rec_soi2, soi2) = run_recorded(&model, &hht(Formulation::HhtSoi2), h, 2.0);
    let (rec_i3, i3) = run_recorded(&model, &hht(Formulation::HhtI3), h, 2.0);
    eprintln!(
        "HHT-SOI2: pos {:.3e} vel {:.3e} it {}",
        soi2.max_position_residual, soi2.max_velocity_residual, soi2.newton_iterations
    );
    eprintln!(
        "HHT-I3:   pos {:.3e} vel {:.3e} it {}",
        i3.max_position_residual, i3.max_velocity_residual, i3.newton_iterations
    );
    eprintln!(
        "energy soi2 {} -> {}, i3 {} -> {}",
        soi2.energy_initial, soi2.energy_final, i3.energy_initial, i3.energy_final
    );
    assert_eq!(rec_soi2.steps.len(), 2049);
    assert!(
        soi2.max_velocity_residual <= 1e-10,
        "HHT-SOI2 velocity residual {}",
        soi2.max_velocity_residual
    );
    assert!(
        i3.max_velocity_residual >= 1e-6,
        "HHT-I3 velocity residual {}",
        i3.max_velocity_residual
    );
    assert!(i3.max_velocity_residual >= 1e4 * soi2.max_velocity_residual);
    assert!(
        soi2.max_position_residual <= 1e-10,
        "HHT-SOI2 position residual {}",
        soi2.max_position_residual
    );
    assert!(
        i3.max_position_residual <= 1e-10,
        "HHT-I3 position residual {}",
        i3.max_position_residual
    );
    // The streams carry the same numbers as the summary.
    let vel = rec_i3.column("velocity_residual").expect("column");
    assert_eq!(
        vel.iter().cloned().fold(0.0, f64::max),
        i3.max_velocity_residual
    );
    // No damping in the model: the mechanical energy moves only by HHT's numerical dissipation.
    let drift =
        (soi2.energy_final - soi2.energy_initial).abs() / soi2.energy_initial.abs().max(1.0);
    assert!(drift < 1e-2, "energy drift {drift}");
}

#[test]
fn additive_form_of_13d_gives_the_general_result() {
    let model = Pendulum::default();
    let general = Method {
        formulation: Formulation::General,
        coefficients: Coefficients::from_rho_inf(0.2),
        newton: NewtonOptions::default(),
    };
    let additive = Method {
        formulation: Formulation::Additive,
        ..general
    };
    let sizes = Schedule {
        h: 1e-2,
        pattern: vec![1.0 / 3.0, 2.0 / 3.0],
        end: End::Time(1.0),
    }
    .sizes();
    let out = Soi2Output {
        every: 1000,
        probes: vec![],
    };
    let (a, _) = integrate(
        &model,
        &general,
        StartValue::A0,
        &sizes,
        true,
        &out,
        &mut Recorder::default(),
    )
    .expect("general");
    let (b, _) = integrate(
        &model,
        &additive,
        StartValue::A0,
        &sizes,
        true,
        &out,
        &mut Recorder::default(),
    )
    .expect("additive");
    for (x, y) in
        a.y.iter()
            .chain(&a.z)
            .chain(&a.lambda)
            .zip(b.y.iter().chain(&b.z).chain(&b.lambda))
    {
        assert!((x - y).abs() <= 1e-8 * (1.0 + x.abs()), "{x} vs {y}");
    }
    // HHT-SOI2 (17) is the additive generalized-α-SOI2 with α_m = 0: same numbers.
    let hht17 = hht(Formulation::HhtSoi2);
    let hht_add = Method {
        formulation: Formulation::Additive,
        ..hht17
    };
    let (c, _) = integrate(
        &model,
        &hht17,
        StartValue::A0,
        &sizes,
        true,
        &out,
        &mut Recorder::default(),
    )
    .expect("17");
    let (d, _) = integrate(
        &model,
        &hht_add,
        StartValue::A0,
        &sizes,
        true,
        &out,
        &mut Recorder::default(),
    )
    .expect("13 additive");
    for (x, y) in
        c.y.iter()
            .chain(&c.z)
            .chain(&c.lambda)
            .zip(d.y.iter().chain(&d.z).chain(&d.lambda))
    {
        assert!((x - y).abs() <= 1e-8 * (1.0 + x.abs()), "{x} vs {y}");
    }
}

#[test]
fn ad_jacobians_match_closed_form() {
    // Pendulum gives g_y and g_t + g_y z in closed form; the trait's AD defaults must agree.
    struct AdOnly(Pendulum);
    impl ConstrainedModel for AdOnly {
        fn dims(&self) -> signorini_core::soi2::Dims {
            self.0.dims()
        }
        fn mass<T: signorini_core::soi2::Scalar>(&self, t: T, y: &[T], m: &mut [T]) {
            self.0.mass(t, y, m)
        }
        fn force<T: signorini_core::soi2::Scalar>(
            &self,
            t: T,
            y: &[T],
            z: &[T],
            l: &[T],
            p: &[T],
            f: &mut [T],
        ) {
            self.0.force(t, y, z, l, p, f)
        }
        fn g<T: signorini_core::soi2::Scalar>(&self, t: T, y: &[T], out: &mut [T]) {
            self.0.g(t, y, out)
        }
        fn initial(&self) -> signorini_core::soi2::InitialValues {
            self.0.initial()
        }
    }
    let p = Pendulum::default();
    let ad = AdOnly(p.clone());
    let (y, z): ([f64; 3], [f64; 3]) = ([0.3, -1.2, 4.1], [0.7, 0.2, -3.0]);
    let (mut a, mut b) = ([0.0f64; 6], [0.0f64; 6]);
    p.g_y(0.0, &y, &mut a);
    ad.g_y(0.0, &y, &mut b);
    for (u, v) in a.iter().zip(&b) {
        assert!((u - v).abs() < 1e-14, "{u} vs {v}");
    }
    let (mut a, mut b) = ([0.0f64; 2], [0.0f64; 2]);
    p.g_dot(0.0, &y, &z, &mut a);
    ad.g_dot(0.0, &y, &z, &mut b);
    for (u, v) in a.iter().zip(&b) {
        assert!((u - v).abs() < 1e-14, "{u} vs {v}");
    }
    // Nested duals: d/dy₃ of the closed-form g_y equals the AD of the AD default.
    let yd: Vec<Dual64> = y
        .iter()
        .enumerate()
        .map(|(i, &v)| Dual64::new(v, if i == 2 { 1.0 } else { 0.0 }))
        .collect();
    let (mut a, mut b) = ([Dual64::from_re(0.0); 6], [Dual64::from_re(0.0); 6]);
    p.g_y(Dual64::from_re(0.0), &yd, &mut a);
    ad.g_y(Dual64::from_re(0.0), &yd, &mut b);
    assert!((a[2].eps - 2.0 * 4.1f64.cos()).abs() < 1e-14);
    for (u, v) in a.iter().zip(&b) {
        assert!((u.eps - v.eps).abs() < 1e-14);
    }
}

#[test]
fn pendulum_damping_work_balances_energy() {
    // With the damper the only dissipation besides the scheme's: E(t) − E(0) ≈ work_damping.
    let model = Pendulum::default();
    let m = Method {
        formulation: Formulation::Additive,
        coefficients: Coefficients::from_rho_inf(0.9),
        newton: NewtonOptions::default(),
    };
    let (rec, stats) = run_recorded(&model, &m, 2f64.powi(-12), 0.5);
    let de = stats.energy_final - stats.energy_initial;
    eprintln!("ΔE = {de}, work_damping = {}", stats.work_damping_total);
    assert!(stats.work_damping_total < 0.0);
    assert!(
        (de - stats.work_damping_total).abs() <= 1e-3 * stats.work_damping_total.abs(),
        "ΔE {de} vs W {}",
        stats.work_damping_total
    );
    let e = rec.column("energy").expect("energy");
    let w = rec.column("work_damping_total").expect("work");
    assert!((e[e.len() - 1] - e[0] - w[w.len() - 1]).abs() <= 1e-3 * w[w.len() - 1].abs());
}
