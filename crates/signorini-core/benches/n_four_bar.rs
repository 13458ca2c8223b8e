//! IFToMM A02, the N-four-bar mechanism (docs/benchmarks.md): cost per step, Newton iterations
//! and the error of B0 against the exact motion, for N loops and each scheme that takes joints.
//!
//! `cargo bench -p signorini-core --bench n_four_bar -- [--loops 10,40,160] [--t-end 1]
//! [--h 0.001] [--schemes soi2_generalized_alpha,soi2_hht,hht_i3,ns_generalized_alpha]
//! [--newton full|simplified]` (`--newton`: every scheme's Newton strategy; each scheme's own
//! default without it)
//! (plain main, harness = false). CPU seconds of the process, so a busy machine shows in the
//! wall column but not in the CPU one.

// Only the core library must stay pure (clippy.toml): a benchmark times itself and prints.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use serde_json::{Value, json};
use signorini_core::job::{Job, run};
use signorini_core::observer::Recorder;
use signorini_core::outcome::SummaryBody;
use signorini_core::spec::JobSpec;
use std::time::Instant;

fn cpu_seconds() -> f64 {
    // Process CPU time (the machine is shared): /proc/self/stat utime + stime in clock ticks.
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit_once(')').map(|(_, r)| r).unwrap_or("");
    let f: Vec<&str> = after.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (ticks(11) + ticks(12)) / 100.0
}

/// The A02 spec with `n` loops (as `examples/benchmarks/n_four_bar.py` writes it), recording
/// every 10th step and the rockers' angles.
fn four_bar_spec(n: usize, integrator: &Value, h: f64, t_end: f64) -> Value {
    let mut names = Vec::new();
    let mut entries = Vec::new();
    for i in 0..=n {
        names.push(format!("p{i}"));
        let k = 2 * i;
        entries.push(json!([
            k,
            k,
            if i < n { "m*L^2/3 + m*L^2" } else { "m*L^2/3" }
        ]));
        if i < n {
            names.push(format!("s{}", i + 1));
            entries.push(json!([k, k + 1, format!("m*L^2/2*cos(p{i} - s{})", i + 1)]));
            entries.push(json!([k + 1, k + 1, "m*L^2/3"]));
        }
    }
    let potential: Vec<String> = (0..=n)
        .map(|i| format!("m*g*L/2*sin(p{i})"))
        .chain((0..n).map(|i| format!("m*g*(L*sin(p{i}) + L/2*sin(s{}))", i + 1)))
        .collect();
    let constraints: Vec<Value> = (1..=n)
        .flat_map(|i| {
            [
                json!({"expr": format!("L*cos(p{}) + L*cos(s{i}) - L*cos(p{i}) - L", i - 1)}),
                json!({"expr": format!("L*sin(p{}) + L*sin(s{i}) - L*sin(p{i})", i - 1)}),
            ]
        })
        .collect();
    let rocker = |name: &String, yes: f64| if name.starts_with('p') { yes } else { 0.0 };
    let q0: Vec<f64> = names
        .iter()
        .map(|s| rocker(s, std::f64::consts::FRAC_PI_2))
        .collect();
    let v0: Vec<f64> = names.iter().map(|s| rocker(s, -1.0)).collect();
    json!({
        "model": {
            "scene": "lagrangian",
            "coordinates": names,
            "parameters": {"m": 1.0, "L": 1.0, "g": 9.81},
            "mass": {"entries": entries},
            "potential": potential.join(" + "),
            "q0": q0,
            "v0": v0,
            "constraints": constraints
        },
        "integrator": integrator,
        "time": {"h": h, "t_end": t_end},
        "output": {"every": 10, "probes": [0]}
    })
}

/// θ(t) of the parallelogram branch (classical Runge–Kutta at h = 10⁻⁴), at increasing `ts`.
fn four_bar_angle(n: usize, ts: &[f64]) -> Vec<f64> {
    let inertia = (n as f64 + 1.0) / 3.0 + n as f64;
    let c = 9.81 * (3.0 * n as f64 + 1.0) / 2.0;
    let f = |th: f64, w: f64| (w, -c * th.cos() / inertia);
    let (mut th, mut w, mut t) = (std::f64::consts::FRAC_PI_2, -1.0, 0.0);
    let mut out = Vec::with_capacity(ts.len());
    for &target in ts {
        while t < target - 1e-12 {
            let h = (target - t).min(1e-4);
            let k1 = f(th, w);
            let k2 = f(th + h / 2.0 * k1.0, w + h / 2.0 * k1.1);
            let k3 = f(th + h / 2.0 * k2.0, w + h / 2.0 * k2.1);
            let k4 = f(th + h * k3.0, w + h * k3.1);
            th += h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
            w += h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
            t += h;
        }
        out.push(th);
    }
    out
}

fn integrator(scheme: &str, newton: Option<&str>) -> Value {
    let mut doc = match scheme {
        "soi2_hht" | "hht_i3" => json!({"scheme": scheme, "alpha": -0.05}),
        _ => json!({"scheme": scheme}),
    };
    if let Some(newton) = newton {
        doc["newton"] = json!(newton);
    }
    doc
}

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let loops: Vec<usize> = arg(&args, "--loops")
        .unwrap_or_else(|| "10,40".into())
        .split(',')
        .map(|v| v.parse().expect("--loops N,N,…"))
        .collect();
    let t_end: f64 = arg(&args, "--t-end").map_or(1.0, |v| v.parse().expect("--t-end"));
    let h: f64 = arg(&args, "--h").map_or(1e-3, |v| v.parse().expect("--h"));
    let schemes = arg(&args, "--schemes")
        .unwrap_or_else(|| "soi2_generalized_alpha,soi2_hht,hht_i3,ns_generalized_alpha".into());
    let newton = arg(&args, "--newton");
    println!("A02 over {t_end} s at h = {h}\n");
    println!(
        "| N | scheme | steps | CPU s | wall s | steps/s (CPU) | Newton it/step | Jacobians/step | B0 error (m) | energy drift |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for &n in &loops {
        for scheme in schemes.split(',') {
            let doc = four_bar_spec(n, &integrator(scheme, newton.as_deref()), h, t_end);
            let spec: JobSpec = serde_json::from_value(doc).expect("a spec");
            let (w0, c0) = (Instant::now(), cpu_seconds());
            let job = Job::from_spec(&spec).expect("a valid spec");
            let compiled = cpu_seconds() - c0;
            let mut rec = Recorder::default();
            let out = match run(&job, 1, &mut rec) {
                Ok(out) => out,
                Err(e) => {
                    println!("| {n} | {scheme} | failed: {e} |");
                    continue;
                }
            };
            let (wall, cpu) = (w0.elapsed().as_secs_f64(), cpu_seconds() - c0);
            let (steps, iterations, jacobians) = match &out.summary.body {
                SummaryBody::Soi2(s) => (
                    s.steps,
                    s.newton_iterations_mean,
                    s.newton_jacobians_total as f64 / s.steps as f64,
                ),
                SummaryBody::NsAlpha(s) => (
                    s.stats.base.steps,
                    s.stats.base.newton_iterations_mean,
                    s.stats.newton_jacobians_total as f64 / s.stats.base.steps as f64,
                ),
                _ => unreachable!("a jointed run"),
            };
            let exact = four_bar_angle(n, &rec.t);
            let first = rec
                .column("y_0")
                .or_else(|| rec.column("q_0"))
                .expect("φ_0");
            let error = first
                .iter()
                .zip(&exact)
                .map(|(phi, th)| (phi.cos() - th.cos()).hypot(phi.sin() - th.sin()))
                .fold(0.0, f64::max);
            let energy = rec.column("energy").expect("energy");
            let drift = energy
                .iter()
                .map(|e| (e - energy[0]).abs())
                .fold(0.0, f64::max)
                / energy[0].abs();
            println!(
                "| {n} | {scheme} | {steps} | {cpu:.2} | {wall:.2} | {:.0} | {iterations:.2} | {jacobians:.3} | {error:.2e} | {drift:.1e} |",
                steps as f64 / cpu.max(1e-9),
            );
            eprintln!(
                "  (N = {n}: validation and compilation {compiled:.3} s CPU, included; last φ_0 {:?}, to compare runs bit for bit)",
                first.last().copied().unwrap_or(f64::NAN)
            );
        }
    }
}
