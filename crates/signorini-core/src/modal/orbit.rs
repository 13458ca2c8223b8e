//! Periodic orbits of the wave bar: trajectories of kernel vectors, admissibility COND1–COND3
//! (§5.1), and stability by perturbed integration (§6.5).

use crate::outcome::SpaceTime;
use crate::scenes::LeftEnd;
use crate::wfem::{EndCondition, WaveBar, WaveState, step, transport};
use nalgebra::{DMatrix, DVector};

/// Contact-end history of a ring state over a sequence of phases.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// u_{N+1/2}^{(n)}, n = 0..=T.
    pub u: Vec<f64>,
    /// a_N^{(n)} (the contact stress (52) under the fixed condition, per unit S), n = 0..T.
    pub a_end: Vec<f64>,
}

/// Runs the phases from the ring vector `x` (positions of [`WaveState`]) with a fixed left end;
/// u(L) starts from the strain integration `Σ Δx σ_i / E`. O(N + T).
pub fn trajectory(bar: &WaveBar, phases: &[(EndCondition, usize)], x: &[f64]) -> Trajectory {
    let u0 = bar.dx() / bar.young * 0.5 * x.iter().sum::<f64>();
    let mut state = WaveState::from_ring(x.to_vec(), 0.0, u0);
    let total: usize = phases.iter().map(|p| p.1).sum();
    let mut u = Vec::with_capacity(total + 1);
    let mut a_end = Vec::with_capacity(total);
    u.push(u0);
    for &(end, steps) in phases {
        for _ in 0..steps {
            a_end.push(state.a(bar.cells - 1));
            transport(bar, &mut state, end, 0.0);
            u.push(state.u_right);
        }
    }
    Trajectory { u, a_end }
}

/// An admissible periodic orbit.
#[derive(Debug, Clone, PartialEq)]
pub struct Orbit {
    /// The phases of one period, starting with a free phase.
    pub phases: Vec<(EndCondition, usize)>,
    /// Initial ring state Q^{(0)} (characteristic values).
    pub ring: Vec<f64>,
    /// dim ker S_T.
    pub kernel_dim: usize,
    /// Cell energy (conserved).
    pub energy: f64,
    /// Contact-end displacement over the period, n = 0..=T.
    pub u: Vec<f64>,
    /// Contact steps whose force (52) is zero to round-off (|r| ≤ 10⁻⁹ max|a_N|).
    pub zero_force_steps: usize,
    /// Free steps strictly inside a free phase where the end touches the wall
    /// (u = g0 to round-off): the grazing instants of §6.2.
    pub grazing_steps: usize,
}

impl Orbit {
    /// Period in steps.
    pub fn period_steps(&self) -> usize {
        self.phases.iter().map(|p| p.1).sum()
    }

    /// Steps in contact per period.
    pub fn contact_steps(&self) -> usize {
        self.phases
            .iter()
            .filter(|p| p.0 == EndCondition::Contact)
            .map(|p| p.1)
            .sum()
    }
}

/// Relative tolerance of the admissibility tests (the kernel vectors are exact ±1 patterns, so
/// only the O(T) sums of the displacement carry round-off).
pub const ADMISSIBILITY_TOLERANCE: f64 = 1e-9;

/// Looks for an admissible orbit in the span of `basis` (kernel of S_T for `phases`).
///
/// The coefficients α solve, in the least-norm sense, the closure conditions u = g0 at the start
/// of each contact phase (for g0 = 0, with the extra normalisation "mean free-phase displacement
/// = −10⁻³ L", which only fixes the arbitrary scale). The orbit is admissible when the
/// conditions hold and COND1 (u ≤ g0 in the free phases, and a grazing end leaves: a_N ≥ 0),
/// COND2 (contact force (52) r = S a_N ≤ 0 in the contact phases) and COND3 (ε > −1) hold.
/// A free step from a closed gap needs a strictly tensile (52) r > 0, as in Algorithm 2, so the
/// split of a period into free and contact steps is the one Algorithm 2 reproduces. An orbit
/// whose contact phases carry no force at all (r = 0 to round-off at every contact step: a free
/// vibration of the bar that only touches the wall, A_f^T Q⁽⁰⁾ = Q⁽⁰⁾, whose free/contact split
/// round-off decides) is not a nonsmooth mode and is rejected ([`has_wall_force`]).
pub fn admissible_orbit(
    bar: &WaveBar,
    phases: &[(EndCondition, usize)],
    basis: &[Vec<f64>],
) -> Option<Orbit> {
    if basis.is_empty() || bar.left != LeftEnd::Fixed {
        return None;
    }
    let g0 = bar.gap;
    let trajs: Vec<Trajectory> = basis.iter().map(|x| trajectory(bar, phases, x)).collect();
    // Contact-phase starts and free-phase state ranges.
    let mut n = 0;
    let mut closures = Vec::new();
    let mut free_ranges = Vec::new();
    let mut contact_ranges = Vec::new();
    for &(end, steps) in phases {
        match end {
            EndCondition::Free => free_ranges.push((n, n + steps)),
            EndCondition::Contact => {
                closures.push(n);
                contact_ranges.push((n, n + steps));
            }
        }
        n += steps;
    }
    let h = basis.len();
    let reference = 1e-3 * bar.length;
    let mut rows: Vec<Vec<f64>> = closures
        .iter()
        .map(|&nc| trajs.iter().map(|t| t.u[nc]).collect())
        .collect();
    let mut rhs: Vec<f64> = vec![g0; closures.len()];
    let free_count: usize = free_ranges.iter().map(|r| r.1 - r.0 + 1).sum();
    if g0 == 0.0 {
        rows.push(
            trajs
                .iter()
                .map(|t| {
                    free_ranges
                        .iter()
                        .flat_map(|&(a, b)| t.u[a..=b].iter())
                        .sum::<f64>()
                        / free_count as f64
                })
                .collect(),
        );
        rhs.push(-reference);
    }
    let alpha: Vec<f64> = if h == 1 && rows.len() == 1 {
        if rows[0][0].abs() < 1e-300 {
            return None;
        }
        vec![rhs[0] / rows[0][0]]
    } else {
        let c = DMatrix::from_fn(rows.len(), h, |i, j| rows[i][j]);
        let svd = c.svd(true, true);
        let sol = svd.solve(&DVector::from_vec(rhs.clone()), 1e-12).ok()?;
        sol.iter().copied().collect()
    };
    let combine = |f: &dyn Fn(&Trajectory) -> &Vec<f64>, i: usize| -> f64 {
        trajs.iter().zip(&alpha).map(|(t, a)| a * f(t)[i]).sum()
    };
    let total = n;
    let u: Vec<f64> = (0..=total).map(|i| combine(&|t| &t.u, i)).collect();
    let a_end: Vec<f64> = (0..total).map(|i| combine(&|t| &t.a_end, i)).collect();
    let u_scale = g0.abs().max(u.iter().fold(0.0f64, |m, x| m.max(x.abs())));
    let a_scale = a_end.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if u_scale == 0.0 || a_scale == 0.0 {
        return None;
    }
    let tol_u = ADMISSIBILITY_TOLERANCE * u_scale;
    let tol_a = ADMISSIBILITY_TOLERANCE * a_scale;
    // Closure equations.
    if closures.iter().any(|&nc| (u[nc] - g0).abs() > tol_u) {
        return None;
    }
    // COND1: free phases stay on the open side, a grazing end leaves, and the gap really opens.
    let mut opens = false;
    for &(a, b) in &free_ranges {
        for i in a..=b {
            if u[i] > g0 + tol_u {
                return None;
            }
            // Algorithm 2 takes a free step from a closed gap only under tension (52): r > 0.
            if i < b && u[i] >= g0 - tol_u && a_end[i] <= tol_a {
                return None;
            }
            opens |= u[i] < g0 - tol_u;
        }
    }
    if !opens {
        return None;
    }
    // COND2: compressive contact force during the contact phases (u = g0 holds there since the
    // end does not move under the fixed condition).
    for &(a, b) in &contact_ranges {
        if a_end[a..b].iter().any(|&r| r > tol_a) {
            return None;
        }
    }
    let contact_forces = || contact_ranges.iter().flat_map(|&(a, b)| a_end[a..b].iter());
    if !has_wall_force(contact_forces(), tol_a) {
        return None;
    }
    let zero_force_steps = contact_forces().filter(|r| r.abs() <= tol_a).count();
    let grazing_steps = free_ranges
        .iter()
        .map(|&(a, b)| grazing(&u[a..=b], g0, tol_u))
        .sum();
    let mut ring = vec![0.0; basis[0].len()];
    for (x, a) in basis.iter().zip(&alpha) {
        for (r, xi) in ring.iter_mut().zip(x) {
            *r += a * xi;
        }
    }
    // COND3: |σ| ≤ max |ring| at every step (values are only permuted), so ε ≥ −max|x|/E.
    let max_abs = ring.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if max_abs >= bar.young {
        return None;
    }
    let energy = bar.area * bar.dx() / (4.0 * bar.density * bar.wave_speed().powi(2))
        * ring.iter().map(|x| x * x).sum::<f64>();
    Some(Orbit {
        phases: phases.to_vec(),
        ring,
        kernel_dim: h,
        energy,
        u,
        zero_force_steps,
        grazing_steps,
    })
}

/// Some contact step carries a strictly compressive force (52), r < −`tol` (a nonsmooth mode,
/// not a free vibration that touches the wall).
pub fn has_wall_force<'a>(contact_forces: impl IntoIterator<Item = &'a f64>, tol: f64) -> bool {
    contact_forces.into_iter().any(|&r| r < -tol)
}

/// Grazing instants of one free phase `u[0..=m]` (u(0) and u(m) are the opening and the
/// closure): the steps strictly inside with u ≥ g0 − `tol`.
pub fn grazing(free_u: &[f64], g0: f64, tol: f64) -> usize {
    let inner = free_u.len().saturating_sub(1);
    free_u
        .iter()
        .take(inner)
        .skip(1)
        .filter(|&&u| u >= g0 - tol)
        .count()
}

/// Result of a stability run (§6.5).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stability {
    /// Periods integrated.
    pub periods: usize,
    /// Relative size of the initial perturbation.
    pub perturbation: f64,
    /// Orbital distance over the last period: min over phase shifts s of
    /// max_n |u_pert(n) − u_orbit(n + s)| / max_n |u_orbit(n)|.
    pub relative_deviation: f64,
    /// Same measure for the unperturbed run against the orbit's own first period (drift of the
    /// orbit itself under Algorithm 2).
    pub orbit_drift: f64,
}

/// Integrates the orbit and a copy whose stresses are perturbed by `perturbation · max|σ| ·
/// sin(π x/L)` with Algorithm 2 for `periods` periods, and compares the contact-end
/// displacements over the last period.
pub fn stability(bar: &WaveBar, orbit: &Orbit, periods: usize, perturbation: f64) -> Stability {
    let n = bar.cells;
    let z = bar.impedance();
    let t_steps = orbit.period_steps();
    let start = WaveState::from_ring(orbit.ring.clone(), 0.0, orbit.u[0]);
    let (sigma, v) = start.cells_sigma_v(z);
    let smax = sigma
        .iter()
        .fold(0.0f64, |m, x| m.max(x.abs()))
        .max(z * v.iter().fold(0.0f64, |m, x| m.max(x.abs())));
    let dx = bar.dx();
    let sigma_p: Vec<f64> = sigma
        .iter()
        .enumerate()
        .map(|(i, s)| {
            s + perturbation
                * smax
                * (std::f64::consts::PI * (i as f64 + 0.5) * dx / bar.length).sin()
        })
        .collect();
    let mut perturbed = WaveState::from_cells(&sigma_p, &v, z, 0.0, 0.0);
    perturbed.u_right = perturbed.u_right_from_strains(bar);
    let mut reference = start.clone();
    let total = periods * t_steps;
    let mut drift: f64 = 0.0;
    let mut last = Vec::with_capacity(t_steps);
    let scale = orbit.u.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for k in 0..total {
        step(bar, &mut reference);
        step(bar, &mut perturbed);
        if k + t_steps >= total {
            let phase = (k + 1) % t_steps;
            last.push(perturbed.u_right);
            drift = drift.max((reference.u_right - orbit.u[phase]).abs());
        }
    }
    // Orbital distance: the perturbed end displacement over the last period against the orbit's,
    // at the best phase shift (a perturbed orbit of another energy has another period, so a
    // pointwise comparison at equal times measures the phase drift, not the distance to the orbit).
    let first_phase = (total - t_steps + 1) % t_steps;
    let dev = (0..t_steps)
        .map(|shift| {
            last.iter()
                .enumerate()
                .map(|(i, u)| (u - orbit.u[(first_phase + i + shift) % t_steps]).abs())
                .fold(0.0f64, f64::max)
        })
        .fold(f64::INFINITY, f64::min);
    let _ = n;
    Stability {
        periods,
        perturbation,
        relative_deviation: dev / scale,
        orbit_drift: drift / scale,
    }
}

/// Displacement u(x, t) of an orbit over one period (Figs. 9, 13), sampled on at most 80 points
/// in x (interfaces) by 120 in t (steps), by running the orbit's phases from its ring state.
pub fn space_time(name: &str, bar: &WaveBar, orbit: &Orbit) -> SpaceTime {
    let n = bar.cells;
    let t_steps = orbit.period_steps();
    let mut state = WaveState::from_ring(orbit.ring.clone(), 0.0, orbit.u[0]);
    let nx = n.min(80);
    let nt = t_steps.min(120);
    let mut field: Vec<Vec<f64>> = Vec::with_capacity(nt);
    let mut step = 0;
    for &(end, steps) in &orbit.phases {
        for _ in 0..steps {
            if step * nt / t_steps.max(1) >= field.len() {
                let u = state.interface_displacements(bar);
                field.push((0..nx).map(|j| u[(j * n) / nx + 1]).collect());
            }
            transport(bar, &mut state, end, 0.0);
            step += 1;
        }
    }
    SpaceTime {
        name: name.to_string(),
        length: bar.length,
        period: t_steps as f64 * bar.dt(),
        free_steps: orbit.phases[0].1,
        contact_steps: orbit.contact_steps(),
        field,
    }
}
