//! Speed of the expression language on a slider-crank-sized model (the mechanism of
//! `soi2::models::SliderCrank` written as expressions: 8 coordinates, 7 joints): ns per tape
//! node evaluated over f64 and over dual numbers, symbolic against automatic derivatives, the
//! hand-written closed form, a tree walk, and the `fasteval` crate.
//!
//! `cargo bench -p signorini-core --bench expr` (plain main, harness = false). Figures in
//! docs/expr.md.

// Only the core library must stay pure (clippy.toml): a benchmark times itself and prints.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use fasteval::{Compiler, Evaler};
use num_dual::Dual64;
use signorini_core::expr::{Expr, Param, Scope, Tape};
use signorini_core::soi2::ConstrainedModel;
use signorini_core::soi2::models::SliderCrank;
use std::hint::black_box;
use std::time::Instant;

const COORDINATES: [&str; 8] = ["x1", "y1", "th1", "x2", "y2", "th2", "x3", "y3"];

/// The joints of `SliderCrank::g` (crank 0.2 m, rod 0.5 m).
const JOINTS: [&str; 7] = [
    "x1 - r/2*cos(th1)",
    "y1 - r/2*sin(th1)",
    "x1 + r/2*cos(th1) - x2 + l/2*cos(th2)",
    "y1 + r/2*sin(th1) - y2 + l/2*sin(th2)",
    "x2 + l/2*cos(th2) - x3",
    "y2 + l/2*sin(th2) - y3",
    "y3",
];

/// The same joints for fasteval (numbers in place of parameters: it has no parameter folding).
const JOINTS_FASTEVAL: [&str; 7] = [
    "x1 - 0.1*cos(th1)",
    "y1 - 0.1*sin(th1)",
    "x1 + 0.1*cos(th1) - x2 + 0.25*cos(th2)",
    "y1 + 0.1*sin(th1) - y2 + 0.25*sin(th2)",
    "x2 + 0.25*cos(th2) - x3",
    "y2 + 0.25*sin(th2) - y3",
    "y3",
];

/// Nanoseconds per call of `f`, best of 7 rounds of `n` calls (the machine is shared).
fn time(n: usize, mut f: impl FnMut(usize)) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..7 {
        let t0 = Instant::now();
        for i in 0..n {
            f(i);
        }
        best = best.min(t0.elapsed().as_secs_f64() * 1e9 / n as f64);
    }
    best
}

/// A state that changes with `i` so nothing is hoisted out of the loop.
fn state(i: usize) -> [f64; 17] {
    let s = (i % 1000) as f64 * 1e-3;
    let mut v = [0.0; 17];
    for (k, x) in v.iter_mut().enumerate() {
        *x = 0.1 * k as f64 + s;
    }
    v
}

fn main() {
    let n = 200_000;
    let coords: Vec<String> = COORDINATES.iter().map(|s| s.to_string()).collect();
    let params = vec![
        ("r".to_string(), Param::Value(0.2)),
        ("l".to_string(), Param::Value(0.5)),
    ];
    let scope = Scope::lagrangian(&coords, &params).expect("scope");
    // One-off cost at validation: parse, differentiate twice, compile.
    let setup = time(20, |_| {
        let g: Vec<Expr> = JOINTS
            .iter()
            .map(|s| Expr::parse(s, &scope).expect("parse"))
            .collect();
        let q: Vec<usize> = (0..8).collect();
        let mut all = g.clone();
        for e in &g {
            all.extend(e.gradient(&q));
            all.extend(e.hessian(&q));
        }
        black_box(Tape::compile(&all));
    });
    println!(
        "setup (parse 7 joints, gradients, Hessians, compile one tape): {:.0} µs",
        setup / 1e3
    );
    let g: Vec<Expr> = JOINTS
        .iter()
        .map(|s| Expr::parse(s, &scope).expect("parse"))
        .collect();
    let q: Vec<usize> = (0..8).collect();
    let g_y: Vec<Expr> = g.iter().flat_map(|e| e.gradient(&q)).collect();
    // Hessians of the joints over q: what d/dt g_y = Σ H_gᵢ q̇ needs.
    let g_yy: Vec<Expr> = g.iter().flat_map(|e| e.hessian(&q)).collect();

    let tape_g = Tape::compile(&g);
    let tape_gy = Tape::compile(&g_y);
    let mut both = g.clone();
    both.extend(g_y.iter().cloned());
    let tape_both = Tape::compile(&both);
    let tape_gyy = Tape::compile(&g_yy);
    let tree_nodes: usize = g.iter().map(Expr::tree_size).sum();

    println!("slider-crank joints: 7 expressions, {tree_nodes} tree nodes");
    for (name, t) in [
        ("g", &tape_g),
        ("g_y", &tape_gy),
        ("g + g_y", &tape_both),
        ("Hessians", &tape_gyy),
    ] {
        println!(
            "tape {name}: {} nodes ({} operations, the rest variables and constants)",
            t.len(),
            t.operations()
        );
    }
    println!(
        "{:<44} {:>10} {:>10} {:>12}",
        "case", "ns/call", "nodes", "ns/node"
    );
    let row = |name: &str, ns: f64, nodes: usize| {
        println!(
            "{name:<44} {ns:>10.1} {nodes:>10} {:>12.2}",
            ns / nodes as f64
        );
    };

    let mut scratch = Vec::new();
    let mut out = vec![0.0; 56];
    let ns = time(n, |i| {
        tape_g.eval_into(black_box(&state(i)), &mut scratch, &mut out[..7]);
        black_box(&out);
    });
    row("g, tape f64", ns, tape_g.len());
    let ns_gy = time(n, |i| {
        tape_gy.eval_into(black_box(&state(i)), &mut scratch, &mut out);
        black_box(&out);
    });
    row("g_y symbolic, tape f64", ns_gy, tape_gy.len());
    let mut out_both = vec![0.0; 63];
    let ns = time(n, |i| {
        tape_both.eval_into(black_box(&state(i)), &mut scratch, &mut out_both);
        black_box(&out_both);
    });
    row("g + g_y symbolic, one tape f64", ns, tape_both.len());

    let mut dscratch: Vec<Dual64> = Vec::new();
    let mut dout = vec![Dual64::from_re(0.0); 7];
    let ns = time(n, |i| {
        let s = state(i);
        let mut v: Vec<Dual64> = s.iter().map(|&x| Dual64::from_re(x)).collect();
        for j in 0..8 {
            v[j].eps = 1.0;
            tape_g.eval_into(black_box(&v), &mut dscratch, &mut dout);
            for (k, d) in dout.iter().enumerate() {
                out[k * 8 + j] = d.eps;
            }
            v[j].eps = 0.0;
        }
        black_box(&out);
    });
    row("g_y by Dual64 AD (8 sweeps of g)", ns, 8 * tape_g.len());

    let ns = time(n, |i| {
        let s = state(i);
        let v: Vec<Dual64> = s
            .iter()
            .enumerate()
            .map(|(k, &x)| Dual64::new(x, if k < 8 { s[8 + k] } else { 0.0 }))
            .collect();
        let mut d56 = [Dual64::from_re(0.0); 56];
        tape_gy.eval_into(black_box(&v), &mut dscratch, &mut d56);
        black_box(&d56);
    });
    row(
        "d/dt g_y = g_yy q_dot: Dual64 over g_y tape",
        ns,
        tape_gy.len(),
    );

    let mut out_h = vec![0.0; 7 * 64];
    let ns = time(n / 4, |i| {
        tape_gyy.eval_into(black_box(&state(i)), &mut scratch, &mut out_h);
        black_box(&out_h);
    });
    row(
        "Hessians symbolic, tape f64 (448 outputs)",
        ns,
        tape_gyy.len(),
    );

    let ns = time(n / 4, |i| {
        let s = state(i);
        for (k, e) in g.iter().enumerate() {
            out[k] = e.eval(black_box(&s));
        }
        black_box(&out);
    });
    row("g, tree walk (Expr::eval)", ns, tree_nodes);

    let crank = SliderCrank::default();
    let ns_hand = time(n, |i| {
        let s = state(i);
        crank.g(0.0, black_box(&s[..8]), &mut out[..7]);
        black_box(&out);
    });
    println!("{:<44} {ns_hand:>10.1}", "g, hand-written closed form");
    let ns_hand_gy = time(n, |i| {
        let s = state(i);
        crank.g_y(0.0, black_box(&s[..8]), &mut out);
        black_box(&out);
    });
    println!("{:<44} {ns_hand_gy:>10.1}", "g_y, hand-written closed form");
    println!(
        "g_y symbolic tape / hand-written: {:.2}×",
        ns_gy / ns_hand_gy
    );
    // Over Dual64, as inside SOI2's Newton Jacobian (f = f₀ − g_yᵀλ evaluated per column).
    let dual_state = |i: usize| -> [Dual64; 17] {
        let s = state(i);
        std::array::from_fn(|k| Dual64::new(s[k], if k == 2 { 1.0 } else { 0.0 }))
    };
    let mut d56 = [Dual64::from_re(0.0); 56];
    let ns_tape_d = time(n, |i| {
        tape_gy.eval_into(black_box(&dual_state(i)), &mut dscratch, &mut d56);
        black_box(&d56);
    });
    row("g_y symbolic, tape over Dual64", ns_tape_d, tape_gy.len());
    let ns_hand_d = time(n, |i| {
        let v = dual_state(i);
        crank.g_y(Dual64::from_re(0.0), black_box(&v[..8]), &mut d56);
        black_box(&d56);
    });
    println!("{:<44} {ns_hand_d:>10.1}", "g_y, hand-written over Dual64");
    println!(
        "over Dual64, tape / hand-written: {:.2}×",
        ns_tape_d / ns_hand_d
    );

    // fasteval: compiled expressions, variables through a callback.
    let mut slabs = Vec::new();
    let mut compiled = Vec::new();
    for src in JOINTS_FASTEVAL {
        let mut slab = fasteval::Slab::new();
        let c = fasteval::Parser::new()
            .parse(src, &mut slab.ps)
            .expect("fasteval parse")
            .from(&slab.ps)
            .compile(&slab.ps, &mut slab.cs);
        slabs.push(slab);
        compiled.push(c);
    }
    let ns = time(n / 4, |i| {
        let s = black_box(state(i));
        let mut ns = |name: &str, _args: Vec<f64>| -> Option<f64> {
            COORDINATES.iter().position(|c| *c == name).map(|k| s[k])
        };
        for (k, (c, slab)) in compiled.iter().zip(&slabs).enumerate() {
            out[k] = c.eval(slab, &mut ns).unwrap_or(f64::NAN);
        }
        black_box(&out);
    });
    row("g, fasteval compiled (callback variables)", ns, tree_nodes);
}
