//! `scene = "rigid_bodies"`: bodies with a shape, mass and inertia, a pose and a
//! twist, fixed or free, under gravity, with the contact law of every pair. Validation
//! ([`RigidBodiesSpec::validate`]) builds the [`RigidScene`]; every error names its field
//! (`model.bodies[2].shape.radius`).

use super::SpecError;
use crate::rigid::{
    Body, BodyState, ContactLaw, Joint, JointKind, JointSide, RigidScene, Shape, tangent_basis,
};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// `[model]` of `scene = "rigid_bodies"`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RigidBodiesSpec {
    /// Gravity (world), default (0, 0, −9.81).
    #[serde(default = "default_gravity")]
    pub gravity: [f64; 3],
    /// The contact law of every pair, its overrides, and the detection margin.
    #[serde(default)]
    pub contact: RigidContactSpec,
    /// The bodies (at least one free).
    pub bodies: Vec<RigidBodySpec>,
    /// Joints between bodies or to `world`: `spherical` and `revolute` (`prismatic` and
    /// `fixed` are refused naming `model.joints[j].kind`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub joints: Vec<RigidJointSpec>,
}

fn default_gravity() -> [f64; 3] {
    [0.0, 0.0, -9.81]
}

/// `[model.contact]`: the defaults of every pair of bodies.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RigidContactSpec {
    /// Newton's restitution e ∈ [0, 1], default 0.
    #[serde(default)]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub restitution: f64,
    /// Coulomb's friction coefficient μ ≥ 0, default 0.
    #[serde(default)]
    #[schemars(range(min = 0.0))]
    pub friction: f64,
    /// Contact points of gap ≤ margin are detected, and enter the index set when their
    /// predicted gap g + γ h U_n is ≤ margin (≥ 0, default 1e-3 m). A body landing comes to rest
    /// at most about this far from what it lands on: take it small against the bodies' size,
    /// or set `integrator.activation = "predicted_gap"` (Siconos' rule: predicted gap ≤ 0, the
    /// margin only finding the candidates), with which bodies touch and an impact may leave up
    /// to ½ h |U_n| of penetration.
    #[serde(default = "default_margin")]
    #[schemars(range(min = 0.0))]
    pub margin: f64,
    /// Per-pair overrides.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pairs: Vec<RigidPairSpec>,
}

fn default_margin() -> f64 {
    1e-3
}

impl Default for RigidContactSpec {
    fn default() -> Self {
        Self {
            restitution: 0.0,
            friction: 0.0,
            margin: default_margin(),
            pairs: Vec::new(),
        }
    }
}

/// `[[model.contact.pairs]]`: the law of one pair of bodies.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RigidPairSpec {
    /// The two bodies' names.
    pub bodies: [String; 2],
    /// Restitution of the pair (default: `model.contact.restitution`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub restitution: Option<f64>,
    /// Friction coefficient of the pair (default: `model.contact.friction`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<f64>,
}

/// `[[model.bodies]]`: one body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RigidBodySpec {
    /// Unique name, the prefix of its columns (`NAME_x`, …).
    pub name: String,
    /// Its geometry in the body frame (origin at the centre of mass).
    pub shape: ShapeSpec,
    /// Density, from which mass and inertia follow (sphere, box, capsule, cylinder).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub density: Option<f64>,
    /// Mass (> 0); overrides `density`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<f64>,
    /// Principal moments of inertia [I_xx, I_yy, I_zz] in the body frame (each > 0); override
    /// `density`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inertia: Option<[f64; 3]>,
    /// Position of the centre of mass (world), default the origin.
    #[serde(default)]
    pub position: [f64; 3],
    /// Unit quaternion (w, x, y, z), body to world, default the identity.
    #[serde(default = "identity")]
    pub orientation: [f64; 4],
    /// Velocity of the centre of mass (world), default 0.
    #[serde(default)]
    pub velocity: [f64; 3],
    /// Angular velocity (world frame), default 0.
    #[serde(default)]
    pub angular_velocity: [f64; 3],
    /// A fixed body does not move (a `half_space` always is), default false.
    #[serde(default)]
    pub fixed: bool,
}

fn identity() -> [f64; 4] {
    [1.0, 0.0, 0.0, 0.0]
}

/// A body's shape; the axis of a capsule or cylinder is the body z axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeSpec {
    /// A ball.
    Sphere {
        /// Radius > 0.
        radius: f64,
    },
    /// A box.
    Box {
        /// Half extents along the body axes, each > 0.
        half_extents: [f64; 3],
    },
    /// A segment from z = −half_height to half_height swept by a ball of `radius`.
    Capsule {
        /// Radius > 0.
        radius: f64,
        /// Half length of the axis segment ≥ 0.
        half_height: f64,
    },
    /// A solid cylinder about the body z axis.
    Cylinder {
        /// Radius > 0.
        radius: f64,
        /// Half height > 0.
        half_height: f64,
    },
    /// The convex hull of points (body frame, centre of mass at the origin); needs `mass` and
    /// `inertia`.
    Convex {
        /// At least 4 points, not coplanar.
        points: Vec<[f64; 3]>,
    },
    /// The half-space on the inner side of the plane through the body's `position` with
    /// outward unit `normal` (body frame); always fixed.
    HalfSpace {
        /// Outward unit normal.
        normal: [f64; 3],
    },
}

/// `[[model.joints]]`: a bilateral joint between two bodies, or a body and `world` (a fixed
/// body counts as the ground).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RigidJointSpec {
    /// `spherical` (the anchor points of both bodies coincide) or `revolute` (and the axis
    /// stays a common axis: a hinge); `prismatic` and `fixed` are not implemented.
    pub kind: String,
    /// The two bodies (`world` for the ground), different.
    pub bodies: [String; 2],
    /// Anchor point (world frame at t = 0), required.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub anchor: Option<[f64; 3]>,
    /// Hinge axis (world frame at t = 0, unit): required by `revolute`, refused by `spherical`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis: Option<[f64; 3]>,
}

/// How far from 1 a given quaternion's or normal's norm may be (it is then normalised).
pub const UNIT_TOLERANCE: f64 = 1e-9;

fn finite_vec(field: &str, v: &[f64]) -> Result<(), SpecError> {
    match v.iter().find(|x| !x.is_finite()) {
        Some(x) => Err(SpecError::new(field, format!("must be finite, got {x}"))),
        None => Ok(()),
    }
}

fn positive(field: String, x: f64) -> Result<f64, SpecError> {
    if x.is_finite() && x > 0.0 {
        Ok(x)
    } else {
        Err(SpecError::new(
            field,
            format!("must be a finite number > 0, got {x}"),
        ))
    }
}

fn unit(field: &str, v: &[f64]) -> Result<f64, SpecError> {
    finite_vec(field, v)?;
    let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if (norm - 1.0).abs() > UNIT_TOLERANCE {
        return Err(SpecError::new(
            field,
            format!("must have norm 1 (±{UNIT_TOLERANCE:e}), got {norm}"),
        ));
    }
    Ok(norm)
}

fn law_value(field: String, x: f64, upper: Option<f64>) -> Result<f64, SpecError> {
    let ok = x.is_finite() && x >= 0.0 && upper.is_none_or(|u| x <= u);
    if ok {
        Ok(x)
    } else {
        let range = upper.map_or("≥ 0".to_string(), |u| format!("in [0, {u}]"));
        Err(SpecError::new(field, format!("must be {range}, got {x}")))
    }
}

impl ShapeSpec {
    fn shape(&self, field: &str) -> Result<Shape, SpecError> {
        let f = |name: &str| format!("{field}.{name}");
        Ok(match self {
            ShapeSpec::Sphere { radius } => Shape::Sphere {
                radius: positive(f("radius"), *radius)?,
            },
            ShapeSpec::Box { half_extents } => {
                for (k, x) in half_extents.iter().enumerate() {
                    positive(format!("{field}.half_extents[{k}]"), *x)?;
                }
                Shape::Box {
                    half_extents: *half_extents,
                }
            }
            ShapeSpec::Capsule {
                radius,
                half_height,
            } => Shape::Capsule {
                radius: positive(f("radius"), *radius)?,
                half_height: law_value(f("half_height"), *half_height, None)?,
            },
            ShapeSpec::Cylinder {
                radius,
                half_height,
            } => Shape::Cylinder {
                radius: positive(f("radius"), *radius)?,
                half_height: positive(f("half_height"), *half_height)?,
            },
            ShapeSpec::Convex { points } => {
                if points.len() < 4 {
                    return Err(SpecError::new(
                        f("points"),
                        format!(
                            "a convex hull needs at least 4 points, got {}",
                            points.len()
                        ),
                    ));
                }
                for (k, p) in points.iter().enumerate() {
                    finite_vec(&format!("{field}.points[{k}]"), p)?;
                }
                Shape::Convex {
                    points: points.clone(),
                }
            }
            ShapeSpec::HalfSpace { normal } => {
                let norm = unit(&f("normal"), normal)?;
                Shape::HalfSpace {
                    normal: normal.map(|x| x / norm),
                }
            }
        })
    }
}

impl RigidBodySpec {
    fn body(&self, field: &str) -> Result<(Body, BodyState), SpecError> {
        let f = |name: &str| format!("{field}.{name}");
        let shape = self.shape.shape(&f("shape"))?;
        let half_space = matches!(shape, Shape::HalfSpace { .. });
        let fixed = self.fixed || half_space;
        finite_vec(&f("position"), &self.position)?;
        finite_vec(&f("velocity"), &self.velocity)?;
        finite_vec(&f("angular_velocity"), &self.angular_velocity)?;
        let norm = unit(&f("orientation"), &self.orientation)?;
        let [w, x, y, z] = self.orientation.map(|c| c / norm);
        if fixed {
            for (name, v) in [
                ("velocity", self.velocity),
                ("angular_velocity", self.angular_velocity),
            ] {
                if v.iter().any(|x| *x != 0.0) {
                    return Err(SpecError::new(
                        f(name),
                        "a fixed body (or half_space) does not move: leave it 0",
                    ));
                }
            }
        }
        let (mass, inertia) = if fixed {
            (0.0, [0.0; 3])
        } else {
            let from_density = match self.density {
                Some(d) => {
                    let d = positive(f("density"), d)?;
                    shape.mass_properties(d)
                }
                None => None,
            };
            let mass = match (self.mass, from_density) {
                (Some(m), _) => positive(f("mass"), m)?,
                (None, Some((m, _))) => m,
                (None, None) => return Err(missing_mass(&f("density"), &shape)),
            };
            let inertia = match (self.inertia, from_density) {
                (Some(i), _) => {
                    for (k, x) in i.iter().enumerate() {
                        positive(format!("{field}.inertia[{k}]"), *x)?;
                    }
                    i
                }
                (None, Some((_, i))) => i,
                (None, None) => return Err(missing_mass(&f("inertia"), &shape)),
            };
            (mass, inertia)
        };
        let q = UnitQuaternion::new_unchecked(Quaternion::new(w, x, y, z));
        let omega = q.inverse() * Vector3::from(self.angular_velocity);
        Ok((
            Body {
                shape,
                mass,
                inertia,
                fixed,
            },
            BodyState {
                position: self.position,
                orientation: [w, x, y, z],
                velocity: self.velocity,
                angular_velocity: [omega.x, omega.y, omega.z],
            },
        ))
    }
}

fn missing_mass(field: &str, shape: &Shape) -> SpecError {
    let reason = if matches!(shape, Shape::Convex { .. }) {
        "a convex hull's mass and inertia are not computed: give `mass` and `inertia`"
    } else {
        "a free body needs `density`, or `mass` and `inertia`"
    };
    SpecError::new(field, reason)
}

impl RigidBodiesSpec {
    /// Checks every field and builds the scene; errors name the field.
    pub fn validate(&self) -> Result<RigidScene, SpecError> {
        finite_vec("model.gravity", &self.gravity)?;
        if self.bodies.is_empty() {
            return Err(SpecError::new("model.bodies", "at least one body"));
        }
        let mut names: Vec<String> = Vec::new();
        let mut bodies = Vec::new();
        let mut initial = Vec::new();
        for (i, b) in self.bodies.iter().enumerate() {
            let field = format!("model.bodies[{i}]");
            let name_ok = !b.name.is_empty()
                && b.name != "world"
                && b.name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_');
            if !name_ok {
                return Err(SpecError::new(
                    format!("{field}.name"),
                    format!(
                        "`{}`: a name is letters, digits and _ (not `world`)",
                        b.name
                    ),
                ));
            }
            if names.contains(&b.name) {
                return Err(SpecError::new(
                    format!("{field}.name"),
                    format!("`{}` names two bodies", b.name),
                ));
            }
            let (body, state) = b.body(&field)?;
            names.push(b.name.clone());
            bodies.push(body);
            initial.push(state);
        }
        if bodies.iter().all(|b| b.fixed) {
            return Err(SpecError::new(
                "model.bodies",
                "every body is fixed: nothing moves",
            ));
        }
        let c = &self.contact;
        let default_law = ContactLaw {
            restitution: law_value("model.contact.restitution".into(), c.restitution, Some(1.0))?,
            friction: law_value("model.contact.friction".into(), c.friction, None)?,
        };
        let margin = law_value("model.contact.margin".into(), c.margin, None)?;
        let index = |field: String, name: &str| {
            names
                .iter()
                .position(|n| n == name)
                .ok_or_else(|| SpecError::new(field, format!("unknown body `{name}`")))
        };
        let mut pair_laws = Vec::new();
        for (p, pair) in c.pairs.iter().enumerate() {
            let field = format!("model.contact.pairs[{p}]");
            let a = index(format!("{field}.bodies[0]"), &pair.bodies[0])?;
            let b = index(format!("{field}.bodies[1]"), &pair.bodies[1])?;
            if a == b {
                return Err(SpecError::new(
                    format!("{field}.bodies"),
                    "two different bodies",
                ));
            }
            let law = ContactLaw {
                restitution: match pair.restitution {
                    Some(e) => law_value(format!("{field}.restitution"), e, Some(1.0))?,
                    None => default_law.restitution,
                },
                friction: match pair.friction {
                    Some(mu) => law_value(format!("{field}.friction"), mu, None)?,
                    None => default_law.friction,
                },
            };
            pair_laws.push(([a, b], law));
        }
        let mut joints = Vec::new();
        for (j, joint) in self.joints.iter().enumerate() {
            let sides = joint
                .bodies
                .iter()
                .enumerate()
                .map(|(s, name)| {
                    if name == "world" {
                        Ok(None)
                    } else {
                        index(format!("model.joints[{j}].bodies[{s}]"), name).map(Some)
                    }
                })
                .collect::<Result<Vec<_>, _>>()?;
            joints.push(joint.joint(j, [sides[0], sides[1]], &bodies, &initial)?);
        }
        Ok(RigidScene {
            names,
            bodies,
            initial,
            gravity: self.gravity,
            default_law,
            pair_laws,
            margin,
            joints,
        })
    }
}

impl RigidJointSpec {
    /// The joint `model.joints[j]` between the bodies of `sides` (`None`: world), its anchor and
    /// axis taken into each side's frame at t = 0.
    fn joint(
        &self,
        j: usize,
        sides: [Option<usize>; 2],
        bodies: &[Body],
        initial: &[BodyState],
    ) -> Result<Joint, SpecError> {
        let f = |name: &str| format!("model.joints[{j}].{name}");
        let kind = match self.kind.as_str() {
            "spherical" => JointKind::Spherical,
            "revolute" => JointKind::Revolute,
            "prismatic" | "fixed" => {
                return Err(SpecError::new(
                    f("kind"),
                    format!(
                        "`{}` joints are not implemented: spherical and revolute are",
                        self.kind
                    ),
                ));
            }
            other => {
                return Err(SpecError::new(
                    f("kind"),
                    format!("unknown joint kind `{other}`: spherical or revolute"),
                ));
            }
        };
        if sides[0] == sides[1] {
            let reason = match sides[0] {
                Some(_) => format!("a body jointed to itself (`{}`)", self.bodies[0]),
                None => "both sides are `world`".to_string(),
            };
            return Err(SpecError::new(f("bodies"), reason));
        }
        // A fixed body is the ground, as the world is.
        let free = sides.map(|s| s.filter(|&b| !bodies[b].fixed));
        if free.iter().all(Option::is_none) {
            return Err(SpecError::new(
                f("bodies"),
                "both sides are fixed: the joint constrains nothing",
            ));
        }
        let anchor = self.anchor.ok_or_else(|| {
            SpecError::new(f("anchor"), "required: the joint's point (world, at t = 0)")
        })?;
        finite_vec(&f("anchor"), &anchor)?;
        let to_local = |s: usize, p: Vector3<f64>, point: bool| -> [f64; 3] {
            match free[s] {
                Some(b) => {
                    let st = &initial[b];
                    let q = st.rotation();
                    let origin = if point {
                        Vector3::from(st.position)
                    } else {
                        Vector3::zeros()
                    };
                    let l = q.inverse() * (p - origin);
                    [l.x, l.y, l.z]
                }
                None => [p.x, p.y, p.z],
            }
        };
        let anchor_v = Vector3::from(anchor);
        let joint_sides = [0, 1].map(|s| match free[s] {
            Some(body) => JointSide::Body {
                body,
                anchor: to_local(s, anchor_v, true),
            },
            None => JointSide::Ground { anchor },
        });
        let (axis, perpendicular) = match (kind, self.axis) {
            (JointKind::Spherical, Some(_)) => {
                return Err(SpecError::new(
                    f("axis"),
                    "a spherical joint has no axis: leave it out",
                ));
            }
            (JointKind::Spherical, None) => ([0.0; 3], [[0.0; 3]; 2]),
            (JointKind::Revolute, None) => {
                return Err(SpecError::new(
                    f("axis"),
                    "required by a revolute joint (world, at t = 0, unit)",
                ));
            }
            (JointKind::Revolute, Some(axis)) => {
                let norm = unit(&f("axis"), &axis)?;
                let axis = axis.map(|x| x / norm);
                let [t1, t2] = tangent_basis(axis);
                (
                    to_local(0, Vector3::from(axis), false),
                    [
                        to_local(1, Vector3::from(t1), false),
                        to_local(1, Vector3::from(t2), false),
                    ],
                )
            }
        };
        Ok(Joint {
            kind,
            sides: joint_sides,
            axis,
            perpendicular,
        })
    }
}
