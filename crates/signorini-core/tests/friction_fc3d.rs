//! The three-dimensional friction problem (`signorini_core::friction::fc3d`): closed-form single
//! contacts (stick, slide on the cone's boundary opposite to the sliding velocity, take-off, a
//! block thrown across a slope), random problems built backwards from known solutions on which
//! every solver must return a point within tolerance that satisfies the cone and the
//! complementarity per contact, the exact embedding of planar problems, and typed errors.

use proptest::prelude::*;
use signorini_core::friction::{
    BlockCsr, Fc3dError, Fc3dNewtonLinear, Fc3dOptions, Fc3dProblem, Fc3dSolution, Fc3dSolverKind,
    Fc3dStall, FrictionProblem, solve_fc3d, solve_fc3d_from, solve_fc3d_newton, solve_fc3d_nsgs,
    solve_fc3d_nsgs_anderson, solve_fc3d_prox, solve_friction,
};
use signorini_core::lcp::{LcpOptions, LcpSolverKind};

/// Every solver configuration: the five kinds, and Newton with its GMRES and sparse LU paths
/// forced.
fn configurations(tolerance: f64) -> Vec<(&'static str, Fc3dOptions)> {
    let base = Fc3dOptions {
        tolerance,
        ..Fc3dOptions::default()
    };
    vec![
        (
            "auto",
            Fc3dOptions {
                kind: Fc3dSolverKind::Auto,
                ..base
            },
        ),
        (
            "nsgs",
            Fc3dOptions {
                kind: Fc3dSolverKind::Nsgs,
                ..base
            },
        ),
        (
            "nsgs_aa",
            Fc3dOptions {
                kind: Fc3dSolverKind::NsgsAnderson,
                ..base
            },
        ),
        (
            "nsn_ac dense",
            Fc3dOptions {
                kind: Fc3dSolverKind::NewtonAlartCurnier,
                ..base
            },
        ),
        (
            "nsn_ac gmres",
            Fc3dOptions {
                kind: Fc3dSolverKind::NewtonAlartCurnier,
                newton_linear: Fc3dNewtonLinear::Gmres,
                ..base
            },
        ),
        (
            "nsn_ac sparse_lu",
            Fc3dOptions {
                kind: Fc3dSolverKind::NewtonAlartCurnier,
                newton_linear: Fc3dNewtonLinear::SparseLu,
                ..base
            },
        ),
        (
            "prox",
            Fc3dOptions {
                kind: Fc3dSolverKind::Prox,
                ..base
            },
        ),
    ]
}

fn diagonal_problem(w: [f64; 3], q: [f64; 3], mu: f64) -> Fc3dProblem {
    Fc3dProblem {
        w: BlockCsr::from_triplets(3, 3, [(0, 0, w[0]), (1, 1, w[1]), (2, 2, w[2])]).unwrap(),
        q: q.to_vec(),
        mu: vec![mu],
    }
}

fn solve_all(problem: &Fc3dProblem) -> Vec<(&'static str, Fc3dSolution)> {
    configurations(1e-12)
        .into_iter()
        .map(|(name, options)| {
            let s = solve_fc3d(problem, &options).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(s.error <= 1e-12, "{name}: error {}", s.error);
            assert_eq!(s.error, problem.error(&s.r), "{name}");
            (name, s)
        })
        .collect()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-10 * a.abs().max(b.abs()).max(1.0)
}

/// W = diag(2, 0.5, 0.25), q = (−3, 0.4, −0.1): the sticking impulse r = −W⁻¹q = (1.5, −0.8,
/// 0.4) has ‖r_t‖ = 0.894 ≤ μ r_n = 1.2, so the contact sticks with u = 0.
#[test]
fn single_contact_sticks_inside_the_cone() {
    let problem = diagonal_problem([2.0, 0.5, 0.25], [-3.0, 0.4, -0.1], 0.8);
    for (name, s) in solve_all(&problem) {
        for (got, want) in s.r.iter().zip([1.5, -0.8, 0.4]) {
            assert!(close(*got, want), "{name}: r = {:?}", s.r);
        }
        assert!(
            s.u.iter().all(|u| u.abs() <= 1e-10),
            "{name}: u = {:?}",
            s.u
        );
    }
}

/// W = diag(1, 2, 2), q = (−2, 3, 4), μ = 0.3: stick would need ‖r_t‖ = 2.5 > μ r_n = 0.6, so
/// the contact slides: r_n = 2, r_t = −0.6 (3, 4)/5 = (−0.36, −0.48), on the cone's boundary and
/// opposite to u_t = q_t + 2 r_t = (2.28, 3.04), u_n = 0.
#[test]
fn single_contact_slides_on_the_boundary_opposite_to_the_velocity() {
    let problem = diagonal_problem([1.0, 2.0, 2.0], [-2.0, 3.0, 4.0], 0.3);
    for (name, s) in solve_all(&problem) {
        for (got, want) in s.r.iter().zip([2.0, -0.36, -0.48]) {
            assert!(close(*got, want), "{name}: r = {:?}", s.r);
        }
        for (got, want) in s.u.iter().zip([0.0, 2.28, 3.04]) {
            assert!(close(*got, want), "{name}: u = {:?}", s.u);
        }
        let rt = s.r[1].hypot(s.r[2]);
        assert!(close(rt, 0.3 * s.r[0]), "{name}: on the boundary");
        assert!(
            problem.friction_work(&s.r) < 0.0,
            "{name}: friction dissipates"
        );
    }
}

/// q_n > 0: the contact opens, r = 0 and u = q, whatever the tangential free velocity.
#[test]
fn single_contact_separates() {
    let problem = diagonal_problem([1.0, 1.0, 1.0], [0.5, -7.0, 3.0], 0.5);
    for (name, s) in solve_all(&problem) {
        assert_eq!(s.r, vec![0.0; 3], "{name}");
        assert_eq!(s.u, vec![0.5, -7.0, 3.0], "{name}");
    }
}

/// A point mass m on a plane inclined by α, thrown across it (horizontally, v0 along t2) while
/// gravity pulls it down the slope (t1): one Moreau–Jean step of size h with W = I/m and free
/// velocity q = (−g cos α h, g sin α h, v0). It slides: r_n = m g cos α h, and the friction
/// impulse is opposite to the velocity after the step, which is parallel to q_t = (g sin α h,
/// v0) — along the sliding direction, not along the slope.
#[test]
fn block_thrown_across_a_slope_feels_friction_along_its_sliding_direction() {
    let (m, g, alpha, h, v0, mu) = (2.0, 9.81, 0.4f64, 1e-2, 1.5, 0.3);
    let qt = [g * alpha.sin() * h, v0];
    let problem = diagonal_problem([1.0 / m; 3], [-g * alpha.cos() * h, qt[0], qt[1]], mu);
    let rn = m * g * alpha.cos() * h;
    let qt_norm = qt[0].hypot(qt[1]);
    for (name, s) in solve_all(&problem) {
        assert!(close(s.r[0], rn), "{name}: r_n = {}", s.r[0]);
        // r_t = −μ r_n q_t / ‖q_t‖.
        assert!(
            close(s.r[1], -mu * rn * qt[0] / qt_norm),
            "{name}: {:?}",
            s.r
        );
        assert!(
            close(s.r[2], -mu * rn * qt[1] / qt_norm),
            "{name}: {:?}",
            s.r
        );
        // Along the sliding direction: r_t2 / r_t1 = v0 / (g sin α h), not 0 as along the slope.
        assert!(close(s.r[2] / s.r[1], v0 / (g * alpha.sin() * h)), "{name}");
        // The speed drops by μ g cos α h.
        let speed = s.u[1].hypot(s.u[2]);
        assert!(close(speed, qt_norm - mu * g * alpha.cos() * h), "{name}");
    }
}

/// A planar problem embedded in 3D ([`Fc3dProblem::from_planar`]) has the planar solver's
/// solution: the two-contact problem of the planar tests, solved by Lemke in 2D and by every 3D
/// solver, gives the same impulses and r_t2 = u_t2 = 0.
#[test]
fn embedded_planar_problem_has_the_planar_solution() {
    let w = [
        2.0, 0.3, 0.5, 0.1, //
        0.3, 1.0, 0.2, -0.1, //
        0.5, 0.2, 1.5, 0.4, //
        0.1, -0.1, 0.4, 1.2,
    ];
    let q = [-1.0, 2.0, -0.5, -0.3];
    let mu = [0.4, 0.9];
    let planar = solve_friction(
        FrictionProblem {
            w: &w,
            q: &q,
            mu: &mu,
        },
        &LcpOptions {
            kind: LcpSolverKind::Lemke,
            tolerance: 1e-12,
            max_iterations: 10_000,
        },
    )
    .unwrap();
    let problem =
        Fc3dProblem::from_planar(&BlockCsr::from_dense_row_major(2, 4, &w).unwrap(), &q, &mu)
            .unwrap();
    for (name, s) in solve_all(&problem) {
        let (r, u) = s.planar();
        for (a, b) in r.iter().zip(&planar.p) {
            assert!(close(*a, *b), "{name}: {r:?} against {:?}", planar.p);
        }
        assert_eq!(u.len(), 4);
        assert!(s.r[2] == 0.0 && s.r[5] == 0.0, "{name}: {:?}", s.r);
        assert!(s.u[2] == 0.0 && s.u[5] == 0.0, "{name}: {:?}", s.u);
    }
}

#[test]
fn bad_problems_are_typed_errors() {
    let w = BlockCsr::from_triplets(3, 3, [(0, 0, 1.0)]).unwrap();
    let bad_mu = Fc3dProblem {
        w: w.clone(),
        q: vec![-1.0, 0.0, 0.0],
        mu: vec![-0.1],
    };
    assert_eq!(
        solve_fc3d(&bad_mu, &Fc3dOptions::default()),
        Err(Fc3dError::InvalidFriction {
            contact: 0,
            mu: -0.1
        })
    );
    let bad_q = Fc3dProblem {
        w: w.clone(),
        q: vec![-1.0, 0.0],
        mu: vec![0.1],
    };
    assert!(matches!(
        solve_fc3d(&bad_q, &Fc3dOptions::default()),
        Err(Fc3dError::Dimensions { q_len: 2, .. })
    ));
    let nan_q = Fc3dProblem {
        w,
        q: vec![f64::NAN, 0.0, 0.0],
        mu: vec![0.1],
    };
    assert!(matches!(
        solve_fc3d(&nan_q, &Fc3dOptions::default()),
        Err(Fc3dError::NotFiniteQ { index: 0, .. })
    ));
}

/// A starved Gauss–Seidel on coupled contacts fails with its best iterate and error.
#[test]
fn starved_solvers_fail_with_a_typed_error() {
    let problem = Fc3dProblem {
        w: BlockCsr::from_dense_row_major(
            3,
            6,
            &[
                2.0, 0.1, 0.0, 1.5, 0.2, 0.0, //
                0.1, 1.0, 0.0, 0.1, 0.5, 0.0, //
                0.0, 0.0, 1.0, 0.0, 0.0, 0.4, //
                1.5, 0.1, 0.0, 2.0, 0.0, 0.1, //
                0.2, 0.5, 0.0, 0.0, 1.0, 0.0, //
                0.0, 0.0, 0.4, 0.1, 0.0, 1.0,
            ],
        )
        .unwrap(),
        q: vec![-1.0, 0.3, 0.2, -1.0, -0.1, 0.4],
        mu: vec![0.5, 0.5],
    };
    let options = Fc3dOptions {
        kind: Fc3dSolverKind::Nsgs,
        tolerance: 1e-14,
        max_iterations: 1,
        ..Fc3dOptions::default()
    };
    match solve_fc3d(&problem, &options) {
        Err(Fc3dError::NotConverged {
            solver,
            iterations,
            error,
            tolerance,
            best,
        }) => {
            assert_eq!((solver, iterations), ("nsgs", 1));
            assert!(error > tolerance);
            assert_eq!(problem.error(&best), error);
        }
        other => panic!("{other:?}"),
    }
}

/// `auto` starved of iterations fails with the iterate of smallest error over its stages, never
/// worse than its first stage (the accelerated sweeps, whose first sweep is a plain Gauss–Seidel
/// sweep: Gauss–Seidel alone with the same budget), and counts the iterations of every stage it
/// ran.
#[test]
fn starved_auto_keeps_the_best_iterate_of_its_stages() {
    let problem = Fc3dProblem {
        w: BlockCsr::from_dense_row_major(
            3,
            6,
            &[
                2.0, 0.1, 0.0, 1.5, 0.2, 0.0, //
                0.1, 1.0, 0.0, 0.1, 0.5, 0.0, //
                0.0, 0.0, 1.0, 0.0, 0.0, 0.4, //
                1.5, 0.1, 0.0, 2.0, 0.0, 0.1, //
                0.2, 0.5, 0.0, 0.0, 1.0, 0.0, //
                0.0, 0.0, 0.4, 0.1, 0.0, 1.0,
            ],
        )
        .unwrap(),
        q: vec![-1.0, 0.3, 0.2, -1.0, -0.1, 0.4],
        mu: vec![0.5, 0.5],
    };
    let starved = |kind| Fc3dOptions {
        kind,
        tolerance: 1e-300,
        max_iterations: 1,
        ..Fc3dOptions::default()
    };
    let Err(Fc3dError::NotConverged { error: alone, .. }) =
        solve_fc3d(&problem, &starved(Fc3dSolverKind::Nsgs))
    else {
        panic!("one sweep cannot reach 1e-300");
    };
    match solve_fc3d(&problem, &starved(Fc3dSolverKind::Auto)) {
        Err(Fc3dError::NotConverged {
            iterations,
            error,
            best,
            ..
        }) => {
            // One sweep, one Newton iteration of the proximal point method from the best
            // iterate, one from the start, one sweep.
            assert_eq!(iterations, 4);
            assert!(error <= alone, "{error} > {alone}");
            assert_eq!(problem.error(&best), error);
        }
        other => panic!("{other:?}"),
    }
}

/// The state of a contact in a problem built backwards.
#[derive(Debug, Clone, Copy)]
enum State {
    Stick,
    Slide,
    Separate,
}

prop_compose! {
    /// m contacts in a chain (contact a coupled to a + 1 through a random 3×3 block), W = H Hᵀ +
    /// δ I with H block-bidiagonal; per contact a state and the impulse and velocity of that
    /// state; q = u − W r, so (r, u) is a solution by construction.
    fn built_problem()(
        m in 1usize..9,
        seed in prop::collection::vec(-1.0f64..1.0, 9 * 9 * 2),
        states in prop::collection::vec(0usize..3, 9),
        mus in prop::collection::vec(0.0f64..1.0, 9),
        sizes in prop::collection::vec(0.1f64..2.0, 9 * 3),
        angles in prop::collection::vec(0.0f64..std::f64::consts::TAU, 9),
    ) -> (Fc3dProblem, Vec<f64>) {
        let n = 3 * m;
        // H: identity-weighted diagonal blocks plus one coupling block to the next contact.
        let mut h = vec![0.0; n * n];
        for a in 0..m {
            for i in 0..3 {
                for k in 0..3 {
                    let s = seed[(a * 9 + 3 * i + k) % seed.len()];
                    h[(3 * a + i) * n + 3 * a + k] = if i == k { 1.0 + 0.5 * s } else { 0.3 * s };
                    if a + 1 < m {
                        h[(3 * a + i) * n + 3 * (a + 1) + k] = 0.4 * seed[(81 + a * 9 + 3 * i + k) % seed.len()];
                    }
                }
            }
        }
        let mut w = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                w[i * n + j] = (0..n).map(|k| h[i * n + k] * h[j * n + k]).sum::<f64>()
                    + if i == j { 0.1 } else { 0.0 };
            }
        }
        let mut r = vec![0.0; n];
        let mut u = vec![0.0; n];
        for a in 0..m {
            let mu = mus[a];
            let (c, s) = (angles[a].cos(), angles[a].sin());
            let (x, y, z) = (sizes[3 * a], sizes[3 * a + 1], sizes[3 * a + 2]);
            let state = match states[a] { 0 => State::Stick, 1 => State::Slide, _ => State::Separate };
            match state {
                State::Stick => {
                    // Strictly inside the cone: ‖r_t‖ = μ r_n × (y / 2.1) < μ r_n.
                    let rt = mu * x * y / 2.1;
                    r[3 * a..3 * a + 3].copy_from_slice(&[x, rt * c, rt * s]);
                }
                State::Slide => {
                    r[3 * a..3 * a + 3].copy_from_slice(&[x, -mu * x * c, -mu * x * s]);
                    u[3 * a..3 * a + 3].copy_from_slice(&[0.0, y * c, y * s]);
                }
                State::Separate => {
                    u[3 * a..3 * a + 3].copy_from_slice(&[x, y * c, z * s]);
                }
            }
        }
        let q: Vec<f64> = (0..n)
            .map(|i| u[i] - (0..n).map(|j| w[i * n + j] * r[j]).sum::<f64>())
            .collect();
        let problem = Fc3dProblem {
            w: BlockCsr::from_dense_row_major(3, n, &w).unwrap(),
            q,
            mu: mus[..m].to_vec(),
        };
        (problem, r)
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// The built solution has error ≤ 1e-14; every solver returns a point of error ≤ 1e-10 that
    /// lies in the cone, does not penetrate, is complementary and dissipates, per contact (within
    /// the round-off of the error: 1e-8 of the problem's scale).
    #[test]
    fn every_solver_solves_problems_built_backwards((problem, built) in built_problem()) {
        let m = problem.contacts();
        prop_assert!(problem.error(&built) <= 1e-14, "the built solution has error {}", problem.error(&built));
        for (name, options) in configurations(1e-10) {
            let s = solve_fc3d(&problem, &options).map_err(|e| TestCaseError::fail(format!("{name}: {e}")))?;
            prop_assert!(s.error <= 1e-10, "{}: error {}", name, s.error);
            let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
            let scale = norm(&problem.q).max(norm(&s.r)).max(norm(&s.u));
            let slack = 1e-8 * scale;
            for c in 0..m {
                let (r, u, mu) = (&s.r[3 * c..3 * c + 3], &s.u[3 * c..3 * c + 3], problem.mu[c]);
                let rt = r[1].hypot(r[2]);
                prop_assert!(r[0] >= -slack && rt <= mu * r[0] + slack, "{}: contact {} r = {:?}", name, c, r);
                prop_assert!(u[0] >= -slack, "{}: contact {} u = {:?}", name, c, u);
                prop_assert!((r[0] * u[0]).abs() <= slack * scale, "{}: contact {} r_n u_n", name, c);
                prop_assert!(r[1] * u[1] + r[2] * u[2] <= slack * scale, "{}: contact {} works", name, c);
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// A warm start changes the path, not the answer's bound: from the built solution Gauss–Seidel
    /// stops after one sweep (the solution is its fixed point), and from the built solution
    /// perturbed by up to 50 % per entry every solver returns a point of error ≤ 1e-10, as from
    /// r = 0.
    #[test]
    fn warm_started_solvers_meet_the_same_tolerance(
        (problem, built) in built_problem(),
        noise in prop::collection::vec(-0.5f64..0.5, 27),
    ) {
        let nsgs = Fc3dOptions { kind: Fc3dSolverKind::Nsgs, tolerance: 1e-10, ..Fc3dOptions::default() };
        let s = solve_fc3d_from(&problem, &nsgs, &built).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(s.iterations, 1);
        prop_assert!(s.error <= 1e-10, "error {}", s.error);
        let start: Vec<f64> = built.iter().zip(&noise).map(|(r, e)| r * (1.0 + e) + 0.1 * e).collect();
        for (name, options) in configurations(1e-10) {
            let s = solve_fc3d_from(&problem, &options, &start)
                .map_err(|e| TestCaseError::fail(format!("{name}: {e}")))?;
            prop_assert!(s.error <= 1e-10, "{}: error {}", name, s.error);
            prop_assert!(problem.error(&s.r) <= 1e-10, "{}: error of r {}", name, problem.error(&s.r));
        }
    }
}

#[test]
fn a_start_of_the_wrong_length_or_not_a_number_is_refused() {
    let problem = diagonal_problem([1.0, 1.0, 1.0], [-1.0, 0.0, 0.0], 0.5);
    let options = Fc3dOptions::default();
    assert!(matches!(
        solve_fc3d_from(&problem, &options, &[0.0; 2]),
        Err(Fc3dError::StartLength {
            expected: 3,
            got: 2
        })
    ));
    assert!(matches!(
        solve_fc3d_from(&problem, &options, &[0.0, f64::NAN, 0.0]),
        Err(Fc3dError::NotFiniteStart { index: 1, .. })
    ));
    // Each solver's own entry checks its inputs as `solve_fc3d_from` does (a short start used
    // to index past its end in Gauss–Seidel's sweep).
    type Solver = fn(&Fc3dProblem, &Fc3dOptions, &[f64]) -> Result<Fc3dSolution, Fc3dError>;
    let solvers: [Solver; 4] = [
        solve_fc3d_nsgs,
        solve_fc3d_nsgs_anderson,
        solve_fc3d_newton,
        solve_fc3d_prox,
    ];
    for solve in solvers {
        assert!(matches!(
            solve(&problem, &options, &[0.0; 2]),
            Err(Fc3dError::StartLength {
                expected: 3,
                got: 2
            })
        ));
        let nan_tolerance = Fc3dOptions {
            tolerance: f64::NAN,
            ..options
        };
        assert!(matches!(
            solve(&problem, &nan_tolerance, &[0.0; 3]),
            Err(Fc3dError::InvalidTolerance { .. })
        ));
        let s = solve(&problem, &options, &[0.0; 3]).unwrap();
        assert!(s.error <= options.tolerance && close(s.r[0], 1.0), "{s:?}");
    }
    // A start on the solution (r_n = 1: W r + q = 0, inside the cone) is kept to the last bit.
    let s = solve_fc3d_from(&problem, &options, &[1.0, 0.0, 0.0]).unwrap();
    assert_eq!(s.r, vec![1.0, 0.0, 0.0]);
    assert_eq!(s.error, 0.0);
}

/// A column of n spheres (mass 1) resting on a floor, as point masses: contact 0 between the floor
/// and sphere 0, contact k between spheres k − 1 and k, each axis coupled as the translations are
/// (W = G M⁻¹ Gᵀ per axis: 1 on contact 0's diagonal, 2 on the others', −1 between neighbours),
/// every sphere's free velocity −g h (so q_n = −g h at the floor, 0 between spheres), μ = 0.3.
/// The solution: every sphere at rest, r_n,k = (n − k) g h, r_t = 0.
fn sphere_column(n: usize) -> Fc3dProblem {
    let gh = 9.81e-3;
    let mut entries = Vec::new();
    for k in 0..n {
        for axis in 0..3 {
            let i = 3 * k + axis;
            entries.push((i, i, if k == 0 { 1.0 } else { 2.0 }));
            if k + 1 < n {
                entries.push((i, i + 3, -1.0));
                entries.push((i + 3, i, -1.0));
            }
        }
    }
    let mut q = vec![0.0; 3 * n];
    q[0] = -gh;
    Fc3dProblem {
        w: BlockCsr::from_triplets(3, 3 * n, entries).unwrap(),
        q,
        mu: vec![0.3; n],
    }
}

/// On the column of 30 spheres, Gauss–Seidel crawls (the weight crosses the column one contact
/// per sweep, a spectral radius near 1 − π²/n²: 6 223 sweeps to 1e-10) and Anderson's
/// acceleration of the same sweeps reaches the same tolerance in a fraction of them (79 sweeps
/// with its first restart rule, 78 with the restarts from the best sweep output, which never
/// make it fall back to plain sweeps here);
/// both return the weights of the spheres above each contact.
#[test]
fn anderson_acceleration_crosses_a_column_of_spheres_in_few_sweeps() {
    let n = 30;
    let problem = sphere_column(n);
    let options = |kind| Fc3dOptions {
        kind,
        tolerance: 1e-10,
        max_iterations: 100_000,
        ..Fc3dOptions::default()
    };
    let plain = solve_fc3d(&problem, &options(Fc3dSolverKind::Nsgs)).unwrap();
    let fast = solve_fc3d(&problem, &options(Fc3dSolverKind::NsgsAnderson)).unwrap();
    for s in [&plain, &fast] {
        for k in 0..n {
            let weight = (n - k) as f64 * 9.81e-3;
            assert!(
                (s.r[3 * k] - weight).abs() <= 1e-7 * weight,
                "{}: contact {k} {:?}",
                s.solver,
                &s.r[3 * k..3 * k + 3]
            );
            assert!(
                s.r[3 * k + 1].abs() + s.r[3 * k + 2].abs() <= 1e-12,
                "{}",
                s.solver
            );
        }
    }
    assert_eq!(fast.solver, "nsgs_aa");
    assert!(plain.iterations > 1000, "{}", plain.iterations);
    assert!(
        10 * fast.iterations < plain.iterations,
        "{} against {}",
        fast.iterations,
        plain.iterations
    );
    assert!(fast.iterations <= 85, "{}", fast.iterations);
}

/// The stagnation test (`Fc3dOptions::stall`) stops sweeps that no longer make progress
/// and nothing else. On the column of 30 spheres Gauss–Seidel crawls at a steady rate (6 223
/// sweeps to 1e-10) that a window of 100 sweeps leaves alone, to the last bit; asked for an error
/// below round-off (1e-300), the sweeps reach their floor (1.4e-16) and stop a window later
/// instead of spending the budget, plain and accelerated, with the smallest error the whole
/// budget finds; with the test bounded below that floor (1e-20) they go on to the end of the
/// budget. A window of zero sweeps, a bound that is not a positive number, or a test given to
/// a solver that does not sweep is refused.
#[test]
fn sweeps_stop_when_they_stall_and_only_then() {
    let problem = sphere_column(30);
    let window = 100;
    let stall = |sweeps, below| Some(Fc3dStall { sweeps, below });
    let options = |kind, tolerance, stall| Fc3dOptions {
        kind,
        tolerance,
        max_iterations: 20_000,
        stall,
        ..Fc3dOptions::default()
    };
    for kind in [Fc3dSolverKind::Nsgs, Fc3dSolverKind::NsgsAnderson] {
        let free = solve_fc3d(&problem, &options(kind, 1e-10, None)).unwrap();
        let watched = solve_fc3d(
            &problem,
            &options(kind, 1e-10, stall(window, f64::INFINITY)),
        )
        .unwrap();
        assert_eq!(free, watched, "{kind:?}");
        let Err(Fc3dError::NotConverged {
            iterations, error, ..
        }) = solve_fc3d(&problem, &options(kind, 1e-300, None))
        else {
            panic!("{kind:?} reached 1e-300");
        };
        assert_eq!(iterations, 20_000, "{kind:?}");
        let floor = error;
        assert!(floor <= 1e-15, "{kind:?}: {floor:e}");
        let Err(Fc3dError::NotConverged {
            iterations, error, ..
        }) = solve_fc3d(
            &problem,
            &options(kind, 1e-300, stall(window, f64::INFINITY)),
        )
        else {
            panic!("{kind:?} reached 1e-300");
        };
        // Stopped a window after the floor (the plain sweeps reach it after about 11 200; the
        // accelerated ones reach 1e-10 in tens, then fall back to plain sweeps from the start,
        // whose window starts over), with the same smallest error as the whole budget found.
        assert!(
            iterations < 12_000 && iterations > window,
            "{kind:?}: stopped after {iterations} sweeps at {error:e} (floor {floor:e})"
        );
        assert_eq!(error, floor, "{kind:?}");
        // Sweeps stalled above the test's bound go on: here they spend the budget again.
        let Err(Fc3dError::NotConverged { iterations, .. }) =
            solve_fc3d(&problem, &options(kind, 1e-300, stall(window, 1e-20)))
        else {
            panic!("{kind:?} reached 1e-300");
        };
        assert_eq!(iterations, 20_000, "{kind:?}");
        assert!(error <= 1e-15, "{kind:?}: {error:e}");
    }
    assert!(matches!(
        solve_fc3d(
            &problem,
            &options(Fc3dSolverKind::Nsgs, 1e-8, stall(0, 1.0))
        ),
        Err(Fc3dError::InvalidStall { .. })
    ));
    assert!(matches!(
        solve_fc3d(
            &problem,
            &options(Fc3dSolverKind::Nsgs, 1e-8, stall(10, f64::NAN))
        ),
        Err(Fc3dError::InvalidStall { .. })
    ));
    for kind in [Fc3dSolverKind::Prox, Fc3dSolverKind::NewtonAlartCurnier] {
        assert!(matches!(
            solve_fc3d(&problem, &options(kind, 1e-8, stall(window, 1.0))),
            Err(Fc3dError::StallWithoutSweeps { .. })
        ));
    }
}
