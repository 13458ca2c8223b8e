//! Rigid bodies under Moreau–Jean with parry's contacts, against closed-form mechanics: rolling
//! and sliding on an incline, a ball thrown sliding that starts to roll, a box that slides to a
//! stop, a box that sticks on a slope, the torque-free asymmetric top, and the energy ledger.

use signorini_collision::ParryDetectors;
use signorini_core::observer::Recorder;
use signorini_core::rigid::{
    Body, BodyState, ContactLaw, DetectorFactory, RigidMoreauJean, RigidMoreauJeanParams,
    RigidScene, RigidStepping, Shape,
};
use signorini_core::stepping::run;

const G: f64 = 9.81;

fn state(position: [f64; 3], velocity: [f64; 3], angular_velocity: [f64; 3]) -> BodyState {
    BodyState {
        position,
        orientation: [1.0, 0.0, 0.0, 0.0],
        velocity,
        angular_velocity,
    }
}

/// A fixed half-space through the origin with outward normal n.
fn ground(n: [f64; 3]) -> (String, Body, BodyState) {
    (
        "ground".into(),
        Body {
            shape: Shape::HalfSpace { normal: n },
            mass: 0.0,
            inertia: [0.0; 3],
            fixed: true,
        },
        state([0.0; 3], [0.0; 3], [0.0; 3]),
    )
}

fn body(name: &str, shape: Shape, density: f64, s: BodyState) -> (String, Body, BodyState) {
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

fn scene(parts: Vec<(String, Body, BodyState)>, friction: f64, restitution: f64) -> RigidScene {
    RigidScene {
        names: parts.iter().map(|p| p.0.clone()).collect(),
        bodies: parts.iter().map(|p| p.1.clone()).collect(),
        initial: parts.iter().map(|p| p.2).collect(),
        gravity: [0.0, 0.0, -G],
        default_law: ContactLaw {
            restitution,
            friction,
        },
        pair_laws: Vec::new(),
        margin: 1e-6,
        joints: Vec::new(),
    }
}

/// Runs `steps` steps of h with θ, recording every step.
fn simulate(scene: &RigidScene, h: f64, theta: f64, steps: u64) -> Recorder {
    let scheme = RigidMoreauJean::new(
        RigidMoreauJeanParams {
            theta,
            ..RigidMoreauJeanParams::default()
        },
        h,
    );
    let detector = ParryDetectors.detector(&scene.bodies).unwrap();
    let mut family = RigidStepping::new(scene, &scheme, detector, steps);
    let mut rec = Recorder::default();
    run(&mut family, 1, &mut rec, None).unwrap();
    rec
}

fn col(rec: &Recorder, name: &str) -> Vec<f64> {
    rec.column(name).unwrap()
}

fn last(rec: &Recorder, name: &str) -> f64 {
    *col(rec, name).last().unwrap()
}

/// The energy ledger closes at round-off in every step, friction never does positive work.
fn assert_ledger(rec: &Recorder, scale: f64) {
    for (k, e) in col(rec, "energy_error").iter().enumerate() {
        assert!(e.abs() <= 1e-12 * scale, "step {k}: energy_error {e:e}");
    }
    for (k, w) in col(rec, "work_friction").iter().enumerate() {
        assert!(*w <= 1e-14 * scale, "step {k}: work_friction {w:e} > 0");
    }
}

/// A sphere released on an incline of α = 20°: after 1 s, its displacement along the slope,
/// its spin times r, the friction work, and the records.
fn incline(mu: f64, h: f64) -> (f64, f64, f64, Recorder) {
    let alpha = 20f64.to_radians();
    let n = [alpha.sin(), 0.0, alpha.cos()];
    let r = 0.1;
    let ball = body(
        "ball",
        Shape::Sphere { radius: r },
        1000.0,
        state([r * n[0], 0.0, r * n[2]], [0.0; 3], [0.0; 3]),
    );
    let s = scene(vec![ground(n), ball], mu, 0.0);
    let steps = (1.0 / h).round() as u64;
    let rec = simulate(&s, h, 0.5, steps);
    let down = [alpha.cos(), 0.0, -alpha.sin()];
    let x = last(&rec, "ball_x") - r * n[0];
    let z = last(&rec, "ball_z") - r * n[2];
    let along = x * down[0] + z * down[2];
    // Spin about +y (rolling down +x along the slope), times r.
    let spin = last(&rec, "ball_wy") * r;
    (along, spin, last(&rec, "work_friction_total"), rec)
}

#[test]
fn a_sphere_on_an_incline_rolls_at_five_sevenths_g_sin_alpha_without_losing_energy() {
    let alpha = 20f64.to_radians();
    assert!(0.5 >= 2.0 / 7.0 * alpha.tan());
    let exact = 0.5 * 5.0 / 7.0 * G * alpha.sin();
    let mut errors = Vec::new();
    for h in [2e-3, 1e-3] {
        let (along, spin, friction_work, rec) = incline(0.5, h);
        let energy = col(&rec, "energy");
        assert_ledger(&rec, energy[0].abs().max(1.0));
        // Rolling: v = ω r, and no energy is lost (friction does no work on a rolling contact).
        let v = last(&rec, "ball_vx").hypot(last(&rec, "ball_vz"));
        assert!((v - spin).abs() <= 1e-9 * v, "slip {}", v - spin);
        assert!(
            friction_work.abs() <= 1e-9,
            "friction work {friction_work:e}"
        );
        assert!((energy.last().unwrap() - energy[0]).abs() <= 1e-9 * energy[0].abs());
        errors.push((along - exact).abs() / exact);
    }
    // First order at least: the error at h/2 is at most half the error at h (both can be at
    // round-off: constant accelerations are integrated exactly by the θ = ½ scheme).
    assert!(errors[1] <= 0.5 * errors[0] + 1e-10, "{errors:?}");
    // Measured: 7e-16 and 6e-16.
    assert!(errors[0] <= 1e-12, "{errors:?}");
}

#[test]
fn a_sphere_on_a_steep_incline_slides_and_friction_dissipates_mu_m_g_cos_alpha_per_slip() {
    let alpha = 20f64.to_radians();
    let mu = 0.05;
    assert!(mu < 2.0 / 7.0 * alpha.tan());
    let r: f64 = 0.1;
    let mass = 1000.0 * 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    let acceleration = G * (alpha.sin() - mu * alpha.cos());
    // Slip rate v − ωr grows at g(sin α − 7/2 μ cos α).
    let slip = 0.5 * G * (alpha.sin() - 3.5 * mu * alpha.cos());
    let dissipated = -mu * mass * G * alpha.cos() * slip;
    let mut errors = Vec::new();
    for h in [2e-3, 1e-3] {
        let (along, _, friction_work, rec) = incline(mu, h);
        assert_ledger(&rec, col(&rec, "energy")[0].abs().max(1.0));
        let e_along = (along - 0.5 * acceleration).abs() / (0.5 * acceleration);
        let e_work = (friction_work - dissipated).abs() / dissipated.abs();
        errors.push(e_along.max(e_work));
    }
    assert!(errors[1] <= 0.5 * errors[0] + 1e-10, "{errors:?}");
    // Measured: 3e-15 and 4e-15.
    assert!(errors[0] <= 1e-12, "{errors:?}");
}

/// A ball thrown at v₀ without spin on a floor slides until t* = 2v₀/(7μg), then rolls at
/// (5/7)v₀; the start of rolling is found within one step.
#[test]
fn a_ball_thrown_sliding_rolls_from_two_v0_over_seven_mu_g_at_five_sevenths_v0() {
    let (v0, mu, r) = (2.0, 0.2, 0.1);
    let t_star = 2.0 * v0 / (7.0 * mu * G);
    for h in [2e-3, 1e-3] {
        let ball = body(
            "ball",
            Shape::Sphere { radius: r },
            1000.0,
            state([0.0, 0.0, r], [v0, 0.0, 0.0], [0.0; 3]),
        );
        let s = scene(vec![ground([0.0, 0.0, 1.0]), ball], mu, 0.0);
        let steps = (2.0 * t_star / h).round() as u64;
        let rec = simulate(&s, h, 0.5, steps);
        assert_ledger(&rec, col(&rec, "energy")[0]);
        let vx = col(&rec, "ball_vx");
        let wy = col(&rec, "ball_wy");
        let rolling = (0..vx.len())
            .find(|&k| (vx[k] - r * wy[k]).abs() <= 1e-9)
            .expect("the ball rolls");
        let t_roll = rec.t[rolling];
        assert!(
            t_roll >= t_star - 1e-12 && t_roll <= t_star + h,
            "h = {h}: rolls from {t_roll}, t* = {t_star}"
        );
        // From then on it rolls at (5/7)v₀: the transition step's error is O(h), and after it
        // the speed is constant.
        let v_end = last(&rec, "ball_vx");
        assert!((v_end - 5.0 / 7.0 * v0).abs() <= 1e-9, "h = {h}: {v_end}");
        assert!((last(&rec, "ball_vx") - r * last(&rec, "ball_wy")).abs() <= 1e-9);
    }
}

/// A box thrown at v₀ on a floor (four corner contacts) slides v₀²/(2μg) and stops.
#[test]
fn a_box_thrown_on_a_floor_stops_after_v0_squared_over_two_mu_g() {
    let (v0, mu, a) = (1.0, 0.3, 0.1);
    let exact = v0 * v0 / (2.0 * mu * G);
    let mut errors = Vec::new();
    for h in [2e-3, 1e-3] {
        let cube = body(
            "box",
            Shape::Box {
                half_extents: [a; 3],
            },
            500.0,
            state([0.0, 0.0, a], [v0, 0.0, 0.0], [0.0; 3]),
        );
        let s = scene(vec![ground([0.0, 0.0, 1.0]), cube], mu, 0.0);
        let steps = (1.5 * v0 / (mu * G) / h).round() as u64;
        let rec = simulate(&s, h, 0.5, steps);
        assert_ledger(&rec, col(&rec, "energy")[0]);
        assert_eq!(
            last(&rec, "contacts"),
            4.0,
            "a box on its face touches at 4 corners"
        );
        assert!(last(&rec, "box_vx").abs() <= 1e-9, "stopped");
        // Flat: no tipping.
        assert!((last(&rec, "box_qw") - 1.0).abs() <= 1e-12);
        errors.push((last(&rec, "box_x") - exact).abs());
    }
    // The stop falls inside a step: an error of at most v₀ h, halving with h.
    assert!(
        errors[0] <= 1.0 * 2e-3 && errors[1] <= 1.0 * 1e-3,
        "{errors:?}"
    );
    assert!(errors[1] <= 0.5 * errors[0] + 1e-12, "{errors:?}");
}

/// A box at rest on a 20° slope with μ = 0.5 > tan 20° does not move: drift ≤ 1e-9 m in 10 s.
#[test]
fn a_box_on_a_twenty_degree_slope_with_mu_half_sticks_for_ten_seconds() {
    let alpha = 20f64.to_radians();
    assert!(0.5 > alpha.tan());
    let a = 0.1;
    // The box turned by −α about y sits on the plane of normal (sin α, 0, cos α).
    let n = [alpha.sin(), 0.0, alpha.cos()];
    let mut cube = body(
        "box",
        Shape::Box {
            half_extents: [a; 3],
        },
        500.0,
        state([a * n[0], 0.0, a * n[2]], [0.0; 3], [0.0; 3]),
    );
    // Rotation by +α about y takes body z to (sin α, 0, cos α).
    cube.2.orientation = [(alpha / 2.0).cos(), 0.0, (alpha / 2.0).sin(), 0.0];
    let s = scene(vec![ground(n), cube], 0.5, 0.0);
    let h = 1e-3;
    let rec = simulate(&s, h, 0.5, 10_000);
    assert_ledger(&rec, 1.0);
    let drift = (last(&rec, "box_x") - a * n[0])
        .hypot(last(&rec, "box_y"))
        .hypot(last(&rec, "box_z") - a * n[2]);
    assert!(drift <= 1e-9, "drift {drift:e} m");
    assert_eq!(last(&rec, "contacts"), 4.0);
}

/// The torque-free asymmetric body (I = diag(1, 2, 3)) spinning near its unstable middle axis:
/// the quaternion stays unit to round-off, ΩᵀIΩ and ‖IΩ‖ are kept exactly by the midpoint
/// rule, and the world angular momentum R I Ω drifts as h² (second order).
#[test]
fn a_free_asymmetric_body_keeps_its_quaternion_unit_its_energy_and_its_angular_momentum() {
    let inertia = [1.0, 2.0, 3.0];
    let omega0 = [0.1, 2.0, 0.1];
    let top = |h: f64| {
        let free = Body {
            shape: Shape::Sphere { radius: 0.1 },
            mass: 1.0,
            inertia,
            fixed: false,
        };
        let s = RigidScene {
            names: vec!["top".into()],
            bodies: vec![free],
            initial: vec![state([0.0; 3], [0.0; 3], omega0)],
            gravity: [0.0; 3],
            default_law: ContactLaw {
                restitution: 0.0,
                friction: 0.0,
            },
            pair_laws: Vec::new(),
            margin: 1e-6,
            joints: Vec::new(),
        };
        simulate(&s, h, 0.5, (5.0 / h).round() as u64)
    };
    let momentum = |rec: &Recorder, k: usize| -> [f64; 3] {
        let get = |c: &str| col(rec, c)[k];
        let q = [get("top_qw"), get("top_qx"), get("top_qy"), get("top_qz")];
        let w = [get("top_wx"), get("top_wy"), get("top_wz")];
        // World L = R I Rᵀ ω.
        let rot = |v: [f64; 3], inverse: bool| {
            let (s, x, y, z) = (
                q[0],
                if inverse { -q[1] } else { q[1] },
                if inverse { -q[2] } else { q[2] },
                if inverse { -q[3] } else { q[3] },
            );
            let u = [x, y, z];
            let c = |a: [f64; 3], b: [f64; 3]| {
                [
                    a[1] * b[2] - a[2] * b[1],
                    a[2] * b[0] - a[0] * b[2],
                    a[0] * b[1] - a[1] * b[0],
                ]
            };
            let t = c(u, v).map(|e| 2.0 * e);
            let ut = c(u, t);
            [
                v[0] + s * t[0] + ut[0],
                v[1] + s * t[1] + ut[1],
                v[2] + s * t[2] + ut[2],
            ]
        };
        let body = rot(w, true);
        rot(
            [
                inertia[0] * body[0],
                inertia[1] * body[1],
                inertia[2] * body[2],
            ],
            false,
        )
    };
    let mut drifts = Vec::new();
    for h in [2e-3, 1e-3] {
        let rec = top(h);
        for k in 0..rec.rows.len() {
            let get = |c: &str| col(&rec, c)[k];
            let norm = [get("top_qw"), get("top_qx"), get("top_qy"), get("top_qz")]
                .iter()
                .map(|x| x * x)
                .sum::<f64>()
                .sqrt();
            assert!((norm - 1.0).abs() <= 1e-14, "step {k}: |q| = {norm}");
        }
        let energy = col(&rec, "kinetic");
        let e0 = energy[0];
        let worst = energy
            .iter()
            .map(|e| (e - e0).abs() / e0)
            .fold(0.0, f64::max);
        assert!(worst <= 1e-12, "{worst:e}");
        assert_ledger(&rec, e0);
        let (l0, l1) = (momentum(&rec, 0), momentum(&rec, rec.rows.len() - 1));
        let drift =
            ((l1[0] - l0[0]).powi(2) + (l1[1] - l0[1]).powi(2) + (l1[2] - l0[2]).powi(2)).sqrt();
        drifts.push(drift / 2.0);
    }
    // Second order: halving h divides the drift by 4 (measured 2.67e-6 and 6.68e-7).
    let ratio = drifts[0] / drifts[1];
    assert!((3.5..4.5).contains(&ratio), "{drifts:?}");
    assert!(drifts[0] <= 1e-5, "{drifts:?}");
}

/// A ball dropped with spin and sideways speed on a rough floor: with e ≤ 1 no impact creates
/// energy (work_contact ≤ 0 in every step, θ = ½), and with e = 1 and no friction the bounce
/// returns the impact speed.
#[test]
fn impacts_with_restitution_at_most_one_never_create_energy() {
    for (e, mu) in [(0.0, 0.3), (0.8, 0.3), (1.0, 0.3), (1.0, 0.0)] {
        let r = 0.1;
        let ball = body(
            "ball",
            Shape::Sphere { radius: r },
            1000.0,
            state([0.0, 0.0, 0.5], [1.0, 0.0, 0.0], [3.0, -20.0, 1.0]),
        );
        let s = scene(vec![ground([0.0, 0.0, 1.0]), ball], mu, e);
        let rec = simulate(&s, 1e-3, 0.5, 1500);
        let scale = col(&rec, "energy")[0];
        assert_ledger(&rec, scale);
        for (k, w) in col(&rec, "work_contact").iter().enumerate() {
            assert!(*w <= 1e-12 * scale, "e = {e}, step {k}: work_contact {w:e}");
        }
        let energy = col(&rec, "energy");
        assert!(energy.windows(2).all(|w| w[1] <= w[0] + 1e-12 * scale));
        if e == 1.0 && mu == 0.0 {
            // Elastic and frictionless: no energy lost at all.
            assert!((energy.last().unwrap() - energy[0]).abs() <= 1e-9 * scale);
        }
    }
}
