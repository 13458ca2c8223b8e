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
//! P-matrix W, Murty 1974) until it does. Each iteration is one banded factorisation and solve;
//! a warm start from the last step's 𝒜 (a lasting contact region changes by a few nodes per
//! step) ends most steps in one or two, and an 𝒜 equal to the factorised one reuses its
//! factor. The iteration budget is [`LcpOptions::max_iterations`]; exhausting it, or a singular
//! exchanged system, is an [`LcpError`].
//!
//! The complementarity error is that of every solver here, `‖min(P, w)‖_∞ / max(1, ‖b‖_∞)`
//! ([`crate::lcp`]), on the contacts of the problem.

use super::{LcpError, LcpOptions};
use crate::band::SymBand;

/// Block pivots in a row without fewer infeasible contacts before Murty's single pivot.
pub const BLOCK_TRIES: usize = 3;

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
    map: ImpulseMap,
    /// The active dofs of the last solution (warm start).
    warm: Vec<bool>,
    /// The active dofs of `lu`, and the factor.
    lu: Option<(Vec<bool>, BandLu)>,
    /// Active flags per dof of the current iterate, and the row of each dof (usize::MAX: none).
    act: Vec<bool>,
    row_of: Vec<usize>,
    rhs: Vec<f64>,
}

impl BandedActiveSet {
    /// A solver for `S x = (R D) G P` (n = order of S).
    pub fn new(s: SymBand, map: ImpulseMap) -> Self {
        let n = s.n();
        Self {
            s,
            map,
            warm: vec![false; n],
            lu: None,
            act: vec![false; n],
            row_of: vec![usize::MAX; n],
            rhs: vec![0.0; n],
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
        p[..k].fill(0.0);
        x.fill(0.0);
        for (r, &(dof, _)) in rows.iter().enumerate() {
            self.row_of[dof] = r;
            self.act[dof] = false;
        }
        let scale = b.iter().fold(1.0f64, |s, a| s.max(a.abs()));
        let result = if b.iter().all(|&bi| bi >= 0.0) {
            // P = 0 solves it (as for the dense solvers).
            Ok(ActiveSetStats {
                size: k,
                ..Default::default()
            })
        } else {
            self.iterate(rows, b, options, scale, p, x)
        };
        for &(dof, _) in rows {
            self.row_of[dof] = usize::MAX;
            self.warm[dof] = self.act[dof] && result.is_ok();
            self.act[dof] = false;
        }
        result
    }

    fn iterate(
        &mut self,
        rows: &[(usize, f64)],
        b: &[f64],
        options: &LcpOptions,
        scale: f64,
        p: &mut [f64],
        x: &mut [f64],
    ) -> Result<ActiveSetStats, LcpError> {
        let k = rows.len();
        // Infeasibilities below this level are round-off: exchanging them would cycle.
        let tau = 1e-3 * options.tolerance * scale;
        let mut active = 0;
        for &(dof, _) in rows {
            self.act[dof] = self.warm[dof];
            active += usize::from(self.warm[dof]);
        }
        let (mut best, mut tries) = (usize::MAX, 0);
        let mut w = vec![0.0; k];
        for iteration in 1..=options.max_iterations {
            self.solve_active(rows, b, active, p, x)?;
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
                    .zip(&w)
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
            let block = tries < BLOCK_TRIES;
            for (r, &(dof, _)) in rows.iter().enumerate() {
                let bad = if self.act[dof] {
                    p[r] < -tau
                } else {
                    w[r] < -tau
                };
                if bad && (block || r == least) {
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
            .zip(&w)
            .fold(0.0f64, |e, (&pi, &wi)| e.max(pi.min(wi).abs()))
            / scale;
        Err(LcpError::NotConverged {
            solver: "banded_active_set",
            iterations: options.max_iterations,
            error,
            tolerance: options.tolerance,
        })
    }

    /// x and P for the current active flags: the banded system with the columns of the active
    /// dofs exchanged for their impulses.
    fn solve_active(
        &mut self,
        rows: &[(usize, f64)],
        b: &[f64],
        active: usize,
        p: &mut [f64],
        x: &mut [f64],
    ) -> Result<(), LcpError> {
        let n = self.s.n();
        p[..rows.len()].fill(0.0);
        if active == 0 {
            x.fill(0.0);
            return Ok(());
        }
        let reuse = matches!(&self.lu, Some((flags, _)) if *flags == self.act);
        if !reuse {
            let lu = self.factor_active(rows)?;
            self.lu = Some((self.act.clone(), lu));
        }
        // Right-hand side −Σ_{j active} S_ij x_j with x_j = −b_α / g_α.
        let kd = self.s.kd();
        self.rhs.fill(0.0);
        for (r, &(dof, coef)) in rows.iter().enumerate() {
            if self.act[dof] {
                let xj = -b[r] / coef;
                for i in dof.saturating_sub(kd)..(dof + kd + 1).min(n) {
                    self.rhs[i] -= self.s.get(i, dof) * xj;
                }
            }
        }
        if let Some((_, lu)) = &self.lu {
            lu.solve_in_place(&mut self.rhs);
        }
        x.copy_from_slice(&self.rhs);
        for (r, &(dof, coef)) in rows.iter().enumerate() {
            if self.act[dof] {
                p[r] = x[dof];
                x[dof] = -b[r] / coef;
            }
        }
        Ok(())
    }

    fn factor_active(&self, rows: &[(usize, f64)]) -> Result<BandLu, LcpError> {
        let n = self.s.n();
        let kd = match &self.map {
            ImpulseMap::Direct => self.s.kd(),
            ImpulseMap::Filtered { r, .. } => self.s.kd().max(r.kd()),
        };
        let mut a = BandLu::zeros(n, kd, kd);
        for j in 0..n {
            let lo = j.saturating_sub(kd);
            let hi = (j + kd + 1).min(n);
            if self.act[j] {
                let coef = rows[self.row_of[j]].1;
                match &self.map {
                    ImpulseMap::Direct => a.set(j, j, -coef),
                    ImpulseMap::Filtered { r, d } => {
                        for i in lo..hi {
                            a.set(i, j, -r.get(i, j) * d[j] * coef);
                        }
                    }
                }
            } else {
                for i in lo..hi {
                    a.set(i, j, self.s.get(i, j));
                }
            }
        }
        a.factor()
            .map_err(|dof| LcpError::SingularActiveSet { dof })?;
        Ok(a)
    }
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
}

impl BandLu {
    fn zeros(n: usize, kl: usize, ku: usize) -> Self {
        Self {
            n,
            kl,
            ku,
            ab: vec![0.0; n * (2 * kl + ku + 1)],
            pivots: vec![0; n],
        }
    }

    fn idx(&self, i: usize, j: usize) -> usize {
        j * (2 * self.kl + self.ku + 1) + self.kl + self.ku + i - j
    }

    fn set(&mut self, i: usize, j: usize, a: f64) {
        let k = self.idx(i, j);
        self.ab[k] = a;
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
            b[j] /= self.ab[self.idx(j, j)];
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
