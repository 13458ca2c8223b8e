//! What the service can run, as data: every scene, scheme and contact solver with its
//! parameters, their defaults and valid ranges (gRPC `Capabilities`, `GET /v1/capabilities`,
//! `signorini capabilities`).
//!
//! Defaults are not restated here: they are read from the spec types' own `Default` values
//! (serialized), so they cannot drift from what a run uses. Ranges and descriptions are the
//! ones the builders check (`scenes.rs`, `job.rs`, `soi2`).

use crate::scenes::{BarSpec, BouncingBall, Chain};
use crate::soi2::models::{JayNegrutTest, Pendulum, SliderCrank};
use crate::spec::{
    ContactSolverSpec, HhtSoi2Spec, LinearSpec, MoreauJeanSpec, NsNewmarkSpec, OutputSpec,
    Soi2GeneralizedAlphaSpec,
};
use serde::Serialize;
use serde_json::Value;

/// One parameter of a scene, scheme or section.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Parameter {
    /// Field name in the spec.
    pub name: String,
    /// Value type (`float`, `integer`, `bool`, `string`, `[float]`, …).
    pub kind: String,
    /// Default value as JSON text, or a phrase when the default is computed.
    pub default: String,
    /// Valid range or values.
    pub range: String,
    /// What it is.
    pub description: String,
}

/// A scene, a scheme, a solver or a spec section.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Component {
    /// Name as written in specs (`scene = …`, `scheme = …`, `kind = …`, or the section).
    pub name: String,
    /// What it is.
    pub description: String,
    /// Its parameters.
    pub parameters: Vec<Parameter>,
}

/// Everything a job spec can name.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Capabilities {
    /// `[model] scene = …`.
    pub models: Vec<Component>,
    /// `[integrator] scheme = …`.
    pub integrators: Vec<Component>,
    /// `[contact_solver] kind = …`.
    pub contact_solvers: Vec<Component>,
    /// `[time]`, `[contact_solver]`, `[output]`.
    pub sections: Vec<Component>,
}

/// (name, kind, range, description)
type Row = (&'static str, &'static str, &'static str, &'static str);

/// The values serde fills in for a spec section given as `{}` (its documented defaults), or `{}`
/// when the section has required fields.
fn serde_defaults<T: Serialize + serde::de::DeserializeOwned>() -> Value {
    serde_json::from_value::<T>(Value::Object(serde_json::Map::new()))
        .ok()
        .and_then(|t| serde_json::to_value(t).ok())
        .unwrap_or_else(|| Value::Object(serde_json::Map::new()))
}

fn component<T: Serialize>(
    name: &str,
    description: &str,
    defaults: &T,
    rows: &[Row],
    unset: &str,
) -> Component {
    let defaults = serde_json::to_value(defaults).unwrap_or(Value::Null);
    Component {
        name: name.into(),
        description: description.into(),
        parameters: rows
            .iter()
            .map(|&(n, kind, range, description)| Parameter {
                name: n.into(),
                kind: kind.into(),
                default: defaults
                    .get(n)
                    .filter(|v| !v.is_null())
                    .map_or_else(|| unset.to_string(), |v| v.to_string()),
                range: range.into(),
                description: description.into(),
            })
            .collect(),
    }
}

const BAR_ROWS: &[Row] = &[
    (
        "elements",
        "integer",
        "1 … 10⁷",
        "number of linear finite elements",
    ),
    ("length", "float", "> 0", "bar length L"),
    ("young", "float", "> 0", "Young's modulus E"),
    ("density", "float", "> 0", "density ρ"),
    ("area", "float", "> 0", "cross-section A"),
    (
        "mass_matrix",
        "string",
        "lumped | consistent",
        "mass matrix of the elements",
    ),
    (
        "left",
        "string",
        "fixed | free",
        "boundary condition of the left end",
    ),
    (
        "gap",
        "float",
        "any",
        "distance from the right end to the obstacle at rest",
    ),
    (
        "restitution",
        "float",
        "[0, 1]",
        "Newton restitution at the right end",
    ),
    (
        "initial_velocity",
        "float",
        "finite",
        "uniform initial velocity toward the obstacle",
    ),
    (
        "initial_displacement",
        "float",
        "finite",
        "uniform initial displacement toward the obstacle",
    ),
    (
        "body_force",
        "float",
        "finite",
        "force per unit length toward the obstacle",
    ),
    (
        "rayleigh_mass",
        "float",
        "≥ 0",
        "Rayleigh damping C = a M + b K: a",
    ),
    ("rayleigh_stiffness", "float", "≥ 0", "Rayleigh damping: b"),
    (
        "harmonic_force",
        "{amplitude, omega}",
        "finite",
        "distributed force amplitude·sin(omega t)",
    ),
    (
        "wall_motion",
        "{amplitude, omega}",
        "finite",
        "obstacle motion amplitude·sin(omega t)",
    ),
];

/// The index-set parameters every velocity-level scheme of the linear family takes.
const INDEX_SET_ROWS: [Row; 2] = [
    (
        "activation",
        "string",
        "gap_and_velocity | predicted_gap",
        "index-set rule: (24) of Acary 2016, or Siconos' g + γhU ≤ 0",
    ),
    (
        "activation_gamma",
        "float",
        "> 0",
        "γ of the predicted-gap rule",
    ),
];

/// The escape hatch of the α-family and the baselines.
const ALLOW_UNSTABLE_ROW: Row = (
    "allow_unstable",
    "bool",
    "",
    "accept parameters outside the stability conditions",
);

const ALPHA_ROWS: [Row; 5] = [
    (
        "rho_inf",
        "float",
        "[0, 1]",
        "spectral radius at infinity (sets α_m, α_f, β, γ by (27))",
    ),
    (
        "alpha_m",
        "float",
        "α_m ≤ α_f ≤ ½",
        "α_m (instead of rho_inf)",
    ),
    ("alpha_f", "float", "≤ ½", "α_f"),
    ("beta", "float", "stability conditions", "β"),
    ("gamma", "float", "stability conditions", "γ"),
];

const POSITION_ROWS: &[Row] = &[
    ("alpha", "float", "[0, 1/3]", "HHT α (0: Newmark)"),
    ("beta", "float", "stability conditions", "β"),
    ("gamma", "float", "≥ ½", "γ"),
    ALLOW_UNSTABLE_ROW,
];

const SOI2_NEWTON_ROWS: [Row; 5] = [
    (
        "start",
        "string",
        "a0 | lunk_simeon",
        "start value of a_α: a₀ or (8)",
    ),
    (
        "newton_tolerance",
        "float",
        "> 0",
        "Newton convergence ‖Δx‖∞ ≤ tol·(1 + ‖x‖∞)",
    ),
    (
        "newton_max_iterations",
        "integer",
        "≥ 1",
        "Newton iterations per step",
    ),
    (
        "newton",
        "string",
        "simplified | full",
        "step Newton: Jacobian kept across iterations and steps while the increments contract, or rebuilt at every iterate",
    ),
    (
        "consistency_tolerance",
        "float",
        "> 0",
        "largest constraint residual accepted in the initial values",
    ),
];

/// The description of everything a job spec can name.
pub fn capabilities() -> Capabilities {
    let models = vec![
        component(
            "bouncing_ball",
            "a point mass falling onto the ground q = 0 (1 dof, 1 contact)",
            &BouncingBall::default(),
            &[
                ("mass", "float", "> 0", "mass m"),
                ("gravity", "float", "≥ 0", "gravity acceleration"),
                ("q0", "float", "≥ 0", "initial height"),
                ("v0", "float", "finite", "initial velocity"),
                ("restitution", "float", "[0, 1]", "Newton restitution e"),
            ],
            "",
        ),
        component(
            "bar",
            "elastic bar of linear finite elements, right end against an obstacle",
            &BarSpec::default(),
            BAR_ROWS,
            "scene default",
        ),
        component(
            "dep_bar",
            "Doyen–Ern–Piperno bouncing bar (Yoong et al. 2018, Table 1); same fields as bar",
            &BarSpec::default(),
            BAR_ROWS,
            "Table 1 value",
        ),
        component(
            "chain",
            "point masses joined by springs, one unilateral contact per mass against a wall",
            &Chain::default(),
            &[
                ("masses", "[float]", "each > 0, ≥ 1 entry", "the masses"),
                (
                    "stiffness",
                    "float",
                    "≥ 0",
                    "spring stiffness between neighbours",
                ),
                (
                    "positions",
                    "[float]",
                    "one per mass",
                    "initial absolute positions",
                ),
                (
                    "velocities",
                    "[float]",
                    "one per mass",
                    "initial velocities",
                ),
                ("wall", "float", "finite", "wall position"),
                ("restitution", "float", "[0, 1]", "Newton restitution"),
                (
                    "force",
                    "[float]",
                    "one per mass",
                    "constant force on each mass",
                ),
            ],
            "none",
        ),
        component(
            "linear",
            "M q̈ + C q̇ + K q = F(t) + G λ, g = g_matrix·q + g_offset ≥ 0 (dense rows or *_triplets)",
            &LinearSpec::default(),
            &[
                (
                    "mass",
                    "[[float]]",
                    "symmetric positive definite",
                    "M as dense rows (or mass_triplets)",
                ),
                (
                    "stiffness",
                    "[[float]]",
                    "symmetric positive semidefinite",
                    "K (or stiffness_triplets)",
                ),
                (
                    "damping",
                    "[[float]]",
                    "symmetric positive semidefinite",
                    "C (or damping_triplets)",
                ),
                ("force", "[float]", "n entries", "constant force"),
                (
                    "harmonic_force",
                    "[{shape, omega, phase}]",
                    "shape: n entries",
                    "harmonic force terms",
                ),
                (
                    "g_matrix",
                    "[[float]]",
                    "rows of n entries",
                    "Gᵀ, one row per contact",
                ),
                ("g_offset", "[float]", "one per contact", "gap offsets w"),
                (
                    "restitution",
                    "[float]",
                    "each in [0, 1], one per contact",
                    "Newton restitution per contact",
                ),
                ("q0", "[float]", "n entries", "initial positions"),
                ("v0", "[float]", "n entries", "initial velocities"),
            ],
            "zero / none",
        ),
        component(
            "pendulum",
            "pendulum (16) of Jay & Negrut 2008, Fig. 3 (SOI2 schemes)",
            &Pendulum::default(),
            &[
                ("mass", "float", "> 0", "m"),
                ("length", "float", "> 0", "L"),
                ("stiffness", "float", "≥ 0", "torsional spring k"),
                ("damping", "float", "≥ 0", "damper c"),
                ("gravity", "float", "finite", "g"),
                ("theta0", "float", "finite", "θ(0)"),
                ("omega0", "float", "finite", "θ'(0)"),
                ("y0", "[float]", "3 entries", "y₀ override"),
                ("z0", "[float]", "3 entries", "z₀ override"),
            ],
            "from θ(0), θ'(0)",
        ),
        component(
            "slider_crank",
            "rigid slider-crank under gravity (SOI2 schemes)",
            &SliderCrank::default(),
            &[
                ("crank_length", "float", "> 0", "crank length r"),
                ("crank_mass", "float", "> 0", "crank mass"),
                ("rod_length", "float", "≥ crank_length", "rod length l"),
                ("rod_mass", "float", "> 0", "rod mass"),
                ("slider_mass", "float", "> 0", "slider mass"),
                ("gravity", "float", "finite", "g"),
                ("crank_angle", "float", "finite", "initial crank angle θ₀"),
                ("crank_speed", "float", "finite", "initial crank speed θ'₀"),
            ],
            "",
        ),
        component(
            "jay_negrut_test",
            "test problem (15) of Jay & Negrut 2008 with its exact solution (summary has `errors`)",
            &JayNegrutTest::default(),
            &[
                ("y0", "[float]", "2 entries", "y₀ override"),
                ("z0", "[float]", "2 entries", "z₀ override"),
            ],
            "the paper's values",
        ),
    ];
    let with_index_set = |head: &[Row], unstable: bool| -> Vec<Row> {
        let tail = unstable.then_some(ALLOW_UNSTABLE_ROW);
        head.iter()
            .copied()
            .chain(INDEX_SET_ROWS)
            .chain(tail)
            .collect()
    };
    let mj_rows = with_index_set(
        &[(
            "theta",
            "float",
            "[0, 1]",
            "θ of the force average and the position update",
        )],
        false,
    );
    let newmark_rows = with_index_set(
        &[
            ("beta", "float", "stability: 2β ≥ γ ≥ ½", "Newmark β"),
            ("gamma", "float", "≥ ½", "Newmark γ"),
        ],
        true,
    );
    let hht_alpha_rows = with_index_set(
        &[
            ("alpha", "float", "[0, 1/3]", "HHT α"),
            ("beta", "float", "default (1 + α)²/4", "β"),
            ("gamma", "float", "default ½ + α", "γ"),
        ],
        true,
    );
    let alpha_rows = with_index_set(&ALPHA_ROWS, true);
    let soi2_ga_rows: Vec<Row> = [
        (
            "rho_inf",
            "float",
            "[0, 1]",
            "spectral radius at infinity (sets α_m, α_f, β, γ)",
        ),
        (
            "alpha_m",
            "float",
            "≠ 1, |α_m/(1−α_m)| ≤ 1",
            "α_m (instead of rho_inf)",
        ),
        ("alpha_f", "float", "≠ 1", "α_f"),
        ("beta", "float", "≠ 0", "β"),
        ("gamma", "float", "≠ 0", "γ"),
        (
            "additive",
            "bool",
            "true only for additive forces",
            "additive-force form of (13d)",
        ),
    ]
    .into_iter()
    .chain(SOI2_NEWTON_ROWS)
    .collect();
    let hht_rows: Vec<Row> = [("alpha", "float", "[−1/3, 0]", "HHT α")]
        .into_iter()
        .chain(SOI2_NEWTON_ROWS)
        .collect();
    let integrators = vec![
        component(
            "moreau_jean",
            "Moreau–Jean θ-scheme, Acary 2016 (21)–(24)",
            &MoreauJeanSpec::default(),
            &mj_rows,
            "1 (predicted_gap only)",
        ),
        component(
            "moreau_jean_variant",
            "Moreau–Jean variant (29): q_{k+1} = q_k + h v_{k+1/2}",
            &MoreauJeanSpec::default(),
            &mj_rows,
            "1 (predicted_gap only)",
        ),
        component(
            "ns_newmark",
            "nonsmooth Newmark, Acary 2016 (25)–(27) with α_m = α_f = 0",
            &serde_defaults::<NsNewmarkSpec>(),
            &newmark_rows,
            "none",
        ),
        component(
            "ns_hht",
            "nonsmooth HHT, Acary 2016 (α_m = 0, α_f = α)",
            &serde_json::json!({}),
            &hht_alpha_rows,
            "none (alpha required; beta, gamma derived: see range)",
        ),
        component(
            "ns_generalized_alpha",
            "nonsmooth generalized-α, Acary 2016 (25)–(27)",
            &serde_json::json!({}),
            &alpha_rows,
            "from rho_inf",
        ),
        component(
            "ns_kh_alpha",
            "Krenk–Høgsberg generalized-α variant (30), Acary 2016",
            &serde_json::json!({}),
            &alpha_rows,
            "from rho_inf",
        ),
        component(
            "newmark_position_contact",
            "baseline: smooth Newmark with a position-level contact multiplier",
            &serde_json::json!({}),
            POSITION_ROWS,
            "none (beta ¼, gamma ½ when unset)",
        ),
        component(
            "hht_position_contact",
            "baseline: smooth HHT with a position-level contact multiplier",
            &serde_json::json!({}),
            POSITION_ROWS,
            "none (alpha required; beta, gamma as for ns_hht)",
        ),
        component(
            "wfem",
            "wave finite elements (Yoong et al. 2018), Δt = Δx/c, for the bar and dep_bar scenes",
            &serde_json::json!({}),
            &[],
            "",
        ),
        component(
            "soi2_generalized_alpha",
            "generalized-α-SOI2, Jay & Negrut 2008 (13), Newton iterations",
            &Soi2GeneralizedAlphaSpec::default(),
            &soi2_ga_rows,
            "rho_inf = 0.2 unless alpha_m/alpha_f given",
        ),
        component(
            "soi2_hht",
            "HHT-SOI2, Jay & Negrut 2008 (17)",
            &HhtSoi2Spec::default(),
            &hht_rows,
            "",
        ),
        component(
            "hht_i3",
            "HHT-I3 (index 3, position constraints only): baseline of HHT-SOI2",
            &HhtSoi2Spec::default(),
            &hht_rows,
            "",
        ),
    ];
    let solver = |name: &str, description: &str| Component {
        name: name.into(),
        description: description.into(),
        parameters: Vec::new(),
    };
    let contact_solvers = vec![
        solver(
            "auto",
            "enumeration up to 3 unknowns, Lemke up to 200, projected Gauss–Seidel above",
        ),
        solver(
            "lemke",
            "Lemke's complementary pivoting (exact up to round-off)",
        ),
        solver("pgs", "projected Gauss–Seidel (large symmetric problems)"),
        solver(
            "enum",
            "enumeration of index sets (tiny problems, reference)",
        ),
    ];
    let sections = vec![
        component(
            "time",
            "step size and duration (t_end or steps)",
            &serde_json::json!({}),
            &[
                ("h", "float", "> 0", "step size (required)"),
                ("t_end", "float", "≥ 0", "final time (or steps)"),
                ("steps", "integer", "≥ 0", "number of steps (or t_end)"),
                (
                    "pattern",
                    "[float]",
                    "each > 0",
                    "relative step sizes repeated (variable-step schemes)",
                ),
                (
                    "adjust",
                    "bool",
                    "",
                    "step-size adjusting formulas (14) (variable-step schemes)",
                ),
            ],
            "required / unset",
        ),
        component(
            "contact_solver",
            "LCP solver settings",
            &ContactSolverSpec::default(),
            &[
                ("kind", "string", "auto | lemke | pgs | enum", "solver"),
                (
                    "tolerance",
                    "float",
                    "> 0",
                    "largest complementarity error accepted",
                ),
                ("max_iterations", "integer", "≥ 1", "pivot or sweep budget"),
            ],
            "",
        ),
        component(
            "output",
            "what to record",
            &OutputSpec::default(),
            &[
                (
                    "every",
                    "integer",
                    "≥ 1",
                    "record every k-th step (the last always)",
                ),
                (
                    "probes",
                    "[integer]",
                    "dof indices < n",
                    "dofs whose q_j, v_j are recorded",
                ),
            ],
            "",
        ),
    ];
    Capabilities {
        models,
        integrators,
        contact_solvers,
        sections,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::{IntegratorSpec, ModelSpec};

    /// Every scene and scheme name pinned in DESIGN.md §7 that the spec types accept is described.
    #[test]
    fn every_accepted_scene_and_scheme_is_described() {
        let caps = capabilities();
        let scenes = [
            "bouncing_ball",
            "bar",
            "dep_bar",
            "chain",
            "linear",
            "pendulum",
            "slider_crank",
            "jay_negrut_test",
        ];
        for s in scenes {
            let accepted = serde_json::from_value::<ModelSpec>(serde_json::json!({ "scene": s }))
                .map_err(|e| e.to_string())
                .map_or_else(|e| !e.contains("unknown variant"), |_| true);
            if accepted {
                assert!(
                    caps.models.iter().any(|m| m.name == s),
                    "scene {s} missing from capabilities"
                );
            }
        }
        let schemes = [
            "moreau_jean",
            "moreau_jean_variant",
            "ns_newmark",
            "ns_hht",
            "ns_generalized_alpha",
            "ns_kh_alpha",
            "newmark_position_contact",
            "hht_position_contact",
            "wfem",
            "soi2_generalized_alpha",
            "soi2_hht",
            "hht_i3",
        ];
        for s in schemes {
            let accepted =
                serde_json::from_value::<IntegratorSpec>(serde_json::json!({ "scheme": s }))
                    .map_err(|e| e.to_string())
                    .map_or_else(|e| !e.contains("unknown variant"), |_| true);
            if accepted {
                assert!(
                    caps.integrators.iter().any(|m| m.name == s),
                    "scheme {s} missing from capabilities"
                );
            }
        }
        // Every field a SOI2 scheme's spec serialises (all of them have defaults) is listed.
        for (name, spec) in [
            (
                "soi2_generalized_alpha",
                serde_json::to_value(crate::spec::Soi2GeneralizedAlphaSpec::default()),
            ),
            (
                "soi2_hht",
                serde_json::to_value(crate::spec::HhtSoi2Spec::default()),
            ),
            (
                "hht_i3",
                serde_json::to_value(crate::spec::HhtSoi2Spec::default()),
            ),
        ] {
            let c = caps
                .integrators
                .iter()
                .find(|c| c.name == name)
                .expect("described");
            let fields = spec.expect("serialises");
            for field in fields.as_object().expect("an object").keys() {
                assert!(
                    c.parameters.iter().any(|p| &p.name == field),
                    "{name}.{field} missing from capabilities"
                );
            }
        }
        let newton = caps
            .integrators
            .iter()
            .filter(|c| ["soi2_generalized_alpha", "soi2_hht", "hht_i3"].contains(&c.name.as_str()))
            .map(|c| c.parameters.iter().find(|p| p.name == "newton"))
            .collect::<Vec<_>>();
        assert_eq!(newton.len(), 3);
        for p in newton {
            let p = p.expect("newton listed");
            assert_eq!(p.default, "\"simplified\"");
            assert_eq!(p.range, "simplified | full");
        }
        for c in caps.models.iter().chain(&caps.integrators) {
            for p in &c.parameters {
                assert!(
                    !p.range.is_empty() || p.kind == "bool",
                    "{}.{} has no range",
                    c.name,
                    p.name
                );
            }
        }
    }
}
