//! User models (`scene = "lagrangian"`): a validated model compiled, once, into a
//! [`UserModel`] that the integrators run.
//!
//! The equations are Lagrange's,
//!
//! ```text
//! M(q) q̈ + c(q, q̇) = −∇V(q, t) + f(t, q, q̇) + g_qᵀλ + (contact impulses),
//! c(q, q̇) = Ṁ(q) q̇ − ½ ∇_q(q̇ᵀ M(q) q̇),   Ṁ_ij = Σ_k ∂M_ij/∂q_k q̇_k,
//! ```
//!
//! with c derived symbolically from the mass matrix. Every expression is parsed once in one
//! [`Scope::lagrangian`](crate::expr::Scope::lagrangian) (variables q, q̇, t in that order); the smooth force
//! F = −∇V − c + f, its Jacobians ∂F/∂q and ∂F/∂q̇, the joint Jacobian g_q and velocity
//! g_q q̇ + g_t, the gap Jacobian and ∂g/∂t are exact symbolic derivatives compiled into
//! [`Tape`]s, evaluated over `f64` or over the dual numbers of the SOI2 Newton iterations.
//!
//! The spec is checked and parsed first, by
//! [`LagrangianSpec::validate`](crate::spec::LagrangianSpec::validate), into the
//! [`UserModelParams`] compiled here.

pub(crate) mod newton_terms;
pub mod projection;
mod state_terms;

pub use projection::{PROJECTION_ITERATIONS, ProjectionError, StartProjection, project_start};

use crate::expr::{Expr, Node, Number, Tape};
use crate::nonlinear::LagrangianSystem;
use crate::nonlinear::delassus::JointStructure;
use crate::soi2::sparsity::{Coupling, Pattern};
use crate::soi2::{ConstrainedModel, Dims, InitialValues, Scalar, StateTerms};
use crate::triplets::Triplets;
use newton_terms::{NewtonSources, NewtonTerms};
use state_terms::StateTape;
use std::sync::OnceLock;

/// Relative tolerance of the symmetry check of M at q0.
pub const SYMMETRY_TOLERANCE: f64 = 1e-12;

/// Relative tolerance (to ‖q0‖∞) of a joint residual at q0.
pub const JOINT_TOLERANCE: f64 = 1e-8;

/// A compiled user model: tapes of M, V, F and its Jacobians, f, the joints and the gaps, over
/// the variables (q, q̇, t).
#[derive(Debug, Clone, PartialEq)]
pub struct UserModel {
    n: usize,
    joints: usize,
    contacts: usize,
    q0: Vec<f64>,
    v0: Vec<f64>,
    restitution: Vec<f64>,
    /// Coulomb μ per contact (0 without friction).
    friction: Vec<f64>,
    /// M(q), n×n row-major, mirrored from the upper triangle.
    mass: Tape,
    /// V(q, t).
    potential: Tape,
    /// F = −∇V − c + f, n entries.
    forces: Tape,
    /// f, n entries.
    applied: Tape,
    /// c, n entries.
    coriolis: Tape,
    /// ∂F/∂q then ∂F/∂q̇, 2n² entries.
    force_jacobians: Tape,
    /// g(q, t), one per joint.
    joint: Tape,
    /// g_q, joints×n.
    joint_jacobian: Tape,
    /// g_q q̇ + g_t, one per joint.
    joint_rate: Tape,
    /// Gaps, one per contact.
    gaps: Tape,
    /// ∇_q gap, contacts×n.
    gap_jacobian: Tape,
    /// ∂gap/∂t, one per contact.
    gap_rates: Tape,
    /// The tangent rows T (∇_q τ, or the coefficients of q̇ in a tangential velocity),
    /// contacts×n (zero rows for contacts without a tangent).
    tangent_jacobian: Tape,
    /// The tangential velocity at rest (∂τ/∂t, or U_t at q̇ = 0), one per contact (zero
    /// without a tangent).
    tangent_rates: Tape,
    /// Which coordinates each equation of motion and each joint uses.
    coupling: Coupling,
    /// The structure of the joints' Delassus operator when M is block diagonal and it has a
    /// band ([`crate::nonlinear::delassus`]).
    joint_structure: Option<JointStructure>,
    /// The structure of Newton's matrix with one and with two coordinate and joint blocks
    /// (SOI2's systems), built at first use.
    patterns: Patterns,
    /// The expressions of M, G and G q̇ + g_t that the second-derivative terms of
    /// `ns_generalized_alpha`'s Newton matrix are derived from.
    newton_sources: NewtonSources,
    /// Those terms' tapes, built at first use ([`newton_terms`]).
    newton_terms: FirstUse<NewtonTerms>,
    /// F and g, which [`StateTape`] is compiled from with the joints' derivatives.
    state_sources: (Vec<Expr>, Vec<Expr>),
    /// The terms of an SOI2 step's residual on one tape, built at first use ([`state_terms`]).
    state_tape: FirstUse<StateTape>,
}

/// A value built at first use: a cache, so two models compare equal whether or not it is
/// filled.
#[derive(Debug, Clone)]
struct FirstUse<T>(OnceLock<T>);

impl<T> Default for FirstUse<T> {
    fn default() -> Self {
        FirstUse(OnceLock::new())
    }
}

impl<T> PartialEq for FirstUse<T> {
    fn eq(&self, _other: &Self) -> bool {
        true
    }
}

/// Newton patterns derived from [`UserModel::coupling`] at first use: a cache, so two models
/// compare equal whether or not it is filled.
#[derive(Debug, Clone, Default)]
struct Patterns([OnceLock<Pattern>; 2]);

impl PartialEq for Patterns {
    fn eq(&self, _other: &Self) -> bool {
        true
    }
}

/// A validated user model, what [`UserModel::new`] compiles: the expressions parsed over the
/// variables (q, q̇, t) of [`Scope::lagrangian`](crate::expr::Scope::lagrangian) and checked
/// (by [`LagrangianSpec::validate`](crate::spec::LagrangianSpec::validate)).
#[derive(Debug, Clone, PartialEq)]
pub struct UserModelParams {
    /// q(0), n entries.
    pub q0: Vec<f64>,
    /// q̇(0), n entries.
    pub v0: Vec<f64>,
    /// The nonzero entries (i ≤ j, M_ij) of the upper triangle of M(q), in row-major order.
    pub mass: Vec<(usize, usize, Expr)>,
    /// V(q, t).
    pub potential: Expr,
    /// f(t, q, q̇), n entries.
    pub applied: Vec<Expr>,
    /// g(q, t), one per joint.
    pub joints: Vec<Expr>,
    /// The contacts.
    pub contacts: Vec<ContactParams>,
    /// How q0 and v0 were moved onto the joints (`model.project_onto_joints`), for the
    /// summary; `None` when they were taken as given.
    pub projection: Option<StartProjection>,
}

/// One validated contact.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactParams {
    /// gap(q, t).
    pub gap: Expr,
    /// Restitution e ∈ [0, 1].
    pub restitution: f64,
    /// Coulomb μ ≥ 0 (0 without friction).
    pub friction: f64,
    /// The tangential direction when μ > 0 (or given).
    pub tangent: Option<Tangent>,
}

/// The tangential velocity of a contact, U_t = T(q, t) q̇ + b(q, t): its row T and its rest
/// value b.
#[derive(Debug, Clone, PartialEq)]
pub enum Tangent {
    /// A tangential relative position τ(q, t) (`tangent`): T = ∇_q τᵀ, b = ∂τ/∂t.
    Position(Expr),
    /// A tangential velocity written directly (`tangent_velocity`), linear in q̇ (checked at
    /// validation): T_i = ∂U_t/∂q̇_i, b = U_t at q̇ = 0. It need not be the derivative of any
    /// τ(q, t): a disk rolling on a curved floor has U_t = √(1 + f'²)(1 − (R + d)κ) ṡ + (R + d) φ̇
    /// in the floor's arc coordinate s, offset d and angle φ, whose row is not a gradient.
    Velocity(Expr),
}

impl Tangent {
    /// The row T (n entries over q, t) and the rest value b of the tangential velocity of a
    /// model with n coordinates (variables q, q̇, t as in
    /// [`Scope::lagrangian`](crate::expr::Scope::lagrangian)).
    pub fn row_and_rate(&self, n: usize) -> (Vec<Expr>, Expr) {
        let (entries, rate) = self.sparse_row_and_rate(n);
        let mut row = vec![Expr::constant(0.0); n];
        for (k, e) in entries {
            row[k] = e;
        }
        (row, rate)
    }

    /// [`Tangent::row_and_rate`] with the row as its nonzero entries (coordinate, T_k), in
    /// increasing order.
    pub fn sparse_row_and_rate(&self, n: usize) -> (Vec<(usize, Expr)>, Expr) {
        match self {
            Tangent::Position(tau) => (tau.sparse_gradient(0..n), tau.derivative(2 * n)),
            Tangent::Velocity(u) => (
                u.sparse_gradient(n..2 * n)
                    .into_iter()
                    .map(|(k, e)| (k - n, e))
                    .collect(),
                at_rest(u, n),
            ),
        }
    }
}

/// `e` with every velocity q̇_i (variables n..2n) replaced by 0.
fn at_rest(e: &Expr, n: usize) -> Expr {
    if e.variables_in(n..2 * n).next().is_none() {
        return e.clone();
    }
    let r = |a: &Expr| at_rest(a, n);
    match e.node() {
        Node::Const(_) => e.clone(),
        Node::Var(i) if (n..2 * n).contains(i) => Expr::constant(0.0),
        Node::Var(_) => e.clone(),
        Node::Neg(a) => -r(a),
        Node::Add(a, b) => r(a) + r(b),
        Node::Sub(a, b) => r(a) - r(b),
        Node::Mul(a, b) => r(a) * r(b),
        Node::Div(a, b) => r(a) / r(b),
        Node::Pow(a, b) => r(a).pow(r(b)),
        Node::Call(f, a) => r(a).apply(*f),
        Node::Call2(f, a, b) => r(a).apply2(*f, r(b)),
    }
}

/// The nonzero entries of M(q) by row: row i the pairs (j, index into the upper-triangle list
/// of the entry M_ij = M_ji), sorted by column; entries that are the constant 0 are left out,
/// and an entry given twice keeps its last expression (as a dense matrix written entry by
/// entry would).
fn mass_rows(upper: &[(usize, usize, Expr)], n: usize) -> Vec<Vec<(usize, usize)>> {
    let mut rows: Vec<Vec<(usize, usize)>> = vec![Vec::new(); n];
    for (k, (i, j, e)) in upper.iter().enumerate() {
        if e.is_zero() {
            continue;
        }
        rows[*i].push((*j, k));
        if i != j {
            rows[*j].push((*i, k));
        }
    }
    for row in &mut rows {
        row.sort_by_key(|&(j, _)| j);
        let mut kept: Vec<(usize, usize)> = Vec::with_capacity(row.len());
        for &(j, k) in row.iter() {
            match kept.last_mut() {
                Some(last) if last.0 == j => *last = (j, k),
                _ => kept.push((j, k)),
            }
        }
        *row = kept;
    }
    rows
}

/// The Coriolis/centrifugal vector c = Ṁq̇ − ½∇_q(q̇ᵀMq̇) of M(q) given by its nonzero entries
/// (`rows` of [`mass_rows`] over `upper`):
/// `c_i = Σ_j (Σ_k ∂M_ij/∂q_k q̇_k) q̇_j − ½ Σ_{j,k} ∂M_jk/∂q_i q̇_j q̇_k`. Only the nonzero
/// entries of M and the coordinates each one uses are visited, in the order of the dense sums
/// (j, then k ascending), so the expressions are those of the dense sums with their zero terms
/// folded away; a constant or diagonal-in-its-own-coordinate M costs O(n + nonzeros), not n³.
fn coriolis(upper: &[(usize, usize, Expr)], rows: &[Vec<(usize, usize)>], n: usize) -> Vec<Expr> {
    let vel = |k: usize| Expr::var(n + k);
    // For each entry of the upper triangle: the coordinates k it uses and ∂M_ij/∂q_k (once for
    // both M_ij and M_ji).
    let partials: Vec<Vec<(usize, Expr)>> = upper
        .iter()
        .map(|(_, _, e)| e.variables_in(0..n).map(|k| (k, e.derivative(k))).collect())
        .collect();
    // For each coordinate i: the entries (j, k, entry) of M that use q_i, in row-major order.
    let mut users: Vec<Vec<(usize, usize, usize)>> = vec![Vec::new(); n];
    for (j, row) in rows.iter().enumerate() {
        for &(k, entry) in row {
            for (i, _) in &partials[entry] {
                users[*i].push((j, k, entry));
            }
        }
    }
    (0..n)
        .map(|i| {
            let mdot_v: Expr = rows[i]
                .iter()
                .filter(|(_, entry)| !partials[*entry].is_empty())
                .map(|&(j, entry)| {
                    let mdot_ij: Expr = partials[entry]
                        .iter()
                        .map(|(k, d)| d.clone() * vel(*k))
                        .sum();
                    mdot_ij * vel(j)
                })
                .sum();
            let quadratic: Expr = users[i]
                .iter()
                .map(|&(j, k, entry)| {
                    let d = partials[entry]
                        .iter()
                        .find(|(k, _)| *k == i)
                        .map(|(_, d)| d.clone())
                        .unwrap_or_else(|| Expr::constant(0.0));
                    d * vel(j) * vel(k)
                })
                .sum();
            mdot_v - Expr::constant(0.5) * quadratic
        })
        .collect()
}

/// Which coordinates each equation uses: row i of the equations of motion the columns of the
/// nonzeros of row i of M (`rows` of [`mass_rows`] over `upper`), the coordinates (position or
/// velocity) of those entries and of the force `forces[i]`; each joint the coordinates of its
/// expression.
fn coupling_of(
    upper: &[(usize, usize, Expr)],
    rows: &[Vec<(usize, usize)>],
    forces: &[Expr],
    joints: &[Expr],
    n: usize,
) -> Coupling {
    let coordinates = |e: &Expr, into: &mut Vec<usize>| {
        into.extend(e.variables_in(0..2 * n).map(|v| v % n));
    };
    let motion = (0..n)
        .map(|i| {
            let mut row = Vec::new();
            for &(j, entry) in &rows[i] {
                row.push(j);
                coordinates(&upper[entry].2, &mut row);
            }
            coordinates(&forces[i], &mut row);
            row.sort_unstable();
            row.dedup();
            row
        })
        .collect();
    let joints = joints
        .iter()
        .map(|g| {
            let mut vars = Vec::new();
            coordinates(g, &mut vars);
            vars.sort_unstable();
            vars.dedup();
            vars
        })
        .collect();
    Coupling { motion, joints }
}

/// The rows of a matrix as the nonzero entries of a row-major `rows.len()`×`width` list: entry
/// (r, k) at r·width + k + `offset`.
fn flatten(rows: &[Vec<(usize, Expr)>], width: usize, offset: usize) -> Vec<(usize, Expr)> {
    rows.iter()
        .enumerate()
        .flat_map(|(r, row)| {
            row.iter()
                .map(move |(k, e)| (offset + r * width + k, e.clone()))
        })
        .collect()
}

impl UserModel {
    /// Compiles a validated model ([`LagrangianSpec::validate`](crate::spec::LagrangianSpec::validate)):
    /// the exact symbolic derivatives and their tapes.
    pub fn new(params: UserModelParams) -> UserModel {
        let UserModelParams {
            q0,
            v0,
            mass: upper,
            potential,
            applied,
            joints,
            contacts,
            projection: _,
        } = params;
        let n = q0.len();
        let nn = n * n;
        // Everything below is built from the nonzero entries and the variables each
        // expression depends on: no n×n loop, no derivative along a variable an expression
        // does not use (issue 27).
        let rows = mass_rows(&upper, n);
        let mass: Vec<(usize, Expr)> = rows
            .iter()
            .enumerate()
            .flat_map(|(i, row)| row.iter().map(move |&(j, k)| (i * n + j, k)))
            .map(|(at, k)| (at, upper[k].2.clone()))
            .collect();
        let (mut gaps, mut restitution, mut friction, mut tangents) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for c in contacts {
            gaps.push(c.gap);
            restitution.push(c.restitution);
            friction.push(c.friction);
            tangents.push(c.tangent);
        }
        // Exact derivatives, built symbolically.
        let coriolis = coriolis(&upper, &rows, n);
        let mut grad_v = vec![Expr::constant(0.0); n];
        for (k, d) in potential.sparse_gradient(0..n) {
            grad_v[k] = d;
        }
        let forces: Vec<Expr> = (0..n)
            .map(|i| applied[i].clone() - grad_v[i].clone() - coriolis[i].clone())
            .collect();
        drop(grad_v);
        let (dq, dv): (Vec<_>, Vec<_>) = forces
            .iter()
            .map(|f| {
                let dv = f.sparse_gradient(n..2 * n);
                let dv = dv.into_iter().map(|(k, e)| (k - n, e)).collect();
                (f.sparse_gradient(0..n), dv)
            })
            .unzip();
        let mut force_jacobians = flatten(&dq, n, 0);
        force_jacobians.extend(flatten(&dv, n, nn));
        drop((dq, dv));
        let joint_jacobian: Vec<Vec<(usize, Expr)>> =
            joints.iter().map(|g| g.sparse_gradient(0..n)).collect();
        // Velocities were refused above, so the time derivative exists.
        let joint_rate: Vec<Expr> = joints
            .iter()
            .map(|g| {
                g.time_derivative(n)
                    .unwrap_or_else(|| Expr::constant(f64::NAN))
            })
            .collect();
        let gap_jacobian: Vec<Vec<(usize, Expr)>> =
            gaps.iter().map(|g| g.sparse_gradient(0..n)).collect();
        let gap_rates: Vec<Expr> = gaps.iter().map(|g| g.derivative(2 * n)).collect();
        let (tangent_jacobian, tangent_rates): (Vec<Vec<(usize, Expr)>>, Vec<Expr>) = tangents
            .iter()
            .map(|t| match t {
                Some(t) => t.sparse_row_and_rate(n),
                None => (Vec::new(), Expr::constant(0.0)),
            })
            .unzip();
        let coupling = coupling_of(&upper, &rows, &forces, &joints, n);
        let mass_entries: Vec<(usize, usize)> = upper
            .iter()
            .filter(|(_, _, e)| !e.is_zero())
            .map(|&(i, j, _)| (i, j))
            .collect();
        let joint_structure = JointStructure::new(n, &mass_entries, &coupling.joints);
        UserModel {
            n,
            joints: joints.len(),
            contacts: gaps.len(),
            q0,
            v0,
            restitution,
            friction,
            mass: Tape::compile_sparse(nn, &mass),
            potential: potential.compile(),
            forces: Tape::compile(&forces),
            applied: Tape::compile(&applied),
            coriolis: Tape::compile(&coriolis),
            force_jacobians: Tape::compile_sparse(2 * nn, &force_jacobians),
            joint: Tape::compile(&joints),
            joint_jacobian: Tape::compile_sparse(joints.len() * n, &flatten(&joint_jacobian, n, 0)),
            joint_rate: Tape::compile(&joint_rate),
            gaps: Tape::compile(&gaps),
            gap_jacobian: Tape::compile_sparse(gaps.len() * n, &flatten(&gap_jacobian, n, 0)),
            gap_rates: Tape::compile(&gap_rates),
            tangent_jacobian: Tape::compile_sparse(
                tangents.len() * n,
                &flatten(&tangent_jacobian, n, 0),
            ),
            tangent_rates: Tape::compile(&tangent_rates),
            coupling,
            joint_structure,
            patterns: Patterns::default(),
            newton_sources: NewtonSources {
                mass,
                joint_jacobian,
                joint_rate,
            },
            newton_terms: FirstUse::default(),
            state_sources: (forces, joints),
            state_tape: FirstUse::default(),
        }
    }

    /// The second-derivative terms of `ns_generalized_alpha`'s Newton matrix, compiled at the
    /// first call.
    pub(crate) fn newton_terms(&self) -> &NewtonTerms {
        self.newton_terms
            .0
            .get_or_init(|| NewtonTerms::new(self.n, &self.newton_sources))
    }

    /// The terms of an SOI2 step's residual on one tape, compiled at the first call.
    fn state_tape(&self) -> &StateTape {
        self.state_tape.0.get_or_init(|| {
            let (forces, joints) = &self.state_sources;
            StateTape::new(self.n, forces, joints, &self.newton_sources)
        })
    }

    /// Which coordinates each equation of motion and each joint uses.
    pub fn coupling(&self) -> &Coupling {
        &self.coupling
    }

    /// The structure of the joints' Delassus operator, when M is block diagonal and the
    /// operator has a band that pays ([`crate::nonlinear::delassus`]).
    pub fn joint_structure(&self) -> Option<&JointStructure> {
        self.joint_structure.as_ref()
    }

    /// Number of joints (holonomic constraints).
    pub fn joints(&self) -> usize {
        self.joints
    }

    /// The Coriolis/centrifugal vector c(q, q̇) = Ṁq̇ − ½∇_q(q̇ᵀMq̇), n entries.
    pub fn coriolis(&self, q: &[f64], v: &[f64], out: &mut [f64]) {
        self.eval(&self.coriolis, 0.0, q, Some(v), out);
    }

    /// Evaluates `tape` at (q, v, t); v = 0 when `None` (the tape does not use it).
    fn eval<T: Number>(&self, tape: &Tape, t: T, q: &[T], v: Option<&[T]>, out: &mut [T]) {
        tape.eval_into(&self.variables(t, q, v), &mut Vec::new(), out);
    }

    /// The tapes' variables: q, then v (zeros when the tape takes no velocity), then t.
    fn variables<T: Number>(&self, t: T, q: &[T], v: Option<&[T]>) -> Vec<T> {
        let mut vars = Vec::with_capacity(2 * self.n + 1);
        vars.extend_from_slice(&q[..self.n]);
        match v {
            Some(v) => vars.extend_from_slice(&v[..self.n]),
            None => vars.resize(2 * self.n, T::zero()),
        }
        vars.push(t);
        vars
    }

    /// Calls `f(k, value)` for every output k the tape stores (its structural nonzeros, by
    /// flat row-major index; every output of a dense tape), evaluated at (q, v, t) and, for a
    /// tape with more variables after t ([`newton_terms`]), `w`.
    fn for_each_stored<T: Number>(
        &self,
        tape: &Tape,
        (t, q, v, w): (T, &[T], Option<&[T]>, &[T]),
        mut f: impl FnMut(usize, T),
    ) {
        let mut vars = self.variables(t, q, v);
        vars.extend_from_slice(w);
        let mut scratch = Vec::new();
        match tape.stored_outputs() {
            Some(index) => {
                let mut values = vec![T::zero(); index.len()];
                tape.eval_stored_into(&vars, &mut scratch, &mut values);
                for (&k, x) in index.iter().zip(values) {
                    f(k as usize, x);
                }
            }
            None => {
                let mut values = vec![T::zero(); tape.outputs()];
                tape.eval_into(&vars, &mut scratch, &mut values);
                for (k, x) in values.into_iter().enumerate() {
                    f(k, x);
                }
            }
        }
    }

    /// Calls `f(i, k, value)` for every entry (i, k) of M(q) (n×n) or G(q, t) (nb×n) that its
    /// tape stores (the structural nonzeros): the derivatives of M and G read these without a
    /// dense array, in any number type (dual numbers for their own derivatives).
    pub(crate) fn stored_entries<T: Number>(
        &self,
        which: StoredMatrix,
        t: T,
        q: &[T],
        mut f: impl FnMut(usize, usize, T),
    ) {
        let n = self.n;
        self.for_each_stored(self.stored_tape(which), (t, q, None, &[]), |k, x| {
            f(k / n, k % n, x)
        });
    }

    /// The tape of `which`.
    pub(crate) fn stored_tape(&self, which: StoredMatrix) -> &Tape {
        match which {
            StoredMatrix::Mass => &self.mass,
            StoredMatrix::JointJacobian => &self.joint_jacobian,
        }
    }
}

/// The matrices of a user model whose stored entries the derivatives of
/// [`crate::nonlinear::joints::JointedSystem`] read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum StoredMatrix {
    /// M(q), n×n.
    Mass,
    /// G(q, t) = ∂g/∂q, nb×n.
    JointJacobian,
}

/// Joints as holonomic constraints in the additive form f = F(t, y, z) − g_yᵀλ (§6 of Jay &
/// Negrut 2008), g_y and g_t + g_y z from their symbolic tapes.
impl ConstrainedModel for UserModel {
    fn dims(&self) -> Dims {
        Dims {
            n: self.n,
            holonomic: self.joints,
            nonholonomic: 0,
        }
    }

    /// `q_j, v_j`, as under `moreau_jean` and `ns_generalized_alpha`: one naming of a
    /// `lagrangian` model's state whatever the scheme.
    fn state_names(&self) -> (&'static str, &'static str) {
        ("q", "v")
    }

    fn mass<T: Scalar>(&self, t: T, y: &[T], m: &mut [T]) {
        self.eval(&self.mass, t, y, None, m);
    }

    /// The entries M's tape stores, in its (row-major) order, but for those zero at `y`.
    fn mass_entries_at(&self, t: f64, y: &[f64], out: &mut Vec<(usize, usize, f64)>) {
        self.stored_entries(StoredMatrix::Mass, t, y, |i, k, m| {
            if m != 0.0 {
                out.push((i, k, m));
            }
        });
    }

    fn force<T: Scalar>(&self, t: T, y: &[T], z: &[T], lambda: &[T], _psi: &[T], f: &mut [T]) {
        self.eval(&self.forces, t, y, Some(z), f);
        if self.joints > 0 {
            self.stored_entries(StoredMatrix::JointJacobian, t, y, |r, i, g| {
                f[i] -= g * lambda[r];
            });
        }
    }

    fn g<T: Scalar>(&self, t: T, y: &[T], out: &mut [T]) {
        self.eval(&self.joint, t, y, None, out);
    }

    /// One tape for all the terms ([`state_terms`]); a `lagrangian` model has no
    /// nonholonomic constraint, so ψ is empty.
    fn state_terms<T: Scalar>(
        &self,
        t: T,
        (y, z): (&[T], &[T]),
        multipliers: &[(&[T], &[T])],
        with_g_y: bool,
    ) -> StateTerms<T> {
        let lambdas: Vec<&[T]> = multipliers.iter().map(|&(lambda, _)| lambda).collect();
        self.state_tape()
            .eval(&self.variables(t, y, Some(z)), &lambdas, with_g_y)
    }

    fn g_y<T: Scalar>(&self, t: T, y: &[T], out: &mut [T]) {
        self.eval(&self.joint_jacobian, t, y, None, out);
    }

    fn g_y_entries<T: Scalar>(&self, t: T, y: &[T], out: &mut Vec<(usize, usize, T)>) {
        self.stored_entries(StoredMatrix::JointJacobian, t, y, |r, i, g| {
            out.push((r, i, g));
        });
    }

    fn g_dot<T: Scalar>(&self, t: T, y: &[T], z: &[T], out: &mut [T]) {
        self.eval(&self.joint_rate, t, y, Some(z), out);
    }

    fn additive(&self) -> bool {
        true
    }

    /// From the variables the expressions use ([`Coupling`]).
    fn newton_pattern(&self, blocks: usize) -> Option<&Pattern> {
        let cell = self.patterns.0.get(blocks.checked_sub(1)?)?;
        Some(cell.get_or_init(|| Pattern::new(&self.coupling, blocks)))
    }

    fn potential(&self, t: f64, y: &[f64]) -> f64 {
        let mut out = [0.0];
        self.eval(&self.potential, t, y, None, &mut out);
        out[0]
    }

    /// The applied forces f (their work is the SOI2 stream's `work_damping`).
    fn damping_force(&self, t: f64, y: &[f64], z: &[f64], out: &mut [f64]) {
        self.eval(&self.applied, t, y, Some(z), out);
    }

    fn initial(&self) -> InitialValues {
        InitialValues {
            t: 0.0,
            y: self.q0.clone(),
            z: self.v0.clone(),
            lambda: vec![0.0; self.joints],
            psi: Vec::new(),
        }
    }
}

impl LagrangianSystem for UserModel {
    fn dofs(&self) -> usize {
        self.n
    }

    fn contacts(&self) -> usize {
        self.contacts
    }

    fn initial(&self) -> (Vec<f64>, Vec<f64>) {
        (self.q0.clone(), self.v0.clone())
    }

    fn mass(&self, q: &[f64], out: &mut [f64]) {
        self.eval(&self.mass, 0.0, q, None, out);
    }

    fn forces(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
        self.eval(&self.forces, t, q, Some(v), out);
    }

    fn force_jacobians(&self, t: f64, q: &[f64], v: &[f64], dq: &mut [f64], dv: &mut [f64]) {
        let nn = self.n * self.n;
        let mut both = vec![0.0; 2 * nn];
        self.eval(&self.force_jacobians, t, q, Some(v), &mut both);
        dq[..nn].copy_from_slice(&both[..nn]);
        dv[..nn].copy_from_slice(&both[nn..]);
    }

    /// The entries the mass tape stores.
    fn mass_entries(&self, q: &[f64], out: &mut Triplets) {
        out.clear();
        out.reserve(self.mass.stored());
        self.stored_entries(StoredMatrix::Mass, 0.0, q, |i, k, x| out.push(i, k, x));
    }

    /// The entries the tape of ∂F/∂q then ∂F/∂v stores.
    fn force_jacobian_entries(
        &self,
        t: f64,
        q: &[f64],
        v: &[f64],
        dq: &mut Triplets,
        dv: &mut Triplets,
    ) {
        let n = self.n;
        dq.clear();
        dv.clear();
        dq.reserve(self.force_jacobians.stored());
        dv.reserve(self.force_jacobians.stored());
        self.for_each_stored(&self.force_jacobians, (t, q, Some(v), &[]), |k, x| {
            let (into, k) = if k < n * n {
                (&mut *dq, k)
            } else {
                (&mut *dv, k - n * n)
            };
            into.push(k / n, k % n, x);
        });
    }

    fn applied_forces(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
        self.eval(&self.applied, t, q, Some(v), out);
    }

    fn potential(&self, t: f64, q: &[f64]) -> f64 {
        ConstrainedModel::potential(self, t, q)
    }

    fn gaps(&self, t: f64, q: &[f64], out: &mut [f64]) {
        self.eval(&self.gaps, t, q, None, out);
    }

    fn gap_jacobian(&self, t: f64, q: &[f64], out: &mut [f64]) {
        self.eval(&self.gap_jacobian, t, q, None, out);
    }

    fn gap_rates(&self, t: f64, q: &[f64], out: &mut [f64]) {
        self.eval(&self.gap_rates, t, q, None, out);
    }

    fn restitution(&self, alpha: usize) -> f64 {
        self.restitution[alpha]
    }

    fn friction(&self, alpha: usize) -> f64 {
        self.friction[alpha]
    }

    fn tangent_jacobian(&self, t: f64, q: &[f64], out: &mut [f64]) {
        self.eval(&self.tangent_jacobian, t, q, None, out);
    }

    fn tangent_rates(&self, t: f64, q: &[f64], out: &mut [f64]) {
        self.eval(&self.tangent_rates, t, q, None, out);
    }
}
