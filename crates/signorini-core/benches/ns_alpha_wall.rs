//! Error against CPU time on the pendulum against a wall (`examples/pendulum_wall.toml`: a point
//! mass on a rod of length 1, θ₀ = 1 rad, the wall through the pivot, gap sin θ ≥ 0),
//! nonlinear Moreau–Jean θ = ½ against the nonsmooth generalized-α ρ∞ = 0.8. Plain `fn main`:
//!
//! ```text
//! cargo bench -p signorini-core --bench ns_alpha_wall
//! ```
//!
//! Writes `docs/ns_generalized_alpha/wall.csv` and `double_pendulum.csv` and prints one line per run. For each restitution
//! e ∈ {0.5, 0.8} and h = 2⁻ʲ·10⁻², j = 0…6, over t ∈ [0, 3] (three impacts):
//!
//! * `err_theta` = max_k |θ_h(t_k) − θ(t_k)|, against a reference by RK4 (step 1e-4) whose
//!   impacts are located by bisection and resolved by ω⁺ = −e ω⁻ (error ≪ 1e-10);
//! * `err_energy` = max over the impacts of |E_after/E_before − e²|, E_after the energy at the
//!   end of the impact step, E_before at its start — the exact ratio is e², since the wall is at
//!   the bottom of the swing;
//! * `err_smooth` = |θ_h(t) − θ(t)| at t = 0.4 s, before the first impact (≈ 0.53 s).
//!
//! And without contact, where M depends on q: the double pendulum in angles (unit masses and
//! lengths, from both rods horizontal, at rest), `err_q` = max_j |q_j(1) − q_j,ref(1)| against
//! RK4 on the same compiled model (M(q) q̈ = F, step 1e-4), same step sizes.
//!
//! Cost: building the scheme and the whole run through the public run loops with every step
//! recorded, best of 3 repetitions, each repeating the run until it lasts ≥ 30 ms.

// Only the core library must stay pure (clippy.toml): a benchmark times itself and prints.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::integrators::OutputOptions;
use signorini_core::lagrangian::UserModel;
use signorini_core::lcp::LcpOptions;
use signorini_core::nonlinear::LagrangianSystem;
use signorini_core::nonlinear::generalized_alpha::{NonsmoothGeneralizedAlpha, NsAlphaParams};
use signorini_core::nonlinear::moreau_jean::{
    NonlinearMoreauJean, NonlinearMoreauJeanParams, NonlinearState,
};
use signorini_core::nonlinear::run::{run_nonlinear, run_ns_alpha};
use signorini_core::observer::Recorder;
use signorini_core::spec::{JobSpec, ModelSpec};
use std::hint::black_box;
use std::path::Path;
use std::time::{Duration, Instant};

const T_END: f64 = 3.0;
const G: f64 = 9.81;
const REF_STEP: f64 = 1e-4;

/// One RK4 step of θ'' = −g sin θ (L = 1).
fn rk4(th: f64, om: f64, dt: f64) -> (f64, f64) {
    let f = |th: f64, om: f64| (om, -G * th.sin());
    let (k1t, k1o) = f(th, om);
    let (k2t, k2o) = f(th + 0.5 * dt * k1t, om + 0.5 * dt * k1o);
    let (k3t, k3o) = f(th + 0.5 * dt * k2t, om + 0.5 * dt * k2o);
    let (k4t, k4o) = f(th + dt * k3t, om + dt * k3o);
    (
        th + dt / 6.0 * (k1t + 2.0 * k2t + 2.0 * k3t + k4t),
        om + dt / 6.0 * (k1o + 2.0 * k2o + 2.0 * k3o + k4o),
    )
}

/// The exact motion (to ≪ 1e-10) at the times `grid`, increasing.
fn reference(e: f64, grid: &[f64]) -> Vec<f64> {
    let (mut t, mut th, mut om) = (0.0, 1.0, 0.0);
    let mut out = Vec::with_capacity(grid.len());
    for &tk in grid {
        while tk - t > 1e-14 {
            let dt = REF_STEP.min(tk - t);
            let (th1, om1) = rk4(th, om, dt);
            if th1 < 0.0 {
                // The impact inside this substep: θ(τ) = 0 by bisection on RK4 from (th, om).
                let (mut lo, mut hi) = (0.0, dt);
                while hi - lo > 1e-17 {
                    let mid = 0.5 * (lo + hi);
                    if rk4(th, om, mid).0 < 0.0 {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                let (_, om_c) = rk4(th, om, hi);
                t += hi;
                th = 0.0;
                om = -e * om_c;
                continue;
            }
            t += dt;
            th = th1;
            om = om1;
        }
        out.push(th);
    }
    out
}

fn time_best<R>(reps: usize, mut f: impl FnMut() -> R) -> (f64, R) {
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..reps {
        let start = Instant::now();
        let mut calls = 0u32;
        loop {
            last = Some(black_box(f()));
            calls += 1;
            if start.elapsed() >= Duration::from_millis(30) {
                break;
            }
        }
        best = best.min(start.elapsed().as_secs_f64() / f64::from(calls));
    }
    (best, last.expect("reps ≥ 1"))
}

fn model(e: f64) -> UserModel {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/pendulum_wall.toml");
    let text = std::fs::read_to_string(path).expect("reading the example");
    let spec: JobSpec = toml::from_str(&text).expect("the example parses");
    let Some(ModelSpec::Lagrangian(mut l)) = spec.model else {
        panic!("a lagrangian model")
    };
    l.contacts[0].restitution = e;
    UserModel::new(l.validate().expect("a valid model"))
}

/// The double pendulum in angles as a user model.
fn double_pendulum() -> UserModel {
    let spec: JobSpec = serde_json::from_str(
        r#"{"model": {"scene": "lagrangian", "coordinates": ["p1", "p2"],
            "parameters": {"g": 9.81},
            "mass": [["2", "cos(p1 - p2)"], ["cos(p1 - p2)", "1"]],
            "potential": "-2*g*cos(p1) - g*cos(p2)",
            "q0": [1.5707963267948966, 1.5707963267948966], "v0": [0.0, 0.0]}}"#,
    )
    .expect("spec");
    let Some(ModelSpec::Lagrangian(l)) = spec.model else {
        panic!("a lagrangian model")
    };
    UserModel::new(l.validate().expect("a valid model"))
}

/// q(t_end) by RK4 on M(q) q̈ = F(q, q̇) with step `dt`.
fn rk4_reference(system: &UserModel, t_end: f64, dt: f64) -> Vec<f64> {
    let n = system.dofs();
    let acc = |q: &[f64], v: &[f64]| -> Vec<f64> {
        let mut m = vec![0.0; n * n];
        let mut f = vec![0.0; n];
        system.mass(q, &mut m);
        system.forces(0.0, q, v, &mut f);
        let m = nalgebra::DMatrix::from_row_slice(n, n, &m);
        let x = m
            .lu()
            .solve(&nalgebra::DVector::from_column_slice(&f))
            .expect("M regular");
        x.as_slice().to_vec()
    };
    let (mut q, mut v) = system.initial();
    let steps = (t_end / dt).round() as usize;
    let axpy = |x: &[f64], a: f64, y: &[f64]| -> Vec<f64> {
        x.iter().zip(y).map(|(x, y)| x + a * y).collect()
    };
    for _ in 0..steps {
        let (k1q, k1v) = (v.clone(), acc(&q, &v));
        let (q2, v2) = (axpy(&q, 0.5 * dt, &k1q), axpy(&v, 0.5 * dt, &k1v));
        let (k2q, k2v) = (v2.clone(), acc(&q2, &v2));
        let (q3, v3) = (axpy(&q, 0.5 * dt, &k2q), axpy(&v, 0.5 * dt, &k2v));
        let (k3q, k3v) = (v3.clone(), acc(&q3, &v3));
        let (q4, v4) = (axpy(&q, dt, &k3q), axpy(&v, dt, &k3v));
        let (k4q, k4v) = (v4.clone(), acc(&q4, &v4));
        for i in 0..n {
            q[i] += dt / 6.0 * (k1q[i] + 2.0 * k2q[i] + 2.0 * k3q[i] + k4q[i]);
            v[i] += dt / 6.0 * (k1v[i] + 2.0 * k2v[i] + 2.0 * k3v[i] + k4v[i]);
        }
    }
    q
}

fn main() {
    let output = OutputOptions {
        every: 1,
        probes: vec![0],
    };
    let mut csv = String::from("scheme,e,h,steps,cpu_s,err_theta,err_energy,err_smooth\n");
    let mut csv_dp = String::from("scheme,h,steps,cpu_s,err_q\n");
    for e in [0.5, 0.8] {
        let system = model(e);
        for j in 0..7 {
            let h = 1e-2 / f64::from(1 << j);
            let steps = (T_END / h).round() as u64;
            let grid: Vec<f64> = (0..=steps).map(|k| k as f64 * h).collect();
            let exact = reference(e, &grid);
            let k_smooth = (0.4 / h).round() as usize;
            for scheme in ["moreau_jean", "ns_generalized_alpha"] {
                let (cpu, rec) = time_best(3, || {
                    let mut rec = Recorder::default();
                    let mut state = NonlinearState::initial(&system);
                    if scheme == "moreau_jean" {
                        let mut s = NonlinearMoreauJean::new(
                            &system,
                            NonlinearMoreauJeanParams::default(),
                            h,
                            LcpOptions::default(),
                        )
                        .expect("parameters");
                        run_nonlinear(&system, &mut s, &mut state, steps, &output, &mut rec)
                            .expect("runs");
                    } else {
                        let mut s = NonsmoothGeneralizedAlpha::new(
                            &system,
                            NsAlphaParams::from_rho_inf(0.8),
                            h,
                            LcpOptions::default(),
                        )
                        .expect("parameters");
                        run_ns_alpha(&system, &mut s, &mut state, steps, &output, &mut rec)
                            .expect("runs");
                    }
                    rec
                });
                let theta = rec.column("q_0").expect("q_0");
                let energy = rec.column("energy").expect("energy");
                let p = rec.column("p_0").expect("p_0");
                let err_theta = theta
                    .iter()
                    .zip(&exact)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0f64, f64::max);
                let err_smooth = (theta[k_smooth] - exact[k_smooth]).abs();
                let mut err_energy = 0.0f64;
                for k in 1..p.len() {
                    if p[k] > 0.0 && p[k - 1] == 0.0 && energy[k - 1] > 1e-3 {
                        let ratio = energy[k] / energy[k - 1];
                        err_energy = err_energy.max((ratio - e * e).abs());
                    }
                }
                println!(
                    "{scheme:22} e = {e} h = {h:.3e} steps {steps:6} cpu {cpu:.3e} s  err_theta {err_theta:.3e}  err_energy {err_energy:.3e}  err_smooth {err_smooth:.3e}"
                );
                csv.push_str(&format!(
                    "{scheme},{e},{h:e},{steps},{cpu:e},{err_theta:e},{err_energy:e},{err_smooth:e}\n"
                ));
            }
        }
    }
    let system = double_pendulum();
    let q_ref = rk4_reference(&system, 1.0, REF_STEP);
    let output = OutputOptions {
        every: 1,
        probes: vec![0, 1],
    };
    for j in 0..7 {
        let h = 1e-2 / f64::from(1 << j);
        let steps = (1.0 / h).round() as u64;
        for scheme in ["moreau_jean", "ns_generalized_alpha"] {
            let (cpu, q) = time_best(3, || {
                let mut rec = Recorder::default();
                let mut state = NonlinearState::initial(&system);
                if scheme == "moreau_jean" {
                    let mut s = NonlinearMoreauJean::new(
                        &system,
                        NonlinearMoreauJeanParams::default(),
                        h,
                        LcpOptions::default(),
                    )
                    .expect("parameters");
                    run_nonlinear(&system, &mut s, &mut state, steps, &output, &mut rec)
                        .expect("runs");
                } else {
                    let mut s = NonsmoothGeneralizedAlpha::new(
                        &system,
                        NsAlphaParams::from_rho_inf(0.8),
                        h,
                        LcpOptions::default(),
                    )
                    .expect("parameters");
                    run_ns_alpha(&system, &mut s, &mut state, steps, &output, &mut rec)
                        .expect("runs");
                }
                state.q
            });
            let err_q = q
                .iter()
                .zip(&q_ref)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f64, f64::max);
            println!(
                "double pendulum {scheme:22} h = {h:.3e} steps {steps:6} cpu {cpu:.3e} s  err_q {err_q:.3e}"
            );
            csv_dp.push_str(&format!("{scheme},{h:e},{steps},{cpu:e},{err_q:e}\n"));
        }
    }
    let out = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/ns_generalized_alpha");
    std::fs::create_dir_all(&out).expect("creating docs/ns_generalized_alpha");
    std::fs::write(out.join("wall.csv"), csv).expect("writing wall.csv");
    std::fs::write(out.join("double_pendulum.csv"), csv_dp).expect("writing double_pendulum.csv");
}
