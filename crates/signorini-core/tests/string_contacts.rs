//! The `string` scene and distributed obstacles (`obstacle` on `string` and `bar`): the banded
//! impulse equals the dense one step for step, the energy identities of Moreau–Jean (Acary 2016,
//! Lemma 1) and of the nonsmooth α-family (Lemma 2) close at round-off with a contact at every
//! node, and bad specs name their field.

use signorini_core::integrators::alpha::{AlphaParams, AlphaScheme, NonsmoothAlpha};
use signorini_core::integrators::moreau_jean::{MoreauJean, MoreauJeanParams};
use signorini_core::integrators::{
    LinearRunStats, LinearScheme, LinearState, OutputOptions, StepReport, run_linear,
};
use signorini_core::job::Job;
use signorini_core::lcp::{LcpOptions, LcpSolverKind};
use signorini_core::model::LinearModel;
use signorini_core::observer::{Observer, StepRecord};
use signorini_core::scenes::{Bar, Obstacle, Pluck, StringScene};
use signorini_core::spec::JobSpec;
use std::ops::ControlFlow;

/// Keeps nothing: the run's statistics carry what the tests check.
struct Discard;

impl Observer for Discard {
    fn observe(&mut self, _: &StepRecord<'_>) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }
}

/// A string plucked up by 2 mm over an obstacle just under its rest line (`offset` 10 µm):
/// the inverted wave lays the string on it, node after node.
fn string(nodes: usize, curvature: f64) -> StringScene {
    StringScene {
        nodes,
        pluck: Some(Pluck {
            position: 0.3,
            amplitude: 0.002,
        }),
        obstacle: Some(Obstacle {
            offset: 1e-5,
            curvature,
            restitution: 0.0,
        }),
        ..StringScene::default()
    }
}

fn options(kind: LcpSolverKind) -> LcpOptions {
    LcpOptions {
        kind,
        ..LcpOptions::default()
    }
}

/// Runs `steps` steps; returns the final state, the statistics and the number of contacts
/// that took an impulse at some step.
fn run(
    model: &LinearModel,
    scheme: &mut dyn LinearScheme,
    steps: u64,
) -> (LinearState, LinearRunStats, usize) {
    /// Which contacts had P > 0 at some step; `first` is the column of p_0.
    struct Hit {
        first: usize,
        hit: Vec<bool>,
    }
    impl Observer for Hit {
        fn start(&mut self, columns: &signorini_core::observer::Columns) {
            self.first = columns.index("p_0").unwrap_or(usize::MAX);
        }
        fn observe(&mut self, r: &StepRecord<'_>) -> ControlFlow<()> {
            // Columns from p_0 on: p_α, gap_α+1, u_α+1, p_α+1, …
            if self.first != usize::MAX {
                for (h, c) in self.hit.iter_mut().zip(r.values[self.first..].chunks(3)) {
                    *h |= c[0] > 0.0;
                }
            }
            ControlFlow::Continue(())
        }
    }
    let mut state = LinearState::initial(model);
    let mut hit = Hit {
        first: usize::MAX,
        hit: vec![false; model.contacts.len()],
    };
    let output = OutputOptions {
        every: 1,
        probes: vec![],
    };
    let stats = run_linear(model, scheme, &mut state, steps, &output, &mut hit).unwrap();
    (state, stats, hit.hit.iter().filter(|&&h| h).count())
}

fn alpha_schemes() -> [AlphaParams; 4] {
    [
        AlphaParams::newmark(0.25, 0.5),
        AlphaParams::hht(0.1),
        AlphaParams::from_rho_inf(AlphaScheme::GeneralizedAlpha, 0.8),
        AlphaParams::from_rho_inf(AlphaScheme::KrenkHogsberg, 0.8),
    ]
}

#[test]
fn banded_impulses_equal_dense_ones_step_for_step() {
    // 60 contacts: small enough for Lemke on the dense Delassus operator. Restitution ½: no
    // lasting contact whose U_k is zero only to round-off, where the index set's sign test
    // (24) would be decided by the last bits of each solver's U (the banded solver returns
    // U = 0 exactly on its active set, Lemke within its round-off).
    let mut scene = string(60, -0.001);
    if let Some(o) = scene.obstacle.as_mut() {
        o.restitution = 0.5;
    }
    let model = scene.build().unwrap();
    let (h, steps) = (2e-5, 1500);
    let compare = |a: &LinearState, b: &LinearState, what: &str| {
        let scale = a.q.iter().fold(1e-3f64, |m, x| m.max(x.abs()));
        let vscale = a.v.iter().fold(1e-3f64, |m, x| m.max(x.abs()));
        for i in 0..a.q.len() {
            assert!((a.q[i] - b.q[i]).abs() <= 1e-9 * scale, "{what}: q[{i}]");
            assert!((a.v[i] - b.v[i]).abs() <= 1e-9 * vscale, "{what}: v[{i}]");
        }
    };
    for theta in [0.5, 0.75] {
        let params = MoreauJeanParams {
            theta,
            ..Default::default()
        };
        let mut dense = MoreauJean::new(&model, params, h, options(LcpSolverKind::Lemke)).unwrap();
        let mut banded =
            MoreauJean::new(&model, params, h, options(LcpSolverKind::BandedActiveSet)).unwrap();
        let (a, sa, touching) = run(&model, &mut dense, steps);
        let (b, sb, _) = run(&model, &mut banded, steps);
        assert!(
            touching > 40,
            "the string must lie on the bridge ({touching} contacts)"
        );
        assert_eq!(sa.lcp_solves, sb.lcp_solves);
        compare(&a, &b, &format!("moreau_jean θ = {theta}"));
    }
    for params in alpha_schemes() {
        let mut dense =
            NonsmoothAlpha::new(&model, params, h, options(LcpSolverKind::Lemke)).unwrap();
        let mut banded =
            NonsmoothAlpha::new(&model, params, h, options(LcpSolverKind::BandedActiveSet))
                .unwrap();
        let (a, _, _) = run(&model, &mut dense, steps);
        let (b, _, _) = run(&model, &mut banded, steps);
        compare(&a, &b, params.scheme.name());
    }
}

/// |balance_residual| ≤ 1e-11 · E_max at every step (E ≈ 3e-4 J here: a relative bound).
fn assert_ledger(stats: &LinearRunStats, what: &str) {
    let bound = 1e-11 * stats.energy_max;
    assert!(
        stats.max_abs_balance_residual <= bound,
        "{what}: |residual| = {:e} > {bound:e}",
        stats.max_abs_balance_residual
    );
}

#[test]
fn energy_ledgers_close_with_every_node_a_contact() {
    // 2 000 nodes over a flat obstacle: the inverted pluck lays most of the string on it. The
    // default `auto` takes the banded path (more than 200 contacts).
    let nodes = 2000;
    let model = string(nodes, 0.0).build().unwrap();
    assert_eq!(model.contacts.len(), nodes);
    let (h, steps) = (2e-5, 700);
    for (theta, variant) in [(0.5, false), (0.75, false), (0.5, true)] {
        let params = MoreauJeanParams {
            theta,
            variant,
            ..Default::default()
        };
        let mut scheme = MoreauJean::new(&model, params, h, LcpOptions::default()).unwrap();
        let (_, stats, touching) = run(&model, &mut scheme, steps);
        assert!(touching > nodes / 2, "θ = {theta}: {touching} contacts");
        assert!(stats.lcp_max_error <= 1e-12);
        assert_ledger(
            &stats,
            &format!("moreau_jean θ = {theta}, variant = {variant}"),
        );
    }
    for params in alpha_schemes() {
        let mut scheme = NonsmoothAlpha::new(&model, params, h, LcpOptions::default()).unwrap();
        let (_, stats, touching) = run(&model, &mut scheme, steps);
        assert!(
            touching > nodes / 2,
            "{}: {touching} contacts",
            params.scheme.name()
        );
        assert_ledger(&stats, params.scheme.name());
    }
}

#[test]
fn ten_thousand_nodes_all_in_contact_close_the_ledger() {
    let model = string(10_000, 0.0).build().unwrap();
    let mut scheme = MoreauJean::new(
        &model,
        MoreauJeanParams::default(),
        2e-5,
        LcpOptions::default(),
    )
    .unwrap();
    let mut state = LinearState::initial(&model);
    let output = OutputOptions {
        every: 1000,
        probes: vec![],
    };
    let stats = run_linear(&model, &mut scheme, &mut state, 600, &output, &mut Discard).unwrap();
    assert!(
        stats.lcp_solves > 0 && stats.impacts > 5000,
        "{} impacts",
        stats.impacts
    );
    assert_ledger(&stats, "moreau_jean, 10⁴ nodes");
}

/// The plucked string of the benchmark at N = 10⁵ (c h/Δx = 200 node spacings per step):
/// the index set of a step is hundreds of contacts wider than the contact region, which
/// shrinks by its edges (`lcp::active_set`). Before the window, the monotone pivots and the
/// leaps, its 47 steps with contacts took 140 iterations each on average, each a banded LU of
/// all 10⁵ dofs; they now take 48.3 on a window of the contacts.
#[test]
fn the_plucked_string_of_a_hundred_thousand_nodes_needs_few_iterations() {
    let model = string(100_000, 0.0).build().unwrap();
    let mut scheme = MoreauJean::new(
        &model,
        MoreauJeanParams::default(),
        2e-5,
        LcpOptions::default(),
    )
    .unwrap();
    let mut state = LinearState::initial(&model);
    let mut report = StepReport::with_contacts(model.contacts.len());
    let (mut steps, mut iterations, mut residual, mut energy) = (0, 0, 0.0f64, 0.0f64);
    for _ in 0..200 {
        scheme.step(&model, &mut state, &mut report).unwrap();
        if report.lcp.size > 0 {
            steps += 1;
            iterations += report.lcp.iterations;
            assert!(report.lcp.error <= 1e-12, "error {:e}", report.lcp.error);
        }
        residual = residual.max(report.energy.balance_residual.abs());
        energy = energy.max(report.energy.energy());
    }
    assert_eq!(steps, 47);
    let mean = iterations as f64 / steps as f64;
    assert!(mean <= 50.0, "{mean} iterations per step");
    assert!(residual <= 1e-11 * energy, "|residual| {residual:e}");
}

#[test]
fn a_bar_on_a_foundation_takes_the_banded_path_with_the_same_result() {
    // A bar pushed down by its body force onto a parabolic foundation, lumped mass (both
    // families) — 50 contacts, so Lemke can check.
    let bar = Bar {
        elements: 50,
        body_force: -2.0,
        gap: 1.0,
        ..Bar::default()
    };
    let obstacle = Obstacle {
        offset: 0.01,
        curvature: 0.02,
        restitution: 0.5,
    };
    let model = bar.build_with(Some(&obstacle)).unwrap();
    assert_eq!(model.contacts.len(), 50);
    let (h, steps) = (5e-3, 600);
    let params = MoreauJeanParams::default();
    let mut dense = MoreauJean::new(&model, params, h, options(LcpSolverKind::Lemke)).unwrap();
    let mut banded =
        MoreauJean::new(&model, params, h, options(LcpSolverKind::BandedActiveSet)).unwrap();
    let (a, _, touching) = run(&model, &mut dense, steps);
    let (b, stats, _) = run(&model, &mut banded, steps);
    assert!(touching > 5);
    assert_ledger(&stats, "bar, moreau_jean");
    for i in 0..a.q.len() {
        assert!(
            (a.q[i] - b.q[i]).abs() <= 1e-9 * (1.0 + a.q[i].abs()),
            "q[{i}]"
        );
    }
    let p = AlphaParams::hht(0.1);
    let mut scheme =
        NonsmoothAlpha::new(&model, p, h, options(LcpSolverKind::BandedActiveSet)).unwrap();
    let (_, stats, _) = run(&model, &mut scheme, steps);
    assert_ledger(&stats, "bar, ns_hht");
}

fn spec(text: &str) -> JobSpec {
    toml::from_str(text).expect("the spec parses")
}

fn field_of(text: &str) -> String {
    match Job::from_spec(&spec(text)) {
        Ok(_) => panic!("accepted: {text}"),
        Err(e) => e.field,
    }
}

#[test]
fn bad_values_name_their_field() {
    let base = |model: &str, rest: &str| {
        format!(
            "[model]\nscene = \"string\"\n{model}\n[integrator]\nscheme = \"moreau_jean\"\n[time]\nh = 1e-5\nsteps = 10\n{rest}"
        )
    };
    let cases = [
        ("nodes = 0", "", "model.nodes"),
        ("tension = -1.0", "", "model.tension"),
        ("linear_density = 0.0", "", "model.linear_density"),
        (
            "pluck = { position = 1.5, amplitude = 0.001 }",
            "",
            "model.pluck.position",
        ),
        (
            "obstacle = { offset = 0.001, restitution = 2.0 }",
            "",
            "model.obstacle.restitution",
        ),
        (
            // The bridge rises above the fixed ends: the string starts below it.
            "obstacle = { offset = 0.001, curvature = 0.1 }",
            "",
            "model.obstacle.offset",
        ),
        (
            // Lemke on 20 000 contacts would need the dense operators (3 GB).
            "nodes = 20000\nobstacle = { offset = 0.001 }",
            "[contact_solver]\nkind = \"lemke\"",
            "model.contacts",
        ),
    ];
    for (model, rest, field) in cases {
        assert_eq!(field_of(&base(model, rest)), field, "{model}");
    }
    // The same string with `auto` is accepted: it goes banded.
    Job::from_spec(&spec(&base(
        "nodes = 20000\nobstacle = { offset = 0.001 }",
        "",
    )))
    .unwrap();
    // A consistent-mass bar cannot take the α-family's banded impulse.
    let bar = "[model]\nscene = \"bar\"\nmass_matrix = \"consistent\"\nobstacle = { offset = 0.1 }\n[integrator]\nscheme = \"ns_hht\"\nalpha = 0.1\n[time]\nh = 1e-3\nsteps = 10\n[contact_solver]\nkind = \"banded_active_set\"\n";
    assert_eq!(field_of(bar), "contact_solver.kind");
    let wfem = "[model]\nscene = \"bar\"\nobstacle = { offset = 0.1 }\n[integrator]\nscheme = \"wfem\"\n[time]\nh = 0.01\nsteps = 10\n";
    assert_eq!(field_of(wfem), "model.obstacle");
}
