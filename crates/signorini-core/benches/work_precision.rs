//! Work–precision diagrams: error against CPU time, per integrator, on two scenes
//! with an exact solution. Plain `fn main` (`harness = false`):
//!
//! ```text
//! cargo bench -p signorini-core --bench work_precision            # ≈ 1–2 min
//! cargo bench -p signorini-core --bench work_precision -- --quick # ≈ 10 s, coarse points only
//! ```
//!
//! Writes `docs/work_precision/`: `dep_bar.csv`, `dep_bar.svg` (displacement error),
//! `dep_bar_force.svg` (impulse error), `dep_bar_trace.{csv,svg}` (u(L, t) of every scheme at
//! N = 100, c_r = 1), `ball.csv`, `ball.svg` (a bench may write files; the core crate does no
//! I/O), and prints one line per run.
//!
//! **Scene 1, the Doyen–Ern–Piperno bar** (`Bar::doyen_ern_piperno(N)`, Yoong et al. 2018
//! Table 1) on [0, T], T = 6 s (two contact phases, from t = 1 s and t ≈ 3.7 s), against its exact solution by
//! characteristics (`wfem::exact`). Errors, with u the contact-end displacement and t_k the steps:
//!
//! * `err_u` = max_k |u_h(t_k) − u(t_k)| in metres (u runs over [0, g0 = 5 m]);
//! * `err_force` = Σ_k |P_k − I_k| / Σ_k I_k, the relative L¹ error of the contact impulse per
//!   step, with P_k the scheme's impulse over [t_{k−1}, t_k] (`p_0`; h λ for the position-contact
//!   baseline) and I_k = −∫ r dt over the same step from the exact (piecewise linear) force r.
//!
//! Finite elements (lumped mass, N elements, Δx = L/N) with h = c_r Δx / c for c_r ∈ {1, 4};
//! the WFEM with its own step Δt = Δx/c.
//!
//! **Scene 2, the bouncing ball** (m = 1, g = 9.81, q0 = 1, e = 0.9): |q_h − q| at t = 1.7 s, in
//! mid-flight after two impacts, h = 1.7/(170·2^j). Where the impacts fall inside a step makes
//! this error jump by 10× between neighbouring h, so each point plots the largest error over the
//! eight step sizes h·(16 + i)/16, i = 0…7 (`err_q_envelope`; CPU time is that of h).
//!
//! **Cost.** One run = building the scheme (factorisations, Delassus operator) plus the whole
//! integration through the public run loops (`integrators::run_linear`, `wfem::job::run_wave`,
//! every step recorded, energy bookkeeping on, as a job does it); the errors are computed from the
//! kept columns after the clock stops. Time is wall-clock (`Instant`) of this single-threaded
//! process, best of `REPS` repetitions, each repetition repeating short runs until it lasts
//! ≥ 30 ms; on the shared 2-core VM the best-of filters out most preemption by other jobs.

// Only the core library must stay pure (clippy.toml): a benchmark times itself and prints.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::integrators::alpha::{AlphaParams, AlphaScheme, NonsmoothAlpha};
use signorini_core::integrators::moreau_jean::{MoreauJean, MoreauJeanParams};
use signorini_core::integrators::position_contact::{PositionContact, PositionContactParams};
use signorini_core::integrators::{LinearScheme, LinearState, OutputOptions, run_linear};
use signorini_core::lcp::LcpOptions;
use signorini_core::model::LinearModel;
use signorini_core::observer::{Columns, Observer, StepRecord};
use signorini_core::scenes::{Bar, BouncingBall};
use signorini_core::wfem::WaveBar;
use signorini_core::wfem::exact::{ExactBar, ExactSolution};
use signorini_core::wfem::job::run_wave;
use std::fmt::Write as _;
use std::hint::black_box;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// End of the bar runs (s).
const T_BAR: f64 = 6.0;
/// Courant numbers c h / Δx of the finite-element runs.
const COURANT: [f64; 2] = [1.0, 4.0];
/// Time of the ball's position error (mid-flight after the second impact).
const T_BALL: f64 = 1.7;
/// Step sizes per point of the ball's error envelope.
const ENVELOPE: usize = 8;

/// Keeps `t`, `gap_0` and `p_0` of every record (the columns both run loops share).
#[derive(Default)]
struct Keep {
    gap: usize,
    p: usize,
    t: Vec<f64>,
    g: Vec<f64>,
    imp: Vec<f64>,
}

impl Keep {
    fn with_capacity(n: usize) -> Self {
        Self {
            t: Vec::with_capacity(n),
            g: Vec::with_capacity(n),
            imp: Vec::with_capacity(n),
            ..Default::default()
        }
    }
}

impl Observer for Keep {
    fn start(&mut self, columns: &Columns) {
        self.gap = columns.index("gap_0").expect("gap_0 column");
        self.p = columns.index("p_0").expect("p_0 column");
    }

    fn observe(&mut self, r: &StepRecord<'_>) -> ControlFlow<()> {
        self.t.push(r.t);
        self.g.push(r.values[self.gap]);
        self.imp.push(r.values[self.p]);
        ControlFlow::Continue(())
    }
}

type Make = Box<dyn Fn(&LinearModel, f64) -> Box<dyn LinearScheme>>;

/// A linear scheme of the comparison: name, parameters (as in a spec), constructor.
struct Scheme {
    name: &'static str,
    params: &'static str,
    make: Make,
}

fn schemes() -> Vec<Scheme> {
    let lcp = LcpOptions::default();
    let mj = move |theta: f64, variant: bool| -> Make {
        Box::new(move |m, h| {
            let p = MoreauJeanParams {
                theta,
                variant,
                ..Default::default()
            };
            Box::new(MoreauJean::new(m, p, h, lcp).expect("SPD")) as Box<dyn LinearScheme>
        })
    };
    let ns = move |p: AlphaParams| -> Make {
        Box::new(move |m, h| {
            Box::new(NonsmoothAlpha::new(m, p, h, lcp).expect("SPD")) as Box<dyn LinearScheme>
        })
    };
    vec![
        Scheme {
            name: "moreau_jean",
            params: "θ=½",
            make: mj(0.5, false),
        },
        Scheme {
            name: "moreau_jean",
            params: "θ=1",
            make: mj(1.0, false),
        },
        // θ = ½ would be the same scheme as moreau_jean θ = ½ (v_{k+θ} = v_{k+1/2}).
        Scheme {
            name: "moreau_jean_variant",
            params: "θ=1",
            make: mj(1.0, true),
        },
        Scheme {
            name: "ns_newmark",
            params: "β=¼ γ=½",
            make: ns(AlphaParams::newmark(0.25, 0.5)),
        },
        Scheme {
            name: "ns_hht",
            params: "α=0.1",
            make: ns(AlphaParams::hht(0.1)),
        },
        Scheme {
            name: "ns_generalized_alpha",
            params: "ρ∞=0.8",
            make: ns(AlphaParams::from_rho_inf(
                AlphaScheme::GeneralizedAlpha,
                0.8,
            )),
        },
        Scheme {
            name: "ns_kh_alpha",
            params: "ρ∞=0.8",
            make: ns(AlphaParams::from_rho_inf(AlphaScheme::KrenkHogsberg, 0.8)),
        },
        Scheme {
            name: "newmark_position_contact",
            params: "β=¼ γ=½",
            make: Box::new(move |m, h| {
                Box::new(
                    PositionContact::new(m, PositionContactParams::newmark(0.25, 0.5), h, lcp)
                        .expect("SPD"),
                ) as Box<dyn LinearScheme>
            }),
        },
    ]
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

/// −∫_{ta}^{tb} r dt of the exact contact force (≥ 0), exactly (r is linear on each piece).
fn exact_impulse(ex: &ExactSolution, area: f64, ta: f64, tb: f64) -> f64 {
    let mut sum = 0.0;
    let start = ex.pieces.partition_point(|p| p.t1 <= ta);
    for p in &ex.pieces[start..] {
        if p.t0 >= tb {
            break;
        }
        if !p.contact {
            continue;
        }
        let (a, b) = (ta.max(p.t0), tb.min(p.t1));
        if b > a {
            // ∫ (a0 + a1 (t − t0)) dt over [a, b].
            let mid = 0.5 * (a + b) - p.t0;
            sum += area * (p.a0 + p.a1 * mid) * (b - a);
        }
    }
    -sum
}

/// Errors of a bar run from its kept columns: (max |u_h − u|, relative L¹ impulse error, gap
/// closures seen).
fn bar_errors(keep: &Keep, ex: &ExactSolution, gap0: f64, area: f64) -> (f64, f64, usize) {
    let (mut e_u, mut e_p, mut total) = (0.0f64, 0.0, 0.0);
    let mut closures = 0;
    for k in 0..keep.t.len() {
        let u = gap0 - keep.g[k];
        e_u = e_u.max((u - ex.end_displacement(keep.t[k])).abs());
        if k > 0 {
            let exact = exact_impulse(ex, area, keep.t[k - 1], keep.t[k]);
            e_p += (keep.imp[k] - exact).abs();
            total += exact;
            closures += usize::from(keep.imp[k] > 0.0 && keep.imp[k - 1] <= 0.0);
        }
    }
    (e_u, e_p / total, closures)
}

/// Exact (q, v) at time t of a ball dropped at rest from q0 with restitution e (before the
/// accumulation point of its impacts); as in `tests/moreau_jean_exact.rs`.
fn ball_exact(q0: f64, g: f64, e: f64, t: f64) -> (f64, f64) {
    let t1 = (2.0 * q0 / g).sqrt();
    if t < t1 {
        return (q0 - 0.5 * g * t * t, -g * t);
    }
    let (mut start, mut u) = (t1, e * g * t1);
    loop {
        let flight = 2.0 * u / g;
        if t < start + flight {
            let s = t - start;
            return (u * s - 0.5 * g * s * s, u - g * s);
        }
        start += flight;
        u *= e;
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

/// Scene 1. Returns the displacement and force diagrams' points.
fn dep_bar(out: &Path, quick: bool, reps: usize) -> (Vec<Point>, Vec<Point>) {
    let exact_bar = ExactBar::doyen_ern_piperno();
    let ex = ExactSolution::solve(exact_bar, T_BAR + 1.0);
    let (gap0, area) = (exact_bar.gap, exact_bar.area);
    let exact_closures = ex.contacts.iter().filter(|c| c.0 <= T_BAR).count();
    let ns: &[usize] = if quick {
        &[25, 50, 100, 200]
    } else {
        &[25, 50, 100, 200, 400, 800, 1600]
    };
    let mut csv = String::from(
        "scheme,params,courant,elements,h,steps,cpu_seconds,err_u_max_m,err_force_l1_rel,closures,exact_closures,status\n",
    );
    let (mut pu, mut pf) = (Vec::new(), Vec::new());
    let mut push = |series: String, cpu: f64, e_u: f64, e_f: f64| {
        pu.push(Point {
            series: series.clone(),
            cpu,
            err: e_u,
        });
        pf.push(Point {
            series,
            cpu,
            err: e_f,
        });
    };
    // WFEM: Δt = Δx/c.
    for &n in ns {
        let bar = Bar::doyen_ern_piperno(n);
        let dt = 10.0 / n as f64 / bar.wave_speed();
        let steps = (T_BAR / dt).round() as u64;
        let (cpu, keep) = time_best(reps, || {
            let wave = WaveBar::from_bar(&bar).expect("DEP bar");
            let mut state = wave.initial_state();
            let mut keep = Keep::with_capacity(steps as usize + 1);
            run_wave(&wave, &mut state, steps, 1, &mut keep).expect("wfem run");
            keep
        });
        let (e_u, e_f, closures) = bar_errors(&keep, &ex, gap0, area);
        println!(
            "dep_bar wfem N={n:5} h={dt:.3e} steps={steps:6} cpu={cpu:.3e}s err_u={e_u:.3e} err_force={e_f:.3e} closures={closures}/{exact_closures}"
        );
        let _ = writeln!(
            csv,
            "wfem,,1,{n},{dt:e},{steps},{cpu:e},{e_u:e},{e_f:e},{closures},{exact_closures},ok"
        );
        push("wfem (h = Δx/c)".into(), cpu, e_u, e_f);
    }
    for scheme in schemes() {
        for &cr in &COURANT {
            let series = format!("{} {}, c_r = {cr}", scheme.name, scheme.params);
            for &n in ns {
                let bar = Bar::doyen_ern_piperno(n);
                let model = bar.build().expect("DEP bar");
                let h = cr * bar.length / n as f64 / bar.wave_speed();
                let steps = (T_BAR / h).round() as u64;
                let output = OutputOptions {
                    every: 1,
                    probes: vec![],
                };
                let (cpu, result) = time_best(reps, || {
                    let mut s = (scheme.make)(&model, h);
                    let mut state = LinearState::initial(&model);
                    let mut keep = Keep::with_capacity(steps as usize + 1);
                    run_linear(&model, s.as_mut(), &mut state, steps, &output, &mut keep)
                        .map(|_| keep)
                });
                let (name, params) = (scheme.name, scheme.params);
                match result {
                    Ok(keep) => {
                        let (e_u, e_f, closures) = bar_errors(&keep, &ex, gap0, area);
                        println!(
                            "dep_bar {name} {params} c_r={cr} N={n:5} h={h:.3e} steps={steps:6} cpu={cpu:.3e}s err_u={e_u:.3e} err_force={e_f:.3e} closures={closures}/{exact_closures}"
                        );
                        let _ = writeln!(
                            csv,
                            "{name},{params},{cr},{n},{h:e},{steps},{cpu:e},{e_u:e},{e_f:e},{closures},{exact_closures},ok"
                        );
                        push(series.clone(), cpu, e_u, e_f);
                    }
                    Err(err) => {
                        println!("dep_bar {name} {params} c_r={cr} N={n}: failed: {err}");
                        let _ = writeln!(
                            csv,
                            "{name},{params},{cr},{n},{h:e},{steps},{cpu:e},,,,{exact_closures},\"failed: {err}\""
                        );
                    }
                }
            }
        }
    }
    std::fs::write(out.join("dep_bar.csv"), csv).expect("write dep_bar.csv");
    let (trace_csv, trace_svg) = trace(&ex, gap0);
    std::fs::write(out.join("dep_bar_trace.csv"), trace_csv).expect("write trace");
    std::fs::write(out.join("dep_bar_trace.svg"), trace_svg).expect("write trace");
    (pu, pf)
}

/// Contact-end displacement histories at N = TRACE_N, c_r = 1 (and the WFEM, and the exact
/// solution), one column per scheme, every TRACE_EVERY-th step.
fn trace(ex: &ExactSolution, gap0: f64) -> (String, String) {
    const TRACE_N: usize = 100;
    const TRACE_EVERY: usize = 3;
    let bar = Bar::doyen_ern_piperno(TRACE_N);
    let h = bar.length / TRACE_N as f64 / bar.wave_speed();
    let steps = (T_BAR / h).round() as u64;
    let mut cols: Vec<(String, Vec<f64>)> = Vec::new();
    let wave = WaveBar::from_bar(&bar).expect("DEP bar");
    let mut state = wave.initial_state();
    let mut keep = Keep::default();
    run_wave(&wave, &mut state, steps, 1, &mut keep).expect("wfem run");
    let t = keep.t.clone();
    cols.push((
        "exact".into(),
        t.iter().map(|&t| ex.end_displacement(t)).collect(),
    ));
    cols.push(("wfem".into(), keep.g.iter().map(|g| gap0 - g).collect()));
    let model = bar.build().expect("DEP bar");
    for scheme in schemes() {
        let mut s = (scheme.make)(&model, h);
        let mut state = LinearState::initial(&model);
        let mut keep = Keep::default();
        let output = OutputOptions {
            every: 1,
            probes: vec![],
        };
        let u = match run_linear(&model, s.as_mut(), &mut state, steps, &output, &mut keep) {
            Ok(_) => keep.g.iter().map(|g| gap0 - g).collect(),
            Err(_) => vec![f64::NAN; t.len()],
        };
        cols.push((format!("{} {}", scheme.name, scheme.params), u));
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
        &format!("Doyen–Ern–Piperno bar, N = {TRACE_N}, h = Δx/c: contact-end displacement"),
        "t (s)",
        "u(L, t) (m); the obstacle is at u = 5 m",
        &t,
        &cols,
    );
    (csv, svg)
}

/// Scene 2. Returns the diagram's points.
fn bouncing_ball(out: &Path, quick: bool, reps: usize) -> Vec<Point> {
    let ball = BouncingBall {
        mass: 1.0,
        gravity: 9.81,
        q0: 1.0,
        v0: 0.0,
        restitution: 0.9,
    };
    let model = ball.build().expect("ball");
    let (q_ex, v_ex) = ball_exact(ball.q0, ball.gravity, ball.restitution, T_BALL);
    let levels = if quick { 5 } else { 9 };
    let mut csv = String::from(
        "scheme,params,h,steps,cpu_seconds,err_q_m,err_q_envelope_m,err_v_m_per_s,impacts,status\n",
    );
    let mut points = Vec::new();
    for scheme in schemes() {
        let (name, params) = (scheme.name, scheme.params);
        for j in 0..levels {
            let steps = 170u64 << j;
            let h = T_BALL / steps as f64;
            let output = OutputOptions {
                every: steps,
                probes: vec![0],
            };
            let (cpu, result) = time_best(reps, || {
                let mut s = (scheme.make)(&model, h);
                let mut state = LinearState::initial(&model);
                let mut keep = Keep::default();
                run_linear(&model, s.as_mut(), &mut state, steps, &output, &mut keep)
                    .map(|stats| (state, stats.impacts))
            });
            match result {
                Ok((state, impacts)) => {
                    let (e_q, e_v) = ((state.q[0] - q_ex).abs(), (state.v[0] - v_ex).abs());
                    // The error depends on where the impacts fall inside a step: take the
                    // largest over ENVELOPE step sizes h·(16 + i)/16, i = 0…7 (untimed runs).
                    let mut env = e_q;
                    for i in 1..ENVELOPE {
                        let n = (steps as f64 * 16.0 / (16.0 + i as f64)).round() as u64;
                        let mut s = (scheme.make)(&model, T_BALL / n as f64);
                        let mut st = LinearState::initial(&model);
                        let o = OutputOptions {
                            every: n,
                            probes: vec![],
                        };
                        match run_linear(&model, s.as_mut(), &mut st, n, &o, &mut Keep::default()) {
                            Ok(_) => env = env.max((st.q[0] - q_ex).abs()),
                            Err(_) => env = f64::NAN,
                        }
                    }
                    println!(
                        "ball {name} {params} h={h:.3e} steps={steps:6} cpu={cpu:.3e}s err_q={e_q:.3e} err_q_envelope={env:.3e} err_v={e_v:.3e} impacts={impacts}"
                    );
                    let _ = writeln!(
                        csv,
                        "{name},{params},{h:e},{steps},{cpu:e},{e_q:e},{env:e},{e_v:e},{impacts},ok"
                    );
                    points.push(Point {
                        series: format!("{name} {params}"),
                        cpu,
                        err: env,
                    });
                }
                Err(err) => {
                    println!("ball {name} {params} h={h:.3e}: failed: {err}");
                    let _ = writeln!(
                        csv,
                        "{name},{params},{h:e},{steps},{cpu:e},,,,,\"failed: {err}\""
                    );
                }
            }
        }
    }
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
