//! The names an expression may use: variables and parameters.

use super::parse::{Tok, tokenize};
use super::{Expr, ExprError, reserved_names};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use thiserror::Error;

/// A parameter's definition in the spec: a number, or an expression of other parameters
/// (`I = "m*(w^2+hgt^2)/12"`). In a spec it is written as either (untagged):
/// `parameters = { m = 1.0, I = "m*w^2/12" }`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
pub enum Param {
    /// A number.
    Value(f64),
    /// An expression of numbers, other parameters, `pi` and functions (no variables).
    Expr(String),
}

/// A problem with the declared names. [`ScopeError::name`] gives the offending name so the
/// caller can point at its spec field (`model.parameters.m`, `model.coordinates`).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ScopeError {
    /// Not an identifier.
    #[error(
        "{kind} '{name}' is not a valid name (letters, digits and '_', not starting with a digit)"
    )]
    BadName {
        /// `coordinate`, `variable` or `parameter`.
        kind: &'static str,
        /// The name.
        name: String,
    },
    /// The name is taken: by a function, `pi`, the time, another variable or parameter.
    #[error("{kind} '{name}' clashes with {other}")]
    Clash {
        /// `coordinate`, `velocity`, `variable` or `parameter`.
        kind: &'static str,
        /// The name.
        name: String,
        /// What it clashes with (`the function sin`, `coordinate 'x'`).
        other: String,
    },
    /// A parameter that is NaN or infinite.
    #[error("parameter '{name}' is not a finite number ({value})")]
    NotFinite {
        /// The parameter.
        name: String,
        /// Its value.
        value: f64,
    },
    /// A parameter whose expression does not parse.
    #[error("parameter '{name}': {source}")]
    Expr {
        /// The parameter.
        name: String,
        /// The parse error.
        #[source]
        source: ExprError,
    },
    /// A parameter whose expression uses a variable.
    #[error("parameter '{name}' uses the variable '{variable}': parameters are constants")]
    NotConstant {
        /// The parameter.
        name: String,
        /// The variable.
        variable: String,
    },
    /// Parameters defined in terms of each other in a circle.
    #[error("parameters depend on each other in a cycle: {}", .cycle.join(" -> "))]
    Cycle {
        /// The cycle, first name repeated at the end (`a -> b -> a`).
        cycle: Vec<String>,
    },
}

impl ScopeError {
    /// The name the error is about (for a cycle, its first parameter).
    pub fn name(&self) -> &str {
        match self {
            ScopeError::BadName { name, .. }
            | ScopeError::Clash { name, .. }
            | ScopeError::NotFinite { name, .. }
            | ScopeError::Expr { name, .. }
            | ScopeError::NotConstant { name, .. } => name,
            ScopeError::Cycle { cycle } => cycle.first().map_or("", String::as_str),
        }
    }
}

/// The variables (indices into the vector a tape is evaluated at) and the parameters (constants,
/// folded at parse time) of a set of expressions.
#[derive(Debug, Clone, PartialEq)]
pub struct Scope {
    variables: Vec<String>,
    parameters: Vec<(String, f64)>,
    /// The index of each variable by name (a model of 10⁴ coordinates names 2·10⁴ + 1
    /// variables: looked up per name of every expression, a scan would be quadratic).
    index: HashMap<String, usize>,
}

fn is_identifier(s: &str) -> bool {
    let mut chars = s.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

impl Scope {
    /// Variables with the given names (index i is `variables[i]`) and parameters.
    pub fn new(variables: &[String], parameters: &[(String, Param)]) -> Result<Scope, ScopeError> {
        let vars: Vec<_> = variables.iter().map(|v| ("variable", v.clone())).collect();
        Scope::build(vars, parameters)
    }

    /// The variables of a Lagrangian model with n coordinates: index i < n is the coordinate
    /// qᵢ, n + i its velocity `<qᵢ>_dot`, 2n the time `t`.
    pub fn lagrangian(
        coordinates: &[String],
        parameters: &[(String, Param)],
    ) -> Result<Scope, ScopeError> {
        let mut vars: Vec<_> = coordinates
            .iter()
            .map(|q| ("coordinate", q.clone()))
            .collect();
        for q in coordinates {
            if is_identifier(q) {
                vars.push(("velocity", format!("{q}_dot")));
            }
        }
        vars.push(("time", "t".to_string()));
        Scope::build(vars, parameters)
    }

    fn build(
        vars: Vec<(&'static str, String)>,
        parameters: &[(String, Param)],
    ) -> Result<Scope, ScopeError> {
        // Every name claimed so far, with its kind.
        let mut taken: HashMap<String, &'static str> = HashMap::with_capacity(vars.len());
        let describe = |kind: &str, name: &str| -> String {
            match kind {
                "time" => "the time t".to_string(),
                _ => format!("{kind} '{name}'"),
            }
        };
        let mut claim = |kind: &'static str, name: &str| -> Result<(), ScopeError> {
            if !is_identifier(name) {
                return Err(ScopeError::BadName {
                    kind,
                    name: name.to_string(),
                });
            }
            let other = if name == "pi" {
                Some("the constant pi".to_string())
            } else if reserved_names().any(|r| r == name) {
                Some(format!("the function {name}"))
            } else {
                taken.get(name).map(|k| describe(k, name))
            };
            if let Some(other) = other {
                // The time clashes with a coordinate named `t`: report the coordinate.
                let (kind, other) = if kind == "time" {
                    let k = taken.get(name).map_or("variable", |k| *k);
                    (k, "the time t".to_string())
                } else {
                    (kind, other)
                };
                return Err(ScopeError::Clash {
                    kind,
                    name: name.to_string(),
                    other,
                });
            }
            taken.insert(name.to_string(), kind);
            Ok(())
        };
        for (kind, name) in &vars {
            claim(kind, name)?;
        }
        for (name, _) in parameters {
            claim("parameter", name)?;
        }
        let variables: Vec<String> = vars.into_iter().map(|(_, n)| n).collect();
        let index = variables
            .iter()
            .enumerate()
            .map(|(i, n)| (n.clone(), i))
            .collect();
        let mut scope = Scope {
            variables,
            parameters: Vec::with_capacity(parameters.len()),
            index,
        };
        scope.resolve(parameters)?;
        Ok(scope)
    }

    /// Gives every parameter its value, the ones it depends on first (depth-first order), and
    /// refuses cycles.
    fn resolve(&mut self, parameters: &[(String, Param)]) -> Result<(), ScopeError> {
        let index = |name: &str| parameters.iter().position(|(n, _)| n == name);
        // The parameters each one names.
        let mut deps: Vec<Vec<usize>> = Vec::with_capacity(parameters.len());
        for (name, p) in parameters {
            deps.push(match p {
                Param::Value(_) => Vec::new(),
                Param::Expr(src) => tokenize(src)
                    .map_err(|source| ScopeError::Expr {
                        name: name.clone(),
                        source,
                    })?
                    .iter()
                    .filter_map(|t| match t.tok {
                        Tok::Name(n) => index(n),
                        _ => None,
                    })
                    .collect(),
            });
        }
        // 0 = not visited, 1 = on the path, 2 = done.
        let mut state = vec![0u8; parameters.len()];
        for root in 0..parameters.len() {
            if state[root] != 0 {
                continue;
            }
            // Iterative depth-first search: (parameter, next dependency to look at).
            let mut path: Vec<(usize, usize)> = vec![(root, 0)];
            state[root] = 1;
            while let Some(&mut (p, ref mut next)) = path.last_mut() {
                if let Some(&q) = deps[p].get(*next) {
                    *next += 1;
                    match state[q] {
                        0 => {
                            state[q] = 1;
                            path.push((q, 0));
                        }
                        1 => {
                            let from = path.iter().position(|&(r, _)| r == q).unwrap_or(0);
                            let mut cycle: Vec<String> = path[from..]
                                .iter()
                                .map(|&(r, _)| parameters[r].0.clone())
                                .collect();
                            cycle.push(parameters[q].0.clone());
                            return Err(ScopeError::Cycle { cycle });
                        }
                        _ => {}
                    }
                } else {
                    path.pop();
                    state[p] = 2;
                    let value = self.value_of(&parameters[p])?;
                    self.parameters.push((parameters[p].0.clone(), value));
                }
            }
        }
        Ok(())
    }

    /// The value of one parameter whose dependencies are resolved.
    fn value_of(&self, (name, p): &(String, Param)) -> Result<f64, ScopeError> {
        let value = match p {
            Param::Value(v) => *v,
            Param::Expr(src) => {
                let e = Expr::parse(src, self).map_err(|source| ScopeError::Expr {
                    name: name.clone(),
                    source,
                })?;
                match (e.as_constant(), e.variables().first()) {
                    (Some(v), _) => v,
                    (None, Some(&i)) => {
                        return Err(ScopeError::NotConstant {
                            name: name.clone(),
                            variable: self.variables[i].clone(),
                        });
                    }
                    // Every expression without variables folds to a constant.
                    (None, None) => f64::NAN,
                }
            }
        };
        if !value.is_finite() {
            return Err(ScopeError::NotFinite {
                name: name.clone(),
                value,
            });
        }
        Ok(value)
    }

    /// The variable names, by index.
    pub fn variables(&self) -> &[String] {
        &self.variables
    }

    /// The parameters with their values (dependencies before the parameters that use them).
    pub fn parameters(&self) -> &[(String, f64)] {
        &self.parameters
    }

    /// The index of a variable.
    pub fn variable(&self, name: &str) -> Option<usize> {
        self.index.get(name).copied()
    }

    /// The value of a parameter.
    pub fn parameter(&self, name: &str) -> Option<f64> {
        self.parameters
            .iter()
            .find(|(n, _)| n == name)
            .map(|&(_, v)| v)
    }

    /// Every variable and parameter name (for "did you mean").
    pub(super) fn names(&self) -> impl Iterator<Item = &str> {
        self.variables
            .iter()
            .chain(self.parameters.iter().map(|(n, _)| n))
            .map(String::as_str)
    }
}
