//! Rigid bodies in space: bodies with a shape, mass and principal inertia
//! ([`body`]), a scene of them with the contact law of each pair ([`scene`]), contact detection
//! behind a trait of our own ([`detector`]), spherical and revolute joints ([`joint`]), the Moreau–Jean time-stepping of Newton–Euler
//! dynamics with the 3D friction problem per step ([`moreau_jean`]), and its place under the
//! one time-stepping driver ([`stepping`]).

pub mod body;
pub mod detector;
pub mod joint;
pub mod moreau_jean;
pub mod scene;
pub mod stepping;

pub use body::{Body, BodyState, Pose, Shape};
pub use detector::{ContactDetector, ContactPoint, DetectError, DetectorFactory, tangent_basis};
pub use joint::{Joint, JointKind, JointSide};
pub use moreau_jean::{
    AUTO_SWEEPS, ContactImpulse, RELAXATION, RigidMoreauJean, RigidMoreauJeanParams, RigidScratch,
    RigidStepError, STALL_SWEEPS, StepPhase, StepPhases, StepReport,
};
pub use scene::{ContactLaw, RigidScene};
pub use stepping::{
    CONTACT_COLUMNS, RigidMemory, RigidRunError, RigidRunStats, RigidStepping, rigid_columns,
};
