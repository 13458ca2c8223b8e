//! Coulomb friction under the nonsmooth generalized-α scheme on `lagrangian` models
//! (`nonlinear::generalized_alpha`, issue 26): the double pendulum against a rough wall (the
//! user's case: it ran as if μ were 0) now loses energy to friction, `work_friction` ≤ 0 at
//! every step and its ledger closes; a point mass thrown against a rough wall closes its energy
//! balance at round-off (constant M, a wall along gravity: the smooth and position stages do
//! no work there); a block sliding on a rough floor decelerates by μ g h per step and stops at
//! v0²/(2 μ g) to first order, by the discrete closed form; μ = 0 is the frictionless model bit
//! for bit, and so is friction on a contact that never enters the index set.

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use serde_json::{Value, json};
use signorini_core::job::{Job, run};
use signorini_core::observer::Recorder;
use signorini_core::spec::JobSpec;
use std::path::Path;

fn example_json(name: &str) -> Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../examples/{name}.toml"));
    let text = std::fs::read_to_string(&path).expect("reading the example");
    let spec: JobSpec = toml::from_str(&text).expect("the example parses");
    serde_json::to_value(spec).expect("as JSON")
}

fn record(v: &Value) -> (Recorder, Value) {
    let spec: JobSpec = serde_json::from_value(v.clone()).expect("spec");
    let job = Job::from_spec(&spec).unwrap_or_else(|e| panic!("spec refused: {e}"));
    let mut rec = Recorder::default();
    let out = run(&job, 1, &mut rec).unwrap_or_else(|e| panic!("run failed: {e}"));
    (rec, Value::Object(out.summary.to_map()))
}

fn col(rec: &Recorder, name: &str) -> Vec<f64> {
    rec.column(name)
        .unwrap_or_else(|| panic!("no column {name} in {:?}", rec.columns.names()))
}

fn max_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0f64, |m, a| m.max(a.abs()))
}

const NS_ALPHA: &str = r#"{"scheme": "ns_generalized_alpha", "rho_inf": 0.9}"#;

fn ns_alpha() -> Value {
    serde_json::from_str(NS_ALPHA).expect("json")
}

/// `work_friction` ≤ 0 at every record up to round-off (1e-12 Σ|pt| max(1, max|ut|): a
/// sticking contact has U_t = 0 only to round-off).
fn assert_dissipative(rec: &Recorder, contacts: usize, what: &str) {
    let pts: Vec<Vec<f64>> = (0..contacts)
        .map(|a| col(rec, &format!("pt_{a}")))
        .collect();
    let vmax = (0..contacts)
        .map(|a| max_abs(&col(rec, &format!("ut_{a}"))))
        .fold(1.0f64, f64::max);
    for (k, w) in col(rec, "work_friction").iter().enumerate() {
        let tol = 1e-12 * vmax * pts.iter().map(|p| p[k].abs()).sum::<f64>();
        assert!(
            *w <= tol,
            "{what}: work_friction {w:e} > {tol:e} at record {k}"
        );
    }
}

/// The ledger of every recorded step (every step recorded): ΔE = work_ext + work_contact +
/// work_friction + energy_error to round-off, and the totals are the sums of the steps'.
/// Returns max |energy_error|.
fn assert_ledger(rec: &Recorder, what: &str) -> f64 {
    let e = col(rec, "energy");
    let (we, wc, wf, err) = (
        col(rec, "work_ext"),
        col(rec, "work_contact"),
        col(rec, "work_friction"),
        col(rec, "energy_error"),
    );
    let scale = max_abs(&e).max(1.0);
    for k in 1..e.len() {
        let residual = (e[k] - e[k - 1]) - we[k] - wc[k] - wf[k] - err[k];
        assert!(
            residual.abs() <= 1e-13 * scale,
            "{what}: ledger off by {residual:e} at record {k}"
        );
    }
    let last = e.len() - 1;
    for (total, steps) in [("work_contact_total", &wc), ("work_friction_total", &wf)] {
        let sum: f64 = steps[1..].iter().sum();
        let t = col(rec, total)[last];
        assert!(
            (t - sum).abs() <= 1e-12 * scale,
            "{what}: {total} {t} against Σ {sum}"
        );
    }
    max_abs(&err)
}

/// The issue's case: the double pendulum of `examples/double_pendulum_rough_wall.toml` (two
/// contacts on the wall, μ = 0.3, e = 0.5) under `ns_generalized_alpha`, h = 1e-3, 3 s, every
/// step recorded. Friction is no longer dropped: the run has the friction columns, friction
/// dissipates more than 1 J, the motion and the final energy differ from the frictionless
/// run's, and the final energy is the nonlinear Moreau–Jean scheme's to 0.1 J;
/// `work_friction` ≤ 0 at every step; the ledger closes at every step with
/// `work_friction` in it; the scheme's error (`energy_error`) is no larger than 2× the
/// frictionless run's, so the friction work is not left in it; P_t = −μ P_n on a sliding
/// impact step.
#[test]
fn the_double_pendulum_on_a_rough_wall_dissipates_by_friction_and_closes_its_ledger() {
    let mut rough = example_json("double_pendulum_rough_wall");
    rough["integrator"] = ns_alpha();
    rough["output"] = json!({"every": 1, "probes": [0, 1]});
    let mut smooth = rough.clone();
    for c in smooth["model"]["contacts"]
        .as_array_mut()
        .expect("contacts")
    {
        c["friction"] = json!(0.0);
    }
    let (r, summary) = record(&rough);
    let (s, _) = record(&smooth);
    assert!(s.column("pt_1").is_none() && s.column("work_friction_total").is_none());
    let last = r.rows.len() - 1;
    let (er, es) = (col(&r, "energy")[last], col(&s, "energy")[last]);
    let friction_total = col(&r, "work_friction_total")[last];
    let error_rough = assert_ledger(&r, "μ = 0.3");
    let error_smooth = max_abs(&col(&s, "energy_error"));
    println!(
        "E(3) = {er:.4} with μ = 0.3, {es:.4} with μ = 0; Σ work_friction {friction_total:.4}, Σ work_contact {:.4}; max |energy_error| {error_rough:.2e} (μ = 0: {error_smooth:.2e}); summary work_friction_max {}",
        col(&r, "work_contact_total")[last],
        summary["work_friction_max"]
    );
    assert!(
        friction_total < -1.0,
        "friction dissipated {friction_total}"
    );
    // The motion differs from the frictionless one, and the energy at the end agrees with the
    // nonlinear Moreau–Jean scheme's on the same model (−25.19 J, the example's `[check]`).
    let (p1r, p1s) = (col(&r, "q_1")[last], col(&s, "q_1")[last]);
    assert!((p1r - p1s).abs() > 1e-2, "q_1(3) = {p1r} and {p1s}");
    assert!(
        (er - es).abs() > 0.1,
        "E(3) = {er} with friction, {es} without"
    );
    assert!(
        (er + 25.19).abs() <= 0.1,
        "E(3) = {er} against −25.19 under moreau_jean"
    );
    assert_eq!(
        summary["work_friction_total"].as_f64(),
        Some(friction_total)
    );
    assert!(summary["work_friction_max"].as_f64().expect("max") <= 1e-12);
    assert_dissipative(&r, 2, "μ = 0.3");
    assert!(
        error_rough <= 2.0 * error_smooth,
        "energy_error {error_rough:e} against {error_smooth:e} without friction"
    );
    // A sliding impact: |U_t| > 0 after it, and the tangential impulse on Coulomb's cone.
    let (p, pt, ut) = (col(&r, "p_1"), col(&r, "pt_1"), col(&r, "ut_1"));
    let sliding = (0..p.len())
        .filter(|&k| p[k] > 1e-3 && ut[k].abs() > 1e-6)
        .inspect(|&k| {
            assert!(
                (pt[k] + 0.3 * p[k] * ut[k].signum()).abs() <= 1e-10 * p[k],
                "record {k}: P_t {} against −μ P_n sign(U_t) = {}",
                pt[k],
                -0.3 * p[k] * ut[k].signum()
            )
        })
        .count();
    assert!(sliding >= 1, "no sliding impact");
}

/// A point mass (x, y) under gravity thrown at a rough vertical wall x = 0.5 (e = 0.5, μ = 0.3,
/// tangent y), 1 s at h = 1e-3: it hits the wall once, sliding up it through the impact
/// (P_t = −μ P_n, U_t > 0 after), and its energy balance closes at round-off at every step
/// (|energy_error| ≤ 1e-13 × the energy's scale: M is constant and the wall is along gravity,
/// so only the impulses of the velocity stage change the energy, by exactly their work),
/// with `work_friction` < 0 at the impact and ≤ 0 everywhere.
#[test]
fn a_mass_thrown_at_a_rough_wall_closes_its_energy_balance_at_round_off() {
    let spec = json!({
        "model": {
            "scene": "lagrangian",
            "coordinates": ["x", "y"],
            "parameters": {"m": 2.0, "g": 9.81},
            "mass": [["m", 0], [0, "m"]],
            "potential": "m*g*y",
            "q0": [0.0, 0.0],
            "v0": [2.0, 4.0],
            "contacts": [{"gap": "0.5 - x", "restitution": 0.5, "friction": 0.3, "tangent": "y"}]
        },
        "integrator": ns_alpha(),
        "time": {"h": 1e-3, "t_end": 1.0},
        "output": {"every": 1, "probes": [0, 1]}
    });
    let (rec, _) = record(&spec);
    let error = assert_ledger(&rec, "mass on a wall");
    let scale = max_abs(&col(&rec, "energy")).max(max_abs(&col(&rec, "kinetic")));
    let (p, pt, ut, wf) = (
        col(&rec, "p_0"),
        col(&rec, "pt_0"),
        col(&rec, "ut_0"),
        col(&rec, "work_friction"),
    );
    let impacts: Vec<usize> = (0..p.len()).filter(|&k| p[k] > 0.0).collect();
    println!(
        "impacts at records {impacts:?}: P_n {:?}, P_t {:?}, U_t {:?}, work_friction {:?}; max |energy_error| {error:e} (scale {scale})",
        impacts.iter().map(|&k| p[k]).collect::<Vec<_>>(),
        impacts.iter().map(|&k| pt[k]).collect::<Vec<_>>(),
        impacts.iter().map(|&k| ut[k]).collect::<Vec<_>>(),
        impacts.iter().map(|&k| wf[k]).collect::<Vec<_>>(),
    );
    assert_eq!(impacts.len(), 1, "one impact");
    let k = impacts[0];
    assert!(
        ut[k] > 0.1,
        "sliding up the wall after the impact: U_t = {}",
        ut[k]
    );
    assert!((pt[k] + 0.3 * p[k]).abs() <= 1e-12 * p[k]);
    assert!(wf[k] < -0.1, "friction work at the impact {}", wf[k]);
    assert!(error <= 1e-13 * scale, "energy_error {error:e}");
    assert_dissipative(&rec, 1, "mass on a wall");
}

/// A block (x, y) sliding on a rough floor y ≥ 0 (e = 0, μ = 0.3) from v0 = 3: the smooth
/// stage has no contact force, so each step's velocity stage takes P_n = m g h and, while the
/// block slides, P_t = −μ m g h: v_x drops by exactly μ g h per step (to round-off), and
/// x_{k+1} = x_k + h v_k. The block stops at the first step whose start velocity is below
/// μ g h, after the distance h Σ_{k=0}^{K} (v0 − k μ g h), K = ⌊v0/(μ g h)⌋ (to round-off):
/// v0²/(2 μ g) + O(h), first order; measured at h = 1e-3 and 5e-4, the distance's error
/// against v0²/(2 μ g) is below v0 h and halves with h.
#[test]
fn a_block_on_a_rough_floor_decelerates_at_mu_g_and_stops_at_the_closed_form_distance() {
    let (v0, mu, g) = (3.0f64, 0.3f64, 9.81f64);
    let exact = v0 * v0 / (2.0 * mu * g);
    let mut errors = Vec::new();
    for h in [1e-3, 5e-4] {
        let spec = json!({
            "model": {
                "scene": "lagrangian",
                "coordinates": ["x", "y"],
                "parameters": {"m": 1.5, "g": g},
                "mass": [["m", 0], [0, "m"]],
                "potential": "m*g*y",
                "q0": [0.0, 0.0],
                "v0": [v0, 0.0],
                "contacts": [{"gap": "y", "restitution": 0.0, "friction": mu, "tangent": "x"}]
            },
            "integrator": ns_alpha(),
            "time": {"h": h, "t_end": 1.5},
            "output": {"every": 1, "probes": [0, 1]}
        });
        let (rec, _) = record(&spec);
        let (x, v) = (col(&rec, "q_0"), col(&rec, "v_0"));
        let dv = mu * g * h;
        let steps = (v0 / dv).floor() as usize;
        for k in 0..steps {
            assert!(
                (v[k + 1] - (v[k] - dv)).abs() <= 1e-12 * v0,
                "h = {h}, step {k}: v {} → {}",
                v[k],
                v[k + 1]
            );
        }
        assert!(v[steps + 1].abs() <= 1e-12 * v0, "h = {h}: still moving");
        assert!(
            max_abs(&v[steps + 1..]) <= 1e-12 * v0,
            "h = {h}: moved again"
        );
        let discrete: f64 = h * (0..=steps).map(|k| v0 - k as f64 * dv).sum::<f64>();
        let distance = *x.last().expect("a record");
        println!(
            "h = {h}: stopped after {} steps at x = {distance:.9}, discrete closed form {discrete:.9}, v0²/(2μg) = {exact:.9}",
            steps + 1
        );
        assert!((distance - discrete).abs() <= 1e-12 * exact, "h = {h}");
        assert!((distance - exact).abs() <= v0 * h, "h = {h}");
        errors.push(distance - exact);
    }
    let ratio = errors[0] / errors[1];
    assert!(
        (1.8..=2.2).contains(&ratio),
        "errors {errors:?}: ratio {ratio}"
    );
}

/// μ = 0 on every contact (the tangents kept) is the frictionless model bit for bit: same
/// columns, same values, same summary. And μ = 0.3 on the upper mass's contact alone, which
/// never enters the index set in these 3 s, leaves every frictionless column bit for bit:
/// without friction on the index set the step is the frictionless one, operation for
/// operation.
#[test]
fn zero_friction_and_friction_off_the_index_set_are_the_frictionless_run_bit_for_bit() {
    let mut rough = example_json("double_pendulum_rough_wall");
    rough["integrator"] = ns_alpha();
    rough["output"] = json!({"every": 1, "probes": [0, 1]});
    let mut frictionless = rough.clone();
    let mut zero = rough.clone();
    let mut upper = rough.clone();
    for a in 0..2 {
        let c = frictionless["model"]["contacts"][a]
            .as_object_mut()
            .expect("contact");
        c.remove("friction");
        c.remove("tangent");
        zero["model"]["contacts"][a]["friction"] = json!(0.0);
    }
    upper["model"]["contacts"][1]["friction"] = json!(0.0);
    let (f, fs) = record(&frictionless);
    let (z, zs) = record(&zero);
    assert_eq!(f.columns.names(), z.columns.names());
    assert_eq!(f.t, z.t);
    assert_eq!(f.rows.len(), z.rows.len());
    for (a, b) in f.rows.iter().zip(&z.rows) {
        let (a, b): (Vec<u64>, Vec<u64>) = (
            a.iter().map(|x| x.to_bits()).collect(),
            b.iter().map(|x| x.to_bits()).collect(),
        );
        assert_eq!(a, b);
    }
    assert_eq!(fs, zs);
    let (u, _) = record(&upper);
    assert!(
        col(&u, "p_0").iter().all(|&p| p == 0.0),
        "the upper mass hit"
    );
    assert!(col(&u, "work_friction_total").iter().all(|&w| w == 0.0));
    for name in f.columns.names() {
        let (a, b) = (col(&f, name), col(&u, name));
        assert!(
            a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
            "column {name} differs"
        );
    }
}
