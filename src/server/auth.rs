//! Who may call what: the bearer tokens a server takes, and the scope each one
//! grants. Three settings:
//!
//! * none: every call is open;
//! * `--token T` (one shared token): mutating calls need it, reads stay open;
//! * `--tokens FILE`: a TOML file of `[[token]]` tables `{ name, scope = "read" | "write",
//!   sha256 = "hex of the token" }` (the tokens themselves are never stored); every call but
//!   `/healthz` (and the gRPC health service) needs one: 401 / UNAUTHENTICATED without a known
//!   token, 403 / PERMISSION_DENIED for a read token on a mutating call. `write` implies `read`.

use crate::error::ApiError;
use anyhow::{Context, Result, bail};
use serde::Deserialize;
use sha2::{Digest, Sha256};
use std::path::Path;
use std::sync::Arc;

/// What a call needs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Scope {
    /// Reading jobs, results, events, capabilities, metrics.
    Read,
    /// Submitting, cancelling, pausing, resuming, extending, deleting (and reading).
    Write,
}

/// One `[[token]]` of the tokens file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct TokenEntry {
    /// Whose token (logs and errors name it, never the token).
    name: String,
    /// What it may do.
    scope: Scope,
    /// SHA-256 of the token, 64 hex digits.
    sha256: String,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TokensFile {
    token: Vec<TokenEntry>,
}

/// A known token of the tokens file: its holder, its scope and its digest.
#[derive(Debug, Clone)]
pub struct Known {
    name: String,
    scope: Scope,
    digest: [u8; 32],
}

/// The server's access rule.
#[derive(Debug, Clone, Default)]
pub enum Access {
    /// Every call is open.
    #[default]
    Open,
    /// One shared token for the mutating calls; reads are open.
    Shared(Arc<str>),
    /// Tokens with scopes; every call needs one.
    Scoped(Arc<[Known]>),
}

/// The 32 bytes of 64 hex digits.
fn parse_digest(hex: &str) -> Option<[u8; 32]> {
    let hex = hex.trim();
    if hex.len() != 64 || !hex.is_ascii() {
        return None;
    }
    let mut out = [0u8; 32];
    for (k, byte) in out.iter_mut().enumerate() {
        *byte = u8::from_str_radix(&hex[2 * k..2 * k + 2], 16).ok()?;
    }
    Some(out)
}

/// SHA-256 of `token`, as the tokens file holds it (lowercase hex).
pub fn sha256_hex(token: &str) -> String {
    Sha256::digest(token.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

impl Access {
    /// The rule of `--tokens FILE`: every entry checked (its name, its scope, its digest).
    pub fn from_file(path: &Path) -> Result<Access> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        let file: TokensFile =
            toml::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
        if file.token.is_empty() {
            bail!("{}: no [[token]]", path.display());
        }
        let known = file
            .token
            .into_iter()
            .enumerate()
            .map(|(i, t)| {
                let digest = parse_digest(&t.sha256).with_context(|| {
                    format!(
                        "{}: token[{i}].sha256 ({}) is not 64 hex digits",
                        path.display(),
                        t.name
                    )
                })?;
                Ok(Known {
                    name: t.name,
                    scope: t.scope,
                    digest,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Access::Scoped(known.into()))
    }

    /// Checks an `Authorization` header value for a call that needs `need`.
    pub fn check(&self, header: Option<&str>, need: Scope) -> Result<(), ApiError> {
        // The scheme is case-insensitive (RFC 9110, 11.1): `Bearer`, `bearer`, `BEARER`.
        let given = header
            .and_then(|h| h.trim_start().split_once(' '))
            .filter(|(scheme, _)| scheme.eq_ignore_ascii_case("bearer"))
            .map(|(_, token)| token.trim());
        match self {
            Access::Open => Ok(()),
            Access::Shared(_) if need == Scope::Read => Ok(()),
            Access::Shared(token) => match given {
                Some(g) if constant_time_eq(g.as_bytes(), token.as_bytes()) => Ok(()),
                _ => Err(ApiError::Unauthenticated),
            },
            Access::Scoped(known) => {
                let digest: [u8; 32] = match given {
                    Some(g) => Sha256::digest(g.as_bytes()).into(),
                    None => return Err(ApiError::Unauthenticated),
                };
                let holder = known
                    .iter()
                    .find(|k| constant_time_eq(&k.digest, &digest))
                    .ok_or(ApiError::Unauthenticated)?;
                if holder.scope >= need {
                    Ok(())
                } else {
                    Err(ApiError::Forbidden {
                        name: holder.name.clone(),
                    })
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scoped_tokens_grant_what_their_scope_says() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("tokens.toml");
        std::fs::write(
            &path,
            format!(
                "[[token]]\nname = \"viewer\"\nscope = \"read\"\nsha256 = \"{}\"\n\n[[token]]\nname = \"ci\"\nscope = \"write\"\nsha256 = \"{}\"\n",
                sha256_hex("r-secret"),
                sha256_hex("w-secret")
            ),
        )
        .expect("write");
        let access = Access::from_file(&path).expect("tokens");
        let check = |h: Option<&str>, need| access.check(h, need);
        assert!(matches!(
            check(None, Scope::Read),
            Err(ApiError::Unauthenticated)
        ));
        assert!(matches!(
            check(Some("Bearer nope"), Scope::Read),
            Err(ApiError::Unauthenticated)
        ));
        assert!(check(Some("Bearer r-secret"), Scope::Read).is_ok());
        assert!(matches!(
            check(Some("bearer r-secret"), Scope::Write),
            Err(ApiError::Forbidden { name }) if name == "viewer"
        ));
        assert!(check(Some("Bearer w-secret"), Scope::Write).is_ok());
        assert!(check(Some("Bearer w-secret"), Scope::Read).is_ok());
        // SHA-256("abc"), FIPS 180-2 appendix B.1.
        assert_eq!(
            sha256_hex("abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }
}
