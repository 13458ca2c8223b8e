//! Work–precision diagrams: error against CPU time, per integrator, on two scenes
//! with an exact solution, run from the study specs in `examples/` by the core's study code
//! (`signorini_core::study`: the same expansion, errors, fits as `signorini run STUDY.toml` and
//! the service). Plain `fn main` (`harness = false`):
//!
//! ```text
//! cargo bench -p signorini-core --bench work_precision            # ≈ 2 min
//! cargo bench -p signorini-core --bench work_precision -- --quick # N ≤ 200, j ≤ 4, 1 repetition
//! ```
//!
//! Writes `docs/work_precision/`: `dep_bar.csv`, `dep_bar.svg` (displacement error),
//! `dep_bar_force.svg` (impulse error), `dep_bar_trace.{csv,svg}` (u(L, t) of every scheme at
//! N = 100, c_r = 1), `ball.csv`, `ball.svg` (a bench may write files; the core crate does no
//! I/O), and prints one line per run and the observed orders.
//!
//! **Scene 1, the Doyen–Ern–Piperno bar**: `examples/work_precision_dep_bar.toml` (c_r = 1, the
//! WFEM too) and `examples/work_precision_dep_bar_cr4.toml` (c_r = 4), against the exact solution
//! by characteristics. `err_u` is the study's `max_abs` norm (of the contact-end gap, so of the
//! displacement u = g0 − gap); `err_force` the same runs in the study's `impulse_l1` norm (the
//! relative L¹ error of the contact impulse per step). The trace is the c_r = 1 runs at N = 100.
//!
//! **Scene 2, the bouncing ball**: `examples/work_precision_ball.toml`, |q_h − q| at t = 1.7 s
//! (the `final` norm). Where the impacts fall inside a step makes this error jump by 10× between
//! neighbouring h, so each plotted point is the largest error over the eight step sizes of one
//! level j of the grid (`err_q_envelope`; the CPU time is that of its first h). The envelope is a
//! maximum over runs, not a norm of one run, so it stays here, over the study's points.
//!
//! **Cost.** One run = `job::run` of the study's validated job (building the scheme, then the
//! whole integration, every step recorded into the study's `Samples`, energy bookkeeping on), as
//! `signorini run` does it; the errors are computed from the samples after the clock stops. Time
//! is wall-clock (`Instant`) of this single-threaded process, best of `REPS` repetitions, each
//! repetition repeating short runs until it lasts ≥ 30 ms; on the shared 2-core VM the best-of
//! filters out most preemption by other jobs.

// Only the core library must stay pure (clippy.toml): a benchmark times itself and prints.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::job;
use signorini_core::spec::JobSpec;
use signorini_core::spec::study::ErrorNorm;
use signorini_core::study::{Samples, Study, StudyPoint, StudyReport, StudyRun, inline_base};
use std::fmt::Write as _;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// End of the bar runs (s).
const T_BAR: f64 = 6.0;
/// Step sizes per point of the ball's error envelope (one level of its grid).
const ENVELOPE: usize = 8;
/// Elements of the trace.
const TRACE_N: f64 = 100.0;

/// The study of `examples/NAME`, expanded by the core (the base inline).
fn study(name: &str) -> Study {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .join(name);
    let text = std::fs::read_to_string(&path).expect("reading the study");
    let spec: JobSpec = toml::from_str(&text).expect("a study spec");
    let study_spec = spec.study.as_ref().expect("[study]");
    let base = inline_base(study_spec).expect("an inline base");
    Study::from_spec(study_spec, base)
        .unwrap_or_else(|e| panic!("{name}: {}: {}", e.field, e.reason))
}

/// The same study judged in another norm.
fn in_norm(study: &Study, norm: ErrorNorm) -> Study {
    let mut spec = study.spec.clone();
    spec.error = norm;
    let base = inline_base(&spec).expect("an inline base");
    Study::from_spec(&spec, base).expect("the same study")
}

/// Best time of `reps` repetitions of `f`, each repeating `f` until it lasts ≥ 30 ms; returns
/// seconds per call and the last result.
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

/// One run of a study, timed: its samples (or why it failed) and CPU seconds.
struct Ran<'a> {
    run: &'a StudyRun,
    cpu: f64,
    samples: Result<Samples, String>,
}

/// Runs the runs of `study` kept by `keep`, in order, each timed (best of `reps`).
fn run_study<'a>(
    study: &'a Study,
    reps: usize,
    keep: impl Fn(usize, &StudyRun) -> bool,
) -> Vec<Ran<'a>> {
    study
        .runs
        .iter()
        .enumerate()
        .filter(|(i, r)| keep(*i, r))
        .map(|(_, run)| {
            let (cpu, samples) = time_best(reps, || {
                let mut samples = Samples::default();
                job::run(&run.job, 1, &mut samples)
                    .map(|_| samples)
                    .map_err(|e| e.to_string())
            });
            Ran { run, cpu, samples }
        })
        .collect()
}

/// The study's point of a run (an empty error for a failed one), as the CLI and the service make
/// it.
fn point(study: &Study, ran: &Ran<'_>) -> StudyPoint {
    match &ran.samples {
        Ok(s) => {
            let error = study.error(s, None).unwrap_or(f64::NAN);
            StudyPoint::new(ran.run, ran.run.job.size().steps, ran.cpu, error, Some(s))
        }
        Err(_) => StudyPoint::new(ran.run, 0, f64::NAN, f64::NAN, None),
    }
}

/// Prints the observed orders of a study's points.
fn print_orders(name: &str, study: &Study, points: Vec<StudyPoint>) {
    for o in StudyReport::new(study, points).orders() {
        println!(
            "# {name}: observed order {:.3} ({}, {} runs)",
            o.order, o.scheme, o.points
        );
    }
}

/// One point of a diagram.
#[derive(Debug, Clone)]
struct Point {
    series: String,
    cpu: f64,
    err: f64,
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let reps = if quick { 1 } else { 3 };
    let out = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../docs/work_precision");
    std::fs::create_dir_all(&out).expect("create docs/work_precision");
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "# work–precision, {} hardware threads, load {}",
        std::thread::available_parallelism().map_or(1, |x| x.get()),
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
    let (bar_u, bar_f) = dep_bar(&out, quick, reps);
    let ball = bouncing_ball(&out, quick, reps);
    let write = |name: &str, text: String| {
        std::fs::write(out.join(name), text).expect("write svg");
    };
    write(
        "dep_bar.svg",
        svg_plot(
            "Doyen–Ern–Piperno bar, T = 6 s: contact-end displacement error",
            "max |u_h − u| over the steps (m)",
            &bar_u,
            Some(("∝ CPU^(−1/2)", -0.5, Corner::LowerRight)),
        ),
    );
    write(
        "dep_bar_force.svg",
        svg_plot(
            "Doyen–Ern–Piperno bar, T = 6 s: contact impulse error",
            "relative L¹ error of the impulse per step",
            &bar_f,
            Some(("∝ CPU^(−1/2)", -0.5, Corner::LowerRight)),
        ),
    );
    write(
        "ball.svg",
        svg_plot(
            "Bouncing ball (e = 0.9): position error at t = 1.7 s",
            "max over 8 step sizes in [h, 1.5h) of |q_h − q| at t = 1.7 s (m)",
            &ball,
            Some(("∝ CPU^(−1)", -1.0, Corner::UpperLeft)),
        ),
    );
    println!("# wrote {}", out.display());
}

/// The number of elements of a DEP bar run (its first grid value).
fn elements(run: &StudyRun) -> f64 {
    run.values[0][0].as_f64().unwrap_or(f64::NAN)
}

/// Steps where the contact impulse switches on.
fn closures(samples: &Samples) -> usize {
    samples
        .impulses
        .windows(2)
        .filter(|w| w[1] > 0.0 && w[0] <= 0.0)
        .count()
}

/// Scene 1. Returns the displacement and force diagrams' points.
fn dep_bar(out: &Path, quick: bool, reps: usize) -> (Vec<Point>, Vec<Point>) {
    let mut csv = String::from(
        "scheme,courant,elements,h,steps,cpu_seconds,err_u_max_m,err_force_l1_rel,closures,exact_closures,status\n",
    );
    let (mut pu, mut pf) = (Vec::new(), Vec::new());
    let mut trace: Vec<(String, Vec<f64>, Vec<f64>)> = Vec::new();
    for (file, cr) in [
        ("work_precision_dep_bar.toml", 1.0),
        ("work_precision_dep_bar_cr4.toml", 4.0),
    ] {
        let disp = study(file);
        let force = in_norm(&disp, ErrorNorm::ImpulseL1);
        let signorini_core::study::Reference::DepBar { solution, .. } = &disp.reference else {
            panic!("{file}: the DEP bar's exact reference");
        };
        let exact_closures = solution.contacts.iter().filter(|c| c.0 <= T_BAR).count();
        let ran = run_study(&disp, reps, |_, r| !quick || elements(r) <= 200.0);
        let (mut points_u, mut points_f) = (Vec::new(), Vec::new());
        for r in &ran {
            let (name, n, h) = (&r.run.label, elements(r.run), r.run.h);
            let wfem = r.run.job.spec().integrator.scheme() == "wfem";
            let courant = if wfem { 1.0 } else { cr };
            let (pu_k, pf_k) = (point(&disp, r), point(&force, r));
            let steps = pu_k.steps;
            let series = if wfem {
                "wfem (h = Δx/c)".to_string()
            } else {
                format!("{name}, c_r = {cr}")
            };
            match &r.samples {
                Ok(s) => {
                    let (e_u, e_f, c) = (pu_k.error, pf_k.error, closures(s));
                    println!(
                        "dep_bar {name} c_r={courant} N={n:5} h={h:.3e} steps={steps:6} cpu={:.3e}s err_u={e_u:.3e} err_force={e_f:.3e} closures={c}/{exact_closures}",
                        r.cpu
                    );
                    let _ = writeln!(
                        csv,
                        "\"{name}\",{courant},{n},{h:e},{steps},{:e},{e_u:e},{e_f:e},{c},{exact_closures},ok",
                        r.cpu
                    );
                    pu.push(Point {
                        series: series.clone(),
                        cpu: r.cpu,
                        err: e_u,
                    });
                    pf.push(Point {
                        series,
                        cpu: r.cpu,
                        err: e_f,
                    });
                    if cr == 1.0 && n == TRACE_N {
                        let gap = s.names.iter().position(|c| c == "gap_0").expect("gap_0");
                        let u = s
                            .values
                            .iter()
                            .map(|row| solution_gap(&disp) - row[gap])
                            .collect();
                        trace.push((name.clone(), s.t.clone(), u));
                    }
                }
                Err(err) => {
                    println!("dep_bar {name} c_r={courant} N={n}: failed: {err}");
                    let _ = writeln!(
                        csv,
                        "\"{name}\",{courant},{n},{h:e},,{:e},,,,{exact_closures},\"failed: {err}\"",
                        r.cpu
                    );
                }
            }
            points_u.push(pu_k);
            points_f.push(pf_k);
        }
        print_orders(&format!("dep_bar c_r={cr} err_u"), &disp, points_u);
        print_orders(&format!("dep_bar c_r={cr} err_force"), &force, points_f);
        if cr == 1.0 {
            let (trace_csv, trace_svg) = trace_files(solution, &trace);
            std::fs::write(out.join("dep_bar_trace.csv"), trace_csv).expect("write trace");
            std::fs::write(out.join("dep_bar_trace.svg"), trace_svg).expect("write trace");
        }
    }
    std::fs::write(out.join("dep_bar.csv"), csv).expect("write dep_bar.csv");
    (pu, pf)
}

/// The initial gap g0 of a DEP bar study.
fn solution_gap(study: &Study) -> f64 {
    match &study.reference {
        signorini_core::study::Reference::DepBar { gap, .. } => *gap,
        _ => f64::NAN,
    }
}

/// Contact-end displacement histories at N = TRACE_N, c_r = 1 (the WFEM's steps are the
/// abscissa; the exact solution first), every TRACE_EVERY-th step.
fn trace_files(
    exact: &signorini_core::wfem::exact::ExactSolution,
    runs: &[(String, Vec<f64>, Vec<f64>)],
) -> (String, String) {
    const TRACE_EVERY: usize = 3;
    let t = runs
        .iter()
        .find(|r| r.0 == "wfem")
        .map_or_else(|| runs[0].1.clone(), |r| r.1.clone());
    let mut cols: Vec<(String, Vec<f64>)> = vec![(
        "exact".into(),
        t.iter().map(|&t| exact.end_displacement(t)).collect(),
    )];
    for (name, ts, u) in runs {
        // Every c_r = 1 run at N = 100 has the WFEM's steps (h = Δx/c).
        let u = if ts.len() == t.len() {
            u.clone()
        } else {
            vec![f64::NAN; t.len()]
        };
        cols.push((name.clone(), u));
    }
    let mut csv = String::from("t");
    for (name, _) in &cols {
        let _ = write!(csv, ",{name}");
    }
    csv.push('\n');
    for (k, t) in t.iter().enumerate().step_by(TRACE_EVERY) {
        let _ = write!(csv, "{t:.6}");
        for (_, u) in &cols {
            let _ = write!(csv, ",{:.6}", u[k]);
        }
        csv.push('\n');
    }
    let svg = svg_lines(
        "Doyen–Ern–Piperno bar, N = 100, h = Δx/c: contact-end displacement",
        "t (s)",
        "u(L, t) (m); the obstacle is at u = 5 m",
        &t,
        &cols,
    );
    (csv, svg)
}

/// Scene 2. Returns the diagram's points.
fn bouncing_ball(out: &Path, quick: bool, reps: usize) -> Vec<Point> {
    let study = study("work_precision_ball.toml");
    let levels = if quick { 5 } else { 9 };
    let per_scheme = study.runs.len() / study.spec.schemes.len();
    let ran = run_study(&study, reps, |i, _| (i % per_scheme) / ENVELOPE < levels);
    let mut csv = String::from("scheme,h,steps,cpu_seconds,err_q_m,err_q_envelope_m,status\n");
    let mut points = Vec::new();
    let mut study_points = Vec::new();
    for level in ran.chunks(ENVELOPE) {
        let first = &level[0];
        let (name, h) = (&first.run.label, first.run.h);
        let errors: Vec<StudyPoint> = level.iter().map(|r| point(&study, r)).collect();
        let steps = errors[0].steps;
        let e_q = errors[0].error;
        let env = errors.iter().map(|p| p.error).fold(0.0f64, |a, e| {
            if a.is_nan() || e.is_nan() {
                f64::NAN
            } else {
                a.max(e)
            }
        });
        match &first.samples {
            Ok(_) => {
                println!(
                    "ball {name} h={h:.3e} steps={steps:6} cpu={:.3e}s err_q={e_q:.3e} err_q_envelope={env:.3e}",
                    first.cpu
                );
                let _ = writeln!(
                    csv,
                    "\"{name}\",{h:e},{steps},{:e},{e_q:e},{env:e},ok",
                    first.cpu
                );
                points.push(Point {
                    series: name.clone(),
                    cpu: first.cpu,
                    err: env,
                });
            }
            Err(err) => {
                println!("ball {name} h={h:.3e}: failed: {err}");
                let _ = writeln!(csv, "\"{name}\",{h:e},,{:e},,,\"failed: {err}\"", first.cpu);
            }
        }
        study_points.extend(errors);
    }
    print_orders("ball err_q", &study, study_points);
    std::fs::write(out.join("ball.csv"), csv).expect("write ball.csv");
    points
}

// ---------------------------------------------------------------------------------------------
// A small log–log SVG plotter (no dependency).

const COLORS: [&str; 9] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
    "#000000",
];

fn marker(shape: usize, x: f64, y: f64, color: &str) -> String {
    let r = 4.5;
    match shape % 6 {
        0 => format!(r#"<circle cx="{x:.1}" cy="{y:.1}" r="{r}" fill="{color}"/>"#),
        1 => format!(
            r#"<rect x="{:.1}" y="{:.1}" width="{}" height="{}" fill="{color}"/>"#,
            x - r,
            y - r,
            2.0 * r,
            2.0 * r
        ),
        2 => format!(
            r#"<polygon points="{:.1},{:.1} {:.1},{:.1} {:.1},{:.1}" fill="{color}"/>"#,
            x,
            y - r * 1.2,
            x - r * 1.1,
            y + r * 0.8,
            x + r * 1.1,
            y + r * 0.8
        ),
        3 => format!(
            r#"<polygon points="{:.1},{:.1} {:.1},{:.1} {:.1},{:.1} {:.1},{:.1}" fill="{color}"/>"#,
            x,
            y - r * 1.3,
            x + r * 1.3,
            y,
            x,
            y + r * 1.3,
            x - r * 1.3,
            y
        ),
        4 => format!(
            r#"<polygon points="{:.1},{:.1} {:.1},{:.1} {:.1},{:.1}" fill="{color}"/>"#,
            x,
            y + r * 1.2,
            x - r * 1.1,
            y - r * 0.8,
            x + r * 1.1,
            y - r * 0.8
        ),
        _ => format!(
            r#"<circle cx="{x:.1}" cy="{y:.1}" r="{r}" fill="white" stroke="{color}" stroke-width="2"/>"#
        ),
    }
}

/// Where a reference slope is drawn.
#[derive(Clone, Copy)]
enum Corner {
    UpperLeft,
    LowerRight,
}

/// `10^k` as SVG text with a raised exponent.
fn decade_label(k: i32, x: f64, y: f64, anchor: &str) -> String {
    format!(
        r#"<text x="{x:.1}" y="{y:.1}" text-anchor="{anchor}" font-size="14">10<tspan dy="-7" font-size="10">{k}</tspan></text>"#
    )
}

/// Log–log plot of error against CPU seconds, one polyline + markers per series (in order of
/// first appearance), legend on the right, decade ticks, an optional reference slope.
fn svg_plot(
    title: &str,
    ylabel: &str,
    points: &[Point],
    slope: Option<(&str, f64, Corner)>,
) -> String {
    let mut names: Vec<&str> = Vec::new();
    for p in points {
        if !names.contains(&p.series.as_str()) {
            names.push(&p.series);
        }
    }
    let good = |p: &&Point| p.cpu > 0.0 && p.err > 0.0 && p.cpu.is_finite() && p.err.is_finite();
    let (mut xmin, mut xmax, mut ymin, mut ymax) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in points.iter().filter(good) {
        xmin = xmin.min(p.cpu.log10());
        xmax = xmax.max(p.cpu.log10());
        ymin = ymin.min(p.err.log10());
        ymax = ymax.max(p.err.log10());
    }
    let (x0, x1) = (xmin.floor() as i32, xmax.ceil() as i32);
    let (y0, y1) = (
        ymin.floor() as i32,
        ymax.ceil().max(ymin.floor() + 1.0) as i32,
    );
    let (w, h) = (1100.0, 700.0);
    let (left, right, top, bottom) = (90.0, 720.0, 50.0, 630.0);
    let px = |lx: f64| left + (lx - f64::from(x0)) / f64::from(x1 - x0) * (right - left);
    let py = |ly: f64| bottom - (ly - f64::from(y0)) / f64::from(y1 - y0) * (bottom - top);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="DejaVu Sans, Helvetica, Arial, sans-serif">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="28" text-anchor="middle" font-size="17">{}</text>"#,
        0.5 * (left + right),
        xml(title)
    );
    // Grid, ticks and labels.
    for k in x0..=x1 {
        let x = px(f64::from(k));
        let _ = writeln!(
            s,
            r##"<line x1="{x:.1}" y1="{top}" x2="{x:.1}" y2="{bottom}" stroke="#ccc"/>"##
        );
        s += &decade_label(k, x, bottom + 22.0, "middle");
        if k < x1 {
            for m in 2..10 {
                let xm = px(f64::from(k) + f64::from(m).log10());
                let _ = writeln!(
                    s,
                    r##"<line x1="{xm:.1}" y1="{bottom}" x2="{xm:.1}" y2="{:.1}" stroke="#000"/>"##,
                    bottom - 5.0
                );
            }
        }
    }
    for k in y0..=y1 {
        let y = py(f64::from(k));
        let _ = writeln!(
            s,
            r##"<line x1="{left}" y1="{y:.1}" x2="{right}" y2="{y:.1}" stroke="#ccc"/>"##
        );
        s += &decade_label(k, left - 8.0, y + 5.0, "end");
        if k < y1 {
            for m in 2..10 {
                let ym = py(f64::from(k) + f64::from(m).log10());
                let _ = writeln!(
                    s,
                    r##"<line x1="{left}" y1="{ym:.1}" x2="{:.1}" y2="{ym:.1}" stroke="#000"/>"##,
                    left + 5.0
                );
            }
        }
    }
    let _ = writeln!(
        s,
        r#"<rect x="{left}" y="{top}" width="{}" height="{}" fill="none" stroke="black"/>"#,
        right - left,
        bottom - top
    );
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="15">CPU time per run (s), best of repetitions, 1 thread</text>"#,
        0.5 * (left + right),
        bottom + 50.0
    );
    let _ = writeln!(
        s,
        r#"<text x="22" y="{:.1}" text-anchor="middle" font-size="15" transform="rotate(-90 22 {:.1})">{}</text>"#,
        0.5 * (top + bottom),
        0.5 * (top + bottom),
        xml(ylabel)
    );
    // Reference slope through the upper-left part of the plot.
    if let Some((label, m, corner)) = slope {
        let (lx0, ly0) = match corner {
            Corner::UpperLeft => (
                f64::from(x0) + 0.15 * f64::from(x1 - x0),
                f64::from(y1) - 0.3,
            ),
            Corner::LowerRight => (f64::from(x1) - 3.2, f64::from(y0) + 0.3 - 2.0 * m),
        };
        let lx1 = (lx0 + 2.0).min(f64::from(x1));
        let ly1 = ly0 + m * (lx1 - lx0);
        let _ = writeln!(
            s,
            r##"<line x1="{:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="#888" stroke-width="1.5" stroke-dasharray="2,4"/>"##,
            px(lx0),
            py(ly0),
            px(lx1),
            py(ly1)
        );
        let _ = writeln!(
            s,
            r##"<text x="{:.1}" y="{:.1}" font-size="13" fill="#555">{}</text>"##,
            px(lx1) + 6.0,
            py(ly1) + 4.0,
            xml(label)
        );
    }
    // Series: colour by scheme family, marker by scheme, dashes for the larger Courant number.
    let mut families: Vec<&str> = Vec::new();
    for (i, name) in names.iter().enumerate() {
        let family = name.split(", c_r").next().unwrap_or(name);
        let f = families
            .iter()
            .position(|x| *x == family)
            .unwrap_or_else(|| {
                families.push(family);
                families.len() - 1
            });
        let color = COLORS[f % COLORS.len()];
        let shape = f;
        let dashed = name.contains("c_r = 4");
        let dash = if dashed {
            r#" stroke-dasharray="7,4""#
        } else {
            ""
        };
        let mut pts: Vec<(f64, f64)> = points
            .iter()
            .filter(good)
            .filter(|p| p.series == *name)
            .map(|p| (px(p.cpu.log10()), py(p.err.log10())))
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let line: Vec<String> = pts.iter().map(|(x, y)| format!("{x:.1},{y:.1}")).collect();
        let _ = writeln!(
            s,
            r#"<polyline points="{}" fill="none" stroke="{color}" stroke-width="2"{dash}/>"#,
            line.join(" ")
        );
        for &(x, y) in &pts {
            s += &marker(shape, x, y, color);
        }
        // Legend entry.
        let ly = top + 10.0 + 24.0 * i as f64;
        let lx = right + 20.0;
        let _ = writeln!(
            s,
            r#"<line x1="{lx}" y1="{ly:.1}" x2="{:.1}" y2="{ly:.1}" stroke="{color}" stroke-width="2"{dash}/>"#,
            lx + 36.0
        );
        s += &marker(shape, lx + 18.0, ly, color);
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{:.1}" font-size="13">{}</text>"#,
            lx + 44.0,
            ly + 4.5,
            xml(name)
        );
    }
    s += "</svg>\n";
    s
}

/// Linear plot of several curves y(t) sharing the abscissa `t` (first curve drawn thick grey).
fn svg_lines(
    title: &str,
    xlabel: &str,
    ylabel: &str,
    t: &[f64],
    cols: &[(String, Vec<f64>)],
) -> String {
    let (w, h) = (1100.0, 700.0);
    let (left, right, top, bottom) = (80.0, 760.0, 50.0, 630.0);
    let (tmax, ymin, ymax) = (T_BAR, -2.0, 6.0);
    let px = |x: f64| left + x / tmax * (right - left);
    let py = |y: f64| bottom - (y.clamp(ymin, ymax) - ymin) / (ymax - ymin) * (bottom - top);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="DejaVu Sans, Helvetica, Arial, sans-serif">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="28" text-anchor="middle" font-size="17">{}</text>"#,
        0.5 * (left + right),
        xml(title)
    );
    for k in 0..=(tmax as i32) {
        let x = px(f64::from(k));
        let _ = writeln!(
            s,
            r##"<line x1="{x:.1}" y1="{top}" x2="{x:.1}" y2="{bottom}" stroke="#ccc"/><text x="{x:.1}" y="{:.1}" text-anchor="middle" font-size="14">{k}</text>"##,
            bottom + 22.0
        );
    }
    for k in (ymin as i32)..=(ymax as i32) {
        let y = py(f64::from(k));
        let _ = writeln!(
            s,
            r##"<line x1="{left}" y1="{y:.1}" x2="{right}" y2="{y:.1}" stroke="#ccc"/><text x="{:.1}" y="{:.1}" text-anchor="end" font-size="14">{k}</text>"##,
            left - 8.0,
            y + 5.0
        );
    }
    let _ = writeln!(
        s,
        r#"<rect x="{left}" y="{top}" width="{}" height="{}" fill="none" stroke="black"/>"#,
        right - left,
        bottom - top
    );
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="15">{}</text>"#,
        0.5 * (left + right),
        bottom + 50.0,
        xml(xlabel)
    );
    let _ = writeln!(
        s,
        r#"<text x="22" y="{:.1}" text-anchor="middle" font-size="15" transform="rotate(-90 22 {:.1})">{}</text>"#,
        0.5 * (top + bottom),
        0.5 * (top + bottom),
        xml(ylabel)
    );
    for (i, (name, y)) in cols.iter().enumerate() {
        let (color, width) = if i == 0 {
            ("#bbbbbb", 6.0)
        } else {
            (COLORS[(i - 1) % COLORS.len()], 1.6)
        };
        let line: Vec<String> = t
            .iter()
            .zip(y)
            .step_by(2)
            .filter(|(_, y)| y.is_finite())
            .map(|(&t, &y)| format!("{:.1},{:.1}", px(t), py(y)))
            .collect();
        let _ = writeln!(
            s,
            r#"<polyline points="{}" fill="none" stroke="{color}" stroke-width="{width}"/>"#,
            line.join(" ")
        );
        let ly = top + 10.0 + 24.0 * i as f64;
        let lx = right + 20.0;
        let _ = writeln!(
            s,
            r#"<line x1="{lx}" y1="{ly:.1}" x2="{:.1}" y2="{ly:.1}" stroke="{color}" stroke-width="{width}"/><text x="{:.1}" y="{:.1}" font-size="13">{}</text>"#,
            lx + 36.0,
            lx + 44.0,
            ly + 4.5,
            xml(name)
        );
    }
    s += "</svg>\n";
    s
}

fn xml(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}
