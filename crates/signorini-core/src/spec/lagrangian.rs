//! `scene = "lagrangian"`: a nonlinear mechanical system the user writes as expressions over
//! their own generalized coordinates (the model language; [`crate::expr`] is its expression
//! language, [`crate::lagrangian`] compiles and checks it).

use crate::expr::Param;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// A number or an expression (an entry of the mass matrix or of the force vector).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
pub enum Term {
    /// A number.
    Number(f64),
    /// An expression over the coordinates, velocities, `t` and the parameters.
    Expr(String),
}

/// `scene = "lagrangian"`: Lagrange's equations M(q) q̈ + c(q, q̇) = −∇V(q, t) + f(t, q, q̇) +
/// g_qᵀλ + (contact impulses), with the Coriolis/centrifugal vector c = Ṁq̇ − ½∇_q(q̇ᵀMq̇)
/// derived by the program from M(q). Expressions use the coordinates, their velocities
/// `<name>_dot`, the time `t`, the parameters, numbers, `+ - * / ^`, parentheses and the
/// functions `sin cos tan asin acos atan atan2 sinh cosh tanh exp log sqrt abs min max pow`, the
/// constant `pi`. Joints run with `soi2_generalized_alpha`, `soi2_hht`, `hht_i3`; contacts with
/// `moreau_jean`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LagrangianSpec {
    /// The generalized coordinates q, by name (distinct identifiers); their velocities are named
    /// `<name>_dot` and the time `t`.
    pub coordinates: Vec<String>,
    /// Named constants usable in every expression: a number, or an expression of other parameters
    /// (`I = "m*L^2/3"`); no cycles, no name of a coordinate, velocity, `t`, `pi` or a function.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub parameters: BTreeMap<String, Param>,
    /// The mass matrix M(q): n rows of n entries, each a number or an expression of the
    /// coordinates and parameters (no velocities, no `t`). Symmetric: the upper triangle is used,
    /// and each entry below the diagonal must equal its mirror at q0 (relative 1e-12); positive
    /// definite at q0.
    pub mass: Vec<Vec<Term>>,
    /// The potential energy V(q, t): the conservative forces are −∇V and V is part of the energy
    /// (0 when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub potential: Option<String>,
    /// The applied non-conservative generalized forces f(t, q, q̇), n entries (zero when absent);
    /// their work is `work_ext`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forces: Option<Vec<Term>>,
    /// Initial positions q(0), n entries.
    pub q0: Vec<f64>,
    /// Initial velocities q̇(0), n entries (zero when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub v0: Option<Vec<f64>>,
    /// Bilateral holonomic joints g(q, t) = 0, each `{ expr = "..." }`; each must hold at q0 to
    /// 1e-8 relative to ‖q0‖∞. Run by the SOI2 schemes.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub constraints: Vec<JointSpec>,
    /// Unilateral contacts, each `{ gap = "...", restitution = e }`: gap(q, t) ≥ 0 with Newton's
    /// impact law, e ∈ [0, 1] (default 0); `friction` μ with its `tangent` (planar Coulomb
    /// friction). Run by `moreau_jean`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub contacts: Vec<UserContactSpec>,
}

/// One bilateral holonomic joint g(q, t) = 0.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct JointSpec {
    /// g(q, t): an expression of the coordinates, `t` and the parameters (no velocities).
    pub expr: String,
}

/// One unilateral contact: gap(q, t) ≥ 0, Newton's impact law with restitution e.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct UserContactSpec {
    /// The gap g(q, t) ≥ 0 (no velocities); its gradient is the contact normal in generalized
    /// coordinates.
    pub gap: String,
    /// Newton's restitution coefficient e ∈ [0, 1] (default 0: plastic impact).
    #[serde(default)]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub restitution: f64,
    /// Coulomb friction coefficient μ ≥ 0 (default 0: frictionless); μ > 0 needs `tangent`.
    /// The step then solves the planar friction problem (`contact_solver.kind`: lemke on the
    /// LCP reformulation, pgs the nonsmooth Gauss–Seidel, auto by size). Taken by
    /// `moreau_jean`; `ns_generalized_alpha` refuses μ > 0 (its impact law is frictionless).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0))]
    pub friction: Option<f64>,
    /// The tangential relative position τ(q, t) (no velocities); its gradient is the tangent
    /// direction, and U_t = ∇τ·q̇ + ∂τ/∂t the tangential velocity that friction opposes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tangent: Option<String>,
}
