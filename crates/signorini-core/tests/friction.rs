//! The one-step planar friction problem (`signorini_core::friction`): closed-form single
//! contacts, the block on an inclined plane as one step, random problems on which both solvers
//! must return solutions that dissipate and agree, and the typed failure of a starved
//! Gauss–Seidel.

use nalgebra::{DMatrix, SymmetricEigen};
use proptest::prelude::*;
use signorini_core::friction::{
    FrictionError, FrictionProblem, FrictionSolution, solve_friction, solve_friction_lemke,
    solve_friction_nsgs,
};
use signorini_core::lcp::{Lcp, LcpOptions, LcpSolverKind, solve};

fn options(kind: LcpSolverKind) -> LcpOptions {
    LcpOptions {
        kind,
        tolerance: 1e-12,
        max_iterations: 100_000,
    }
}

const KINDS: [LcpSolverKind; 3] = [
    LcpSolverKind::Lemke,
    LcpSolverKind::Pgs,
    LcpSolverKind::Auto,
];

fn solve_all(problem: FrictionProblem<'_>) -> Vec<(LcpSolverKind, FrictionSolution)> {
    KINDS
        .iter()
        .map(|&kind| {
            let s =
                solve_friction(problem, &options(kind)).unwrap_or_else(|e| panic!("{kind:?}: {e}"));
            assert!(s.error <= 1e-12, "{kind:?}: error {}", s.error);
            (kind, s)
        })
        .collect()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0)
}

/// Diagonal W = diag(a, b), q_n < 0, |q_t| / b ≤ μ P_n: sticking, P = (−q_n/a, −q_t/b), U = 0.
#[test]
fn single_contact_sticks_with_the_closed_form_impulse() {
    let (a, b, mu) = (2.0, 0.5, 0.8);
    let q = [-3.0, 0.4]; // P_n = 1.5, stick P_t = −0.8, |P_t| ≤ μ P_n = 1.2
    let problem = FrictionProblem {
        w: &[a, 0.0, 0.0, b],
        q: &q,
        mu: &[mu],
    };
    for (kind, s) in solve_all(problem) {
        assert!(
            close(s.p[0], 1.5) && close(s.p[1], -0.8),
            "{kind:?}: {:?}",
            s.p
        );
        let u = problem.local_velocity(&s.p);
        assert!(
            u[0].abs() <= 1e-12 && u[1].abs() <= 1e-12,
            "{kind:?}: U = {u:?}"
        );
    }
}

/// Same W, larger q_t: sliding, P_t = −μ P_n sign(q_t), U_t = q_t + b P_t of the sign of q_t.
#[test]
fn single_contact_slides_on_the_cone_edge() {
    let (a, b, mu) = (2.0, 0.5, 0.3);
    for qt in [1.0, -1.0] {
        let q = [-3.0, qt];
        let problem = FrictionProblem {
            w: &[a, 0.0, 0.0, b],
            q: &q,
            mu: &[mu],
        };
        let pn = 1.5;
        let pt = -mu * pn * qt.signum();
        for (kind, s) in solve_all(problem) {
            assert!(
                close(s.p[0], pn) && close(s.p[1], pt),
                "{kind:?}: {:?}",
                s.p
            );
            let u = problem.local_velocity(&s.p);
            assert!(
                close(u[1], qt + b * pt) && u[1] * qt > 0.0,
                "{kind:?}: U = {u:?}"
            );
            assert!(problem.friction_work(&s.p) < 0.0);
        }
    }
}

/// q_n ≥ 0: the contact separates, P = 0 whatever q_t.
#[test]
fn separating_contact_has_no_impulse() {
    let q = [0.5, -7.0];
    let problem = FrictionProblem {
        w: &[2.0, 0.3, 0.3, 0.5],
        q: &q,
        mu: &[0.9],
    };
    for (kind, s) in solve_all(problem) {
        assert_eq!(s.p, vec![0.0, 0.0], "{kind:?}");
        assert_eq!(s.iterations, 0);
    }
    // The solvers called directly find it too.
    for s in [
        solve_friction_lemke(problem, &options(LcpSolverKind::Lemke)).unwrap(),
        solve_friction_nsgs(problem, &options(LcpSolverKind::Pgs)).unwrap(),
    ] {
        assert_eq!(s.p, vec![0.0, 0.0]);
    }
}

/// μ = 0: exactly the frictionless LCP on the normal rows, P_t = 0 exactly, with every solver,
/// including the solvers called directly (not through the μ = 0 shortcut of the dispatch).
#[test]
fn zero_friction_is_the_frictionless_lcp() {
    let w = [
        2.0, 0.4, 0.5, 0.1, //
        0.4, 1.0, 0.2, 0.3, //
        0.5, 0.2, 1.5, -0.2, //
        0.1, 0.3, -0.2, 0.8,
    ];
    let q = [-1.0, 0.7, -0.4, -0.9];
    let problem = FrictionProblem {
        w: &w,
        q: &q,
        mu: &[0.0, 0.0],
    };
    let wnn = [2.0, 0.5, 0.5, 1.5];
    let qn = [-1.0, -0.4];
    let lcp = solve(Lcp { m: &wnn, q: &qn }, &options(LcpSolverKind::Auto)).unwrap();
    for (kind, s) in solve_all(problem) {
        assert_eq!(s.p[1], 0.0);
        assert_eq!(s.p[3], 0.0);
        for c in 0..2 {
            assert!(
                close(s.p[2 * c], lcp.z[c]),
                "{kind:?}: {:?} vs {:?}",
                s.p,
                lcp.z
            );
        }
    }
    for s in [
        solve_friction_lemke(problem, &options(LcpSolverKind::Lemke)).unwrap(),
        solve_friction_nsgs(problem, &options(LcpSolverKind::Pgs)).unwrap(),
    ] {
        assert_eq!(s.p[1], 0.0);
        assert_eq!(s.p[3], 0.0);
        for c in 0..2 {
            assert!(close(s.p[2 * c], lcp.z[c]));
        }
    }
}

/// Four frictionless contacts on which Lemke's method on the 4m-unknown reformulation ended on
/// a ray (found by `both_solvers_solve_random_problems`, the case it shrank to): every μ is 0,
/// so the rows `0 ≤ −β⁺ − β⁻ ⊥ λ` only force β = 0 and cost the matrix its copositivity-plus.
/// A frictionless contact now keeps its normal unknown alone, and Lemke solves the problem as
/// the frictionless LCP on W_nn (an SPD matrix here) does.
#[test]
fn lemke_solves_frictionless_contacts_on_their_normal_lcp() {
    let g = [
        0.0,
        0.17906238483479173,
        0.0,
        -0.7024584745235901,
        0.0,
        0.398513206484654,
        0.0,
        0.2841930825126067,
        0.6222823750869008,
        0.7472723050052968,
        0.0,
        0.46736804561088374,
        0.0,
        0.5915685052389497,
        0.0,
        0.7996236944669913,
        0.0,
        0.6058196580344979,
        0.0,
        -0.22717680900184697,
        0.0,
        0.58321310380903,
        0.0,
        -0.15128764580609694,
        0.0,
        0.44061179644527054,
        -0.950530418201461,
        0.049068659640149066,
        0.0,
        -0.8132177815671314,
        0.0,
        -0.7763694553616894,
        0.0,
        -0.25401127132075757,
        0.0,
        -0.4028630635988386,
        0.0,
        0.0,
        0.0,
        -0.5053383788644189,
        0.0,
        -0.02350951894525018,
        0.0,
        0.6103588354338468,
        0.0,
        -0.5154353372228079,
        0.0,
        0.9321162698281035,
        -0.11826331662847459,
        -0.154778098146176,
        0.0,
        0.6790140670963344,
        0.0,
        -0.6124527684489218,
        0.0,
        0.28489978566498053,
        -0.7177138061606646,
        -0.17544526372359748,
        0.0,
        -0.363044465932068,
        0.0,
        -0.6428800286439561,
        0.0,
        0.6448525896162447,
    ];
    let masses = [
        1.7482691709149247,
        0.5469465442538046,
        1.3545952829220396,
        3.5711459769111484,
        1.1386523877531636,
        0.5302871882998041,
        4.91555562054409,
        0.20249693255807902,
    ];
    let q = [
        -0.9308737315552157,
        1.803729317969632,
        0.0,
        1.713343269985822,
        0.0,
        1.861786985456195,
        1.1325182065365622,
        1.930187339728494,
    ];
    let w = delassus(4, &g, &masses);
    let problem = FrictionProblem {
        w: &w,
        q: &q,
        mu: &[0.0; 4],
    };
    let s = solve_friction_lemke(problem, &options(LcpSolverKind::Lemke)).unwrap();
    let wnn: Vec<f64> = (0..16).map(|k| w[16 * (k / 4) + 2 * (k % 4)]).collect();
    let qn: Vec<f64> = (0..4).map(|c| q[2 * c]).collect();
    let lcp = solve(Lcp { m: &wnn, q: &qn }, &options(LcpSolverKind::Lemke)).unwrap();
    for c in 0..4 {
        assert_eq!(s.p[2 * c + 1], 0.0);
        assert!(close(s.p[2 * c], lcp.z[c]), "{:?} vs {:?}", s.p, lcp.z);
    }
    assert!(s.error <= 1e-12, "{}", s.error);
}

/// A block of mass m at rest on a plane inclined by α, one step h with gravity, e = 0. Local
/// frame: n the outward normal, t down the slope; W = diag(1/m, 1/m) and the free velocity
/// q = h g (−cos α, sin α). Sticking (tan α ≤ μ): P = m h g (cos α, −sin α) and U = 0.
/// Sliding (tan α > μ): P_n = m h g cos α, P_t = −μ P_n, U_t = h g (sin α − μ cos α) > 0.
#[test]
fn block_on_a_slope_sticks_below_and_slides_above_the_friction_angle() {
    let (mass, h, g, mu) = (2.0, 1e-3, 9.81, 0.5);
    for alpha_deg in [10.0f64, 20.0, 26.0, 27.0, 35.0, 60.0] {
        let alpha = alpha_deg.to_radians();
        let w = [1.0 / mass, 0.0, 0.0, 1.0 / mass];
        let q = [-h * g * alpha.cos(), h * g * alpha.sin()];
        let problem = FrictionProblem {
            w: &w,
            q: &q,
            mu: &[mu],
        };
        let pn = mass * h * g * alpha.cos();
        for (kind, s) in solve_all(problem) {
            let u = problem.local_velocity(&s.p);
            assert!(close(s.p[0], pn), "{kind:?} α = {alpha_deg}°: {:?}", s.p);
            assert!(u[0].abs() <= 1e-15, "{kind:?} α = {alpha_deg}°: U = {u:?}");
            if alpha.tan() < mu {
                assert!(close(s.p[1], -mass * h * g * alpha.sin()), "{kind:?}");
                assert!(u[1].abs() <= 1e-15, "{kind:?} α = {alpha_deg}°: U = {u:?}");
            } else {
                assert!(close(s.p[1], -mu * pn), "{kind:?} α = {alpha_deg}°");
                let ut = h * g * (alpha.sin() - mu * alpha.cos());
                assert!(
                    u[1] > 0.0 && close(u[1], ut),
                    "{kind:?} α = {alpha_deg}°: {u:?}"
                );
            }
            assert!(problem.friction_work(&s.p) <= 1e-15);
        }
    }
}

/// Two contacts both active and coupled through W: one sweep is not enough, and the typed error says so.
#[test]
fn starved_gauss_seidel_fails_with_a_typed_error() {
    let w = [
        2.0, 0.4, 0.5, 0.1, //
        0.4, 1.0, 0.2, 0.3, //
        0.5, 0.2, 2.5, -0.2, //
        0.1, 0.3, -0.2, 0.8,
    ];
    let q = [-1.0, 0.7, -1.0, -0.9];
    let problem = FrictionProblem {
        w: &w,
        q: &q,
        mu: &[0.4, 0.6],
    };
    let starved = LcpOptions {
        kind: LcpSolverKind::Pgs,
        tolerance: 1e-12,
        max_iterations: 1,
    };
    match solve_friction(problem, &starved) {
        Err(FrictionError::NotConverged {
            solver,
            iterations,
            error,
            tolerance,
        }) => {
            assert_eq!(solver, "nsgs");
            assert_eq!(iterations, 1);
            assert!(error > tolerance);
        }
        other => panic!("expected NotConverged, got {other:?}"),
    }
    // With a budget it converges.
    assert!(solve_friction(problem, &options(LcpSolverKind::Pgs)).is_ok());
}

#[test]
fn bad_inputs_are_typed_errors() {
    let w = [1.0, 0.0, 0.0, 1.0];
    let q = [-1.0, 0.0];
    let bad_mu = FrictionProblem {
        w: &w,
        q: &q,
        mu: &[-0.1],
    };
    assert!(matches!(
        solve_friction(bad_mu, &LcpOptions::default()),
        Err(FrictionError::InvalidFriction { contact: 0, .. })
    ));
    let nan_mu = FrictionProblem {
        mu: &[f64::NAN],
        ..bad_mu
    };
    assert!(matches!(
        solve_friction(nan_mu, &LcpOptions::default()),
        Err(FrictionError::InvalidFriction { contact: 0, .. })
    ));
    let short_q = FrictionProblem {
        w: &w,
        q: &q[..1],
        mu: &[0.5],
    };
    assert!(matches!(
        solve_friction(short_q, &LcpOptions::default()),
        Err(FrictionError::Dimensions { contacts: 1, .. })
    ));
    let ok = FrictionProblem {
        w: &w,
        q: &q,
        mu: &[0.5],
    };
    assert!(matches!(
        solve_friction(ok, &options(LcpSolverKind::Enumeration)),
        Err(FrictionError::UnsupportedSolver { .. })
    ));
    let singular = FrictionProblem {
        w: &[1.0, 1.0, 1.0, 1.0],
        q: &q,
        mu: &[0.5],
    };
    assert!(matches!(
        solve_friction_nsgs(singular, &options(LcpSolverKind::Pgs)),
        Err(FrictionError::LocalBlockNotDefinite { contact: 0 })
    ));
}

/// W = Gᵀ M⁻¹ G (2m×2m) from a random square G (diagonally dominated, so W is SPD) and a
/// random diagonal M.
fn delassus(m: usize, g: &[f64], masses: &[f64]) -> Vec<f64> {
    let n = 2 * m;
    let gm = DMatrix::from_fn(n, n, |i, j| g[i * n + j] + if i == j { 3.0 } else { 0.0 });
    let minv = DMatrix::from_fn(n, n, |i, j| if i == j { 1.0 / masses[i] } else { 0.0 });
    let w = gm.transpose() * minv * &gm;
    let w = (&w + w.transpose()) * 0.5;
    (0..n * n).map(|k| w[(k / n, k % n)]).collect()
}

/// κ(W) = λ_max / λ_min. Two solutions P, P′ satisfy, from `P ⊥ Û′`-type inequalities of the
/// De Saxcé formulation, `λ_min ‖ΔP‖² ≤ ΔPᵀ W ΔP ≤ Σ μ |ΔP_n| |ΔU_t| ≤ μ_max λ_max ‖ΔP‖²`,
/// so μ_max κ(W) < 1 makes the solution unique.
fn condition(n: usize, w: &[f64]) -> f64 {
    let e = SymmetricEigen::new(DMatrix::from_row_slice(n, n, w)).eigenvalues;
    e.max() / e.min()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, .. ProptestConfig::default() })]

    /// Both solvers solve random problems (natural map ≤ 1e-8, scaled), friction never does
    /// positive work (`P_t U_t ≤ 1e-10` per contact), and where the solution is unique
    /// (μ_max κ(W) ≤ 1/2, see `condition`) they agree on P and U. Outside that regime the
    /// Gauss–Seidel may cycle (seen: a 2-cycle with μ ≈ 1.1–1.3 and W_n3t1 ≈ 8 on W_n1n1 ≈ 11);
    /// it must then fail with `NotConverged`, and Lemke must still solve.
    #[test]
    fn both_solvers_solve_random_problems(
        m in 1usize..=4,
        g in prop::collection::vec(-1.0f64..1.0, 64),
        masses in prop::collection::vec(0.2f64..5.0, 8),
        q in prop::collection::vec(-2.0f64..2.0, 8),
        mu in prop::collection::vec(0.0f64..1.5, 4),
        unique_scale in 0.0f64..1.0,
    ) {
        let n = 2 * m;
        let w = delassus(m, &g[..n * n], &masses[..n]);
        let kappa = condition(n, &w);
        // Half the cases draw μ small enough for uniqueness.
        let mu: Vec<f64> = if unique_scale < 0.5 {
            mu[..m].iter().map(|x| x / 1.5 * 0.5 / kappa).collect()
        } else {
            mu[..m].to_vec()
        };
        let problem = FrictionProblem { w: &w, q: &q[..n], mu: &mu };
        // The default tolerance 1e-12: near a solution of error ε a sticking contact may work
        // ε|P_t| > 0 (seen: P_t = 0.94, U_t = 1.9e-10 at ε = 9.8e-11), so 1e-10 on P_t U_t needs
        // ε well below 1e-10.
        let opts = LcpOptions { kind: LcpSolverKind::Lemke, tolerance: 1e-12, max_iterations: 1_000_000 };
        let lemke = solve_friction_lemke(problem, &opts).map_err(|e| TestCaseError::fail(format!("lemke: {e}")))?;
        let mu_max = mu.iter().fold(0.0f64, |a, &b| a.max(b));
        let unique = mu_max * kappa <= 0.5;
        let nsgs = match solve_friction_nsgs(problem, &opts) {
            Ok(s) => s,
            // Gauss–Seidel may cycle on strongly coupled problems with large μ (Coulomb
            // friction is not monotone); there it must fail with the typed error.
            Err(FrictionError::NotConverged { .. }) if !unique => lemke.clone(),
            Err(e) => return Err(TestCaseError::fail(format!("nsgs: {e}"))),
        };
        for (name, s) in [("lemke", &lemke), ("nsgs", &nsgs)] {
            prop_assert!(s.error <= 1e-8, "{}: error {}", name, s.error);
            prop_assert!((problem.error(&s.p) - s.error).abs() <= 1e-15);
            let u = problem.local_velocity(&s.p);
            for c in 0..m {
                prop_assert!(s.p[2 * c + 1] * u[2 * c + 1] <= 1e-10,
                    "{}: contact {} works: P_t = {}, U_t = {}, error {}",
                    name, c, s.p[2 * c + 1], u[2 * c + 1], s.error);
            }
        }
        if unique {
            let ul = problem.local_velocity(&lemke.p);
            let un = problem.local_velocity(&nsgs.p);
            let scale = lemke.p.iter().chain(&ul).fold(1.0f64, |a, b| a.max(b.abs()));
            for i in 0..n {
                prop_assert!((lemke.p[i] - nsgs.p[i]).abs() <= 1e-7 * scale * kappa,
                    "P[{}]: {} vs {}", i, lemke.p[i], nsgs.p[i]);
                prop_assert!((ul[i] - un[i]).abs() <= 1e-7 * scale * kappa,
                    "U[{}]: {} vs {}", i, ul[i], un[i]);
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, .. ProptestConfig::default() })]

    /// Problems built backwards from a known solution (as `scripts/lcp_corpus.py` does for
    /// LCPs): per contact a random case of the law — separating `P = 0, U_n > 0`, sticking
    /// `U = 0, |P_t| ≤ μ P_n`, sliding either way `U_n = 0, P_t = −μ P_n sign(U_t)` — and
    /// `q = U − W P`. With μ_max κ(W) ≤ 1/2 the solution is unique (see `condition`), so both
    /// solvers must return the known P (and U) to 1e-9 relative.
    #[test]
    fn both_solvers_recover_a_known_solution(
        m in 1usize..=4,
        g in prop::collection::vec(-1.0f64..1.0, 64),
        masses in prop::collection::vec(0.2f64..5.0, 8),
        cases in prop::collection::vec(0usize..4, 4),
        sizes in prop::collection::vec(0.1f64..2.0, 8),
        inside in prop::collection::vec(-1.0f64..1.0, 4),
        mu in prop::collection::vec(0.0f64..1.0, 4),
    ) {
        let n = 2 * m;
        let w = delassus(m, &g[..n * n], &masses[..n]);
        let kappa = condition(n, &w);
        let mu: Vec<f64> = mu[..m].iter().map(|x| x * 0.5 / kappa).collect();
        let mut p = vec![0.0; n];
        let mut u = vec![0.0; n];
        for c in 0..m {
            let (a, b) = (sizes[2 * c], sizes[2 * c + 1]);
            match cases[c] {
                0 => {
                    u[2 * c] = a;
                    u[2 * c + 1] = 2.0 * b - 2.0;
                }
                1 => {
                    p[2 * c] = a;
                    p[2 * c + 1] = mu[c] * a * inside[c];
                }
                k => {
                    let s = if k == 2 { 1.0 } else { -1.0 };
                    p[2 * c] = a;
                    p[2 * c + 1] = -s * mu[c] * a;
                    u[2 * c + 1] = s * b;
                }
            }
        }
        let q: Vec<f64> = (0..n)
            .map(|i| u[i] - (0..n).map(|j| w[i * n + j] * p[j]).sum::<f64>())
            .collect();
        let problem = FrictionProblem { w: &w, q: &q, mu: &mu };
        prop_assert!(problem.error(&p) <= 1e-14, "the built solution has error {}", problem.error(&p));
        let opts = LcpOptions { kind: LcpSolverKind::Lemke, tolerance: 1e-11, max_iterations: 1_000_000 };
        let scale = p.iter().chain(&u).fold(1.0f64, |a, b| a.max(b.abs()));
        for (name, s) in [
            ("lemke", solve_friction_lemke(problem, &opts)),
            ("nsgs", solve_friction_nsgs(problem, &opts)),
        ] {
            let s = s.map_err(|e| TestCaseError::fail(format!("{name}: {e}")))?;
            let us = problem.local_velocity(&s.p);
            for i in 0..n {
                prop_assert!((s.p[i] - p[i]).abs() <= 1e-9 * scale * kappa,
                    "{}: P[{}] = {} but the solution is {}", name, i, s.p[i], p[i]);
                prop_assert!((us[i] - u[i]).abs() <= 1e-9 * scale * kappa,
                    "{}: U[{}] = {} but the solution is {}", name, i, us[i], u[i]);
            }
        }
    }
}

/// Lemke's tableau is sized before it is allocated (issue 28: the 7 002-contact granular problem
/// aborted the process asking for 12.6 GB): an LCP of size n needs 8 n (2n + 2) bytes and is
/// refused above the limit; the planar reformulation of m contacts adds its 4m×4m matrix, so 1 700
/// contacts (6 800 unknowns: 740 MB of tableau and 370 MB of matrix) exceed the 1 GiB default.
#[test]
fn lemke_refuses_a_tableau_that_would_not_fit() {
    use signorini_core::lcp::{DEFAULT_TABLEAU_LIMIT, LcpError, solve_lemke_within, tableau_bytes};
    assert_eq!(tableau_bytes(28_008), 12_551_617_152);
    let m = [2.0, 1.0, 1.0, 2.0];
    let q = [-1.0, -1.0];
    let lcp = Lcp { m: &m, q: &q };
    let refused = solve_lemke_within(lcp, &options(LcpSolverKind::Lemke), 95);
    assert_eq!(
        refused,
        Err(LcpError::TooLargeForMemory {
            solver: "lemke",
            size: 2,
            bytes: 96,
            limit: 95
        })
    );
    assert!(solve_lemke_within(lcp, &options(LcpSolverKind::Lemke), 96).is_ok());
    // The planar reformulation: refused before W's 1 700 contacts are even looked at beyond
    // their count (W is a zero-filled slice of the right length).
    let contacts = 1_700;
    let w = vec![0.0; 4 * contacts * contacts];
    let mut q = vec![0.0; 2 * contacts];
    q[0] = -1.0;
    let mu = vec![0.5; contacts];
    let problem = FrictionProblem {
        w: &w,
        q: &q,
        mu: &mu,
    };
    let n4 = 4 * contacts;
    match solve_friction_lemke(problem, &options(LcpSolverKind::Lemke)) {
        Err(FrictionError::Lcp(LcpError::TooLargeForMemory { bytes, limit, .. })) => {
            assert_eq!(bytes, 8 * n4 * n4 + tableau_bytes(n4));
            assert_eq!(limit, DEFAULT_TABLEAU_LIMIT);
        }
        other => panic!("{other:?}"),
    }
}
