//! What compiling a `lagrangian` model costs against its size (issue 27: "a 10⁴-coordinate
//! chain with a banded M compiled in < 1 s and < 200 MB"). The model is a bar of n nodes on a
//! line, written as a user would: coordinates x0…x(n−1), the consistent mass matrix of linear
//! bar elements as the `entries` of its upper triangle (tridiagonal, constant), the potential a
//! flat sum of n − 1 spring terms and n gravity terms, the first node held by a joint
//! (`x0 = 0`) and the last one above a floor (a contact). Per n: the seconds to parse the TOML,
//! to validate it (`LagrangianSpec::validate`: the symbolic checks at q0) and to compile it
//! (`UserModel::new`: the derivatives and their tapes), in wall time (`*_s`) and in CPU time of
//! the thread (`*_cpu_s`, from `/proc/thread-self/schedstat`: what to compare on a loaded
//! machine), and the process's peak resident memory after it (VmHWM; the sizes run in
//! increasing order, so the peak is the largest model's). With `--run STEPS [--scheme S]` each
//! bar is then run STEPS steps under `moreau_jean` (or S, e.g. `ns_generalized_alpha`): what
//! running a model of that size costs (CPU seconds, ms a step, peak memory) and its ledger and
//! joint residual.
//!
//! `cargo bench -p signorini-core --bench compile_cost [-- --sizes 100,1000,10000] [--run 2000
//! [--scheme ns_generalized_alpha]]`
//! (the default sizes are 100, 1 000 and 10 000).

// Only the core library must stay pure (clippy.toml): a benchmark times itself and prints.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::job::{Job, run};
use signorini_core::lagrangian::UserModel;
use signorini_core::observer::Recorder;
use signorini_core::spec::{JobSpec, LagrangianSpec};
use std::fmt::Write;
use std::time::Instant;

/// The bar of `n` nodes as a `lagrangian` model in TOML.
fn bar_spec(n: usize) -> String {
    let mut s = String::new();
    let names: Vec<String> = (0..n).map(|i| format!("x{i}")).collect();
    writeln!(s, "coordinates = {names:?}").unwrap();
    writeln!(s, "parameters = {{ m = 0.01, k = 1.0e4, g = 9.81 }}").unwrap();
    // Consistent mass of bar elements of mass m: m/3 on each end's diagonal, m/6 between them.
    let mut entries = Vec::with_capacity(2 * n);
    for i in 0..n {
        let ends = if i == 0 || i + 1 == n { 1 } else { 2 };
        entries.push(format!("[{i}, {i}, \"{ends}*m/3\"]"));
        if i + 1 < n {
            entries.push(format!("[{i}, {}, \"m/6\"]", i + 1));
        }
    }
    writeln!(s, "mass = {{ entries = [{}] }}", entries.join(", ")).unwrap();
    let mut potential = Vec::with_capacity(2 * n);
    for i in 0..n - 1 {
        potential.push(format!("k/2*(x{} - x{i})^2", i + 1));
    }
    for i in 0..n {
        potential.push(format!("m*g*x{i}"));
    }
    writeln!(s, "potential = \"{}\"", potential.join(" + ")).unwrap();
    writeln!(s, "q0 = {:?}", vec![0.0; n]).unwrap();
    writeln!(s, "constraints = [{{ expr = \"x0\" }}]").unwrap();
    writeln!(s, "contacts = [{{ gap = \"x{} + 1\" }}]", n - 1).unwrap();
    s
}

/// CPU time of this thread so far, in seconds (NaN where the kernel does not say).
fn cpu_s() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .map_or(f64::NAN, |ns| ns * 1e-9)
}

/// The process's peak resident set (VmHWM), in MiB.
fn peak_mib() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let sizes: Vec<usize> = args
        .iter()
        .position(|a| a == "--sizes")
        .and_then(|i| args.get(i + 1))
        .map(|s| {
            s.split(',')
                .map(|x| x.parse().expect("--sizes N,N,…"))
                .collect()
        })
        .unwrap_or_else(|| vec![100, 1_000, 10_000]);
    let run_steps: Option<u64> = args
        .iter()
        .position(|a| a == "--run")
        .and_then(|i| args.get(i + 1))
        .map(|s| s.parse().expect("--run STEPS"));
    let scheme = args
        .iter()
        .position(|a| a == "--scheme")
        .and_then(|i| args.get(i + 1))
        .map_or("moreau_jean", String::as_str);
    for n in sizes {
        let text = bar_spec(n);
        let (t0, c0) = (Instant::now(), cpu_s());
        let spec: LagrangianSpec = toml::from_str(&text).expect("the bar spec parses");
        let (t1, c1) = (Instant::now(), cpu_s());
        let params = spec.validate().expect("the bar spec is valid");
        let (t2, c2) = (Instant::now(), cpu_s());
        let model = UserModel::new(params);
        let (t3, c3) = (Instant::now(), cpu_s());
        std::hint::black_box(&model);
        println!(
            "{{\"bench\":\"compile_bar\",\"n\":{n},\"spec_bytes\":{},\"parse_s\":{:.4},\"validate_s\":{:.4},\"compile_s\":{:.4},\"parse_cpu_s\":{:.4},\"validate_cpu_s\":{:.4},\"compile_cpu_s\":{:.4},\"peak_mib\":{:.1}}}",
            text.len(),
            (t1 - t0).as_secs_f64(),
            (t2 - t1).as_secs_f64(),
            (t3 - t2).as_secs_f64(),
            c1 - c0,
            c2 - c1,
            c3 - c2,
            peak_mib(),
        );
        if let Some(steps) = run_steps {
            run_bar(&text, n, steps, scheme);
        }
    }
}

/// Runs the bar `steps` steps under `scheme` (its defaults; θ = ½ for `moreau_jean`; h = 10⁻⁴,
/// every 100th step recorded)
/// through the job path, and prints the CPU seconds of the run (validation and compilation
/// again included), the peak memory after it, the largest |energy_error| and joint residual.
fn run_bar(model: &str, n: usize, steps: u64, scheme: &str) {
    let mut model: serde_json::Value = toml::from_str(model).expect("the bar spec parses");
    model["scene"] = "lagrangian".into();
    let doc = serde_json::json!({
        "name": format!("bar of {n} nodes"),
        "model": model,
        "integrator": if scheme == "moreau_jean" {
            serde_json::json!({ "scheme": scheme, "theta": 0.5 })
        } else {
            serde_json::json!({ "scheme": scheme })
        },
        "time": { "h": 1e-4, "steps": steps },
        "output": { "every": 100 },
    });
    let spec: JobSpec = serde_json::from_value(doc).expect("a job spec");
    let c0 = cpu_s();
    let job = Job::from_spec(&spec).expect("a valid job");
    let mut rec = Recorder::default();
    run(&job, 1, &mut rec).expect("the bar runs");
    let cpu = cpu_s() - c0;
    let amax = |name: &str| {
        rec.column(name)
            .expect("a column")
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()))
    };
    println!(
        "{{\"bench\":\"run_bar\",\"n\":{n},\"scheme\":\"{scheme}\",\"steps\":{steps},\"run_cpu_s\":{cpu:.3},\"ms_per_step\":{:.4},\"peak_mib\":{:.1},\"max_energy_error\":{:.2e},\"max_position_residual\":{:.2e}}}",
        1e3 * cpu / steps as f64,
        peak_mib(),
        amax("energy_error"),
        amax("position_residual"),
    );
}
