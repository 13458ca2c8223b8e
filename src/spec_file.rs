//! Reading job specs from TOML or JSON text, with errors that name the field.

use serde::de::DeserializeOwned;
use serde_json::{Map, Value};
use signorini_core::job::Job;
use signorini_core::spec::study::ReferenceRun;
use signorini_core::spec::{IntegratorSpec, JobSpec, ModelSpec, SpecError};
use std::path::Path;

/// Spec text formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// TOML (`.toml`).
    Toml,
    /// JSON (`.json`).
    Json,
}

impl Format {
    /// The format a path's extension names (TOML unless it ends in `.json`).
    pub fn of_path(path: &Path) -> Format {
        match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("json") => Format::Json,
            _ => Format::Toml,
        }
    }
}

/// Parses spec text. Errors name the field by its dotted path (`model.mas: unknown field …`).
pub fn parse(text: &str, format: Format) -> Result<JobSpec, SpecError> {
    parse_tracked(text, format).map_err(|e| match tree(text, format) {
        Some(root) => {
            let e = section_error(&root, e);
            nested_error(&root, e)
        }
        None => e,
    })
}

/// The error of a section read as a whole, located inside `model` or `integrator` when serde
/// could only name the section.
fn section_error(root: &Value, e: SpecError) -> SpecError {
    {
        let missing = e.reason.starts_with("missing field");
        match (e.field.as_str(), Some(root.clone())) {
            (f, Some(root)) if f == "model" || f.starts_with("model.") => {
                match scene_error(&root) {
                    Some(located) => located,
                    None if f == "model" || f == "model.scene" || missing => {
                        refine::<ModelSpec>(&root, "model", "scene", e)
                    }
                    None => e,
                }
            }
            ("integrator" | "integrator.scheme", Some(root)) => {
                refine::<IntegratorSpec>(&root, "integrator", "scheme", e)
            }
            // serde reports a missing field before it reads the flattened field groups: a
            // field of the section that is wrong in itself comes first, as without the groups.
            (f, Some(root)) if missing && f.starts_with("integrator.") => {
                refine::<IntegratorSpec>(&root, "integrator", "scheme", e)
            }
            _ => e,
        }
    }
}

/// Tag fields of the spec's tagged tables: never the culprit of an error other than an
/// unknown variant (which [`located`] names already).
const TAGS: [&str; 3] = ["scene", "scheme", "kind"];

/// An error serde could only locate at a table (or list) that holds the bad field, made
/// precise: a study's inline base is read as a spec of its own (`study.base.time.h`), its
/// reference as a reference run (`study.reference.h`), and any other table tagged by `kind` or
/// `scheme` (a rigid body's `shape`, `analysis`, `study.schemes[i]`), which serde buffers
/// before its variant is known, is searched by [`pinpoint`].
fn nested_error(root: &Value, e: SpecError) -> SpecError {
    let settled = [
        "unknown field",
        "unknown variant",
        "missing field",
        "malformed",
    ];
    if settled.iter().any(|p| e.reason.starts_with(p)) {
        return e;
    }
    let Some(at) = root.pointer(&pointer(&e.field)) else {
        return e;
    };
    if !(at.is_object() || at.is_array()) {
        return e;
    }
    match e.field.as_str() {
        "study.base" if at.is_object() => match parse(&at.to_string(), Format::Json) {
            Err(inner) => SpecError::new(format!("study.base.{}", inner.field), inner.reason),
            Ok(_) => e,
        },
        "study.reference" if at.is_object() => {
            let read = |v: &Value| {
                serde_path_to_error::deserialize::<_, ReferenceRun>(v.clone())
                    .map(drop)
                    .map_err(|e| located(e.path().to_string(), e.inner().to_string()))
            };
            match read(at) {
                Err(inner) => {
                    let inner = pinpoint(at, inner, &read);
                    let field = match inner.field.as_str() {
                        "spec" => "study.reference".to_string(),
                        f => format!("study.reference.{f}"),
                    };
                    SpecError::new(field, inner.reason)
                }
                Ok(()) => e,
            }
        }
        _ => pinpoint(root, e, &|v: &Value| {
            parse_tracked(&v.to_string(), Format::Json).map(drop)
        }),
    }
}

/// The JSON pointer of a dotted field path (`study.schemes[1]` → `/study/schemes/1`).
fn pointer(field: &str) -> String {
    let mut out = String::new();
    for part in field.split('.') {
        let (key, indices) = part.split_once('[').unwrap_or((part, ""));
        out.push('/');
        out.push_str(key);
        for index in indices.split('[') {
            let index = index.trim_end_matches(']');
            if !index.is_empty() {
                out.push('/');
                out.push_str(index);
            }
        }
    }
    out
}

/// The field inside the table (or list) `error` is located at that causes it: the first entry
/// whose removal (in a list: whose replacement by its neighbour, so lengths stay) changes the
/// error `read` gives for `root`; searched again inside that entry while it is a table or a
/// list. `error` as it is when no entry changes it.
fn pinpoint(
    root: &Value,
    error: SpecError,
    read: &dyn Fn(&Value) -> Result<(), SpecError>,
) -> SpecError {
    let mut field = error.field.clone();
    'deeper: for _ in 0..16 {
        let here = if field == "spec" {
            String::new()
        } else {
            pointer(&field)
        };
        let Some(at) = root.pointer(&here) else {
            break;
        };
        let keys: Vec<String> = match at {
            Value::Object(table) => table
                .keys()
                .filter(|k| !TAGS.contains(&k.as_str()))
                .cloned()
                .collect(),
            Value::Array(list) if list.len() >= 2 => {
                (0..list.len()).map(|i| i.to_string()).collect()
            }
            _ => break,
        };
        for key in keys {
            let mut probe = root.clone();
            match probe.pointer_mut(&here) {
                Some(Value::Object(table)) => {
                    table.remove(&key);
                }
                Some(Value::Array(list)) => {
                    let i: usize = key.parse().unwrap_or_default();
                    list[i] = list[(i + 1) % list.len()].clone();
                }
                _ => break 'deeper,
            }
            // JSON's messages end in the position, which any removal moves.
            let same = matches!(read(&probe), Err(e)
                if e.field == error.field && without_position(&e.reason) == without_position(&error.reason));
            if !same {
                field = match (field.as_str(), at.is_array()) {
                    ("spec", _) => key,
                    (_, true) => format!("{field}[{key}]"),
                    (_, false) => format!("{field}.{key}"),
                };
                continue 'deeper;
            }
        }
        break;
    }
    SpecError::new(field, error.reason)
}

/// A serde_json message without its trailing ` at line L column C`.
fn without_position(reason: &str) -> &str {
    reason
        .rsplit_once(" at line ")
        .map_or(reason, |(message, _)| message)
}

fn parse_tracked(text: &str, format: Format) -> Result<JobSpec, SpecError> {
    match format {
        Format::Json => {
            let de = &mut serde_json::Deserializer::from_str(text);
            serde_path_to_error::deserialize(de).map_err(|e| {
                let inner = e.inner();
                if inner.is_syntax() || inner.is_eof() {
                    // Not JSON: where the text breaks, not the field serde was reading.
                    let message = inner.to_string();
                    let message = message
                        .rsplit_once(" at line ")
                        .map_or(message.as_str(), |(m, _)| m);
                    return SpecError::new(
                        "spec",
                        format!(
                            "malformed JSON at line {}, column {}: {message}",
                            inner.line(),
                            inner.column()
                        ),
                    );
                }
                located(e.path().to_string(), inner.to_string())
            })
        }
        Format::Toml => {
            let de = toml::Deserializer::parse(text).map_err(|e| {
                let at = e.span().map(|span| {
                    let before = &text[..span.start.min(text.len())];
                    let line = before.matches('\n').count() + 1;
                    let column = before.chars().rev().take_while(|&c| c != '\n').count() + 1;
                    format!(" at line {line}, column {column}")
                });
                SpecError::new(
                    "spec",
                    format!("malformed TOML{}: {}", at.unwrap_or_default(), e.message()),
                )
            })?;
            serde_path_to_error::deserialize(de)
                .map_err(|e| located(e.path().to_string(), e.inner().message().to_string()))
        }
    }
}

/// The spec as a JSON tree (TOML converts losslessly for our purposes).
fn tree(text: &str, format: Format) -> Option<Value> {
    match format {
        Format::Json => serde_json::from_str(text).ok(),
        Format::Toml => toml::from_str(text).ok(),
    }
}

/// A tagged section (`[model]` tagged by `scene`, `[integrator]` by `scheme`) is buffered by
/// serde before its variant is known, so a type error inside it comes back located at the
/// section only, and an unknown value of an enumerated field (`start = "x"`, `newton = "x"`)
/// reads like an unknown tag ("unknown variant"). Find the field: when the tag alone is
/// accepted (or only misses required fields), try the section's fields one at a time, each with
/// the tag, and name the first one that alone reproduces an error other than a missing field.
fn refine<T: DeserializeOwned>(
    root: &Value,
    section: &str,
    tag: &str,
    error: SpecError,
) -> SpecError {
    let Some(fields) = root.get(section).and_then(Value::as_object) else {
        return error;
    };
    let Some(tag_value) = fields.get(tag) else {
        return error;
    };
    let tag_only = Map::from_iter([(tag.to_string(), tag_value.clone())]);
    if let Err(e) = serde_json::from_value::<T>(Value::Object(tag_only))
        && !e.to_string().starts_with("missing field")
    {
        // The tag itself is at fault (an unknown scene or scheme).
        return error;
    }
    for (key, value) in fields.iter().filter(|(k, _)| k.as_str() != tag) {
        let probe = Map::from_iter([
            (tag.to_string(), tag_value.clone()),
            (key.clone(), value.clone()),
        ]);
        if let Some(reason) = probe_error::<T>(probe) {
            return SpecError::new(format!("{section}.{key}"), reason);
        }
    }
    error
}

/// The error of the `[model]` table read as its scene's own struct, located by its full path
/// (`model.q0[0]`, `model.contacts[0].restitutin`); `None` when the scene is unknown (the tag is
/// at fault) or the fields read without error.
fn scene_error(root: &Value) -> Option<SpecError> {
    let mut fields = root.get("model")?.as_object()?.clone();
    let Some(Value::String(scene)) = fields.remove("scene") else {
        return None;
    };
    let mut track = serde_path_to_error::Track::new();
    let de = serde_path_to_error::Deserializer::new(Value::Object(fields), &mut track);
    let error = ModelSpec::from_scene_fields(&scene, de)?.err()?;
    let path = track.path().to_string();
    let path = if path == "." {
        "model".to_string()
    } else {
        format!("model.{path}")
    };
    Some(located(path, error.to_string()))
}

/// Why a probe (the tag and one field) fails, unless only for a missing field. serde
/// reports a missing required field (`ns_hht`'s `alpha`) before it reads the flattened field
/// groups (the index set, the Newton settings), so each missing field is filled with a number
/// (every required field of a tagged section is one) and the probe tried again.
fn probe_error<T: DeserializeOwned>(mut probe: Map<String, Value>) -> Option<String> {
    for _ in 0..8 {
        let message = serde_json::from_value::<T>(Value::Object(probe.clone()))
            .err()?
            .to_string();
        let Some(rest) = message.strip_prefix("missing field `") else {
            return Some(message);
        };
        let missing = rest.split('`').next().unwrap_or_default().to_string();
        if probe.contains_key(&missing) {
            return None;
        }
        probe.insert(missing, Value::from(0.0));
    }
    None
}

/// Parses and validates: the one entry point from text to a runnable [`Job`].
pub fn load(text: &str, format: Format) -> Result<Job, SpecError> {
    Job::from_spec(&parse(text, format)?)
}

/// Turns serde's (path, message) into a field error. serde reports an unknown tag as an error
/// on the enclosing section; we name the tag field (`model.scene`, `integrator.scheme`).
fn located(path: String, message: String) -> SpecError {
    let path = if path == "." { String::new() } else { path };
    let field = if message.starts_with("unknown variant") {
        match path.as_str() {
            "model" => "model.scene".to_string(),
            "integrator" => "integrator.scheme".to_string(),
            _ => path,
        }
    } else if let Some(rest) = message.strip_prefix("unknown field `") {
        let name = rest.split('`').next().unwrap_or_default();
        if path.is_empty() {
            name.to_string()
        } else if path.ends_with(&format!(".{name}")) {
            // A deserializer that tracked the key itself (a table read outside a tagged section).
            path
        } else {
            format!("{path}.{name}")
        }
    } else if let Some(rest) = message.strip_prefix("missing field `") {
        let name = rest.split('`').next().unwrap_or_default();
        if path.is_empty() {
            name.to_string()
        } else {
            format!("{path}.{name}")
        }
    } else {
        path
    };
    let field = if field.is_empty() {
        "spec".to_string()
    } else {
        field
    };
    SpecError::new(field, message)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Text that is not JSON (or TOML) is reported where it breaks, by line and column, under
    /// the field `spec` (it used to name whatever field serde was in, e.g. `model.?`).
    #[test]
    fn malformed_text_is_located_by_line_and_column() {
        let e = parse(
            "{\"model\": {\"scene\": \"bouncing_ball\",\n  \"mass\": 1.0,,}}",
            Format::Json,
        )
        .unwrap_err();
        assert_eq!(e.field, "spec", "{e}");
        assert!(
            e.reason
                .starts_with("malformed JSON at line 2, column 15: "),
            "{e}"
        );
        let e = parse("{\"model\": {", Format::Json).unwrap_err();
        assert_eq!(e.field, "spec", "{e}");
        assert!(
            e.reason
                .starts_with("malformed JSON at line 1, column 11: "),
            "{e}"
        );
        let e = parse(
            "[model]\nscene = \"bouncing_ball\"\nmass = = 1\n",
            Format::Toml,
        )
        .unwrap_err();
        assert_eq!(e.field, "spec", "{e}");
        assert!(
            e.reason.starts_with("malformed TOML at line 3, column 8"),
            "{e}"
        );
    }

    #[test]
    fn unknown_field_and_scene_are_named() {
        let e = parse(
            "[model]\nscene = \"bouncing_ball\"\nmas = 1.0\n[time]\nh = 0.01\nsteps = 1\n",
            Format::Toml,
        )
        .unwrap_err();
        assert_eq!(e.field, "model.mas", "{e}");
        let e = parse(
            "[model]\nscene = \"bouncy\"\n[time]\nh = 0.01\nsteps = 1\n",
            Format::Toml,
        )
        .unwrap_err();
        assert_eq!(e.field, "model.scene", "{e}");
        let e = parse(
            r#"{"model": {"scene": "chain", "masses": "x"}, "time": {"h": 1, "steps": 1}}"#,
            Format::Json,
        )
        .unwrap_err();
        assert_eq!(e.field, "model.masses", "{e}");
    }

    /// Issue 30: a bad field inside a scene's table is named by its full path, not by the
    /// first field a probe happened to try (`model.contacts` for a value of the wrong type in `q0`) nor by the
    /// table (`model.restitutin` for a typo inside a contact), in TOML and JSON.
    #[test]
    fn a_bad_field_inside_a_scene_is_named_by_its_path() {
        let toml = |model: &str| {
            format!(
                "[model]\nscene = \"lagrangian\"\ncoordinates = [\"a\", \"b\"]\nmass = [[1, 0], [0, 1]]\n{model}\n[integrator]\nscheme = \"moreau_jean\"\n[time]\nh = 0.01\nt_end = 1\n"
            )
        };
        let e = parse(
            &toml("q0 = [true, -1.4]\n[[model.contacts]]\ngap = \"a\"\n"),
            Format::Toml,
        )
        .unwrap_err();
        assert_eq!(e.field, "model.q0[0]", "{e}");
        assert!(e.reason.contains("invalid type: boolean"), "{e}");
        let e = parse(
            &toml("q0 = [0, 0]\n[[model.contacts]]\ngap = \"a\"\nrestitutin = 0.5\n"),
            Format::Toml,
        )
        .unwrap_err();
        assert_eq!(e.field, "model.contacts[0].restitutin", "{e}");
        assert!(e.reason.contains("unknown field"), "{e}");
        let e = parse(
            r#"{"model": {"scene": "lagrangian", "coordinates": ["a", "b"], "mass": [[1, 0], [0, 1]], "contacts": [{"gap": "a"}], "q0": [true, -1.4]}, "time": {"h": 0.01, "t_end": 1}}"#,
            Format::Json,
        )
        .unwrap_err();
        assert_eq!(e.field, "model.q0[0]", "{e}");
        let e = parse(
            r#"{"model": {"scene": "chain", "masses": [1, 2], "positions": [1, "x"]}, "time": {"h": 0.01, "steps": 1}}"#,
            Format::Json,
        )
        .unwrap_err();
        assert_eq!(e.field, "model.positions[1]", "{e}");
    }

    /// Every example's model reads the same through its scene's own struct as through the
    /// tagged section, so [`ModelSpec::from_scene_fields`] knows every scene the examples use.
    #[test]
    fn every_example_model_reads_through_its_scene() {
        let examples = concat!(env!("CARGO_MANIFEST_DIR"), "/examples");
        let mut checked = 0;
        let mut scenes = std::collections::BTreeSet::new();
        // Subfolders too: `examples/rigid/` holds the only `rigid_bodies` models (that scene
        // was missing from `from_scene_fields`, so its fields were named wrongly).
        let paths = std::fs::read_dir(examples)
            .expect("examples/")
            .map(|e| e.expect("entry").path())
            .flat_map(|p| match std::fs::read_dir(&p) {
                Ok(sub) => sub.map(|e| e.expect("entry").path()).collect(),
                Err(_) => vec![p],
            });
        for path in paths {
            let Ok(text) = std::fs::read_to_string(&path) else {
                continue;
            };
            let Ok(spec) = parse(&text, Format::of_path(&path)) else {
                continue;
            };
            let (Some(model), Some(root)) = (spec.model, tree(&text, Format::of_path(&path)))
            else {
                continue;
            };
            let mut fields = root["model"].as_object().expect("a table").clone();
            fields.remove("scene");
            let read = ModelSpec::from_scene_fields(model.scene(), Value::Object(fields))
                .unwrap_or_else(|| panic!("{}: scene {} unknown", path.display(), model.scene()))
                .expect("reads");
            assert_eq!(read, model, "{}", path.display());
            scenes.insert(model.scene());
            checked += 1;
        }
        assert!(checked >= 10, "only {checked} examples");
        assert!(scenes.contains("rigid_bodies"), "{scenes:?}");
    }

    #[test]
    fn unknown_field_next_to_a_field_group_is_named() {
        // The index set and the Newton settings are flattened into the scheme's table; a
        // misspelt field beside them is still named, in TOML and JSON, with or without a
        // missing required field.
        let e = parse(
            "[model]\nscene = \"chain\"\n[integrator]\nscheme = \"ns_hht\"\nalpha = 0.1\nactivaton = \"predicted_gap\"\n[time]\nh = 0.01\nsteps = 1\n",
            Format::Toml,
        )
        .unwrap_err();
        assert_eq!(e.field, "integrator.activaton", "{e}");
        assert!(e.reason.contains("unknown field"), "{e}");
        let e = parse(
            r#"{"model": {"scene": "pendulum"}, "integrator": {"scheme": "soi2_hht", "newton_tolerence": 1e-9}, "time": {"h": 0.01, "steps": 1}}"#,
            Format::Json,
        )
        .unwrap_err();
        assert_eq!(e.field, "integrator.newton_tolerence", "{e}");
        let e = parse(
            r#"{"model": {"scene": "chain"}, "integrator": {"scheme": "ns_hht", "activation_gamma": "x"}, "time": {"h": 0.01, "steps": 1}}"#,
            Format::Json,
        )
        .unwrap_err();
        assert_eq!(e.field, "integrator.activation_gamma", "{e}");
    }

    #[test]
    fn unknown_value_of_an_enumerated_field_is_named() {
        // serde says "unknown variant" for these as for an unknown scheme: the field, not
        // `integrator.scheme`, must be named, in TOML (CLI) and JSON (HTTP).
        for (field, value) in [("newton", "sometimes"), ("start", "a1")] {
            let toml = format!(
                "[model]\nscene = \"pendulum\"\n[integrator]\nscheme = \"soi2_hht\"\n{field} = \"{value}\"\n[time]\nh = 0.01\nt_end = 0.1\n"
            );
            let e = parse(&toml, Format::Toml).unwrap_err();
            assert_eq!(e.field, format!("integrator.{field}"), "{e}");
            assert!(e.reason.contains("unknown variant"), "{e}");
            let json = format!(
                r#"{{"model": {{"scene": "slider_crank"}}, "integrator": {{"scheme": "soi2_generalized_alpha", "{field}": "{value}"}}, "time": {{"h": 0.01, "t_end": 0.1}}}}"#
            );
            let e = parse(&json, Format::Json).unwrap_err();
            assert_eq!(e.field, format!("integrator.{field}"), "{e}");
        }
        let e = parse(
            "[model]\nscene = \"bar\"\nmass_matrix = \"diagonal\"\n[time]\nh = 0.01\nsteps = 1\n",
            Format::Toml,
        )
        .unwrap_err();
        assert_eq!(e.field, "model.mass_matrix", "{e}");
        // An unknown scheme is still the scheme's fault, also with a required field missing.
        let e = parse(
            r#"{"model": {"scene": "chain"}, "integrator": {"scheme": "ns_hhht", "beta": 0.3}, "time": {"h": 0.01, "steps": 1}}"#,
            Format::Json,
        )
        .unwrap_err();
        assert_eq!(e.field, "integrator.scheme", "{e}");
        let e = parse(
            "[model]\nscene = \"chain\"\n[integrator]\nscheme = \"ns_hht\"\nactivation = \"x\"\n[time]\nh = 0.01\nsteps = 1\n",
            Format::Toml,
        )
        .unwrap_err();
        assert_eq!(e.field, "integrator.activation", "{e}");
    }
}
