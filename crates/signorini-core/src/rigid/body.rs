//! A rigid body: its shape, mass and principal inertia, and its state (pose and twist).
//!
//! The body frame has its origin at the centre of mass and its axes along the principal axes of
//! inertia, so the inertia tensor in the body frame is `diag(I_1, I_2, I_3)`, constant. The
//! pose is the position x of the centre of mass (world) and a unit quaternion q = (w, x, y, z)
//! taking body coordinates to world ones, R(q); the twist is the velocity v of the centre of
//! mass (world) and the angular velocity Ω in the body frame, as in Siconos' `NewtonEulerDS`
//! (V. Acary, B. Brogliato, *Numerical Methods for Nonsmooth Dynamical Systems*, Springer, 2008,
//! doi:10.1007/978-3-540-75392-6; the world angular velocity is ω = R(q) Ω).

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The geometry of a body, in its body frame (centre of mass at the origin).
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// A ball of radius r.
    Sphere {
        /// Radius r > 0.
        radius: f64,
    },
    /// A box of half extents (a, b, c) along the body axes.
    Box {
        /// Half extents, each > 0.
        half_extents: [f64; 3],
    },
    /// A capsule: the segment from (0, 0, −a) to (0, 0, a) (body z axis) swept by a ball of
    /// radius r.
    Capsule {
        /// Radius r > 0.
        radius: f64,
        /// Half length a ≥ 0 of its axis segment.
        half_height: f64,
    },
    /// A solid cylinder of radius r about the body z axis, from z = −a to z = a.
    Cylinder {
        /// Radius r > 0.
        radius: f64,
        /// Half height a > 0.
        half_height: f64,
    },
    /// The convex hull of points given in the body frame (centre of mass at the origin).
    Convex {
        /// At least 4 points, not coplanar.
        points: Vec<[f64; 3]>,
    },
    /// The half-space {p : n·p ≤ 0} of the body frame, with n its outward unit normal (bodies
    /// live on the side n points to); always fixed.
    HalfSpace {
        /// Outward unit normal n.
        normal: [f64; 3],
    },
}

impl Shape {
    /// Mass and principal inertia (I_1, I_2, I_3) of the shape filled with `density`, in its
    /// body frame: ball m = ρ 4πr³/3, I = 2mr²/5; box m = 8ρabc, I_1 = m(b² + c²)/3 (and
    /// cyclically); cylinder m = ρπr²·2a, I_3 = mr²/2, I_1 = I_2 = m(3r² + 4a²)/12; capsule
    /// (cylinder m_c of length 2a and two hemispheres of total mass m_s) I_3 = m_c r²/2 +
    /// 2m_s r²/5, I_1 = I_2 = m_c(a²/3 + r²/4) + m_s(2r²/5 + a² + 3ar/4). `None` for a convex
    /// hull (its mass and inertia are given) and for a half-space (fixed, no mass).
    pub fn mass_properties(&self, density: f64) -> Option<(f64, [f64; 3])> {
        match *self {
            Shape::Sphere { radius: r } => {
                let m = density * 4.0 / 3.0 * PI * r.powi(3);
                let i = 0.4 * m * r * r;
                Some((m, [i, i, i]))
            }
            Shape::Box {
                half_extents: [a, b, c],
            } => {
                let m = 8.0 * density * a * b * c;
                Some((
                    m,
                    [
                        m * (b * b + c * c) / 3.0,
                        m * (a * a + c * c) / 3.0,
                        m * (a * a + b * b) / 3.0,
                    ],
                ))
            }
            Shape::Cylinder {
                radius: r,
                half_height: a,
            } => {
                let m = density * PI * r * r * 2.0 * a;
                let side = m * (3.0 * r * r + 4.0 * a * a) / 12.0;
                Some((m, [side, side, 0.5 * m * r * r]))
            }
            Shape::Capsule {
                radius: r,
                half_height: a,
            } => {
                let mc = density * PI * r * r * 2.0 * a;
                let ms = density * 4.0 / 3.0 * PI * r.powi(3);
                let axial = 0.5 * mc * r * r + 0.4 * ms * r * r;
                let side =
                    mc * (a * a / 3.0 + r * r / 4.0) + ms * (0.4 * r * r + a * a + 0.75 * a * r);
                Some((mc + ms, [side, side, axial]))
            }
            Shape::Convex { .. } | Shape::HalfSpace { .. } => None,
        }
    }
}

/// A body as the dynamics sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// Its geometry.
    pub shape: Shape,
    /// Mass m > 0 (ignored for a fixed body).
    pub mass: f64,
    /// Principal moments of inertia (I_1, I_2, I_3), each > 0 (ignored for a fixed body).
    pub inertia: [f64; 3],
    /// A fixed body keeps its pose; its twist is zero.
    pub fixed: bool,
}

/// Pose and twist of one body: what a step reads and writes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BodyState {
    /// Position x of the centre of mass (world).
    pub position: [f64; 3],
    /// Unit quaternion (w, x, y, z), body to world.
    pub orientation: [f64; 4],
    /// Velocity v of the centre of mass (world).
    pub velocity: [f64; 3],
    /// Angular velocity Ω in the body frame.
    pub angular_velocity: [f64; 3],
}

impl BodyState {
    /// The rotation R(q).
    pub fn rotation(&self) -> UnitQuaternion<f64> {
        let [w, x, y, z] = self.orientation;
        UnitQuaternion::new_unchecked(Quaternion::new(w, x, y, z))
    }

    /// The world angular velocity ω = R(q) Ω.
    pub fn world_angular_velocity(&self) -> [f64; 3] {
        let w = self.rotation() * Vector3::from(self.angular_velocity);
        [w.x, w.y, w.z]
    }

    /// The pose, for a contact detector.
    pub fn pose(&self) -> Pose {
        Pose {
            position: self.position,
            orientation: self.orientation,
        }
    }
}

/// Where a body is: the position of its centre of mass and its orientation (w, x, y, z).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Position of the body frame's origin (world).
    pub position: [f64; 3],
    /// Unit quaternion (w, x, y, z), body to world.
    pub orientation: [f64; 4],
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The capsule's inertia tends to the ball's as a → 0 and the cylinder's share dominates
    /// for a long one: checked against the ball and against the sum of its parts at a = 0.
    #[test]
    fn capsule_of_zero_length_is_a_ball_and_box_inertia_is_the_cube_formula() {
        let ball = Shape::Sphere { radius: 0.3 }.mass_properties(2.0).unwrap();
        let caps = Shape::Capsule {
            radius: 0.3,
            half_height: 0.0,
        }
        .mass_properties(2.0)
        .unwrap();
        assert!((ball.0 - caps.0).abs() < 1e-15);
        for k in 0..3 {
            assert!((ball.1[k] - caps.1[k]).abs() < 1e-15);
        }
        // A unit cube of density 6: m = 6, I = m(1/4 + 1/4)/3 · ... = m s²/6 = 1 with s = 1.
        let (m, i) = Shape::Box {
            half_extents: [0.5; 3],
        }
        .mass_properties(6.0)
        .unwrap();
        assert!((m - 6.0).abs() < 1e-15);
        assert!(i.iter().all(|x| (x - 1.0).abs() < 1e-15));
        // Cylinder of radius 1, length 2 (a = 1): I_3 = m/2, I_1 = m(3 + 4)/12.
        let (m, i) = Shape::Cylinder {
            radius: 1.0,
            half_height: 1.0,
        }
        .mass_properties(1.0)
        .unwrap();
        assert!((m - 2.0 * PI).abs() < 1e-14);
        assert!((i[2] - m / 2.0).abs() < 1e-14 && (i[0] - 7.0 * m / 12.0).abs() < 1e-14);
    }
}
