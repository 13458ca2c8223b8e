//! WFEM and nonsmooth-modal-analysis speed (plain `fn main`, `harness = false`):
//! `cargo bench -p signorini-core --bench wfem` (about 1–2 minutes in total).
//!
//! 1. Backbone scan N = 1000 over every (m, p) with m + p ≤ 4000 (kernel dimension in O(1) for
//!    all 7 998 000 pairs, admissibility for the pairs with a kernel), 1 and 2 threads, per gap.
//! 2. The straightforward path (signed permutation + kernel basis + one trajectory per basis
//!    vector) and the dense-SVD kernel (A_c^p A_f^m − I, nalgebra SVD) timed on samples of pairs,
//!    the latter at N = 50, 100, 200, and extrapolated to the N = 1000 scan by the measured growth.
//! 3. Cell updates per second at N = 10³…10⁶, single thread, on-CPU time of the thread
//!    (`/proc/thread-self/schedstat`; wall clock where that is missing).
//!    `cargo bench -p signorini-core --bench wfem -- --cells-only` runs this part alone.

// Only the core library must stay pure (clippy.toml): a benchmark times itself and prints.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use nalgebra::DMatrix;
use signorini_core::modal::kernel::{dense_kernel_dim, dense_matrix, kernel_dim_closed_form};
use signorini_core::modal::{examine, scan_with};
use signorini_core::wfem::{EndCondition, WaveBar, flux_form_step, step};
use std::hint::black_box;
use std::ops::ControlFlow;
use std::time::Instant;

const PAIRS_1000: f64 = 7_998_000.0;

fn pairs(n: usize) -> f64 {
    let t = 4 * n;
    (t * (t - 1) / 2) as f64
}

/// Seconds per (m, p) of the dense approach at N = `n`: one product A_c^p A_f^m (the powers are
/// built incrementally in a scan, so not timed) and one SVD of `A_c^p A_f^m − I`.
fn dense_per_pair(n: usize, samples: usize) -> f64 {
    let bar = WaveBar::unit(n, 0.0);
    let af = dense_matrix(&bar, EndCondition::Free);
    let ac = dense_matrix(&bar, EndCondition::Contact);
    let pow =
        |a: &DMatrix<f64>, k: usize| (0..k).fold(DMatrix::identity(2 * n, 2 * n), |x, _| a * x);
    let (af_m, ac_p) = (pow(&af, 2 * n + 3), pow(&ac, n / 2 + 1));
    let t = Instant::now();
    let mut sum = 0;
    for _ in 0..samples {
        let prod = black_box(&ac_p) * black_box(&af_m);
        sum += dense_kernel_dim(&prod, 1e-8);
    }
    black_box(sum);
    t.elapsed().as_secs_f64() / samples as f64
}

/// On-CPU time of this thread in seconds (Linux), or `None`.
fn cpu_seconds() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: f64 = s.split_whitespace().next()?.parse().ok()?;
    Some(ns * 1e-9)
}

/// Seconds `f` takes: on-CPU time of this thread, wall clock where that is missing.
fn timed(f: impl FnOnce()) -> f64 {
    let (t0, c0) = (Instant::now(), cpu_seconds());
    f();
    let wall = t0.elapsed().as_secs_f64();
    match (c0, cpu_seconds()) {
        (Some(a), Some(b)) => b - a,
        _ => wall,
    }
}

fn main() {
    let threads = std::thread::available_parallelism().map_or(1, |x| x.get());
    println!("# {threads} hardware threads");
    if std::env::args().any(|a| a == "--cells-only") {
        cell_updates();
        return;
    }
    // 1. Kernel dimensions alone.
    let n = 1000;
    let t = Instant::now();
    let mut sum = 0usize;
    let mut with_kernel = 0usize;
    for total in 2..=4000 {
        for p in 1..total {
            let h = kernel_dim_closed_form(n, total - p, p);
            sum += h;
            with_kernel += usize::from(h > 0);
        }
    }
    println!(
        "closed-form kernel dims, N = 1000, all {PAIRS_1000} pairs m+p ≤ 4000: {:.3} s ({with_kernel} pairs with a kernel)",
        t.elapsed().as_secs_f64()
    );
    // 1b. The backbone scans, as the job runs them (no orbit shapes kept).
    let mut scan_times = Vec::new();
    for gap in [1e-3, 0.0, -1e-3] {
        let bar = WaveBar::unit(n, gap);
        for th in [1, threads] {
            let t = Instant::now();
            let pts = scan_with(&bar, (2, 4000), 1, false, false, th, &|| {
                ControlFlow::Continue(())
            })
            .unwrap_or_default();
            let s = t.elapsed().as_secs_f64();
            println!(
                "backbone scan N = 1000, m+p ≤ 4000, g0 = {gap:+e}, {th} thread(s): {s:.2} s, {} admissible points",
                pts.len()
            );
            if th == threads {
                scan_times.push(s);
            }
        }
    }
    // 2. The straightforward path at N = 1000 on a sample of pairs with a kernel, over the
    // whole range of periods.
    let bar = WaveBar::unit(n, 1e-3);
    let t = Instant::now();
    let mut count = 0usize;
    for total in (2..=4000).step_by(97) {
        for p in (1..total).step_by(13) {
            if kernel_dim_closed_form(n, total - p, p) > 0 {
                black_box(examine(&bar, total - p, p, 0));
                count += 1;
            }
            if count >= 400 {
                break;
            }
        }
    }
    let per = t.elapsed().as_secs_f64() / count as f64;
    println!(
        "straightforward examine, N = 1000: {:.0} µs per pair with a kernel ({count} sampled) → {:.0} s for the {with_kernel} pairs",
        per * 1e6,
        per * with_kernel as f64
    );
    // 3. Dense SVD at N = 50, 100, 200: per-pair time, growth exponent, extrapolation.
    let mut dense = Vec::new();
    for (nd, samples) in [(50usize, 40usize), (100, 12), (200, 3)] {
        let per_d = dense_per_pair(nd, samples);
        println!(
            "dense SVD kernel N = {nd}: {:.2} ms per (m, p) → {:.0} s for its own scan m+p ≤ {} ({} pairs)",
            per_d * 1e3,
            per_d * pairs(nd),
            4 * nd,
            pairs(nd)
        );
        dense.push((nd as f64, per_d));
    }
    let alpha = (dense[2].1 / dense[0].1).ln() / (dense[2].0 / dense[0].0).ln();
    let per_1000 = dense[1].1 * (1000.0 / 100.0f64).powf(alpha);
    let total_1000 = per_1000 * PAIRS_1000;
    let best_scan = scan_times.iter().copied().fold(f64::INFINITY, f64::min);
    println!(
        "dense SVD growth per pair ∝ N^{alpha:.2} (N = 50 → 200); extrapolated N = 1000: {per_1000:.2} s per pair, {total_1000:.2e} s ({:.1} years) for all m+p ≤ 4000, kernels only — {:.1e}× the fast scan",
        total_1000 / 3.156e7,
        total_1000 / best_scan
    );
    cell_updates();
    black_box(sum);
}

/// Cell updates per second (N counted per step, see docs/wfem.md).
fn cell_updates() {
    for cells in [1_000usize, 10_000, 100_000, 1_000_000] {
        let mut bar = WaveBar::unit(cells, 1e-3);
        bar.initial_velocity = 1e-3;
        let steps = 2_000_000;
        let mut st = bar.initial_state();
        let mut contacts = 0usize;
        let secs = timed(|| {
            for _ in 0..steps {
                contacts += usize::from(black_box(step(&bar, &mut st)).contact);
            }
        });
        black_box(contacts);
        let ring = cells as f64 * steps as f64 / secs;
        let ns_step = secs / steps as f64 * 1e9;
        bar.damping = 1e-3;
        let steps_f = (200_000_000 / cells).max(20);
        let mut st = bar.initial_state();
        let forced_secs = timed(|| {
            for _ in 0..steps_f {
                black_box(step(&bar, &mut st));
            }
        });
        let forced = cells as f64 * steps_f as f64 / forced_secs;
        let steps_x = (20_000_000 / cells).max(5);
        let (mut s, mut v) = (vec![0.0; cells], vec![1e-3; cells]);
        let flux_secs = timed(|| {
            for _ in 0..steps_x {
                (s, v) = flux_form_step(&bar, &s, &v, EndCondition::Free);
            }
        });
        black_box(&s);
        let flux = cells as f64 * steps_x as f64 / flux_secs;
        println!(
            "N = {cells:>8}: unforced signed permutation {ring:.2e} cell-updates/s ({ns_step:.1} ns per step, O(1)); with damping source (every cell read and written) {forced:.2e}; flux form (36)–(39) {flux:.2e}"
        );
    }
}
