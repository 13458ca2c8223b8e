//! The main branches of the nonsmooth modes as the paper draws them (Yoong, Thorin & Legrand
//! 2018, §6.1, Figs. 5–8): the k-th main branch is the line (2k − 1) m + 2k p = 4N of
//! one-contact-phase orbits; on the first, E/E_lin = (8/π²)/(4ω₁/ω − 3)² with ω = 2π/T the
//! orbit's frequency and ω₁ = πc/(2L) the first fixed–free frequency (10) (the code's
//! `omega_over_omega1` is ω/ω₁); the second has the asymptote 16ω₁/5, and the k-th the energy
//! (8/π²)/((2k)² ω₁/ω − (2k + 1))²; orbits without any wall
//! force are not modes; the job shows an orbit of the first main branch.

use signorini_core::job::{Job, run};
use signorini_core::modal::fast::{Scratch, examine_one_contact};
use signorini_core::modal::orbit::trajectory;
use signorini_core::modal::{
    BackbonePoint, examine, first_mode_orbit, main_asymptote, main_branch, scan,
};
use signorini_core::observer::{Observer, StepRecord};
use signorini_core::outcome::Chart;
use signorini_core::spec::JobSpec;
use signorini_core::wfem::{EndCondition, WaveBar, WaveState, step};
use std::f64::consts::PI;
use std::ops::ControlFlow;

/// The admissible one-contact-phase orbits on the line (2k − 1) m + 2k p = 4N, by increasing ω.
fn branch(bar: &WaveBar, k: usize) -> Vec<BackbonePoint> {
    let n = bar.cells;
    let mut s = Scratch::default();
    let mut pts: Vec<BackbonePoint> = (1..4 * n)
        .filter_map(|p| {
            let m = (4 * n).checked_sub(2 * k * p)?;
            (m % (2 * k - 1) == 0 && m > 0).then_some((m / (2 * k - 1), p))
        })
        .filter_map(|(m, p)| examine_one_contact(bar, m, p, &mut s))
        .filter(|pt| pt.admissible.is_some())
        .collect();
    pts.sort_by(|a, b| a.omega_over_omega1.total_cmp(&b.omega_over_omega1));
    pts
}

#[test]
fn first_main_branch_energy_is_8_over_pi2_over_4w1_over_w_minus_3_squared() {
    for n in [100usize, 1000] {
        for gap in [1e-3, -1e-3] {
            let bar = WaveBar::unit(n, gap);
            let pts = branch(&bar, 1);
            // A branch spans (ω₁, 4ω₁/3] for g0 > 0 and [4ω₁/3, Ω₁) for g0 < 0: about N/2
            // orbits of the N − 1 on the line.
            assert!(pts.len() * 3 >= n, "N = {n}, g0 = {gap}: {}", pts.len());
            let mut worst: f64 = 0.0;
            for pt in &pts {
                assert_eq!(pt.branch, Some(1));
                let w = pt.omega_over_omega1;
                let expected = (8.0 / (PI * PI)) / (4.0 / w - 3.0).powi(2);
                worst = worst.max((pt.energy_normalized / expected - 1.0).abs());
                if gap > 0.0 {
                    assert!((1.0..=main_asymptote(1) + 1e-12).contains(&w), "{w}");
                } else {
                    assert!((main_asymptote(1) - 1e-12..=2.0).contains(&w), "{w}");
                }
            }
            assert!(
                worst < 1e-12,
                "N = {n}, g0 = {gap}: relative error {worst:e}"
            );
            // Single-valued and monotone: hardening for g0 > 0, softening for g0 < 0.
            for w in pts.windows(2) {
                let (a, b) = (&w[0], &w[1]);
                assert!(b.omega_over_omega1 > a.omega_over_omega1);
                assert_eq!(
                    b.energy_normalized > a.energy_normalized,
                    gap > 0.0,
                    "N = {n}, g0 = {gap}"
                );
            }
        }
    }
}

#[test]
fn second_main_branch_has_the_asymptote_16_over_5() {
    let n = 100;
    assert!((main_asymptote(2) - 16.0 / 5.0).abs() < 1e-15);
    // g0 = 0: the branch is the vertical line ω = 16ω₁/5, (m, p) = (N, N/4).
    let grazing = branch(&WaveBar::unit(n, 0.0), 2);
    assert!(!grazing.is_empty());
    for pt in &grazing {
        assert!((pt.omega_over_omega1 - 16.0 / 5.0).abs() < 1e-12, "{pt:?}");
    }
    assert!(grazing.iter().any(|pt| (pt.m, pt.p) == (n, n / 4)));
    // g0 ≠ 0: on either side of it, the energy growing without bound toward it.
    for gap in [1e-3, -1e-3] {
        let pts = branch(&WaveBar::unit(n, gap), 2);
        assert!(pts.len() >= 5, "g0 = {gap}: {}", pts.len());
        for pt in &pts {
            let w = pt.omega_over_omega1;
            if gap > 0.0 {
                assert!((3.0..=16.0 / 5.0 + 1e-12).contains(&w), "{w}");
            } else {
                assert!((16.0 / 5.0 - 1e-12..=4.0).contains(&w), "{w}");
            }
        }
        let nearest = if gap > 0.0 { pts.last() } else { pts.first() }.expect("points");
        let farthest = if gap > 0.0 {
            &pts[0]
        } else {
            &pts[pts.len() - 1]
        };
        // One step of T from the asymptote: T = 125 ± 1 steps.
        assert!(
            (nearest.omega_over_omega1 - 16.0 / 5.0).abs() <= 4.0 * n as f64 / 124.0 - 3.2 + 1e-12,
            "g0 = {gap}: {}",
            nearest.omega_over_omega1
        );
        assert!(
            nearest.energy_normalized > 50.0 * farthest.energy_normalized,
            "g0 = {gap}: {} vs {}",
            nearest.energy_normalized,
            farthest.energy_normalized
        );
        // The k-th branch generalises the first: E/E_lin = (8/π²)/((2k)² ω₁/ω − (2k + 1))²,
        // which diverges at the asymptote (2k)²/(2k + 1) ω₁.
        for (k, cells) in [(2usize, n), (3, 4 * n)] {
            let pts = branch(&WaveBar::unit(cells, gap), k);
            assert!(pts.len() >= 3, "k = {k}, g0 = {gap}");
            for pt in &pts {
                let (kk, w) = ((2 * k) as f64, pt.omega_over_omega1);
                let expected = (8.0 / (PI * PI)) / (kk * kk / w - (kk + 1.0)).powi(2);
                let err = (pt.energy_normalized / expected - 1.0).abs();
                assert!(
                    err < 1e-12,
                    "k = {k}, g0 = {gap}, ({}, {}): {err:e}",
                    pt.m,
                    pt.p
                );
            }
        }
    }
}

#[test]
fn a_free_vibration_that_touches_the_wall_is_not_a_mode() {
    // (m, p) = (9, 7), T = 16 Δt at N = 100: a kernel vector closes at the wall, but its force is
    // zero at every contact step, so the contact/free split is decided by round-off.
    let bar = WaveBar::unit(100, 1e-3);
    let pt = examine(&bar, 9, 7, 0).expect("a nontrivial kernel");
    assert!(pt.kernel_dim >= 1);
    assert_eq!(pt.admissible, None);
    assert!(pt.orbit.is_none());
    let fast = examine_one_contact(&bar, 9, 7, &mut Scratch::default()).expect("kernel");
    assert_eq!(fast.admissible, None);
    for (m, p) in [(10, 6), (11, 5), (12, 4)] {
        assert_eq!(examine(&bar, m, p, 0).and_then(|pt| pt.admissible), None);
    }
}

#[test]
fn every_admissible_mode_presses_on_the_wall() {
    for (n, gap) in [(40, 1e-3), (40, 0.0), (40, -1e-3), (17, 1e-3)] {
        let bar = WaveBar::unit(n, gap);
        let pts = scan(&bar, (2, 4 * n), 1, false, 2, &|| ControlFlow::Continue(())).expect("scan");
        assert!(pts.len() > 20);
        for pt in &pts {
            let orbit = pt.orbit.as_ref().expect("scan keeps shapes");
            let class = pt.admissible.expect("admissible");
            let traj = trajectory(&bar, &orbit.phases, &orbit.ring);
            let scale = traj.a_end.iter().fold(0.0f64, |a, x| a.max(x.abs()));
            let mut at = 0;
            let mut contact = Vec::new();
            for &(end, steps) in &orbit.phases {
                if end == EndCondition::Contact {
                    contact.extend_from_slice(&traj.a_end[at..at + steps]);
                }
                at += steps;
            }
            let min = contact.iter().copied().fold(f64::INFINITY, f64::min);
            assert!(
                min < -1e-6 * scale,
                "({}, {}): min force {min:e}",
                pt.m,
                pt.p
            );
            assert!(class.zero_force_steps < contact.len());
            // The branch column is the relation (2k − 1) m + 2k p = 4N.
            if let Some(k) = pt.branch {
                assert_eq!((2 * k - 1) * pt.m + 2 * k * pt.p, 4 * n);
            } else {
                assert_eq!(main_branch(n, pt.m, pt.p), None);
            }
        }
    }
}

struct Nothing;

impl Observer for Nothing {
    fn observe(&mut self, _: &StepRecord<'_>) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }
}

#[test]
fn the_job_shows_and_runs_an_orbit_of_the_first_main_branch() {
    let n = 40;
    let spec = format!(
        "name = \"modes\"\n[analysis]\nkind = \"nonsmooth_modes\"\ncells = {n}\ngaps = [1e-3, 0.0, -1e-3]\nphases = 1\nstability_periods = 100\n"
    );
    let job = Job::from_spec(&toml::from_str::<JobSpec>(&spec).expect("toml")).expect("valid");
    let out = run(&job, 2, &mut Nothing).expect("run");
    let summary = out.summary.to_map();
    // The summary names the analysis, not a scheme.
    assert_eq!(summary["analysis"], "nonsmooth_modes");
    assert!(!summary.contains_key("scheme"));
    let (m, p) = (
        summary["stability"]["m"].as_u64().expect("m") as usize,
        summary["stability"]["p"].as_u64().expect("p") as usize,
    );
    assert_eq!(m + 2 * p, 4 * n, "stability run off the main branch");
    let ends = out
        .charts
        .iter()
        .find_map(|c| match c {
            Chart::ContactEnd(e) => Some(e),
            _ => None,
        })
        .expect("contact_end chart");
    assert_eq!(ends.len(), 3);
    for e in ends {
        assert_eq!(e.m + 2 * e.p, 4 * n, "g0 = {}", e.gap);
        assert_eq!((e.u.len(), e.force.len()), (e.m + e.p + 1, e.m + e.p));
        // Fig. 8: free phase below the wall, a compressive force in contact, none when free.
        assert!(e.u.iter().all(|&u| u <= e.gap + 1e-12));
        assert!(e.force[..e.m].iter().all(|&r| r == 0.0));
        assert!(e.force[e.m..].iter().all(|&r| r <= 0.0));
        assert!(e.force[e.m..].iter().any(|&r| r < 0.0));
    }
    // Same choice as first_mode_orbit on the scan.
    let bar = WaveBar::unit(n, 1e-3);
    let pts = scan(&bar, (2, 4 * n), 1, false, 2, &|| ControlFlow::Continue(())).expect("scan");
    let shown = first_mode_orbit(&pts).expect("shown");
    assert_eq!((shown.m, shown.p), (m, p));
    // One panel per mode of the scan's main branches, with the backbone and the orbits.
    let names: Vec<&str> = out.charts.iter().map(Chart::name).collect();
    assert!(names.contains(&"backbone_mode_1") && names.contains(&"backbone_mode_2"));
    // The table's classification columns.
    let table = &out.tables[0];
    let col = |c: &str| table.columns.iter().position(|x| x == c).expect(c);
    let (b, z, g) = (col("branch"), col("zero_force_steps"), col("grazing_steps"));
    assert!(table.rows.iter().any(|r| r[b] == 1.0));
    assert!(table.rows.iter().any(|r| r[b] == 0.0));
    // A default table is finite (the service stores it as JSON, which has no NaN).
    assert!(table.rows.iter().flatten().all(|x| x.is_finite()));
    assert!(
        table
            .rows
            .iter()
            .all(|r| r[z] >= 0.0 && r[g] >= 0.0 && r[z] < r[col("p")])
    );
}

/// The paper's §6 remark ("admissible solutions are only found when h = 1") does not hold for
/// the discrete problem: most of the first main branch has h ≥ 2, and each of those orbits is
/// reproduced by Algorithm 2 itself (the switching integration, not the kernel): the state
/// returns to itself after T steps, with exactly p contact steps.
#[test]
fn main_branch_orbits_with_h_at_least_2_are_orbits_of_algorithm_2() {
    let n = 100;
    for gap in [1e-3, -1e-3] {
        let bar = WaveBar::unit(n, gap);
        let pts = branch(&bar, 1);
        let high: Vec<_> = pts.iter().filter(|pt| pt.kernel_dim >= 2).collect();
        assert!(
            high.len() * 2 > pts.len(),
            "g0 = {gap}: {} of {} with h ≥ 2",
            high.len(),
            pts.len()
        );
        for pt in high {
            let full = examine(&bar, pt.m, pt.p, 0).expect("kernel");
            let orbit = full.orbit.expect("admissible");
            let mut state = WaveState::from_ring(orbit.ring.clone(), 0.0, orbit.u[0]);
            let mut contact = 0;
            for _ in 0..pt.m + pt.p {
                contact += usize::from(step(&bar, &mut state).contact);
            }
            let scale = orbit.ring.iter().fold(0.0f64, |a, x| a.max(x.abs()));
            let err = state
                .ring()
                .iter()
                .zip(&orbit.ring)
                .fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
            assert_eq!(contact, pt.p, "g0 = {gap}, ({}, {})", pt.m, pt.p);
            assert!(
                err <= 1e-12 * scale,
                "g0 = {gap}, ({}, {}): {err:e}",
                pt.m,
                pt.p
            );
        }
    }
}
