//! Moreau–Jean energy bookkeeping (Acary 2016, Lemma 1 (33), Proposition 1, Corollary 1 for the
//! variant (29)): every scene, every θ and restitution the issue names, every step.

mod common;

use proptest::prelude::*;
use signorini_core::integrators::moreau_jean::{MoreauJean, MoreauJeanParams};
use signorini_core::integrators::{LinearRunStats, LinearState, OutputOptions, run_linear};
use signorini_core::lcp::LcpOptions;
use signorini_core::model::LinearModel;
use signorini_core::observer::Recorder;
use signorini_core::scenes::{Bar, BouncingBall, Chain, HarmonicSpec, LeftEnd, MassMatrix};

/// Runs Moreau–Jean for `steps` steps, recording every one.
fn simulate(
    model: &LinearModel,
    params: MoreauJeanParams,
    h: f64,
    steps: u64,
) -> (Recorder, LinearRunStats) {
    let mut scheme = MoreauJean::new(model, params, h, LcpOptions::default()).expect("Ŵ is SPD");
    common::simulate(model, &mut scheme, steps)
}

/// Lemma 1 (33) closes to round-off at every step, for θ ∈ {½, ¾, 1}, e ∈ {0, ½, 1}, both
/// position updates, on every scene (bars with damping, harmonic load and a moving wall).
#[test]
fn lemma_1_balance_closes_at_every_step() {
    for e in [0.0, 0.5, 1.0] {
        for common::Scene {
            name,
            model,
            h,
            steps,
        } in common::reference_scenes(e)
        {
            for theta in [0.5, 0.75, 1.0] {
                for variant in [false, true] {
                    let params = MoreauJeanParams {
                        theta,
                        variant,
                        ..Default::default()
                    };
                    let (rec, stats) = simulate(&model, params, h, steps);
                    let bound = 1e-10 * stats.energy_max.max(1.0);
                    let residual = rec.column("balance_residual").unwrap();
                    let worst = residual.iter().fold(0.0f64, |m, r| m.max(r.abs()));
                    assert!(
                        worst <= bound,
                        "{name}, e = {e}, θ = {theta}, variant = {variant}: |residual| = {worst:e} > {bound:e}"
                    );
                    assert!(
                        stats.impacts > 0,
                        "{name}: the scene must impact to test anything"
                    );
                }
            }
        }
    }
}

/// Lemma 1 with the terms spelled out: for θ = 1 the numerical dissipation is −½(‖Δv‖²_M + ‖Δq‖²_K),
/// so it must be ≤ 0 and nonzero on a moving system; for θ = ½ it vanishes identically.
#[test]
fn numerical_dissipation_has_the_sign_of_half_minus_theta() {
    let model = Bar {
        elements: 20,
        gap: 0.01,
        initial_velocity: 1.0,
        ..Default::default()
    }
    .build()
    .unwrap();
    let (rec1, _) = simulate(
        &model,
        MoreauJeanParams {
            theta: 1.0,
            ..Default::default()
        },
        1e-3,
        500,
    );
    let d1 = rec1.column("numerical_dissipation").unwrap();
    assert!(d1.iter().all(|&d| d <= 0.0));
    assert!(d1.iter().sum::<f64>() < -1e-6);
    let (rec_half, _) = simulate(&model, MoreauJeanParams::default(), 1e-3, 500);
    assert!(
        rec_half
            .column("numerical_dissipation")
            .unwrap()
            .iter()
            .all(|&d| d == 0.0)
    );
}

/// Proposition 1 at e = 1, θ = ½, over 10⁶ steps: the ball's energy plus its gravity potential
/// (E − cumulative work of gravity) stays constant to 1e-9 relative.
#[test]
fn elastic_ball_conserves_energy_over_a_million_steps() {
    let ball = BouncingBall {
        restitution: 1.0,
        q0: 1.0 - 1e-7,
        ..Default::default()
    };
    let model = ball.build().unwrap();
    let mut scheme = MoreauJean::new(
        &model,
        MoreauJeanParams::default(),
        1e-3,
        LcpOptions::default(),
    )
    .unwrap();
    let mut state = LinearState::initial(&model);
    // Record sparsely: the statistics cover every step.
    let output = OutputOptions {
        every: 1000,
        probes: vec![0],
    };
    let mut rec = Recorder::default();
    let stats = run_linear(
        &model,
        &mut scheme,
        &mut state,
        1_000_000,
        &output,
        &mut rec,
    )
    .unwrap();
    let total0 = model.energy(&model.q0, &model.v0).0 + ball.mass * ball.gravity * ball.q0;
    let energy = rec.column("energy").unwrap();
    let q = rec.column("q_0").unwrap();
    let worst = energy
        .iter()
        .zip(&q)
        .map(|(e, q)| ((e + ball.mass * ball.gravity * q) - total0).abs() / total0)
        .fold(0.0f64, f64::max);
    assert!(worst <= 1e-9, "relative drift {worst:e}");
    assert!(
        stats.impacts >= 1000,
        "only {} impacts in 1000 s",
        stats.impacts
    );
    // The discrete work of gravity is exactly −m g Δq (31), so the cumulative column agrees too.
    let drift = (stats.energy_final - stats.energy_initial - stats.work_ext_total).abs() / total0;
    assert!(drift <= 1e-9, "E − W_ext drift {drift:e}");
}

/// Variant (29), Corollary 1 (91): dissipative for every θ ≥ ½ and every e, even e = 1 with θ = 1
/// where the original scheme is not covered by Proposition 1. (The obstacle is held still: a
/// moving wall does work on the body, which is then not dissipation.)
#[test]
fn variant_dissipates_for_any_restitution() {
    for common::Scene {
        name,
        mut model,
        h,
        steps,
    } in common::reference_scenes(1.0)
    {
        for c in &mut model.contacts {
            c.motion = None;
        }
        let params = MoreauJeanParams {
            theta: 1.0,
            variant: true,
            ..Default::default()
        };
        let (rec, _) = simulate(&model, params, h, steps);
        let wc = rec.column("work_contact").unwrap();
        let nd = rec.column("numerical_dissipation").unwrap();
        assert!(
            wc.iter().all(|&w| w <= 1e-12),
            "{name}: positive contact work {:e}",
            wc.iter().fold(f64::MIN, |a, &b| a.max(b))
        );
        assert!(nd.iter().all(|&d| d <= 0.0), "{name}");
    }
}

fn random_model(kind: u8, seed: &[f64], e: f64) -> LinearModel {
    match kind % 3 {
        0 => BouncingBall {
            restitution: e,
            q0: 0.2 + seed[0],
            v0: -seed[1] * 3.0,
            ..Default::default()
        }
        .build()
        .unwrap(),
        1 => Bar {
            elements: 5 + (seed[2] * 30.0) as usize,
            mass_matrix: if seed[3] < 0.5 {
                MassMatrix::Lumped
            } else {
                MassMatrix::Consistent
            },
            left: if seed[4] < 0.5 {
                LeftEnd::Fixed
            } else {
                LeftEnd::Free
            },
            gap: 0.05 * seed[0],
            restitution: e,
            initial_velocity: 0.2 + 2.0 * seed[1],
            body_force: seed[5],
            rayleigh_mass: 0.1 * seed[6],
            rayleigh_stiffness: 1e-3 * seed[7],
            harmonic_force: Some(HarmonicSpec {
                amplitude: seed[8],
                omega: 10.0 * seed[9],
            }),
            ..Default::default()
        }
        .build()
        .unwrap(),
        _ => Chain {
            masses: vec![0.5 + seed[0], 0.5 + seed[1], 0.5 + seed[2]],
            stiffness: 200.0 * seed[3],
            positions: vec![
                0.01 + 0.1 * seed[4],
                0.02 + 0.1 * seed[5],
                0.03 + 0.1 * seed[6],
            ],
            velocities: vec![-seed[7] * 2.0, -seed[8], -seed[9] * 3.0],
            restitution: e,
            ..Default::default()
        }
        .build()
        .unwrap(),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    /// Proposition 1 (39)–(40): with the index set (24) and ½ ≤ θ ≤ 1/(1+ē), the energy never rises
    /// by more than the step's work_ext + work_damping.
    #[test]
    fn proposition_1_energy_bounded_by_works(
        kind in 0u8..3,
        seed in proptest::collection::vec(0.0f64..1.0, 10),
        e in 0.0f64..1.0,
        s in 0.0f64..1.0,
        h in 1e-4f64..5e-3,
    ) {
        let model = random_model(kind, &seed, e);
        let theta = 0.5 + s * (1.0 / (1.0 + e) - 0.5);
        let (rec, stats) = simulate(&model, MoreauJeanParams { theta, ..Default::default() }, h, 800);
        let energy = rec.column("energy").unwrap();
        let we = rec.column("work_ext").unwrap();
        let wd = rec.column("work_damping").unwrap();
        let tol = 1e-12 * stats.energy_max.max(1.0);
        for k in 1..energy.len() {
            let excess = energy[k] - energy[k - 1] - we[k] - wd[k];
            prop_assert!(excess <= tol, "step {k}: ΔE − W = {excess:e} (θ = {theta}, e = {e})");
        }
    }
}
