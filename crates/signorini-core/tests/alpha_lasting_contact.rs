//! Regression: the α-family in a lasting contact (found by the work–precision benchmark on the
//! Doyen–Ern–Piperno bar). The sign test of (24) must read U_k ≤ the round-off of the LCP that
//! made U_k; with a plain `U_k ≤ 0`, round-off of either sign released the contact for one
//! step, the smooth step pushed the contact node h²a/2 into the obstacle, and hundreds of such
//! releases left the bar 0.3 m deep in the wall at N = 100 and non-convergent in h.

use signorini_core::integrators::alpha::{AlphaParams, AlphaScheme, NonsmoothAlpha};
use signorini_core::integrators::moreau_jean::{MoreauJean, MoreauJeanParams};
use signorini_core::integrators::{LinearScheme, LinearState, OutputOptions, run_linear};
use signorini_core::lcp::LcpOptions;
use signorini_core::model::LinearModel;
use signorini_core::observer::Recorder;
use signorini_core::scenes::Bar;

fn contact_end(model: &LinearModel, scheme: &mut dyn LinearScheme, steps: u64) -> (Vec<f64>, u64) {
    let mut state = LinearState::initial(model);
    let mut rec = Recorder::default();
    let output = OutputOptions {
        every: 1,
        probes: vec![],
    };
    let stats = run_linear(model, scheme, &mut state, steps, &output, &mut rec).unwrap();
    (rec.column("gap_0").unwrap(), stats.lcp_solves)
}

/// Acary 2016 §4.2: nonsmooth Newmark with γ = 2β = ½ *is* Moreau–Jean with θ = ½. On the DEP
/// bar (two lasting contact phases in 3 s) the gaps of both agree to round-off at every step,
/// and the other members stay within a few step-lengths of penetration.
#[test]
fn newmark_half_is_moreau_jean_half_through_lasting_contact() {
    let bar = Bar::doyen_ern_piperno(100);
    let model = bar.build().unwrap();
    let h = bar.length / bar.elements as f64 / bar.wave_speed();
    let steps = (3.0 / h).round() as u64;
    let mut mj = MoreauJean::new(
        &model,
        MoreauJeanParams::default(),
        h,
        LcpOptions::default(),
    )
    .unwrap();
    let (gap_mj, solves) = contact_end(&model, &mut mj, steps);
    assert!(
        solves > 100,
        "the bar must stay in contact for a while ({solves} LCP steps)"
    );
    let mut nm = NonsmoothAlpha::new(
        &model,
        AlphaParams::newmark(0.25, 0.5),
        h,
        LcpOptions::default(),
    )
    .unwrap();
    let (gap_nm, _) = contact_end(&model, &mut nm, steps);
    let worst = gap_mj
        .iter()
        .zip(&gap_nm)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        worst <= 1e-9,
        "ns_newmark(¼, ½) and moreau_jean(½) part by {worst:e}"
    );
    let deepest_mj = gap_mj.iter().cloned().fold(f64::INFINITY, f64::min);
    for (name, params) in [
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
        let mut s = NonsmoothAlpha::new(&model, params, h, LcpOptions::default()).unwrap();
        let (gap, _) = contact_end(&model, &mut s, steps);
        let deepest = gap.iter().cloned().fold(f64::INFINITY, f64::min);
        // Before the fix: −0.29 m. Now within a few times Moreau–Jean's penetration (−0.017 m).
        assert!(
            deepest >= 4.0 * deepest_mj,
            "{name}: penetration {deepest} (Moreau–Jean {deepest_mj})"
        );
    }
}
