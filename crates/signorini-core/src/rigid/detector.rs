//! Contact detection as the time stepping sees it: a trait, and the plain contact points it
//! returns. The numerics never see a shape type of a collision library; an implementation
//! (parry3d in the `signorini-collision` crate) builds its own shapes from [`Body::shape`] and
//! reports every pair of points closer than the margin, the way rapier keeps its narrow phase
//! apart from its solver.

use super::body::{Body, Pose};
use thiserror::Error;

/// One contact point between two bodies, in world coordinates.
///
/// The normal n points from body `bodies[0]` to body `bodies[1]`; the gap is
/// g = (p_1 − p_0)·n (negative in penetration), with p_0, p_1 the witness points on each body;
/// the local velocity of the contact is u = R_cᵀ(v_1(p_1) − v_0(p_0)) in the frame
/// R_c = (n, t_1, t_2), so that u_n > 0 separates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactPoint {
    /// The two bodies (indices in the scene), `bodies[0] < bodies[1]` not required.
    pub bodies: [usize; 2],
    /// Witness points p_0 on body 0 and p_1 on body 1 (world).
    pub points: [[f64; 3]; 2],
    /// Unit normal n from body 0 to body 1.
    pub normal: [f64; 3],
    /// Two unit tangents t_1, t_2 with (n, t_1, t_2) a right-handed orthonormal frame.
    pub tangents: [[f64; 3]; 2],
    /// Gap g = (p_1 − p_0)·n.
    pub gap: f64,
    /// The features (vertex, edge or face of each shape, as the detector numbers them) the
    /// point joins: with the two bodies, the key that recognises the same contact from one step
    /// to the next, whose last impulse warm-starts the next step's friction problem.
    pub features: [u32; 2],
}

/// Why detection failed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DetectError {
    /// The library cannot compute contacts between these two shapes.
    #[error(
        "no contact generation between body {first} ({first_shape}) and body {second} ({second_shape})"
    )]
    Unsupported {
        /// First body.
        first: usize,
        /// Its shape kind.
        first_shape: &'static str,
        /// Second body.
        second: usize,
        /// Its shape kind.
        second_shape: &'static str,
    },
    /// A shape could not be built (a degenerate convex hull).
    #[error("body {body}: {reason}")]
    Shape {
        /// The body.
        body: usize,
        /// Why.
        reason: String,
    },
}

/// Finds the contact points of a set of bodies at given poses.
pub trait ContactDetector {
    /// Writes into `contacts` (cleared first) every contact point of every pair of bodies, not
    /// both fixed, whose gap is ≤ `margin`, in an order that depends only on the poses (a run
    /// resumed from a checkpoint detects the same points in the same order).
    fn detect(
        &mut self,
        poses: &[Pose],
        margin: f64,
        contacts: &mut Vec<ContactPoint>,
    ) -> Result<(), DetectError>;
}

/// Builds a detector for a scene's bodies (their shapes and which are fixed).
pub trait DetectorFactory: Send + Sync {
    /// A detector for `bodies`; a shape the library cannot build is refused naming its body.
    fn detector(&self, bodies: &[Body]) -> Result<Box<dyn ContactDetector>, DetectError>;
}

/// The tangents (t_1, t_2) of the contact frame of a unit normal n: t_1 = n × e / ‖n × e‖ with
/// e the coordinate axis least aligned with n, t_2 = n × t_1 (a function of n only, so two
/// detectors that agree on n agree on the frame).
pub fn tangent_basis(n: [f64; 3]) -> [[f64; 3]; 2] {
    let a = [n[0].abs(), n[1].abs(), n[2].abs()];
    let e = if a[0] <= a[1] && a[0] <= a[2] {
        [1.0, 0.0, 0.0]
    } else if a[1] <= a[2] {
        [0.0, 1.0, 0.0]
    } else {
        [0.0, 0.0, 1.0]
    };
    let t1 = cross(n, e);
    let norm = (t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2]).sqrt();
    let t1 = [t1[0] / norm, t1[1] / norm, t1[2] / norm];
    [t1, cross(n, t1)]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tangent_basis_is_a_right_handed_orthonormal_frame() {
        for n in [
            [0.0, 0.0, 1.0],
            [0.0, -1.0, 0.0],
            [0.6, 0.0, 0.8],
            [1.0 / 3f64.sqrt(); 3],
        ] {
            let [t1, t2] = tangent_basis(n);
            let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
            assert!(dot(n, t1).abs() < 1e-15 && dot(n, t2).abs() < 1e-15);
            assert!(dot(t1, t2).abs() < 1e-15);
            assert!((dot(t1, t1) - 1.0).abs() < 1e-15 && (dot(t2, t2) - 1.0).abs() < 1e-15);
            // (n, t1, t2) right-handed: n × t1 = t2.
            let c = cross(n, t1);
            assert!((0..3).all(|k| (c[k] - t2[k]).abs() < 1e-15));
        }
    }
}
