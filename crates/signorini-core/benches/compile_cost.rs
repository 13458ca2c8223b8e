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
//! increasing order, so the peak is the largest model's).
//!
//! `cargo bench -p signorini-core --bench compile_cost [-- --sizes 100,1000,10000]` (the
//! default sizes are 100, 1 000 and 10 000).

// Only the core library must stay pure (clippy.toml): a benchmark times itself and prints.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::lagrangian::UserModel;
use signorini_core::spec::LagrangianSpec;
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
    }
}
