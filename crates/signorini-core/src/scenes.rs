//! Built-in scenes: builders that produce a [`LinearModel`], the smallest model each scene needs
//! (a 1D bar is 1D, no dof is added that no output or constraint uses). Their parameter
//! structs are the `[model]` section of the job spec (one domain type, serde at the edges).

use crate::band::SymBand;
use crate::model::{
    Contact, Forcing, Harmonic, HarmonicLoad, LinearModel, ModelError, check_range, check_vector,
};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A point mass falling under gravity onto the ground q = 0 (1 dof, gap g = q).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct BouncingBall {
    /// Mass (> 0), default 1.
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub mass: f64,
    /// Gravity acceleration (≥ 0, pulls toward the ground), default 9.81.
    #[schemars(range(min = 0.0))]
    pub gravity: f64,
    /// Initial height (≥ 0), default 1.
    #[schemars(range(min = 0.0))]
    pub q0: f64,
    /// Initial velocity, default 0.
    pub v0: f64,
    /// Restitution in [0, 1], default 0.9.
    #[schemars(range(min = 0.0, max = 1.0))]
    pub restitution: f64,
}

impl BouncingBall {
    /// The exact motion (height, velocity) at t: free flights under gravity between impacts,
    /// each impact reversing the velocity times the restitution e (Newton's law). With e < 1
    /// the impacts accumulate at a finite time, after which the ball rests on the ground.
    pub fn exact_motion(&self, t: f64) -> (f64, f64) {
        let (g, e) = (self.gravity, self.restitution);
        let flight = |q: f64, v: f64, s: f64| (q + v * s - 0.5 * g * s * s, v - g * s);
        // First landing: q0 + v0 s − g s²/2 = 0, the positive root.
        let landing = if g > 0.0 {
            (self.v0 + (self.v0 * self.v0 + 2.0 * g * self.q0).sqrt()) / g
        } else if self.v0 < 0.0 {
            -self.q0 / self.v0
        } else {
            f64::INFINITY
        };
        if t < landing {
            return flight(self.q0, self.v0, t);
        }
        let mut start = landing;
        let mut u = -e * (self.v0 - g * landing);
        if g == 0.0 {
            return (u * (t - start), u);
        }
        if e < 1.0 && t >= start + 2.0 * u / (g * (1.0 - e)) {
            return (0.0, 0.0);
        }
        loop {
            let duration = 2.0 * u / g;
            if t < start + duration || duration <= 0.0 {
                return if duration <= 0.0 {
                    (0.0, 0.0)
                } else {
                    flight(0.0, u, t - start)
                };
            }
            start += duration;
            u *= e;
        }
    }
}

impl Default for BouncingBall {
    fn default() -> Self {
        Self {
            mass: 1.0,
            gravity: 9.81,
            q0: 1.0,
            v0: 0.0,
            restitution: 0.9,
        }
    }
}

impl BouncingBall {
    /// The model `m q̈ = −m g + λ`, `g = q ≥ 0`.
    pub fn build(&self) -> Result<LinearModel, ModelError> {
        check_range("mass", self.mass, f64::MIN_POSITIVE, f64::MAX, "(0, ∞)")?;
        check_range("gravity", self.gravity, 0.0, f64::MAX, "[0, ∞)")?;
        check_range(
            "q0",
            self.q0,
            0.0,
            f64::MAX,
            "[0, ∞) (the ball starts above the ground)",
        )?;
        check_range("v0", self.v0, f64::MIN, f64::MAX, "finite values")?;
        check_range("restitution", self.restitution, 0.0, 1.0, "[0, 1]")?;
        LinearModel::new(
            SymBand::diagonal(&[self.mass]),
            SymBand::zeros(1, 0),
            SymBand::zeros(1, 0),
            Forcing {
                constant: vec![-self.mass * self.gravity],
                harmonic: vec![],
            },
            vec![Contact {
                g: vec![(0, 1.0)],
                offset: 0.0,
                motion: None,
                restitution: self.restitution,
            }],
            vec![self.q0],
            vec![self.v0],
        )
    }
}

/// Mass matrix of the bar elements.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum MassMatrix {
    /// Diagonal, ρ A h_e / 2 per element end.
    #[default]
    Lumped,
    /// ρ A h_e / 6 · [[2, 1], [1, 2]].
    Consistent,
}

/// Boundary condition of the bar's left end.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum LeftEnd {
    /// u(0) = 0 (the node is removed).
    #[default]
    Fixed,
    /// Free end.
    Free,
}

/// `amplitude · sin(omega · t)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct HarmonicSpec {
    /// Amplitude.
    pub amplitude: f64,
    /// Angular frequency (rad/s).
    pub omega: f64,
}

/// Most elements of a bar (finite or wave elements): 10⁷, a few hundred MB of state; checked
/// before anything is allocated.
pub const MAX_ELEMENTS: usize = 10_000_000;

/// An elastic bar of linear finite elements along x ∈ [0, L], its right end facing a rigid
/// obstacle at distance `gap`: `g = gap + wall(t) − u_N ≥ 0`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Bar {
    /// Number of elements N ≥ 1, default 100.
    pub elements: usize,
    /// Length L > 0, default 1.
    pub length: f64,
    /// Young's modulus E > 0, default 1.
    pub young: f64,
    /// Density ρ > 0, default 1.
    pub density: f64,
    /// Cross-section A > 0, default 1.
    pub area: f64,
    /// Lumped (default) or consistent mass.
    pub mass_matrix: MassMatrix,
    /// Left end fixed (default) or free.
    pub left: LeftEnd,
    /// Distance from the right end to the obstacle at rest (any sign), default 0.
    pub gap: f64,
    /// Restitution in [0, 1] at the right end, default 0.
    pub restitution: f64,
    /// Uniform initial velocity (toward the obstacle), default 0.
    pub initial_velocity: f64,
    /// Uniform initial displacement (toward the obstacle), default 0.
    pub initial_displacement: f64,
    /// Body force per unit length, toward the obstacle, default 0.
    pub body_force: f64,
    /// Rayleigh damping C = a M + b K: the coefficient a ≥ 0, default 0.
    pub rayleigh_mass: f64,
    /// Rayleigh damping coefficient b ≥ 0, default 0.
    pub rayleigh_stiffness: f64,
    /// Distributed force per unit length `amplitude · sin(omega t)`, toward the obstacle.
    pub harmonic_force: Option<HarmonicSpec>,
    /// Obstacle motion away from the bar, `amplitude · sin(omega t)`.
    pub wall_motion: Option<HarmonicSpec>,
}

impl Default for Bar {
    fn default() -> Self {
        Self {
            elements: 100,
            length: 1.0,
            young: 1.0,
            density: 1.0,
            area: 1.0,
            mass_matrix: MassMatrix::Lumped,
            left: LeftEnd::Fixed,
            gap: 0.0,
            restitution: 0.0,
            initial_velocity: 0.0,
            initial_displacement: 0.0,
            body_force: 0.0,
            rayleigh_mass: 0.0,
            rayleigh_stiffness: 0.0,
            harmonic_force: None,
            wall_motion: None,
        }
    }
}

impl Bar {
    /// The Doyen–Ern–Piperno bouncing bar (Yoong et al. 2018, Table 1): free left end, E = 900,
    /// ρ = 1, L = 10, A = 1, g0 = 5, body force 10 N/m toward the obstacle, at rest, e = 0.
    pub fn doyen_ern_piperno(elements: usize) -> Self {
        Self {
            elements,
            length: 10.0,
            young: 900.0,
            density: 1.0,
            area: 1.0,
            left: LeftEnd::Free,
            gap: 5.0,
            body_force: 10.0,
            ..Self::default()
        }
    }

    /// Wave speed c = √(E/ρ).
    pub fn wave_speed(&self) -> f64 {
        (self.young / self.density).sqrt()
    }

    /// Dof index of the node at x = L.
    pub fn contact_dof(&self) -> usize {
        match self.left {
            LeftEnd::Fixed => self.elements - 1,
            LeftEnd::Free => self.elements,
        }
    }

    /// Builds the model. Dofs are nodal displacements from left to right (without node 0 when
    /// the left end is fixed).
    pub fn build(&self) -> Result<LinearModel, ModelError> {
        self.build_with(None)
    }

    /// The nodes a distributed obstacle touches, `(dof, x)` from left to right: every node but
    /// the right end (which keeps its end contact) and a fixed left end.
    pub fn obstacle_nodes(&self) -> Vec<(usize, f64)> {
        let he = self.length / self.elements as f64;
        let first = match self.left {
            LeftEnd::Fixed => 1,
            LeftEnd::Free => 0,
        };
        (0..self.contact_dof())
            .map(|i| (i, (i + first) as f64 * he))
            .collect()
    }

    /// Builds the model with a distributed `obstacle` under every node but the right end
    /// (field `obstacle.…` in errors); [`Bar::build`] without.
    pub fn build_with(&self, obstacle: Option<&Obstacle>) -> Result<LinearModel, ModelError> {
        if !(1..=MAX_ELEMENTS).contains(&self.elements) {
            return Err(ModelError::OutOfRange {
                field: "elements".into(),
                value: self.elements as f64,
                range: "[1, 10⁷]",
            });
        }
        for (f, x) in [
            ("length", self.length),
            ("young", self.young),
            ("density", self.density),
            ("area", self.area),
        ] {
            check_range(f, x, f64::MIN_POSITIVE, f64::MAX, "(0, ∞)")?;
        }
        for (f, x) in [
            ("gap", self.gap),
            ("initial_velocity", self.initial_velocity),
            ("initial_displacement", self.initial_displacement),
            ("body_force", self.body_force),
        ] {
            check_range(f, x, f64::MIN, f64::MAX, "finite values")?;
        }
        check_range("restitution", self.restitution, 0.0, 1.0, "[0, 1]")?;
        check_range("rayleigh_mass", self.rayleigh_mass, 0.0, f64::MAX, "[0, ∞)")?;
        check_range(
            "rayleigh_stiffness",
            self.rayleigh_stiffness,
            0.0,
            f64::MAX,
            "[0, ∞)",
        )?;
        for (f, h) in [
            ("harmonic_force", self.harmonic_force),
            ("wall_motion", self.wall_motion),
        ] {
            if let Some(h) = h {
                check_range(
                    &format!("{f}.amplitude"),
                    h.amplitude,
                    f64::MIN,
                    f64::MAX,
                    "finite values",
                )?;
                check_range(
                    &format!("{f}.omega"),
                    h.omega,
                    f64::MIN,
                    f64::MAX,
                    "finite values",
                )?;
            }
        }
        let ne = self.elements;
        let he = self.length / ne as f64;
        let first = match self.left {
            LeftEnd::Fixed => 1,
            LeftEnd::Free => 0,
        };
        let n = ne + 1 - first;
        let dof = |node: usize| node.checked_sub(first);
        let ke = self.young * self.area / he;
        let me = self.density * self.area * he;
        let mut k = SymBand::zeros(n, 1);
        let mut m = SymBand::zeros(
            n,
            if self.mass_matrix == MassMatrix::Consistent {
                1
            } else {
                0
            },
        );
        // Nodal weights of a uniform load per unit length: ∫ N_i = h_e/2 per element end.
        let mut load_shape = vec![0.0; n];
        for e in 0..ne {
            let (a, b) = (dof(e), dof(e + 1));
            for (i, j, s) in [(a, a, 1.0), (b, b, 1.0), (b, a, -1.0)] {
                if let (Some(i), Some(j)) = (i, j) {
                    k.add(i, j, s * ke);
                }
            }
            match self.mass_matrix {
                MassMatrix::Lumped => {
                    for i in [a, b].into_iter().flatten() {
                        m.add(i, i, me / 2.0);
                    }
                }
                MassMatrix::Consistent => {
                    for (i, j, s) in [(a, a, 2.0), (b, b, 2.0), (b, a, 1.0)] {
                        if let (Some(i), Some(j)) = (i, j) {
                            m.add(i, j, s * me / 6.0);
                        }
                    }
                }
            }
            for i in [a, b].into_iter().flatten() {
                load_shape[i] += he / 2.0;
            }
        }
        let damping = SymBand::combine(&[(self.rayleigh_mass, &m), (self.rayleigh_stiffness, &k)]);
        let force = Forcing {
            constant: load_shape.iter().map(|w| w * self.body_force).collect(),
            harmonic: self
                .harmonic_force
                .map(|h| HarmonicLoad {
                    shape: load_shape.iter().map(|w| w * h.amplitude).collect(),
                    omega: h.omega,
                    phase: 0.0,
                })
                .into_iter()
                .collect(),
        };
        let contact = Contact {
            g: vec![(self.contact_dof(), -1.0)],
            offset: self.gap,
            motion: self.wall_motion.map(|h| Harmonic {
                amplitude: h.amplitude,
                omega: h.omega,
                phase: 0.0,
            }),
            restitution: self.restitution,
        };
        let q0 = vec![self.initial_displacement; n];
        let mut contacts = vec![contact];
        if let Some(o) = obstacle {
            contacts.extend(o.contacts(&self.obstacle_nodes(), self.length, &q0)?);
        }
        LinearModel::new(
            m,
            damping,
            k,
            force,
            contacts,
            q0,
            vec![self.initial_velocity; n],
        )
    }
}

/// A rigid obstacle under a string or a bar, of profile `y(x) = −offset + curvature (x − L/2)²`
/// (a parabolic bridge; flat for curvature 0): one contact per node at x_i, gap
/// `g_i = q_i + offset − curvature (x_i − L/2)² ≥ 0`, Newton restitution e.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Obstacle {
    /// Depth of the obstacle's apex (x = L/2) below the rest line (any finite value; the
    /// initial shape must not lie below the obstacle).
    pub offset: f64,
    /// Curvature of the parabolic profile (finite, default 0: a flat obstacle).
    #[serde(default)]
    pub curvature: f64,
    /// Newton restitution in [0, 1], default 0.
    #[serde(default)]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub restitution: f64,
}

impl Obstacle {
    /// Its contacts at the nodes `(dof, x)` of a body of length `length` whose initial
    /// displacement is `q0`; errors name `obstacle.offset`, `obstacle.curvature`,
    /// `obstacle.restitution`, and `obstacle.offset` when a node starts below the profile.
    pub fn contacts(
        &self,
        nodes: &[(usize, f64)],
        length: f64,
        q0: &[f64],
    ) -> Result<Vec<Contact>, ModelError> {
        check_range(
            "obstacle.offset",
            self.offset,
            f64::MIN,
            f64::MAX,
            "finite values",
        )?;
        check_range(
            "obstacle.curvature",
            self.curvature,
            f64::MIN,
            f64::MAX,
            "finite values",
        )?;
        check_range("obstacle.restitution", self.restitution, 0.0, 1.0, "[0, 1]")?;
        nodes
            .iter()
            .map(|&(dof, x)| {
                let w = self.offset - self.curvature * (x - 0.5 * length).powi(2);
                if q0[dof] + w < 0.0 {
                    return Err(ModelError::OutOfRange {
                        field: "obstacle.offset".into(),
                        value: self.offset,
                        range: "values that leave the initial shape on or above the obstacle",
                    });
                }
                Ok(Contact {
                    g: vec![(dof, 1.0)],
                    offset: w,
                    motion: None,
                    restitution: self.restitution,
                })
            })
            .collect()
    }
}

/// The initial shape of a plucked string: a triangle of height `amplitude` at `position`, at
/// rest.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Pluck {
    /// Where the string is plucked, 0 < position < length (m).
    pub position: f64,
    /// Displacement there (m, any sign; positive is away from the obstacle).
    pub amplitude: f64,
}

/// `scene = "string"`: a transverse string of length L under tension T with linear density
/// ρ, fixed at both ends, discretised by `nodes` moving nodes at `x_j = (j + 1) L/(N + 1)`
/// with lumped masses `ρ Δx` and the finite-difference stiffness `(T/Δx) tridiag(−1, 2, −1)`
/// (Δx = L/(N + 1)): `M q̈ + K q = G λ`, the ideal string of Issanchou, Acary, Pérignon, Touzé
/// & Le Carrou 2018 (no stiffness or losses). The wave speed is `c = √(T/ρ)`. An optional
/// [`Obstacle`] puts a contact at every node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct StringScene {
    /// Moving nodes N (1 … 10⁷), default 100.
    #[schemars(range(min = 1, max = 10_000_000))]
    pub nodes: usize,
    /// Length L > 0 (m), default 1.
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub length: f64,
    /// Tension T > 0 (N), default 100.
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub tension: f64,
    /// Linear density ρ > 0 (kg/m), default 0.01.
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub linear_density: f64,
    /// Initial triangular shape (default: none, the string at rest on its line).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pluck: Option<Pluck>,
    /// The obstacle under the string (default: none).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub obstacle: Option<Obstacle>,
}

impl Default for StringScene {
    fn default() -> Self {
        Self {
            nodes: 100,
            length: 1.0,
            tension: 100.0,
            linear_density: 0.01,
            pluck: None,
            obstacle: None,
        }
    }
}

impl StringScene {
    /// Node spacing Δx = L/(N + 1).
    pub fn spacing(&self) -> f64 {
        self.length / (self.nodes + 1) as f64
    }

    /// Abscissa of dof j.
    pub fn x(&self, j: usize) -> f64 {
        (j + 1) as f64 * self.spacing()
    }

    /// Builds the model (dofs: the transverse displacements of the moving nodes, left to right).
    pub fn build(&self) -> Result<LinearModel, ModelError> {
        if !(1..=MAX_ELEMENTS).contains(&self.nodes) {
            return Err(ModelError::OutOfRange {
                field: "nodes".into(),
                value: self.nodes as f64,
                range: "[1, 10⁷]",
            });
        }
        for (f, x) in [
            ("length", self.length),
            ("tension", self.tension),
            ("linear_density", self.linear_density),
        ] {
            check_range(f, x, f64::MIN_POSITIVE, f64::MAX, "(0, ∞)")?;
        }
        let (n, dx, l) = (self.nodes, self.spacing(), self.length);
        let mut q0 = vec![0.0; n];
        if let Some(p) = self.pluck {
            if !p.position.is_finite() || p.position <= 0.0 || p.position >= l {
                return Err(ModelError::OutOfRange {
                    field: "pluck.position".into(),
                    value: p.position,
                    range: "(0, length)",
                });
            }
            check_range(
                "pluck.amplitude",
                p.amplitude,
                f64::MIN,
                f64::MAX,
                "finite values",
            )?;
            for (j, q) in q0.iter_mut().enumerate() {
                let x = self.x(j);
                *q = if x <= p.position {
                    p.amplitude * x / p.position
                } else {
                    p.amplitude * (l - x) / (l - p.position)
                };
            }
        }
        let kt = self.tension / dx;
        let mut k = SymBand::zeros(n, 1);
        for j in 0..n {
            k.set(j, j, 2.0 * kt);
            if j > 0 {
                k.set(j, j - 1, -kt);
            }
        }
        let contacts = match &self.obstacle {
            Some(o) => {
                let nodes: Vec<(usize, f64)> = (0..n).map(|j| (j, self.x(j))).collect();
                o.contacts(&nodes, l, &q0)?
            }
            None => Vec::new(),
        };
        LinearModel::new(
            SymBand::diagonal(&vec![self.linear_density * dx; n]),
            SymBand::zeros(n, 0),
            k,
            Forcing {
                constant: vec![0.0; n],
                harmonic: vec![],
            },
            contacts,
            q0,
            vec![0.0; n],
        )
    }
}

/// The `[model]` section of the `bar` and `dep_bar` scenes: every field optional, missing ones
/// taken from the scene's defaults ([`Bar::default`] or [`Bar::doyen_ern_piperno`]).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BarSpec {
    /// Number of linear finite elements (1 … 10⁷).
    #[schemars(range(min = 1, max = 10_000_000))]
    pub elements: Option<usize>,
    /// Bar length L > 0.
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub length: Option<f64>,
    /// Young's modulus E > 0.
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub young: Option<f64>,
    /// Density ρ > 0.
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub density: Option<f64>,
    /// Cross-section A > 0.
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub area: Option<f64>,
    /// Mass matrix of the elements: `lumped` or `consistent`.
    pub mass_matrix: Option<MassMatrix>,
    /// Boundary condition of the left end: `fixed` or `free`.
    pub left: Option<LeftEnd>,
    /// Distance from the right end to the obstacle at rest (any sign; positive displacement moves toward it).
    pub gap: Option<f64>,
    /// Newton restitution at the right end, in [0, 1].
    #[schemars(range(min = 0.0, max = 1.0))]
    pub restitution: Option<f64>,
    /// Uniform initial velocity toward the obstacle.
    pub initial_velocity: Option<f64>,
    /// Uniform initial displacement toward the obstacle.
    pub initial_displacement: Option<f64>,
    /// Force per unit length toward the obstacle.
    pub body_force: Option<f64>,
    /// Rayleigh damping C = a M + b K: a ≥ 0.
    #[schemars(range(min = 0.0))]
    pub rayleigh_mass: Option<f64>,
    /// Rayleigh damping C = a M + b K: b ≥ 0.
    #[schemars(range(min = 0.0))]
    pub rayleigh_stiffness: Option<f64>,
    /// Distributed force `amplitude · sin(omega t)` per unit length.
    pub harmonic_force: Option<HarmonicSpec>,
    /// Obstacle motion `amplitude · sin(omega t)`.
    pub wall_motion: Option<HarmonicSpec>,
    /// A distributed obstacle under the bar's displacement (a unilateral foundation): a
    /// contact `u_i ≥ −offset + curvature (x_i − L/2)²` at every node but the right end, which
    /// keeps its end contact. Moreau–Jean and the nonsmooth α-family only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub obstacle: Option<Obstacle>,
}

impl BarSpec {
    /// The bar with the given fields overriding `base`.
    pub fn resolve(&self, base: Bar) -> Bar {
        Bar {
            elements: self.elements.unwrap_or(base.elements),
            length: self.length.unwrap_or(base.length),
            young: self.young.unwrap_or(base.young),
            density: self.density.unwrap_or(base.density),
            area: self.area.unwrap_or(base.area),
            mass_matrix: self.mass_matrix.unwrap_or(base.mass_matrix),
            left: self.left.unwrap_or(base.left),
            gap: self.gap.unwrap_or(base.gap),
            restitution: self.restitution.unwrap_or(base.restitution),
            initial_velocity: self.initial_velocity.unwrap_or(base.initial_velocity),
            initial_displacement: self
                .initial_displacement
                .unwrap_or(base.initial_displacement),
            body_force: self.body_force.unwrap_or(base.body_force),
            rayleigh_mass: self.rayleigh_mass.unwrap_or(base.rayleigh_mass),
            rayleigh_stiffness: self.rayleigh_stiffness.unwrap_or(base.rayleigh_stiffness),
            harmonic_force: self.harmonic_force.or(base.harmonic_force),
            wall_motion: self.wall_motion.or(base.wall_motion),
        }
    }
}

/// Point masses joined by springs along a line, each facing a wall:
/// `g_i = positions[i] + q_i − wall ≥ 0` (several simultaneous contacts).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct Chain {
    /// Masses (> 0), default [1, 1, 1].
    pub masses: Vec<f64>,
    /// Stiffness of the springs between neighbours (≥ 0), at rest initially; default 100.
    #[schemars(range(min = 0.0))]
    pub stiffness: f64,
    /// Initial positions (absolute), default [1, 1.5, 2].
    pub positions: Vec<f64>,
    /// Initial velocities, default all −1 (toward the wall).
    pub velocities: Vec<f64>,
    /// Wall position, default 0.
    pub wall: f64,
    /// Restitution in [0, 1], default 0.5.
    #[schemars(range(min = 0.0, max = 1.0))]
    pub restitution: f64,
    /// Constant force on each mass (optional).
    pub force: Option<Vec<f64>>,
}

impl Default for Chain {
    fn default() -> Self {
        Self {
            masses: vec![1.0; 3],
            stiffness: 100.0,
            positions: vec![1.0, 1.5, 2.0],
            velocities: vec![-1.0; 3],
            wall: 0.0,
            restitution: 0.5,
            force: None,
        }
    }
}

impl Chain {
    /// Builds the model: dofs are displacements from the initial positions.
    pub fn build(&self) -> Result<LinearModel, ModelError> {
        let n = self.masses.len();
        if n == 0 {
            return Err(ModelError::Dimension {
                field: "masses".into(),
                expected: 1,
                found: 0,
            });
        }
        for (i, &m) in self.masses.iter().enumerate() {
            check_range(
                &format!("masses[{i}]"),
                m,
                f64::MIN_POSITIVE,
                f64::MAX,
                "(0, ∞)",
            )?;
        }
        check_range("stiffness", self.stiffness, 0.0, f64::MAX, "[0, ∞)")?;
        check_vector("positions", &self.positions, n)?;
        check_vector("velocities", &self.velocities, n)?;
        check_range("wall", self.wall, f64::MIN, f64::MAX, "finite values")?;
        check_range("restitution", self.restitution, 0.0, 1.0, "[0, 1]")?;
        let force = self.force.clone().unwrap_or_else(|| vec![0.0; n]);
        check_vector("force", &force, n)?;
        let mut k = SymBand::zeros(n, 1);
        for i in 1..n {
            k.add(i, i, self.stiffness);
            k.add(i - 1, i - 1, self.stiffness);
            k.add(i, i - 1, -self.stiffness);
        }
        let contacts = (0..n)
            .map(|i| Contact {
                g: vec![(i, 1.0)],
                offset: self.positions[i] - self.wall,
                motion: None,
                restitution: self.restitution,
            })
            .collect();
        LinearModel::new(
            SymBand::diagonal(&self.masses),
            SymBand::zeros(n, 0),
            k,
            Forcing {
                constant: force,
                harmonic: vec![],
            },
            contacts,
            vec![0.0; n],
            self.velocities.clone(),
        )
    }
}
