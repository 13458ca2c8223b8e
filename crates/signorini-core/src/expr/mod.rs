//! The expression language of user models (`scene = "lagrangian"`): M(q), V(q, t),
//! f(t, q, q̇), joints g(q, t), contact gaps and tangents are written as expressions over the
//! coordinates, their velocities, the time and named parameters.
//!
//! Life of an expression:
//!
//! 1. [`Scope`] declares the names: the variables (for a Lagrangian model, [`Scope::lagrangian`]:
//!    the coordinates q, their velocities `<name>_dot`, the time `t`) and the parameters, which
//!    are constants (a number, or an expression of other parameters; cycles and names that clash
//!    with a variable, `pi` or a function are refused).
//! 2. [`Expr::parse`] parses once, at validation, into a tree whose parameters are already folded
//!    into constants. Errors ([`ExprError`]) carry the byte position and a message for the user
//!    (`unknown name 'hgh' at 0 (did you mean 'hgt'?)`); the caller prefixes the spec field.
//! 3. [`Expr::derivative`] differentiates symbolically (exact, any order), simplifying as it
//!    builds (`0·u`, `1·u`, `u + 0`, constant subtrees are folded).
//! 4. [`Tape::compile`] turns a list of expressions into one flat register tape; equal
//!    subexpressions are computed once (hash-consing), so a value, its gradient and its Hessian
//!    compiled together share their `sin`/`cos`. [`Tape::eval_into`] runs it with a reused
//!    scratch buffer (no allocation, no string handling per step) over `f64` or over any
//!    forward-mode dual number of `num-dual` ([`Number`]), so both symbolic and automatic
//!    derivatives are available from the same tape.
//!
//! ```
//! use signorini_core::expr::{Expr, Param, Scope, Tape};
//!
//! let coordinates = ["x", "y", "phi"].map(String::from);
//! let parameters = [("w", 0.2), ("hgt", 0.4)].map(|(n, v)| (n.to_string(), Param::Value(v)));
//! let scope = Scope::lagrangian(&coordinates, &parameters)?; // x, y, phi, x_dot, y_dot, phi_dot, t
//! let gap = Expr::parse("y - hgt/2*cos(phi) - w/2*sin(phi)", &scope)?;
//! let q = [0, 1, 2];
//! let mut outputs = vec![gap.clone()];
//! outputs.extend(gap.gradient(&q)); // exact ∇g
//! outputs.extend(gap.hessian(&q)); // exact H_g, row-major
//! let tape = Tape::compile(&outputs); // once, at validation
//! let (mut scratch, mut out) = (Vec::new(), vec![0.0f64; tape.outputs()]);
//! let vars = [0.0, 0.2, 0.0, 0.0, 0.0, 1.0, 0.0];
//! tape.eval_into(&vars, &mut scratch, &mut out); // every step, no allocation
//! assert!(out[0].abs() < 1e-15 && out[2] == 1.0 && out[3] == -0.1); // g, ∂g/∂y, ∂g/∂phi
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Grammar
//!
//! ```text
//! expr    := term (('+' | '-') term)*
//! term    := unary (('*' | '/') unary)*
//! unary   := ('-' | '+') unary | power
//! power   := primary ('^' unary)?              right-associative: 2^3^2 = 2^9
//! primary := number | name | name '(' expr (',' expr)* ')' | '(' expr ')'
//! number  := digits ['.' digits] [('e' | 'E') ['+' | '-'] digits]   or  '.' digits ...
//! name    := (letter | '_') (letter | digit | '_')*
//! ```
//!
//! `^` binds tighter than unary minus (`-x^2 = -(x^2)`) and its exponent may carry a sign
//! (`2^-1 = 0.5`). There is no implicit multiplication (`2x` is an error). Whitespace is free.
//!
//! Functions (argument count): `sin cos tan asin acos atan sinh cosh tanh exp log sqrt abs` (1),
//! `atan2 min max pow` (2); `log` is the natural logarithm, `atan2(y, x)` the angle of (x, y),
//! `pow(a, b) = a^b`. The constant `pi`. Angles are in radians.
//!
//! Derivatives of the nonsmooth functions: d|u| = sign(u) du, d min(a, b) = da where a < b, db
//! where b < a and the mean at a tie (likewise `max`). The simplifier folds `0·u` to 0 even where
//! u is not finite, as every computer algebra system does.

mod deps;
mod diff;
mod parse;
mod scope;
mod tape;

pub use scope::{Param, Scope, ScopeError};
pub use tape::Tape;

use num_dual::DualNum;
use std::fmt;
use std::sync::Arc;
use thiserror::Error;

/// A real scalar a tape evaluates over: `f64`, or a (nested) dual number of `num-dual` that carries
/// derivatives along (the same bound as the SOI2 model functions).
pub trait Number: DualNum<Primitive = f64> + Copy {}
impl<T: DualNum<Primitive = f64> + Copy> Number for T {}

/// Deepest expression tree accepted (nesting of parentheses and chains of operators). It keeps
/// the recursive parser, differentiation and compilation far from the stack's end.
pub const MAX_DEPTH: usize = 400;

/// A parse error, with the byte position (0-based) in the expression text. The message names no
/// spec field: the caller prefixes it (`model.potential: unknown name 'hgh' at 4`).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ExprError {
    /// Nothing but whitespace.
    #[error("expression is empty")]
    Empty,
    /// A character that starts no token.
    #[error("unexpected character '{ch}' at {pos}")]
    BadChar {
        /// The character.
        ch: char,
        /// Byte position.
        pos: usize,
    },
    /// A malformed or out-of-range number.
    #[error("invalid number '{text}' at {pos}")]
    BadNumber {
        /// The text of the number.
        text: String,
        /// Byte position.
        pos: usize,
    },
    /// A token where another was expected.
    #[error("unexpected '{found}' at {pos}{}", if *.missing_operator { " (missing operator?)" } else { "" })]
    Unexpected {
        /// The token's text.
        found: String,
        /// Byte position.
        pos: usize,
        /// An operand follows an operand (`2x`, `1 2`).
        missing_operator: bool,
    },
    /// The text ends where something was expected.
    #[error("unexpected end of expression (expected {expected})")]
    UnexpectedEnd {
        /// What was expected.
        expected: &'static str,
    },
    /// A `(` without its `)`.
    #[error("'(' at {pos} is never closed")]
    Unclosed {
        /// Byte position of the `(`.
        pos: usize,
    },
    /// A name that is no variable, parameter or constant.
    #[error("unknown name '{name}' at {pos}{}", did_you_mean(suggestion))]
    UnknownName {
        /// The name.
        name: String,
        /// Byte position.
        pos: usize,
        /// The closest known name, if one is close.
        suggestion: Option<String>,
    },
    /// A call of a name that is no function.
    #[error("unknown function '{name}' at {pos}{}", did_you_mean(suggestion))]
    UnknownFunction {
        /// The name.
        name: String,
        /// Byte position.
        pos: usize,
        /// The closest function name, if one is close.
        suggestion: Option<String>,
    },
    /// A function name used as a value.
    #[error("'{name}' at {pos} is a function: call it as {name}(...)")]
    FunctionWithoutCall {
        /// The function.
        name: String,
        /// Byte position.
        pos: usize,
    },
    /// A wrong number of arguments.
    #[error("{name} takes {expected} argument{}, got {got} (at {pos})", if *.expected == 1 { "" } else { "s" })]
    Arity {
        /// The function.
        name: &'static str,
        /// Its argument count.
        expected: usize,
        /// The count given.
        got: usize,
        /// Byte position of the name.
        pos: usize,
    },
    /// Nesting deeper than [`MAX_DEPTH`].
    #[error("expression nested too deeply at {pos} (more than {MAX_DEPTH} levels)")]
    TooDeep {
        /// Byte position.
        pos: usize,
    },
}

fn did_you_mean(s: &Option<String>) -> String {
    s.as_ref()
        .map(|s| format!(" (did you mean '{s}'?)"))
        .unwrap_or_default()
}

/// A function of one argument. [`Func::Sign`] only appears in derivatives (of `abs`, `min`,
/// `max`); a user cannot call it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[allow(missing_docs)]
pub enum Func {
    Sin,
    Cos,
    Tan,
    Asin,
    Acos,
    Atan,
    Sinh,
    Cosh,
    Tanh,
    Exp,
    Log,
    Sqrt,
    Abs,
    Sign,
}

/// A function of two arguments (`pow` is parsed as `^`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[allow(missing_docs)]
pub enum Func2 {
    Atan2,
    Min,
    Max,
}

impl Func {
    /// The name in the language.
    pub fn name(self) -> &'static str {
        match self {
            Func::Sin => "sin",
            Func::Cos => "cos",
            Func::Tan => "tan",
            Func::Asin => "asin",
            Func::Acos => "acos",
            Func::Atan => "atan",
            Func::Sinh => "sinh",
            Func::Cosh => "cosh",
            Func::Tanh => "tanh",
            Func::Exp => "exp",
            Func::Log => "log",
            Func::Sqrt => "sqrt",
            Func::Abs => "abs",
            Func::Sign => "sign",
        }
    }

    /// Value at `x` over any [`Number`].
    #[inline]
    pub fn apply<T: Number>(self, x: T) -> T {
        match self {
            Func::Sin => x.sin(),
            Func::Cos => x.cos(),
            Func::Tan => x.tan(),
            Func::Asin => x.asin(),
            Func::Acos => x.acos(),
            Func::Atan => x.atan(),
            Func::Sinh => x.sinh(),
            Func::Cosh => x.cosh(),
            Func::Tanh => x.tanh(),
            Func::Exp => x.exp(),
            Func::Log => x.ln(),
            Func::Sqrt => x.sqrt(),
            Func::Abs => x.abs(),
            Func::Sign => T::from(sign(x.re())),
        }
    }
}

impl Func2 {
    /// The name in the language.
    pub fn name(self) -> &'static str {
        match self {
            Func2::Atan2 => "atan2",
            Func2::Min => "min",
            Func2::Max => "max",
        }
    }

    /// Value at `(a, b)` over any [`Number`].
    #[inline]
    pub fn apply<T: Number>(self, a: T, b: T) -> T {
        match self {
            Func2::Atan2 => a.atan2(b),
            Func2::Min => {
                if b.re() < a.re() {
                    b
                } else {
                    a
                }
            }
            Func2::Max => {
                if b.re() > a.re() {
                    b
                } else {
                    a
                }
            }
        }
    }
}

/// sign(x) with sign(0) = 0 (not `f64::signum`, which gives 1 at +0).
fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// What a function name of the language denotes.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Builtin {
    One(Func),
    Two(Func2),
    Pow,
}

impl Builtin {
    fn arity(self) -> usize {
        match self {
            Builtin::One(_) => 1,
            Builtin::Two(_) | Builtin::Pow => 2,
        }
    }
}

/// The functions a user can call, by name.
pub(crate) const BUILTINS: [(&str, Builtin); 17] = [
    ("sin", Builtin::One(Func::Sin)),
    ("cos", Builtin::One(Func::Cos)),
    ("tan", Builtin::One(Func::Tan)),
    ("asin", Builtin::One(Func::Asin)),
    ("acos", Builtin::One(Func::Acos)),
    ("atan", Builtin::One(Func::Atan)),
    ("atan2", Builtin::Two(Func2::Atan2)),
    ("sinh", Builtin::One(Func::Sinh)),
    ("cosh", Builtin::One(Func::Cosh)),
    ("tanh", Builtin::One(Func::Tanh)),
    ("exp", Builtin::One(Func::Exp)),
    ("log", Builtin::One(Func::Log)),
    ("sqrt", Builtin::One(Func::Sqrt)),
    ("abs", Builtin::One(Func::Abs)),
    ("min", Builtin::Two(Func2::Min)),
    ("max", Builtin::Two(Func2::Max)),
    ("pow", Builtin::Pow),
];

/// The functions a user can call, with their argument counts (for capabilities and schemas).
pub fn functions() -> impl Iterator<Item = (&'static str, usize)> {
    BUILTINS.iter().map(|&(name, b)| (name, b.arity()))
}

/// The names no variable or parameter may take: the functions and the constant `pi`.
pub fn reserved_names() -> impl Iterator<Item = &'static str> {
    BUILTINS.iter().map(|&(name, _)| name).chain(["pi"])
}

/// One node of an expression tree. Variables are indices into the [`Scope`]'s variables.
#[derive(Debug, Clone, PartialEq)]
#[allow(missing_docs)]
pub enum Node {
    Const(f64),
    Var(usize),
    Neg(Expr),
    Add(Expr, Expr),
    Sub(Expr, Expr),
    Mul(Expr, Expr),
    Div(Expr, Expr),
    Pow(Expr, Expr),
    Call(Func, Expr),
    Call2(Func2, Expr, Expr),
}

/// An expression: an immutable tree with shared subtrees (cheap to clone; `Send + Sync`, so a
/// model that holds expressions can move between threads). Every node knows the variables it
/// depends on, so a derivative skips the subtrees without its variable.
#[derive(Clone)]
pub struct Expr(Arc<Inner>);

/// A node and its dependence set (a function of the node, computed once when it is built).
struct Inner {
    node: Node,
    deps: deps::Deps,
}

impl Expr {
    /// The expression of `node`, with its dependence set: the union of its operands'.
    pub(crate) fn from_node(node: Node) -> Expr {
        let deps = match &node {
            Node::Const(_) => deps::Deps::None,
            Node::Var(i) => deps::Deps::var(*i),
            Node::Neg(a) | Node::Call(_, a) => a.0.deps.clone(),
            Node::Add(a, b)
            | Node::Sub(a, b)
            | Node::Mul(a, b)
            | Node::Div(a, b)
            | Node::Pow(a, b)
            | Node::Call2(_, a, b) => deps::Deps::union(&a.0.deps, &b.0.deps),
        };
        Expr(Arc::new(Inner { node, deps }))
    }

    /// The address of the node, the key of memo tables over one DAG.
    pub(crate) fn address(&self) -> usize {
        Arc::as_ptr(&self.0) as usize
    }
}

/// Structural equality (the same tree), whatever the sharing.
impl PartialEq for Expr {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0) || self.0.node == other.0.node
    }
}

impl fmt::Debug for Expr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_tuple("Expr").field(&self.0.node).finish()
    }
}

impl Expr {
    /// Parses `src` with the names of `scope`; parameters are folded into constants.
    pub fn parse(src: &str, scope: &Scope) -> Result<Expr, ExprError> {
        parse::parse(src, scope)
    }

    /// The constant `c`.
    pub fn constant(c: f64) -> Expr {
        Expr::from_node(Node::Const(c))
    }

    /// The variable of index `i` in the scope.
    pub fn var(i: usize) -> Expr {
        Expr::from_node(Node::Var(i))
    }

    /// The root node.
    pub fn node(&self) -> &Node {
        &self.0.node
    }

    /// The value if the expression is a constant (after folding).
    pub fn as_constant(&self) -> Option<f64> {
        match self.0.node {
            Node::Const(c) => Some(c),
            _ => None,
        }
    }

    /// Whether the expression is the constant 0 (after folding).
    pub fn is_zero(&self) -> bool {
        self.as_constant() == Some(0.0)
    }

    /// The indices of the variables the expression depends on, sorted, without repeats
    /// (for checks such as "M(q) may not depend on velocities"). Kept in every node: no walk.
    pub fn variables(&self) -> Vec<usize> {
        self.0.deps.iter().map(|v| v as usize).collect()
    }

    /// Whether the expression depends on the variable of index `var` (a constant in it if not).
    pub fn depends_on(&self, var: usize) -> bool {
        u32::try_from(var).is_ok_and(|v| self.0.deps.contains(v))
    }

    /// The variables the expression depends on among `vars` (a range of variable indices), in
    /// increasing order.
    pub fn variables_in(&self, vars: std::ops::Range<usize>) -> impl Iterator<Item = usize> + '_ {
        self.0
            .deps
            .iter()
            .map(|v| v as usize)
            .filter(move |v| vars.contains(v))
    }

    /// Value at `vars` by walking the tree (slow: for checks and tests; a time loop compiles a
    /// [`Tape`]).
    pub fn eval(&self, vars: &[f64]) -> f64 {
        match self.node() {
            Node::Const(c) => *c,
            Node::Var(i) => vars[*i],
            Node::Neg(a) => -a.eval(vars),
            Node::Add(a, b) => a.eval(vars) + b.eval(vars),
            Node::Sub(a, b) => a.eval(vars) - b.eval(vars),
            Node::Mul(a, b) => a.eval(vars) * b.eval(vars),
            Node::Div(a, b) => a.eval(vars) / b.eval(vars),
            Node::Pow(a, b) => a.eval(vars).powf(b.eval(vars)),
            Node::Call(f, a) => f.apply(a.eval(vars)),
            Node::Call2(f, a, b) => f.apply(a.eval(vars), b.eval(vars)),
        }
    }

    /// ∂self/∂x_var, exact and simplified.
    pub fn derivative(&self, var: usize) -> Expr {
        diff::derivative(self, var)
    }

    /// The gradient with respect to `vars`, in that order.
    pub fn gradient(&self, vars: &[usize]) -> Vec<Expr> {
        vars.iter().map(|&v| self.derivative(v)).collect()
    }

    /// The structurally nonzero part of the gradient along the variables of `vars`: the pairs
    /// (variable, ∂self/∂variable) for the variables the expression depends on, in increasing
    /// order (derivatives that simplify to 0 left out). The cost grows with the variables
    /// present, not with the range: what a sparse Jacobian row is built from.
    pub fn sparse_gradient(&self, vars: std::ops::Range<usize>) -> Vec<(usize, Expr)> {
        self.variables_in(vars)
            .map(|v| (v, self.derivative(v)))
            .filter(|(_, d)| !d.is_zero())
            .collect()
    }

    /// The Hessian with respect to `vars`, row-major `vars.len()²` entries; each mixed derivative
    /// is computed once and mirrored.
    pub fn hessian(&self, vars: &[usize]) -> Vec<Expr> {
        let n = vars.len();
        let grad = self.gradient(vars);
        let mut h = vec![Expr::constant(0.0); n * n];
        for i in 0..n {
            for j in i..n {
                let d = grad[i].derivative(vars[j]);
                h[j * n + i] = d.clone();
                h[i * n + j] = d;
            }
        }
        h
    }

    /// The total time derivative along the motion, in the layout of [`Scope::lagrangian`] with
    /// `n` coordinates: ė = Σᵢ ∂e/∂qᵢ q̇ᵢ + ∂e/∂t (the velocity of a gap, g_q q̇ + g_t of a joint).
    /// `None` if the expression uses a velocity (its derivative would need accelerations).
    pub fn time_derivative(&self, n: usize) -> Option<Expr> {
        if self.variables_in(n..2 * n).next().is_some() {
            return None;
        }
        // Only the coordinates present: the other terms are 0·q̇_i, which the sum drops.
        let along: Expr = self
            .variables_in(0..n)
            .map(|i| self.derivative(i) * Expr::var(n + i))
            .sum();
        Some(along + self.derivative(2 * n))
    }

    /// A one-output [`Tape`].
    pub fn compile(&self) -> Tape {
        Tape::compile(std::slice::from_ref(self))
    }

    /// Number of nodes of the tree, shared subtrees counted each time they appear.
    pub fn tree_size(&self) -> usize {
        match self.node() {
            Node::Const(_) | Node::Var(_) => 1,
            Node::Neg(a) | Node::Call(_, a) => 1 + a.tree_size(),
            Node::Add(a, b)
            | Node::Sub(a, b)
            | Node::Mul(a, b)
            | Node::Div(a, b)
            | Node::Pow(a, b)
            | Node::Call2(_, a, b) => 1 + a.tree_size() + b.tree_size(),
        }
    }

    /// The expression as text, with the scope's variable names; parsing the text back gives the
    /// same values.
    pub fn display<'a>(&'a self, scope: &'a Scope) -> impl fmt::Display + 'a {
        Shown {
            e: self,
            names: scope.variables(),
        }
    }
}

struct Shown<'a> {
    e: &'a Expr,
    names: &'a [String],
}

/// Binding strength for printing: sums 1, products 2, unary minus 3, powers 4, atoms 5.
fn precedence(n: &Node) -> u8 {
    match n {
        Node::Add(..) | Node::Sub(..) => 1,
        Node::Mul(..) | Node::Div(..) => 2,
        Node::Neg(_) => 3,
        Node::Const(c) if *c < 0.0 || !c.is_finite() => 3,
        Node::Pow(..) => 4,
        _ => 5,
    }
}

impl Shown<'_> {
    fn write(&self, e: &Expr, min: u8, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = e.node();
        let paren = precedence(n) < min;
        if paren {
            f.write_str("(")?;
        }
        match n {
            Node::Const(c) if c.is_nan() => f.write_str("0/0")?,
            Node::Const(c) if c.is_infinite() => {
                f.write_str(if *c > 0.0 { "1/0" } else { "-1/0" })?
            }
            Node::Const(c) => write!(f, "{c:?}")?,
            Node::Var(i) => match self.names.get(*i) {
                Some(name) => f.write_str(name)?,
                None => write!(f, "var{i}")?,
            },
            Node::Neg(a) => {
                f.write_str("-")?;
                self.write(a, 3, f)?;
            }
            Node::Add(a, b) | Node::Sub(a, b) => {
                self.write(a, 1, f)?;
                f.write_str(if matches!(n, Node::Add(..)) {
                    " + "
                } else {
                    " - "
                })?;
                self.write(b, 2, f)?;
            }
            Node::Mul(a, b) | Node::Div(a, b) => {
                self.write(a, 2, f)?;
                f.write_str(if matches!(n, Node::Mul(..)) { "*" } else { "/" })?;
                self.write(b, 3, f)?;
            }
            Node::Pow(a, b) => {
                self.write(a, 5, f)?;
                f.write_str("^")?;
                self.write(b, 3, f)?;
            }
            Node::Call(func, a) => {
                write!(f, "{}(", func.name())?;
                self.write(a, 0, f)?;
                f.write_str(")")?;
            }
            Node::Call2(func, a, b) => {
                write!(f, "{}(", func.name())?;
                self.write(a, 0, f)?;
                f.write_str(", ")?;
                self.write(b, 0, f)?;
                f.write_str(")")?;
            }
        }
        if paren {
            f.write_str(")")?;
        }
        Ok(())
    }
}

impl fmt::Display for Shown<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.write(self.e, 0, f)
    }
}

/// Building expressions in code (the model layer composes, e.g., the Coriolis vector from the
/// mass matrix): the operators simplify as the parser does.
impl std::ops::Add for Expr {
    type Output = Expr;
    fn add(self, rhs: Expr) -> Expr {
        diff::add(self, rhs)
    }
}

impl std::ops::Sub for Expr {
    type Output = Expr;
    fn sub(self, rhs: Expr) -> Expr {
        diff::sub(self, rhs)
    }
}

impl std::ops::Mul for Expr {
    type Output = Expr;
    fn mul(self, rhs: Expr) -> Expr {
        diff::mul(self, rhs)
    }
}

impl std::ops::Div for Expr {
    type Output = Expr;
    fn div(self, rhs: Expr) -> Expr {
        diff::div(self, rhs)
    }
}

impl std::ops::Neg for Expr {
    type Output = Expr;
    fn neg(self) -> Expr {
        diff::neg(self)
    }
}

/// Left to right as written (`((a + b) + c) + …`) for up to 32 nonzero terms; a longer sum
/// is split into blocks of 32 terms, each folded so, and the blocks are added pairwise, as the
/// parser does with a long chain: its tree stays shallow (⌈log₂(terms/32)⌉ + 32 levels) and
/// building it costs time and memory linear in its terms.
impl std::iter::Sum for Expr {
    fn sum<I: Iterator<Item = Expr>>(iter: I) -> Expr {
        diff::sum(iter)
    }
}

impl Expr {
    /// self^exponent.
    pub fn pow(self, exponent: Expr) -> Expr {
        diff::pow(self, exponent)
    }

    /// f(self).
    pub fn apply(self, f: Func) -> Expr {
        diff::call(f, self)
    }

    /// f(self, other).
    pub fn apply2(self, f: Func2, other: Expr) -> Expr {
        diff::call2(f, self, other)
    }
}
