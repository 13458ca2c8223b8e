//! The α-family's parameters: the member ([`AlphaScheme`]), α_m, α_f, β, γ and the index set
//! ([`AlphaParams`]), their validation against each member's stability and dissipation
//! conditions ([`ParamError`]), and the coefficients a step reads ([`Weighting`], ν, η).

use crate::contact::IndexSetRule;
use std::fmt;

/// Tolerance of the parameter conditions, so that parameters computed from ρ∞ by (27) are not
/// rejected by one ulp.
pub(super) const PARAM_TOL: f64 = 1e-12;

/// Which member of the family: fixes which stability conditions apply and, for KH, the weights.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AlphaScheme {
    /// Nonsmooth Newmark: α_m = α_f = 0; dissipative for 2β ≥ γ ≥ ½ (89).
    Newmark,
    /// Nonsmooth HHT (78): α_m = 0, α_f = α; dissipative for 2β ≥ γ ≥ ½, 0 ≤ α ≤ γ − ½ ≤ ½ (83).
    Hht,
    /// Nonsmooth generalized-α (25), Chung–Hulbert weighting (53). Accepted for
    /// α_m ≤ α_f ≤ ½, γ ≥ ½ + α_f − α_m, β ≥ ¼ + ½(α_f − α_m) (Chung & Hulbert 1993); Lemma 2
    /// gives the identity but no sign.
    GeneralizedAlpha,
    /// Nonsmooth KH generalized-α (30); dissipative under (76).
    KrenkHogsberg,
}

impl AlphaScheme {
    /// The scheme's name in job specs.
    pub fn name(self) -> &'static str {
        match self {
            AlphaScheme::Newmark => "ns_newmark",
            AlphaScheme::Hht => "ns_hht",
            AlphaScheme::GeneralizedAlpha => "ns_generalized_alpha",
            AlphaScheme::KrenkHogsberg => "ns_kh_alpha",
        }
    }
}

/// Parameters of the α-family. Build them with [`AlphaParams::newmark`], [`AlphaParams::hht`],
/// [`AlphaParams::from_rho_inf`] or directly, then [`AlphaParams::validate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlphaParams {
    /// Member of the family.
    pub scheme: AlphaScheme,
    /// α_m < 1 (≤ ½ for stability).
    pub alpha_m: f64,
    /// α_f ≤ 1.
    pub alpha_f: f64,
    /// β ≥ 0.
    pub beta: f64,
    /// γ ≥ 0.
    pub gamma: f64,
    /// Index-set rule, (24) by default.
    pub index_set: IndexSetRule,
}

/// A parameter set the family cannot run, or that is outside the scheme's stability or
/// dissipation conditions. `field` is the parameter's spec name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParamError {
    /// Spec field name (`alpha_m`, `alpha_f`, `alpha`, `beta`, `gamma`, `rho_inf`).
    pub field: &'static str,
    /// What is wrong.
    pub reason: String,
    /// True when the parameters are runnable but outside the proven conditions (a spec may
    /// accept them with `allow_unstable = true`).
    pub stability: bool,
}

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.field, self.reason)
    }
}

impl std::error::Error for ParamError {}

pub(super) fn hard(field: &'static str, reason: String) -> ParamError {
    ParamError {
        field,
        reason,
        stability: false,
    }
}

pub(super) fn unstable(field: &'static str, reason: String) -> ParamError {
    ParamError {
        field,
        reason,
        stability: true,
    }
}

impl AlphaParams {
    /// Nonsmooth Newmark (α_m = α_f = 0). β = ¼, γ = ½ is the trapezoidal rule (Corollary 1).
    pub fn newmark(beta: f64, gamma: f64) -> Self {
        Self {
            scheme: AlphaScheme::Newmark,
            alpha_m: 0.0,
            alpha_f: 0.0,
            beta,
            gamma,
            index_set: IndexSetRule::default(),
        }
    }

    /// Nonsmooth HHT with the second-order choice γ = ½ + α, β = (1 + α)²/4.
    pub fn hht(alpha: f64) -> Self {
        Self::hht_with(alpha, 0.25 * (1.0 + alpha) * (1.0 + alpha), 0.5 + alpha)
    }

    /// Nonsmooth HHT (78) with explicit β, γ.
    pub fn hht_with(alpha: f64, beta: f64, gamma: f64) -> Self {
        Self {
            scheme: AlphaScheme::Hht,
            alpha_m: 0.0,
            alpha_f: alpha,
            beta,
            gamma,
            index_set: IndexSetRule::default(),
        }
    }

    /// Generalized-α or KH parameters from the spectral radius at infinity ρ∞ ∈ [0, 1] by (27):
    /// `α_m = (2ρ∞ − 1)/(ρ∞ + 1)`, `α_f = ρ∞/(ρ∞ + 1)`, γ by (26) `γ = ½ + α_f − α_m`,
    /// `β = ¼(γ + ½)²`.
    pub fn from_rho_inf(scheme: AlphaScheme, rho_inf: f64) -> Self {
        let alpha_m = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0);
        let alpha_f = rho_inf / (rho_inf + 1.0);
        let gamma = 0.5 + alpha_f - alpha_m;
        let beta = 0.25 * (gamma + 0.5) * (gamma + 0.5);
        Self {
            scheme,
            alpha_m,
            alpha_f,
            beta,
            gamma,
            index_set: IndexSetRule::default(),
        }
    }

    /// Filter time-scale parameter ν = ½ − α_m (50).
    pub fn nu(&self) -> f64 {
        0.5 - self.alpha_m
    }

    /// Filter strength η = α_f − α_m (50).
    pub fn eta(&self) -> f64 {
        self.alpha_f - self.alpha_m
    }

    /// The weights (α_M, α_C, α_K, α_L) on the t_k terms of M a, C v, K q, F.
    pub fn weights(&self) -> Weighting {
        let (am, af) = (self.alpha_m, self.alpha_f);
        match self.scheme {
            AlphaScheme::KrenkHogsberg => Weighting {
                mass: am,
                damping: am,
                stiffness: af,
                load: am,
            },
            _ => Weighting {
                mass: am,
                damping: af,
                stiffness: af,
                load: af,
            },
        }
    }

    /// Checks that the scheme can run (finite values, α_m < 1, α_f ≤ 1, β, γ ≥ 0, η = 0 when
    /// ν = 0) and that the parameters satisfy the scheme's stability/dissipation conditions
    /// ([`AlphaScheme`]). Errors with `stability = true` concern only the latter.
    pub fn validate(&self) -> Result<(), ParamError> {
        let hht = self.scheme == AlphaScheme::Hht;
        let f_name = if hht { "alpha" } else { "alpha_f" };
        for (field, x) in [
            ("alpha_m", self.alpha_m),
            (f_name, self.alpha_f),
            ("beta", self.beta),
            ("gamma", self.gamma),
        ] {
            if !x.is_finite() {
                return Err(hard(field, format!("must be finite, got {x}")));
            }
        }
        if self.alpha_m >= 1.0 {
            return Err(hard(
                "alpha_m",
                format!(
                    "must be < 1 (α_m = 1 leaves a_(k+1) undetermined), got {}",
                    self.alpha_m
                ),
            ));
        }
        if self.alpha_f > 1.0 {
            return Err(hard(f_name, format!("must be ≤ 1, got {}", self.alpha_f)));
        }
        if self.beta < 0.0 {
            return Err(hard("beta", format!("must be ≥ 0, got {}", self.beta)));
        }
        if self.gamma < 0.0 {
            return Err(hard("gamma", format!("must be ≥ 0, got {}", self.gamma)));
        }
        if self.nu().abs() <= PARAM_TOL && self.eta().abs() > PARAM_TOL {
            return Err(hard(
                "alpha_f",
                format!(
                    "α_m = ½ requires α_f = ½ (ν = 0 makes the filter (48) vanish, Remark 1), got α_f = {}",
                    self.alpha_f
                ),
            ));
        }
        let (am, af, b, g) = (self.alpha_m, self.alpha_f, self.beta, self.gamma);
        let tol = PARAM_TOL;
        match self.scheme {
            AlphaScheme::Newmark | AlphaScheme::Hht | AlphaScheme::KrenkHogsberg => {
                if g < 0.5 - tol {
                    return Err(unstable(
                        "gamma",
                        format!("must be ≥ ½ for dissipation ((89), (83), (76)), got {g}"),
                    ));
                }
                if 2.0 * b < g - tol {
                    return Err(unstable(
                        "beta",
                        format!("2β ≥ γ is required for dissipation, got β = {b}, γ = {g}"),
                    ));
                }
            }
            AlphaScheme::GeneralizedAlpha => {}
        }
        match self.scheme {
            AlphaScheme::Newmark => {
                if am != 0.0 || af != 0.0 {
                    return Err(hard(
                        "alpha_f",
                        "nonsmooth Newmark has α_m = α_f = 0".into(),
                    ));
                }
            }
            AlphaScheme::Hht => {
                if am != 0.0 {
                    return Err(hard("alpha_m", "nonsmooth HHT has α_m = 0".into()));
                }
                if af < -tol || af > g - 0.5 + tol || g - 0.5 > 0.5 + tol {
                    return Err(unstable(
                        "alpha",
                        format!("(83) requires 0 ≤ α ≤ γ − ½ ≤ ½, got α = {af}, γ = {g}"),
                    ));
                }
            }
            AlphaScheme::KrenkHogsberg => {
                let eta = af - am;
                if eta < -tol || eta > g - 0.5 + tol || g - 0.5 > 0.5 - am + tol {
                    return Err(unstable(
                        "alpha_f",
                        format!(
                            "(76) requires 0 ≤ α_f − α_m ≤ γ − ½ ≤ ½ − α_m, got α_m = {am}, α_f = {af}, γ = {g}"
                        ),
                    ));
                }
            }
            AlphaScheme::GeneralizedAlpha => {
                if am > af + tol || af > 0.5 + tol {
                    return Err(unstable(
                        "alpha_f",
                        format!("stability requires α_m ≤ α_f ≤ ½, got α_m = {am}, α_f = {af}"),
                    ));
                }
                if g < 0.5 + af - am - tol {
                    return Err(unstable(
                        "gamma",
                        format!("stability requires γ ≥ ½ + α_f − α_m, got γ = {g}"),
                    ));
                }
                if b < 0.25 + 0.5 * (af - am) - tol {
                    return Err(unstable(
                        "beta",
                        format!("stability requires β ≥ ¼ + ½(α_f − α_m), got β = {b}"),
                    ));
                }
            }
        }
        Ok(())
    }

    /// The coefficients the smooth part of a step needs.
    pub(crate) fn coefficients(&self) -> Coefficients {
        Coefficients {
            beta: self.beta,
            gamma: self.gamma,
            nu: self.nu(),
            eta: self.eta(),
            weights: self.weights(),
            xy_filters: self.scheme != AlphaScheme::KrenkHogsberg,
        }
    }
}

/// The weights α_M, α_C, α_K, α_L of the t_k terms of M a, C v, K q and F in the collocation
/// relation (the t_{k+1} terms take 1 − α). Chung–Hulbert (53): (α_m, α_f, α_f, α_f);
/// Krenk–Høgsberg (30): (α_m, α_m, α_f, α_m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Weighting {
    /// α_M.
    pub mass: f64,
    /// α_C.
    pub damping: f64,
    /// α_K.
    pub stiffness: f64,
    /// α_L.
    pub load: f64,
}

/// Coefficients shared by the nonsmooth family and the position-contact baselines.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Coefficients {
    pub beta: f64,
    pub gamma: f64,
    pub nu: f64,
    pub eta: f64,
    pub weights: Weighting,
    /// Whether the x (damping) and y (load) filters of (52) enter: Chung–Hulbert weighting only.
    pub xy_filters: bool,
}
