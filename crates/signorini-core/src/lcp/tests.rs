use super::*;
use proptest::prelude::*;

/// Random symmetric positive definite n×n matrix A = BᵀB + δI (a Delassus-like operator).
fn spd(n: usize, entries: &[f64], delta: f64) -> Vec<f64> {
    let mut m = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            m[i * n + j] = (0..n)
                .map(|k| entries[k * n + i] * entries[k * n + j])
                .sum::<f64>();
        }
        m[i * n + i] += delta;
    }
    m
}

fn all_solvers() -> [LcpSolverKind; 3] {
    [
        LcpSolverKind::Lemke,
        LcpSolverKind::Pgs,
        LcpSolverKind::Enumeration,
    ]
}

#[test]
fn scalar_lcp_has_closed_form() {
    // 0 ≤ 2z − 3 ⊥ z ≥ 0 → z = 1.5.
    for kind in all_solvers() {
        let s = solve(
            Lcp {
                m: &[2.0],
                q: &[-3.0],
            },
            &LcpOptions {
                kind,
                ..Default::default()
            },
        )
        .unwrap();
        assert!((s.z[0] - 1.5).abs() < 1e-15, "{kind:?}");
    }
}

#[test]
fn lemke_reports_ray_on_infeasible_problem() {
    // w = −z − 1 can never be ≥ 0 with z ≥ 0.
    let e = solve_lemke(
        Lcp {
            m: &[-1.0],
            q: &[-1.0],
        },
        &LcpOptions::default(),
    )
    .unwrap_err();
    assert!(matches!(e, LcpError::RayTermination { .. }));
}

#[test]
fn pgs_reports_budget_exhaustion() {
    let m = [1.0, 0.999, 0.999, 1.0];
    let opts = LcpOptions {
        kind: LcpSolverKind::Pgs,
        tolerance: 1e-15,
        max_iterations: 3,
    };
    let e = solve(
        Lcp {
            m: &m,
            q: &[-1.0, -1.2],
        },
        &opts,
    )
    .unwrap_err();
    assert!(matches!(
        e,
        LcpError::NotConverged {
            solver: "pgs",
            iterations: 3,
            ..
        }
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]
    #[test]
    fn solvers_agree_on_spd_problems(
        n in 1usize..7,
        entries in proptest::collection::vec(-1.0f64..1.0, 36),
        q in proptest::collection::vec(-2.0f64..2.0, 6),
        delta in 0.05f64..1.0,
    ) {
        let m = spd(n, &entries[..n * n], delta);
        let q = &q[..n];
        let mut sols = Vec::new();
        for kind in all_solvers() {
            let opts = LcpOptions { kind, tolerance: 1e-11, max_iterations: 200_000 };
            let s = solve(Lcp { m: &m, q }, &opts).unwrap();
            prop_assert!(s.error <= 1e-11);
            prop_assert!(s.z.iter().all(|&z| z >= 0.0));
            let w = Lcp { m: &m, q }.w(&s.z);
            prop_assert!(w.iter().all(|&wi| wi >= -1e-10));
            sols.push(s.z);
        }
        // SPD M is a P-matrix: the solution is unique.
        for s in &sols[1..] {
            for i in 0..n {
                prop_assert!((s[i] - sols[0][i]).abs() <= 1e-8 * (1.0 + sols[0][i].abs()));
            }
        }
    }
}
