//! User models (`scene = "lagrangian"`): a [`LagrangianSpec`] compiled, once, into a
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
//! [`Scope::lagrangian`] (variables q, q̇, t in that order); the smooth force
//! F = −∇V − c + f, its Jacobians ∂F/∂q and ∂F/∂q̇, the joint Jacobian g_q and velocity
//! g_q q̇ + g_t, the gap Jacobian and ∂g/∂t are exact symbolic derivatives compiled into
//! [`Tape`]s, evaluated over `f64` or over the dual numbers of the SOI2 Newton iterations.
//!
//! Validation (errors name the spec field, e.g. `model.contacts[0].gap: unknown name 'hgh' at 0
//! (did you mean 'hgt'?)`):
//! * names: coordinates distinct identifiers, parameters without cycles or clashes
//!   (`model.coordinates`, `model.parameters.<name>`); unknown names with a suggestion;
//! * sizes against `coordinates`: `q0`, `v0`, the rows and columns of `mass`, `forces`;
//! * M(q) may use neither velocities nor `t`; V, joints, gaps and tangents no velocities;
//! * every expression is finite at (q0, v0, t = 0);
//! * M symmetric: the model uses the upper triangle, and every entry below the diagonal must
//!   equal its mirror at q0 to [`SYMMETRY_TOLERANCE`] relative (so a typo in one of two mirrored
//!   entries is caught; structurally equal expressions pass at once); M positive definite at q0
//!   (Cholesky);
//! * each joint holds at q0: |g_i(q0)| ≤ [`JOINT_TOLERANCE`] · ‖q0‖∞ (absolute when q0 = 0);
//! * restitution in [0, 1]; friction μ finite and ≥ 0, and μ > 0 needs a `tangent` (the
//!   tangential relative position τ(q, t), checked like a gap: no velocities, known names,
//!   finite at q0); its gradient, the tangent row, is an exact symbolic derivative like the
//!   gap's.

use crate::expr::{Expr, Number, Param, Scope, ScopeError, Tape};
use crate::nonlinear::LagrangianSystem;
use crate::soi2::{ConstrainedModel, Dims, InitialValues, Scalar};
use crate::spec::{LagrangianSpec, SpecError, Term};
use nalgebra::DMatrix;

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
    /// ∇_q τ, contacts×n (zero rows for contacts without a tangent).
    tangent_jacobian: Tape,
    /// ∂τ/∂t, one per contact (zero without a tangent).
    tangent_rates: Tape,
}

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

/// Checks a vector's length against the coordinates and its entries' finiteness.
fn check_vector(field: &str, v: &[f64], n: usize) -> Result<(), SpecError> {
    if v.len() != n {
        return Err(SpecError::new(
            field,
            format!("needs {n} entries (one per coordinate), got {}", v.len()),
        ));
    }
    if let Some((i, x)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
        return Err(SpecError::new(
            format!("{field}[{i}]"),
            format!("must be finite, got {x}"),
        ));
    }
    Ok(())
}

/// Parses expressions in the model's scope and checks them at (q0, v0, 0).
struct Parser<'a> {
    scope: &'a Scope,
    n: usize,
    at_start: Vec<f64>,
}

impl Parser<'_> {
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

impl UserModel {
    /// Compiles and checks a user model; every error names its spec field.
    pub fn new(spec: &LagrangianSpec) -> Result<UserModel, SpecError> {
        let n = spec.coordinates.len();
        if n == 0 {
            return Err(SpecError::new(
                "model.coordinates",
                "needs at least one coordinate",
            ));
        }
        let parameters: Vec<(String, Param)> = spec
            .parameters
            .iter()
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect();
        let scope = Scope::lagrangian(&spec.coordinates, &parameters).map_err(scope_error)?;
        check_vector("model.q0", &spec.q0, n)?;
        let v0 = spec.v0.clone().unwrap_or_else(|| vec![0.0; n]);
        check_vector("model.v0", &v0, n)?;
        let mut at_start = spec.q0.clone();
        at_start.extend_from_slice(&v0);
        at_start.push(0.0);
        let p = Parser {
            scope: &scope,
            n,
            at_start,
        };

        // M(q): parse every entry, use the upper triangle, check the lower one against it.
        if spec.mass.len() != n {
            return Err(SpecError::new(
                "model.mass",
                format!(
                    "needs {n} rows (one per coordinate), got {}",
                    spec.mass.len()
                ),
            ));
        }
        let mut entries = Vec::with_capacity(n * n);
        for (i, row) in spec.mass.iter().enumerate() {
            if row.len() != n {
                return Err(SpecError::new(
                    format!("model.mass[{i}]"),
                    format!("needs {n} entries (one per coordinate), got {}", row.len()),
                ));
            }
            for (j, term) in row.iter().enumerate() {
                entries.push(p.term(&format!("model.mass[{i}][{j}]"), term, Allowed::Positions)?);
            }
        }
        let mut mass = entries.clone();
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
                mass[i * n + j] = upper.clone();
            }
        }
        let m0: Vec<f64> = mass.iter().map(|e| e.eval(&p.at_start)).collect();
        let m0 = DMatrix::from_row_slice(n, n, &m0);
        if m0.clone().cholesky().is_none() {
            let smallest = m0.symmetric_eigenvalues().min();
            return Err(SpecError::new(
                "model.mass",
                format!("M is not positive definite at q0 (smallest eigenvalue {smallest:e})"),
            ));
        }

        let potential = match &spec.potential {
            Some(src) => p.parse("model.potential", src, Allowed::PositionsAndTime)?,
            None => Expr::constant(0.0),
        };
        let applied: Vec<Expr> = match &spec.forces {
            Some(f) if f.len() != n => {
                return Err(SpecError::new(
                    "model.forces",
                    format!("needs {n} entries (one per coordinate), got {}", f.len()),
                ));
            }
            Some(f) => f
                .iter()
                .enumerate()
                .map(|(i, term)| p.term(&format!("model.forces[{i}]"), term, Allowed::Everything))
                .collect::<Result<_, _>>()?,
            None => vec![Expr::constant(0.0); n],
        };
        let joints: Vec<Expr> = spec
            .constraints
            .iter()
            .enumerate()
            .map(|(i, j)| {
                p.parse(
                    &format!("model.constraints[{i}].expr"),
                    &j.expr,
                    Allowed::PositionsAndTime,
                )
            })
            .collect::<Result<_, _>>()?;
        let scale = spec.q0.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        let tolerance = JOINT_TOLERANCE * if scale > 0.0 { scale } else { 1.0 };
        for (i, g) in joints.iter().enumerate() {
            let r = g.eval(&p.at_start);
            if r.abs() > tolerance {
                return Err(SpecError::new(
                    format!("model.constraints[{i}].expr"),
                    format!(
                        "the joint is violated at q0: g = {r:e}, tolerance {tolerance:e} ({JOINT_TOLERANCE:e} relative to max|q0|)"
                    ),
                ));
            }
        }
        let mut gaps = Vec::with_capacity(spec.contacts.len());
        let mut restitution = Vec::with_capacity(spec.contacts.len());
        let mut friction = Vec::with_capacity(spec.contacts.len());
        let mut tangents = Vec::with_capacity(spec.contacts.len());
        for (i, c) in spec.contacts.iter().enumerate() {
            let field = |f: &str| format!("model.contacts[{i}].{f}");
            gaps.push(p.parse(&field("gap"), &c.gap, Allowed::PositionsAndTime)?);
            if !(c.restitution.is_finite() && (0.0..=1.0).contains(&c.restitution)) {
                return Err(SpecError::new(
                    field("restitution"),
                    format!("must be in [0, 1], got {}", c.restitution),
                ));
            }
            restitution.push(c.restitution);
            let tangent = match &c.tangent {
                Some(src) => Some(p.parse(&field("tangent"), src, Allowed::PositionsAndTime)?),
                None => None,
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
                    "a friction coefficient needs a `tangent` (the tangential relative position; `tangent` is required when friction > 0)",
                ));
            }
            friction.push(mu);
            tangents.push(tangent);
        }

        // Exact derivatives, built symbolically.
        let q: Vec<usize> = (0..n).collect();
        let v: Vec<usize> = (n..2 * n).collect();
        let vel = |k: usize| Expr::var(n + k);
        // dm[k][i·n + j] = ∂M_ij/∂q_k.
        let dm: Vec<Vec<Expr>> = q
            .iter()
            .map(|&k| mass.iter().map(|e| e.derivative(k)).collect())
            .collect();
        let coriolis: Vec<Expr> = (0..n)
            .map(|i| {
                let mdot_v: Expr = (0..n)
                    .map(|j| {
                        let mdot_ij: Expr = (0..n).map(|k| dm[k][i * n + j].clone() * vel(k)).sum();
                        mdot_ij * vel(j)
                    })
                    .sum();
                let quadratic: Expr = (0..n)
                    .flat_map(|j| (0..n).map(move |k| (j, k)))
                    .map(|(j, k)| dm[i][j * n + k].clone() * vel(j) * vel(k))
                    .sum();
                mdot_v - Expr::constant(0.5) * quadratic
            })
            .collect();
        let grad_v = potential.gradient(&q);
        let forces: Vec<Expr> = (0..n)
            .map(|i| applied[i].clone() - grad_v[i].clone() - coriolis[i].clone())
            .collect();
        let mut force_jacobians: Vec<Expr> = forces.iter().flat_map(|f| f.gradient(&q)).collect();
        force_jacobians.extend(forces.iter().flat_map(|f| f.gradient(&v)));
        let joint_jacobian: Vec<Expr> = joints.iter().flat_map(|g| g.gradient(&q)).collect();
        // Velocities were refused above, so the time derivative exists.
        let joint_rate: Vec<Expr> = joints
            .iter()
            .map(|g| {
                g.time_derivative(n)
                    .unwrap_or_else(|| Expr::constant(f64::NAN))
            })
            .collect();
        let gap_jacobian: Vec<Expr> = gaps.iter().flat_map(|g| g.gradient(&q)).collect();
        let gap_rates: Vec<Expr> = gaps.iter().map(|g| g.derivative(2 * n)).collect();
        let tangent_jacobian: Vec<Expr> = tangents
            .iter()
            .flat_map(|t| match t {
                Some(t) => t.gradient(&q),
                None => vec![Expr::constant(0.0); n],
            })
            .collect();
        let tangent_rates: Vec<Expr> = tangents
            .iter()
            .map(|t| match t {
                Some(t) => t.derivative(2 * n),
                None => Expr::constant(0.0),
            })
            .collect();
        Ok(UserModel {
            n,
            joints: joints.len(),
            contacts: gaps.len(),
            q0: spec.q0.clone(),
            v0,
            restitution,
            friction,
            mass: Tape::compile(&mass),
            potential: potential.compile(),
            forces: Tape::compile(&forces),
            applied: Tape::compile(&applied),
            coriolis: Tape::compile(&coriolis),
            force_jacobians: Tape::compile(&force_jacobians),
            joint: Tape::compile(&joints),
            joint_jacobian: Tape::compile(&joint_jacobian),
            joint_rate: Tape::compile(&joint_rate),
            gaps: Tape::compile(&gaps),
            gap_jacobian: Tape::compile(&gap_jacobian),
            gap_rates: Tape::compile(&gap_rates),
            tangent_jacobian: Tape::compile(&tangent_jacobian),
            tangent_rates: Tape::compile(&tangent_rates),
        })
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
        let mut vars = Vec::with_capacity(2 * self.n + 1);
        vars.extend_from_slice(&q[..self.n]);
        match v {
            Some(v) => vars.extend_from_slice(&v[..self.n]),
            None => vars.resize(2 * self.n, T::zero()),
        }
        vars.push(t);
        tape.eval_into(&vars, &mut Vec::new(), out);
    }
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

    fn mass<T: Scalar>(&self, t: T, y: &[T], m: &mut [T]) {
        self.eval(&self.mass, t, y, None, m);
    }

    fn force<T: Scalar>(&self, t: T, y: &[T], z: &[T], lambda: &[T], _psi: &[T], f: &mut [T]) {
        self.eval(&self.forces, t, y, Some(z), f);
        if self.joints > 0 {
            let n = self.n;
            let mut gy = vec![T::zero(); self.joints * n];
            self.eval(&self.joint_jacobian, t, y, None, &mut gy);
            for (r, &l) in lambda.iter().enumerate() {
                for (fi, &g) in f.iter_mut().zip(&gy[r * n..(r + 1) * n]) {
                    *fi -= g * l;
                }
            }
        }
    }

    fn g<T: Scalar>(&self, t: T, y: &[T], out: &mut [T]) {
        self.eval(&self.joint, t, y, None, out);
    }

    fn g_y<T: Scalar>(&self, t: T, y: &[T], out: &mut [T]) {
        self.eval(&self.joint_jacobian, t, y, None, out);
    }

    fn g_dot<T: Scalar>(&self, t: T, y: &[T], z: &[T], out: &mut [T]) {
        self.eval(&self.joint_rate, t, y, Some(z), out);
    }

    fn additive(&self) -> bool {
        true
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
