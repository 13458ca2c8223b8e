//! WFEM and nonsmooth-modal-analysis speed (plain `fn main`, `harness = false`):
//! `cargo bench -p signorini-core --bench wfem` (add `-- quick` to skip the N = 1000 full scan).

use signorini_core::modal::kernel::{
    SignedPermutation, dense_kernel_dim, dense_matrix, kernel_dim_closed_form,
};
use signorini_core::modal::{candidate_phases, scan};
use signorini_core::scenes::LeftEnd;
use signorini_core::wfem::{EndCondition, WaveBar, flux_form_step, step};
use std::hint::black_box;
use std::ops::ControlFlow;
use std::time::Instant;

fn main() {
    let quick = std::env::args().any(|a| a == "quick");
    // 1. Kernel dimensions of every (m, p), m + p ≤ 4000, N = 1000.
    let n = 1000;
    let t = Instant::now();
    let mut sum = 0usize;
    for total in 2..=4000 {
        for p in 1..total {
            sum += kernel_dim_closed_form(n, total - p, p);
        }
    }
    println!(
        "closed-form kernel dims, N = 1000, all m+p ≤ 4000 ({} pairs): {:.3} s (Σh = {sum})",
        3999 * 4000 / 2,
        t.elapsed().as_secs_f64()
    );
    let t = Instant::now();
    let mut count = 0usize;
    for total in (2..=4000).step_by(40) {
        for p in 1..total {
            sum +=
                SignedPermutation::product(n, LeftEnd::Fixed, &candidate_phases(total - p, p, 0))
                    .kernel_dim();
            count += 1;
        }
    }
    let per = t.elapsed().as_secs_f64() / count as f64;
    println!(
        "cycle-structure kernel dims, N = 1000: {:.2} µs per (m, p) → {:.1} s for all m+p ≤ 4000",
        per * 1e6,
        per * 7_998_000.0
    );
    // 2. Backbone scan (kernel + admissibility) at N = 1000.
    let bar = WaveBar::unit(n, 1e-3);
    let range = if quick { (3900, 4000) } else { (2, 4000) };
    let t = Instant::now();
    let pts = scan(
        &bar,
        range,
        1,
        false,
        std::thread::available_parallelism().map_or(1, |x| x.get()),
        &|| ControlFlow::Continue(()),
    )
    .unwrap_or_default();
    println!(
        "backbone scan N = 1000, periods {range:?}: {:.2} s, {} admissible points",
        t.elapsed().as_secs_f64(),
        pts.len()
    );
    // 3. Dense SVD at N = 100 (per (m, p), products precomputed), extrapolated.
    let nd = 100;
    let bar_d = WaveBar::unit(nd, 0.0);
    let af = dense_matrix(&bar_d, EndCondition::Free);
    let ac = dense_matrix(&bar_d, EndCondition::Contact);
    let samples = 20;
    let t = Instant::now();
    for _ in 0..samples {
        let prod = &ac * &af;
        sum += dense_kernel_dim(black_box(&prod), 1e-8);
    }
    let per_d = t.elapsed().as_secs_f64() / samples as f64;
    println!(
        "dense SVD N = 100: {:.2} ms per (m, p) → {:.0} s for all m+p ≤ 400 (N = 100 scan); ×1000 (N³) → {:.0} s per pair-set scaled to N = 1000, {:.2e} s for m+p ≤ 4000",
        per_d * 1e3,
        per_d * 79_800.0,
        per_d * 1000.0 * 79_800.0,
        per_d * 1000.0 * 7_998_000.0
    );
    // 4. Cell updates per second.
    for cells in [1_000usize, 10_000, 100_000, 1_000_000] {
        let mut bar = WaveBar::unit(cells, 1e-3);
        bar.initial_velocity = 1e-3;
        let steps = (200_000_000 / cells).max(50);
        let mut st = bar.initial_state();
        let t = Instant::now();
        for _ in 0..steps {
            black_box(step(&bar, &mut st));
        }
        let ring = cells as f64 * steps as f64 / t.elapsed().as_secs_f64();
        bar.damping = 1e-3;
        let steps_f = (20_000_000 / cells).max(20);
        let mut st = bar.initial_state();
        let t = Instant::now();
        for _ in 0..steps_f {
            black_box(step(&bar, &mut st));
        }
        let forced = cells as f64 * steps_f as f64 / t.elapsed().as_secs_f64();
        let (mut s, mut v) = (vec![0.0; cells], vec![1e-3; cells]);
        let t = Instant::now();
        for _ in 0..steps_f {
            (s, v) = flux_form_step(&bar, &s, &v, EndCondition::Free);
        }
        black_box(&s);
        let flux = cells as f64 * steps_f as f64 / t.elapsed().as_secs_f64();
        println!(
            "N = {cells:>8}: signed permutation {ring:.2e}, with damping source {forced:.2e}, flux form (36)–(39) {flux:.2e} cell-updates/s"
        );
    }
    black_box(sum);
}
