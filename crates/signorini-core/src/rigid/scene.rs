//! A validated scene of rigid bodies: the bodies with their names and initial states, gravity,
//! and the contact law of every pair (restitution e and friction μ, a default and per-pair
//! overrides), with the detection margin, and the joints.

use super::body::{Body, BodyState};
use super::joint::Joint;

/// Newton's restitution e ∈ [0, 1] and Coulomb's μ ≥ 0 of a pair of bodies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactLaw {
    /// Restitution e.
    pub restitution: f64,
    /// Friction coefficient μ.
    pub friction: f64,
}

/// The bodies and their contact laws, checked (the spec's validation builds it).
#[derive(Debug, Clone, PartialEq)]
pub struct RigidScene {
    /// Body names (the columns' prefixes), unique.
    pub names: Vec<String>,
    /// The bodies.
    pub bodies: Vec<Body>,
    /// Their states at t = 0 (unit quaternions; fixed bodies at rest).
    pub initial: Vec<BodyState>,
    /// Gravity g (world), the acceleration of every free body.
    pub gravity: [f64; 3],
    /// The law of a pair that has no override.
    pub default_law: ContactLaw,
    /// Per-pair overrides: the two bodies (either order) and their law.
    pub pair_laws: Vec<([usize; 2], ContactLaw)>,
    /// Contacts of gap ≤ margin are found, and enter the index set when their predicted gap
    /// is ≤ margin (≥ 0).
    pub margin: f64,
    /// Bilateral joints between bodies or to the ground (may be empty).
    pub joints: Vec<Joint>,
}

impl RigidScene {
    /// The law between bodies a and b: the pair's override, else the default.
    pub fn law(&self, a: usize, b: usize) -> ContactLaw {
        self.pair_laws
            .iter()
            .find(|([x, y], _)| (*x == a && *y == b) || (*x == b && *y == a))
            .map_or(self.default_law, |(_, law)| *law)
    }
}
