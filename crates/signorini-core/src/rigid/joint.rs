//! Joints between two rigid bodies, or a body and the world (`[[model.joints]]`):
//! bilateral holonomic constraints φ(x, q) = 0 on the poses, their velocity rows (the Jacobian
//! J with J (v, Ω) = φ̇) and the projection of the poses back onto φ = 0 after a step.
//!
//! A joint has two sides s ∈ {0, 1}; a side is a free body (its anchor ρ_s and axis a_s in the
//! body frame) or the ground (`world`, or a fixed body: anchor and axis in the world frame,
//! constant). With p_s = x_s + R_s ρ_s the anchor point of side s in the world:
//!
//! ```text
//! spherical:  φ = p_1 − p_0 = 0                                          (3 rows, world axes d)
//! revolute:   φ = p_1 − p_0 = 0,   ψ_i = u·w_i = 0  (i = 1, 2)            (5 rows)
//! ```
//!
//! where u = R_0 a_0 is the hinge axis carried by side 0 and w_1, w_2 = R_1 b_i are two unit
//! vectors carried by side 1, perpendicular to the axis at t = 0: the revolute joint keeps the
//! anchors together and the axis of side 0 perpendicular to side 1's plane (w_1, w_2), so the only
//! relative motion left is the rotation about u.
//!
//! Velocity rows (derivatives along ẋ = v, ω = R Ω, the same (dᵀ, (Rᵀ(r × d))ᵀ) blocks as a
//! contact's in [`super::moreau_jean`]): for a world axis d and the arm r_s = R_s ρ_s,
//! `d·φ̇ = Σ_s σ_s (d·v_s + Ω_s·R_sᵀ(r_s × d))` with σ_0 = −1, σ_1 = +1; and with c_i = u × w_i,
//! `ψ̇_i = ω_0·c_i − ω_1·c_i = Ω_0·R_0ᵀc_i − Ω_1·R_1ᵀc_i`.
//!
//! **Projection.** After a step the poses are moved back onto φ = 0 by the mass-weighted
//! (Gauss–)Newton projection of Siconos' `MoreauJeanDirectProjectionOSI` (V. Acary, *Projected
//! event-capturing time-stepping schemes for nonsmooth mechanical systems with unilateral contact
//! and Coulomb's friction*, Comput. Methods Appl. Mech. Engrg. 256 (2013) 224–250,
//! doi:10.1016/j.cma.2012.12.012), velocities untouched:
//!
//! ```text
//! A = J M⁻¹ Jᵀ,   μ = −A⁺ φ,   (Δx, ΔΘ) = M⁻¹ Jᵀ μ,   x ← x + Δx,   q ← q ⊗ exp(ΔΘ)
//! ```
//!
//! repeated until max|φ| ≤ the tolerance, with M⁻¹ = diag(m⁻¹ 1, I⁻¹) per body (ΔΘ in the body
//! frame) and A⁺ the pseudo-inverse (minimum-norm multipliers when rows are redundant:
//! a rank-deficient J is not an error).

use super::body::BodyState;
use nalgebra::{DMatrix, DVector, Matrix3, UnitQuaternion, Vector3};

type V3 = Vector3<f64>;

/// Which relative motions a joint takes away.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// The anchor points coincide (3 rows): a ball joint.
    Spherical,
    /// Anchors coincide and the axis stays the axis (5 rows): a hinge.
    Revolute,
}

/// One side of a joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JointSide {
    /// A free body: its index, and the anchor in its body frame.
    Body {
        /// The body.
        body: usize,
        /// Anchor ρ in the body frame.
        anchor: [f64; 3],
    },
    /// The ground (the world, or a fixed body): the anchor in the world frame.
    Ground {
        /// Anchor in the world frame.
        anchor: [f64; 3],
    },
}

/// A validated joint.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// Its kind.
    pub kind: JointKind,
    /// The two sides (at least one a free body, two different bodies).
    pub sides: [JointSide; 2],
    /// Revolute: the axis a_0 in side 0's frame (body frame, or world for the ground), unit.
    pub axis: [f64; 3],
    /// Revolute: w_1, w_2 in side 1's frame, unit, perpendicular to the axis at t = 0.
    pub perpendicular: [[f64; 3]; 2],
}

/// One velocity row of a joint: per side, the body and its signed 1×6 row (columns v, Ω),
/// `None` for the ground.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointRow {
    /// Per side: the body and its row.
    pub sides: [Option<(usize, [f64; 6])>; 2],
}

impl JointRow {
    /// J_row (v, Ω) for twists indexed by body.
    pub fn velocity(&self, twist: &[(V3, V3)]) -> f64 {
        self.sides
            .iter()
            .flatten()
            .map(|(b, row)| {
                let (v, w) = &twist[*b];
                row[0] * v.x
                    + row[1] * v.y
                    + row[2] * v.z
                    + row[3] * w.x
                    + row[4] * w.y
                    + row[5] * w.z
            })
            .sum()
    }
}

fn v3(a: [f64; 3]) -> V3 {
    V3::from(a)
}

impl Joint {
    /// Rows of the joint: 3 (spherical) or 5 (revolute).
    pub fn rows(&self) -> usize {
        match self.kind {
            JointKind::Spherical => 3,
            JointKind::Revolute => 5,
        }
    }

    /// World anchor p_s and arm r_s = p_s − x_s (zero for the ground) of side s.
    fn anchor(&self, s: usize, state: &[BodyState]) -> (V3, V3) {
        match self.sides[s] {
            JointSide::Body { body, anchor } => {
                let b = &state[body];
                let arm = b.rotation() * v3(anchor);
                (v3(b.position) + arm, arm)
            }
            JointSide::Ground { anchor } => (v3(anchor), V3::zeros()),
        }
    }

    /// A direction carried by side s, from its frame to the world.
    fn carried(&self, s: usize, local: [f64; 3], state: &[BodyState]) -> V3 {
        match self.sides[s] {
            JointSide::Body { body, .. } => state[body].rotation() * v3(local),
            JointSide::Ground { .. } => v3(local),
        }
    }

    fn rotation(&self, s: usize, state: &[BodyState]) -> Option<(usize, UnitQuaternion<f64>)> {
        match self.sides[s] {
            JointSide::Body { body, .. } => Some((body, state[body].rotation())),
            JointSide::Ground { .. } => None,
        }
    }

    /// φ at the poses of `state` (module documentation), appended to `out`.
    pub fn residual(&self, state: &[BodyState], out: &mut Vec<f64>) {
        let (p0, _) = self.anchor(0, state);
        let (p1, _) = self.anchor(1, state);
        let d = p1 - p0;
        out.extend([d.x, d.y, d.z]);
        if self.kind == JointKind::Revolute {
            let u = self.carried(0, self.axis, state);
            for b in self.perpendicular {
                out.push(u.dot(&self.carried(1, b, state)));
            }
        }
    }

    /// The velocity rows at the poses of `state`, appended to `out`.
    pub fn jacobian(&self, state: &[BodyState], out: &mut Vec<JointRow>) {
        let arms = [self.anchor(0, state).1, self.anchor(1, state).1];
        let rotations = [self.rotation(0, state), self.rotation(1, state)];
        for d in [V3::x(), V3::y(), V3::z()] {
            let sides = [0, 1].map(|s| {
                let sign = if s == 0 { -1.0 } else { 1.0 };
                rotations[s].map(|(body, r)| {
                    let a = r.inverse() * arms[s].cross(&d);
                    (body, [d.x, d.y, d.z, a.x, a.y, a.z].map(|x| sign * x))
                })
            });
            out.push(JointRow { sides });
        }
        if self.kind == JointKind::Revolute {
            let u = self.carried(0, self.axis, state);
            for b in self.perpendicular {
                let c = u.cross(&self.carried(1, b, state));
                let sides = [0, 1].map(|s| {
                    let sign = if s == 0 { 1.0 } else { -1.0 };
                    rotations[s].map(|(body, r)| {
                        let a = r.inverse() * c;
                        (body, [0.0, 0.0, 0.0, sign * a.x, sign * a.y, sign * a.z])
                    })
                });
                out.push(JointRow { sides });
            }
        }
    }
}

/// The inverse mass of one body as a joint or contact problem sees it: m⁻¹ on v, a 3×3 matrix
/// on Ω.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseMass {
    /// m⁻¹.
    pub linear: f64,
    /// The inverse of the rotational (iteration) matrix.
    pub angular: Matrix3<f64>,
}

impl InverseMass {
    /// M⁻¹ rowᵀ of a 1×6 row: the twist it moves.
    pub fn twist(&self, row: &[f64; 6]) -> (V3, V3) {
        (
            self.linear * V3::new(row[0], row[1], row[2]),
            self.angular * V3::new(row[3], row[4], row[5]),
        )
    }
}

/// A = J M⁻¹ Jᵀ of the rows and its pseudo-inverse A⁺ (singular values below 1e-12 of the
/// largest dropped: minimum-norm multipliers for redundant rows).
pub fn joint_operator(rows: &[JointRow], inverse_mass: &[InverseMass]) -> DMatrix<f64> {
    let n = rows.len();
    let mut a = DMatrix::zeros(n, n);
    for (i, ri) in rows.iter().enumerate() {
        for (b, row_i) in ri.sides.iter().flatten() {
            let (lin, ang) = inverse_mass[*b].twist(row_i);
            for (j, rj) in rows.iter().enumerate() {
                for (c, row_j) in rj.sides.iter().flatten() {
                    if c == b {
                        a[(j, i)] += row_j[0] * lin.x
                            + row_j[1] * lin.y
                            + row_j[2] * lin.z
                            + row_j[3] * ang.x
                            + row_j[4] * ang.y
                            + row_j[5] * ang.z;
                    }
                }
            }
        }
    }
    let svd = a.svd(true, true);
    let largest: f64 = svd.singular_values.max();
    svd.pseudo_inverse(1e-12 * largest.max(f64::MIN_POSITIVE))
        .unwrap_or_else(|_| DMatrix::zeros(n, n))
}

/// Σ_j Jᵀ_j λ_j on each body: its linear and angular parts, added to `out` (indexed by body).
pub fn add_joint_impulse(rows: &[JointRow], lambda: &DVector<f64>, out: &mut [(V3, V3)]) {
    for (j, r) in rows.iter().enumerate() {
        for (b, row) in r.sides.iter().flatten() {
            out[*b].0 += lambda[j] * V3::new(row[0], row[1], row[2]);
            out[*b].1 += lambda[j] * V3::new(row[3], row[4], row[5]);
        }
    }
}

/// What a projection did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Projection {
    /// max|φ| over the joints' rows after it (m for anchors, dimensionless for axes).
    pub residual: f64,
    /// Newton iterates taken.
    pub iterations: usize,
}

/// max|φ| of every joint at the poses of `state`.
pub fn position_residual(joints: &[Joint], state: &[BodyState]) -> f64 {
    let mut phi = Vec::new();
    for j in joints {
        j.residual(state, &mut phi);
    }
    phi.iter().fold(0.0, |m, x| m.max(x.abs()))
}

/// Projects the poses of `state` onto φ = 0 (module documentation): at most `max_iterations`
/// iterates, stopping when max|φ| ≤ `tolerance` or when an iterate no longer decreases it.
/// `inverse_mass` holds diag(m⁻¹, I⁻¹) per body (unused entries of the ground's bodies).
pub fn project(
    joints: &[Joint],
    inverse_mass: &[InverseMass],
    state: &mut [BodyState],
    tolerance: f64,
    max_iterations: usize,
) -> Projection {
    let mut report = Projection {
        residual: position_residual(joints, state),
        iterations: 0,
    };
    let mut rows = Vec::new();
    let mut phi = Vec::new();
    while report.residual > tolerance && report.iterations < max_iterations {
        rows.clear();
        phi.clear();
        for j in joints {
            j.jacobian(state, &mut rows);
            j.residual(state, &mut phi);
        }
        let a_plus = joint_operator(&rows, inverse_mass);
        let mu = -(a_plus * DVector::from_vec(phi.clone()));
        let mut impulse = vec![(V3::zeros(), V3::zeros()); state.len()];
        add_joint_impulse(&rows, &mu, &mut impulse);
        let before: Vec<BodyState> = state.to_vec();
        for (b, (lin, ang)) in impulse.iter().enumerate() {
            if lin.amax() == 0.0 && ang.amax() == 0.0 {
                continue;
            }
            let m = &inverse_mass[b];
            let dx = m.linear * lin;
            let dtheta = m.angular * ang;
            let s = &mut state[b];
            s.position = [
                s.position[0] + dx.x,
                s.position[1] + dx.y,
                s.position[2] + dx.z,
            ];
            let q = s.rotation() * UnitQuaternion::from_scaled_axis(dtheta);
            let q = UnitQuaternion::new_normalize(q.into_inner());
            s.orientation = [q.w, q.i, q.j, q.k];
        }
        report.iterations += 1;
        let residual = position_residual(joints, state);
        if residual >= report.residual {
            state.copy_from_slice(&before);
            break;
        }
        report.residual = residual;
    }
    report
}
