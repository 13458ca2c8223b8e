//! Moreau–Jean against exact solutions.

use signorini_core::integrators::moreau_jean::{MoreauJean, MoreauJeanParams};
use signorini_core::integrators::{LinearState, OutputOptions, run_linear};
use signorini_core::lcp::LcpOptions;
use signorini_core::observer::Recorder;
use signorini_core::scenes::BouncingBall;

/// Exact (q, v) at time t of a ball dropped at rest from q0 with restitution e (before the
/// accumulation point of its impacts).
fn ball_exact(q0: f64, g: f64, e: f64, t: f64) -> (f64, f64) {
    let t1 = (2.0 * q0 / g).sqrt();
    if t < t1 {
        return (q0 - 0.5 * g * t * t, -g * t);
    }
    let (mut start, mut u) = (t1, e * g * t1);
    loop {
        let flight = 2.0 * u / g;
        if t < start + flight {
            let s = t - start;
            return (u * s - 0.5 * g * s * s, u - g * s);
        }
        start += flight;
        u *= e;
    }
}

/// Least-squares slope of log(error) against log(h).
fn order(hs: &[f64], errors: &[f64]) -> f64 {
    let xs: Vec<f64> = hs.iter().map(|h| h.ln()).collect();
    let ys: Vec<f64> = errors.iter().map(|e| e.ln()).collect();
    let n = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let num: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let den: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    num / den
}

/// Through three impacts, the position and velocity at t = 1.7 s (mid-flight) converge at first
/// order in h: the event-capturing scheme places each impact within one step.
#[test]
fn bouncing_ball_converges_at_first_order_through_impacts() {
    let ball = BouncingBall {
        mass: 1.0,
        gravity: 9.81,
        q0: 1.0,
        v0: 0.0,
        restitution: 0.9,
    };
    let model = ball.build().unwrap();
    let t_end = 1.7;
    let (q_exact, v_exact) = ball_exact(ball.q0, ball.gravity, ball.restitution, t_end);
    let hs: Vec<f64> = (0..6).map(|k| 1e-3 * 0.5f64.powi(k)).collect();
    let mut eq = Vec::new();
    let mut ev = Vec::new();
    for &h in &hs {
        let steps = (t_end / h).round() as u64;
        let mut scheme = MoreauJean::new(
            &model,
            MoreauJeanParams::default(),
            h,
            LcpOptions::default(),
        )
        .unwrap();
        let mut state = LinearState::initial(&model);
        let mut rec = Recorder::default();
        let stats = run_linear(
            &model,
            &mut scheme,
            &mut state,
            steps,
            &OutputOptions {
                every: steps,
                probes: vec![],
            },
            &mut rec,
        )
        .unwrap();
        assert_eq!(stats.impacts, 2, "h = {h}: two impacts before t = 1.7 s");
        eq.push((state.q[0] - q_exact).abs());
        ev.push((state.v[0] - v_exact).abs());
    }
    let (pq, pv) = (order(&hs, &eq), order(&hs, &ev));
    assert!(
        (0.8..=1.3).contains(&pq),
        "position order {pq}, errors {eq:?}"
    );
    assert!(
        (0.8..=1.3).contains(&pv),
        "velocity order {pv}, errors {ev:?}"
    );
    assert!(eq[hs.len() - 1] < 2e-3, "{eq:?}");
}

/// Accumulation of impacts (Zeno), e = ½: the exact impacts accumulate at
/// t_∞ = t₁(1 + e)/(1 − e); past it the ball should rest on the ground.
///
/// With Siconos' predicted-gap rule (γ = 1) Moreau–Jean does exactly that: one impulse per step,
/// P = m g h (the weight over the step), v = 0, q constant.
///
/// With the paper's rule (24) it does not, and this test pins down exactly what it does instead:
/// after an active step the restitution leaves U_{k+1} = −e U_k > 0, so (24)'s sign test drops the
/// contact for the next step, the ball falls freely for one step, and so on. The fixed point is a
/// 2-cycle U_b = −gh/(1+e) (active) → U_a = +e g h/(1+e) (free) with P = 2 m g h on every other
/// step, and q sinks by h² g (1 − e)/(2(1 + e)) per step, without bound. Users of resting
/// contacts with e > 0 should choose `activation = "predicted_gap"` (README, docs/siconos.md).
#[test]
fn zeno_ball_rests_with_predicted_gap_and_chatters_with_rule_24() {
    use signorini_core::contact::{Activation, IndexSetRule};
    let ball = BouncingBall {
        mass: 2.0,
        gravity: 9.81,
        q0: 1.0,
        v0: 0.0,
        restitution: 0.5,
    };
    let (m, g, e) = (ball.mass, ball.gravity, ball.restitution);
    let model = ball.build().unwrap();
    let h = 1e-3;
    let t1 = (2.0 * ball.q0 / g).sqrt();
    let t_inf = t1 * (1.0 + e) / (1.0 - e);
    let steps = ((t_inf + 1.0) / h) as u64;
    let rest = ((t_inf + 0.5) / h) as usize;
    let run = |index_set: IndexSetRule| {
        let params = MoreauJeanParams {
            index_set,
            ..Default::default()
        };
        let mut scheme = MoreauJean::new(&model, params, h, LcpOptions::default()).unwrap();
        let mut state = LinearState::initial(&model);
        let mut rec = Recorder::default();
        let output = OutputOptions {
            every: 1,
            probes: vec![0],
        };
        let stats = run_linear(&model, &mut scheme, &mut state, steps, &output, &mut rec).unwrap();
        assert!(
            stats.impacts >= 8,
            "only {} impacts before t_∞",
            stats.impacts
        );
        (
            rec.column("p_0").unwrap(),
            rec.column("v_0").unwrap(),
            rec.column("q_0").unwrap(),
        )
    };

    let (p, v, q) = run(IndexSetRule {
        activation: Activation::PredictedGap,
        gamma: 1.0,
    });
    for k in rest..p.len() {
        assert!(
            (p[k] - m * g * h).abs() <= 1e-12 * m * g * h,
            "predicted gap, step {k}: P = {}",
            p[k]
        );
        assert!(v[k].abs() <= 1e-12, "predicted gap, step {k}: v = {}", v[k]);
        assert_eq!(
            q[k], q[rest],
            "predicted gap, step {k}: the resting ball moved"
        );
    }
    assert!(
        q[rest] <= 0.0 && q[rest] > -h * g * t1,
        "rests at q = {}",
        q[rest]
    );

    let (p, v, q) = run(IndexSetRule::default());
    let (u_active, u_free) = (-g * h / (1.0 + e), e * g * h / (1.0 + e));
    let sink = h * h * g * (1.0 - e) / (2.0 * (1.0 + e));
    for k in rest..p.len() {
        let (expected_v, expected_p) = if p[k] > 0.0 {
            (u_free, 2.0 * m * g * h)
        } else {
            (u_active, 0.0)
        };
        assert!(
            (v[k] - expected_v).abs() <= 1e-9 * g * h,
            "(24), step {k}: v = {}",
            v[k]
        );
        assert!(
            (p[k] - expected_p).abs() <= 1e-9 * m * g * h,
            "(24), step {k}: P = {}",
            p[k]
        );
        assert!(
            (q[k - 1] - q[k] - sink).abs() <= 1e-9 * sink,
            "(24), step {k}: Δq = {}",
            q[k] - q[k - 1]
        );
        assert!(
            (p[k] > 0.0) != (p[k - 1] > 0.0),
            "(24), step {k}: not a 2-cycle"
        );
    }
}

/// Many simultaneous contacts: 40 unsprung-at-rest masses of a chain hit the wall on the same
/// step. The LCP (size 40, Lemke by default) must reverse every velocity exactly
/// (U_{k+1} = −e U_k), and with e = 1, θ = ½ the energy is unchanged across the impact.
#[test]
fn forty_simultaneous_contacts() {
    use signorini_core::scenes::Chain;
    let n = 40;
    let chain = Chain {
        masses: (0..n).map(|i| 1.0 + 0.01 * i as f64).collect(),
        stiffness: 30.0,
        positions: vec![0.0105; n],
        velocities: vec![-1.0; n],
        wall: 0.0,
        restitution: 1.0,
        force: None,
    };
    let model = chain.build().unwrap();
    let h = 1e-3;
    let mut scheme = MoreauJean::new(
        &model,
        MoreauJeanParams::default(),
        h,
        LcpOptions::default(),
    )
    .unwrap();
    let mut state = LinearState::initial(&model);
    let mut rec = Recorder::default();
    let output = OutputOptions {
        every: 1,
        probes: (0..n).collect(),
    };
    let stats = run_linear(&model, &mut scheme, &mut state, 30, &output, &mut rec).unwrap();
    assert_eq!(stats.impacts, n as u64, "every mass impacts once");
    assert!(stats.lcp_max_error <= 1e-12);
    let k = rec
        .column("p_0")
        .unwrap()
        .iter()
        .position(|&p| p > 0.0)
        .expect("an impact");
    for j in 0..n {
        let v = rec.column(&format!("v_{j}")).unwrap();
        let p = rec.column(&format!("p_{j}")).unwrap();
        assert!(p[k] > 0.0, "contact {j} did not take part");
        assert!(
            (v[k] - 1.0).abs() <= 1e-12,
            "mass {j}: v after impact {}",
            v[k]
        );
    }
    let energy = rec.column("energy").unwrap();
    assert!((energy[k] - energy[0]).abs() <= 1e-12 * energy[0]);
    assert!(stats.max_abs_balance_residual <= 1e-13);
}
