//! Wave Finite Element Method (WFEM) for the 1D elastic bar with a floating contact boundary
//! (Yoong, Thorin & Legrand 2018, Appendices A–B, Algorithm 2).
//!
//! The bar x ∈ [0, L] is cut into N cells of stress σ_i and velocity v_i; Δt = Δx/c with
//! c = √(E/ρ). The Godunov update (36) with the ghost cells (37), (50), (51) is, in the
//! characteristic variables `a = σ − ρc v` (right-going) and `b = σ + ρc v` (left-going),
//!
//! ```text
//! a_i ← a_{i−1},   b_i ← b_{i+1}          (36) for the inner cells
//! a_1 ← s_L b_1                           (38): s_L = +1 fixed left end, −1 free left end
//! b_N ← s_R a_N + 2ρc ẇ                   (39) with (50)/(51): s_R = +1 in contact, −1 free
//! ```
//!
//! i.e. a *signed permutation* of the 2N values: the `a` run a_1…a_N followed by the `b` run
//! b_N…b_1 form a ring that rotates by one position per step, with a sign at each end. We
//! store the a's and the b's in cell order, each with a moving origin (the rotation is two
//! opposite shifts, see [`WaveState`]), so an unforced step costs O(1) and moves values without
//! arithmetic: the cell energy `S Δx Σ (a_i² + b_i²)/(4ρc²)` is conserved exactly, not just to
//! round-off. The paper's (36)–(39) form is kept as [`flux_form_step`] for cross-checks.
//!
//! Sources (body force, harmonic distributed force, viscous damping) act on the velocity only
//! and are applied after the transport by a source step that conserves the discrete energy
//! identity exactly (see [`WaveBar::damping`]); a moving wall enters through the contact ghost
//! cell and its work is the contact work `S Δt σ* ẇ`.

pub mod exact;
pub mod job;

use crate::scenes::{Bar, HarmonicSpec, LeftEnd, MassMatrix};
use thiserror::Error;

/// Why a wave bar is invalid.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum WfemError {
    /// A parameter is outside its range.
    #[error("{field} = {value} is outside {range}")]
    OutOfRange {
        /// Parameter name (as in the `bar` scene).
        field: &'static str,
        /// Offending value.
        value: f64,
        /// Accepted range.
        range: &'static str,
    },
    /// A `bar` option that wave finite elements do not model.
    #[error("{field}: {reason}")]
    Unsupported {
        /// Parameter name (as in the `bar` scene).
        field: &'static str,
        /// Why.
        reason: &'static str,
    },
}

/// A bar of wave finite elements: N cells along x ∈ [0, L], left end fixed or free, right end
/// facing an obstacle at distance `gap` (any sign): `g = gap + w(t) − u(L, t) ≥ 0` (Appendix B).
#[derive(Debug, Clone, PartialEq)]
pub struct WaveBar {
    /// Number of cells N ≥ 1.
    pub cells: usize,
    /// Length L > 0.
    pub length: f64,
    /// Young's modulus E > 0.
    pub young: f64,
    /// Density ρ > 0.
    pub density: f64,
    /// Cross-section S > 0.
    pub area: f64,
    /// Left end fixed (u(0) = 0) or free (σ(0) = 0).
    pub left: LeftEnd,
    /// Gap g0 at rest (any sign). With g0 < 0 and a fixed left end the bar starts from its
    /// prestressed static state σ = E g0 / L.
    pub gap: f64,
    /// Uniform initial velocity.
    pub initial_velocity: f64,
    /// Uniform initial displacement (free left end only).
    pub initial_displacement: f64,
    /// Body force per unit length, toward the obstacle.
    pub body_force: f64,
    /// Viscous damping γ ≥ 0 (1/s): a force −γ ρ S v per unit length (the `rayleigh_mass`
    /// coefficient of the `bar` scene). The source step treats it with the trapezoidal rule
    /// `v⁺ − v = Δt (f̄/(ρS) − γ (v + v⁺)/2)`, so `ΔK = work_ext + work_damping` exactly with
    /// `work_ext = Δx Δt f̄ v̄` and `work_damping = −γ ρ S Δx Δt v̄²`, `v̄ = (v + v⁺)/2`.
    pub damping: f64,
    /// Distributed force per unit length `amplitude · sin(omega t)`, toward the obstacle.
    /// The source step uses its exact mean over the step, f̄.
    pub harmonic_force: Option<HarmonicSpec>,
    /// Obstacle motion away from the bar `w(t) = amplitude · sin(omega t)`; in contact the
    /// end velocity is the exact mean wall velocity over the step `(w(t_{n+1}) − w(t_n))/Δt`.
    pub wall_motion: Option<HarmonicSpec>,
}

impl WaveBar {
    /// The wave bar of a `bar`/`dep_bar` scene: cells = elements, `rayleigh_mass` = γ.
    pub fn from_bar(bar: &Bar) -> Result<Self, WfemError> {
        if bar.rayleigh_stiffness != 0.0 {
            return Err(WfemError::Unsupported {
                field: "rayleigh_stiffness",
                reason: "wave finite elements model viscous (mass-proportional) damping only",
            });
        }
        if bar.restitution != 0.0 {
            return Err(WfemError::Unsupported {
                field: "restitution",
                reason: "wave finite elements need no impact law: leave restitution at 0",
            });
        }
        if bar.mass_matrix == MassMatrix::Consistent {
            return Err(WfemError::Unsupported {
                field: "mass_matrix",
                reason: "wave finite elements have no mass matrix: leave it at \"lumped\"",
            });
        }
        let w = WaveBar {
            cells: bar.elements,
            length: bar.length,
            young: bar.young,
            density: bar.density,
            area: bar.area,
            left: bar.left,
            gap: bar.gap,
            initial_velocity: bar.initial_velocity,
            initial_displacement: bar.initial_displacement,
            body_force: bar.body_force,
            damping: bar.rayleigh_mass,
            harmonic_force: bar.harmonic_force,
            wall_motion: bar.wall_motion,
        };
        w.validate()?;
        Ok(w)
    }

    /// A unit bar (L = E = ρ = S = 1) of `cells` cells, fixed left end, gap `gap`, at rest:
    /// the system of the paper's §§2, 6.
    pub fn unit(cells: usize, gap: f64) -> Self {
        WaveBar {
            cells,
            length: 1.0,
            young: 1.0,
            density: 1.0,
            area: 1.0,
            left: LeftEnd::Fixed,
            gap,
            initial_velocity: 0.0,
            initial_displacement: 0.0,
            body_force: 0.0,
            damping: 0.0,
            harmonic_force: None,
            wall_motion: None,
        }
    }

    /// Checks every parameter.
    pub fn validate(&self) -> Result<(), WfemError> {
        if !(1..=crate::scenes::MAX_ELEMENTS).contains(&self.cells) {
            return Err(WfemError::OutOfRange {
                field: "elements",
                value: self.cells as f64,
                range: "[1, 10⁷]",
            });
        }
        for (field, x) in [
            ("length", self.length),
            ("young", self.young),
            ("density", self.density),
            ("area", self.area),
        ] {
            if !(x.is_finite() && x > 0.0) {
                return Err(WfemError::OutOfRange {
                    field,
                    value: x,
                    range: "(0, ∞)",
                });
            }
        }
        for (field, x) in [
            ("gap", self.gap),
            ("initial_velocity", self.initial_velocity),
            ("initial_displacement", self.initial_displacement),
            ("body_force", self.body_force),
        ] {
            if !x.is_finite() {
                return Err(WfemError::OutOfRange {
                    field,
                    value: x,
                    range: "finite values",
                });
            }
        }
        if !(self.damping.is_finite() && self.damping >= 0.0) {
            return Err(WfemError::OutOfRange {
                field: "rayleigh_mass",
                value: self.damping,
                range: "[0, ∞)",
            });
        }
        for (field, h) in [
            ("harmonic_force", self.harmonic_force),
            ("wall_motion", self.wall_motion),
        ] {
            if let Some(h) = h
                && !(h.amplitude.is_finite() && h.omega.is_finite())
            {
                return Err(WfemError::OutOfRange {
                    field,
                    value: h.amplitude * h.omega,
                    range: "finite values",
                });
            }
        }
        if self.left == LeftEnd::Fixed && self.initial_displacement != 0.0 {
            return Err(WfemError::Unsupported {
                field: "initial_displacement",
                reason: "a fixed left end has u(0) = 0: a uniform displacement is only possible with left = \"free\"",
            });
        }
        Ok(())
    }

    /// Wave speed c = √(E/ρ).
    pub fn wave_speed(&self) -> f64 {
        (self.young / self.density).sqrt()
    }

    /// Impedance ρc (stress per velocity).
    pub fn impedance(&self) -> f64 {
        self.density * self.wave_speed()
    }

    /// Cell size Δx = L/N.
    pub fn dx(&self) -> f64 {
        self.length / self.cells as f64
    }

    /// Time step Δt = Δx/c (Appendix A.4).
    pub fn dt(&self) -> f64 {
        self.dx() / self.wave_speed()
    }

    /// Wall position w(t) (0 without wall motion).
    pub fn wall(&self, t: f64) -> f64 {
        self.wall_motion
            .map_or(0.0, |h| h.amplitude * (h.omega * t).sin())
    }

    fn has_source(&self) -> bool {
        self.body_force != 0.0
            || self.damping != 0.0
            || self.harmonic_force.is_some_and(|h| h.amplitude != 0.0)
    }

    /// Exact mean over [t0, t1] of the distributed force per unit length.
    fn mean_force(&self, t0: f64, t1: f64) -> f64 {
        let harmonic = match self.harmonic_force {
            Some(h) if h.omega != 0.0 => {
                h.amplitude * ((h.omega * t0).cos() - (h.omega * t1).cos()) / (h.omega * (t1 - t0))
            }
            _ => 0.0,
        };
        self.body_force + harmonic
    }

    /// The initial state: σ = 0 and v = `initial_velocity` in every cell, except for g0 < 0 with
    /// a fixed left end, where σ = E g0/L (the prestressed static state, u(L) = g0).
    pub fn initial_state(&self) -> WaveState {
        let n = self.cells;
        let z = self.impedance();
        let prestressed = self.gap < 0.0 && self.left == LeftEnd::Fixed;
        let sigma = if prestressed {
            self.young * self.gap / self.length
        } else {
            0.0
        };
        let v = self.initial_velocity;
        let u_left = self.initial_displacement;
        let u_right = if prestressed {
            self.gap
        } else {
            self.initial_displacement
        };
        WaveState::from_cells(&vec![sigma; n], &vec![v; n], z, u_left, u_right)
    }
}

/// State of a wave bar at t_n: the ring of characteristic values (see the module doc), the
/// displacements of both ends, and the step number.
///
/// The ring is stored as two arrays in cell order, the a's in `cells[..N]` and the b's in
/// `cells[N..]`, each with its own moving origin: a step shifts the a's by one cell to the
/// right and the b's by one cell to the left (two opposite shifts by the same count, so one
/// counter `shift` ∈ [0, N) places both: a_i is at `(i − shift) mod N`, b_i at
/// `N + (i + shift) mod N`). A sweep over the cells then reads a_i and b_i from two forward
/// runs (at most three run pairs per sweep), which the compiler vectorises; the ring storing
/// the b's backwards did not. Checkpoints keep the ring's position form (`ring`, `shift` of
/// the module doc), so the format is unchanged.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
#[serde(try_from = "RingForm", into = "RingForm")]
pub struct WaveState {
    cells: Vec<f64>,
    shift: usize,
    /// Step number n.
    pub step: u64,
    /// Displacement u(0, t_n) of the left end (0 for a fixed end).
    pub u_left: f64,
    /// Displacement u(L, t_n) = u_{N+1/2} of the contact end: integral of the interface velocity
    /// of the Riemann solution (30), equal to `u_left + Σ Δx σ_i / E` (the paper's strain
    /// integration) by the discrete conservation law (27).
    pub u_right: f64,
}

/// The serialised form of a [`WaveState`]: the ring in storage with a moving origin, position
/// p (a_1…a_N, b_N…b_1) at `(p − shift) mod 2N` (what checkpoints have always held).
#[derive(serde::Serialize, serde::Deserialize)]
struct RingForm {
    ring: Vec<f64>,
    shift: usize,
    step: u64,
    u_left: f64,
    u_right: f64,
}

impl From<WaveState> for RingForm {
    fn from(s: WaveState) -> Self {
        RingForm {
            ring: s.ring(),
            shift: 0,
            step: s.step,
            u_left: s.u_left,
            u_right: s.u_right,
        }
    }
}

impl TryFrom<RingForm> for WaveState {
    type Error = String;

    fn try_from(r: RingForm) -> Result<Self, String> {
        let n2 = r.ring.len();
        if !n2.is_multiple_of(2) || r.shift >= n2.max(1) {
            return Err(format!(
                "a WFEM ring of {n2} values with shift {} (expected an even length and a shift below it)",
                r.shift
            ));
        }
        let positions = (0..n2).map(|p| r.ring[(p + n2 - r.shift) % n2]).collect();
        let mut state = WaveState::from_ring(positions, r.u_left, r.u_right);
        state.step = r.step;
        Ok(state)
    }
}

/// Two states are equal when their cells, ends and step are (whatever the storage origin).
impl PartialEq for WaveState {
    fn eq(&self, other: &Self) -> bool {
        self.cells.len() == other.cells.len()
            && self.step == other.step
            && self.u_left == other.u_left
            && self.u_right == other.u_right
            && (0..self.cells()).all(|i| self.a(i) == other.a(i) && self.b(i) == other.b(i))
    }
}

impl WaveState {
    /// Whether `self` has as many cells as `other` (a checkpoint's state fits the bar).
    pub(crate) fn fits(&self, other: &WaveState) -> bool {
        self.cells.len() == other.cells.len() && self.shift < self.cells().max(1)
    }
}

impl WaveState {
    /// A state from cell stresses and velocities (equal lengths N ≥ 1) and impedance ρc.
    pub fn from_cells(sigma: &[f64], v: &[f64], impedance: f64, u_left: f64, u_right: f64) -> Self {
        let n = sigma.len();
        let mut cells = vec![0.0; 2 * n];
        for i in 0..n {
            cells[i] = sigma[i] - impedance * v[i];
            cells[n + i] = sigma[i] + impedance * v[i];
        }
        WaveState {
            cells,
            shift: 0,
            step: 0,
            u_left,
            u_right,
        }
    }

    /// A state from ring values (positions 0..N are a_1…a_N, N..2N are b_N…b_1).
    pub fn from_ring(ring: Vec<f64>, u_left: f64, u_right: f64) -> Self {
        let n2 = ring.len();
        let n = n2 / 2;
        let mut cells = ring;
        cells[n..].reverse();
        WaveState {
            cells,
            shift: 0,
            step: 0,
            u_left,
            u_right,
        }
    }

    /// Number of cells N.
    pub fn cells(&self) -> usize {
        self.cells.len() / 2
    }

    /// Storage index of a_i (0-based cell i < N).
    #[inline]
    fn index_a(&self, i: usize) -> usize {
        let n = self.cells();
        let k = i + n - self.shift;
        if k >= n { k - n } else { k }
    }

    /// Storage index of b_i (0-based cell i < N).
    #[inline]
    fn index_b(&self, i: usize) -> usize {
        let n = self.cells();
        let k = i + self.shift;
        n + if k >= n { k - n } else { k }
    }

    /// Calls `f(i, a, b)` on runs of consecutive cells i, i+1, … whose a's and b's are both
    /// contiguous slices (`a[j]`, `b[j]` of cell i + j), in cell order: the two origins split
    /// the cells into at most three runs.
    fn for_each_run(&mut self, mut f: impl FnMut(usize, &mut [f64], &mut [f64])) {
        let n = self.cells();
        let mut i = 0;
        while i < n {
            let ia = self.index_a(i);
            let ib = self.index_b(i) - n;
            let run = (n - i).min(n - ia).min(n - ib);
            let (a, b) = self.cells.split_at_mut(n);
            f(i, &mut a[ia..ia + run], &mut b[ib..ib + run]);
            i += run;
        }
    }

    /// Ring value at `position` (a_{k+1} for k < N, b_{2N−k} for k ≥ N, 1-based cells).
    pub fn ring_value(&self, position: usize) -> f64 {
        let n = self.cells();
        if position < n {
            self.a(position)
        } else {
            self.b(2 * n - 1 - position)
        }
    }

    /// The ring in position order.
    pub fn ring(&self) -> Vec<f64> {
        (0..self.cells.len()).map(|k| self.ring_value(k)).collect()
    }

    /// a_i = σ_i − ρc v_i of cell i (0-based).
    #[inline]
    pub fn a(&self, i: usize) -> f64 {
        self.cells[self.index_a(i)]
    }

    /// b_i = σ_i + ρc v_i of cell i (0-based).
    #[inline]
    pub fn b(&self, i: usize) -> f64 {
        self.cells[self.index_b(i)]
    }

    /// Stress σ_i of cell i.
    pub fn sigma(&self, i: usize) -> f64 {
        0.5 * (self.a(i) + self.b(i))
    }

    /// Velocity v_i of cell i, for impedance ρc.
    pub fn velocity(&self, i: usize, impedance: f64) -> f64 {
        0.5 * (self.b(i) - self.a(i)) / impedance
    }

    /// All stresses and velocities.
    pub fn cells_sigma_v(&self, impedance: f64) -> (Vec<f64>, Vec<f64>) {
        let n = self.cells();
        (
            (0..n).map(|i| self.sigma(i)).collect(),
            (0..n).map(|i| self.velocity(i, impedance)).collect(),
        )
    }

    /// Time t_n = n Δt.
    pub fn time(&self, bar: &WaveBar) -> f64 {
        self.step as f64 * bar.dt()
    }

    /// Kinetic and strain energies of the cells, `Σ S Δx ρ v_i²/2` and `Σ S Δx σ_i²/(2E)`.
    pub fn energies(&self, bar: &WaveBar) -> (f64, f64) {
        let n = self.cells();
        let scale = bar.area * bar.dx() / (8.0 * bar.density * bar.wave_speed().powi(2));
        let (mut kin, mut strain) = (0.0, 0.0);
        for i in 0..n {
            let (a, b) = (self.a(i), self.b(i));
            kin += (b - a) * (b - a);
            strain += (a + b) * (a + b);
        }
        (scale * kin, scale * strain)
    }

    /// Total cell energy `S Δx Σ (a_i² + b_i²)/(4ρc²)` = kinetic + strain.
    pub fn energy(&self, bar: &WaveBar) -> f64 {
        let scale = bar.area * bar.dx() / (4.0 * bar.density * bar.wave_speed().powi(2));
        // In ring position order (a_1…a_N, b_N…b_1): the sum the ring has always summed.
        let n = self.cells();
        let a = (0..n).map(|i| self.a(i));
        let b = (0..n).rev().map(|i| self.b(i));
        scale * a.chain(b).map(|x| x * x).sum::<f64>()
    }

    /// Contact-end displacement by the paper's strain integration (Appendix A.1):
    /// `u(L) = u(0) + Σ Δx σ_i / E`.
    pub fn u_right_from_strains(&self, bar: &WaveBar) -> f64 {
        let n = self.cells();
        self.u_left + bar.dx() / bar.young * (0..n).map(|i| self.sigma(i)).sum::<f64>()
    }

    /// Displacement at the cell interfaces x_{i+1/2}, i = 0..N (strain integration from u(0)).
    pub fn interface_displacements(&self, bar: &WaveBar) -> Vec<f64> {
        let mut u = Vec::with_capacity(self.cells() + 1);
        let mut acc = self.u_left;
        u.push(acc);
        for i in 0..self.cells() {
            acc += bar.dx() / bar.young * self.sigma(i);
            u.push(acc);
        }
        u
    }
}

/// Boundary condition of the contact end during one step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EndCondition {
    /// Free end, σ(L) = 0 (51).
    Free,
    /// Contact, u(L) = g0 + w(t) (50).
    Contact,
}

/// What one step did besides updating the state.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct StepTerms {
    /// True when the contact end was fixed (contact) during the step.
    pub contact: bool,
    /// Interface stress σ* at the contact end over the step (30); the contact force is S σ* (52).
    pub contact_stress: f64,
    /// Interface velocity v* at the contact end over the step (30).
    pub end_velocity: f64,
    /// Mean wall velocity over the step.
    pub wall_velocity: f64,
    /// Work of the distributed forces over the step.
    pub work_ext: f64,
    /// Work of the viscous damping over the step (≤ 0).
    pub work_damping: f64,
    /// Work of the contact force on the bar, `S Δt σ* v*` (0 against a fixed wall).
    pub work_contact: f64,
}

/// Gap tolerance of the contact test: `g ≤ GAP_TOLERANCE · L` counts as closed, so that an orbit
/// closing exactly at g = 0 is not missed by round-off.
pub const GAP_TOLERANCE: f64 = 1e-12;

/// One step of Algorithm 2 from `state` (t_n → t_{n+1}).
///
/// Floating boundary (Appendix B): the gap (49) `g^{(n)} = g0 + w(t_n) − u_{N+1/2}^{(n)}` decides
/// the candidate; with `g ≤ 0` the fixed condition (50) is tried and its contact force (52)
/// `r = S σ*`, `σ* = a_N + ρc ẇ`, is checked: `r > 0` (tension) releases the end (51).
pub fn step(bar: &WaveBar, state: &mut WaveState) -> StepTerms {
    let dt = bar.dt();
    let t0 = state.step as f64 * dt;
    let t1 = (state.step + 1) as f64 * dt;
    let z = bar.impedance();
    let (w0, w1) = (bar.wall(t0), bar.wall(t1));
    let wdot = (w1 - w0) / dt;
    let gap = bar.gap + w0 - state.u_right;
    let condition = if gap <= GAP_TOLERANCE * bar.length && state.a(bar.cells - 1) + z * wdot <= 0.0
    {
        EndCondition::Contact
    } else {
        EndCondition::Free
    };
    let mut terms = transport(bar, state, condition, wdot);
    terms.wall_velocity = wdot;
    if bar.has_source() {
        let (work_ext, work_damping) = source_step(bar, state, t0, t1);
        terms.work_ext = work_ext;
        terms.work_damping = work_damping;
    }
    terms
}

/// The transport part of a step with a given contact-end condition: the signed permutation
/// (36)–(39) with ghost cells (37), (50), (51), and the end displacements advanced by the
/// interface velocities of the Riemann solution (30).
pub fn transport(
    bar: &WaveBar,
    state: &mut WaveState,
    condition: EndCondition,
    wall_velocity: f64,
) -> StepTerms {
    let n = bar.cells;
    let z = bar.impedance();
    let dt = bar.dt();
    let a_n = state.a(n - 1);
    let b_1 = state.b(0);
    let (b_n_new, sigma_star, v_star) = match condition {
        // (50): σ_{N+1} = σ_N, v_{N+1} = 2ẇ − v_N  ⇒  b_N ← a_N + 2ρc ẇ, σ* = a_N + ρc ẇ, v* = ẇ.
        EndCondition::Contact => (
            a_n + 2.0 * z * wall_velocity,
            a_n + z * wall_velocity,
            wall_velocity,
        ),
        // (51): σ_{N+1} = −σ_N, v_{N+1} = v_N  ⇒  b_N ← −a_N, σ* = 0, v* = −a_N/ρc.
        EndCondition::Free => (-a_n, 0.0, -a_n / z),
    };
    // (37) at C_0: fixed σ_0 = σ_1, v_0 = −v_1 ⇒ a_1 ← b_1, v* = 0; free: a_1 ← −b_1, v* = b_1/ρc.
    let (a_1_new, v_left) = match bar.left {
        LeftEnd::Fixed => (b_1, 0.0),
        LeftEnd::Free => (-b_1, b_1 / z),
    };
    // (36): a_i ← a_{i−1}, b_i ← b_{i+1}, one shift of each origin; the freed slots take the
    // boundary values (the a_N and b_1 that leave).
    state.shift = if state.shift + 1 == n {
        0
    } else {
        state.shift + 1
    };
    let i0 = state.index_a(0);
    state.cells[i0] = a_1_new;
    let i_n = state.index_b(n - 1);
    state.cells[i_n] = b_n_new;
    state.step += 1;
    state.u_right += dt * v_star;
    state.u_left += dt * v_left;
    StepTerms {
        contact: condition == EndCondition::Contact,
        contact_stress: sigma_star,
        end_velocity: v_star,
        wall_velocity,
        work_contact: bar.area * dt * sigma_star * v_star,
        ..StepTerms::default()
    }
}

/// Source step over [t0, t1] (velocity only): `v⁺ = ((1 − γΔt/2) v + Δt f̄/(ρS)) / (1 + γΔt/2)`
/// with f̄ the exact mean load. Returns (work_ext, work_damping), which add up to the change of
/// kinetic energy exactly (see [`WaveBar::damping`]).
fn source_step(bar: &WaveBar, state: &mut WaveState, t0: f64, t1: f64) -> (f64, f64) {
    let dt = t1 - t0;
    let z = bar.impedance();
    let rho_s = bar.density * bar.area;
    let f = bar.mean_force(t0, t1);
    let half = 0.5 * bar.damping * dt;
    let keep = (1.0 - half) / (1.0 + half);
    let push = dt * f / rho_s / (1.0 + half);
    let dx = bar.dx();
    // In characteristic values, with d = b − a = 2 z v: v⁺ = keep·v + push gives
    // a⁺ = a + (1 − keep)/2 · d − z·push and b⁺ = b − (1 − keep)/2 · d + z·push; the mean
    // velocity over the step is ((1 + keep)/(2z) · d + push)/2.
    let (shrink, lift) = (0.5 * (1.0 - keep), z * push);
    let (c_d, c_0) = (0.25 * (1.0 + keep) / z, 0.5 * push);
    // One pass over the cells, the two sums in four partial sums by cell index i mod 4 (so the
    // sums do not depend on where the storage origins split the runs: a resumed run sums alike).
    let (mut sum_v, mut sum_v2) = ([0.0; 4], [0.0; 4]);
    let cell = |a: &mut f64, b: &mut f64| {
        let d = *b - *a;
        *a += shrink * d - lift;
        *b -= shrink * d - lift;
        c_d * d + c_0
    };
    state.for_each_run(|i0, a, b| {
        let head = ((4 - i0 % 4) % 4).min(a.len());
        let (a_head, a) = a.split_at_mut(head);
        let (b_head, b) = b.split_at_mut(head);
        for (j, (x, y)) in a_head.iter_mut().zip(b_head.iter_mut()).enumerate() {
            let v = cell(x, y);
            let l = (i0 + j) % 4;
            sum_v[l] += v;
            sum_v2[l] += v * v;
        }
        let (mut ac, mut bc) = (a.chunks_exact_mut(4), b.chunks_exact_mut(4));
        for (x, y) in (&mut ac).zip(&mut bc) {
            for l in 0..4 {
                let v = cell(&mut x[l], &mut y[l]);
                sum_v[l] += v;
                sum_v2[l] += v * v;
            }
        }
        let (a_tail, b_tail) = (ac.into_remainder(), bc.into_remainder());
        for (l, (x, y)) in a_tail.iter_mut().zip(b_tail.iter_mut()).enumerate() {
            let v = cell(x, y);
            sum_v[l] += v;
            sum_v2[l] += v * v;
        }
    });
    let total = |s: [f64; 4]| (s[0] + s[2]) + (s[1] + s[3]);
    (
        dx * dt * f * total(sum_v),
        -bar.damping * rho_s * dx * dt * total(sum_v2),
    )
}

/// The paper's form of one unforced step against a fixed wall: (36) for the inner cells, (38)
/// and (39) for the boundary cells through the ghost cells (37) (left end) and (50)/(51) (contact
/// end). Used to cross-check the signed permutation; `sigma`, `v` are the cell averages.
pub fn flux_form_step(
    bar: &WaveBar,
    sigma: &[f64],
    v: &[f64],
    condition: EndCondition,
) -> (Vec<f64>, Vec<f64>) {
    let n = sigma.len();
    let z = bar.impedance();
    // Ghost cells C_0 and C_{N+1}.
    let (s0, v0) = match bar.left {
        LeftEnd::Fixed => (sigma[0], -v[0]),
        LeftEnd::Free => (-sigma[0], v[0]),
    };
    let (sn1, vn1) = match condition {
        EndCondition::Contact => (sigma[n - 1], -v[n - 1]),
        EndCondition::Free => (-sigma[n - 1], v[n - 1]),
    };
    let s_at = |i: isize| -> f64 {
        if i < 0 {
            s0
        } else if i as usize >= n {
            sn1
        } else {
            sigma[i as usize]
        }
    };
    let v_at = |i: isize| -> f64 {
        if i < 0 {
            v0
        } else if i as usize >= n {
            vn1
        } else {
            v[i as usize]
        }
    };
    let mut s_new = vec![0.0; n];
    let mut v_new = vec![0.0; n];
    for i in 0..n as isize {
        let (sl, sr, vl, vr) = (s_at(i - 1), s_at(i + 1), v_at(i - 1), v_at(i + 1));
        // (36)
        s_new[i as usize] = 0.5 * (sr + sl + z * (vr - vl));
        v_new[i as usize] = 0.5 * (vr + vl + (sr - sl) / z);
    }
    (s_new, v_new)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The state serialises in the ring's position form whatever its storage origins, reads
    /// back a ring stored with a moving origin (the form checkpoints have always held), and a
    /// run continued from the decoded state is bit-identical to the uninterrupted one.
    #[test]
    fn serialised_ring_form_round_trips() {
        let mut bar = WaveBar::unit(7, 1e-3);
        bar.initial_velocity = 1e-3;
        bar.damping = 0.3;
        let mut state = bar.initial_state();
        for _ in 0..11 {
            step(&bar, &mut state);
        }
        assert_ne!(state.shift, 0);
        let bytes = rmp_serde::to_vec_named(&state).unwrap();
        let mut back: WaveState = rmp_serde::from_slice(&bytes).unwrap();
        assert_eq!(back, state);
        assert_eq!(back.ring(), state.ring());
        for _ in 0..23 {
            let (t1, t2) = (step(&bar, &mut state), step(&bar, &mut back));
            assert_eq!(t1, t2);
        }
        assert_eq!(back.ring(), state.ring());
        // A ring stored with origin 3: position p at (p − 3) mod 2N.
        let positions = state.ring();
        let n2 = positions.len();
        let stored: Vec<f64> = (0..n2).map(|k| positions[(k + 3) % n2]).collect();
        let old = RingForm {
            ring: stored,
            shift: 3,
            step: state.step,
            u_left: state.u_left,
            u_right: state.u_right,
        };
        let decoded: WaveState =
            rmp_serde::from_slice(&rmp_serde::to_vec_named(&old).unwrap()).unwrap();
        assert_eq!(decoded, state);
        let bad = RingForm {
            ring: vec![0.0; 3],
            shift: 0,
            step: 0,
            u_left: 0.0,
            u_right: 0.0,
        };
        assert!(
            rmp_serde::from_slice::<WaveState>(&rmp_serde::to_vec_named(&bad).unwrap()).is_err()
        );
    }
}
