//! What the service can run, as data: every scene, scheme, analysis and contact solver with its
//! parameters, their defaults and valid ranges (gRPC `Capabilities`, `GET /v1/capabilities`,
//! `signorini capabilities`).
//!
//! Nothing here is written by hand: the description is read from the JSON Schema of the spec
//! ([`crate::spec::json_schema`]), itself generated from the spec types. Each variant of a tagged
//! section (`scene`, `scheme`, `kind`) is a component, each of its fields a parameter with the
//! field's doc comment, its serde default and the range the schema states (closed bounds and
//! enumerated values; the doc comment says the rest).

use crate::spec::json_schema;
use crate::spec::support::{SchemeSupport, TABLE};
use serde::Serialize;
use serde_json::{Map, Value};

/// One parameter of a scene, scheme or section.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Parameter {
    /// Field name in the spec.
    pub name: String,
    /// Value type (`float`, `integer`, `bool`, `string`, `[float]`, …).
    pub kind: String,
    /// Default value as JSON text, or `unset` when the field has no default (optional, or
    /// computed from other fields: see the description).
    pub default: String,
    /// Valid range or values.
    pub range: String,
    /// What it is.
    pub description: String,
}

/// A scene, a scheme, an analysis, a solver or a spec section.
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
    /// `[analysis] kind = …`.
    pub analyses: Vec<Component>,
    /// `[contact_solver] kind = …`.
    pub contact_solvers: Vec<Component>,
    /// `[time]`, `[contact_solver]`, `[output]`.
    pub sections: Vec<Component>,
    /// Which scheme takes which feature of which model family: the scheme × feature table the
    /// validation refuses from ([`crate::spec::support::TABLE`]), row for row.
    pub support: Vec<SchemeSupport>,
}

/// The description of everything a job spec can name, read from the spec's JSON Schema.
pub fn capabilities() -> Capabilities {
    let schema = json_schema();
    let defs = schema
        .get("$defs")
        .and_then(Value::as_object)
        .cloned()
        .unwrap_or_default();
    let walk = Walk { defs: &defs };
    let sections = ["time", "contact_solver", "output"]
        .iter()
        .filter_map(|&name| {
            let section = walk.resolve(schema.get("properties")?.get(name)?);
            Some(walk.component(name, &section, None))
        })
        .collect();
    Capabilities {
        models: walk.variants("ModelSpec", "scene"),
        integrators: walk.variants("IntegratorSpec", "scheme"),
        analyses: walk.variants("AnalysisSpec", "kind"),
        contact_solvers: walk
            .enum_values("LcpSolverKind")
            .into_iter()
            .map(|(name, description)| Component {
                name,
                description,
                parameters: Vec::new(),
            })
            .collect(),
        sections,
        support: TABLE.to_vec(),
    }
}

/// Reads components and parameters out of the schema's definitions.
struct Walk<'a> {
    defs: &'a Map<String, Value>,
}

/// One line of a doc comment's text.
fn text(v: Option<&Value>) -> String {
    v.and_then(Value::as_str)
        .unwrap_or_default()
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
}

/// A bound as written in a range: integers without a decimal point.
fn number(v: &Value) -> String {
    match v.as_f64() {
        Some(x) if x.fract() == 0.0 && x.abs() < 1e15 => format!("{}", x as i64),
        Some(x) => format!("{x}"),
        None => v.to_string(),
    }
}

impl Walk<'_> {
    /// `schema` with a `$ref` replaced by its definition (its own keywords kept over the
    /// definition's), and `anyOf: [X, null]` (an optional field) by X.
    fn resolve(&self, schema: &Value) -> Value {
        let Some(obj) = schema.as_object() else {
            return schema.clone();
        };
        let mut out = Map::new();
        if let Some(target) = obj
            .get("$ref")
            .and_then(Value::as_str)
            .and_then(|r| r.strip_prefix("#/$defs/"))
            .and_then(|name| self.defs.get(name))
            && let Some(def) = self.resolve(target).as_object()
        {
            out.extend(def.clone());
        }
        if let Some(options) = obj.get("anyOf").and_then(Value::as_array) {
            let non_null: Vec<&Value> = options
                .iter()
                .filter(|o| o.get("type").and_then(Value::as_str) != Some("null"))
                .collect();
            if let [one] = non_null.as_slice()
                && let Some(inner) = self.resolve(one).as_object()
            {
                out.extend(inner.clone());
            }
        }
        for (k, v) in obj {
            if k != "$ref" && k != "anyOf" {
                out.insert(k.clone(), v.clone());
            }
        }
        Value::Object(out)
    }

    /// The components of a tagged enum definition (`oneOf` of objects whose `tag` is a const).
    fn variants(&self, def: &str, tag: &str) -> Vec<Component> {
        let Some(options) = self
            .defs
            .get(def)
            .and_then(|d| d.get("oneOf"))
            .and_then(Value::as_array)
        else {
            return Vec::new();
        };
        options
            .iter()
            .filter_map(|v| {
                let v = self.resolve(v);
                let name = v.get("properties")?.get(tag)?.get("const")?.as_str()?;
                Some(self.component(name, &v, Some(tag)))
            })
            .collect()
    }

    /// The (value, description) pairs of a unit-enum definition.
    fn enum_values(&self, def: &str) -> Vec<(String, String)> {
        let Some(d) = self.defs.get(def) else {
            return Vec::new();
        };
        Self::values(d)
    }

    fn values(d: &Value) -> Vec<(String, String)> {
        if let Some(options) = d.get("oneOf").and_then(Value::as_array) {
            return options
                .iter()
                .filter_map(|o| {
                    let value = o.get("const")?.as_str()?.to_string();
                    Some((value, text(o.get("description"))))
                })
                .collect();
        }
        d.get("enum")
            .and_then(Value::as_array)
            .map(|e| {
                e.iter()
                    .filter_map(|v| Some((v.as_str()?.to_string(), String::new())))
                    .collect()
            })
            .unwrap_or_default()
    }

    /// A component: the object schema's description and its properties but the tag.
    fn component(&self, name: &str, schema: &Value, tag: Option<&str>) -> Component {
        let parameters = schema
            .get("properties")
            .and_then(Value::as_object)
            .map(|props| {
                props
                    .iter()
                    .filter(|(k, _)| Some(k.as_str()) != tag)
                    .map(|(k, p)| self.parameter(k, p))
                    .collect()
            })
            .unwrap_or_default();
        Component {
            name: name.into(),
            description: text(schema.get("description")),
            parameters,
        }
    }

    fn parameter(&self, name: &str, property: &Value) -> Parameter {
        let p = self.resolve(property);
        Parameter {
            name: name.into(),
            kind: self.kind(&p),
            default: p
                .get("default")
                .filter(|v| !v.is_null())
                .map_or_else(|| "unset".to_string(), Value::to_string),
            range: self.range(&p),
            description: text(p.get("description")),
        }
    }

    /// The JSON type of a schema, nulls left out.
    fn json_type(p: &Value) -> Option<String> {
        match p.get("type") {
            Some(Value::String(t)) => Some(t.clone()),
            Some(Value::Array(ts)) => ts
                .iter()
                .filter_map(Value::as_str)
                .find(|t| *t != "null")
                .map(String::from),
            _ if p.get("oneOf").is_some() || p.get("enum").is_some() => Some("string".into()),
            _ => None,
        }
    }

    /// `float`, `integer`, `bool`, `string`, `[float]`, `[[integer, integer, float]]`, `{a, b}`.
    fn kind(&self, p: &Value) -> String {
        match Self::json_type(p).as_deref() {
            Some("number") => "float".into(),
            Some("integer") => "integer".into(),
            Some("boolean") => "bool".into(),
            Some("string") => "string".into(),
            Some("array") => {
                if let Some(items) = p.get("prefixItems").and_then(Value::as_array) {
                    let kinds: Vec<String> =
                        items.iter().map(|i| self.kind(&self.resolve(i))).collect();
                    format!("[{}]", kinds.join(", "))
                } else {
                    let items = p.get("items").map(|i| self.resolve(i));
                    format!("[{}]", items.map_or_else(String::new, |i| self.kind(&i)))
                }
            }
            Some("object") => {
                let fields: Vec<&str> = p
                    .get("properties")
                    .and_then(Value::as_object)
                    .map(|o| o.keys().map(String::as_str).collect())
                    .unwrap_or_default();
                format!("{{{}}}", fields.join(", "))
            }
            _ => "any".into(),
        }
    }

    /// The range the schema states: enumerated values, closed or open bounds; otherwise what
    /// the type allows.
    fn range(&self, p: &Value) -> String {
        let values = Self::values(p);
        if !values.is_empty() {
            return values
                .iter()
                .map(|(v, _)| v.as_str())
                .collect::<Vec<_>>()
                .join(" | ");
        }
        let lower = p
            .get("exclusiveMinimum")
            .map(|v| ("(", "> ", number(v)))
            .or_else(|| p.get("minimum").map(|v| ("[", "≥ ", number(v))));
        let upper = p.get("maximum").map(number);
        match (lower, upper) {
            (Some((bracket, _, lo)), Some(hi)) => format!("{bracket}{lo}, {hi}]"),
            (Some((_, op, lo)), None) => format!("{op}{lo}"),
            (None, Some(hi)) => format!("≤ {hi}"),
            (None, None) => match Self::json_type(p).as_deref() {
                Some("number") => "finite".into(),
                Some("boolean") => String::new(),
                Some("array") => "list".into(),
                Some("object") => "table".into(),
                _ => "any".into(),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::{IntegratorSpec, ModelSpec};

    /// Every scene and scheme name of the public spec contract that the spec types accept is
    /// described.
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

    /// Read from the schema, the description misses nothing the spec types say: every component
    /// and parameter has its doc comment, every analysis and section is listed, and the shared
    /// groups appear in each scheme that flattens them.
    #[test]
    fn generated_from_the_spec_types() {
        let caps = capabilities();
        let names = |cs: &[Component]| cs.iter().map(|c| c.name.clone()).collect::<Vec<_>>();
        assert_eq!(
            names(&caps.analyses),
            ["nonsmooth_modes", "forced_response"]
        );
        assert_eq!(names(&caps.sections), ["time", "contact_solver", "output"]);
        assert_eq!(
            names(&caps.contact_solvers),
            ["auto", "lemke", "pgs", "enum", "banded_active_set"]
        );
        for c in caps
            .models
            .iter()
            .chain(&caps.integrators)
            .chain(&caps.analyses)
            .chain(&caps.sections)
            .chain(&caps.contact_solvers)
        {
            assert!(!c.description.is_empty(), "{} has no description", c.name);
            for p in &c.parameters {
                assert!(!p.description.is_empty(), "{}.{}", c.name, p.name);
            }
        }
        for scheme in ["moreau_jean", "ns_newmark", "ns_hht", "ns_kh_alpha"] {
            let c = caps
                .integrators
                .iter()
                .find(|c| c.name == scheme)
                .expect(scheme);
            let gamma = c.parameters.iter().find(|p| p.name == "activation_gamma");
            assert_eq!(gamma.map(|p| p.range.as_str()), Some("> 0"), "{scheme}");
        }
        let every = &caps.sections[2].parameters[0];
        assert_eq!(
            (every.name.as_str(), every.default.as_str()),
            ("every", "1")
        );
    }
}
