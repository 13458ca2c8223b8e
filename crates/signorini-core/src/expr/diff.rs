//! Simplifying constructors and symbolic differentiation.
//!
//! The constructors fold constants and the identities `u + 0`, `u - 0`, `0 - u`, `0·u`, `1·u`,
//! `-1·u`, `u/1`, `0/u`, `u^1`, `u^0`, `--u`, and merge constant factors (`c₁·(c₂·u)`), so that
//! derivatives stay small: the derivative of a term that does not depend on x is the constant 0
//! and vanishes from every sum and product it enters.

use super::{Expr, Func, Func2, Node};
use std::collections::HashMap;

/// The hasher of the memo and hash-consing tables: keys are addresses and small integers built
/// by the program, never by a user, so a fast non-keyed hash is safe (SipHash was a fifth of
/// the compile time of a large model, issue 27).
pub(super) type FastHash = foldhash::fast::FixedState;

/// A hash map with [`FastHash`].
pub(super) type FastMap<K, V> = HashMap<K, V, FastHash>;

fn mk(n: Node) -> Expr {
    Expr::from_node(n)
}

/// Operands of a sum folded left to right before it is split into blocks added pairwise (the
/// parser's `CHAIN_BLOCK`).
const SUM_BLOCK: usize = 32;

/// Σ terms: left to right up to [`SUM_BLOCK`] nonzero terms (exactly the fold
/// `((0 + a) + b) + …` with its zeros dropped), blocks of [`SUM_BLOCK`] added pairwise beyond.
pub(super) fn sum(terms: impl Iterator<Item = Expr>) -> Expr {
    let mut blocks: Vec<Expr> = Vec::new();
    let mut e = Expr::constant(0.0);
    let mut in_block = 0;
    for t in terms.filter(|t| !t.is_zero()) {
        if in_block == SUM_BLOCK {
            blocks.push(std::mem::replace(&mut e, t));
            in_block = 1;
        } else {
            e = add(e, t);
            in_block += 1;
        }
    }
    if blocks.is_empty() {
        return e;
    }
    blocks.push(e);
    while blocks.len() > 1 {
        let mut next = Vec::with_capacity(blocks.len().div_ceil(2));
        let mut it = blocks.into_iter();
        while let Some(l) = it.next() {
            next.push(match it.next() {
                Some(r) => add(l, r),
                None => l,
            });
        }
        blocks = next;
    }
    blocks.pop().unwrap_or_else(|| Expr::constant(0.0))
}

/// a + b.
pub(super) fn add(a: Expr, b: Expr) -> Expr {
    match (a.as_constant(), b.as_constant()) {
        (Some(x), Some(y)) => Expr::constant(x + y),
        (Some(0.0), _) => b,
        (_, Some(0.0)) => a,
        _ => match negated(&b) {
            // a + (−u) = a − u
            Some(u) => sub(a, u),
            None => mk(Node::Add(a, b)),
        },
    }
}

/// a − b.
pub(super) fn sub(a: Expr, b: Expr) -> Expr {
    match (a.as_constant(), b.as_constant()) {
        (Some(x), Some(y)) => Expr::constant(x - y),
        (Some(0.0), _) => neg(b),
        (_, Some(0.0)) => a,
        _ => match negated(&b) {
            // a − (−u) = a + u
            Some(u) => add(a, u),
            None => mk(Node::Sub(a, b)),
        },
    }
}

/// −a.
pub(super) fn neg(a: Expr) -> Expr {
    match a.node() {
        Node::Const(x) => Expr::constant(-x),
        Node::Neg(u) => u.clone(),
        Node::Mul(k, u) if k.as_constant().is_some() => {
            mul(Expr::constant(-k.as_constant().unwrap_or(1.0)), u.clone())
        }
        _ => mk(Node::Neg(a)),
    }
}

/// u when `e` is −u or (−k)·u with k > 0 (as k·u), so that sums print and evaluate as
/// differences.
fn negated(e: &Expr) -> Option<Expr> {
    match e.node() {
        Node::Neg(u) => Some(u.clone()),
        Node::Mul(k, u) => match k.as_constant() {
            Some(k) if k < 0.0 => Some(mul(Expr::constant(-k), u.clone())),
            _ => None,
        },
        _ => None,
    }
}

/// a·b, constants first.
pub(super) fn mul(a: Expr, b: Expr) -> Expr {
    match (a.as_constant(), b.as_constant()) {
        (Some(x), Some(y)) => Expr::constant(x * y),
        (_, Some(_)) => mul(b, a),
        (Some(x), None) => {
            if x == 0.0 {
                Expr::constant(0.0)
            } else if x == 1.0 {
                b
            } else if x == -1.0 {
                neg(b)
            } else {
                match b.node() {
                    // c₁·(c₂·u) = (c₁c₂)·u
                    Node::Mul(k, u) if k.as_constant().is_some() => {
                        let k = k.as_constant().unwrap_or(1.0);
                        mul(Expr::constant(x * k), u.clone())
                    }
                    Node::Neg(u) => mul(Expr::constant(-x), u.clone()),
                    _ => mk(Node::Mul(a, b)),
                }
            }
        }
        (None, None) => match (a.node(), b.node()) {
            (Node::Neg(u), Node::Neg(v)) => mul(u.clone(), v.clone()),
            (Node::Neg(u), _) => neg(mul(u.clone(), b)),
            (_, Node::Neg(v)) => neg(mul(a, v.clone())),
            _ => mk(Node::Mul(a, b)),
        },
    }
}

/// a/b.
pub(super) fn div(a: Expr, b: Expr) -> Expr {
    match (a.as_constant(), b.as_constant()) {
        (Some(x), Some(y)) => Expr::constant(x / y),
        (Some(0.0), None) => Expr::constant(0.0),
        (_, Some(1.0)) => a,
        (_, Some(-1.0)) => neg(a),
        _ => match a.node() {
            Node::Neg(u) => neg(div(u.clone(), b)),
            _ => mk(Node::Div(a, b)),
        },
    }
}

/// a^b.
pub(super) fn pow(a: Expr, b: Expr) -> Expr {
    match (a.as_constant(), b.as_constant()) {
        (Some(x), Some(y)) => Expr::constant(x.powf(y)),
        (_, Some(1.0)) => a,
        (_, Some(0.0)) => Expr::constant(1.0),
        _ => mk(Node::Pow(a, b)),
    }
}

/// f(a), folded when a is constant.
pub(super) fn call(f: Func, a: Expr) -> Expr {
    match a.as_constant() {
        Some(x) => Expr::constant(f.apply(x)),
        None => mk(Node::Call(f, a)),
    }
}

/// f(a, b), folded when both are constant.
pub(super) fn call2(f: Func2, a: Expr, b: Expr) -> Expr {
    match (a.as_constant(), b.as_constant()) {
        (Some(x), Some(y)) => Expr::constant(f.apply(x, y)),
        _ => mk(Node::Call2(f, a, b)),
    }
}

fn c(x: f64) -> Expr {
    Expr::constant(x)
}

/// ∂e/∂x_var. A subtree that does not depend on x_var (its dependence set says so) is not
/// visited: its derivative is 0. Shared subtrees are differentiated once (memo on the node's
/// address), so the work is linear in the number of distinct nodes that depend on x_var.
pub(super) fn derivative(e: &Expr, var: usize) -> Expr {
    if !e.depends_on(var) {
        return c(0.0);
    }
    let mut memo = FastMap::default();
    d(e, var, &mut memo)
}

fn d(e: &Expr, x: usize, memo: &mut FastMap<usize, Expr>) -> Expr {
    if !e.depends_on(x) {
        return c(0.0);
    }
    if let Node::Var(_) = e.node() {
        // The only variable it depends on is x.
        return c(1.0);
    }
    let key = e.address();
    if let Some(r) = memo.get(&key) {
        return r.clone();
    }
    let r = match e.node() {
        Node::Const(_) => c(0.0),
        Node::Var(i) => c(if *i == x { 1.0 } else { 0.0 }),
        Node::Neg(a) => neg(d(a, x, memo)),
        Node::Add(a, b) => add(d(a, x, memo), d(b, x, memo)),
        Node::Sub(a, b) => sub(d(a, x, memo), d(b, x, memo)),
        Node::Mul(a, b) => {
            let (da, db) = (d(a, x, memo), d(b, x, memo));
            add(mul(da, b.clone()), mul(a.clone(), db))
        }
        Node::Div(a, b) => {
            // (a/b)' = a'/b − a b'/b²
            let (da, db) = (d(a, x, memo), d(b, x, memo));
            if db.is_zero() {
                div(da, b.clone())
            } else {
                sub(
                    div(da, b.clone()),
                    div(mul(a.clone(), db), pow(b.clone(), c(2.0))),
                )
            }
        }
        Node::Pow(a, b) => {
            let (da, db) = (d(a, x, memo), d(b, x, memo));
            match b.as_constant() {
                // (a^k)' = k a^(k−1) a'
                Some(k) => mul(mul(c(k), pow(a.clone(), c(k - 1.0))), da),
                // (a^b)' = a^b (b' ln a + b a'/a)
                None => {
                    let log_part = mul(db, call(Func::Log, a.clone()));
                    let base_part = if da.is_zero() {
                        c(0.0)
                    } else {
                        div(mul(b.clone(), da), a.clone())
                    };
                    mul(e.clone(), add(log_part, base_part))
                }
            }
        }
        Node::Call(f, a) => {
            let da = d(a, x, memo);
            if da.is_zero() {
                c(0.0)
            } else {
                mul(func_derivative(*f, a, e), da)
            }
        }
        Node::Call2(f, a, b) => {
            let (da, db) = (d(a, x, memo), d(b, x, memo));
            match f {
                // atan2(a, b)' = (b a' − a b')/(a² + b²)
                Func2::Atan2 => div(
                    sub(mul(b.clone(), da), mul(a.clone(), db)),
                    add(pow(a.clone(), c(2.0)), pow(b.clone(), c(2.0))),
                ),
                // min(a, b)' = (a' + b')/2 − sign(a − b)(a' − b')/2, max with +: a' where the
                // first argument is selected, b' where the second is, the mean at a tie.
                Func2::Min | Func2::Max => {
                    let s = call(Func::Sign, sub(a.clone(), b.clone()));
                    let half_diff = mul(c(0.5), sub(da.clone(), db.clone()));
                    let mean = mul(c(0.5), add(da, db));
                    if *f == Func2::Min {
                        sub(mean, mul(s, half_diff))
                    } else {
                        add(mean, mul(s, half_diff))
                    }
                }
            }
        }
    };
    memo.insert(key, r.clone());
    r
}

/// f'(a) for `e = f(a)` (e is reused where f' = f, as for exp).
fn func_derivative(f: Func, a: &Expr, e: &Expr) -> Expr {
    let a = a.clone();
    let one_minus_sq = || sub(c(1.0), pow(a.clone(), c(2.0)));
    match f {
        Func::Sin => call(Func::Cos, a),
        Func::Cos => neg(call(Func::Sin, a)),
        Func::Tan => div(c(1.0), pow(call(Func::Cos, a), c(2.0))),
        Func::Asin => div(c(1.0), call(Func::Sqrt, one_minus_sq())),
        Func::Acos => neg(div(c(1.0), call(Func::Sqrt, one_minus_sq()))),
        Func::Atan => div(c(1.0), add(c(1.0), pow(a, c(2.0)))),
        Func::Sinh => call(Func::Cosh, a),
        Func::Cosh => call(Func::Sinh, a),
        Func::Tanh => div(c(1.0), pow(call(Func::Cosh, a), c(2.0))),
        Func::Exp => e.clone(),
        Func::Log => div(c(1.0), a),
        Func::Sqrt => div(c(0.5), e.clone()),
        Func::Abs => call(Func::Sign, a),
        Func::Sign => c(0.0),
    }
}
