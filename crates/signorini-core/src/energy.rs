//! The energy terms every step of a linear scheme reports (Acary 2016, Lemma 1 and Lemmas 2–3). Their names are the
//! column names of every output.

/// Names of the per-step energy columns, in output order.
pub const ENERGY_COLUMNS: [&str; 9] = [
    "kinetic",
    "strain",
    "energy",
    "work_ext",
    "work_damping",
    "work_contact",
    "numerical_dissipation",
    "algorithmic_energy",
    "balance_residual",
];

/// Names of the cumulative work columns, in output order (after [`ENERGY_COLUMNS`]).
pub const CUMULATIVE_COLUMNS: [&str; 3] =
    ["work_ext_total", "work_damping_total", "work_contact_total"];

/// Energy terms of one step `[t_k, t_{k+1}]`; the state terms are at t_{k+1}.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct EnergyTerms {
    /// ½ vᵀMv.
    pub kinetic: f64,
    /// ½ qᵀKq.
    pub strain: f64,
    /// Discrete work of the external forces over the step.
    pub work_ext: f64,
    /// Discrete work of the damping forces over the step (≤ 0 for C ⪰ 0).
    pub work_damping: f64,
    /// Discrete work of the contact impulse over the step.
    pub work_contact: f64,
    /// The scheme's quadratic terms (numerical dissipation when ≤ 0).
    pub numerical_dissipation: f64,
    /// The scheme's algorithmic energy H (equals `kinetic + strain` for Moreau–Jean).
    pub algorithmic_energy: f64,
    /// ΔH − work_ext − work_damping − work_contact − numerical_dissipation (− filter terms).
    pub balance_residual: f64,
}

impl EnergyTerms {
    /// Mechanical energy (14): kinetic + strain.
    pub fn energy(&self) -> f64 {
        self.kinetic + self.strain
    }

    /// The values of [`ENERGY_COLUMNS`], in order.
    pub fn values(&self) -> [f64; 9] {
        [
            self.kinetic,
            self.strain,
            self.energy(),
            self.work_ext,
            self.work_damping,
            self.work_contact,
            self.numerical_dissipation,
            self.algorithmic_energy,
            self.balance_residual,
        ]
    }
}
