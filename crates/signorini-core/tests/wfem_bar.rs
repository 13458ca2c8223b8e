//! WFEM (Yoong et al. 2018, Appendices A–B): the signed-permutation step against the paper's
//! (36)–(39), exact energy conservation, the energy balance with sources, and the
//! Doyen–Ern–Piperno bar against its exact solution (first-order convergence).

use signorini_core::observer::Recorder;
use signorini_core::scenes::{Bar, HarmonicSpec, LeftEnd};
use signorini_core::wfem::exact::{ExactBar, ExactSolution};
use signorini_core::wfem::job::run_wave;
use signorini_core::wfem::{EndCondition, WaveBar, WaveState, flux_form_step, step, transport};

/// Deterministic pseudo-random numbers in [−1, 1] (no dependency needed).
fn noise(n: usize, seed: u64) -> Vec<f64> {
    let mut x = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (0..n)
        .map(|_| {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((x >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        })
        .collect()
}

#[test]
fn signed_permutation_equals_flux_form_36_39() {
    for left in [LeftEnd::Fixed, LeftEnd::Free] {
        let mut bar = WaveBar::unit(37, 0.0);
        bar.left = left;
        bar.young = 4.0; // c = 2, ρc = 2: the impedance is not 1
        let z = bar.impedance();
        let sigma = noise(37, 1);
        let v = noise(37, 2);
        let mut ring_state = WaveState::from_cells(&sigma, &v, z, 0.0, 0.0);
        let (mut s, mut w) = (sigma.clone(), v.clone());
        let mut worst: f64 = 0.0;
        for k in 0..500 {
            // Switch the contact-end condition on a pattern to exercise (50) and (51).
            let end = if (k / 7) % 2 == 0 {
                EndCondition::Free
            } else {
                EndCondition::Contact
            };
            transport(&bar, &mut ring_state, end, 0.0);
            (s, w) = flux_form_step(&bar, &s, &w, end);
            let (rs, rv) = ring_state.cells_sigma_v(z);
            for i in 0..37 {
                worst = worst.max((rs[i] - s[i]).abs()).max((rv[i] - w[i]).abs());
            }
        }
        // Values of order 1 go through 500 averaging steps in the flux form: round-off only.
        assert!(worst < 1e-12, "{left:?}: max difference {worst:e}");
    }
}

#[test]
fn unforced_energy_conserved_over_a_million_steps() {
    // A bar thrown at the obstacle: it closes and opens the gap many times.
    let mut bar = WaveBar::unit(64, 0.05);
    bar.initial_velocity = 0.3;
    let mut state = bar.initial_state();
    let e0 = state.energy(&bar);
    let mut closures = 0;
    let mut was = false;
    for _ in 0..1_000_000 {
        let t = step(&bar, &mut state);
        closures += usize::from(t.contact && !was);
        was = t.contact;
    }
    let e1 = state.energy(&bar);
    assert!(closures > 1000, "the gap closed {closures} times");
    assert!(
        ((e1 - e0) / e0).abs() < 1e-12,
        "relative energy change {:e}",
        (e1 - e0) / e0
    );
    // The incremental contact-end displacement equals the strain integration.
    let u_strain = state.u_right_from_strains(&bar);
    assert!(
        (u_strain - state.u_right).abs() < 1e-9,
        "{u_strain} vs {}",
        state.u_right
    );
}

#[test]
fn energy_balance_closes_with_every_source() {
    let mut bar = WaveBar::unit(50, 2e-3);
    bar.body_force = 0.01;
    bar.damping = 0.05;
    bar.harmonic_force = Some(HarmonicSpec {
        amplitude: 0.02,
        omega: 4.0,
    });
    bar.wall_motion = Some(HarmonicSpec {
        amplitude: -4e-3,
        omega: 3.0,
    });
    let mut state = bar.initial_state();
    let mut rec = Recorder::default();
    let stats = run_wave(&bar, &mut state, 20_000, 1, &mut rec).expect("run");
    let e_max = rec
        .column("energy")
        .unwrap()
        .iter()
        .fold(0.0f64, |m, x| m.max(*x));
    assert!(stats.closures > 10, "closures {}", stats.closures);
    assert!(
        stats.work_contact_total.abs() > 1e-6 * e_max,
        "the moving wall does work"
    );
    assert!(stats.work_damping_total < 0.0);
    // Round-off of sums of 100 squares of order e_max per step.
    assert!(
        stats.max_abs_balance_residual < 1e-13 * e_max.max(1e-300) * 100.0,
        "{:e} vs {e_max:e}",
        stats.max_abs_balance_residual
    );
    // Cumulative: E_end − E_0 = Σ works.
    let total = stats.work_ext_total + stats.work_damping_total + stats.work_contact_total;
    assert!(((stats.energy_final - stats.energy_initial) - total).abs() < 1e-10 * e_max);
}

fn dep_errors(cells: usize, exact: &ExactSolution, t_end: f64) -> (f64, f64, Vec<f64>) {
    let bar = WaveBar::from_bar(&Bar::doyen_ern_piperno(cells)).expect("DEP bar");
    let mut state = bar.initial_state();
    let dt = bar.dt();
    let steps = (t_end / dt).round() as u64;
    let (mut e_u, mut e_r) = (0.0f64, 0.0);
    let mut closures = Vec::new();
    let mut was = false;
    for _ in 0..steps {
        let t0 = state.step as f64 * dt;
        let terms = step(&bar, &mut state);
        if terms.contact && !was {
            closures.push(t0);
        }
        was = terms.contact;
        let t1 = state.step as f64 * dt;
        e_u = e_u.max((state.u_right - exact.end_displacement(t1)).abs());
        // L¹ error of the contact force over the step (midpoint of the exact force).
        e_r += dt * (bar.area * terms.contact_stress - exact.contact_force(0.5 * (t0 + t1))).abs();
    }
    (e_u, e_r, closures)
}

#[test]
fn doyen_ern_piperno_bar_converges_at_first_order() {
    let t_end = 6.0;
    let exact = ExactSolution::solve(ExactBar::doyen_ern_piperno(), t_end);
    // Hand check of the first contact: impact at t = √(2 g0 / g) = 1 s, contact for 2L/c.
    let (c0, r0) = exact.contacts[0];
    assert!(
        (c0 - 1.0).abs() < 1e-12 && (r0 - (1.0 + 2.0 / 3.0)).abs() < 1e-12,
        "{c0} {r0}"
    );
    assert!(exact.contacts.len() >= 2, "{:?}", exact.contacts);
    let mut prev: Option<(f64, f64, f64)> = None;
    let mut orders = Vec::new();
    for cells in [50, 100, 200, 400, 800] {
        let (e_u, e_r, closures) = dep_errors(cells, &exact, t_end);
        let e_t = exact
            .contacts
            .iter()
            .zip(&closures)
            .map(|(c, t)| (c.0 - t).abs())
            .fold(0.0f64, f64::max);
        assert_eq!(
            closures.len(),
            exact.contacts.len(),
            "N = {cells}: closures {closures:?} vs {:?}",
            exact.contacts
        );
        if let Some((pu, pr, pt)) = prev {
            orders.push((
                (pu / e_u).log2(),
                (pr / e_r).log2(),
                (pt / e_t.max(1e-300)).log2(),
            ));
        }
        prev = Some((e_u, e_r, e_t));
        // Errors are O(Δt): Δt = 1/(3N) s; constants measured ≈ a few.
        let dt = 1.0 / (3.0 * cells as f64);
        assert!(e_u < 60.0 * dt, "N = {cells}: u error {e_u:e}");
    }
    let mean =
        |f: fn(&(f64, f64, f64)) -> f64| orders.iter().map(f).sum::<f64>() / orders.len() as f64;
    let (ou, or) = (mean(|o| o.0), mean(|o| o.1));
    assert!(
        (0.8..1.3).contains(&ou),
        "displacement order {ou} ({orders:?})"
    );
    assert!(
        (0.8..1.3).contains(&or),
        "contact-force order {or} ({orders:?})"
    );
}
