//! The banded active-set solver (`lcp::active_set`) against Lemke's method on the Delassus
//! operator it never forms: random banded problems of both impulse maps (proptest), the
//! symmetric positive definite problems of the LCP corpus, warm starts, and its budget.

// Only the core library must stay pure (clippy.toml): a test may read fixtures.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]
// Index loops compare entries of two solutions side by side.
#![allow(clippy::needless_range_loop)]

use proptest::prelude::*;
use serde::Deserialize;
use signorini_core::band::SymBand;
use signorini_core::lcp::active_set::{BandedActiveSet, ImpulseMap, unit_columns};
use signorini_core::lcp::{Lcp, LcpError, LcpOptions, LcpSolverKind, solve_lemke};
use std::path::Path;

fn lemke_options() -> LcpOptions {
    LcpOptions {
        kind: LcpSolverKind::Lemke,
        tolerance: 1e-10,
        max_iterations: 100_000,
    }
}

/// Column j of S⁻¹ (dense, by banded solves).
fn inverse_columns(s: &SymBand) -> Vec<Vec<f64>> {
    let f = s.cholesky().unwrap();
    (0..s.n())
        .map(|j| {
            let mut e = vec![0.0; s.n()];
            e[j] = 1.0;
            f.solve_in_place(&mut e);
            e
        })
        .collect()
}

/// The dense Delassus operator W = Gᵀ S⁻¹ R D G (row-major), R D = I for `Direct`.
fn delassus(s: &SymBand, map: &ImpulseMap, rows: &[(usize, f64)]) -> Vec<f64> {
    let n = s.n();
    let inv = inverse_columns(s);
    let k = rows.len();
    let mut w = vec![0.0; k * k];
    for (b, &(j, gb)) in rows.iter().enumerate() {
        // Column of S⁻¹ R D G_β.
        let col: Vec<f64> = match map {
            ImpulseMap::Direct => inv[j].iter().map(|v| v * gb).collect(),
            ImpulseMap::Filtered { r, d } => {
                let mut c = vec![0.0; n];
                for (i, ci) in c.iter_mut().enumerate() {
                    *ci = (0..n)
                        .map(|l| inv[l][i] * r.get(l, j) * d[j] * gb)
                        .sum::<f64>();
                }
                c
            }
        };
        for (a, &(i, ga)) in rows.iter().enumerate() {
            w[a * k + b] = ga * col[i];
        }
    }
    w
}

/// Solves with the banded solver and with Lemke on W; asserts P agree to 1e-9 (relative to
/// max(1, ‖P‖)) and that x = S⁻¹ R D G P.
fn agree(
    solver: &mut BandedActiveSet,
    s: &SymBand,
    map: &ImpulseMap,
    rows: &[(usize, f64)],
    b: &[f64],
) {
    let n = s.n();
    let k = rows.len();
    let w = delassus(s, map, rows);
    let lemke = solve_lemke(Lcp { m: &w, q: b }, &lemke_options()).unwrap();
    let mut p = vec![0.0; k];
    let mut x = vec![0.0; n];
    let stats = solver
        .solve(rows, b, &LcpOptions::default(), &mut p, &mut x)
        .unwrap();
    assert!(stats.error <= 1e-12, "error {}", stats.error);
    let scale = lemke.z.iter().fold(1.0f64, |a, z| a.max(z.abs()));
    for a in 0..k {
        assert!(
            (p[a] - lemke.z[a]).abs() <= 1e-9 * scale,
            "P[{a}] = {} but Lemke gives {} (k = {k}, n = {n})",
            p[a],
            lemke.z[a]
        );
    }
    // x = S⁻¹ R D G P, and w = Gᵀx + b matches W P + b.
    for (a, &(i, g)) in rows.iter().enumerate() {
        let wp: f64 = (0..k).map(|c| w[a * k + c] * p[c]).sum::<f64>() + b[a];
        assert!(
            (g * x[i] + b[a] - wp).abs() <= 1e-9 * (1.0 + b[a].abs()),
            "w[{a}]: {} vs {}",
            g * x[i] + b[a],
            wp
        );
    }
}

/// A random banded SPD matrix: diagonal dominance from `shift` over random off-diagonals.
fn banded_spd(n: usize, kd: usize, off: &[f64], shift: f64) -> SymBand {
    let mut s = SymBand::zeros(n, kd);
    let mut row_abs = vec![0.0; n];
    let mut t = 0;
    for i in 0..n {
        for j in i.saturating_sub(kd)..i {
            let v = off[t % off.len()];
            t += 1;
            s.set(i, j, v);
            row_abs[i] += v.abs();
            row_abs[j] += v.abs();
        }
    }
    for (i, r) in row_abs.iter().enumerate() {
        s.set(i, i, r + shift);
    }
    s
}

/// Contact rows on a random subset of dofs with random signs.
fn pick_rows(n: usize, mask: &[bool], signs: &[f64]) -> Vec<(usize, f64)> {
    (0..n)
        .filter(|&i| mask[i % mask.len()])
        .map(|i| (i, signs[i % signs.len()]))
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn direct_map_equals_lemke(
        n in 2usize..30,
        kd in 1usize..4,
        off in prop::collection::vec(-1.0f64..1.0, 1..40),
        shift in 0.05f64..2.0,
        mask in prop::collection::vec(any::<bool>(), 1..12),
        signs in prop::collection::vec(prop_oneof![Just(1.0f64), Just(-1.0), 0.3f64..3.0], 1..8),
        b in prop::collection::vec(-2.0f64..1.0, 30),
    ) {
        let s = banded_spd(n, kd, &off, shift);
        let rows = pick_rows(n, &mask, &signs);
        prop_assume!(!rows.is_empty());
        let b = &b[..rows.len()];
        let mut solver = BandedActiveSet::new(s.clone(), ImpulseMap::Direct);
        agree(&mut solver, &s, &ImpulseMap::Direct, &rows, b);
        // A warm start from this solution changes nothing on a perturbed problem.
        let b2: Vec<f64> = b.iter().enumerate().map(|(i, v)| v + 0.1 * ((i as f64).sin())).collect();
        agree(&mut solver, &s, &ImpulseMap::Direct, &rows, &b2);
    }

    /// S a Z-matrix (an M-matrix: a mass plus a stiffness with non-positive couplings) and
    /// one sign of G, the structure whose block pivots converge monotonically and whose
    /// shrinking contact regions leap: the obstacle problem of a string, with a smooth
    /// penetrating bump in b (a contact region wider than the solution's) and noise.
    #[test]
    fn z_matrix_direct_map_equals_lemke(
        n in 8usize..90,
        kd in 1usize..3,
        off in prop::collection::vec(-1.0f64..-0.01, 1..40),
        shift in 1e-4f64..0.5,
        sign in prop_oneof![Just(1.0f64), Just(-1.0)],
        mask in prop::collection::vec(prop::bool::weighted(0.9), 1..12),
        bump in (0.1f64..3.0, 0.0f64..1.0, 0.05f64..0.5, -0.5f64..0.5),
        noise in prop::collection::vec(-0.05f64..0.05, 90),
    ) {
        let s = banded_spd(n, kd, &off, shift);
        let rows = pick_rows(n, &mask, &[sign]);
        prop_assume!(!rows.is_empty());
        let (depth, centre, width, lift) = bump;
        let b: Vec<f64> = rows
            .iter()
            .map(|&(i, _)| {
                let u = (i as f64 / n as f64 - centre) / width;
                lift - depth * (-u * u).exp() + noise[i]
            })
            .collect();
        let mut solver = BandedActiveSet::new(s.clone(), ImpulseMap::Direct);
        agree(&mut solver, &s, &ImpulseMap::Direct, &rows, &b);
        // Warm-started from that solution, on the bump moved along.
        let b2: Vec<f64> = rows
            .iter()
            .map(|&(i, _)| {
                let u = (i as f64 / n as f64 - centre - 0.1) / width;
                lift - depth * (-u * u).exp() + noise[(i + 7) % 90]
            })
            .collect();
        agree(&mut solver, &s, &ImpulseMap::Direct, &rows, &b2);
    }

    /// Every dof a contact and every contact pressed (the settled region of a string on its
    /// obstacle): b = −Gᵀ S⁻¹ G P with P > 0, so the solution has every contact active, x
    /// prescribed on every dof and P = (S x)_dof / g, the path with no system to solve; rows
    /// in dof order and in reverse; a warm re-solve takes one iteration on the kept factor.
    #[test]
    fn every_dof_pressed_equals_lemke(
        n in 2usize..40,
        kd in 1usize..4,
        off in prop::collection::vec(-1.0f64..1.0, 1..40),
        shift in 0.05f64..2.0,
        signs in prop::collection::vec(prop_oneof![Just(1.0f64), Just(-1.0), 0.3f64..3.0], 1..8),
        target in prop::collection::vec(0.1f64..2.0, 40),
        reverse in any::<bool>(),
    ) {
        let s = banded_spd(n, kd, &off, shift);
        let mut rows: Vec<(usize, f64)> = (0..n).map(|i| (i, signs[i % signs.len()])).collect();
        if reverse {
            rows.reverse();
        }
        let mut x = vec![0.0; n];
        for (r, &(i, g)) in rows.iter().enumerate() {
            x[i] = g * target[r];
        }
        s.cholesky().unwrap().solve_in_place(&mut x);
        let b: Vec<f64> = rows.iter().map(|&(i, g)| -g * x[i]).collect();
        let mut solver = BandedActiveSet::new(s.clone(), ImpulseMap::Direct);
        agree(&mut solver, &s, &ImpulseMap::Direct, &rows, &b);
        let (mut p, mut xs) = (vec![0.0; n], vec![0.0; n]);
        let stats = solver.solve(&rows, &b, &LcpOptions::default(), &mut p, &mut xs).unwrap();
        prop_assert_eq!((stats.iterations, stats.active), (1, n));
        for (r, &t) in target[..n].iter().enumerate() {
            prop_assert!((p[r] - t).abs() <= 1e-9 * 2.0, "P[{}] = {} for {}", r, p[r], t);
        }
    }

    #[test]
    fn filtered_map_equals_lemke(
        n in 2usize..24,
        kd in 1usize..3,
        off in prop::collection::vec(-1.0f64..1.0, 1..40),
        masses in prop::collection::vec(0.2f64..3.0, 24),
        coefs in (0.3f64..1.0, 0.0f64..0.5, 0.3f64..1.0, 0.0f64..0.3),
        mask in prop::collection::vec(any::<bool>(), 1..12),
        b in prop::collection::vec(-2.0f64..1.0, 24),
    ) {
        // S = a M + c K, R = e M + f K with M diagonal, K ⪰ 0: W = Gᵀ S⁻¹ R M⁻¹ G is SPD
        // (the α-family with 2β ≥ γ).
        let (a, c, e, f) = coefs;
        let k = banded_spd(n, kd, &off, 0.0);
        let m = SymBand::diagonal(&masses[..n]);
        let s = SymBand::combine(&[(a, &m), (c, &k)]);
        let r = SymBand::combine(&[(e, &m), (f, &k)]);
        let map = ImpulseMap::Filtered { r, d: masses[..n].iter().map(|v| 1.0 / v).collect() };
        let rows = pick_rows(n, &mask, &[1.0]);
        prop_assume!(!rows.is_empty());
        let mut solver = BandedActiveSet::new(s.clone(), map.clone());
        agree(&mut solver, &s, &map, &rows, &b[..rows.len()]);
    }
}

#[derive(Deserialize)]
struct Problem {
    m: Vec<Vec<f64>>,
    q: Vec<f64>,
    z: Vec<f64>,
    symmetric: bool,
}

/// Dense inverse by Gauss–Jordan with partial pivoting, symmetrised.
fn inverse(a: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let n = a.len();
    let mut t: Vec<Vec<f64>> = a
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let mut row = r.clone();
            row.extend((0..n).map(|j| f64::from(u8::from(i == j))));
            row
        })
        .collect();
    for c in 0..n {
        let p = (c..n)
            .max_by(|&x, &y| t[x][c].abs().total_cmp(&t[y][c].abs()))
            .unwrap();
        t.swap(c, p);
        let d = t[c][c];
        for v in t[c].iter_mut() {
            *v /= d;
        }
        for r in 0..n {
            if r != c {
                let f = t[r][c];
                let pivot_row = t[c].clone();
                for (v, pv) in t[r].iter_mut().zip(pivot_row) {
                    *v -= f * pv;
                }
            }
        }
    }
    (0..n)
        .map(|i| (0..n).map(|j| 0.5 * (t[i][n + j] + t[j][n + i])).collect())
        .collect()
}

#[test]
fn solves_the_spd_problems_of_the_lcp_corpus() {
    // A symmetric positive definite W is the Delassus operator of S = W⁻¹ (dense band) with
    // G = I: the banded solver must return the corpus' known solution.
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/lcp");
    let mut solved = 0;
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .collect();
    files.sort();
    for path in files {
        let p: Problem = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let n = p.q.len();
        if !p.symmetric || SymBand::from_dense_rows(&p.m).unwrap().cholesky().is_err() {
            continue;
        }
        let s = SymBand::from_dense_rows(&inverse(&p.m)).unwrap();
        let rows: Vec<(usize, f64)> = (0..n).map(|i| (i, 1.0)).collect();
        let mut solver = BandedActiveSet::new(s, ImpulseMap::Direct);
        let mut z = vec![0.0; n];
        let mut x = vec![0.0; n];
        let opts = LcpOptions {
            tolerance: 1e-10,
            ..LcpOptions::default()
        };
        let stats = solver.solve(&rows, &p.q, &opts, &mut z, &mut x).unwrap();
        assert!(stats.error <= 1e-10, "{}", path.display());
        let scale = p.z.iter().fold(1.0f64, |a, b| a.max(b.abs()));
        for i in 0..n {
            assert!(
                (z[i] - p.z[i]).abs() <= 1e-9 * scale,
                "{}: z[{i}] = {} but the solution is {}",
                path.display(),
                z[i],
                p.z[i]
            );
        }
        solved += 1;
    }
    assert!(solved >= 6, "only {solved} corpus problems applied");
}

#[test]
fn the_iteration_budget_ends_in_a_typed_error() {
    // A chain-like tridiagonal S with every contact pushed in: from a cold start the first
    // iteration only finds the set; one iteration cannot finish.
    let n = 50;
    let s = banded_spd(n, 1, &[-1.0], 0.01);
    let rows: Vec<(usize, f64)> = (0..n).map(|i| (i, 1.0)).collect();
    let b: Vec<f64> = (0..n)
        .map(|i| if i % 3 == 0 { -1.0 } else { 0.5 })
        .collect();
    let mut solver = BandedActiveSet::new(s, ImpulseMap::Direct);
    let (mut p, mut x) = (vec![0.0; n], vec![0.0; n]);
    let opts = LcpOptions {
        max_iterations: 1,
        ..LcpOptions::default()
    };
    let e = solver.solve(&rows, &b, &opts, &mut p, &mut x).unwrap_err();
    assert!(
        matches!(
            e,
            LcpError::NotConverged {
                solver: "banded_active_set",
                iterations: 1,
                ..
            }
        ),
        "{e}"
    );
    // With its budget it solves, and a second solve of the same problem, warm, takes one
    // iteration (the factor of the last active set is reused).
    let stats = solver
        .solve(&rows, &b, &LcpOptions::default(), &mut p, &mut x)
        .unwrap();
    assert!(stats.iterations >= 2);
    let warm = solver
        .solve(&rows, &b, &LcpOptions::default(), &mut p, &mut x)
        .unwrap();
    assert_eq!(warm.iterations, 1);
    assert_eq!(warm.active, stats.active);
}

#[test]
fn unit_columns_are_recognised() {
    let g = [vec![(0, 1.0)], vec![(2, -1.0)], vec![(1, 0.5), (3, 0.0)]];
    assert!(unit_columns(4, g.iter().map(|c| c.as_slice())));
    let shared = [vec![(0, 1.0)], vec![(0, -1.0)]];
    assert!(!unit_columns(4, shared.iter().map(|c| c.as_slice())));
    let two = [vec![(0, 1.0), (1, 1.0)]];
    assert!(!unit_columns(4, two.iter().map(|c| c.as_slice())));
}
