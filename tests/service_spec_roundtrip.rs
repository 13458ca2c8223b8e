//! The typed proto spec mirrors the whole core spec: every file in `examples/*.toml`, parsed with
//! `spec_file::parse`, converted to `signorini.v1.JobSpec`, encoded to bytes and decoded (the wire),
//! and converted back, gives an equal `JobSpec`. A new example using a field the proto does not
//! carry fails here. A few extra specs cover the schemes and enum values no example uses.
//! Sections newer than the typed messages (`scene = "lagrangian"`) go over gRPC in the JSON
//! spelling of `SubmitJobRequest` only: their examples are skipped here.

use prost::Message;
use signorini::proto::typed_spec::job_spec_to_proto;
use signorini::proto::v1 as pb;
use signorini::server::convert::job_spec;
use signorini::spec_file::{Format, parse};
use signorini_core::spec::JobSpec;
use std::collections::BTreeSet;
use std::path::Path;

fn round_trip(spec: &JobSpec) -> JobSpec {
    let typed = job_spec_to_proto(spec).expect("a spec the typed message carries");
    let bytes = typed.encode_to_vec();
    let decoded = pb::JobSpec::decode(bytes.as_slice()).expect("decoding the typed spec");
    assert_eq!(decoded, typed, "prost wire round trip");
    job_spec(decoded).expect("typed spec converts back")
}

#[test]
fn every_example_round_trips_through_the_typed_proto() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .expect("examples/")
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 10, "the example corpus: {files:?}");
    let mut scenes = BTreeSet::new();
    let mut schemes = BTreeSet::new();
    let mut analyses = 0;
    for path in &files {
        let text = std::fs::read_to_string(path).expect("reading an example");
        let spec = parse(&text, Format::Toml).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let json_only = |m: &signorini_core::spec::ModelSpec| match m {
            signorini_core::spec::ModelSpec::Lagrangian(_) => true,
            // The `string` scene and a bar's `obstacle` travel as JSON too.
            signorini_core::spec::ModelSpec::String(_) => true,
            signorini_core::spec::ModelSpec::Bar(b)
            | signorini_core::spec::ModelSpec::DepBar(b) => b.obstacle.is_some(),
            signorini_core::spec::ModelSpec::Linear(l) => {
                l.friction.is_some() || l.t_matrix.is_some()
            }
            _ => false,
        };
        if spec.model.as_ref().is_some_and(json_only) {
            // Out of the typed message's scope: `lagrangian` models go as JSON.
            continue;
        }
        if spec.study.is_some() {
            // Studies travel as the JSON spelling only.
            continue;
        }
        // `[check]` is read by `signorini check` only; the typed message does not carry it.
        let spec = JobSpec {
            check: None,
            ..spec
        };
        let back = round_trip(&spec);
        assert_eq!(back, spec, "{} through the typed proto", path.display());
        if let Some(m) = &spec.model {
            scenes.insert(m.scene());
            schemes.insert(spec.integrator.scheme());
        }
        analyses += usize::from(spec.analysis.is_some());
    }
    // The corpus reaches the arms this change added (so the test above is not vacuous for them).
    for s in [
        "pendulum",
        "slider_crank",
        "jay_negrut_test",
        "dep_bar",
        "linear",
    ] {
        assert!(scenes.contains(s), "no example of scene {s}: {scenes:?}");
    }
    for s in [
        "ns_generalized_alpha",
        "ns_hht",
        "newmark_position_contact",
        "soi2_generalized_alpha",
        "soi2_hht",
        "wfem",
    ] {
        assert!(schemes.contains(s), "no example of scheme {s}: {schemes:?}");
    }
    assert!(
        analyses >= 2,
        "nonsmooth_modes and forced_response examples"
    );
}

/// Schemes and enum values that no example uses, written in JSON (the HTTP spelling).
///
/// Every field of the new arms is set to a value other than its default, so a conversion that
/// drops a field (and falls back to the default) fails here even where the examples spell out
/// the defaults.
const EXTRA: &[&str] = &[
    r#"{"model":{"scene":"bouncing_ball","mass":2.0,"gravity":3.0,"q0":4.0,"v0":-5.0,"restitution":0.6},"time":{"h":0.01,"steps":10}}"#,
    r#"{"model":{"scene":"chain","masses":[1.0,2.0],"stiffness":7.0,"positions":[0.3,0.4],"velocities":[-0.1,-0.2],"wall":0.05,"restitution":0.3,"force":[0.5,0.6]},"time":{"h":0.01,"steps":10}}"#,
    r#"{"model":{"scene":"pendulum","mass":1.5,"length":2.5,"stiffness":10.0,"damping":0.5,"gravity":9.0,"theta0":4.0,"omega0":1.0},"integrator":{"scheme":"soi2_hht","alpha":-0.3,"start":"lunk_simeon","newton_tolerance":1e-8,"newton_max_iterations":7,"newton":"full","consistency_tolerance":1e-5},"time":{"h":0.001,"steps":5}}"#,
    r#"{"model":{"scene":"slider_crank","crank_length":0.3,"crank_mass":2.0,"rod_length":0.8,"rod_mass":2.5,"slider_mass":3.0,"gravity":1.0,"crank_angle":0.5,"crank_speed":2.0},"integrator":{"scheme":"soi2_generalized_alpha","rho_inf":0.5,"additive":true,"newton_tolerance":1e-8,"newton_max_iterations":7,"newton":"full"},"time":{"h":0.001,"steps":5}}"#,
    r#"{"analysis":{"kind":"nonsmooth_modes","cells":12,"gaps":[0.002,-0.002],"max_period_steps":30,"min_period_steps":3,"phases":1,"length":1.5,"young":2.5,"density":3.5,"area":4.5,"stability_periods":7,"all_candidates":true}}"#,
    r#"{"analysis":{"kind":"forced_response","cells":11,"length":1.5,"young":2.5,"density":3.5,"area":4.5,"gap":0.002,"excitation":"force","amplitude":0.003,"omegas":[1.1,1.2],"damping":[0.3],"transient_periods":9,"average_periods":8,"backbone":false}}"#,
    r#"{"model":{"scene":"chain"},"integrator":{"scheme":"ns_hht","alpha":0.1,"beta":0.4,"gamma":0.65,"activation":"predicted_gap","activation_gamma":0.5,"allow_unstable":true},"time":{"h":0.01,"steps":5}}"#,
    r#"{"model":{"scene":"chain"},"integrator":{"scheme":"ns_generalized_alpha","rho_inf":0.7,"activation":"predicted_gap","activation_gamma":3.0,"allow_unstable":true},"time":{"h":0.01,"steps":5}}"#,
    r#"{"model":{"scene":"linear","mass_triplets":[[0,0,1.0],[1,1,2.0]],"stiffness_triplets":[[0,1,1.0],[1,0,1.0]],"damping_triplets":[[0,0,0.1]],"harmonic_force":[{"shape":[1.0,0.0],"omega":2.0,"phase":0.3}],"g_matrix":[[1.0,0.0]],"g_offset":[0.1],"restitution":[0.5],"q0":[0.2,0.0],"v0":[-1.0,0.0]},"time":{"h":0.01,"steps":5}}"#,
    r#"{"model":{"scene":"bouncing_ball"},"integrator":{"scheme":"moreau_jean_variant","theta":0.7,"activation":"predicted_gap","activation_gamma":2.0},"time":{"h":0.01,"steps":10},"contact_solver":{"kind":"pgs","tolerance":1e-9,"max_iterations":50}}"#,
    r#"{"model":{"scene":"chain","force":[1.0,0.0,-1.0]},"integrator":{"scheme":"ns_newmark","beta":0.3,"gamma":0.55,"allow_unstable":true},"time":{"h":0.01,"t_end":0.1},"contact_solver":{"kind":"enum"}}"#,
    r#"{"model":{"scene":"bar","elements":10,"mass_matrix":"consistent","left":"free","wall_motion":{"amplitude":0.1,"omega":2.0},"initial_displacement":0.01,"body_force":1.0,"rayleigh_mass":0.1},"integrator":{"scheme":"ns_kh_alpha","alpha_m":0.1,"alpha_f":0.2,"beta":0.3,"gamma":0.6,"activation":"gap_and_velocity"},"time":{"h":0.01,"steps":5},"output":{"every":2,"probes":[0,9]}}"#,
    r#"{"model":{"scene":"chain"},"integrator":{"scheme":"hht_position_contact","alpha":0.1,"beta":0.3,"gamma":0.6},"time":{"h":0.01,"steps":5}}"#,
    r#"{"model":{"scene":"bouncing_ball"},"time":{"h":0.01,"steps":10},"output":{"every":3,"checkpoint_seconds":2.5,"checkpoint_steps":7}}"#,
    r#"{"model":{"scene":"slider_crank","crank_speed":3.0},"integrator":{"scheme":"hht_i3","alpha":-0.1,"start":"lunk_simeon","newton_tolerance":1e-9,"newton_max_iterations":30,"newton":"full","consistency_tolerance":1e-7},"time":{"h":0.001,"steps":5}}"#,
    r#"{"model":{"scene":"pendulum","y0":[0.0,-2.0,4.71238898038469],"z0":[20.0,0.0,10.0]},"integrator":{"scheme":"soi2_generalized_alpha","alpha_m":0.1,"alpha_f":0.2,"beta":0.3,"gamma":0.6,"additive":false,"start":"lunk_simeon","consistency_tolerance":1e-6},"time":{"h":0.001,"steps":5}}"#,
    r#"{"model":{"scene":"jay_negrut_test","y0":[1.0,1.0],"z0":[1.0,-2.0]},"integrator":{"scheme":"soi2_hht"},"time":{"h":0.01,"t_end":0.1,"pattern":[1.0,2.0],"adjust":false}}"#,
    r#"{"name":"modes","analysis":{"kind":"nonsmooth_modes","cells":20,"gap":0.001,"min_period_steps":4,"max_period_steps":40,"phases":2,"length":2.0,"young":3.0,"density":4.0,"area":5.0,"all_candidates":true}}"#,
    r#"{"analysis":{"kind":"forced_response","excitation":"force","cells":10}}"#,
];

#[test]
fn extra_specs_round_trip_through_the_typed_proto() {
    for text in EXTRA {
        let spec = parse(text, Format::Json).unwrap_or_else(|e| panic!("{text}: {e}"));
        assert_eq!(round_trip(&spec), spec, "{text}");
    }
}

#[test]
fn typed_spec_errors_name_the_field() {
    // ns_hht without alpha: the same field the JSON path names.
    let typed = pb::JobSpec {
        integrator: Some(pb::IntegratorSpec {
            scheme: Some(pb::integrator_spec::Scheme::NsHht(pb::NsHht::default())),
        }),
        ..pb::JobSpec::default()
    };
    let e = job_spec(typed).expect_err("alpha is required");
    assert_eq!(e.field, "integrator.alpha");
    let typed = pb::JobSpec {
        analysis: Some(pb::AnalysisSpec { kind: None }),
        ..pb::JobSpec::default()
    };
    assert_eq!(job_spec(typed).expect_err("kind").field, "analysis.kind");
    // An enum value this build does not know (a newer client): named like the JSON path does.
    let typed = pb::JobSpec {
        integrator: Some(pb::IntegratorSpec {
            scheme: Some(pb::integrator_spec::Scheme::Soi2Hht(pb::HhtSoi2 {
                newton: 7,
                ..pb::HhtSoi2::default()
            })),
        }),
        ..pb::JobSpec::default()
    };
    assert_eq!(
        job_spec(typed).expect_err("newton").field,
        "integrator.newton"
    );
}

#[test]
fn newton_strategy_round_trips_and_defaults() {
    // Unset in the typed spec (0, UNSPECIFIED) is the core default, simplified; "full" survives.
    let typed = pb::JobSpec {
        integrator: Some(pb::IntegratorSpec {
            scheme: Some(pb::integrator_spec::Scheme::Soi2GeneralizedAlpha(
                pb::Soi2GeneralizedAlpha::default(),
            )),
        }),
        ..pb::JobSpec::default()
    };
    let core = job_spec(typed).expect("converts");
    match &core.integrator {
        signorini_core::spec::IntegratorSpec::Soi2GeneralizedAlpha(g) => {
            assert_eq!(g.solve.newton, signorini_core::spec::NewtonSpec::Simplified);
        }
        other => panic!("{other:?}"),
    }
    for scheme in ["soi2_generalized_alpha", "soi2_hht", "hht_i3"] {
        let text = format!(
            r#"{{"model":{{"scene":"pendulum"}},"integrator":{{"scheme":"{scheme}","newton":"full"}},"time":{{"h":0.001,"steps":5}}}}"#
        );
        let spec = parse(&text, Format::Json).unwrap_or_else(|e| panic!("{text}: {e}"));
        let typed = job_spec_to_proto(&spec).expect("a typed spec");
        let newton = match typed.integrator.as_ref().and_then(|i| i.scheme.as_ref()) {
            Some(pb::integrator_spec::Scheme::Soi2GeneralizedAlpha(g)) => g.newton,
            Some(
                pb::integrator_spec::Scheme::Soi2Hht(h) | pb::integrator_spec::Scheme::HhtI3(h),
            ) => h.newton,
            other => panic!("{scheme}: {other:?}"),
        };
        assert_eq!(newton, pb::Soi2Newton::Full as i32, "{scheme}");
        assert_eq!(round_trip(&spec), spec, "{scheme}");
    }
}

/// Random specs: every scene, scheme and analysis, every field drawn with and without a value.
/// Lists that are optional are drawn absent or non-empty (a proto3 `repeated` field has no
/// presence: an empty list reads as absent), the editor hint `$schema` absent (not carried).
mod random {
    use proptest::prelude::*;
    use proptest::{collection::vec, option::of};
    use signorini_core::contact::Activation;
    use signorini_core::lcp::LcpSolverKind;
    use signorini_core::scenes::{BarSpec, BouncingBall, Chain, HarmonicSpec, LeftEnd, MassMatrix};
    use signorini_core::soi2::models::{JayNegrutTest, Pendulum, SliderCrank};
    use signorini_core::spec::{
        AlphaCoefficientsSpec, AnalysisSpec, ContactSolverSpec, Excitation, ForcedResponseSpec,
        HarmonicForceSpec, HhtSoi2Spec, IndexSetSpec, IntegratorSpec, JobSpec, LinearSpec,
        ModalSpec, ModelSpec, MoreauJeanSpec, NewtonSpec, NsAlphaSpec, NsHhtSpec, NsNewmarkSpec,
        OutputSpec, PositionContactSpec, Soi2GeneralizedAlphaSpec, Soi2NewtonSpec, StartSpec,
        TimeSpec, WfemSpec,
    };

    fn x() -> impl Strategy<Value = f64> {
        prop_oneof![Just(0.0), -1.0e6..1.0e6f64]
    }
    fn ox() -> impl Strategy<Value = Option<f64>> {
        of(x())
    }
    fn xs() -> impl Strategy<Value = Vec<f64>> {
        vec(x(), 1..4)
    }
    fn oxs() -> impl Strategy<Value = Option<Vec<f64>>> {
        of(xs())
    }
    fn n() -> impl Strategy<Value = usize> {
        0..1_000_000usize
    }
    fn rows() -> impl Strategy<Value = Vec<Vec<f64>>> {
        vec(vec(x(), 0..3), 0..3)
    }
    fn triplets() -> impl Strategy<Value = Option<Vec<(usize, usize, f64)>>> {
        of(vec((0..50usize, 0..50usize, x()), 1..4))
    }
    fn harmonic() -> impl Strategy<Value = HarmonicSpec> {
        (x(), x()).prop_map(|(amplitude, omega)| HarmonicSpec { amplitude, omega })
    }

    fn bar() -> impl Strategy<Value = BarSpec> {
        (
            (of(n()), ox(), ox(), ox(), ox()),
            (
                of(prop_oneof![
                    Just(MassMatrix::Lumped),
                    Just(MassMatrix::Consistent)
                ]),
                of(prop_oneof![Just(LeftEnd::Fixed), Just(LeftEnd::Free)]),
                ox(),
                ox(),
                ox(),
            ),
            (ox(), ox(), ox(), ox(), of(harmonic()), of(harmonic())),
        )
            .prop_map(
                |(
                    (elements, length, young, density, area),
                    (mass_matrix, left, gap, restitution, initial_velocity),
                    (
                        initial_displacement,
                        body_force,
                        rayleigh_mass,
                        rayleigh_stiffness,
                        harmonic_force,
                        wall_motion,
                    ),
                )| BarSpec {
                    elements,
                    length,
                    young,
                    density,
                    area,
                    mass_matrix,
                    left,
                    gap,
                    restitution,
                    initial_velocity,
                    initial_displacement,
                    body_force,
                    rayleigh_mass,
                    rayleigh_stiffness,
                    harmonic_force,
                    wall_motion,
                    obstacle: None,
                },
            )
    }

    fn linear() -> impl Strategy<Value = LinearSpec> {
        (
            (
                of(rows()),
                triplets(),
                of(rows()),
                triplets(),
                of(rows()),
                triplets(),
            ),
            (
                oxs(),
                vec(
                    (vec(x(), 0..3), x(), x()).prop_map(|(shape, omega, phase)| {
                        HarmonicForceSpec {
                            shape,
                            omega,
                            phase,
                        }
                    }),
                    0..3,
                ),
                rows(),
                oxs(),
                vec(x(), 0..3),
                oxs(),
                oxs(),
            ),
        )
            .prop_map(
                |(
                    (mass, mass_triplets, stiffness, stiffness_triplets, damping, damping_triplets),
                    (force, harmonic_force, g_matrix, g_offset, restitution, q0, v0),
                )| LinearSpec {
                    mass,
                    mass_triplets,
                    stiffness,
                    stiffness_triplets,
                    damping,
                    damping_triplets,
                    force,
                    harmonic_force,
                    g_matrix,
                    g_offset,
                    restitution,
                    q0,
                    v0,
                    t_matrix: None,
                    friction: None,
                },
            )
    }

    /// Every scene the typed message carries. `lagrangian` is left out: it has no typed message
    /// (it travels in the JSON spelling of `SubmitJobRequest`), so it has no round trip here.
    fn model() -> impl Strategy<Value = ModelSpec> {
        prop_oneof![
            (x(), x(), x(), x(), x()).prop_map(|(mass, gravity, q0, v0, restitution)| {
                ModelSpec::BouncingBall(BouncingBall {
                    mass,
                    gravity,
                    q0,
                    v0,
                    restitution,
                })
            }),
            bar().prop_map(ModelSpec::Bar),
            bar().prop_map(ModelSpec::DepBar),
            (xs(), x(), xs(), xs(), x(), x(), oxs()).prop_map(
                |(masses, stiffness, positions, velocities, wall, restitution, force)| {
                    ModelSpec::Chain(Chain {
                        masses,
                        stiffness,
                        positions,
                        velocities,
                        wall,
                        restitution,
                        force,
                    })
                }
            ),
            linear().prop_map(ModelSpec::Linear),
            (x(), x(), x(), x(), x(), x(), x(), oxs(), oxs()).prop_map(
                |(mass, length, stiffness, damping, gravity, theta0, omega0, y0, z0)| {
                    ModelSpec::Pendulum(Pendulum {
                        mass,
                        length,
                        stiffness,
                        damping,
                        gravity,
                        theta0,
                        omega0,
                        y0,
                        z0,
                    })
                }
            ),
            (x(), x(), x(), x(), x(), x(), x(), x()).prop_map(
                |(
                    crank_length,
                    crank_mass,
                    rod_length,
                    rod_mass,
                    slider_mass,
                    gravity,
                    crank_angle,
                    crank_speed,
                )| {
                    ModelSpec::SliderCrank(SliderCrank {
                        crank_length,
                        crank_mass,
                        rod_length,
                        rod_mass,
                        slider_mass,
                        gravity,
                        crank_angle,
                        crank_speed,
                    })
                }
            ),
            (oxs(), oxs()).prop_map(|(y0, z0)| ModelSpec::JayNegrutTest(JayNegrutTest { y0, z0 })),
        ]
    }

    fn index_set() -> impl Strategy<Value = IndexSetSpec> {
        (
            prop_oneof![
                Just(None),
                Just(Some(Activation::GapAndVelocity)),
                Just(Some(Activation::PredictedGap))
            ],
            ox(),
        )
            .prop_map(|(activation, activation_gamma)| IndexSetSpec {
                activation,
                activation_gamma,
            })
    }

    fn solve() -> impl Strategy<Value = Soi2NewtonSpec> {
        (
            prop_oneof![Just(NewtonSpec::Simplified), Just(NewtonSpec::Full)],
            x(),
            n(),
            x(),
        )
            .prop_map(
                |(newton, newton_tolerance, newton_max_iterations, consistency_tolerance)| {
                    Soi2NewtonSpec {
                        newton,
                        newton_tolerance,
                        newton_max_iterations,
                        consistency_tolerance,
                    }
                },
            )
    }

    fn coefficients() -> impl Strategy<Value = AlphaCoefficientsSpec> {
        (ox(), ox(), ox(), ox(), ox()).prop_map(|(rho_inf, alpha_m, alpha_f, beta, gamma)| {
            AlphaCoefficientsSpec {
                rho_inf,
                alpha_m,
                alpha_f,
                beta,
                gamma,
            }
        })
    }

    fn start() -> impl Strategy<Value = StartSpec> {
        prop_oneof![Just(StartSpec::A0), Just(StartSpec::LunkSimeon)]
    }

    fn integrator() -> impl Strategy<Value = IntegratorSpec> {
        let mj = || {
            (x(), index_set()).prop_map(|(theta, index_set)| MoreauJeanSpec { theta, index_set })
        };
        let alpha = || {
            (
                coefficients(),
                index_set(),
                any::<bool>(),
                prop_oneof![
                    Just(None),
                    Just(Some(NewtonSpec::Full)),
                    Just(Some(NewtonSpec::Simplified))
                ],
            )
                .prop_map(|(coefficients, index_set, allow_unstable, newton)| {
                    NsAlphaSpec {
                        coefficients,
                        index_set,
                        allow_unstable,
                        newton,
                    }
                })
        };
        let position = || {
            (ox(), ox(), ox(), any::<bool>()).prop_map(|(alpha, beta, gamma, allow_unstable)| {
                PositionContactSpec {
                    alpha,
                    beta,
                    gamma,
                    allow_unstable,
                }
            })
        };
        let hht_soi2 = || {
            (x(), start(), solve()).prop_map(|(alpha, start, solve)| HhtSoi2Spec {
                alpha,
                start,
                solve,
            })
        };
        prop_oneof![
            mj().prop_map(IntegratorSpec::MoreauJean),
            mj().prop_map(IntegratorSpec::MoreauJeanVariant),
            (x(), x(), index_set(), any::<bool>()).prop_map(
                |(beta, gamma, index_set, allow_unstable)| {
                    IntegratorSpec::NsNewmark(NsNewmarkSpec {
                        beta,
                        gamma,
                        index_set,
                        allow_unstable,
                    })
                }
            ),
            (x(), ox(), ox(), index_set(), any::<bool>()).prop_map(
                |(alpha, beta, gamma, index_set, allow_unstable)| {
                    IntegratorSpec::NsHht(NsHhtSpec {
                        alpha,
                        beta,
                        gamma,
                        index_set,
                        allow_unstable,
                    })
                }
            ),
            alpha().prop_map(IntegratorSpec::NsGeneralizedAlpha),
            alpha().prop_map(IntegratorSpec::NsKhAlpha),
            position().prop_map(IntegratorSpec::NewmarkPositionContact),
            position().prop_map(IntegratorSpec::HhtPositionContact),
            Just(IntegratorSpec::Wfem(WfemSpec {})),
            (coefficients(), of(any::<bool>()), start(), solve()).prop_map(
                |(coefficients, additive, start, solve)| {
                    IntegratorSpec::Soi2GeneralizedAlpha(Soi2GeneralizedAlphaSpec {
                        coefficients,
                        additive,
                        start,
                        solve,
                    })
                }
            ),
            hht_soi2().prop_map(IntegratorSpec::Soi2Hht),
            hht_soi2().prop_map(IntegratorSpec::HhtI3),
        ]
    }

    fn analysis() -> impl Strategy<Value = AnalysisSpec> {
        prop_oneof![
            (
                (n(), ox(), oxs(), of(n()), of(n()), n()),
                (x(), x(), x(), x(), n(), any::<bool>()),
            )
                .prop_map(
                    |(
                        (cells, gap, gaps, max_period_steps, min_period_steps, phases),
                        (length, young, density, area, stability_periods, all_candidates),
                    )| {
                        AnalysisSpec::NonsmoothModes(ModalSpec {
                            cells,
                            gap,
                            gaps,
                            max_period_steps,
                            min_period_steps,
                            phases,
                            length,
                            young,
                            density,
                            area,
                            stability_periods,
                            all_candidates,
                        })
                    }
                ),
            (
                (n(), x(), x(), x(), x(), x()),
                (
                    prop_oneof![Just(Excitation::Wall), Just(Excitation::Force)],
                    x(),
                    oxs(),
                    xs(),
                    n(),
                    n(),
                    any::<bool>(),
                ),
            )
                .prop_map(
                    |(
                        (cells, length, young, density, area, gap),
                        (
                            excitation,
                            amplitude,
                            omegas,
                            damping,
                            transient_periods,
                            average_periods,
                            backbone,
                        ),
                    )| {
                        AnalysisSpec::ForcedResponse(ForcedResponseSpec {
                            cells,
                            length,
                            young,
                            density,
                            area,
                            gap,
                            excitation,
                            amplitude,
                            omegas,
                            damping,
                            transient_periods,
                            average_periods,
                            backbone,
                        })
                    }
                ),
        ]
    }

    pub fn job_spec() -> impl Strategy<Value = JobSpec> {
        let time = (x(), ox(), of(any::<u64>()), oxs(), of(any::<bool>())).prop_map(
            |(h, t_end, steps, pattern, adjust)| TimeSpec {
                h,
                t_end,
                steps,
                pattern,
                adjust,
            },
        );
        let contact_solver = (
            prop_oneof![
                Just(LcpSolverKind::Auto),
                Just(LcpSolverKind::Lemke),
                Just(LcpSolverKind::Pgs),
                Just(LcpSolverKind::Enumeration),
            ],
            x(),
            n(),
            ox(),
        )
            .prop_map(|(kind, tolerance, max_iterations, accept_error)| {
                ContactSolverSpec {
                    kind,
                    tolerance,
                    max_iterations,
                    accept_error,
                }
            });
        let output = (
            any::<u64>(),
            vec(n(), 0..4),
            ox(),
            proptest::option::of(any::<u64>()),
        )
            .prop_map(
                |(every, probes, checkpoint_seconds, checkpoint_steps)| OutputSpec {
                    every,
                    probes,
                    checkpoint_seconds,
                    checkpoint_steps,
                    contacts: false,
                    vtk: false,
                },
            );
        (
            of("[a-z _-]{0,12}"),
            of(model()),
            integrator(),
            of(time),
            contact_solver,
            output,
            of(analysis()),
        )
            .prop_map(
                |(name, model, integrator, time, contact_solver, output, analysis)| JobSpec {
                    schema: None,
                    name,
                    model,
                    integrator,
                    time,
                    contact_solver,
                    output,
                    analysis,
                    // Not carried by the typed message (read by `signorini check` only).
                    check: None,
                    study: None,
                },
            )
    }
}

/// to_proto → encode → decode → job_spec gives back the spec, for 512 random specs (with a
/// large stack: the strategy of the whole spec is a deep value in a debug build).
#[test]
fn random_specs_round_trip_through_the_typed_proto() {
    use proptest::test_runner::{Config, TestRunner};
    std::thread::Builder::new()
        .stack_size(256 << 20)
        .spawn(|| {
            let mut runner = TestRunner::new(Config::with_cases(512));
            runner
                .run(&random::job_spec(), |spec| {
                    proptest::prop_assert_eq!(round_trip(&spec), spec);
                    Ok(())
                })
                .unwrap_or_else(|e| panic!("{e}"));
        })
        .expect("spawning the property test")
        .join()
        .expect("the property holds");
}

#[test]
fn json_only_sections_are_named_not_converted() {
    let json_only = |text: &str| {
        let spec = parse(text, Format::Toml).unwrap_or_else(|e| panic!("{text}: {e}"));
        job_spec_to_proto(&spec).expect_err("JSON only").to_string()
    };
    let ball = "[model]\nscene = \"bouncing_ball\"\n[time]\nh = 0.01\nsteps = 10\n";
    assert!(job_spec_to_proto(&parse(ball, Format::Toml).expect("ball")).is_ok());
    let e = json_only(&format!("{ball}[check]\nmax_balance_residual = 1e-12\n"));
    assert!(e.starts_with("[check] has no typed proto message"), "{e}");
    let e = json_only(
        "[model]\nscene = \"lagrangian\"\ncoordinates = [\"x\"]\nmass = [[1.0]]\nq0 = [0.0]\n[time]\nh = 0.01\nsteps = 1\n",
    );
    assert!(e.starts_with("scene `lagrangian`"), "{e}");
}
