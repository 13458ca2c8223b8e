//! User models (`scene = "lagrangian"`): the pendulum (16) written in the model language runs
//! the built-in scene's trajectory under the SOI2 schemes, every Jacobian the language produces
//! matches central differences on random points of every example model, and every bad input is
//! refused with its field named.

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use serde_json::{Value, json};
use signorini_core::job::{Job, run};
use signorini_core::lagrangian::UserModel;
use signorini_core::nonlinear::LagrangianSystem;
use signorini_core::observer::Recorder;
use signorini_core::soi2::ConstrainedModel;
use signorini_core::spec::{JobSpec, LagrangianSpec, ModelSpec};
use std::path::{Path, PathBuf};

mod random;
use random::Random;

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples")
}

fn example(name: &str) -> JobSpec {
    let text = std::fs::read_to_string(examples().join(format!("{name}.toml"))).expect("example");
    toml::from_str(&text).expect("example parses")
}

/// Every example whose scene is `lagrangian`, by file name.
fn lagrangian_examples() -> Vec<(String, LagrangianSpec)> {
    let mut files: Vec<_> = std::fs::read_dir(examples())
        .expect("examples/")
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    files
        .iter()
        .filter_map(|p| {
            let s: JobSpec = toml::from_str(&std::fs::read_to_string(p).expect("read"))
                .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            match s.model {
                Some(ModelSpec::Lagrangian(l)) => Some((p.display().to_string(), l)),
                _ => None,
            }
        })
        .collect()
}

fn recorded(spec: &JobSpec) -> Recorder {
    let job = Job::from_spec(spec).expect("valid");
    let mut rec = Recorder::default();
    run(&job, 1, &mut rec).expect("runs");
    rec
}

/// The pendulum example with the built-in `pendulum` scene in its place: the same parameters
/// and the same initial values (the y0, z0 overrides).
fn builtin_twin(spec: &JobSpec) -> JobSpec {
    let Some(ModelSpec::Lagrangian(l)) = &spec.model else {
        panic!("a lagrangian example")
    };
    let p = |name: &str| match l.parameters[name] {
        signorini_core::expr::Param::Value(v) => v,
        signorini_core::expr::Param::Expr(_) => panic!("a number"),
    };
    let v0 = l.v0.clone().expect("v0");
    let mut twin: Value = serde_json::to_value(spec).expect("serializes");
    twin["model"] = json!({
        "scene": "pendulum",
        "mass": p("m"), "length": p("L"), "stiffness": p("k"), "damping": p("c"),
        "gravity": p("g"), "theta0": l.q0[2], "omega0": v0[2],
        "y0": l.q0, "z0": v0,
    });
    serde_json::from_value(twin).expect("twin spec")
}

/// The pendulum (16) as a `lagrangian` model against the built-in scene, with each SOI2 scheme:
/// every recorded value of the trajectory, the energies, the works and the multipliers agree to
/// 1e-10 relative to the column's largest magnitude (the residual columns are round-off on both
/// sides and Newton's iteration counts are compared in total).
#[test]
fn pendulum_written_as_a_lagrangian_model_runs_the_builtin_trajectory() {
    let base = example("pendulum_lagrangian");
    for scheme in [
        json!({"scheme": "soi2_generalized_alpha", "rho_inf": 0.2, "newton_tolerance": 1e-10}),
        json!({"scheme": "soi2_hht", "alpha": -0.2, "newton_tolerance": 1e-10}),
        json!({"scheme": "hht_i3", "alpha": -0.1, "newton_tolerance": 1e-10}),
    ] {
        let mut v = serde_json::to_value(&base).expect("serializes");
        v["integrator"] = scheme.clone();
        v["output"] = json!({"every": 1, "probes": [0, 1, 2]});
        let user: JobSpec = serde_json::from_value(v).expect("spec");
        let builtin = builtin_twin(&user);
        let (a, b) = (recorded(&user), recorded(&builtin));
        // The same columns, but the probes: q_j, v_j for the lagrangian model (its names under
        // every scheme), y_j, z_j (the paper's) for the built-in scene.
        let builtin_name = |name: &str| {
            if let Some(j) = name.strip_prefix("q_") {
                format!("y_{j}")
            } else if let Some(j) = name.strip_prefix("v_") {
                format!("z_{j}")
            } else {
                name.to_string()
            }
        };
        let renamed: Vec<String> = a.columns.names().iter().map(|n| builtin_name(n)).collect();
        assert_eq!(renamed, b.columns.names());
        assert_eq!(a.steps, b.steps);
        assert!(a.steps.len() > 1000, "{scheme}: every step recorded");
        for name in a.columns.names() {
            if name.ends_with("_residual") || name == "newton_iterations" {
                continue;
            }
            let (ca, cb) = (
                a.column(name).expect("col"),
                b.column(&builtin_name(name)).expect("col"),
            );
            let scale = cb.iter().fold(0.0_f64, |m, x| m.max(x.abs())).max(1e-300);
            for (k, (x, y)) in ca.iter().zip(&cb).enumerate() {
                assert!(
                    (x - y).abs() <= 1e-10 * scale,
                    "{scheme}: {name} at record {k}: {x} vs {y} (scale {scale})"
                );
            }
        }
        let iterations = |r: &Recorder| {
            r.column("newton_iterations")
                .expect("col")
                .iter()
                .sum::<f64>()
        };
        assert_eq!(iterations(&a), iterations(&b), "{scheme}");
    }
}

/// Central difference of `f` (m outputs) along `dir`: (f(x + εd) − f(x − εd)) / 2ε.
fn central(m: usize, eps: f64, f: &mut dyn FnMut(f64, &mut [f64])) -> Vec<f64> {
    let (mut plus, mut minus) = (vec![0.0; m], vec![0.0; m]);
    f(eps, &mut plus);
    f(-eps, &mut minus);
    plus.iter()
        .zip(&minus)
        .map(|(p, q)| (p - q) / (2.0 * eps))
        .collect()
}

/// `exact` against `fd` (same layout): max error ≤ 1e-7 relative to the larger max-norm (1 at
/// least, for Jacobians that are exactly zero).
fn assert_close(what: &str, model: &str, exact: &[f64], fd: &[f64]) {
    let norm = |v: &[f64]| v.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    let scale = norm(exact).max(norm(fd)).max(1.0);
    let err = exact
        .iter()
        .zip(fd)
        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(
        err <= 1e-7 * scale,
        "{model}: {what}: error {err:e} (scale {scale:e})\nexact {exact:?}\nfd    {fd:?}"
    );
}

/// Every Jacobian of every example model (∂F/∂q, ∂F/∂q̇, the Coriolis vector from M, g_y and
/// g_t + g_y q̇ of the joints, the gap Jacobian and ∂g/∂t) against central differences at random
/// points near (q0, v0).
#[test]
fn every_jacobian_matches_central_differences_on_every_example() {
    let models = lagrangian_examples();
    assert!(
        models.len() >= 2,
        "{:?}",
        models.iter().map(|m| &m.0).collect::<Vec<_>>()
    );
    let mut rng = Random(0x9e37_79b9_7f4a_7c15);
    for (name, spec) in &models {
        let model = UserModel::new(spec.validate().unwrap_or_else(|e| panic!("{name}: {e}")));
        let n = LagrangianSystem::dofs(&model);
        let (m, joints) = (model.contacts(), model.joints());
        let eps = 1e-6;
        for _ in 0..5 {
            let (q0, v0) = LagrangianSystem::initial(&model);
            let q: Vec<f64> = q0.iter().map(|x| x + 0.1 * rng.next()).collect();
            let v: Vec<f64> = v0.iter().map(|x| x + rng.next()).collect();
            let t = rng.next().abs();
            let shifted = |x: &[f64], k: usize, s: f64| {
                let mut y = x.to_vec();
                y[k] += s;
                y
            };
            // ∂F/∂q, ∂F/∂v, column by column.
            let (mut dq, mut dv) = (vec![0.0; n * n], vec![0.0; n * n]);
            model.force_jacobians(t, &q, &v, &mut dq, &mut dv);
            let (mut fdq, mut fdv) = (vec![0.0; n * n], vec![0.0; n * n]);
            for k in 0..n {
                let col = central(n, eps, &mut |s, out| {
                    model.forces(t, &shifted(&q, k, s), &v, out)
                });
                let colv = central(n, eps, &mut |s, out| {
                    model.forces(t, &q, &shifted(&v, k, s), out)
                });
                for i in 0..n {
                    fdq[i * n + k] = col[i];
                    fdv[i * n + k] = colv[i];
                }
            }
            assert_close("dF/dq", name, &dq, &fdq);
            assert_close("dF/dv", name, &dv, &fdv);
            // Coriolis: Ṁv − ½∇(vᵀMv) from differences of M.
            let mut c = vec![0.0; n];
            model.coriolis(&q, &v, &mut c);
            let mdot = central(n * n, eps, &mut |s, out| {
                let qs: Vec<f64> = q.iter().zip(&v).map(|(x, w)| x + s * w).collect();
                LagrangianSystem::mass(&model, &qs, out)
            });
            let quad = |mm: &[f64]| -> f64 {
                (0..n)
                    .flat_map(|i| (0..n).map(move |j| (i, j)))
                    .map(|(i, j)| v[i] * mm[i * n + j] * v[j])
                    .sum()
            };
            let fd_c: Vec<f64> = (0..n)
                .map(|i| {
                    let mdot_v: f64 = (0..n).map(|j| mdot[i * n + j] * v[j]).sum();
                    let grad = central(1, eps, &mut |s, out| {
                        let mut mm = vec![0.0; n * n];
                        LagrangianSystem::mass(&model, &shifted(&q, i, s), &mut mm);
                        out[0] = quad(&mm);
                    })[0];
                    mdot_v - 0.5 * grad
                })
                .collect();
            assert_close("Coriolis", name, &c, &fd_c);
            // Joints: g_y and g_t + g_y v.
            let mut gy = vec![0.0; joints * n];
            ConstrainedModel::g_y(&model, t, &q, &mut gy);
            let mut fd_gy = vec![0.0; joints * n];
            for k in 0..n {
                let col = central(joints, eps, &mut |s, out| {
                    ConstrainedModel::g(&model, t, &shifted(&q, k, s), out)
                });
                for r in 0..joints {
                    fd_gy[r * n + k] = col[r];
                }
            }
            assert_close("g_y", name, &gy, &fd_gy);
            let mut gdot = vec![0.0; joints];
            ConstrainedModel::g_dot(&model, t, &q, &v, &mut gdot);
            let fd_gdot = central(joints, eps, &mut |s, out| {
                let qs: Vec<f64> = q.iter().zip(&v).map(|(x, w)| x + s * w).collect();
                ConstrainedModel::g(&model, t + s, &qs, out)
            });
            assert_close("g_t + g_y v", name, &gdot, &fd_gdot);
            // Gaps: ∇g and ∂g/∂t.
            let mut gj = vec![0.0; m * n];
            model.gap_jacobian(t, &q, &mut gj);
            let mut fd_gj = vec![0.0; m * n];
            for k in 0..n {
                let col = central(m, eps, &mut |s, out| model.gaps(t, &shifted(&q, k, s), out));
                for r in 0..m {
                    fd_gj[r * n + k] = col[r];
                }
            }
            assert_close("gap Jacobian", name, &gj, &fd_gj);
            let mut rates = vec![0.0; m];
            model.gap_rates(t, &q, &mut rates);
            let fd_rates = central(m, eps, &mut |s, out| model.gaps(t + s, &q, out));
            assert_close("dg/dt", name, &rates, &fd_rates);
        }
    }
}

/// A small valid model (a block on a floor with a joint keeping x = 0.1·phi, and one contact):
/// the base the bad-input cases modify.
fn base() -> Value {
    json!({
        "model": {
            "scene": "lagrangian",
            "coordinates": ["x", "y", "phi"],
            "parameters": {"m": 1.0, "w": 0.2, "hgt": 0.4, "g": 9.81, "I": "m*(w^2+hgt^2)/12"},
            "mass": [["m", 0, 0], [0, "m", 0], [0, 0, "I"]],
            "potential": "m*g*y",
            "forces": ["0", "0", "-0.01*phi_dot"],
            "q0": [0.0, 0.2, 0.0],
            "v0": [0.1, 0.0, 1.0],
            "constraints": [{"expr": "x - 0.1*phi"}],
            "contacts": [{"gap": "y - hgt/2*cos(phi) - w/2*sin(phi)", "restitution": 0.5}]
        },
        "integrator": {"scheme": "soi2_generalized_alpha"},
        "time": {"h": 0.001, "t_end": 0.01}
    })
}

fn refused(spec: Value) -> signorini_core::spec::SpecError {
    let s: JobSpec = serde_json::from_value(spec).expect("the spec parses");
    Job::from_spec(&s).expect_err("must be refused")
}

/// Item 2 of the issue, case by case: the field named and the reason.
#[test]
fn bad_models_are_refused_with_the_field_named() {
    type Edit = fn(&mut Value);
    let cases: Vec<(&str, Edit, &str, &str)> = vec![
        (
            "unknown name",
            |s| s["model"]["contacts"][0]["gap"] = json!("y - hgh/2"),
            "model.contacts[0].gap",
            "unknown name 'hgh' at 4 (did you mean 'hgt'?)",
        ),
        (
            "unknown function",
            |s| s["model"]["forces"][2] = json!("-0.01*sni(phi)"),
            "model.forces[2]",
            "did you mean 'sin'?",
        ),
        (
            "syntax",
            |s| s["model"]["potential"] = json!("m*g*(y"),
            "model.potential",
            "never closed",
        ),
        (
            "mass rows",
            |s| s["model"]["mass"] = json!([["m", 0, 0], [0, "m", 0]]),
            "model.mass",
            "needs 3 rows",
        ),
        (
            "mass columns",
            |s| s["model"]["mass"][1] = json!([0, "m"]),
            "model.mass[1]",
            "needs 3 entries",
        ),
        (
            "q0 size",
            |s| s["model"]["q0"] = json!([0.0, 0.2]),
            "model.q0",
            "needs 3 entries",
        ),
        (
            "v0 size",
            |s| s["model"]["v0"] = json!([0.0]),
            "model.v0",
            "needs 3 entries",
        ),
        (
            "forces size",
            |s| s["model"]["forces"] = json!(["0"]),
            "model.forces",
            "needs 3 entries",
        ),
        (
            "not symmetric",
            |s| {
                s["model"]["mass"][0][1] = json!("0.1*m");
                s["model"]["mass"][1][0] = json!("0.2*m");
            },
            "model.mass[1][0]",
            "not symmetric",
        ),
        (
            "not positive definite",
            |s| s["model"]["mass"][2][2] = json!("-I"),
            "model.mass",
            "not positive definite",
        ),
        (
            "singular mass",
            |s| s["model"]["mass"][0][0] = json!("m*x"),
            "model.mass",
            "not positive definite",
        ),
        (
            "mass uses a velocity",
            |s| s["model"]["mass"][0][0] = json!("m + x_dot"),
            "model.mass[0][0]",
            "velocity 'x_dot'",
        ),
        (
            "mass uses t",
            |s| s["model"]["mass"][0][0] = json!("m*(1 + t)"),
            "model.mass[0][0]",
            "uses the time t",
        ),
        (
            "gap uses a velocity",
            |s| s["model"]["contacts"][0]["gap"] = json!("y - y_dot"),
            "model.contacts[0].gap",
            "velocity 'y_dot'",
        ),
        (
            "NaN at q0",
            |s| s["model"]["potential"] = json!("m*g*log(y - 1)"),
            "model.potential",
            "NaN at q0",
        ),
        (
            "infinite at q0",
            |s| s["model"]["forces"][0] = json!("1/x"),
            "model.forces[0]",
            "inf at q0",
        ),
        (
            "joint violated",
            |s| s["model"]["constraints"][0]["expr"] = json!("x - 0.1*phi - 1e-3"),
            "model.constraints[0].expr",
            "violated at q0",
        ),
        (
            "friction without tangent",
            |s| s["model"]["contacts"][0]["friction"] = json!(0.5),
            "model.contacts[0].friction",
            "needs a `tangent`",
        ),
        (
            "negative friction",
            |s| {
                s["model"]["contacts"][0]["friction"] = json!(-0.5);
                s["model"]["contacts"][0]["tangent"] = json!("x");
            },
            "model.contacts[0].friction",
            "finite number ≥ 0",
        ),
        (
            "tangent NaN at q0",
            |s| {
                s["model"]["contacts"][0]["friction"] = json!(0.5);
                s["model"]["contacts"][0]["tangent"] = json!("log(-1 - y)");
            },
            "model.contacts[0].tangent",
            "NaN at q0",
        ),
        (
            "tangent uses a velocity",
            |s| s["model"]["contacts"][0]["tangent"] = json!("x + x_dot"),
            "model.contacts[0].tangent",
            "velocity 'x_dot'",
        ),
        (
            "bad tangent",
            |s| s["model"]["contacts"][0]["tangent"] = json!("xx"),
            "model.contacts[0].tangent",
            "unknown name 'xx'",
        ),
        (
            "restitution",
            |s| s["model"]["contacts"][0]["restitution"] = json!(1.5),
            "model.contacts[0].restitution",
            "[0, 1]",
        ),
        (
            "duplicate coordinates",
            |s| s["model"]["coordinates"] = json!(["x", "x", "phi"]),
            "model.coordinates",
            "clashes with coordinate 'x'",
        ),
        (
            "no coordinates",
            |s| s["model"]["coordinates"] = json!([]),
            "model.coordinates",
            "at least one",
        ),
        (
            "coordinate named like a velocity",
            |s| s["model"]["coordinates"] = json!(["x", "x_dot", "phi"]),
            "model.coordinates",
            "clashes",
        ),
        (
            "parameter cycle",
            |s| {
                s["model"]["parameters"]["a"] = json!("b + 1");
                s["model"]["parameters"]["b"] = json!("2*a");
            },
            "model.parameters.a",
            "cycle: a -> b -> a",
        ),
        (
            "parameter shadows a coordinate",
            |s| s["model"]["parameters"]["phi"] = json!(1.0),
            "model.parameters.phi",
            "clashes with coordinate 'phi'",
        ),
        (
            "parameter shadows a function",
            |s| s["model"]["parameters"]["sin"] = json!(1.0),
            "model.parameters.sin",
            "the function sin",
        ),
        (
            "parameter uses a coordinate",
            |s| s["model"]["parameters"]["I"] = json!("m*x"),
            "model.parameters.I",
            "uses the variable 'x'",
        ),
        (
            "parameter unknown name",
            |s| s["model"]["parameters"]["I"] = json!("m*ww^2"),
            "model.parameters.I",
            "unknown name 'ww' at 2",
        ),
        (
            "velocities violate a joint",
            |s| {
                s["model"]["contacts"] = json!([]);
                s["model"]["v0"] = json!([0.0, 0.0, 1.0]);
            },
            "model.v0",
            "velocity constraint residual",
        ),
        (
            "dependent joints",
            |s| {
                s["model"]["contacts"] = json!([]);
                s["model"]["constraints"] =
                    json!([{"expr": "x - 0.1*phi"}, {"expr": "2*x - 0.2*phi"}]);
            },
            "model.constraints",
            "singular constraint Jacobian",
        ),
        (
            "contacts under SOI2",
            |_| {},
            "integrator.scheme",
            "moreau_jean",
        ),
        (
            "a linear scheme",
            |s| {
                s["model"]["contacts"] = json!([]);
                s["integrator"] = json!({"scheme": "ns_hht", "alpha": -0.1});
            },
            "integrator.scheme",
            "scene `lagrangian` runs with",
        ),
    ];
    for (what, edit, field, reason) in cases {
        let mut s = base();
        edit(&mut s);
        let e = refused(s);
        assert_eq!(e.field, field, "{what}: {e}");
        assert!(e.reason.contains(reason), "{what}: {e}");
    }
    // Joints and a rough contact together are a moreau_jean job (their friction problem has
    // the joint rows condensed out); this case was refused before that was built.
    let mut s = base();
    s["integrator"] = json!({"scheme": "moreau_jean"});
    s["model"]["contacts"][0]["friction"] = json!(0.3);
    s["model"]["contacts"][0]["tangent"] = json!("x");
    let spec: JobSpec = serde_json::from_value(s).expect("spec");
    Job::from_spec(&spec).expect("joints and friction under moreau_jean");
    // The base without its contact is a valid SOI2 job.
    let mut s = base();
    s["model"]["contacts"] = json!([]);
    s["integrator"] = json!({"scheme": "soi2_generalized_alpha"});
    let spec: JobSpec = serde_json::from_value(s).expect("spec");
    Job::from_spec(&spec).expect("valid");
}

/// The double pendulum in Cartesian coordinates: no applied forces, so the energy changes only
/// by the scheme's numerical dissipation; the rods keep their lengths.
#[test]
fn double_pendulum_keeps_its_joints_and_nearly_its_energy() {
    let mut spec = example("double_pendulum_cartesian");
    spec.time.as_mut().expect("time").t_end = Some(1.0);
    let rec = recorded(&spec);
    let e = rec.column("energy").expect("energy");
    let drift = e.iter().fold(0.0_f64, |m, x| m.max((x - e[0]).abs()));
    // m g L = 9.81: the energy scale.
    assert!(drift < 1e-3 * 9.81, "energy drift {drift}");
    for c in ["position_residual", "velocity_residual"] {
        let r = rec.column(c).expect(c);
        assert!(r.iter().all(|x| *x < 1e-9), "{c}: {r:?}");
    }
}

/// `energy_error` = E(t) − E(0) − Σ work_ext on a conservative model (the double pendulum) shrinks
/// as h² under the second-order generalized-α-SOI2 without dissipation (ρ∞ = 1): the observed
/// order over h and h/2, from the largest |energy_error| over t ∈ [0, 0.5].
#[test]
fn energy_error_of_a_conservative_model_shrinks_as_h_squared() {
    let error = |h: f64| {
        let mut v = serde_json::to_value(example("double_pendulum_cartesian")).expect("json");
        v["integrator"] =
            json!({"scheme": "soi2_generalized_alpha", "rho_inf": 1.0, "newton_tolerance": 1e-12});
        v["time"] = json!({"h": h, "t_end": 0.5});
        v["output"] = json!({"every": 1});
        let rec = recorded(&serde_json::from_value(v).expect("spec"));
        let w = rec.column("work_ext").expect("work_ext");
        assert!(w.iter().all(|x| *x == 0.0), "no applied force");
        rec.column("energy_error")
            .expect("energy_error")
            .iter()
            .fold(0.0_f64, |m, x| m.max(x.abs()))
    };
    let (e1, e2) = (error(4e-3), error(2e-3));
    let order = (e1 / e2).log2();
    println!("energy_error: {e1:e} at h = 4e-3, {e2:e} at h = 2e-3, order {order:.2}");
    assert!((1.8..2.3).contains(&order), "order {order}");
}

/// A pendulum on a cart, M(q) = [[M + m, m L cos θ], [m L cos θ, m L²]], no joints: the Coriolis
/// vector the program derives from M is the one that conserves the energy — `energy_error`
/// shrinks as h² (a wrong sign or factor in c would leave an O(1) drift), and the momentum of
/// the cart–pendulum along x, (M + m) ẋ + m L cos θ θ̇ (x is cyclic), drifts only by the
/// scheme's O(h²) error.
#[test]
fn coriolis_forces_from_a_configuration_dependent_mass_conserve_energy_and_momentum() {
    let run_with = |h: f64| {
        let spec = json!({
            "model": {
                "scene": "lagrangian",
                "coordinates": ["x", "th"],
                "parameters": {"M": 2.0, "m": 0.5, "L": 0.8, "g": 9.81},
                "mass": [["M + m", "m*L*cos(th)"], ["m*L*cos(th)", "m*L^2"]],
                "potential": "-m*g*L*cos(th)",
                "q0": [0.0, 1.2],
                "v0": [0.3, -0.5]
            },
            "integrator": {"scheme": "soi2_generalized_alpha", "rho_inf": 1.0, "newton_tolerance": 1e-12},
            "time": {"h": h, "t_end": 1.0},
            "output": {"every": 1, "probes": [0, 1]}
        });
        recorded(&serde_json::from_value(spec).expect("spec"))
    };
    let max_abs = |v: &[f64]| v.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    let (a, b) = (run_with(1e-2), run_with(5e-3));
    let (e1, e2) = (
        max_abs(&a.column("energy_error").expect("col")),
        max_abs(&b.column("energy_error").expect("col")),
    );
    let order = (e1 / e2).log2();
    assert!(
        (1.8..2.3).contains(&order),
        "energy_error {e1:e}, {e2:e}: order {order}"
    );
    let drift = |r: &Recorder| {
        let (th, xd, thd) = (
            r.column("q_1").expect("θ"),
            r.column("v_0").expect("ẋ"),
            r.column("v_1").expect("θ̇"),
        );
        let p: Vec<f64> = (0..th.len())
            .map(|k| 2.5 * xd[k] + 0.5 * 0.8 * th[k].cos() * thd[k])
            .collect();
        p.iter().fold(0.0_f64, |m, x| m.max((x - p[0]).abs()))
    };
    let (d1, d2) = (drift(&a), drift(&b));
    let order = (d1 / d2).log2();
    assert!(
        (1.8..2.3).contains(&order),
        "momentum drift {d1:e}, {d2:e}: order {order}"
    );
}

/// A force that turns NaN during the run (sqrt(0.5 − t) past t = 0.5) fails the job with the
/// step and its time, without a panic or a hang.
#[test]
fn a_nan_during_the_run_fails_the_job_with_step_and_time() {
    let mut v = serde_json::to_value(example("pendulum_lagrangian")).expect("json");
    v["model"]["forces"][2] = json!("-c*theta_dot*sqrt(0.5 - t)");
    v["time"] = json!({"h": 0.01, "t_end": 1.0});
    let spec: JobSpec = serde_json::from_value(v).expect("spec");
    let job = Job::from_spec(&spec).expect("valid at t = 0");
    let err = run(&job, 1, &mut Recorder::default()).expect_err("NaN past t = 0.5");
    let msg = err.to_string();
    // t₅₀ = 0.5 + round-off: the first step whose force is NaN.
    assert!(
        msg.contains("step 50 (t = 0.5") && msg.contains("NaN"),
        "{msg}"
    );
}

/// The validated start of a `lagrangian` spec.
fn validated(spec: &Value) -> signorini_core::lagrangian::UserModelParams {
    let s: JobSpec = serde_json::from_value(spec.clone()).expect("the spec parses");
    let Some(ModelSpec::Lagrangian(l)) = s.model else {
        panic!("a lagrangian model")
    };
    l.validate().expect("valid")
}

/// Issue 30, item 3: `q0` and `v0` may be expressions of the parameters, evaluated at
/// validation to the values f64 arithmetic gives them; an entry that does not parse, uses a
/// coordinate or is not finite is refused naming `model.q0[i]` / `model.v0[i]`, and a value
/// of neither type says what it got.
#[test]
fn start_values_may_be_expressions_of_the_parameters() {
    let mut s = base();
    s["model"]["contacts"] = json!([]);
    s["model"]["q0"] = json!(["0.1*pi/3", "w + hgt/2", "pi/3"]);
    s["model"]["v0"] = json!(["0.1*sqrt(g)", 0, "sqrt(g)"]);
    let p = validated(&s);
    let pi = std::f64::consts::PI;
    assert_eq!(p.q0, vec![0.1 * pi / 3.0, 0.2 + 0.4 / 2.0, pi / 3.0]);
    assert_eq!(p.v0, vec![0.1 * 9.81_f64.sqrt(), 0.0, 9.81_f64.sqrt()]);
    assert!(p.projection.is_none());

    type Edit = fn(&mut Value);
    let cases: Vec<(Edit, &str, &str)> = vec![
        (
            |s| s["model"]["q0"][1] = json!("hgh/2"),
            "model.q0[1]",
            "unknown name 'hgh'",
        ),
        (
            |s| s["model"]["q0"][0] = json!("0.1*phi"),
            "model.q0[0]",
            "uses 'phi'",
        ),
        (
            |s| s["model"]["v0"][2] = json!("sqrt(-g)"),
            "model.v0[2]",
            "must be finite, got NaN",
        ),
    ];
    for (edit, field, reason) in cases {
        let mut s = base();
        edit(&mut s);
        let e = refused(s);
        assert_eq!(e.field, field, "{e}");
        assert!(e.reason.contains(reason), "{e}");
    }
    let mut s = base();
    s["model"]["q0"][1] = json!(true);
    let e = serde_json::from_value::<JobSpec>(s).expect_err("a boolean is no start value");
    assert!(
        e.to_string()
            .contains("invalid type: boolean `true`, expected a number or an expression"),
        "{e}"
    );
}

/// Issue 30, item 3: with `project_onto_joints` a start off the joints is moved onto them, by
/// the least change in the M norm. For the linear joint a·q = x − 0.1φ = 0 of the base model,
/// M = diag(m, m, I) with I = m (w² + hgt²)/12 (radians and metres weighed differently), the
/// projection is the closed form q0 − M⁻¹a (a·q0)/(a M⁻¹ aᵀ), reached in one iteration, and v0
/// moves by −M⁻¹a (a·v0)/(a M⁻¹ aᵀ); the M norm of the position change is |a·q0|/√(a M⁻¹ aᵀ).
/// (The Euclidean projection, q0 − a (a·q0)/(a·a), moves x by 0.0495 and φ by 0.00495; this one
/// moves x by 0.03125 and φ by 0.1875.) The run starts there and its summary reports it. A joint
/// without a solution (x² + y² + 1 = 0) is refused naming it.
#[test]
fn a_start_off_the_joints_is_projected_onto_them() {
    let mut s = base();
    s["model"]["contacts"] = json!([]);
    s["model"]["q0"] = json!([0.05, 0.2, 0.0]);
    s["model"]["v0"] = json!([0.3, 0.0, 1.0]);
    let e = refused(s.clone());
    assert_eq!(e.field, "model.constraints[0].expr", "{e}");
    assert!(e.reason.contains("project_onto_joints"), "{e}");

    s["model"]["project_onto_joints"] = json!(true);
    let p = validated(&s);
    let a = [1.0, 0.0, -0.1];
    let inertia = 1.0 * (0.2_f64.powi(2) + 0.4_f64.powi(2)) / 12.0;
    let mass = [1.0, 1.0, inertia];
    let minv_a: Vec<f64> = (0..3).map(|i| a[i] / mass[i]).collect();
    let a_minv_a: f64 = (0..3).map(|i| a[i] * minv_a[i]).sum();
    assert!((a_minv_a - 1.6).abs() < 1e-14, "{a_minv_a}");
    let (q_given, v_given) = ([0.05, 0.2, 0.0], [0.3, 0.0, 1.0]);
    let (ga, va) = (0.05 / a_minv_a, (0.3 - 0.1) / a_minv_a);
    for i in 0..3 {
        assert!(
            (p.q0[i] - (q_given[i] - minv_a[i] * ga)).abs() < 1e-15,
            "{:?}",
            p.q0
        );
        assert!(
            (p.v0[i] - (v_given[i] - minv_a[i] * va)).abs() < 1e-15,
            "{:?}",
            p.v0
        );
    }
    assert!((p.q0[0] - 0.01875).abs() < 1e-15 && (p.q0[2] - 0.1875).abs() < 1e-15);
    let report = p.projection.clone().expect("a projection");
    assert_eq!(report.newton_iterations, 1);
    assert_eq!(report.q0_given, q_given.to_vec());
    assert_eq!(report.v0_given, v_given.to_vec());
    assert_eq!(report.q0, p.q0);
    assert!((report.joint_residual_given - 0.05).abs() < 1e-15);
    assert!(report.joint_residual < 1e-16, "{report:?}");
    let euclidean = (0.03125_f64.powi(2) + 0.1875_f64.powi(2)).sqrt();
    assert!(
        (report.position_change - euclidean).abs() < 1e-15,
        "{report:?}"
    );
    assert!(
        (report.position_change_mass_norm - 0.05 / a_minv_a.sqrt()).abs() < 1e-15,
        "{report:?}"
    );
    assert!(
        (report.velocity_change_mass_norm - 0.2 / a_minv_a.sqrt()).abs() < 1e-15,
        "{report:?}"
    );

    let spec: JobSpec = serde_json::from_value(s.clone()).expect("spec");
    let job = Job::from_spec(&spec).expect("projected start runs");
    assert_eq!(job.start_projection(), Some(&report));
    let out = run(&job, 1, &mut Recorder::default()).expect("runs");
    let summary = out.summary.to_map();
    assert_eq!(
        summary["start_projection"]["q0"],
        json!(p.q0),
        "{summary:?}"
    );
    assert_eq!(summary["start_projection"]["newton_iterations"], json!(1));

    let mut s = s;
    s["model"]["constraints"] = json!([{"expr": "x^2 + y^2 + 1"}]);
    let e = refused(s);
    assert_eq!(e.field, "model.constraints[0].expr", "{e}");
    assert!(e.reason.contains("could not be projected"), "{e}");
}

/// |M d − G(q)ᵀ λ|∞ / |M d|∞ for the best λ: how far the change d is from satisfying the
/// stationarity condition of the M-norm projection onto the double pendulum's rods at q,
/// M = diag(m1, m1, m2, m2), rows G₁ = (x1, y1, 0, 0), G₂ = (−Δx, −Δy, Δx, Δy). The lower rod's
/// λ₂ comes from the entries of the second mass, the upper rod's λ₁ from the first's.
fn rods_stationarity(m: [f64; 2], q: &[f64], d: &[f64]) -> f64 {
    let md = [m[0] * d[0], m[0] * d[1], m[1] * d[2], m[1] * d[3]];
    let (x1, y1, dx, dy) = (q[0], q[1], q[2] - q[0], q[3] - q[1]);
    let lambda2 = (md[2] * dx + md[3] * dy) / (dx * dx + dy * dy);
    let lambda1 = ((md[0] + lambda2 * dx) * x1 + (md[1] + lambda2 * dy) * y1) / (x1 * x1 + y1 * y1);
    let gt_lambda = [
        lambda1 * x1 - lambda2 * dx,
        lambda1 * y1 - lambda2 * dy,
        lambda2 * dx,
        lambda2 * dy,
    ];
    let scale = md.iter().fold(0.0_f64, |a, x| a.max(x.abs()));
    (0..4).fold(0.0_f64, |a, i| a.max((md[i] - gt_lambda[i]).abs())) / scale
}

/// The double pendulum's rods (quadratic joints), masses m1 = 1 and m2 = 4, from a start 0.1
/// off both: the iteration brings both within 1e-12, and the start it returns is the nearest in
/// the M norm: M(q* − q0) = g_q(q*)ᵀ λ to 1e-12 (the stationarity condition; the
/// Euclidean projection's point misses it by 5.6e-2), and every neighbour on the rods, the rods' angles moved
/// by ±1e-3, is farther. v0 lands on the tangent space with M(v* − v0) = g_qᵀ P, and a SOI2 run
/// from there keeps the rods.
#[test]
fn a_double_pendulum_started_off_its_rods_is_projected_by_newton() {
    let mut s = serde_json::to_value(example("double_pendulum_cartesian")).expect("json");
    let m = [1.0, 4.0];
    s["model"]["parameters"]["m2"] = json!(m[1]);
    let (q_given, v_given) = ([1.1, 0.05, 2.0, -0.1], [0.0, 1.0, 0.0, 0.5]);
    s["model"]["q0"] = json!(q_given);
    s["model"]["v0"] = json!(v_given);
    s["model"]["project_onto_joints"] = json!(true);
    s["time"]["t_end"] = json!(0.5);
    let p = validated(&s);
    let [x1, y1, x2, y2] = [p.q0[0], p.q0[1], p.q0[2], p.q0[3]];
    assert!((x1 * x1 + y1 * y1 - 1.0).abs() < 1e-12, "{:?}", p.q0);
    assert!(((x2 - x1).powi(2) + (y2 - y1).powi(2) - 1.0).abs() < 1e-12);
    let [u1, w1, u2, w2] = [p.v0[0], p.v0[1], p.v0[2], p.v0[3]];
    assert!((x1 * u1 + y1 * w1).abs() < 1e-12, "{:?}", p.v0);
    assert!(((x2 - x1) * (u2 - u1) + (y2 - y1) * (w2 - w1)).abs() < 1e-12);

    let d: Vec<f64> = (0..4).map(|i| p.q0[i] - q_given[i]).collect();
    let stationarity = rods_stationarity(m, &p.q0, &d);
    assert!(stationarity < 1e-12, "{stationarity:e} at {:?}", p.q0);
    let dv: Vec<f64> = (0..4).map(|i| p.v0[i] - v_given[i]).collect();
    let impulsive = rods_stationarity(m, &p.q0, &dv);
    assert!(impulsive < 1e-12, "{impulsive:e}");

    let distance = |q: [f64; 4]| {
        (0..4)
            .map(|i| m[i / 2] * (q[i] - q_given[i]).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let best = distance([x1, y1, x2, y2]);
    let report = p.projection.expect("a projection");
    assert!(
        (report.position_change_mass_norm - best).abs() < 1e-15,
        "{report:?}"
    );
    let (a1, a2) = (y1.atan2(x1), (y2 - y1).atan2(x2 - x1));
    for (e1, e2) in [
        (1e-3, 0.0),
        (-1e-3, 0.0),
        (0.0, 1e-3),
        (0.0, -1e-3),
        (1e-3, -1e-3),
    ] {
        let (c1, c2) = (a1 + e1, a2 + e2);
        let neighbour = [c1.cos(), c1.sin(), c1.cos() + c2.cos(), c1.sin() + c2.sin()];
        assert!(
            distance(neighbour) > best,
            "({e1}, {e2}): {}",
            distance(neighbour)
        );
    }
    assert!(report.newton_iterations >= 2, "{report:?}");
    assert!(report.position_change < 0.2, "{report:?}");
    let spec: JobSpec = serde_json::from_value(s).expect("spec");
    let out = run(
        &Job::from_spec(&spec).expect("valid"),
        1,
        &mut Recorder::default(),
    )
    .expect("runs");
    let residual = out.summary.to_map()["max_position_residual"]
        .as_f64()
        .expect("residual");
    assert!(residual < 1e-10, "{residual:e}");
}

/// Issue 30, item 3: `tangent_velocity` gives the tangential velocity itself. The rocking
/// block's corners written with U_t = d/dt τ by hand run the trajectory of their `tangent`
/// τ (to 1e-9 of each column's largest value: the rows are the same functions, written
/// differently); a velocity that is not linear, uses no velocity, or comes with a `tangent` is
/// refused naming `model.contacts[i].tangent_velocity`.
#[test]
fn a_tangent_velocity_runs_as_its_tangent() {
    let mut by_position = serde_json::to_value(example("rocking_block_friction")).expect("json");
    by_position["time"]["t_end"] = json!(0.6);
    let mut by_velocity = by_position.clone();
    let contacts = &mut by_velocity["model"]["contacts"];
    for (i, u) in [
        "x_dot + (w/2*sin(phi) + hgt/2*cos(phi))*phi_dot",
        "x_dot + (hgt/2*cos(phi) - w/2*sin(phi))*phi_dot",
    ]
    .iter()
    .enumerate()
    {
        contacts[i]
            .as_object_mut()
            .expect("contact")
            .remove("tangent");
        contacts[i]["tangent_velocity"] = json!(u);
    }
    let a = recorded(&serde_json::from_value(by_position.clone()).expect("spec"));
    let b = recorded(&serde_json::from_value(by_velocity.clone()).expect("spec"));
    assert_eq!(a.columns, b.columns);
    assert_eq!(a.rows.len(), b.rows.len());
    for (c, name) in a.columns.names().iter().enumerate() {
        let scale = a.rows.iter().fold(1e-300_f64, |m, r| m.max(r[c].abs()));
        for (ra, rb) in a.rows.iter().zip(&b.rows) {
            assert!(
                (ra[c] - rb[c]).abs() <= 1e-9 * scale,
                "{name}: {} against {}",
                ra[c],
                rb[c]
            );
        }
    }
    let pt = a.column("pt_0").expect("pt_0");
    assert!(pt.iter().any(|p| p.abs() > 1e-3), "friction acts");

    for (u, reason) in [
        ("x_dot^2", "not linear in the velocities"),
        ("x*phi_dot*phi_dot", "not linear in the velocities"),
        ("x + phi", "uses no velocity"),
    ] {
        let mut s = by_velocity.clone();
        s["model"]["contacts"][1]["tangent_velocity"] = json!(u);
        let e = refused(s);
        assert_eq!(e.field, "model.contacts[1].tangent_velocity", "{u}: {e}");
        assert!(e.reason.contains(reason), "{u}: {e}");
    }
    let mut s = by_velocity;
    s["model"]["contacts"][0]["tangent"] = json!("x");
    let e = refused(s);
    assert_eq!(e.field, "model.contacts[0].tangent_velocity", "{e}");
    assert!(e.reason.contains("not both"), "{e}");
}
