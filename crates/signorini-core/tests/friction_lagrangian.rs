//! Coulomb friction in the nonlinear Moreau–Jean time-stepping of `lagrangian` models, through
//! the whole job path (issue 11): the block on an inclined plane (sticking at rest to round-off,
//! sliding with x(t) = ½ g (sin α − μ cos α) t², the dissipated energy μ m g cos α × distance in
//! the ledger), Housner's ratio of the rocking block on a rough floor, μ = 0 equal to the
//! frictionless model bit for bit, `work_friction` ≤ 0 at every step, and the step failing with
//! step and t when the friction solver does not converge.

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::job::{Job, run};
use signorini_core::observer::Recorder;
use signorini_core::spec::JobSpec;
use std::path::Path;

fn example(name: &str) -> JobSpec {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../examples/{name}.toml"));
    let text = std::fs::read_to_string(&path).expect("reading the example");
    toml::from_str(&text).expect("the example parses")
}

fn record(spec: &JobSpec) -> Recorder {
    let job = Job::from_spec(spec).unwrap_or_else(|e| panic!("spec refused: {e}"));
    let mut rec = Recorder::default();
    run(&job, 1, &mut rec).unwrap_or_else(|e| panic!("run failed: {e}"));
    rec
}

fn col(rec: &Recorder, name: &str) -> Vec<f64> {
    rec.column(name)
        .unwrap_or_else(|| panic!("no column {name} in {:?}", rec.columns.names()))
}

const G: f64 = 9.81;
const M: f64 = 2.0;

/// The block of `examples/block_on_slope.toml` with slope α, friction μ, θ, step h, run to
/// t_end, every step recorded.
fn slope(alpha: f64, mu: f64, theta: f64, h: f64, t_end: f64) -> JobSpec {
    serde_json::from_value(serde_json::json!({
        "model": {
            "scene": "lagrangian",
            "coordinates": ["x", "y"],
            "parameters": {"m": M, "g": G, "alpha": alpha},
            "mass": [["m", 0], [0, "m"]],
            "potential": "m*g*(y*cos(alpha) - x*sin(alpha))",
            "q0": [0.0, 0.0],
            "contacts": [{"gap": "y", "tangent": "x", "friction": mu}]
        },
        "integrator": {"scheme": "moreau_jean", "theta": theta},
        "time": {"h": h, "t_end": t_end},
        "output": {"probes": [0, 1]}
    }))
    .expect("slope spec")
}

/// `work_friction` ≤ 0 at every recorded step (all of them) up to round-off, and the cone
/// holds: |pt_α| ≤ μ p_α (to the solver's round-off). Round-off: a sticking contact has U_t = 0
/// only to ~ε × the velocities of the step, so its work P_t U_t is ±ε|P_t||U|; the bound is
/// 1e-12 Σ_α |pt_α| × max(1, max|ut|), far below any sliding work.
fn assert_friction_dissipates(rec: &Recorder, mu: &[f64], what: &str) {
    let vmax = (0..mu.len())
        .flat_map(|a| col(rec, &format!("ut_{a}")))
        .fold(1.0f64, |m, u| m.max(u.abs()));
    let pts: Vec<Vec<f64>> = (0..mu.len())
        .map(|a| col(rec, &format!("pt_{a}")))
        .collect();
    for (k, w) in col(rec, "work_friction").iter().enumerate() {
        let tol = 1e-12 * vmax * pts.iter().map(|p| p[k].abs()).sum::<f64>();
        assert!(
            *w <= tol,
            "{what}: work_friction = {w:e} > {tol:e} at record {k}"
        );
    }
    for (a, &mu) in mu.iter().enumerate() {
        let (p, pt) = (col(rec, &format!("p_{a}")), col(rec, &format!("pt_{a}")));
        for (k, (p, pt)) in p.iter().zip(&pt).enumerate() {
            assert!(
                pt.abs() <= mu * p + 1e-12 * p.abs().max(1e-300),
                "{what}: contact {a} outside the cone at record {k}: |pt| = {} > μ p = {}",
                pt.abs(),
                mu * p
            );
        }
    }
}

/// Sticking, tan α < μ: the block stays at rest to round-off (x, both velocities), the
/// tangential impulse balances gravity, P_t = −m h g sin α, and friction does no work.
#[test]
fn a_block_on_a_slope_sticks_below_the_friction_angle() {
    let h = 1e-3;
    for (alpha_deg, mu) in [(10.0f64, 0.5), (25.0, 0.5), (26.0, 0.5), (30.0, 0.6)] {
        let alpha = alpha_deg.to_radians();
        assert!(alpha.tan() < mu);
        for theta in [0.5, 1.0] {
            let rec = record(&slope(alpha, mu, theta, h, 1.0));
            let what = format!("α = {alpha_deg}°, μ = {mu}, θ = {theta}");
            let x = col(&rec, "q_0");
            let v = col(&rec, "v_0");
            let worst_x = x.iter().fold(0.0f64, |m, a| m.max(a.abs()));
            let worst_v = v.iter().fold(0.0f64, |m, a| m.max(a.abs()));
            assert!(worst_x <= 1e-15, "{what}: |x| up to {worst_x:e}");
            assert!(worst_v <= 1e-14, "{what}: |v| up to {worst_v:e}");
            let pt = col(&rec, "pt_0");
            let expected = -M * h * G * alpha.sin();
            for p in &pt[1..] {
                assert!(
                    (p - expected).abs() <= 1e-12 * expected.abs(),
                    "{what}: P_t = {p} not {expected}"
                );
            }
            assert_friction_dissipates(&rec, &[mu], &what);
            let wf = col(&rec, "work_friction_total");
            assert!(wf.last().unwrap().abs() <= 1e-15, "{what}: {wf:?}");
        }
    }
}

/// Sliding, tan α > μ: x(t) = ½ a t², a = g (sin α − μ cos α). With θ = ½ the scheme is the
/// trapezoidal rule on a constant acceleration, exact to round-off; with θ = 1 the position
/// lags by ½ a h t, an error first order in h (ratio 2 when h halves). The dissipated energy
/// −work_friction_total equals μ m g cos α × x, and the balance (energy_error) closes at
/// round-off.
#[test]
fn a_block_on_a_slope_slides_above_the_friction_angle() {
    let t_end = 1.0;
    for (alpha_deg, mu) in [(30.0f64, 0.3), (45.0, 0.5), (60.0, 1.2)] {
        let alpha = alpha_deg.to_radians();
        assert!(alpha.tan() > mu);
        let a = G * (alpha.sin() - mu * alpha.cos());
        let exact = 0.5 * a * t_end * t_end;
        let mut errors = Vec::new();
        for h in [4e-3, 2e-3, 1e-3, 5e-4] {
            for theta in [0.5, 1.0] {
                let rec = record(&slope(alpha, mu, theta, h, t_end));
                let what = format!("α = {alpha_deg}°, μ = {mu}, θ = {theta}, h = {h}");
                let x = col(&rec, "q_0");
                let xe = *x.last().unwrap();
                let err = xe - exact;
                if theta == 0.5 {
                    assert!(
                        err.abs() <= 1e-12 * exact,
                        "{what}: x = {xe}, exact {exact}"
                    );
                } else {
                    // q_{k+1} = q_k + h v_{k+1}: x_k = ½ a t_k (t_k + h), exactly.
                    let lag = 0.5 * a * h * t_end;
                    assert!(
                        (err - lag).abs() <= 1e-11 * exact,
                        "{what}: error {err:e}, expected ½ a h t = {lag:e}"
                    );
                    errors.push(err);
                }
                // The block stays on the plane, sliding with P_t = −μ P_n.
                let y = col(&rec, "q_1");
                assert!(y.iter().all(|y| y.abs() <= 1e-14), "{what}: y {y:?}");
                let (p, pt) = (col(&rec, "p_0"), col(&rec, "pt_0"));
                for (p, pt) in p[1..].iter().zip(&pt[1..]) {
                    assert!((pt + mu * p).abs() <= 1e-12 * p, "{what}: {pt} vs −μ {p}");
                }
                // Ledger: dissipated energy = μ m g cos α × distance, and the balance closes.
                let wf = *col(&rec, "work_friction_total").last().unwrap();
                let expected = -mu * M * G * alpha.cos() * xe;
                assert!(
                    (wf - expected).abs() <= 1e-12 * expected.abs(),
                    "{what}: work_friction_total {wf} vs −μ m g cos α x = {expected}"
                );
                // energy_error = (½ − θ) m |Δv|² (Lemma 1's numerical dissipation, Δv = a h
                // on every step), 0 for θ = ½, to round-off.
                let dissipation = (0.5 - theta) * M * (a * h).powi(2);
                let worst = col(&rec, "energy_error")[1..]
                    .iter()
                    .fold(0.0f64, |m, e| m.max((e - dissipation).abs()));
                assert!(
                    worst <= 1e-13 * M * G * xe,
                    "{what}: balance residual {worst:e}"
                );
                assert_friction_dissipates(&rec, &[mu], &what);
            }
        }
        // θ = 1: the error halves with h (first order).
        for pair in errors.windows(2) {
            let ratio = pair[0] / pair[1];
            assert!((ratio - 2.0).abs() <= 1e-6, "order: ratio {ratio}");
        }
    }
}

/// μ = 0 written out (`friction = 0`, with a tangent) gives the frictionless run bit for bit,
/// with the frictionless columns only.
#[test]
fn zero_friction_is_the_frictionless_model_bit_for_bit() {
    let mut frictionless = example("rocking_block");
    let mut zero = frictionless.clone();
    if let Some(signorini_core::spec::ModelSpec::Lagrangian(l)) = zero.model.as_mut() {
        for c in &mut l.contacts {
            c.friction = Some(0.0);
            c.tangent = Some("x".into());
        }
    }
    for spec in [&mut frictionless, &mut zero] {
        spec.time = Some(
            serde_json::from_value(serde_json::json!({"h": 0.0005, "t_end": 0.6}))
                .expect("time section"),
        );
    }
    let (a, b) = (record(&frictionless), record(&zero));
    assert_eq!(a.columns.names(), b.columns.names());
    assert!(a.columns.index("work_friction").is_none());
    assert_eq!(a.rows, b.rows, "bit for bit");
}

/// Housner's rocking block on a rough floor (`examples/rocking_block_friction.toml`: e = 0,
/// μ = 2, θ = 1). At each impact the angular velocity ratio ω⁺/ω⁻ is r = 1 − (3/2) sin²α
/// (α = atan(w/hgt)) for a block that neither slides nor bounces; the scheme's error in it is
/// O(h) (the impact step also integrates gravity over h), checked at two steps on the first
/// three impacts. The pivot corner does not slide (|ut| ≤ 1e-9, Newton's tolerance, while it is the only corner in
/// contact), and friction never does positive work.
#[test]
fn the_rocking_block_on_a_rough_floor_follows_housner() {
    let (w, hgt) = (0.2f64, 0.4f64);
    let sin2 = (w / hgt).atan().sin().powi(2);
    let r = 1.0 - 1.5 * sin2;
    let mut worst_by_h = Vec::new();
    for h in [4e-4, 1e-4] {
        let mut spec = example("rocking_block_friction");
        spec.time =
            Some(serde_json::from_value(serde_json::json!({"h": h, "t_end": 1.0})).expect("time"));
        spec.output.every = 1;
        let rec = record(&spec);
        let what = format!("h = {h}");
        assert_friction_dissipates(&rec, &[2.0, 2.0], &what);
        let omega = col(&rec, "v_2");
        let p = [col(&rec, "p_0"), col(&rec, "p_1")];
        let ut = [col(&rec, "ut_0"), col(&rec, "ut_1")];
        let mut ratios = Vec::new();
        let mut slip = 0.0f64;
        for k in 1..omega.len() {
            for (a, b) in [(0, 1), (1, 0)] {
                // An impact: corner a lands while b was the pivot.
                if p[a][k] > 0.0 && p[a][k - 1] == 0.0 && p[b][k - 1] > 0.0 {
                    ratios.push(omega[k] / omega[k - 1]);
                }
                // Corner a the only pivot over the step: it sticks.
                if p[a][k] > 0.0 && p[a][k - 1] > 0.0 && p[b][k] == 0.0 && p[b][k - 1] == 0.0 {
                    slip = slip.max(ut[a][k].abs());
                }
            }
        }
        println!("{what}: ratios {ratios:?} (Housner r = {r}), pivot slip {slip:e}");
        assert!(ratios.len() >= 3, "{what}: {} impacts", ratios.len());
        assert!(slip <= 1e-9, "{what}: the pivot slides at {slip:e}");
        let worst = ratios
            .iter()
            .take(3)
            .fold(0.0f64, |m, q| m.max((q - r).abs()));
        worst_by_h.push(worst);
    }
    println!("worst ratio error by h (4e-4, 1e-4): {worst_by_h:?}");
    assert!(worst_by_h[0] <= 1e-2, "ratio error {worst_by_h:?}");
    assert!(
        worst_by_h[1] <= 0.4 * worst_by_h[0],
        "the ratio error shrinks like h: {worst_by_h:?}"
    );
}
