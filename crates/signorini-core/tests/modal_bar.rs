//! Nonsmooth modal analysis (Yoong et al. 2018, §§4–6): kernels from the cycle structure against
//! the dense SVD, grazing modes, asymptotes, hardening/softening, two contact phases, stability.

// Only the core library must stay pure (clippy.toml): a test may read fixtures and print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use nalgebra::DMatrix;
use signorini_core::modal::kernel::{
    SignedPermutation, dense_kernel_dim, dense_matrix, kernel_dim_closed_form,
};
use signorini_core::modal::orbit::stability;
use signorini_core::modal::{
    BackbonePoint, candidate_phases, examine, first_mode_orbit, main_asymptote, scan,
};
use signorini_core::scenes::LeftEnd;
use signorini_core::wfem::{EndCondition, WaveBar, WaveState, step};
use std::ops::ControlFlow;

#[test]
fn cycle_kernel_equals_dense_svd_for_every_m_p_up_to_200() {
    let n = 20;
    let bar = WaveBar::unit(n, 0.0);
    let af = dense_matrix(&bar, EndCondition::Free);
    let ac = dense_matrix(&bar, EndCondition::Contact);
    let mut af_pow = vec![DMatrix::<f64>::identity(2 * n, 2 * n)];
    let mut ac_pow = vec![DMatrix::<f64>::identity(2 * n, 2 * n)];
    for k in 1..200 {
        af_pow.push(&af * &af_pow[k - 1]);
        ac_pow.push(&ac * &ac_pow[k - 1]);
    }
    let pairs: Vec<(usize, usize)> = (1..200)
        .flat_map(|m| (1..=200 - m).map(move |p| (m, p)))
        .collect();
    let mismatches: Vec<_> = std::thread::scope(|s| {
        let chunks: Vec<_> = pairs
            .chunks(pairs.len() / 2 + 1)
            .map(|chunk| {
                let (af_pow, ac_pow) = (&af_pow, &ac_pow);
                s.spawn(move || {
                    let mut bad = Vec::new();
                    for &(m, p) in chunk {
                        let cycles = SignedPermutation::product(
                            n,
                            LeftEnd::Fixed,
                            &candidate_phases(m, p, 0),
                        )
                        .kernel_dim();
                        let closed = kernel_dim_closed_form(n, m, p);
                        // Singular values of P − I for a signed permutation are |λ − 1| ≥ 2 sin(π/40) ≈ 0.157
                        // or 0; the flux-form matrices carry round-off ≪ 1e-8.
                        let dense = dense_kernel_dim(&(&ac_pow[p] * &af_pow[m]), 1e-8);
                        if cycles != dense || closed != dense {
                            bad.push((m, p, cycles, closed, dense));
                        }
                    }
                    bad
                })
            })
            .collect();
        chunks
            .into_iter()
            .flat_map(|h| h.join().expect("thread"))
            .collect()
    });
    assert_eq!(pairs.len(), 19_900);
    assert!(mismatches.is_empty(), "{mismatches:?}");
}

#[test]
fn two_phase_kernels_match_dense_svd() {
    let n = 12;
    let bar = WaveBar::unit(n, 0.0);
    let af = dense_matrix(&bar, EndCondition::Free);
    let ac = dense_matrix(&bar, EndCondition::Contact);
    let pow =
        |a: &DMatrix<f64>, k: usize| (0..k).fold(DMatrix::identity(2 * n, 2 * n), |acc, _| a * acc);
    for (m, p, k) in [(5, 3, 7), (10, 2, 10), (12, 6, 12), (3, 9, 17), (8, 4, 20)] {
        let dense = pow(&ac, p) * pow(&af, k) * pow(&ac, p) * pow(&af, m);
        let cycles =
            SignedPermutation::product(n, LeftEnd::Fixed, &candidate_phases(m, p, k)).kernel_dim();
        assert_eq!(
            cycles,
            dense_kernel_dim(&dense, 1e-8),
            "(m, p, k) = ({m}, {p}, {k})"
        );
    }
}

fn first_branch(points: &[BackbonePoint]) -> Vec<&BackbonePoint> {
    points
        .iter()
        .filter(|p| {
            p.orbit.is_some() && p.k == 0 && p.omega_over_omega1 > 1.0 && p.omega_over_omega1 < 2.0
        })
        .collect()
}

fn no_stop() -> ControlFlow<()> {
    ControlFlow::Continue(())
}

#[test]
fn grazing_modes_have_period_3l_over_c_and_5l_over_4c() {
    let n = 40;
    let bar = WaveBar::unit(n, 0.0);
    // First mode: T = 3L/c = 3N steps with contact L/c = N steps.
    let first = examine(&bar, 2 * n, n, 0).expect("kernel");
    let orbit = first
        .orbit
        .as_ref()
        .expect("the grazing first mode is admissible");
    assert!((first.omega_over_omega1 - main_asymptote(1)).abs() < 1e-12);
    // Second mode: T = 5L/(4c), contact L/(4c).
    let second = examine(&bar, n, n / 4, 0).expect("kernel");
    assert!(
        second.orbit.is_some(),
        "the grazing second mode is admissible"
    );
    assert!((second.omega_over_omega1 - main_asymptote(2)).abs() < 1e-12);
    // g0 = 0: any multiple is an orbit ("at every energy"): Algorithm 2 reproduces the period
    // and the contact duration for energies spread over four decades.
    for scale in [0.01, 0.3, 1.0, 7.0, 100.0] {
        let ring: Vec<f64> = orbit.ring.iter().map(|x| x * scale).collect();
        let mut state = WaveState::from_ring(ring.clone(), 0.0, scale * orbit.u[0]);
        let mut contact_steps = 0;
        for _ in 0..3 * n {
            contact_steps += usize::from(step(&bar, &mut state).contact);
        }
        assert_eq!(contact_steps, n, "scale {scale}");
        let back = state.ring();
        let err = back
            .iter()
            .zip(&ring)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f64, f64::max);
        assert!(err <= 1e-12 * scale, "scale {scale}: not periodic, {err:e}");
    }
    // A scan of (ω₁, 2ω₁) at g0 = 0 finds admissible one-phase orbits only on vertical lines: the
    // main asymptote 4ω₁/3 (period exactly 3L/c) and the subharmonic asymptotes (16) with k = 1,
    // ω = 4(n + 1)ω₁/(2n + 3).
    let pts = scan(&bar, (2 * n + 1, 4 * n - 1), 1, false, 2, &no_stop).expect("scan");
    let main: Vec<_> = first_branch(&pts);
    assert!(!main.is_empty());
    for p in &main {
        let on_main = p.m + p.p == 3 * n;
        let on_sub = (1..=4 * n).any(|k| {
            (p.omega_over_omega1 - 4.0 * (k + 1) as f64 / (2 * k + 3) as f64).abs() < 1e-12
        });
        assert!(
            on_main || on_sub,
            "admissible grazing orbit off the asymptotes: {:?}",
            (p.m, p.p, p.omega_over_omega1)
        );
    }
    assert!(main.iter().any(|p| (p.m, p.p) == (2 * n, n)));
    for p in main.iter().filter(|p| p.m + p.p == 3 * n) {
        assert!((p.period - 3.0).abs() < 1e-12);
    }
}

#[test]
fn positive_gap_hardens_negative_gap_softens_toward_the_asymptote() {
    let n = 40;
    let asym = main_asymptote(1);
    for (gap, hardening) in [(1e-3, true), (-1e-3, false)] {
        let bar = WaveBar::unit(n, gap);
        let pts = scan(&bar, (2 * n + 1, 4 * n), 1, false, 2, &no_stop).expect("scan");
        let branch = first_branch(&pts);
        assert!(branch.len() >= 5, "gap {gap}: {} points", branch.len());
        // The main branch lies on its side of the asymptote and reaches it within one step.
        let main: Vec<_> = branch
            .iter()
            .filter(|p| {
                if hardening {
                    p.omega_over_omega1 <= asym + 1e-9
                } else {
                    p.omega_over_omega1 >= asym - 1e-9
                }
            })
            .collect();
        assert!(
            main.len() * 2 >= branch.len(),
            "gap {gap}: most points on the main branch"
        );
        let closest = main
            .iter()
            .map(|p| (p.omega_over_omega1 - asym).abs())
            .fold(f64::INFINITY, f64::min);
        assert!(
            closest <= asym * 1.5 / (3 * n) as f64,
            "gap {gap}: nearest {closest}"
        );
        // Hardening: energy grows with frequency (g0 > 0); softening: it falls (g0 < 0). Every
        // frequency also carries high-energy points of other families, so compare the lowest
        // energy found at the lowest and at the highest frequency of the branch.
        let w_lo = main
            .iter()
            .map(|p| p.omega_over_omega1)
            .fold(f64::INFINITY, f64::min);
        let w_hi = main
            .iter()
            .map(|p| p.omega_over_omega1)
            .fold(0.0f64, f64::max);
        let lowest_energy_at = |w: f64| {
            main.iter()
                .filter(|p| p.omega_over_omega1 == w)
                .map(|p| p.energy_normalized)
                .fold(f64::INFINITY, f64::min)
        };
        let (lo, hi) = (
            (w_lo, lowest_energy_at(w_lo)),
            (w_hi, lowest_energy_at(w_hi)),
        );
        if hardening {
            assert!(hi.1 > 2.0 * lo.1, "g0 > 0 must harden: {lo:?} → {hi:?}");
            assert!(lo.0 >= 1.0 - 1e-9, "starts at ω₁ or above");
        } else {
            assert!(hi.1 < 0.5 * lo.1, "g0 < 0 must soften: {lo:?} → {hi:?}");
            assert!(hi.0 <= 2.0 + 1e-9, "starts at Ω₁ or below");
        }
        println!("gap {gap}: lowest energy {lo:?} → {hi:?}");
    }
}

#[test]
fn first_mode_orbit_is_orbitally_stable_over_1000_periods() {
    let n = 40;
    let bar = WaveBar::unit(n, 1e-3);
    let pts = scan(&bar, (3 * n, 4 * n), 1, false, 2, &no_stop).expect("scan");
    let pt = first_mode_orbit(&pts).expect("a first-mode orbit");
    let orbit = pt.orbit.as_ref().expect("admissible");
    let st = stability(&bar, orbit, 1000, 1e-6);
    assert!(st.orbit_drift < 1e-6, "the orbit itself drifts: {st:?}");
    assert!(st.relative_deviation < 1e-3, "{st:?}");
}

#[test]
fn two_contact_phases_per_period_exist_for_positive_gap() {
    // (18) with equal contact phases: the branch near ω₂/5 = 3ω₁/5 (Fig. 19).
    let n = 20;
    let bar = WaveBar::unit(n, 1e-3);
    let pts = scan(&bar, (4 * n, 8 * n), 2, false, 2, &no_stop).expect("scan");
    let two: Vec<_> = pts
        .iter()
        .filter(|p| p.k > 0 && p.orbit.is_some())
        .collect();
    assert!(!two.is_empty(), "no admissible two-contact orbit");
    for p in &two {
        assert!(
            p.kernel_dim >= 2,
            "two contact phases need dim ker ≥ 2, got {}",
            p.kernel_dim
        );
    }
}
