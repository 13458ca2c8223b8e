//! Rigid-body scenes of issue 29 with many simultaneous contacts or a second model to agree
//! with: a tower of ten boxes standing still for 10 s, Newton's cradle (touching balls under
//! Moreau's simultaneous impact law, and the gapped cradle of `examples/rigid/newtons_cradle.toml`),
//! and a `rigid_bodies` ball that equals the same ball written as a `lagrangian` model step for
//! step.

use signorini_collision::ParryDetectors;
use signorini_core::job::{self, Job};
use signorini_core::observer::Recorder;
use signorini_core::rigid::{
    Body, BodyState, ContactDetector, ContactLaw, ContactPoint, DetectError, DetectorFactory, Pose,
    RigidMoreauJean, RigidMoreauJeanParams, RigidScene, RigidStepping, STALL_SWEEPS, Shape,
};
use signorini_core::spec::JobSpec;
use signorini_core::stepping::run;
use std::path::Path;

const G: f64 = 9.81;

fn at_rest(position: [f64; 3], velocity: [f64; 3]) -> BodyState {
    BodyState {
        position,
        orientation: [1.0, 0.0, 0.0, 0.0],
        velocity,
        angular_velocity: [0.0; 3],
    }
}

fn floor() -> (String, Body, BodyState) {
    (
        "floor".into(),
        Body {
            shape: Shape::HalfSpace {
                normal: [0.0, 0.0, 1.0],
            },
            mass: 0.0,
            inertia: [0.0; 3],
            fixed: true,
        },
        at_rest([0.0; 3], [0.0; 3]),
    )
}

fn free(name: &str, shape: Shape, density: f64, s: BodyState) -> (String, Body, BodyState) {
    let (mass, inertia) = shape.mass_properties(density).unwrap();
    (
        name.into(),
        Body {
            shape,
            mass,
            inertia,
            fixed: false,
        },
        s,
    )
}

fn scene(parts: Vec<(String, Body, BodyState)>, law: ContactLaw, gravity: f64) -> RigidScene {
    RigidScene {
        names: parts.iter().map(|p| p.0.clone()).collect(),
        bodies: parts.iter().map(|p| p.1.clone()).collect(),
        initial: parts.iter().map(|p| p.2).collect(),
        gravity: [0.0, 0.0, -gravity],
        default_law: law,
        pair_laws: Vec::new(),
        margin: 1e-6,
        joints: Vec::new(),
    }
}

fn simulate(
    scene: &RigidScene,
    params: RigidMoreauJeanParams,
    h: f64,
    steps: u64,
    every: u64,
    detector: Box<dyn ContactDetector>,
) -> Recorder {
    let scheme = RigidMoreauJean::new(params, h);
    let mut family = RigidStepping::new(scene, &scheme, detector, steps);
    let mut rec = Recorder::default();
    run(&mut family, every, &mut rec, None).unwrap();
    rec
}

fn col(rec: &Recorder, name: &str) -> Vec<f64> {
    rec.column(name)
        .unwrap_or_else(|| panic!("no column {name} in {:?}", rec.columns.names()))
}

fn last(rec: &Recorder, name: &str) -> f64 {
    *col(rec, name).last().unwrap()
}

/// Half the height of a box of [`box_stack`].
const BOX_HALF_HEIGHT: f64 = 0.1;

/// `count` boxes 0.2 m high (density 500, μ = 0.5, e = 0), each 1 cm narrower than the one
/// below, stacked face on face on a floor, at rest.
fn box_stack(count: usize) -> RigidScene {
    let a = BOX_HALF_HEIGHT;
    let mut parts = vec![floor()];
    for i in 0..count {
        parts.push(free(
            &format!("box{i}"),
            Shape::Box {
                half_extents: [0.2 - 0.01 * i as f64, 0.2 - 0.01 * i as f64, a],
            },
            500.0,
            at_rest([0.0, 0.0, a + 2.0 * a * i as f64], [0.0; 3]),
        ));
    }
    scene(
        parts,
        ContactLaw {
            restitution: 0.0,
            friction: 0.5,
        },
        G,
    )
}

/// Ten boxes 0.2 m high (μ = 0.5), each 1 cm narrower than the one below, stacked face on face
/// on a floor and released at rest: the tower stands still for 10 s (h = 2 ms). Each box rests on
/// the one below through its four lower corners (parry's box–box manifold; equal faces would
/// give a degenerate clipping), so every step solves a friction problem of 40 contacts coupled
/// all the way down. Asserted: the
/// index set keeps its 40 points, no box moves more than 1e-9 m from where it started (measured
/// 1.2e-14 m on the top box), no box turns (|q − 1| ≤ 1e-12), the kinetic energy stays at
/// round-off (≤ 1e-20 J, measured ~1e-27 J), and the ledger closes to 1e-12 of the potential
/// energy in every recorded step.
#[test]
fn a_stack_of_ten_boxes_stands_still_for_ten_seconds() {
    let a = BOX_HALF_HEIGHT;
    let s = box_stack(10);
    let detector = ParryDetectors.detector(&s.bodies).unwrap();
    let rec = simulate(
        &s,
        RigidMoreauJeanParams::default(),
        2e-3,
        5_000,
        50,
        detector,
    );
    assert_eq!(rec.t.last().copied(), Some(10.0));
    // Every step's index set (the record of t = 0 has no step).
    let contacts = col(&rec, "contacts");
    assert!(contacts[1..].iter().all(|c| *c == 40.0), "{contacts:?}");
    let mut drift: f64 = 0.0;
    for i in 0..10 {
        let z0 = a + 2.0 * a * i as f64;
        for k in 0..rec.rows.len() {
            let at = |c: &str| col(&rec, &format!("box{i}_{c}"))[k];
            let d = at("x").hypot(at("y")).hypot(at("z") - z0);
            drift = drift.max(d);
            assert!((at("qw") - 1.0).abs() <= 1e-12, "box{i} turned at step {k}");
        }
    }
    assert!(drift <= 1e-9, "drift {drift:e} m");
    let scale = col(&rec, "potential")[0].abs();
    for (k, e) in col(&rec, "energy_error").iter().enumerate() {
        assert!(e.abs() <= 1e-12 * scale, "record {k}: energy_error {e:e}");
    }
    let kinetic = col(&rec, "kinetic").into_iter().fold(0.0, f64::max);
    assert!(kinetic <= 1e-20, "kinetic {kinetic:e} J");
}

/// Three equal balls in a row, touching, no gravity, e = 1, μ = 0; the first is thrown at the
/// other two at v₀. Moreau's impact law is simultaneous: both contacts are in the index set of
/// the same step and one LCP gives the impulses (P₁, P₂) with
/// 2P₁ − P₂ = (1 + e) v₀ (contact 1 leaves at e v₀) and 2P₂ − P₁ = 0 (contact 2 leaves at 0),
/// so P₁ = 4v₀/3, P₂ = 2v₀/3 and the velocities after are (−v₀/3, 2v₀/3, 2v₀/3): the last two
/// balls leave together and the first bounces back. Momentum and (here, for three equal balls
/// and e = 1) kinetic energy are kept, but this is not the one-ball-out of a real cradle, whose
/// balls are never exactly in contact: see the gapped cradle below.
#[test]
fn touching_balls_share_the_impact_as_moreaus_simultaneous_law_says() {
    let (r, v0) = (0.1, 1.0);
    let parts = (0..3)
        .map(|i| {
            let v = if i == 0 { [v0, 0.0, 0.0] } else { [0.0; 3] };
            free(
                &format!("b{i}"),
                Shape::Sphere { radius: r },
                1000.0,
                at_rest([2.0 * r * i as f64, 0.0, 0.0], v),
            )
        })
        .collect();
    let s = scene(
        parts,
        ContactLaw {
            restitution: 1.0,
            friction: 0.0,
        },
        0.0,
    );
    let detector = ParryDetectors.detector(&s.bodies).unwrap();
    let rec = simulate(&s, RigidMoreauJeanParams::default(), 1e-3, 100, 1, detector);
    for (name, v) in [
        ("b0", -v0 / 3.0),
        ("b1", 2.0 * v0 / 3.0),
        ("b2", 2.0 * v0 / 3.0),
    ] {
        let vx = col(&rec, &format!("{name}_vx"))[1];
        assert!(
            (vx - v).abs() <= 1e-9,
            "{name}: {vx} after the impact, {v} expected"
        );
        assert!((last(&rec, &format!("{name}_vx")) - v).abs() <= 1e-9);
    }
    let energy = col(&rec, "kinetic");
    assert!((energy.last().unwrap() - energy[0]).abs() <= 1e-9 * energy[0]);
}

fn example(name: &str) -> JobSpec {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../examples/{name}.toml"));
    let text = std::fs::read_to_string(&path).expect("reading the example");
    toml::from_str(&text).expect("the example parses")
}

/// `examples/rigid/newtons_cradle.toml`: five equal balls in a row, 1 cm apart, e = 1, no
/// gravity, the first thrown at 1 m/s. With gaps each impact is a binary impact of
/// equal masses, which swaps the two velocities: the momentum is handed down the chain ball by
/// ball, and after the last impact the first four are at rest and the fifth carries all of it.
/// Asserted: the final velocities (0, 0, 0, 0, v₀) to 1e-9, total momentum m v₀ in every
/// recorded step, the kinetic energy never above its start (no impact creates energy) and equal
/// to it at the end, and the ledger at round-off.
#[test]
fn the_gapped_cradle_hands_the_momentum_down_the_chain_without_creating_energy() {
    let spec = example("rigid/newtons_cradle");
    let job = Job::from_spec(&spec).unwrap();
    let mut rec = Recorder::default();
    job::run_with_detectors(&job, 1, &mut rec, None, &ParryDetectors)
        .unwrap_or_else(|e| panic!("{e}"));
    let v0 = col(&rec, "ball1_vx")[0];
    assert_eq!(v0, 1.0);
    let names = ["ball1", "ball2", "ball3", "ball4", "ball5"];
    for (i, name) in names.iter().enumerate() {
        let expected = if i == 4 { v0 } else { 0.0 };
        let v = last(&rec, &format!("{name}_vx"));
        assert!((v - expected).abs() <= 1e-9, "{name}: {v}");
    }
    for k in 0..rec.rows.len() {
        let momentum: f64 = names.iter().map(|n| col(&rec, &format!("{n}_vx"))[k]).sum();
        assert!((momentum - v0).abs() <= 1e-9, "record {k}: Σv = {momentum}");
    }
    let kinetic = col(&rec, "kinetic");
    let k0 = kinetic[0];
    assert!(kinetic.iter().all(|k| *k <= k0 * (1.0 + 1e-12)));
    assert!((kinetic.last().unwrap() - k0).abs() <= 1e-9 * k0);
    assert!(
        col(&rec, "energy_error")
            .iter()
            .all(|e| e.abs() <= 1e-12 * k0)
    );
}

/// Parry's detector searching `extra` farther than the scheme asks: every point of gap
/// ≤ margin + extra is reported (the index set then keeps those of predicted gap ≤ margin).
struct FartherSearch {
    inner: Box<dyn ContactDetector>,
    extra: f64,
}

impl ContactDetector for FartherSearch {
    fn detect(
        &mut self,
        poses: &[Pose],
        margin: f64,
        contacts: &mut Vec<ContactPoint>,
    ) -> Result<(), DetectError> {
        self.inner.detect(poses, margin + self.extra, contacts)
    }
}

/// A ball (no spin, thrown sideways, e = 0.8, μ = 0) bouncing on a floor as a `rigid_bodies`
/// scene and as the same system written as a `lagrangian` model (coordinates x, y, z, M = m 1,
/// V = m g z, gap z − r) under `moreau_jean` with θ = ½: the two give the same trajectory, the
/// same kinetic and potential energies and the same contact work in every step, to 1e-12 of
/// each column's scale.
///
/// Where the two discretisations differ by design, and why this configuration is the one where
/// they must coincide:
/// - The rigid scheme updates the orientation by the exponential map and carries the
///   gyroscopic term; with no spin and no friction no torque acts (the contact normal passes
///   through the centre), Ω stays exactly 0 and both terms vanish. The lagrangian model has no
///   rotation at all.
/// - The lagrangian scheme solves Newton on q_{k+1} with the θ-averaged force; for a constant
///   M and gravity the problem is linear and its first iterate is exact, as (1a) of the rigid
///   scheme is.
/// - The lagrangian model evaluates its gap g(q) = z − r everywhere and activates by Siconos'
///   predicted gap g + γ h U_n ≤ 0; the rigid scheme applies the same test, but only to the
///   points its detector reports, those of gap ≤ margin. Here the margin is 0 and the detector
///   searches γ h max|U_n| farther (`FartherSearch`), so both index sets are the set of
///   g + γ h U_n ≤ 0 (γ = ½ in both).
/// - Friction: the lagrangian contact has no tangent; the rigid one has μ = 0, so its tangential
///   impulses are 0 and the one-step FC3D problem is the LCP of the normal impulse.
#[test]
fn a_rigid_ball_on_a_floor_equals_the_same_ball_written_as_a_lagrangian_model() {
    let (m, r, e, h) = (2.0, 0.1, 0.8, 1e-3);
    let (q0, v0) = ([0.0, 0.0, 0.6], [0.5, -0.3, 0.7]);
    let ball = (
        "ball".to_string(),
        Body {
            shape: Shape::Sphere { radius: r },
            mass: m,
            inertia: [0.4 * m * r * r; 3],
            fixed: false,
        },
        at_rest(q0, v0),
    );
    let mut s = scene(
        vec![floor(), ball],
        ContactLaw {
            restitution: e,
            friction: 0.0,
        },
        G,
    );
    s.margin = 0.0;
    let steps = 2000;
    // |U_n| ≤ √(v_z0² + 2 g z0) < 4 m/s: γ h |U_n| < 2e-3.
    let detector = Box::new(FartherSearch {
        inner: ParryDetectors.detector(&s.bodies).unwrap(),
        extra: 2e-3,
    });
    let params = RigidMoreauJeanParams {
        theta: 0.5,
        gamma: 0.5,
        ..RigidMoreauJeanParams::default()
    };
    let rigid = simulate(&s, params, h, steps, 1, detector);

    let user: JobSpec = serde_json::from_value(serde_json::json!({
        "model": {
            "scene": "lagrangian",
            "coordinates": ["x", "y", "z"],
            "parameters": { "m": m, "g": G, "r": r },
            "mass": [["m", 0, 0], [0, "m", 0], [0, 0, "m"]],
            "potential": "m*g*z",
            "q0": q0, "v0": v0,
            "contacts": [{ "gap": "z - r", "restitution": e }]
        },
        "integrator": { "scheme": "moreau_jean", "theta": 0.5,
                        "activation": "predicted_gap", "activation_gamma": 0.5 },
        "time": { "h": h, "steps": steps },
        "output": { "probes": [0, 1, 2] }
    }))
    .unwrap();
    let job = Job::from_spec(&user).unwrap();
    let mut lagrangian = Recorder::default();
    job::run(&job, 1, &mut lagrangian).unwrap();

    assert_eq!(rigid.steps, lagrangian.steps);
    let pairs = [
        ("ball_x", "q_0"),
        ("ball_y", "q_1"),
        ("ball_z", "q_2"),
        ("ball_vx", "v_0"),
        ("ball_vy", "v_1"),
        ("ball_vz", "v_2"),
        ("kinetic", "kinetic"),
        ("potential", "potential"),
        ("work_contact", "work_contact"),
    ];
    for (a, b) in pairs {
        let (x, y) = (col(&rigid, a), col(&lagrangian, b));
        let scale = x.iter().fold(1e-300_f64, |s, v| s.max(v.abs()));
        let worst = x
            .iter()
            .zip(&y)
            .map(|(u, v)| (u - v).abs() / scale)
            .fold(0.0, f64::max);
        assert!(worst <= 1e-12, "{a} / {b} differ by {worst:.2e} of scale");
    }
    // It bounced several times, and never turned.
    let impacts = col(&rigid, "work_contact")
        .iter()
        .filter(|w| **w < -1e-6)
        .count();
    assert!(impacts >= 3, "{impacts} impacts");
    assert!(col(&rigid, "ball_wx").iter().all(|w| *w == 0.0));
    assert!(col(&rigid, "ball_qw").iter().all(|q| *q == 1.0));
}

/// A stack of three boxes asked for an FC3D error no solver reaches (1e-300) within three
/// iterations: without `accept_error` the first step fails on its friction problem; with it the
/// run goes on with the best iterates, counts every step as accepted, reports the largest error
/// of a step's last solve (the one whose impulses the step applies) within the bound, and the
/// energy ledger still closes to round-off (it holds for any impulse the update applies).
#[test]
fn a_step_above_the_friction_tolerance_fails_unless_its_error_is_accepted_and_then_is_counted() {
    let s = box_stack(3);
    let unreachable = |accept_error| {
        let mut params = RigidMoreauJeanParams {
            accept_error,
            ..RigidMoreauJeanParams::default()
        };
        params.fc3d.tolerance = 1e-300;
        params.fc3d.max_iterations = 3;
        params
    };
    let steps = 20;
    let scheme = RigidMoreauJean::new(unreachable(None), 2e-3);
    let detector = ParryDetectors.detector(&s.bodies).unwrap();
    let mut family = RigidStepping::new(&s, &scheme, detector, steps);
    let failed = run(&mut family, 1, &mut Recorder::default(), None);
    let message = format!("{:?}", failed.unwrap_err());
    assert!(
        message.contains("Friction { step: 1") && message.contains("NotConverged"),
        "{message}"
    );

    let bound = 0.1;
    let scheme = RigidMoreauJean::new(unreachable(Some(bound)), 2e-3);
    let detector = ParryDetectors.detector(&s.bodies).unwrap();
    let mut family = RigidStepping::new(&s, &scheme, detector, steps);
    let mut rec = Recorder::default();
    run(&mut family, 1, &mut rec, None).unwrap();
    let stats = family.stats();
    assert_eq!(stats.steps, steps);
    assert_eq!(stats.friction_steps_accepted, steps);
    assert!(
        stats.friction_error_max > 1e-300 && stats.friction_error_max <= bound,
        "{stats:?}"
    );
    let scale = col(&rec, "potential")[0].abs();
    for (k, e) in col(&rec, "energy_error").iter().enumerate() {
        assert!(e.abs() <= 1e-12 * scale, "record {k}: energy_error {e:e}");
    }
}

/// The stack asked for 1e-300 again, with a budget of 20 000 sweeps: with `accept_error` its
/// sweeps reach their round-off floor and stop `stall_sweeps` later (the stall within the bound,
/// `rigid::STALL_SWEEPS` by default), where without the stagnation test every step spends the
/// whole budget; the steps, their acceptance and the ledger are the same either way.
#[test]
fn a_rigid_step_stops_sweeping_once_its_solver_stalls_within_the_accepted_error() {
    let s = box_stack(3);
    let steps = 5;
    let budget = 20_000;
    let stats = |stall_sweeps| {
        let mut params = RigidMoreauJeanParams {
            accept_error: Some(0.1),
            stall_sweeps,
            ..RigidMoreauJeanParams::default()
        };
        params.fc3d.tolerance = 1e-300;
        params.fc3d.max_iterations = budget;
        let scheme = RigidMoreauJean::new(params, 2e-3);
        let detector = ParryDetectors.detector(&s.bodies).unwrap();
        let mut family = RigidStepping::new(&s, &scheme, detector, steps);
        run(&mut family, 1, &mut Recorder::default(), None).unwrap();
        family.stats().clone()
    };
    let spent = stats(None);
    let stopped = stats(Some(STALL_SWEEPS));
    for s in [&spent, &stopped] {
        assert_eq!(s.steps, steps);
        assert_eq!(s.friction_steps_accepted, steps);
        assert!(s.friction_error_max <= 1e-12, "{s:?}");
    }
    // `auto`: 5 000 accelerated sweeps, the proximal point method, then the plain sweeps twice
    // (over-relaxed, then not), each with the whole budget.
    assert!(
        spent.friction_iterations_total >= steps * 2 * budget as u64,
        "{spent:?}"
    );
    assert!(
        stopped.friction_iterations_total < steps * budget as u64 / 2,
        "{stopped:?}"
    );
}
