//! The impulse problem of a step solved on the banded iteration matrix, for contacts whose
//! columns of G are single dofs (a distributed obstacle: a string or a bar against a bridge):
//!
//! ```text
//! S x = R D G P,     w = Gᵀ x + b,     0 ≤ w ⊥ P ≥ 0,
//! ```
//!
//! with S, R symmetric banded n×n and D diagonal. Moreau–Jean is `S = Ŵ`, `R D = I`
//! ([`ImpulseMap::Direct`], Acary 2016, (21a)): x is the velocity change the impulse makes. The
//! α-family is `S` its iteration matrix, `R = (1−α_M) M + (1−α_K) h²(β − γ/2) K`, `D = M⁻¹`
//! (lumped mass) ([`ImpulseMap::Filtered`], see [`crate::integrators::alpha`]). Eliminating x
//! gives the LCP `0 ≤ W P + b ⊥ P ≥ 0` with the Delassus operator `W = Gᵀ S⁻¹ R D G`, which is
//! never formed: for a guess 𝒜 of the contacts with w = 0 (their x prescribed, x_i = −b_α/g_α)
//! and P = 0 elsewhere, the n equations `S x − R D G P = 0` are one banded system in the
//! unknowns x (free dofs) and P_𝒜 (the columns of the prescribed dofs exchanged), of the
//! bandwidth of S and R, solved by banded LU with partial pivoting in O(n · bandwidth²).
//! With `R D = I` and S positive definite (Moreau–Jean) the same system splits: the free rows
//! `S_FF x_F = −S_F𝒜 x_𝒜` are S with the rows and columns of 𝒜 replaced by the identity's
//! (positive definite, banded Cholesky, no pivoting), and the rows of 𝒜 give
//! `P_α = (S x)_dof / g_α`, one banded product.
//!
//! # The method
//!
//! Block principal pivoting (Júdice & Pires 1994, "A block principal pivoting algorithm for
//! large-scale strictly monotone linear complementarity problems", Computers & Operations
//! Research 21(5), 587–596), which is the primal–dual active-set method of Hintermüller, Ito &
//! Kunisch 2002 (SIAM J. Optim. 13(3), 865–888) for the LCP: from 𝒜, solve; the infeasible
//! contacts are those of 𝒜 with P_α < 0 and those outside with w_α < 0; exchange all of them
//! (a block pivot) while their number decreases, and after [`BLOCK_TRIES`] block pivots without
//! a decrease exchange only the infeasible contact of least index (Murty's rule, finite for a
//! P-matrix W, Murty 1974) until it does. A warm start from the last step's 𝒜 (a lasting
//! contact region changes by a few nodes per step) ends most steps in one or two iterations,
//! and an 𝒜 equal to the factorised one reuses its factor. The iteration budget is
//! [`LcpOptions::max_iterations`]; exhausting it, or a singular exchanged system, is an
//! [`LcpError`].
//!
//! # A moving contact region
//!
//! When the wave crosses many nodes per step (a string of 10⁵ nodes at h = 2·10⁻⁵ s: c h/Δx =
//! 200), the contacts predicted to close (the index set, w < 0 at P = 0) form a region hundreds
//! of nodes wider than the one that takes impulses: the first pivot activates all of it, and
//! the next ones find P < 0 only at its edges, one contact per edge per pivot, while P in its
//! interior stays positive — the region shrinks by two contacts per iteration, the count of
//! infeasible contacts stalls, and Murty's single pivots would halve even that pace. Three
//! things keep such a step cheap:
//!
//! * **The window.** The unknowns outside `[first contact − kd, last contact + kd]` are free
//!   dofs whose equations touch no contact column and no right-hand side: they are condensed
//!   once onto the window's edges (the Schur complement of S's leading block is
//!   `S₂₂ − L₂₁L₂₁ᵀ` with L the Cholesky factor of S, and likewise for its trailing block with
//!   the factor of S in reverse order, both computed once), and solved once at the end. An
//!   iteration costs O(window · kd²) instead of O(n · kd²).
//! * **Monotone pivots.** With R D = I, S a Z-matrix (off-diagonals ≤ 0, as for a mass plus
//!   a string's or a bar's stiffness) and one sign of G, W⁻¹ is an M-matrix (a Schur complement
//!   of one), for which the block pivots converge monotonically from any start
//!   (Hintermüller, Ito & Kunisch 2002, §3): the pivots go on while the count stalls (up to
//!   k of them, then Murty's rule as above).
//! * **Leaps.** In that case, while an iteration only removes contacts, each retreating edge
//!   (an exchanged contact with an inactive neighbour on one side) takes the next `reach − 1`
//!   active contacts inwards along with it, `reach` doubling at each such iteration; a leap too
//!   far shows as contacts that join again, and `reach` falls to a quarter. After [`MAX_LEAPS`]
//!   leaps too far the pivots go on without leaping. Any 𝒜 is a legitimate guess: the answer is
//!   the exact solution of the last 𝒜's system with every sign checked, the same as without
//!   leaps (W is a P-matrix: the LCP's solution is unique).
//!
//! The complementarity error is that of every solver here, `‖min(P, w)‖_∞ / max(1, ‖b‖_∞)`
//! ([`crate::lcp`]), on the contacts of the problem.

use super::{LcpError, LcpOptions};
use crate::band::SymBand;

/// Block pivots in a row without fewer infeasible contacts before Murty's single pivot.
pub const BLOCK_TRIES: usize = 3;

/// Leaps of a shrinking contact region that went too far before the block pivots go on
/// without leaping (see the [module](self) documentation).
pub const MAX_LEAPS: usize = 8;

/// How the impulse enters the velocity equation of the step.
#[derive(Debug, Clone)]
pub enum ImpulseMap {
    /// `S x = G P` (Moreau–Jean: S = Ŵ).
    Direct,
    /// `S x = R D G P` with R symmetric banded and D diagonal (the α-family).
    Filtered {
        /// R.
        r: SymBand,
        /// The diagonal of D.
        d: Vec<f64>,
    },
}

/// What one solve did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ActiveSetStats {
    /// Contacts in the problem.
    pub size: usize,
    /// Active-set iterations (banded solves).
    pub iterations: usize,
    /// Complementarity error.
    pub error: f64,
    /// Contacts with w = 0 at the solution.
    pub active: usize,
}

/// The banded impulse solver of one scheme: S, the impulse map, the warm start and the last
/// factorisation. Memory O(n · bandwidth).
#[derive(Debug, Clone)]
pub struct BandedActiveSet {
    s: SymBand,
    /// The lower diagonals of S, entry (i, i − k) at `k n + i` (the products of the reduced
    /// solve run along them).
    lower: Vec<f64>,
    map: ImpulseMap,
    /// The active dofs of the last solution (warm start).
    warm: Vec<bool>,
    /// The last factorisation, reused while the window and its active dofs stay the same.
    factor: Option<Factored>,
    /// Cholesky factors of S and of S with its dofs in reverse order: their leading blocks
    /// condense the free dofs on either side of the window ([`BandChol::corner`]).
    chol: Option<(BandChol, BandChol)>,
    /// S is a Z-matrix (off-diagonals ≤ 0) and the map is `Direct`: with one sign of G the
    /// block pivots converge monotonically (see the [module](self) documentation).
    z_matrix: bool,
    /// The rows of the current problem are on consecutive dofs in increasing order.
    in_order: bool,
    /// Active flags per dof of the current iterate, and the row of each dof (usize::MAX: none).
    act: Vec<bool>,
    row_of: Vec<usize>,
    rhs: Vec<f64>,
    /// The prescribed x of the active dofs on the window, zero elsewhere (the reduced solve).
    fixed: Vec<f64>,
    /// Per contact: w and the exchange flags of the current iterate.
    w: Vec<f64>,
    flip: Vec<bool>,
}

/// A factorised system of the active-set iterations, for one window and its active dofs.
#[derive(Debug, Clone)]
struct Factored {
    lo: usize,
    hi: usize,
    /// The active flags of the window's dofs.
    flags: Vec<bool>,
    /// How many of them are free.
    free: usize,
    system: System,
}

/// How the system of an iterate is factorised.
#[derive(Debug, Clone)]
enum System {
    /// The exchanged system (columns of the active dofs exchanged for their impulses), banded
    /// LU with partial pivoting: any map, any S.
    Exchanged(BandLu),
    /// `Direct` map and S positive definite: S on the window with the rows and columns of the
    /// active dofs replaced by the identity's (their x is prescribed), minus the Schur
    /// complements of the free dofs outside, is positive definite; its Cholesky factor gives x
    /// on the window, and `P_α = (S x)_dof / g_α` (the row of an active dof in `S x = G P`).
    Reduced(BandChol),
}

impl BandedActiveSet {
    /// A solver for `S x = (R D) G P` (n = order of S). S is symmetric positive definite for
    /// every scheme here; were it not, its Cholesky factors are missing and every system is
    /// solved on the whole range of dofs.
    pub fn new(s: SymBand, map: ImpulseMap) -> Self {
        let n = s.n();
        let kd = s.kd();
        let z_matrix = matches!(map, ImpulseMap::Direct)
            && (0..n).all(|i| (i.saturating_sub(kd)..i).all(|j| s.get(i, j) <= 0.0));
        let chol = BandChol::of(&s, false).zip(BandChol::of(&s, true));
        let mut lower = vec![0.0; n * (kd + 1)];
        for k in 0..=kd {
            for i in k..n {
                lower[k * n + i] = s.get(i, i - k);
            }
        }
        Self {
            s,
            lower,
            map,
            warm: vec![false; n],
            factor: None,
            chol,
            z_matrix,
            in_order: false,
            act: vec![false; n],
            row_of: vec![usize::MAX; n],
            rhs: vec![0.0; n],
            fixed: vec![0.0; n],
            w: Vec::new(),
            flip: Vec::new(),
        }
    }

    /// Order n.
    pub fn n(&self) -> usize {
        self.s.n()
    }

    /// Solves the problem with contacts `rows` (column α of G is `coef · e_dof`; distinct dofs)
    /// and `b`: writes P into `p` (one per row) and x into `x` (n entries).
    pub fn solve(
        &mut self,
        rows: &[(usize, f64)],
        b: &[f64],
        options: &LcpOptions,
        p: &mut [f64],
        x: &mut [f64],
    ) -> Result<ActiveSetStats, LcpError> {
        let k = rows.len();
        // One pass over the contacts: the row of each dof, the warm start as the first guess,
        // the scale of b, whether P = 0 solves it, the bounds of the window and the signs of G.
        let (mut scale, mut nonnegative, mut active) = (1.0f64, true, 0);
        let (mut first, mut last) = (usize::MAX, 0);
        let (mut positive, mut negative) = (true, true);
        let mut in_order = true;
        let dof0 = rows.first().map_or(0, |&(d, _)| d);
        for (r, (&(dof, coef), &bi)) in rows.iter().zip(&b[..k]).enumerate() {
            in_order &= dof == dof0 + r;
            self.row_of[dof] = r;
            self.act[dof] = self.warm[dof];
            active += usize::from(self.warm[dof]);
            scale = scale.max(bi.abs());
            nonnegative &= bi >= 0.0;
            first = first.min(dof);
            last = last.max(dof);
            positive &= coef > 0.0;
            negative &= coef < 0.0;
        }
        self.in_order = in_order;
        let result = if nonnegative {
            // P = 0 solves it (as for the dense solvers).
            p[..k].fill(0.0);
            x.fill(0.0);
            Ok(ActiveSetStats {
                size: k,
                ..Default::default()
            })
        } else {
            let window = self.window(first, last);
            // W⁻¹ is an M-matrix (S a Z-matrix, R D = I, one sign of G): block pivots converge
            // monotonically, in at most k of them, whether or not the count of infeasible
            // contacts falls at each (Hintermüller, Ito & Kunisch 2002, §3, the M-matrix
            // case); the count stalls while a contact region shrinks by its two edge contacts
            // per pivot, and Murty's single pivots would only halve that pace.
            let monotone = self.z_matrix && (positive || negative);
            self.iterate(rows, b, options, scale, window, monotone, active, p, x)
        };
        let solved = result.is_ok() && !nonnegative;
        for &(dof, _) in rows {
            self.row_of[dof] = usize::MAX;
            self.warm[dof] = self.act[dof] && solved;
            self.act[dof] = false;
        }
        result
    }

    /// The active dofs the next solve starts from (those of the last solution).
    pub fn warm_start(&self) -> &[bool] {
        &self.warm
    }

    /// Sets the active dofs the next solve starts from (a resumed run: those a checkpoint
    /// saved from [`BandedActiveSet::warm_start`]); `false` for another number of dofs.
    pub fn set_warm_start(&mut self, warm: &[bool]) -> bool {
        if warm.len() != self.warm.len() {
            return false;
        }
        self.warm.copy_from_slice(warm);
        true
    }

    /// Half-width of the band of the exchanged system: that of S and R.
    fn kd(&self) -> usize {
        match &self.map {
            ImpulseMap::Direct => self.s.kd(),
            ImpulseMap::Filtered { r, .. } => self.s.kd().max(r.kd()),
        }
    }

    /// The first and last dof of the window the iterations solve on: the dofs of the
    /// contacts (`first` to `last`) and [`BandedActiveSet::kd`] more on each side. The equations of the dofs
    /// outside touch no contact's column and have no right-hand side, so they are condensed
    /// onto the window's edges (the Schur complements of S's leading and trailing blocks,
    /// [`BandChol::corner`]) and solved once at the end ([`BandChol::solve_outer`]): an
    /// iteration costs O(window · bandwidth²) instead of O(n · bandwidth²).
    fn window(&self, first: usize, last: usize) -> (usize, usize) {
        let n = self.s.n();
        if self.chol.is_none() {
            return (0, n - 1);
        }
        let kd = self.kd();
        (first.saturating_sub(kd), (last + kd).min(n - 1))
    }

    /// The pivots from the warm start (`active` contacts), with the solver's scratch.
    #[allow(clippy::too_many_arguments)]
    fn iterate(
        &mut self,
        rows: &[(usize, f64)],
        b: &[f64],
        options: &LcpOptions,
        scale: f64,
        window: (usize, usize),
        monotone: bool,
        active: usize,
        p: &mut [f64],
        x: &mut [f64],
    ) -> Result<ActiveSetStats, LcpError> {
        let k = rows.len();
        // Infeasibilities below this level are round-off: exchanging them would cycle.
        let tau = 1e-3 * options.tolerance * scale;
        let patience = if monotone { k } else { BLOCK_TRIES };
        let mut w = std::mem::take(&mut self.w);
        let mut flip = std::mem::take(&mut self.flip);
        w.resize(k, 0.0);
        flip.resize(k, false);
        let result = self.pivot(
            rows,
            b,
            options,
            (scale, tau),
            window,
            (patience, monotone),
            active,
            p,
            x,
            (&mut w[..k], &mut flip[..k]),
        );
        self.w = w;
        self.flip = flip;
        result
    }

    /// The pivots of [`BandedActiveSet::iterate`] from its active flags, with its scratch.
    #[allow(clippy::too_many_arguments)]
    fn pivot(
        &mut self,
        rows: &[(usize, f64)],
        b: &[f64],
        options: &LcpOptions,
        (scale, tau): (f64, f64),
        window: (usize, usize),
        (patience, monotone): (usize, bool),
        mut active: usize,
        p: &mut [f64],
        x: &mut [f64],
        (w, flip): (&mut [f64], &mut [bool]),
    ) -> Result<ActiveSetStats, LcpError> {
        let k = rows.len();
        let (mut best, mut tries) = (usize::MAX, 0);
        let (mut reach, mut leaps) = (1, 0);
        for iteration in 1..=options.max_iterations {
            self.solve_active(rows, b, active, window, p, x)?;
            let mut infeasible = 0;
            let mut least = usize::MAX;
            for (r, &(dof, coef)) in rows.iter().enumerate() {
                w[r] = coef * x[dof] + b[r];
                let bad = if self.act[dof] {
                    p[r] < -tau
                } else {
                    w[r] < -tau
                };
                if bad {
                    infeasible += 1;
                    least = least.min(r);
                }
            }
            if infeasible == 0 {
                let error = p[..k]
                    .iter()
                    .zip(w.iter())
                    .fold(0.0f64, |e, (&pi, &wi)| e.max(pi.min(wi).abs()))
                    / scale;
                if error > options.tolerance {
                    return Err(LcpError::NotConverged {
                        solver: "banded_active_set",
                        iterations: iteration,
                        error,
                        tolerance: options.tolerance,
                    });
                }
                self.solve_outside(window, x);
                return Ok(ActiveSetStats {
                    size: k,
                    iterations: iteration,
                    error,
                    active,
                });
            }
            if infeasible < best {
                best = infeasible;
                tries = 0;
            } else {
                tries += 1;
            }
            let block = tries < patience;
            for (r, &(dof, _)) in rows.iter().enumerate() {
                flip[r] = if self.act[dof] {
                    p[r] < -tau
                } else {
                    w[r] < -tau
                } && (block || r == least);
            }
            if monotone && block && leaps < MAX_LEAPS {
                // Only edges retreat (no contact joins): the region shrinks by `reach`
                // contacts per edge, doubling while it keeps shrinking; a leap too far shows
                // as contacts that join again at the next pivot, and `reach` falls to a quarter.
                let joins = rows
                    .iter()
                    .zip(flip.iter())
                    .any(|(&(dof, _), &f)| f && !self.act[dof]);
                if joins {
                    leaps += usize::from(reach > 1);
                    reach = (reach / 4).max(1);
                } else {
                    self.leap(rows, flip, reach);
                    reach = (2 * reach).min(k);
                }
            }
            for (r, &(dof, _)) in rows.iter().enumerate() {
                if flip[r] {
                    self.act[dof] = !self.act[dof];
                    if self.act[dof] {
                        active += 1;
                    } else {
                        active -= 1;
                    }
                }
            }
        }
        let error = p[..k]
            .iter()
            .zip(w.iter())
            .fold(0.0f64, |e, (&pi, &wi)| e.max(pi.min(wi).abs()))
            / scale;
        Err(LcpError::NotConverged {
            solver: "banded_active_set",
            iterations: options.max_iterations,
            error,
            tolerance: options.tolerance,
        })
    }

    /// Extends each retreating edge of the active contacts (a flipped active contact with
    /// an inactive neighbour in `rows` on one side and an active one on the other) by the
    /// `reach − 1` next active contacts inwards.
    fn leap(&self, rows: &[(usize, f64)], flip: &mut [bool], reach: usize) {
        let k = rows.len();
        let on = |r: usize| self.act[rows[r].0];
        let edges: Vec<usize> = (0..k).filter(|&r| flip[r] && on(r)).collect();
        // Active and staying so before any extension.
        let kept: Vec<bool> = (0..k).map(|r| on(r) && !flip[r]).collect();
        for r in edges {
            let left = r > 0 && kept[r - 1];
            let right = r + 1 < k && kept[r + 1];
            if right && !left {
                for i in (r + 1..k).take(reach - 1).take_while(|&i| kept[i]) {
                    flip[i] = true;
                }
            } else if left && !right {
                for i in (0..r).rev().take(reach - 1).take_while(|&i| kept[i]) {
                    flip[i] = true;
                }
            }
        }
    }

    /// x on the window and P for the current active flags, condensed onto the window: the
    /// reduced positive definite system ([`System::Reduced`]) when the map is `Direct` and S
    /// positive definite, else the exchanged system ([`System::Exchanged`]). The factor of
    /// the last iterate is reused when the window and its active dofs are the same (a settled
    /// contact region: the warm start of the next step is the last solution).
    fn solve_active(
        &mut self,
        rows: &[(usize, f64)],
        b: &[f64],
        active: usize,
        (lo, hi): (usize, usize),
        p: &mut [f64],
        x: &mut [f64],
    ) -> Result<(), LcpError> {
        if active == 0 {
            p[..rows.len()].fill(0.0);
            x[lo..=hi].fill(0.0);
            return Ok(());
        }
        let flags = &self.act[lo..=hi];
        let reuse = matches!(&self.factor, Some(f) if (f.lo, f.hi) == (lo, hi) && f.flags == flags);
        if !reuse {
            let system = if matches!(self.map, ImpulseMap::Direct) && self.chol.is_some() {
                System::Reduced(self.factor_reduced((lo, hi))?)
            } else {
                System::Exchanged(self.factor_exchanged(rows, (lo, hi))?)
            };
            let mut flags = self.factor.take().map(|f| f.flags).unwrap_or_default();
            flags.clear();
            flags.extend_from_slice(&self.act[lo..=hi]);
            let free = flags.iter().filter(|&&a| !a).count();
            self.factor = Some(Factored {
                lo,
                hi,
                flags,
                free,
                system,
            });
        }
        let Self {
            s,
            lower,
            in_order,
            act,
            factor,
            rhs,
            fixed,
            ..
        } = self;
        let Some(factored) = factor else {
            return Ok(());
        };
        let m = hi - lo + 1;
        let rhs = &mut rhs[..m];
        match &factored.system {
            System::Reduced(_) if factored.free == 0 => {
                // Every dof is a contact's and active (a settled region without a gap: the
                // window is all dofs): x = x_A, nothing to solve, P = (S x)_A / g_A.
                let xw = &mut x[lo..=hi];
                let (n, kd) = (s.n(), s.kd());
                if *in_order {
                    // Row r on dof lo + r: vector passes.
                    for ((xi, &(_, coef)), &br) in xw.iter_mut().zip(rows).zip(b) {
                        *xi = -br / coef;
                    }
                    band_mul(lower, n, kd, lo, xw, rhs);
                    for ((pr, &(_, coef)), &y) in p.iter_mut().zip(rows).zip(rhs.iter()) {
                        *pr = y / coef;
                    }
                } else {
                    for (&(dof, coef), &br) in rows.iter().zip(b) {
                        xw[dof - lo] = -br / coef;
                    }
                    for (pr, &(dof, coef)) in p.iter_mut().zip(rows) {
                        *pr = band_row(lower, n, kd, dof, lo, xw) / coef;
                    }
                }
            }
            System::Reduced(chol) => {
                // x_A = −b_A / g_A prescribed; S'x = r with r = x_A on the active rows and
                // −(S x_A) on the free ones; then P_α = (S x)_dof / g_α.
                p[..rows.len()].fill(0.0);
                let fixed = &mut fixed[..m];
                fixed.fill(0.0);
                for (r, &(dof, coef)) in rows.iter().enumerate() {
                    if act[dof] {
                        fixed[dof - lo] = -b[r] / coef;
                    }
                }
                let (n, kd) = (s.n(), s.kd());
                band_mul(lower, n, kd, lo, fixed, rhs);
                for ((ri, &fi), &a) in rhs.iter_mut().zip(fixed.iter()).zip(&act[lo..=hi]) {
                    *ri = if a { fi } else { -*ri };
                }
                chol.solve_in_place(rhs);
                let xw = &mut x[lo..=hi];
                xw.copy_from_slice(rhs);
                for (r, &(dof, coef)) in rows.iter().enumerate() {
                    if act[dof] {
                        xw[dof - lo] = fixed[dof - lo];
                        p[r] = band_row(lower, n, kd, dof, lo, xw) / coef;
                    }
                }
            }
            System::Exchanged(lu) => {
                // Right-hand side −Σ_{j active} S_ij x_j with x_j = −b_α / g_α.
                p[..rows.len()].fill(0.0);
                let (n, kd) = (s.n(), s.kd());
                rhs.fill(0.0);
                for (r, &(dof, coef)) in rows.iter().enumerate() {
                    if act[dof] {
                        let xj = -b[r] / coef;
                        for i in dof.saturating_sub(kd)..(dof + kd + 1).min(n) {
                            rhs[i - lo] -= s.get(i, dof) * xj;
                        }
                    }
                }
                lu.solve_in_place(rhs);
                x[lo..=hi].copy_from_slice(rhs);
                for (r, &(dof, coef)) in rows.iter().enumerate() {
                    if act[dof] {
                        p[r] = x[dof];
                        x[dof] = -b[r] / coef;
                    }
                }
            }
        }
        Ok(())
    }

    /// The Schur complements of the free dofs outside the window `lo..=hi` (m dofs), as
    /// `add(i, j, −value)` on window-local indices of its leading and trailing ks × ks corners.
    fn corners(&self, (lo, hi): (usize, usize), mut add: impl FnMut(usize, usize, f64)) {
        if let Some((chol, rev)) = &self.chol {
            // The corners are entries of free dofs: the contacts are kd dofs inside.
            let (n, ks) = (self.s.n(), self.s.kd());
            let m = hi - lo + 1;
            if lo > 0 {
                for i in 0..ks.min(m) {
                    for j in 0..ks.min(m) {
                        add(i, j, -chol.corner(lo, i, j));
                    }
                }
            }
            if hi + 1 < n {
                let size = n - 1 - hi;
                for i in 0..ks.min(m) {
                    for j in 0..ks.min(m) {
                        add(m - 1 - i, m - 1 - j, -rev.corner(size, i, j));
                    }
                }
            }
        }
    }

    /// [`System::Reduced`] on the window `lo..=hi`: S with the rows and columns of the active
    /// dofs replaced by the identity's, minus the Schur complements of the free dofs outside.
    fn factor_reduced(&self, (lo, hi): (usize, usize)) -> Result<BandChol, LcpError> {
        let (m, kd) = (hi - lo + 1, self.s.kd());
        // Row i, entries i − kd … i, as BandChol stores them.
        let mut a = vec![0.0; m * (kd + 1)];
        let at = |i: usize, j: usize| i * (kd + 1) + kd + j - i;
        for i in 0..m {
            for j in i.saturating_sub(kd)..=i {
                let (di, dj) = (lo + i, lo + j);
                a[at(i, j)] = if self.act[di] || self.act[dj] {
                    if i == j { 1.0 } else { 0.0 }
                } else {
                    self.s.get(di, dj)
                };
            }
        }
        self.corners((lo, hi), |i, j, v| {
            if j <= i {
                a[at(i, j)] += v;
            }
        });
        BandChol::from_lower(m, kd, a).map_err(|row| LcpError::SingularActiveSet { dof: row + lo })
    }

    /// [`System::Exchanged`] on the window `lo..=hi`, minus the Schur complements of the free
    /// dofs outside it.
    fn factor_exchanged(
        &self,
        rows: &[(usize, f64)],
        (lo, hi): (usize, usize),
    ) -> Result<BandLu, LcpError> {
        let kd = self.kd();
        let mut a = BandLu::zeros(hi - lo + 1, kd, kd);
        for j in lo..=hi {
            let top = j.saturating_sub(kd).max(lo);
            let bottom = (j + kd).min(hi);
            if self.act[j] {
                let coef = rows[self.row_of[j]].1;
                match &self.map {
                    ImpulseMap::Direct => a.set(j - lo, j - lo, -coef),
                    ImpulseMap::Filtered { r, d } => {
                        for i in top..=bottom {
                            a.set(i - lo, j - lo, -r.get(i, j) * d[j] * coef);
                        }
                    }
                }
            } else {
                for i in top..=bottom {
                    a.set(i - lo, j - lo, self.s.get(i, j));
                }
            }
        }
        self.corners((lo, hi), |i, j, v| a.add(i, j, v));
        a.factor()
            .map_err(|col| LcpError::SingularActiveSet { dof: col + lo })?;
        Ok(a)
    }

    /// x on the free dofs outside the window `lo..=hi`, from x on it: `S_OO x_O = −S_OI x_I`.
    fn solve_outside(&self, (lo, hi): (usize, usize), x: &mut [f64]) {
        if let Some((chol, rev)) = &self.chol {
            let n = self.s.n();
            chol.solve_outer(&self.s, lo, x, |i| i);
            rev.solve_outer(&self.s, n - 1 - hi, x, |i| n - 1 - i);
        }
    }
}

/// The lower Cholesky factor L of a symmetric positive definite band matrix S (`S = L Lᵀ`),
/// or of S with its dofs in reverse order. Its leading block of order a is the factor of S's
/// leading block, so it solves the free dofs before a window (and, reversed, after one).
#[derive(Debug, Clone)]
struct BandChol {
    n: usize,
    kd: usize,
    /// Row i, entries L_ij for j = i − kd … i, at `i (kd + 1) + kd + j − i`.
    l: Vec<f64>,
    /// 1/L_ii.
    inv: Vec<f64>,
}

impl BandChol {
    /// The factor of S (`reversed`: of S_{n−1−i, n−1−j}); `None` if S is not positive definite.
    fn of(s: &SymBand, reversed: bool) -> Option<Self> {
        let (n, kd) = (s.n(), s.kd());
        let mut a = vec![0.0; n * (kd + 1)];
        for i in 0..n {
            for j in i.saturating_sub(kd)..=i {
                a[i * (kd + 1) + kd + j - i] = if reversed {
                    s.get(n - 1 - i, n - 1 - j)
                } else {
                    s.get(i, j)
                };
            }
        }
        Self::from_lower(n, kd, a).ok()
    }

    /// The factor of the symmetric matrix of order n whose lower band (row i, entries
    /// i − kd … i) is `a`, stored as the factor is (`i (kd + 1) + kd + j − i`), factorised in
    /// its place; `Err(i)` when the pivot of row i is not positive.
    fn from_lower(n: usize, kd: usize, a: Vec<f64>) -> Result<Self, usize> {
        let mut c = Self {
            n,
            kd,
            l: a,
            inv: vec![0.0; n],
        };
        for i in 0..n {
            for j in i.saturating_sub(kd)..=i {
                let mut sum = c.l[i * (kd + 1) + kd + j - i];
                for k in i.saturating_sub(kd)..j {
                    sum -= c.get(i, k) * c.get(j, k);
                }
                let v = if i == j {
                    if !(sum > 0.0 && sum.is_finite()) {
                        return Err(i);
                    }
                    let d = sum.sqrt();
                    c.inv[i] = 1.0 / d;
                    d
                } else {
                    sum * c.inv[j]
                };
                c.l[i * (kd + 1) + kd + j - i] = v;
            }
        }
        Ok(c)
    }

    /// Solves `L Lᵀ x = b` in place.
    // Band algorithms read best with the indices of the matrix they walk.
    #[allow(clippy::needless_range_loop)]
    fn solve_in_place(&self, b: &mut [f64]) {
        let (n, kd) = (self.n, self.kd);
        let b = &mut b[..n];
        let w = kd + 1;
        if kd == 1 {
            // Tridiagonal: one recurrence each way.
            let mut prev = 0.0;
            for (i, bi) in b.iter_mut().enumerate() {
                prev = (*bi - self.l[i * w] * prev) * self.inv[i];
                *bi = prev;
            }
            let mut next = 0.0;
            for i in (0..n).rev() {
                let sub = if i + 1 < n { self.l[(i + 1) * w] } else { 0.0 };
                next = (b[i] - sub * next) * self.inv[i];
                b[i] = next;
            }
            return;
        }
        for i in 0..n {
            let mut s = b[i];
            for k in i.saturating_sub(kd)..i {
                s -= self.l[i * w + kd + k - i] * b[k];
            }
            b[i] = s * self.inv[i];
        }
        for i in (0..n).rev() {
            let mut s = b[i];
            for k in i + 1..(i + kd + 1).min(n) {
                s -= self.l[k * w + kd + i - k] * b[k];
            }
            b[i] = s * self.inv[i];
        }
    }

    /// L_ij (zero outside the band; j ≤ i).
    fn get(&self, i: usize, j: usize) -> f64 {
        if j + self.kd < i {
            0.0
        } else {
            self.l[i * (self.kd + 1) + self.kd + j - i]
        }
    }

    /// Entry (a + i, a + j) (i, j < kd) of what eliminating the leading block of order a
    /// takes off the trailing one, `S_{2,1} S_{1,1}⁻¹ S_{1,2} = L_{2,1} L_{2,1}ᵀ`.
    fn corner(&self, a: usize, i: usize, j: usize) -> f64 {
        let (ri, rj) = (a + i, a + j);
        (ri.max(rj).saturating_sub(self.kd)..a)
            .map(|k| self.get(ri, k) * self.get(rj, k))
            .sum()
    }

    /// Solves the leading block of order a for the free dofs `dof(0..a)` given x on the dofs
    /// after them: `S_11 x_1 = −S_12 x_2` (the right-hand side lives on the last kd rows).
    fn solve_outer(&self, s: &SymBand, a: usize, x: &mut [f64], dof: impl Fn(usize) -> usize) {
        if a == 0 {
            return;
        }
        let kd = self.kd;
        let first = a.saturating_sub(kd);
        // Forward: L y = −S_12 x_2, zero before `first`.
        for i in first..a {
            let mut y = 0.0;
            for j in a..(i + kd + 1).min(self.n) {
                y -= s.get(dof(i), dof(j)) * x[dof(j)];
            }
            for k in i.saturating_sub(kd).max(first)..i {
                y -= self.get(i, k) * x[dof(k)];
            }
            x[dof(i)] = y * self.inv[i];
        }
        // Backward: Lᵀ x_1 = y.
        for i in (0..a).rev() {
            let mut v = if i >= first { x[dof(i)] } else { 0.0 };
            for k in i + 1..(i + kd + 1).min(a) {
                v -= self.get(k, i) * x[dof(k)];
            }
            x[dof(i)] = v * self.inv[i];
        }
    }
}

/// `y = S x` on the window of m = x.len() dofs from `lo` (S's entries inside the window only),
/// with `lower` the lower diagonals of S of order n, entry (i, i − k) at `k n + i`.
fn band_mul(lower: &[f64], n: usize, kd: usize, lo: usize, x: &[f64], y: &mut [f64]) {
    let m = x.len();
    for ((yi, a), xi) in y.iter_mut().zip(&lower[lo..lo + m]).zip(x) {
        *yi = a * xi;
    }
    for k in 1..=kd.min(m.saturating_sub(1)) {
        // S(lo + i, lo + i − k) for i = k … m − 1.
        let d = &lower[k * n + lo + k..k * n + lo + m];
        for ((yi, a), xj) in y[k..].iter_mut().zip(d).zip(&x[..m - k]) {
            *yi += a * xj;
        }
        for ((yj, a), xi) in y[..m - k].iter_mut().zip(d).zip(&x[k..]) {
            *yj += a * xi;
        }
    }
}

/// `(S x)_dof` with x given on the window from `lo` (which holds dof's band), `lower` as in
/// [`band_mul`].
#[inline]
fn band_row(lower: &[f64], n: usize, kd: usize, dof: usize, lo: usize, x: &[f64]) -> f64 {
    let mut sum = lower[dof] * x[dof - lo];
    for k in 1..=kd {
        if dof >= k {
            sum += lower[k * n + dof] * x[dof - k - lo];
        }
        if dof + k < n {
            sum += lower[k * n + dof + k] * x[dof + k - lo];
        }
    }
    sum
}

/// Whether every contact's column of G is one dof and no two share a dof (the structure
/// [`BandedActiveSet`] solves), given the columns as sparse (dof, coefficient) lists.
pub fn unit_columns<'a>(n: usize, columns: impl Iterator<Item = &'a [(usize, f64)]>) -> bool {
    let mut seen = vec![false; n];
    for g in columns {
        let mut nonzero = g.iter().filter(|&&(_, c)| c != 0.0);
        let (Some(&(dof, _)), None) = (nonzero.next(), nonzero.next()) else {
            return false;
        };
        if dof >= n || std::mem::replace(&mut seen[dof], true) {
            return false;
        }
    }
    true
}

/// A general band matrix (kl sub-, ku super-diagonals) and its LU factorisation with partial
/// pivoting, in the column-major band storage of LAPACK's `dgbtrf` (the factor's upper band
/// grows to kl + ku).
#[derive(Debug, Clone)]
struct BandLu {
    n: usize,
    kl: usize,
    ku: usize,
    /// Leading dimension 2 kl + ku + 1: entry (i, j) at `j ld + kl + ku + i − j`.
    ab: Vec<f64>,
    pivots: Vec<usize>,
    /// 1/U_jj: a solve multiplies (a division in its dependency chain would bound its speed).
    inv: Vec<f64>,
}

impl BandLu {
    fn zeros(n: usize, kl: usize, ku: usize) -> Self {
        Self {
            n,
            kl,
            ku,
            ab: vec![0.0; n * (2 * kl + ku + 1)],
            pivots: vec![0; n],
            inv: vec![0.0; n],
        }
    }

    fn idx(&self, i: usize, j: usize) -> usize {
        j * (2 * self.kl + self.ku + 1) + self.kl + self.ku + i - j
    }

    fn set(&mut self, i: usize, j: usize, a: f64) {
        let k = self.idx(i, j);
        self.ab[k] = a;
    }

    fn add(&mut self, i: usize, j: usize, a: f64) {
        let k = self.idx(i, j);
        self.ab[k] += a;
    }

    /// Factorises in place; `Err(j)` when column j has no non-zero pivot.
    fn factor(&mut self) -> Result<(), usize> {
        let (n, kl) = (self.n, self.kl);
        let ku = self.kl + self.ku;
        for j in 0..n {
            let last = (j + kl).min(n - 1);
            let mut piv = j;
            for i in j + 1..=last {
                if self.ab[self.idx(i, j)].abs() > self.ab[self.idx(piv, j)].abs() {
                    piv = i;
                }
            }
            self.pivots[j] = piv;
            let pv = self.ab[self.idx(piv, j)];
            if pv == 0.0 || !pv.is_finite() {
                return Err(j);
            }
            let right = (j + ku).min(n - 1);
            if piv != j {
                for c in j..=right {
                    let (a, b) = (self.idx(j, c), self.idx(piv, c));
                    self.ab.swap(a, b);
                }
            }
            let inv = 1.0 / pv;
            self.inv[j] = inv;
            for i in j + 1..=last {
                let k = self.idx(i, j);
                self.ab[k] *= inv;
            }
            for c in j + 1..=right {
                let u = self.ab[self.idx(j, c)];
                if u != 0.0 {
                    for i in j + 1..=last {
                        let l = self.ab[self.idx(i, j)];
                        let k = self.idx(i, c);
                        self.ab[k] -= l * u;
                    }
                }
            }
        }
        Ok(())
    }

    // Band algorithms read best with the indices of the matrix they walk.
    #[allow(clippy::needless_range_loop)]
    fn solve_in_place(&self, b: &mut [f64]) {
        let n = self.n;
        let ku = self.kl + self.ku;
        for j in 0..n {
            let piv = self.pivots[j];
            if piv != j {
                b.swap(j, piv);
            }
            let bj = b[j];
            if bj != 0.0 {
                for i in j + 1..=(j + self.kl).min(n - 1) {
                    b[i] -= self.ab[self.idx(i, j)] * bj;
                }
            }
        }
        for j in (0..n).rev() {
            b[j] *= self.inv[j];
            let bj = b[j];
            if bj != 0.0 {
                for i in j.saturating_sub(ku)..j {
                    b[i] -= self.ab[self.idx(i, j)] * bj;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[allow(clippy::needless_range_loop)]
    fn band_lu_solves_a_nonsymmetric_system_that_needs_pivoting() {
        // Zero first pivot: only a row exchange gets past it.
        let n = 6;
        let mut a = BandLu::zeros(n, 1, 2);
        let mut dense = vec![vec![0.0; n]; n];
        for i in 0..n {
            for j in i.saturating_sub(1)..(i + 3).min(n) {
                let v = if i == 0 && j == 0 {
                    0.0
                } else {
                    1.0 + ((i * 7 + j * 3) % 5) as f64 - 0.5 * (i as f64 - j as f64)
                };
                a.set(i, j, v);
                dense[i][j] = v;
            }
        }
        let x: Vec<f64> = (0..n).map(|i| (i as f64 + 0.3).cos()).collect();
        let mut b: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|j| dense[i][j] * x[j]).sum())
            .collect();
        a.factor().unwrap();
        a.solve_in_place(&mut b);
        for i in 0..n {
            assert!((b[i] - x[i]).abs() < 1e-12, "{} vs {}", b[i], x[i]);
        }
    }
}
