//! Hard cases for the nonsmooth α-family: e = 1 over 10⁶ steps, and the
//! accumulation of impacts (Zeno) until rest.

use signorini_core::contact::{Activation, IndexSetRule};
use signorini_core::integrators::alpha::{AlphaParams, AlphaScheme, NonsmoothAlpha};
use signorini_core::integrators::{LinearState, OutputOptions, run_linear};
use signorini_core::lcp::LcpOptions;
use signorini_core::observer::Recorder;
use signorini_core::scenes::BouncingBall;

/// Corollary 1 (92) with e = 1: nonsmooth Newmark γ = 2β = ½ and the generalized-α with ρ∞ = 1
/// (α_m = α_f = ½, γ = ½, β = ¼: H = E and every quadratic term vanishes) change the mechanical
/// energy only by the work of gravity, −m g Δq, and the impacts do no work
/// (U_{k+1/2} = 0 when U_{k+1} = −U_k). Over 10⁶ steps and hundreds of impacts, E + m g q stays
/// constant to 1e-9 relative.
#[test]
fn elastic_ball_conserves_energy_over_a_million_steps() {
    let ball = BouncingBall {
        restitution: 1.0,
        q0: 1.0 - 1e-7,
        ..Default::default()
    };
    let model = ball.build().unwrap();
    let total0 = ball.mass * ball.gravity * ball.q0;
    for (name, params) in [
        ("ns_newmark γ = 2β = ½", AlphaParams::newmark(0.25, 0.5)),
        (
            "ns_generalized_alpha ρ∞ = 1",
            AlphaParams::from_rho_inf(AlphaScheme::GeneralizedAlpha, 1.0),
        ),
    ] {
        let mut scheme = NonsmoothAlpha::new(&model, params, 1e-3, LcpOptions::default()).unwrap();
        let mut state = LinearState::initial(&model);
        let mut rec = Recorder::default();
        let output = OutputOptions {
            every: 1000,
            probes: vec![0],
        };
        let stats = run_linear(
            &model,
            &mut scheme,
            &mut state,
            1_000_000,
            &output,
            &mut rec,
        )
        .unwrap();
        assert!(
            stats.impacts >= 1000,
            "{name}: only {} impacts",
            stats.impacts
        );
        let energy = rec.column("energy").unwrap();
        let q = rec.column("q_0").unwrap();
        let worst = energy
            .iter()
            .zip(&q)
            .map(|(e, q)| ((e + ball.mass * ball.gravity * q) - total0).abs() / total0)
            .fold(0.0f64, f64::max);
        assert!(worst <= 1e-9, "{name}: relative drift {worst:e}");
        assert!(
            stats.max_abs_balance_residual <= 1e-12,
            "{name}: {:e}",
            stats.max_abs_balance_residual
        );
    }
}

/// Accumulation of impacts (Zeno), e = ½: with the predicted-gap rule every member of the family
/// brings the ball to rest past t_∞ = t₁(1 + e)/(1 − e): v = 0 and q constant, and the energy
/// balance still closes at every step. (With the default rule (24) the family falls into the same
/// sinking 2-cycle as Moreau–Jean — U = −gh/(1+e), +egh/(1+e) — pinned for Moreau–Jean in
/// `moreau_jean_exact.rs`; README "Choosing the index set".)
#[test]
fn zeno_ball_comes_to_rest_with_the_predicted_gap_rule() {
    let ball = BouncingBall {
        mass: 2.0,
        gravity: 9.81,
        q0: 1.0,
        v0: 0.0,
        restitution: 0.5,
    };
    let model = ball.build().unwrap();
    let h = 1e-3;
    let t1 = (2.0 * ball.q0 / ball.gravity).sqrt();
    let t_inf = t1 * (1.0 + ball.restitution) / (1.0 - ball.restitution);
    let steps = ((t_inf + 1.0) / h) as u64;
    let rest = ((t_inf + 0.5) / h) as usize;
    let predicted_gap = IndexSetRule {
        activation: Activation::PredictedGap,
        gamma: 1.0,
    };
    for (name, mut params) in [
        ("ns_newmark", AlphaParams::newmark(0.25, 0.5)),
        ("ns_hht", AlphaParams::hht(0.1)),
        (
            "ns_generalized_alpha",
            AlphaParams::from_rho_inf(AlphaScheme::GeneralizedAlpha, 0.8),
        ),
        (
            "ns_kh_alpha",
            AlphaParams::from_rho_inf(AlphaScheme::KrenkHogsberg, 0.8),
        ),
    ] {
        params.index_set = predicted_gap;
        let mut scheme = NonsmoothAlpha::new(&model, params, h, LcpOptions::default()).unwrap();
        let mut state = LinearState::initial(&model);
        let mut rec = Recorder::default();
        let output = OutputOptions {
            every: 1,
            probes: vec![0],
        };
        let stats = run_linear(&model, &mut scheme, &mut state, steps, &output, &mut rec).unwrap();
        assert!(stats.impacts >= 8, "{name}: only {} impacts", stats.impacts);
        assert!(stats.max_abs_balance_residual <= 1e-10 * stats.algorithmic_energy_max.max(1.0));
        let (v, q) = (rec.column("v_0").unwrap(), rec.column("q_0").unwrap());
        for k in rest..v.len() {
            assert!(v[k].abs() <= 1e-9, "{name}, step {k}: v = {:e}", v[k]);
            assert!(
                (q[k] - q[rest]).abs() <= 1e-12,
                "{name}, step {k}: q moved {:e}",
                q[k] - q[rest]
            );
        }
        assert!(
            q[rest] <= 1e-12 && q[rest] > -h * ball.gravity * t1,
            "{name}: rests at q = {}",
            q[rest]
        );
    }
}
