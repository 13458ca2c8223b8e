//! Issue 27 ("compiling a model must scale too"): the derivatives of a `lagrangian` model are
//! built from dependence sets and sparse gradients, and compiled into tapes that store only the
//! structurally nonzero entries. Here random banded models with a configuration-dependent mass,
//! a long flat potential (more than one block of the parser's chains), velocity-dependent
//! forces, a joint, contacts and tangents check every compiled matrix against forward-mode dual
//! numbers over the model's own value tapes (an independent route to the same derivatives),
//! to round-off.

// Only the core library must stay pure (clippy.toml): a test may print.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use num_dual::Dual64;
use signorini_core::expr::Expr;
use signorini_core::lagrangian::{Tangent, UserModel};
use signorini_core::nonlinear::LagrangianSystem;
use signorini_core::soi2::ConstrainedModel;
use signorini_core::spec::LagrangianSpec;
use std::fmt::Write;

mod random;
use random::Random;

/// A uniform index below `n`.
fn index(rng: &mut Random, n: usize) -> usize {
    (((rng.next() + 1.0) * 0.5 * n as f64) as usize).min(n - 1)
}

/// A random model of `n` coordinates: M pentadiagonal, diagonally dominant, depending on q;
/// V a flat sum of `terms` random terms; f velocity dependent; a joint x0 = x1; two contacts,
/// one with a tangent.
fn random_model(n: usize, terms: usize, rng: &mut Random) -> String {
    let mut s = String::new();
    let names: Vec<String> = (0..n).map(|i| format!("x{i}")).collect();
    writeln!(s, "coordinates = {names:?}").unwrap();
    let mut entries = Vec::new();
    for i in 0..n {
        let (a, b) = (2.5 + 0.5 * rng.next(), 0.25 + 0.25 * rng.next());
        entries.push(format!("[{i}, {i}, \"{a:?} + {b:?}*cos(x{i})^2\"]"));
        if i + 1 < n {
            let c = 0.3 * rng.next();
            entries.push(format!("[{i}, {}, \"{c:?}*sin(x{})\"]", i + 1, i + 1));
        }
        if i + 2 < n {
            let c = 0.2 * rng.next();
            entries.push(format!("[{i}, {}, \"{c:?}*x{i}*x{}\"]", i + 2, i + 2));
        }
    }
    writeln!(s, "mass = {{ entries = [{}] }}", entries.join(", ")).unwrap();
    let mut potential = Vec::new();
    for _ in 0..terms {
        let (a, b, k) = (index(rng, n), index(rng, n), rng.next());
        potential.push(match index(rng, 4) {
            0 => format!("{k:?}*(x{a} - x{b})^2"),
            1 => format!("{k:?}*cos(x{a})*x{b}"),
            2 => format!("{k:?}*x{a}^3"),
            _ => format!("{k:?}*exp(0.1*x{a})*sin(x{b})"),
        });
    }
    writeln!(s, "potential = \"{}\"", potential.join(" + ")).unwrap();
    let forces: Vec<String> = (0..n)
        .map(|i| {
            let (j, k, d, e) = (index(rng, n), index(rng, n), rng.next(), rng.next());
            format!("-{:?}*x{i}_dot + {e:?}*sin(x{j})*x{k}_dot", d.abs())
        })
        .collect();
    writeln!(s, "forces = {forces:?}").unwrap();
    let mut q0: Vec<f64> = (0..n).map(|_| 0.5 * rng.next()).collect();
    q0[1] = q0[0];
    let v0: Vec<f64> = (0..n).map(|_| rng.next()).collect();
    writeln!(s, "q0 = {q0:?}").unwrap();
    writeln!(s, "v0 = {v0:?}").unwrap();
    writeln!(s, "constraints = [{{ expr = \"x0 - x1 + 0.1*t*sin(t)\" }}]").unwrap();
    let (a, b, c, d) = (index(rng, n), index(rng, n), index(rng, n), index(rng, n));
    writeln!(
        s,
        "contacts = [{{ gap = \"x{a} + 0.3*x{b}^2 + 5 + 0.1*t\", friction = 0.3, tangent = \"x{c}*cos(x{d}) + t\" }}, {{ gap = \"x{d} - x{c} + 4\" }}]"
    )
    .unwrap();
    s
}

/// max |exact − dual| ≤ 1e-12 relative to the larger max-norm (1 at least).
fn assert_round_off(what: &str, exact: &[f64], dual: &[f64]) {
    assert_eq!(exact.len(), dual.len(), "{what}");
    let norm = |v: &[f64]| v.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    let scale = norm(exact).max(norm(dual)).max(1.0);
    let err = exact
        .iter()
        .zip(dual)
        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(
        err <= 1e-12 * scale,
        "{what}: error {err:e} (scale {scale:e})\nexact {exact:?}\ndual  {dual:?}"
    );
}

fn duals(x: &[f64]) -> Vec<Dual64> {
    x.iter().map(|&v| Dual64::from(v)).collect()
}

/// Column j of a dense row-major `rows`×`cols` matrix written into `into`.
fn set_column(into: &mut [f64], cols: usize, j: usize, column: &[Dual64]) {
    for (r, c) in column.iter().enumerate() {
        into[r * cols + j] = c.eps;
    }
}

/// Every compiled matrix of random banded models against dual numbers over the value tapes:
/// ∂F/∂q and ∂F/∂q̇ (F over `Dual64` seeded on one coordinate or velocity at a time), the
/// Coriolis vector c = Ṁq̇ − ½∇_q(q̇ᵀMq̇) (M over `Dual64`), the joint Jacobian g_q and rate
/// g_q q̇ + g_t; the mass matrix against its entries' trees, exactly zero off the band.
#[test]
fn sparse_derivatives_match_dual_numbers_on_random_banded_models() {
    let mut rng = Random(0x5eed_0027_dead_beef);
    for (n, terms) in [(3, 5), (9, 40), (17, 80)] {
        let text = random_model(n, terms, &mut rng);
        let spec: LagrangianSpec = toml::from_str(&text).expect("the random model parses");
        let params = spec.validate().unwrap_or_else(|e| panic!("{e}\n{text}"));
        let upper = params.mass.clone();
        let model = UserModel::new(params);
        let joints = model.joints();
        for _ in 0..3 {
            let q: Vec<f64> = (0..n).map(|_| 0.7 * rng.next()).collect();
            let v: Vec<f64> = (0..n).map(|_| rng.next()).collect();
            let t = rng.next().abs();
            let lambda = vec![Dual64::from(0.0); joints];
            // ∂F/∂q and ∂F/∂q̇.
            let (mut dq, mut dv) = (vec![0.0; n * n], vec![0.0; n * n]);
            LagrangianSystem::force_jacobians(&model, t, &q, &v, &mut dq, &mut dv);
            let (mut ad_q, mut ad_v) = (vec![0.0; n * n], vec![0.0; n * n]);
            let mut f = vec![Dual64::from(0.0); n];
            for j in 0..n {
                let (mut qd, vd) = (duals(&q), duals(&v));
                qd[j].eps = 1.0;
                ConstrainedModel::force(&model, Dual64::from(t), &qd, &vd, &lambda, &[], &mut f);
                set_column(&mut ad_q, n, j, &f);
                let (qd, mut vd) = (duals(&q), duals(&v));
                vd[j].eps = 1.0;
                ConstrainedModel::force(&model, Dual64::from(t), &qd, &vd, &lambda, &[], &mut f);
                set_column(&mut ad_v, n, j, &f);
            }
            assert_round_off(&format!("n = {n}: ∂F/∂q"), &dq, &ad_q);
            assert_round_off(&format!("n = {n}: ∂F/∂q̇"), &dv, &ad_v);
            // M against its entries, zero off the given entries.
            let mut m = vec![0.0; n * n];
            LagrangianSystem::mass(&model, &q, &mut m);
            let mut vars = q.clone();
            vars.extend_from_slice(&v);
            vars.push(t);
            let mut from_entries = vec![0.0; n * n];
            for (i, j, e) in &upper {
                from_entries[i * n + j] = e.eval(&vars);
                from_entries[j * n + i] = e.eval(&vars);
            }
            assert_round_off(&format!("n = {n}: M"), &m, &from_entries);
            // c = Ṁq̇ − ½∇_q(q̇ᵀMq̇) from dual evaluations of M.
            let mut c = vec![0.0; n];
            model.coriolis(&q, &v, &mut c);
            let mut md = vec![Dual64::from(0.0); n * n];
            let along: Vec<Dual64> = q.iter().zip(&v).map(|(&x, &w)| Dual64::new(x, w)).collect();
            ConstrainedModel::mass(&model, Dual64::from(0.0), &along, &mut md);
            let mut reference: Vec<f64> = (0..n)
                .map(|i| (0..n).map(|j| md[i * n + j].eps * v[j]).sum())
                .collect();
            for (i, r) in reference.iter_mut().enumerate() {
                let mut qd = duals(&q);
                qd[i].eps = 1.0;
                ConstrainedModel::mass(&model, Dual64::from(0.0), &qd, &mut md);
                let quadratic: f64 = (0..n)
                    .flat_map(|j| (0..n).map(move |k| (j, k)))
                    .map(|(j, k)| v[j] * md[j * n + k].eps * v[k])
                    .sum();
                *r -= 0.5 * quadratic;
            }
            assert_round_off(&format!("n = {n}: c"), &c, &reference);
            // g_q and g_q q̇ + g_t.
            let mut gy = vec![0.0; joints * n];
            ConstrainedModel::g_y(&model, t, &q, &mut gy);
            let mut ad_gy = vec![0.0; joints * n];
            let mut g = vec![Dual64::from(0.0); joints];
            for j in 0..n {
                let mut qd = duals(&q);
                qd[j].eps = 1.0;
                ConstrainedModel::g(&model, Dual64::from(t), &qd, &mut g);
                set_column(&mut ad_gy, n, j, &g);
            }
            assert_round_off(&format!("n = {n}: g_q"), &gy, &ad_gy);
            let mut rate = vec![0.0; joints];
            ConstrainedModel::g_dot(&model, t, &q, &v, &mut rate);
            let along: Vec<Dual64> = q.iter().zip(&v).map(|(&x, &w)| Dual64::new(x, w)).collect();
            ConstrainedModel::g(&model, Dual64::new(t, 1.0), &along, &mut g);
            let ad_rate: Vec<f64> = g.iter().map(|x| x.eps).collect();
            assert_round_off(&format!("n = {n}: g_q q̇ + g_t"), &rate, &ad_rate);
        }
    }
}

/// The gap and tangent Jacobians and rates of the random models against the trees of their
/// expressions' dense gradients (`Expr::gradient` over every coordinate, the pre-issue-27 way
/// of building them), to round-off, and zero wherever the expression does not use a coordinate.
#[test]
fn sparse_gap_and_tangent_rows_match_the_dense_gradients() {
    let mut rng = Random(0x0bad_cafe_0027_0001);
    for n in [4, 12, 40] {
        let text = random_model(n, 2 * n, &mut rng);
        let spec: LagrangianSpec = toml::from_str(&text).expect("the random model parses");
        let params = spec.validate().unwrap_or_else(|e| panic!("{e}\n{text}"));
        let contacts = params.contacts.clone();
        let model = UserModel::new(params);
        let m = contacts.len();
        let q: Vec<f64> = (0..n).map(|_| 0.7 * rng.next()).collect();
        let t = rng.next().abs();
        let mut vars = q.clone();
        vars.extend(std::iter::repeat_n(0.0, n));
        vars.push(t);
        let all: Vec<usize> = (0..n).collect();
        let dense = |rows: Vec<Vec<Expr>>| -> Vec<f64> {
            rows.iter().flatten().map(|e| e.eval(&vars)).collect()
        };
        let mut jac = vec![0.0; m * n];
        model.gap_jacobian(t, &q, &mut jac);
        let gaps = dense(contacts.iter().map(|c| c.gap.gradient(&all)).collect());
        assert_round_off(&format!("n = {n}: gap Jacobian"), &jac, &gaps);
        let mut rates = vec![0.0; m];
        model.gap_rates(t, &q, &mut rates);
        let gap_rates: Vec<f64> = contacts
            .iter()
            .map(|c| c.gap.derivative(2 * n).eval(&vars))
            .collect();
        assert_round_off(&format!("n = {n}: gap rates"), &rates, &gap_rates);
        let mut tangent = vec![0.0; m * n];
        model.tangent_jacobian(t, &q, &mut tangent);
        let rows: Vec<Vec<_>> = contacts
            .iter()
            .map(|c| match &c.tangent {
                Some(Tangent::Position(tau)) => tau.gradient(&all),
                _ => vec![Expr::constant(0.0); n],
            })
            .collect();
        assert_round_off(&format!("n = {n}: tangent rows"), &tangent, &dense(rows));
    }
}
