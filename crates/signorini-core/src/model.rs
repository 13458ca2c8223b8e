//! The linear mechanical system with unilateral contacts, Acary 2016 eq. (2):
//!
//! ```text
//! M q̈ + C q̇ + K q = F(t) + G λ,     g(t) = Gᵀ q + w(t) ≥ 0,   0 ≤ g ⊥ λ ≥ 0,
//! ```
//!
//! with Newton's impact law `U⁺ = −e U⁻` per contact (6), `U = Gᵀ v + ẇ(t)` the local velocity.
//! M is symmetric positive definite, K and C symmetric positive semidefinite, all stored banded.

use crate::band::{BandError, SymBand};
use thiserror::Error;

/// `amplitude · sin(omega · t + phase)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Harmonic {
    /// Amplitude.
    pub amplitude: f64,
    /// Angular frequency (rad/s).
    pub omega: f64,
    /// Phase (rad).
    pub phase: f64,
}

impl Harmonic {
    /// Value at t.
    pub fn value(&self, t: f64) -> f64 {
        self.amplitude * (self.omega * t + self.phase).sin()
    }

    /// Time derivative at t.
    pub fn rate(&self, t: f64) -> f64 {
        self.amplitude * self.omega * (self.omega * t + self.phase).cos()
    }
}

/// One harmonic load: `shape · sin(omega t + phase)` (a vector of nodal amplitudes).
#[derive(Debug, Clone, PartialEq)]
pub struct HarmonicLoad {
    /// Nodal amplitudes, one per dof.
    pub shape: Vec<f64>,
    /// Angular frequency (rad/s).
    pub omega: f64,
    /// Phase (rad).
    pub phase: f64,
}

/// External force `F(t) = constant + Σ_k shape_k sin(ω_k t + φ_k)`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Forcing {
    /// Constant part, one entry per dof.
    pub constant: Vec<f64>,
    /// Harmonic parts.
    pub harmonic: Vec<HarmonicLoad>,
}

impl Forcing {
    /// F(t) written into `f`.
    pub fn eval_into(&self, t: f64, f: &mut [f64]) {
        f.copy_from_slice(&self.constant);
        for h in &self.harmonic {
            let s = (h.omega * t + h.phase).sin();
            for (fi, si) in f.iter_mut().zip(&h.shape) {
                *fi += si * s;
            }
        }
    }
}

/// A unilateral contact α: `g_α(t) = Σ_i G_iα q_i + offset + motion(t)`, restitution e_α.
#[derive(Debug, Clone, PartialEq)]
pub struct Contact {
    /// Sparse column α of G: (dof, coefficient).
    pub g: Vec<(usize, f64)>,
    /// Constant part of w_α.
    pub offset: f64,
    /// Harmonic motion of the obstacle (w_α moves; U_α then includes ẇ_α).
    pub motion: Option<Harmonic>,
    /// Newton's coefficient of restitution e_α ∈ [0, 1].
    pub restitution: f64,
}

impl Contact {
    /// (Gᵀ x)_α.
    pub fn project(&self, x: &[f64]) -> f64 {
        self.g.iter().map(|&(i, c)| c * x[i]).sum()
    }

    /// w_α(t).
    pub fn w(&self, t: f64) -> f64 {
        self.offset + self.motion.map_or(0.0, |m| m.value(t))
    }

    /// ẇ_α(t).
    pub fn w_rate(&self, t: f64) -> f64 {
        self.motion.map_or(0.0, |m| m.rate(t))
    }

    /// Gap g_α(q, t).
    pub fn gap(&self, q: &[f64], t: f64) -> f64 {
        self.project(q) + self.w(t)
    }

    /// Local velocity U_α = (Gᵀ v)_α + ẇ_α(t).
    pub fn local_velocity(&self, v: &[f64], t: f64) -> f64 {
        self.project(v) + self.w_rate(t)
    }
}

/// Coulomb friction of contact α of a linear model (planar: one tangent per contact): its
/// tangent row T_α, so that the tangential local velocity is U_t,α = T_α v (the obstacle does not
/// move tangentially), and its coefficient μ_α ≥ 0.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactFriction {
    /// Sparse tangent row T_α: (dof, coefficient).
    pub t: Vec<(usize, f64)>,
    /// Coulomb coefficient μ_α ≥ 0.
    pub mu: f64,
}

impl ContactFriction {
    /// T_α x.
    pub fn project(&self, x: &[f64]) -> f64 {
        self.t.iter().map(|&(i, c)| c * x[i]).sum()
    }
}

/// Why a model is invalid. `field` names the offending input, relative to the model section.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ModelError {
    /// A matrix is malformed, not symmetric or not finite.
    #[error("{field}: {source}")]
    Matrix {
        /// Which matrix.
        field: String,
        /// What is wrong with it.
        source: BandError,
    },
    /// The mass matrix is not positive definite.
    #[error(
        "{field}: mass matrix is not symmetric positive definite (pivot {pivot:e} at row {row})"
    )]
    MassNotPositiveDefinite {
        /// Which matrix.
        field: String,
        /// Row where Cholesky broke down.
        row: usize,
        /// Its pivot.
        pivot: f64,
    },
    /// A stiffness or damping matrix has a negative eigenvalue.
    #[error(
        "{field}: matrix is not positive semidefinite (pivot {pivot:e} at row {row} of the shifted factorisation)"
    )]
    NotPositiveSemidefinite {
        /// Which matrix.
        field: String,
        /// Row where the factorisation of A + δI broke down.
        row: usize,
        /// Its pivot.
        pivot: f64,
    },
    /// Sizes disagree.
    #[error("{field}: expected {expected} entries, got {found}")]
    Dimension {
        /// Which input.
        field: String,
        /// Expected size.
        expected: usize,
        /// Given size.
        found: usize,
    },
    /// A value is NaN or infinite.
    #[error("{field}: value is not finite")]
    NotFinite {
        /// Which input.
        field: String,
    },
    /// A value is outside its valid range.
    #[error("{field}: {value} is outside {range}")]
    OutOfRange {
        /// Which input.
        field: String,
        /// The value.
        value: f64,
        /// The valid range, as text.
        range: &'static str,
    },
    /// Too many contacts for the dense contact operators `Ŵ⁻¹G` (n × m) and `W = GᵀŴ⁻¹G`
    /// (m × m) each scheme precomputes.
    #[error(
        "{field}: {contacts} contacts on {dofs} dofs need {entries:.2e} stored entries for the dense operators Ŵ⁻¹G and W = GᵀŴ⁻¹G, more than the {max:.2e} allowed (1 GiB each)",
        entries = (*contacts as f64) * (*contacts.max(dofs) as f64),
        max = crate::band::MAX_STORED_ENTRIES as f64
    )]
    TooManyContacts {
        /// Which input.
        field: String,
        /// m.
        contacts: usize,
        /// n.
        dofs: usize,
    },
    /// An input that another one makes necessary is missing.
    #[error("{field}: {reason}")]
    Required {
        /// Which input.
        field: String,
        /// Why it is needed.
        reason: &'static str,
    },
    /// A contact refers to a dof that does not exist.
    #[error("{field}: dof {dof} does not exist (the model has {n} dofs)")]
    NoSuchDof {
        /// Which input.
        field: String,
        /// Dof index.
        dof: usize,
        /// Number of dofs.
        n: usize,
    },
}

impl ModelError {
    /// The offending field, relative to the model section.
    pub fn field(&self) -> &str {
        match self {
            ModelError::Matrix { field, .. }
            | ModelError::MassNotPositiveDefinite { field, .. }
            | ModelError::NotPositiveSemidefinite { field, .. }
            | ModelError::Dimension { field, .. }
            | ModelError::NotFinite { field }
            | ModelError::OutOfRange { field, .. }
            | ModelError::TooManyContacts { field, .. }
            | ModelError::Required { field, .. }
            | ModelError::NoSuchDof { field, .. } => field,
        }
    }

    /// The reason, without the field name.
    pub fn reason(&self) -> String {
        let s = self.to_string();
        match s.split_once(": ") {
            Some((_, r)) => r.to_string(),
            None => s,
        }
    }
}

/// Whether m contacts on n dofs need more than [`crate::band::MAX_STORED_ENTRIES`] entries
/// for the dense operators Ŵ⁻¹G (n × m) and W (m × m).
pub fn dense_contacts_too_large(n: usize, m: usize) -> bool {
    m.saturating_mul(m.max(n)) > crate::band::MAX_STORED_ENTRIES
}

/// Checks that `x` has `n` finite entries.
pub fn check_vector(field: &str, x: &[f64], n: usize) -> Result<(), ModelError> {
    if x.len() != n {
        return Err(ModelError::Dimension {
            field: field.into(),
            expected: n,
            found: x.len(),
        });
    }
    if x.iter().any(|a| !a.is_finite()) {
        return Err(ModelError::NotFinite {
            field: field.into(),
        });
    }
    Ok(())
}

/// Checks that `x` is finite and in [lo, hi].
pub fn check_range(
    field: &str,
    x: f64,
    lo: f64,
    hi: f64,
    range: &'static str,
) -> Result<(), ModelError> {
    if !x.is_finite() {
        return Err(ModelError::NotFinite {
            field: field.into(),
        });
    }
    if x < lo || x > hi {
        return Err(ModelError::OutOfRange {
            field: field.into(),
            value: x,
            range,
        });
    }
    Ok(())
}

/// Checks that a symmetric matrix is positive semidefinite: A + δI must factorise with
/// δ = 1e-12 · max|A_ii| (a singular K — a free bar's rigid mode — passes; an indefinite one
/// does not). The energy identities and the dissipation results all assume K, C ⪰ 0.
fn check_semidefinite(field: &str, a: &SymBand) -> Result<(), ModelError> {
    let scale = (0..a.n()).fold(0.0f64, |m, i| m.max(a.get(i, i).abs()));
    if scale == 0.0 && a.is_zero() {
        return Ok(());
    }
    let delta = 1e-12 * scale.max(f64::MIN_POSITIVE);
    let mut shifted = a.clone();
    for i in 0..a.n() {
        shifted.add(i, i, delta);
    }
    match shifted.cholesky() {
        Ok(_) => Ok(()),
        Err(BandError::NotPositiveDefinite { row, pivot }) => {
            Err(ModelError::NotPositiveSemidefinite {
                field: field.into(),
                row,
                pivot,
            })
        }
        Err(source) => Err(ModelError::Matrix {
            field: field.into(),
            source,
        }),
    }
}

/// A validated linear model with its initial state.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearModel {
    /// Mass matrix M (SPD).
    pub mass: SymBand,
    /// Damping matrix C (symmetric PSD).
    pub damping: SymBand,
    /// Stiffness matrix K (symmetric PSD).
    pub stiffness: SymBand,
    /// External force F(t).
    pub force: Forcing,
    /// Unilateral contacts (columns of G, offsets w, restitutions).
    pub contacts: Vec<Contact>,
    /// Coulomb friction, one per contact, or empty (frictionless model, the default).
    pub friction: Vec<ContactFriction>,
    /// q(t₀).
    pub q0: Vec<f64>,
    /// v(t₀).
    pub v0: Vec<f64>,
}

impl LinearModel {
    /// Validates and builds a model. Field names in errors are `mass`, `damping`, `stiffness`,
    /// `force`, `contacts[α]…`, `q0`, `v0`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        mass: SymBand,
        damping: SymBand,
        stiffness: SymBand,
        force: Forcing,
        contacts: Vec<Contact>,
        q0: Vec<f64>,
        v0: Vec<f64>,
    ) -> Result<Self, ModelError> {
        let n = mass.n();
        let m = contacts.len();
        // Single-dof contacts can take the banded path, which stores no dense operator; a job
        // that sends them to a dense solver checks this size itself (`job.rs`).
        let banded =
            crate::lcp::active_set::unit_columns(n, contacts.iter().map(|c| c.g.as_slice()));
        if !banded && dense_contacts_too_large(n, m) {
            return Err(ModelError::TooManyContacts {
                field: "contacts".into(),
                contacts: m,
                dofs: n,
            });
        }
        for (field, m) in [("damping", &damping), ("stiffness", &stiffness)] {
            if m.n() != n {
                return Err(ModelError::Dimension {
                    field: field.into(),
                    expected: n,
                    found: m.n(),
                });
            }
        }
        if let Err(BandError::NotPositiveDefinite { row, pivot }) = mass.cholesky() {
            return Err(ModelError::MassNotPositiveDefinite {
                field: "mass".into(),
                row,
                pivot,
            });
        }
        check_semidefinite("stiffness", &stiffness)?;
        check_semidefinite("damping", &damping)?;
        check_vector("force", &force.constant, n)?;
        for (k, h) in force.harmonic.iter().enumerate() {
            check_vector(&format!("force.harmonic[{k}]"), &h.shape, n)?;
            check_range(
                &format!("force.harmonic[{k}].omega"),
                h.omega,
                f64::MIN,
                f64::MAX,
                "finite values",
            )?;
        }
        check_vector("q0", &q0, n)?;
        check_vector("v0", &v0, n)?;
        for (a, c) in contacts.iter().enumerate() {
            for &(i, coef) in &c.g {
                if i >= n {
                    return Err(ModelError::NoSuchDof {
                        field: format!("contacts[{a}]"),
                        dof: i,
                        n,
                    });
                }
                if !coef.is_finite() {
                    return Err(ModelError::NotFinite {
                        field: format!("contacts[{a}].g"),
                    });
                }
            }
            if c.g.iter().all(|&(_, coef)| coef == 0.0) {
                return Err(ModelError::OutOfRange {
                    field: format!("contacts[{a}].g"),
                    value: 0.0,
                    range: "non-zero columns of G",
                });
            }
            check_range(
                &format!("contacts[{a}].offset"),
                c.offset,
                f64::MIN,
                f64::MAX,
                "finite values",
            )?;
            check_range(
                &format!("contacts[{a}].restitution"),
                c.restitution,
                0.0,
                1.0,
                "[0, 1]",
            )?;
        }
        Ok(Self {
            mass,
            damping,
            stiffness,
            force,
            contacts,
            friction: Vec::new(),
            q0,
            v0,
        })
    }

    /// The model with Coulomb friction on its contacts: one [`ContactFriction`] per contact
    /// (field `friction`), tangent rows on existing dofs with finite coefficients (field
    /// `t_matrix[α]`), non-zero where μ > 0, and μ finite and ≥ 0 (field `friction[α]`).
    pub fn with_friction(mut self, friction: Vec<ContactFriction>) -> Result<Self, ModelError> {
        let n = self.dofs();
        if friction.len() != self.contacts.len() {
            return Err(ModelError::Dimension {
                field: "friction".into(),
                expected: self.contacts.len(),
                found: friction.len(),
            });
        }
        for (a, f) in friction.iter().enumerate() {
            check_range(&format!("friction[{a}]"), f.mu, 0.0, f64::MAX, "[0, ∞)")?;
            for &(i, coef) in &f.t {
                if i >= n {
                    return Err(ModelError::NoSuchDof {
                        field: format!("t_matrix[{a}]"),
                        dof: i,
                        n,
                    });
                }
                if !coef.is_finite() {
                    return Err(ModelError::NotFinite {
                        field: format!("t_matrix[{a}]"),
                    });
                }
            }
            if f.mu > 0.0 && f.t.iter().all(|&(_, coef)| coef == 0.0) {
                return Err(ModelError::OutOfRange {
                    field: format!("t_matrix[{a}]"),
                    value: 0.0,
                    range: "non-zero tangent rows where friction > 0",
                });
            }
        }
        self.friction = friction;
        Ok(self)
    }

    /// Whether some contact has μ > 0.
    pub fn has_friction(&self) -> bool {
        self.friction.iter().any(|f| f.mu > 0.0)
    }

    /// Number of dofs n.
    pub fn dofs(&self) -> usize {
        self.mass.n()
    }

    /// Largest restitution ē = max e_α (0 without contacts).
    pub fn max_restitution(&self) -> f64 {
        self.contacts.iter().fold(0.0, |e, c| e.max(c.restitution))
    }

    /// Mechanical energy (14): ½vᵀMv + ½qᵀKq, as (kinetic, strain).
    pub fn energy(&self, q: &[f64], v: &[f64]) -> (f64, f64) {
        (0.5 * self.mass.quad(v, v), 0.5 * self.stiffness.quad(q, q))
    }
}
