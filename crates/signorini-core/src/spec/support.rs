//! What each scheme takes of a model: one table, scheme × model family × feature.
//!
//! The validation reads it (a feature a scheme does not take is refused from here, naming the
//! table's field, with the table's reason: [`check`], [`refusal`]) and so does `capabilities`
//! ([`crate::capabilities::Capabilities::support`], the same rows as data), so what the service
//! says a scheme takes and what it accepts cannot disagree. A pair (scheme, family) that is not
//! in the table does not run at all and is refused as a mismatch, naming `integrator.scheme`
//! ([`super::mismatch`]).

use super::SpecError;
use serde::Serialize;

/// The families of models as the schemes see them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ModelFamily {
    /// The linear scenes: `bouncing_ball`, `bar`, `dep_bar`, `chain`, `linear`.
    Linear,
    /// `lagrangian`: the user's nonlinear model (joints, contacts, friction).
    Lagrangian,
    /// The built-in nonlinear constrained scenes: `pendulum`, `slider_crank`,
    /// `jay_negrut_test`.
    ConstrainedScene,
    /// `rigid_bodies`.
    RigidBodies,
}

/// A feature of a model, or of its time grid, that a scheme may take or refuse.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Feature {
    /// Unilateral contacts (gaps ≥ 0 with an impact law).
    Contacts,
    /// Coulomb friction on a contact (μ > 0).
    Friction,
    /// Friction in space: two tangents per contact, Coulomb's cone (FC3D).
    Tangents3d,
    /// Bilateral joints g(q, t) = 0.
    Joints,
    /// Joints whose Jacobian may lose rank (`redundant_joints`).
    RedundantJoints,
    /// Nonholonomic (velocity) constraints.
    Nonholonomic,
    /// Variable step sizes (`time.pattern`).
    VariableStep,
}

impl ModelFamily {
    /// The family's name, as `capabilities` lists it.
    pub fn name(self) -> &'static str {
        match self {
            ModelFamily::Linear => "linear",
            ModelFamily::Lagrangian => "lagrangian",
            ModelFamily::ConstrainedScene => "constrained_scene",
            ModelFamily::RigidBodies => "rigid_bodies",
        }
    }
}

impl Feature {
    /// The feature's name, as `capabilities` lists it.
    pub fn name(self) -> &'static str {
        match self {
            Feature::Contacts => "contacts",
            Feature::Friction => "friction",
            Feature::Tangents3d => "tangents_3d",
            Feature::Joints => "joints",
            Feature::RedundantJoints => "redundant_joints",
            Feature::Nonholonomic => "nonholonomic",
            Feature::VariableStep => "variable_step",
        }
    }
}

/// Every feature, in the order of a row.
pub const FEATURES: [Feature; 7] = [
    Feature::Contacts,
    Feature::Friction,
    Feature::Tangents3d,
    Feature::Joints,
    Feature::RedundantJoints,
    Feature::Nonholonomic,
    Feature::VariableStep,
];

/// Whether a scheme takes a feature of a model family.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Support {
    /// The scheme takes it.
    Takes,
    /// The scheme refuses it: the field the refusal names and why (after the scheme's name).
    Refused {
        /// The field named.
        field: &'static str,
        /// Why, a sentence that follows the scheme's name.
        reason: &'static str,
    },
    /// The family has no such feature: no field of its models can give it.
    NotInModel,
}

impl Support {
    /// As `capabilities` lists it: `(support, field, reason)`, where `support` is `takes`,
    /// `refused` or `not_in_model` and only a refusal has a field and a reason (empty
    /// otherwise).
    pub fn parts(self) -> (&'static str, &'static str, &'static str) {
        match self {
            Support::Takes => ("takes", "", ""),
            Support::Refused { field, reason } => ("refused", field, reason),
            Support::NotInModel => ("not_in_model", "", ""),
        }
    }
}

/// One row of the table: what `scheme` takes of a `family` model, one [`Support`] per
/// [`FEATURES`] entry. Serialized as `capabilities` answers it over gRPC and HTTP alike:
/// `{"scheme", "model", "features": [{"feature", "support", "field", "reason"}]}`
/// ([`Support::parts`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SchemeSupport {
    /// The scheme, as written in specs.
    pub scheme: &'static str,
    /// The model family.
    pub family: ModelFamily,
    /// Per feature of [`FEATURES`], in that order.
    pub features: [(Feature, Support); 7],
}

impl Serialize for SchemeSupport {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        #[derive(Serialize)]
        struct Cell {
            feature: &'static str,
            support: &'static str,
            field: &'static str,
            reason: &'static str,
        }
        #[derive(Serialize)]
        struct Row {
            scheme: &'static str,
            model: &'static str,
            features: Vec<Cell>,
        }
        Row {
            scheme: self.scheme,
            model: self.family.name(),
            features: self
                .features
                .iter()
                .map(|&(feature, support)| {
                    let (support, field, reason) = support.parts();
                    Cell {
                        feature: feature.name(),
                        support,
                        field,
                        reason,
                    }
                })
                .collect(),
        }
        .serialize(serializer)
    }
}

use Feature as F;
use Support::{NotInModel, Takes};

const FIXED_STEP: Support = Support::Refused {
    field: "time.pattern",
    reason: "takes a fixed step h: variable step sizes are supported by the SOI2 schemes only",
};
const POSITION_LEVEL_FRICTION: Support = Support::Refused {
    field: "integrator.scheme",
    reason: "does not take Coulomb friction: its contact is a force at position level, with no impulse for Coulomb's law; use moreau_jean, moreau_jean_variant or the nonsmooth α-family (ns_newmark, ns_hht, ns_generalized_alpha, ns_kh_alpha)",
};
const SOI2_CONTACTS: Support = Support::Refused {
    field: "integrator.scheme",
    reason: "takes joints, not contacts: a lagrangian model with contacts runs with moreau_jean or ns_generalized_alpha",
};
const FULL_RANK_JOINTS: Support = Support::Refused {
    field: "model.redundant_joints",
    reason: "does not solve rank-deficient joints: redundant joints run with soi2_generalized_alpha, soi2_hht, hht_i3 or ns_generalized_alpha",
};
const HOLONOMIC_ONLY: Support = Support::Refused {
    field: "integrator.scheme",
    reason: "handles holonomic constraints only; this scene has nonholonomic ones: use soi2_generalized_alpha",
};

/// A row of a linear scene under `scheme`: contacts, and friction as `friction` says.
const fn linear(scheme: &'static str, friction: Support) -> SchemeSupport {
    SchemeSupport {
        scheme,
        family: ModelFamily::Linear,
        features: [
            (F::Contacts, Takes),
            (F::Friction, friction),
            (F::Tangents3d, NotInModel),
            (F::Joints, NotInModel),
            (F::RedundantJoints, NotInModel),
            (F::Nonholonomic, NotInModel),
            (F::VariableStep, FIXED_STEP),
        ],
    }
}

/// A row of a SOI2 scheme: on a `lagrangian` model (joints, no contacts) or on a built-in
/// scene (`nonholonomic` as given).
const fn soi2(scheme: &'static str, family: ModelFamily, nonholonomic: Support) -> SchemeSupport {
    let (contacts, redundant) = match family {
        ModelFamily::Lagrangian => (SOI2_CONTACTS, Takes),
        _ => (NotInModel, NotInModel),
    };
    SchemeSupport {
        scheme,
        family,
        features: [
            (F::Contacts, contacts),
            (F::Friction, contacts),
            (F::Tangents3d, NotInModel),
            (F::Joints, Takes),
            (F::RedundantJoints, redundant),
            (F::Nonholonomic, nonholonomic),
            (F::VariableStep, Takes),
        ],
    }
}

/// A row of a fixed-step scheme on a `lagrangian` model: contacts and joints, friction and
/// redundant joints as `friction` and `redundant` say.
const fn lagrangian(scheme: &'static str, friction: Support, redundant: Support) -> SchemeSupport {
    SchemeSupport {
        scheme,
        family: ModelFamily::Lagrangian,
        features: [
            (F::Contacts, Takes),
            (F::Friction, friction),
            (F::Tangents3d, NotInModel),
            (F::Joints, Takes),
            (F::RedundantJoints, redundant),
            (F::Nonholonomic, NotInModel),
            (F::VariableStep, FIXED_STEP),
        ],
    }
}

/// The table: every pair (scheme, family) that runs, and what it takes.
pub const TABLE: [SchemeSupport; 18] = [
    linear("moreau_jean", Takes),
    linear("moreau_jean_variant", Takes),
    linear("ns_newmark", Takes),
    linear("ns_hht", Takes),
    linear("ns_generalized_alpha", Takes),
    linear("ns_kh_alpha", Takes),
    linear("newmark_position_contact", POSITION_LEVEL_FRICTION),
    linear("hht_position_contact", POSITION_LEVEL_FRICTION),
    lagrangian("moreau_jean", Takes, FULL_RANK_JOINTS),
    lagrangian("ns_generalized_alpha", Takes, Takes),
    soi2(
        "soi2_generalized_alpha",
        ModelFamily::Lagrangian,
        NotInModel,
    ),
    soi2("soi2_hht", ModelFamily::Lagrangian, NotInModel),
    soi2("hht_i3", ModelFamily::Lagrangian, NotInModel),
    soi2(
        "soi2_generalized_alpha",
        ModelFamily::ConstrainedScene,
        Takes,
    ),
    soi2("soi2_hht", ModelFamily::ConstrainedScene, HOLONOMIC_ONLY),
    soi2("hht_i3", ModelFamily::ConstrainedScene, HOLONOMIC_ONLY),
    SchemeSupport {
        scheme: "moreau_jean",
        family: ModelFamily::RigidBodies,
        features: [
            (F::Contacts, Takes),
            (F::Friction, Takes),
            (F::Tangents3d, Takes),
            (F::Joints, Takes),
            (F::RedundantJoints, Takes),
            (F::Nonholonomic, NotInModel),
            (F::VariableStep, FIXED_STEP),
        ],
    },
    // WFEM's bar: one contact at its end, nothing else.
    SchemeSupport {
        scheme: "wfem",
        family: ModelFamily::Linear,
        features: [
            (F::Contacts, Takes),
            (F::Friction, NotInModel),
            (F::Tangents3d, NotInModel),
            (F::Joints, NotInModel),
            (F::RedundantJoints, NotInModel),
            (F::Nonholonomic, NotInModel),
            (F::VariableStep, FIXED_STEP),
        ],
    },
];

/// What `scheme` takes of `feature` on a `family` model; `None` when the pair does not run.
pub fn support(scheme: &str, family: ModelFamily, feature: Feature) -> Option<Support> {
    TABLE
        .iter()
        .find(|row| row.scheme == scheme && row.family == family)
        .and_then(|row| row.features.iter().find(|(f, _)| *f == feature))
        .map(|(_, s)| *s)
}

/// The refusal of `feature` under `scheme` on a `family` model, when the table refuses it: the
/// table's field, and "SCHEME REASON" followed by ` (detail)` when `detail` is not empty (which
/// entry of the model has the feature).
pub fn refusal(
    scheme: &str,
    family: ModelFamily,
    feature: Feature,
    detail: &str,
) -> Option<SpecError> {
    match support(scheme, family, feature)? {
        Support::Refused { field, reason } => {
            let detail = if detail.is_empty() {
                String::new()
            } else {
                format!(" ({detail})")
            };
            Some(SpecError::new(field, format!("{scheme} {reason}{detail}")))
        }
        Support::Takes | Support::NotInModel => None,
    }
}

/// [`refusal`] as a result: `Ok` when the scheme takes the feature (or the table has no word on
/// it).
pub fn check(
    scheme: &str,
    family: ModelFamily,
    feature: Feature,
    detail: &str,
) -> Result<(), SpecError> {
    refusal(scheme, family, feature, detail).map_or(Ok(()), Err)
}
