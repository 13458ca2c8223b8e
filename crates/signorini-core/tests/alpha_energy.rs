//! Energy bookkeeping of the nonsmooth α-family (Acary 2016, Lemma 2 (58), Lemma 3,
//! Propositions 2–4, Corollary 1) and of the position-contact baselines: every scheme, every
//! scene, several (ρ∞, e, h), every step.

use signorini_core::integrators::alpha::{AlphaParams, AlphaScheme, NonsmoothAlpha};
use signorini_core::integrators::position_contact::{PositionContact, PositionContactParams};
mod common;

use signorini_core::integrators::{LinearRunStats, LinearScheme};
use signorini_core::lcp::LcpOptions;
use signorini_core::model::LinearModel;
use signorini_core::observer::Recorder;

/// A scheme of the family or a baseline, by label.
#[derive(Debug, Clone, Copy)]
enum Scheme {
    Ns(AlphaParams),
    Position(PositionContactParams),
}

impl Scheme {
    fn build(&self, model: &LinearModel, h: f64) -> Box<dyn LinearScheme> {
        match *self {
            Scheme::Ns(p) => {
                p.validate().expect("parameters inside the conditions");
                Box::new(NonsmoothAlpha::new(model, p, h, LcpOptions::default()).expect("S is SPD"))
            }
            Scheme::Position(p) => {
                p.validate().expect("parameters inside the conditions");
                Box::new(
                    PositionContact::new(model, p, h, LcpOptions::default()).expect("S is SPD"),
                )
            }
        }
    }
}

fn simulate(model: &LinearModel, scheme: Scheme, h: f64, steps: u64) -> (Recorder, LinearRunStats) {
    common::simulate(model, scheme.build(model, h).as_mut(), steps)
}

fn family() -> Vec<(String, Scheme)> {
    let mut v = vec![];
    for (b, g) in [(0.25, 0.5), (0.3025, 0.6), (0.4, 0.5)] {
        v.push((
            format!("ns_newmark β={b} γ={g}"),
            Scheme::Ns(AlphaParams::newmark(b, g)),
        ));
    }
    for a in [0.05, 0.3] {
        v.push((format!("ns_hht α={a}"), Scheme::Ns(AlphaParams::hht(a))));
    }
    v.push((
        "ns_hht α=0.1 β=0.4 γ=0.7".into(),
        Scheme::Ns(AlphaParams::hht_with(0.1, 0.4, 0.7)),
    ));
    for r in [0.0, 0.5, 0.9, 1.0] {
        v.push((
            format!("ns_generalized_alpha ρ∞={r}"),
            Scheme::Ns(AlphaParams::from_rho_inf(AlphaScheme::GeneralizedAlpha, r)),
        ));
    }
    for r in [0.0, 0.6, 1.0] {
        v.push((
            format!("ns_kh_alpha ρ∞={r}"),
            Scheme::Ns(AlphaParams::from_rho_inf(AlphaScheme::KrenkHogsberg, r)),
        ));
    }
    v
}

fn baselines() -> Vec<(String, Scheme)> {
    vec![
        (
            "newmark_position_contact".into(),
            Scheme::Position(PositionContactParams::newmark(0.25, 0.5)),
        ),
        (
            "hht_position_contact α=0.1".into(),
            Scheme::Position(PositionContactParams::hht(0.1)),
        ),
    ]
}

/// Lemma 2 (58) — with (73), (81), (87) as its special cases — closes to round-off at every
/// step: |balance_residual| ≤ 1e-10 · max(1, max|H|), for every scheme of the family and both
/// baselines, e ∈ {0, ½, 1}, two step sizes, every scene.
#[test]
fn lemma_2_balance_closes_at_every_step() {
    let all: Vec<_> = family().into_iter().chain(baselines()).collect();
    for e in [0.0, 0.5, 1.0] {
        for common::Scene {
            name,
            model,
            h: h0,
            steps,
        } in common::reference_scenes(e)
        {
            for h in [h0, 2.5 * h0] {
                for (label, scheme) in &all {
                    let (rec, stats) = simulate(&model, *scheme, h, steps);
                    let bound = 1e-10 * stats.algorithmic_energy_max.max(1.0);
                    let residual = rec.column("balance_residual").unwrap();
                    let (k, worst) = residual.iter().enumerate().fold((0, 0.0f64), |m, (k, r)| {
                        if r.abs() > m.1 { (k, r.abs()) } else { m }
                    });
                    assert!(
                        worst <= bound,
                        "{name}, {label}, e = {e}, h = {h}: |residual| = {worst:e} > {bound:e} at step {k}"
                    );
                    assert!(
                        stats.impacts > 0,
                        "{name}: the scene must touch the obstacle to test anything"
                    );
                }
            }
        }
    }
}
