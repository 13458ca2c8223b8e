//! `scene = "lagrangian"`: a nonlinear mechanical system the user writes as expressions over
//! their own generalized coordinates (the model language; [`crate::expr`] is its expression
//! language, [`LagrangianSpec::validate`] checks a model into the parameters
//! [`crate::lagrangian::UserModel`] compiles).

use super::SpecError;
use crate::band::SymBand;
use crate::expr::{Expr, Param, Scope, ScopeError};
use crate::lagrangian::{
    ContactParams, JOINT_TOLERANCE, SYMMETRY_TOLERANCE, StartProjection, Tangent, UserModelParams,
    project_start,
};
use nalgebra::DMatrix;
use schemars::JsonSchema;
use serde::de::{self, Deserializer, Visitor};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;

/// A number or an expression (an entry of the mass matrix, of the force vector, of q0 or v0).
#[derive(Debug, Clone, PartialEq, Serialize, JsonSchema)]
#[serde(untagged)]
pub enum Term {
    /// A number.
    Number(f64),
    /// An expression over the coordinates, velocities, `t` and the parameters.
    Expr(String),
}

/// Reads a number or a string, and names what it got otherwise ("invalid type: boolean `true`,
/// expected a number or an expression (a string)"), where an untagged enum would only say that
/// no variant matched.
impl<'de> Deserialize<'de> for Term {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Term, D::Error> {
        struct TermVisitor;
        impl Visitor<'_> for TermVisitor {
            type Value = Term;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a number or an expression (a string)")
            }
            fn visit_f64<E: de::Error>(self, x: f64) -> Result<Term, E> {
                Ok(Term::Number(x))
            }
            fn visit_i64<E: de::Error>(self, x: i64) -> Result<Term, E> {
                Ok(Term::Number(x as f64))
            }
            fn visit_u64<E: de::Error>(self, x: u64) -> Result<Term, E> {
                Ok(Term::Number(x as f64))
            }
            fn visit_str<E: de::Error>(self, s: &str) -> Result<Term, E> {
                Ok(Term::Expr(s.to_string()))
            }
        }
        deserializer.deserialize_any(TermVisitor)
    }
}

/// `scene = "lagrangian"`: Lagrange's equations M(q) q̈ + c(q, q̇) = −∇V(q, t) + f(t, q, q̇) +
/// g_qᵀλ + (contact impulses), with the Coriolis/centrifugal vector c = Ṁq̇ − ½∇_q(q̇ᵀMq̇)
/// derived by the program from M(q). Expressions use the coordinates, their velocities
/// `<name>_dot`, the time `t`, the parameters, numbers, `+ - * / ^`, parentheses and the
/// functions `sin cos tan asin acos atan atan2 sinh cosh tanh exp log sqrt abs min max pow`, the
/// constant `pi`. Joints run with `soi2_generalized_alpha`, `soi2_hht`, `hht_i3`; contacts,
/// joints or both with `moreau_jean` (friction without joints) and `ns_generalized_alpha`
/// (without friction).
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
    /// The mass matrix M(q), each entry a number or an expression of the coordinates and
    /// parameters (no velocities, no `t`); positive definite at q0. Dense: n rows of n entries
    /// (symmetric: the upper triangle is used, and each entry below the diagonal must equal its
    /// mirror at q0, relative 1e-12); or sparse: `{ diagonal = [...] }` (n entries) or
    /// `{ entries = [[i, j, term], ...] }` (the upper triangle i ≤ j, 0-based, each entry once;
    /// the rest is zero), whose cost grows with the entries given, not with n².
    pub mass: MassSpec,
    /// The potential energy V(q, t): the conservative forces are −∇V and V is part of the energy
    /// (0 when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub potential: Option<String>,
    /// The applied non-conservative generalized forces f(t, q, q̇), n entries (zero when absent);
    /// their work is `work_ext`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forces: Option<Vec<Term>>,
    /// Initial positions q(0), n entries: numbers, or expressions of the parameters
    /// (`"pi/3"`, `"L*sin(th0)"`), evaluated once at validation.
    pub q0: Vec<Term>,
    /// Initial velocities q̇(0), n entries like `q0` (zero when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub v0: Option<Vec<Term>>,
    /// Bilateral holonomic joints g(q, t) = 0, each `{ expr = "..." }`; each must hold at q0 to
    /// 1e-8 relative to ‖q0‖∞ (or `project_onto_joints`). Run by the SOI2 schemes,
    /// `moreau_jean` and `ns_generalized_alpha` (the last two with contacts too).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub constraints: Vec<JointSpec>,
    /// Move the start onto the joints instead of refusing it (default false): q0 to the point
    /// of g(q, 0) = 0 nearest in the M(q0) norm (radians and metres weighed by the inertia they
    /// move; to 1e-12 relative to ‖q0‖∞, at most 100 iterations; refused naming the joint when
    /// it does not converge), then v0 by the change of least kinetic energy onto
    /// g_q v + g_t = 0. The projected values are reported (`start_projection` in the summary).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub project_onto_joints: bool,
    /// The joints are dependent on purpose (default false): redundant at every configuration,
    /// like Bricard's mechanism (Grübler's count says 0 degrees of freedom, the mobility is 1).
    /// Validation then accepts a rank-deficient g_q at q0 (otherwise refused naming
    /// `model.constraints`, to catch a joint written twice), and the SOI2 schemes and
    /// `ns_generalized_alpha` solve for the minimum-norm multipliers (`rank_deficient_steps` in
    /// the summary); `moreau_jean` refuses it.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub redundant_joints: bool,
    /// Unilateral contacts, each `{ gap = "...", restitution = e }`: gap(q, t) ≥ 0 with Newton's
    /// impact law, e ∈ [0, 1] (default 0); `friction` μ with its `tangent` (planar Coulomb
    /// friction). Run by `moreau_jean` and `ns_generalized_alpha`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub contacts: Vec<UserContactSpec>,
}

/// The mass matrix of a `lagrangian` model: dense rows, or sparse (a diagonal, or the entries of
/// the upper triangle).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged, deny_unknown_fields)]
pub enum MassSpec {
    /// n rows of n entries, symmetric.
    Dense(Vec<Vec<Term>>),
    /// `{ diagonal = [...] }`: n diagonal entries, zero elsewhere.
    Diagonal {
        /// M_ii, one per coordinate.
        diagonal: Vec<Term>,
    },
    /// `{ entries = [[i, j, term], ...] }`: entries of the upper triangle (0-based i ≤ j, each
    /// once), mirrored below the diagonal; zero elsewhere.
    Entries {
        /// `[i, j, term]` triples.
        entries: Vec<(usize, usize, Term)>,
    },
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
    /// Coulomb friction coefficient μ ≥ 0 (default 0: frictionless); μ > 0 needs `tangent` or
    /// `tangent_velocity`.
    /// The step then solves the planar friction problem (`contact_solver.kind`: lemke on the
    /// LCP reformulation, pgs the nonsmooth Gauss–Seidel, auto the Gauss–Seidel first with Lemke
    /// when it does not converge). Taken by
    /// `moreau_jean`; `ns_generalized_alpha` refuses μ > 0 (its impact law is frictionless).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0))]
    pub friction: Option<f64>,
    /// The tangential relative position τ(q, t) (no velocities); its gradient is the tangent
    /// direction, and U_t = ∇τ·q̇ + ∂τ/∂t the tangential velocity that friction opposes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tangent: Option<String>,
    /// In place of `tangent`: the tangential velocity U_t(q, q̇, t) itself, linear in the
    /// velocities (checked: its derivatives by the velocities may not use them); its coefficients
    /// are the tangent row. For a tangent that is not the gradient of any τ(q, t), e.g. the
    /// sliding velocity of a disk rolling on a curved floor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tangent_velocity: Option<String>,
}

// ---------------------------------------------------------------------------------------------
// Validation: spec → UserModelParams

/// What an expression may depend on.
#[derive(Clone, Copy, PartialEq)]
enum Allowed {
    /// q only: M(q).
    Positions,
    /// q and t: V, joints, gaps, tangents.
    PositionsAndTime,
    /// q, q̇ and t: applied forces.
    Everything,
}

fn scope_error(e: ScopeError) -> SpecError {
    let field = match &e {
        ScopeError::BadName { kind, name } | ScopeError::Clash { kind, name, .. }
            if *kind == "parameter" =>
        {
            format!("model.parameters.{name}")
        }
        ScopeError::BadName { .. } | ScopeError::Clash { .. } => "model.coordinates".to_string(),
        _ => format!("model.parameters.{}", e.name()),
    };
    SpecError::new(field, e.to_string())
}

/// The values of a start vector (`model.q0`, `model.v0`): n entries, each a number or an
/// expression of the parameters alone, finite; every error names its entry.
fn start_vector(scope: &Scope, field: &str, v: &[Term], n: usize) -> Result<Vec<f64>, SpecError> {
    if v.len() != n {
        return Err(SpecError::new(
            field,
            format!("needs {n} entries (one per coordinate), got {}", v.len()),
        ));
    }
    v.iter()
        .enumerate()
        .map(|(i, term)| {
            let entry = format!("{field}[{i}]");
            let x = match term {
                Term::Number(x) => *x,
                Term::Expr(src) => {
                    let e = Expr::parse(src, scope)
                        .map_err(|e| SpecError::new(&entry, e.to_string()))?;
                    if let Some(&v) = e.variables().first() {
                        return Err(SpecError::new(
                            entry,
                            format!(
                                "uses '{}': a start value is a number or an expression of the parameters",
                                scope.variables()[v]
                            ),
                        ));
                    }
                    e.eval(&[])
                }
            };
            if !x.is_finite() {
                return Err(SpecError::new(entry, format!("must be finite, got {x}")));
            }
            Ok(x)
        })
        .collect()
}

/// Parses expressions in the model's scope and checks them at (q0, v0, 0).
struct Parser<'a> {
    scope: &'a Scope,
    n: usize,
    at_start: Vec<f64>,
}

impl<'a> Parser<'a> {
    /// Checks at (q0, v0, t = 0).
    fn at(scope: &'a Scope, q0: &[f64], v0: &[f64]) -> Parser<'a> {
        let mut at_start = q0.to_vec();
        at_start.extend_from_slice(v0);
        at_start.push(0.0);
        Parser {
            scope,
            n: q0.len(),
            at_start,
        }
    }

    fn parse(&self, field: &str, src: &str, allowed: Allowed) -> Result<Expr, SpecError> {
        let e = Expr::parse(src, self.scope).map_err(|e| SpecError::new(field, e.to_string()))?;
        self.check(field, e, allowed)
    }

    fn term(&self, field: &str, term: &Term, allowed: Allowed) -> Result<Expr, SpecError> {
        match term {
            Term::Number(c) => self.check(field, Expr::constant(*c), allowed),
            Term::Expr(src) => self.parse(field, src, allowed),
        }
    }

    fn check(&self, field: &str, e: Expr, allowed: Allowed) -> Result<Expr, SpecError> {
        let n = self.n;
        let names = self.scope.variables();
        for v in e.variables() {
            if (n..2 * n).contains(&v) && allowed != Allowed::Everything {
                return Err(SpecError::new(
                    field,
                    format!(
                        "uses the velocity '{}': only `forces` may depend on velocities",
                        names[v]
                    ),
                ));
            }
            if v == 2 * n && allowed == Allowed::Positions {
                return Err(SpecError::new(
                    field,
                    "uses the time t: the mass matrix M(q) depends on the coordinates only",
                ));
            }
        }
        let value = e.eval(&self.at_start);
        if !value.is_finite() {
            return Err(SpecError::new(
                field,
                format!(
                    "is {value} at q0 (with v0 and t = 0): every expression must be finite there"
                ),
            ));
        }
        Ok(e)
    }
}

/// The upper-triangle entries (i ≤ j, expression) of M from any of the spec's three forms,
/// parsed and checked (sizes, indices, and for the dense form the symmetry of the entries below
/// the diagonal at q0); every error names its field. Entries that are the constant 0 are left
/// out.
fn mass_entries(
    p: &Parser<'_>,
    spec: &MassSpec,
    n: usize,
) -> Result<Vec<(usize, usize, Expr)>, SpecError> {
    let mut upper = Vec::new();
    match spec {
        MassSpec::Dense(rows) => {
            if rows.len() != n {
                return Err(SpecError::new(
                    "model.mass",
                    format!("needs {n} rows (one per coordinate), got {}", rows.len()),
                ));
            }
            let mut entries = Vec::with_capacity(n * n);
            for (i, row) in rows.iter().enumerate() {
                if row.len() != n {
                    return Err(SpecError::new(
                        format!("model.mass[{i}]"),
                        format!("needs {n} entries (one per coordinate), got {}", row.len()),
                    ));
                }
                for (j, term) in row.iter().enumerate() {
                    entries.push(p.term(
                        &format!("model.mass[{i}][{j}]"),
                        term,
                        Allowed::Positions,
                    )?);
                }
            }
            for i in 0..n {
                for j in 0..i {
                    let (lower, upper) = (&entries[i * n + j], &entries[j * n + i]);
                    if lower != upper {
                        let (a, b) = (lower.eval(&p.at_start), upper.eval(&p.at_start));
                        if (a - b).abs() > SYMMETRY_TOLERANCE * a.abs().max(b.abs()) {
                            return Err(SpecError::new(
                                format!("model.mass[{i}][{j}]"),
                                format!(
                                    "M is not symmetric: M[{i}][{j}] = {a} but M[{j}][{i}] = {b} at q0"
                                ),
                            ));
                        }
                    }
                }
            }
            for i in 0..n {
                for j in i..n {
                    let e = &entries[i * n + j];
                    if !e.is_zero() {
                        upper.push((i, j, e.clone()));
                    }
                }
            }
        }
        MassSpec::Diagonal { diagonal } => {
            if diagonal.len() != n {
                return Err(SpecError::new(
                    "model.mass.diagonal",
                    format!(
                        "needs {n} entries (one per coordinate), got {}",
                        diagonal.len()
                    ),
                ));
            }
            for (i, term) in diagonal.iter().enumerate() {
                let e = p.term(
                    &format!("model.mass.diagonal[{i}]"),
                    term,
                    Allowed::Positions,
                )?;
                if !e.is_zero() {
                    upper.push((i, i, e));
                }
            }
        }
        MassSpec::Entries { entries } => {
            let mut seen = std::collections::HashSet::with_capacity(entries.len());
            for (k, (i, j, term)) in entries.iter().enumerate() {
                let field = format!("model.mass.entries[{k}]");
                if !(i <= j && *j < n) {
                    return Err(SpecError::new(
                        field,
                        format!(
                            "[{i}, {j}] is not in the upper triangle of a {n}×{n} matrix (0-based, i ≤ j < {n})"
                        ),
                    ));
                }
                if !seen.insert((*i, *j)) {
                    return Err(SpecError::new(field, format!("[{i}, {j}] is given twice")));
                }
                let e = p.term(&field, term, Allowed::Positions)?;
                if !e.is_zero() {
                    upper.push((*i, *j, e));
                }
            }
            upper.sort_by_key(|(i, j, _)| (*i, *j));
        }
    }
    Ok(upper)
}

impl LagrangianSpec {
    /// Checks the model and parses its expressions into the parameters a
    /// [`UserModel`](crate::lagrangian::UserModel) is compiled from; every error names its spec
    /// field.
    ///
    /// Validation (errors name the spec field, e.g. `model.contacts[0].gap: unknown name 'hgh' at 0
    /// (did you mean 'hgt'?)`):
    /// * names: coordinates distinct identifiers, parameters without cycles or clashes
    ///   (`model.coordinates`, `model.parameters.<name>`); unknown names with a suggestion;
    /// * sizes against `coordinates`: `q0`, `v0`, the rows and columns of `mass`, `forces`;
    /// * `q0` and `v0` entries numbers or expressions of the parameters, finite
    ///   (`model.q0[i]`);
    /// * M(q) may use neither velocities nor `t`; V, joints, gaps and tangents no velocities;
    /// * every expression is finite at (q0, v0, t = 0);
    /// * M symmetric: the model uses the upper triangle, and every entry below the diagonal must
    ///   equal its mirror at q0 to [`SYMMETRY_TOLERANCE`] relative (so a typo in one of two mirrored
    ///   entries is caught; structurally equal expressions pass at once); M positive definite at q0
    ///   (Cholesky);
    /// * each joint holds at q0: |g_i(q0)| ≤ [`JOINT_TOLERANCE`] · ‖q0‖∞ (absolute when q0 = 0);
    ///   with `project_onto_joints`, q0 and v0 are first moved onto the joints
    ///   ([`project_start`]: q0 to the nearest point of the joints in the M(q0) norm, then v0
    ///   by the velocity change of least kinetic energy), refused naming
    ///   `model.constraints[i].expr` when the iteration does not get there (`model.mass` when M
    ///   is not positive definite at the given q0), and every later check is made at the
    ///   projected start;
    /// * each contact is open or closed at q0, not penetrated: gap(q0, 0) ≥ −[`JOINT_TOLERANCE`]
    ///   · ‖q0‖∞ (a start inside the obstacle is refused naming `model.contacts[i].gap`);
    /// * restitution in [0, 1]; friction μ finite and ≥ 0, and μ > 0 needs a `tangent` (the
    ///   tangential relative position τ(q, t), checked like a gap: no velocities, known names,
    ///   finite at q0); its gradient, the tangent row, is an exact symbolic derivative like the
    ///   gap's. Or a `tangent_velocity` U_t(q, q̇, t) in its place (not both), linear in the
    ///   velocities (each ∂U_t/∂q̇_i free of velocities and finite at q0): its coefficients are
    ///   the tangent row.
    pub fn validate(&self) -> Result<UserModelParams, SpecError> {
        let n = self.coordinates.len();
        if n == 0 {
            return Err(SpecError::new(
                "model.coordinates",
                "needs at least one coordinate",
            ));
        }
        let scope = self.scope()?;
        let (q0, v0) = self.start(&scope, n)?;
        let tolerance = start_tolerance(&q0);
        let joints = parse_joints(&Parser::at(&scope, &q0, &v0), &self.constraints)?;
        let projection = if self.project_onto_joints && !joints.is_empty() {
            // The metric of the projection: M checked at the given start first.
            let mass = mass_matrix(&Parser::at(&scope, &q0, &v0), &self.mass, n)?;
            Some(
                project_start(&joints, &mass, n, &q0, &v0, tolerance)
                    .map_err(|e| SpecError::new(e.field(), e.to_string()))?,
            )
        } else {
            None
        };
        let (q0, v0) = match &projection {
            Some(StartProjection { q0, v0, .. }) => (q0.clone(), v0.clone()),
            None => (q0, v0),
        };
        let p = Parser::at(&scope, &q0, &v0);
        let mass = mass_matrix(&p, &self.mass, n)?;
        let potential = match &self.potential {
            Some(src) => p.parse("model.potential", src, Allowed::PositionsAndTime)?,
            None => Expr::constant(0.0),
        };
        let applied = applied_forces(&p, self.forces.as_deref(), n)?;
        joints_hold(&p, &joints, tolerance)?;
        let contacts = self
            .contacts
            .iter()
            .enumerate()
            .map(|(i, c)| contact(&p, i, c, tolerance))
            .collect::<Result<_, _>>()?;
        Ok(UserModelParams {
            q0,
            v0,
            mass,
            potential,
            applied,
            joints,
            contacts,
            projection,
        })
    }

    /// The scope of every expression: the coordinates, their velocities, `t` and the
    /// parameters (`model.coordinates`, `model.parameters.<name>`).
    fn scope(&self) -> Result<Scope, SpecError> {
        let parameters: Vec<(String, Param)> = self
            .parameters
            .iter()
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect();
        Scope::lagrangian(&self.coordinates, &parameters).map_err(scope_error)
    }

    /// q(0) and q̇(0) (zero when `v0` is absent) as given, n finite entries each.
    fn start(&self, scope: &Scope, n: usize) -> Result<(Vec<f64>, Vec<f64>), SpecError> {
        let q0 = start_vector(scope, "model.q0", &self.q0, n)?;
        let v0 = match &self.v0 {
            Some(v0) => start_vector(scope, "model.v0", v0, n)?,
            None => vec![0.0; n],
        };
        Ok((q0, v0))
    }
}

/// The tolerance of the joints and gaps at q0: [`JOINT_TOLERANCE`] relative to ‖q0‖∞ (absolute
/// when q0 = 0).
fn start_tolerance(q0: &[f64]) -> f64 {
    let scale = q0.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    JOINT_TOLERANCE * if scale > 0.0 { scale } else { 1.0 }
}

/// M(q): the entries of its upper triangle (i ≤ j), checked positive definite at q0 by
/// Cholesky (`model.mass`, with the smallest eigenvalue when it is not). A banded M (the
/// half-bandwidth kd of its nonzeros at q0 below n/4) is factorised in its band, O(n·kd²) time
/// and O(n·kd) memory; a wider one densely.
fn mass_matrix(
    p: &Parser<'_>,
    spec: &MassSpec,
    n: usize,
) -> Result<Vec<(usize, usize, Expr)>, SpecError> {
    let upper = mass_entries(p, spec, n)?;
    let m0: Vec<(usize, usize, f64)> = upper
        .iter()
        .map(|(i, j, e)| (*i, *j, e.eval(&p.at_start)))
        .filter(|&(_, _, v)| v != 0.0)
        .collect();
    let kd = m0.iter().map(|&(i, j, _)| j - i).max().unwrap_or(0);
    if kd < n / 4 {
        let mut band = SymBand::zeros(n, kd);
        for &(i, j, v) in &m0 {
            band.set(j, i, v);
        }
        return match band.cholesky() {
            Ok(_) => Ok(upper),
            Err(_) => Err(not_positive_definite(&m0, n)),
        };
    }
    let dense = dense_mass(&m0, n);
    if dense.clone().cholesky().is_none() {
        return Err(not_positive_definite(&m0, n));
    }
    Ok(upper)
}

/// The dense M at q0 from its upper-triangle entries.
fn dense_mass(m0: &[(usize, usize, f64)], n: usize) -> DMatrix<f64> {
    let mut m = DMatrix::zeros(n, n);
    for &(i, j, v) in m0 {
        m[(i, j)] = v;
        m[(j, i)] = v;
    }
    m
}

/// Largest n for which the error message computes the smallest eigenvalue of M at q0 (a dense
/// symmetric eigensolver: O(n³) time, 8n² bytes).
const EIGENVALUE_REPORT_MAX: usize = 2000;

/// `model.mass` is not positive definite at q0: the error, with M's smallest eigenvalue at q0
/// when n ≤ [`EIGENVALUE_REPORT_MAX`].
fn not_positive_definite(m0: &[(usize, usize, f64)], n: usize) -> SpecError {
    if n <= EIGENVALUE_REPORT_MAX {
        let smallest = dense_mass(m0, n).symmetric_eigenvalues().min();
        return SpecError::new(
            "model.mass",
            format!("M is not positive definite at q0 (smallest eigenvalue {smallest:e})"),
        );
    }
    SpecError::new(
        "model.mass",
        format!(
            "M is not positive definite at q0 (its Cholesky factorisation breaks down; {n} coordinates, too many to compute its smallest eigenvalue)"
        ),
    )
}

/// The applied forces f(t, q, q̇), n entries (`model.forces[i]`); zero when absent.
fn applied_forces(
    p: &Parser<'_>,
    forces: Option<&[Term]>,
    n: usize,
) -> Result<Vec<Expr>, SpecError> {
    match forces {
        Some(f) if f.len() != n => Err(SpecError::new(
            "model.forces",
            format!("needs {n} entries (one per coordinate), got {}", f.len()),
        )),
        Some(f) => f
            .iter()
            .enumerate()
            .map(|(i, term)| p.term(&format!("model.forces[{i}]"), term, Allowed::Everything))
            .collect(),
        None => Ok(vec![Expr::constant(0.0); n]),
    }
}

/// The joints g(q, t), each parsed (`model.constraints[i].expr`).
fn parse_joints(p: &Parser<'_>, constraints: &[JointSpec]) -> Result<Vec<Expr>, SpecError> {
    constraints
        .iter()
        .enumerate()
        .map(|(i, j)| {
            p.parse(
                &format!("model.constraints[{i}].expr"),
                &j.expr,
                Allowed::PositionsAndTime,
            )
        })
        .collect()
}

/// Each joint holds at the start of `p` to `tolerance`.
fn joints_hold(p: &Parser<'_>, joints: &[Expr], tolerance: f64) -> Result<(), SpecError> {
    for (i, g) in joints.iter().enumerate() {
        let r = g.eval(&p.at_start);
        if r.abs() > tolerance {
            return Err(SpecError::new(
                format!("model.constraints[{i}].expr"),
                format!(
                    "the joint is violated at q0: g = {r:e}, tolerance {tolerance:e} ({JOINT_TOLERANCE:e} relative to max|q0|); set `model.project_onto_joints = true` to move q0 and v0 onto the joints"
                ),
            ));
        }
    }
    Ok(())
}

/// Contact `i`: its gap (not negative at q0 beyond `tolerance`), restitution, friction and
/// tangent, each error naming `model.contacts[i].<field>`.
fn contact(
    p: &Parser<'_>,
    i: usize,
    c: &UserContactSpec,
    tolerance: f64,
) -> Result<ContactParams, SpecError> {
    let field = |f: &str| format!("model.contacts[{i}].{f}");
    let gap = p.parse(&field("gap"), &c.gap, Allowed::PositionsAndTime)?;
    // A start inside the obstacle is refused: the impact law acts on velocities, so a
    // negative gap is never pushed back out and the run would go on inside the wall.
    let start = gap.eval(&p.at_start);
    if start < -tolerance {
        return Err(SpecError::new(
            field("gap"),
            format!(
                "the gap is {start:e} < 0 at q0 (t = 0): the model starts inside the obstacle; choose q0 with every gap ≥ 0 (tolerance {tolerance:e})"
            ),
        ));
    }
    if !(c.restitution.is_finite() && (0.0..=1.0).contains(&c.restitution)) {
        return Err(SpecError::new(
            field("restitution"),
            format!("must be in [0, 1], got {}", c.restitution),
        ));
    }
    let tangent = match (&c.tangent, &c.tangent_velocity) {
        (Some(_), Some(_)) => {
            return Err(SpecError::new(
                field("tangent_velocity"),
                "give either `tangent` (the tangential relative position τ(q, t)) or `tangent_velocity` (the tangential velocity, linear in the velocities), not both",
            ));
        }
        (Some(src), None) => Some(Tangent::Position(p.parse(
            &field("tangent"),
            src,
            Allowed::PositionsAndTime,
        )?)),
        (None, Some(src)) => Some(Tangent::Velocity(tangent_velocity(
            p,
            &field("tangent_velocity"),
            src,
        )?)),
        (None, None) => None,
    };
    let mu = c.friction.unwrap_or(0.0);
    if !(mu.is_finite() && mu >= 0.0) {
        return Err(SpecError::new(
            field("friction"),
            format!("must be a finite number ≥ 0, got {mu}"),
        ));
    }
    if mu > 0.0 && tangent.is_none() {
        return Err(SpecError::new(
            field("friction"),
            "a friction coefficient needs a `tangent` (the tangential relative position τ(q, t)) or a `tangent_velocity` (the tangential velocity, linear in the velocities); one of them is required when friction > 0",
        ));
    }
    Ok(ContactParams {
        gap,
        restitution: c.restitution,
        friction: mu,
        tangent,
    })
}

/// A tangential velocity U_t(q, q̇, t) (`model.contacts[i].tangent_velocity`): parsed, finite at
/// the start, using some velocity, and linear in the velocities: each ∂U_t/∂q̇_i (a coefficient
/// of the tangent row) depends on q and t only, and is finite at the start.
fn tangent_velocity(p: &Parser<'_>, field: &str, src: &str) -> Result<Expr, SpecError> {
    let u = p.parse(field, src, Allowed::Everything)?;
    let n = p.n;
    let names = p.scope.variables();
    let velocities: Vec<usize> = u
        .variables()
        .into_iter()
        .filter(|v| (n..2 * n).contains(v))
        .collect();
    if velocities.is_empty() {
        return Err(SpecError::new(
            field,
            "uses no velocity: write the tangential velocity of the contact point, linear in the velocities (e.g. \"x_dot + R*phi_dot\"), or a tangential position as `tangent`",
        ));
    }
    for v in velocities {
        let coefficient = u.derivative(v);
        if let Some(&w) = coefficient
            .variables()
            .iter()
            .find(|w| (n..2 * n).contains(*w))
        {
            return Err(SpecError::new(
                field,
                format!(
                    "is not linear in the velocities: its derivative by '{}' depends on '{}'",
                    names[v], names[w]
                ),
            ));
        }
        let value = coefficient.eval(&p.at_start);
        if !value.is_finite() {
            return Err(SpecError::new(
                field,
                format!(
                    "its coefficient of '{}' is {value} at q0 (t = 0): the tangent row must be finite there",
                    names[v]
                ),
            ));
        }
    }
    Ok(u)
}
