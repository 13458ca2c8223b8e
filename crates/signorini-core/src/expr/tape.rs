//! The compiled form: a flat register tape in static single assignment. The builder hash-conses
//! the expression DAGs into instructions (equal subexpressions of all outputs computed once);
//! the layout then puts the variables and constants first in the register file, so that only
//! operations are dispatched, each writing the next register.

use super::diff::FastMap;
use super::{Expr, Func, Func2, Node, Number};

/// One instruction of the builder; operands are earlier instructions.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Instr {
    Const(f64),
    Var(u32),
    Neg(u32),
    Add(u32, u32),
    Sub(u32, u32),
    Mul(u32, u32),
    Div(u32, u32),
    /// a^k, k a small integer: repeated multiplication, exact for negative bases.
    Powi(u32, i32),
    /// a^c, c a constant that is not a small integer.
    Powf(u32, f64),
    /// a^b, both varying.
    Pow(u32, u32),
    Call(Func, u32),
    Call2(Func2, u32, u32),
}

/// An operation of the final tape: operands are registers (variables first, then constants,
/// then the results of earlier operations).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Op {
    Neg(u32),
    Add(u32, u32),
    Sub(u32, u32),
    Mul(u32, u32),
    Div(u32, u32),
    Powi(u32, i32),
    Powf(u32, f64),
    Pow(u32, u32),
    Call(Func, u32),
    Call2(Func2, u32, u32),
    /// sin(a) and cos(a) into two consecutive registers.
    SinCos(u32),
}

/// Identity of an instruction for hash-consing (constants by their bits).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Key {
    Const(u64),
    Var(u32),
    Neg(u32),
    Add(u32, u32),
    Sub(u32, u32),
    Mul(u32, u32),
    Div(u32, u32),
    Powi(u32, i32),
    Powf(u32, u64),
    Pow(u32, u32),
    Call(Func, u32),
    Call2(Func2, u32, u32),
}

impl Instr {
    fn key(self) -> Key {
        match self {
            Instr::Const(c) => Key::Const(c.to_bits()),
            Instr::Var(i) => Key::Var(i),
            Instr::Neg(a) => Key::Neg(a),
            // a + b = b + a, a·b = b·a: one register for both orders.
            Instr::Add(a, b) => Key::Add(a.min(b), a.max(b)),
            Instr::Sub(a, b) => Key::Sub(a, b),
            Instr::Mul(a, b) => Key::Mul(a.min(b), a.max(b)),
            Instr::Div(a, b) => Key::Div(a, b),
            Instr::Powi(a, k) => Key::Powi(a, k),
            Instr::Powf(a, c) => Key::Powf(a, c.to_bits()),
            Instr::Pow(a, b) => Key::Pow(a, b),
            Instr::Call(f, a) => Key::Call(f, a),
            Instr::Call2(f, a, b) => Key::Call2(f, a, b),
        }
    }
}

/// Integer exponents up to this size are evaluated by `powi` (repeated multiplication).
const POWI_MAX: f64 = 64.0;

/// Compiled expressions: evaluates all its outputs at once over a shared variable vector.
///
/// The register file is `[variables | constants | results]`: the variables and constants are
/// copied in before the run, so only operations are dispatched.
#[derive(Debug, Clone, PartialEq)]
pub struct Tape {
    constants: Vec<f64>,
    code: Vec<Op>,
    /// The register of each output, or of each stored output of a sparse tape.
    outputs: Vec<u32>,
    /// A sparse tape ([`Tape::compile_sparse`]): the number of outputs and the (increasing)
    /// index of each stored one; every other output is 0.
    sparse: Option<(usize, Vec<u32>)>,
    n_vars: usize,
    /// Distinct nodes: operations, constants and the variables used.
    nodes: usize,
    /// Length of the register file.
    registers: usize,
}

struct Builder {
    code: Vec<Instr>,
    keys: FastMap<Key, u32>,
    /// Register of each node already compiled, by the node's address.
    memo: FastMap<usize, u32>,
    n_vars: usize,
}

impl Builder {
    fn emit(&mut self, ins: Instr) -> u32 {
        let key = ins.key();
        if let Some(&r) = self.keys.get(&key) {
            return r;
        }
        let r = self.code.len() as u32;
        self.code.push(ins);
        self.keys.insert(key, r);
        r
    }

    fn node(&mut self, e: &Expr) -> u32 {
        let ptr = e.address();
        if let Some(&r) = self.memo.get(&ptr) {
            return r;
        }
        let ins = match e.node() {
            Node::Const(c) => Instr::Const(*c),
            Node::Var(i) => {
                self.n_vars = self.n_vars.max(i + 1);
                Instr::Var(*i as u32)
            }
            Node::Neg(a) => Instr::Neg(self.node(a)),
            Node::Add(a, b) => Instr::Add(self.node(a), self.node(b)),
            Node::Sub(a, b) => Instr::Sub(self.node(a), self.node(b)),
            Node::Mul(a, b) => Instr::Mul(self.node(a), self.node(b)),
            Node::Div(a, b) => Instr::Div(self.node(a), self.node(b)),
            Node::Pow(a, b) => {
                let ra = self.node(a);
                match b.as_constant() {
                    Some(k) if k.fract() == 0.0 && k.abs() <= POWI_MAX => Instr::Powi(ra, k as i32),
                    Some(k) => Instr::Powf(ra, k),
                    None => Instr::Pow(ra, self.node(b)),
                }
            }
            Node::Call(f, a) => Instr::Call(*f, self.node(a)),
            Node::Call2(f, a, b) => Instr::Call2(*f, self.node(a), self.node(b)),
        };
        let r = self.emit(ins);
        self.memo.insert(ptr, r);
        r
    }
}

impl Tape {
    /// Compiles `exprs` into one tape with one output per expression, in order.
    pub fn compile(exprs: &[Expr]) -> Tape {
        Tape::build(exprs.iter())
    }

    /// Compiles a sparse list of outputs: `len` outputs, entry k of `entries` = (index, e) the
    /// output `index` (indices distinct, below `len`), every other output 0. It evaluates to
    /// what [`Tape::compile`] of the dense list does, but stores and computes the listed
    /// entries only: a Jacobian with n² entries of which O(n) are nonzero compiles in O(n).
    ///
    /// Panics if an index is not below `len` or repeats (the model builds them, not a user).
    pub fn compile_sparse(len: usize, entries: &[(usize, Expr)]) -> Tape {
        let mut index: Vec<(usize, usize)> = entries
            .iter()
            .enumerate()
            .map(|(k, (i, _))| (*i, k))
            .collect();
        index.sort_unstable();
        assert!(
            index.windows(2).all(|w| w[0].0 < w[1].0) && index.last().is_none_or(|l| l.0 < len),
            "sparse tape outputs must be distinct and below {len}"
        );
        let mut tape = Tape::build(index.iter().map(|&(_, k)| &entries[k].1));
        tape.sparse = Some((len, index.iter().map(|&(i, _)| i as u32).collect()));
        tape
    }

    fn build<'a>(exprs: impl Iterator<Item = &'a Expr>) -> Tape {
        let mut b = Builder {
            code: Vec::new(),
            keys: FastMap::default(),
            memo: FastMap::default(),
            n_vars: 0,
        };
        let roots: Vec<u32> = exprs.map(|e| b.node(e)).collect();
        // sin(a) and cos(a) both present: one `sin_cos` (one libm call, and what a dual number's
        // sin or cos computes anyway) fills both registers. Mechanisms have both for every angle.
        let mut sin_of = FastMap::default();
        for (k, ins) in b.code.iter().enumerate() {
            if let Instr::Call(Func::Sin, a) = *ins {
                sin_of.insert(a, k);
            }
        }
        let mut cos_of_sin = FastMap::default();
        for (k, ins) in b.code.iter().enumerate() {
            if let Instr::Call(Func::Cos, a) = *ins
                && let Some(&s) = sin_of.get(&a)
            {
                cos_of_sin.insert(s, k);
                cos_of_sin.insert(k, s);
            }
        }
        // Lay the registers out: variables at their own index, constants after them, then the
        // operations' results in order (the builder emitted every operand before its use).
        let n_vars = b.n_vars;
        let n_consts = b
            .code
            .iter()
            .filter(|i| matches!(i, Instr::Const(_)))
            .count();
        let mut constants = Vec::with_capacity(n_consts);
        let mut code = Vec::with_capacity(b.code.len() - n_consts);
        let mut slot = vec![u32::MAX; b.code.len()];
        let mut next = (n_vars + n_consts) as u32;
        for (k, ins) in b.code.iter().enumerate() {
            if slot[k] != u32::MAX {
                // The second of a sin/cos pair, filled by the first.
                continue;
            }
            let at = |r: u32| slot[r as usize];
            let op = match *ins {
                Instr::Const(c) => {
                    slot[k] = (n_vars + constants.len()) as u32;
                    constants.push(c);
                    continue;
                }
                Instr::Var(i) => {
                    slot[k] = i;
                    continue;
                }
                Instr::Call(f @ (Func::Sin | Func::Cos), a) if cos_of_sin.contains_key(&k) => {
                    let other = cos_of_sin[&k];
                    let (sin, cos) = if f == Func::Sin {
                        (k, other)
                    } else {
                        (other, k)
                    };
                    code.push(Op::SinCos(at(a)));
                    slot[sin] = next;
                    slot[cos] = next + 1;
                    next += 2;
                    continue;
                }
                Instr::Neg(a) => Op::Neg(at(a)),
                Instr::Add(a, c) => Op::Add(at(a), at(c)),
                Instr::Sub(a, c) => Op::Sub(at(a), at(c)),
                Instr::Mul(a, c) => Op::Mul(at(a), at(c)),
                Instr::Div(a, c) => Op::Div(at(a), at(c)),
                Instr::Powi(a, k) => Op::Powi(at(a), k),
                Instr::Powf(a, k) => Op::Powf(at(a), k),
                Instr::Pow(a, c) => Op::Pow(at(a), at(c)),
                Instr::Call(f, a) => Op::Call(f, at(a)),
                Instr::Call2(f, a, c) => Op::Call2(f, at(a), at(c)),
            };
            slot[k] = next;
            next += 1;
            code.push(op);
        }
        Tape {
            constants,
            code,
            outputs: roots.iter().map(|&r| slot[r as usize]).collect(),
            sparse: None,
            n_vars,
            nodes: b.code.len(),
            registers: next as usize,
        }
    }

    /// Number of nodes of the compiled DAG: operations plus distinct constants and variables
    /// used.
    pub fn len(&self) -> usize {
        self.nodes
    }

    /// Whether the tape has no node (it has no output either).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Number of operations dispatched per evaluation (constants and variables are copied in).
    pub fn operations(&self) -> usize {
        self.code.len()
    }

    /// Number of outputs.
    pub fn outputs(&self) -> usize {
        self.sparse
            .as_ref()
            .map_or(self.outputs.len(), |(len, _)| *len)
    }

    /// Number of outputs [`Tape::eval_stored_into`] writes: the stored ones of a sparse tape,
    /// all of a dense one.
    pub fn stored(&self) -> usize {
        self.outputs.len()
    }

    /// The outputs a sparse tape ([`Tape::compile_sparse`]) computes, in increasing order (all
    /// others are 0); `None` for a dense tape. With [`Tape::eval_stored_into`], what a caller
    /// that keeps the matrix sparse reads.
    pub fn stored_outputs(&self) -> Option<&[u32]> {
        self.sparse.as_ref().map(|(_, index)| index.as_slice())
    }

    /// Evaluates the stored outputs only (all outputs of a dense tape; those of
    /// [`Tape::stored_outputs`] of a sparse one, in that order) into `out`.
    ///
    /// Panics if `out` is shorter than the stored outputs.
    pub fn eval_stored_into<T: Number>(&self, vars: &[T], scratch: &mut Vec<T>, out: &mut [T]) {
        assert!(
            out.len() >= self.outputs.len(),
            "tape stores {} outputs, got room for {}",
            self.outputs.len(),
            out.len()
        );
        self.run(vars, scratch);
        for (o, &r) in out.iter_mut().zip(&self.outputs) {
            *o = scratch[r as usize];
        }
    }

    /// The length a variable vector must have at least (1 + the largest variable index used).
    pub fn variables(&self) -> usize {
        self.n_vars
    }

    /// Evaluates every output at `vars` into `out` (one entry per output). `scratch` holds the
    /// registers: pass the same vector on every call and it allocates only the first time.
    ///
    /// Panics if `vars` is shorter than [`Tape::variables`] or `out` than [`Tape::outputs`]
    /// (sizes fixed by the model, not by user input).
    pub fn eval_into<T: Number>(&self, vars: &[T], scratch: &mut Vec<T>, out: &mut [T]) {
        assert!(
            out.len() >= self.outputs(),
            "tape has {} outputs, got room for {}",
            self.outputs(),
            out.len()
        );
        self.run(vars, scratch);
        match &self.sparse {
            None => {
                for (o, &r) in out.iter_mut().zip(&self.outputs) {
                    *o = scratch[r as usize];
                }
            }
            Some((len, index)) => {
                out[..*len].fill(T::zero());
                for (&i, &r) in index.iter().zip(&self.outputs) {
                    out[i as usize] = scratch[r as usize];
                }
            }
        }
    }

    /// Evaluates the tape's only (or first) output; see [`Tape::eval_into`].
    pub fn eval_one<T: Number>(&self, vars: &[T], scratch: &mut Vec<T>) -> T {
        self.run(vars, scratch);
        let first = match &self.sparse {
            Some((_, index)) if index.first() != Some(&0) => None,
            _ => self.outputs.first(),
        };
        first.map_or_else(T::zero, |&r| scratch[r as usize])
    }

    /// The first output at `vars`, allocating its registers: for one-off checks (validation at
    /// q₀); a time loop calls [`Tape::eval_into`] with a kept scratch vector.
    pub fn eval(&self, vars: &[f64]) -> f64 {
        self.eval_one(vars, &mut Vec::new())
    }

    fn run<T: Number>(&self, vars: &[T], r: &mut Vec<T>) {
        assert!(
            vars.len() >= self.n_vars,
            "tape needs {} variables, got {}",
            self.n_vars,
            vars.len()
        );
        r.clear();
        r.reserve(self.registers);
        r.extend_from_slice(&vars[..self.n_vars]);
        r.extend(self.constants.iter().map(|&c| T::from(c)));
        for op in &self.code {
            let v = match *op {
                Op::Neg(a) => -r[a as usize],
                Op::Add(a, b) => r[a as usize] + r[b as usize],
                Op::Sub(a, b) => r[a as usize] - r[b as usize],
                Op::Mul(a, b) => r[a as usize] * r[b as usize],
                Op::Div(a, b) => r[a as usize] / r[b as usize],
                Op::Powi(a, k) => r[a as usize].powi(k),
                Op::Powf(a, c) => r[a as usize].powf(c),
                Op::Pow(a, b) => pow(r[a as usize], r[b as usize]),
                Op::Call(f, a) => f.apply(r[a as usize]),
                Op::Call2(f, a, b) => f.apply(r[a as usize], r[b as usize]),
                Op::SinCos(a) => {
                    let (sin, cos) = r[a as usize].sin_cos();
                    r.push(sin);
                    cos
                }
            };
            r.push(v);
        }
    }
}

/// a^b with both varying: exp(b ln a) carries the derivatives of both where a > 0; elsewhere
/// `powf` with the exponent's value (f64::powf's value, (−2)^3 = −8; the derivative along the
/// exponent, ln a, does not exist there).
#[inline]
fn pow<T: Number>(a: T, b: T) -> T {
    if a.re() > 0.0 {
        a.powd(b)
    } else {
        a.powf(b.re())
    }
}
