//! `[model]`: the scenes. The linear scenes' parameter structs live in [`crate::scenes`], the
//! nonlinear constrained ones in [`crate::soi2::models`]; the raw-matrix `linear` scene here.

use super::lagrangian::LagrangianSpec;
use super::rigid::RigidBodiesSpec;
use crate::scenes::{BarSpec, BouncingBall, Chain, StringScene};
use crate::soi2::models::{JayNegrutTest, Pendulum, SliderCrank};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// `[model]`: the scene and its parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "scene", rename_all = "snake_case")]
pub enum ModelSpec {
    /// A ball bouncing on the ground.
    BouncingBall(BouncingBall),
    /// Elastic bar of linear finite elements against an obstacle.
    Bar(BarSpec),
    /// The Doyen–Ern–Piperno bouncing bar (defaults from Yoong et al. 2018, Table 1).
    DepBar(BarSpec),
    /// Masses and springs, one contact per mass.
    Chain(Chain),
    /// A transverse string with fixed ends, lumped nodes, optionally against a distributed
    /// obstacle (a contact at every node).
    String(StringScene),
    /// Raw matrices.
    Linear(LinearSpec),
    /// The pendulum (16) of Jay & Negrut 2008, Fig. 3 (SOI2 schemes).
    Pendulum(Pendulum),
    /// A rigid slider-crank under gravity (SOI2 schemes).
    SliderCrank(SliderCrank),
    /// The test problem (15) of Jay & Negrut 2008, with its exact solution (SOI2 schemes).
    JayNegrutTest(JayNegrutTest),
    /// Your own nonlinear mechanical system, written as expressions (joints with the SOI2
    /// schemes; contacts, joints or both with moreau_jean and ns_generalized_alpha).
    Lagrangian(LagrangianSpec),
    /// Rigid bodies in space with contacts found from their shapes (moreau_jean).
    RigidBodies(RigidBodiesSpec),
}

impl ModelSpec {
    /// Whether the scene is a built-in nonlinear constrained model (integrated by the SOI2
    /// schemes) rather than a linear one (Moreau–Jean, the α-family, WFEM for the bars). A
    /// `lagrangian` model is neither: [`crate::job::Job::from_spec`] sends it to the SOI2 schemes
    /// (joints) or to Moreau–Jean (contacts) by its contents.
    pub fn is_constrained(&self) -> bool {
        matches!(
            self,
            ModelSpec::Pendulum(_) | ModelSpec::SliderCrank(_) | ModelSpec::JayNegrutTest(_)
        )
    }

    /// The model of scene `scene` read from its fields alone (the `[model]` table without
    /// `scene`), or `None` for a scene this list does not know. serde buffers an internally
    /// tagged section before it knows the variant, which loses the path of a bad field inside it
    /// (`q0[0]`, `contacts[0].restitutin`); reading the variant's own struct with a
    /// path-tracking deserializer (the caller's) keeps it.
    pub fn from_scene_fields<'de, D: serde::Deserializer<'de>>(
        scene: &str,
        fields: D,
    ) -> Option<Result<ModelSpec, D::Error>> {
        Some(match scene {
            "bouncing_ball" => BouncingBall::deserialize(fields).map(ModelSpec::BouncingBall),
            "bar" => BarSpec::deserialize(fields).map(ModelSpec::Bar),
            "dep_bar" => BarSpec::deserialize(fields).map(ModelSpec::DepBar),
            "chain" => Chain::deserialize(fields).map(ModelSpec::Chain),
            "string" => StringScene::deserialize(fields).map(ModelSpec::String),
            "linear" => LinearSpec::deserialize(fields).map(ModelSpec::Linear),
            "pendulum" => Pendulum::deserialize(fields).map(ModelSpec::Pendulum),
            "slider_crank" => SliderCrank::deserialize(fields).map(ModelSpec::SliderCrank),
            "jay_negrut_test" => JayNegrutTest::deserialize(fields).map(ModelSpec::JayNegrutTest),
            "lagrangian" => LagrangianSpec::deserialize(fields).map(ModelSpec::Lagrangian),
            "rigid_bodies" => RigidBodiesSpec::deserialize(fields).map(ModelSpec::RigidBodies),
            _ => return None,
        })
    }

    /// The scene's name as written in specs.
    pub fn scene(&self) -> &'static str {
        match self {
            ModelSpec::BouncingBall(_) => "bouncing_ball",
            ModelSpec::Bar(_) => "bar",
            ModelSpec::DepBar(_) => "dep_bar",
            ModelSpec::Chain(_) => "chain",
            ModelSpec::String(_) => "string",
            ModelSpec::Linear(_) => "linear",
            ModelSpec::Pendulum(_) => "pendulum",
            ModelSpec::SliderCrank(_) => "slider_crank",
            ModelSpec::JayNegrutTest(_) => "jay_negrut_test",
            ModelSpec::Lagrangian(_) => "lagrangian",
            ModelSpec::RigidBodies(_) => "rigid_bodies",
        }
    }
}

/// One harmonic term of the force of a `linear` model: `shape · sin(omega t + phase)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct HarmonicForceSpec {
    /// Amplitude per dof.
    pub shape: Vec<f64>,
    /// Angular frequency.
    pub omega: f64,
    /// Phase (default 0).
    #[serde(default)]
    pub phase: f64,
}

/// `scene = "linear"`: `M q̈ + C q̇ + K q = F(t) + G λ`, `g = g_matrix · q + g_offset ≥ 0`.
/// Each matrix is given as dense rows (`mass`) or as triplets (`mass_triplets`), not both.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LinearSpec {
    /// M as dense rows.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<Vec<Vec<f64>>>,
    /// M as `[row, col, value]` triplets (repeated entries add up).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass_triplets: Option<Vec<(usize, usize, f64)>>,
    /// K as dense rows (zero when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<Vec<Vec<f64>>>,
    /// K as triplets.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness_triplets: Option<Vec<(usize, usize, f64)>>,
    /// C as dense rows (zero when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping: Option<Vec<Vec<f64>>>,
    /// C as triplets.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping_triplets: Option<Vec<(usize, usize, f64)>>,
    /// Constant force (zero when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force: Option<Vec<f64>>,
    /// Harmonic force terms.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub harmonic_force: Vec<HarmonicForceSpec>,
    /// Gᵀ: one row per contact, n entries each.
    #[serde(default)]
    pub g_matrix: Vec<Vec<f64>>,
    /// w: one offset per contact (zero when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub g_offset: Option<Vec<f64>>,
    /// Restitution per contact.
    #[serde(default)]
    pub restitution: Vec<f64>,
    /// Coulomb friction: the tangent rows T, one per contact, n entries each (the tangential
    /// local velocity is U_t = T v). Required when some `friction` is > 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t_matrix: Option<Vec<Vec<f64>>>,
    /// Coulomb friction coefficient μ ≥ 0 per contact (zero when absent). A model with μ > 0
    /// runs with `moreau_jean` or `moreau_jean_variant`; the step solves the planar friction
    /// problem (`contact_solver.kind`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<Vec<f64>>,
    /// Initial positions (zero when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub q0: Option<Vec<f64>>,
    /// Initial velocities (zero when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub v0: Option<Vec<f64>>,
}
