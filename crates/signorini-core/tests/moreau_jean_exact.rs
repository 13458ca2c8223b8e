//! Moreau–Jean against exact solutions (DESIGN.md §8.3).

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
