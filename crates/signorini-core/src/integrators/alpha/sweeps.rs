//! The per-dof sweeps of an α-family step: the predictor and the right-hand side of (53)
//! ([`predict_sweep`], [`predict_general`]) and the sums of Lemma 2 ([`finish_sweep`]), each
//! compiled once per combination of the terms it has (marker types of [`MassKind`],
//! [`FilterKind`], [`PartKind`]) so that a term that is zero costs nothing.

use super::lanes::{F2, F4, Fx, Lane};
use crate::band::SymBand;

/// The α_M M a_k term of a row of (53): none (α_M = 0), m∘a_k with the diagonal m of a lumped
/// mass (the product `SymBand::mul_into` forms), or the stored M a_k of a consistent mass.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum MassTerm {
    /// α_M = 0: no term.
    None,
    /// m∘a_k, m the diagonal of a lumped mass.
    Lumped,
    /// The stored product M a_k of a consistent mass.
    Product,
}

/// A [`MassTerm`] as a type, so that [`predict_sweep`] and [`predict_general`] are compiled
/// once per term.
pub(super) trait MassKind {
    /// The term.
    const TERM: MassTerm;
}

/// [`MassTerm::None`].
pub(super) struct NoMass;
/// [`MassTerm::Lumped`].
pub(super) struct LumpedMass;
/// [`MassTerm::Product`].
pub(super) struct MassProduct;

impl MassKind for NoMass {
    const TERM: MassTerm = MassTerm::None;
}
impl MassKind for LumpedMass {
    const TERM: MassTerm = MassTerm::Lumped;
}
impl MassKind for MassProduct {
    const TERM: MassTerm = MassTerm::Product;
}

/// A predictor pass ([`predict_sweep`] or [`predict_general`] with its arguments), run by
/// [`with_terms`] in the version compiled for its terms.
pub(super) trait PredictPass {
    /// Runs the pass with the mass term `M` and, when `DAMPED`, the α_C C v_k term.
    fn run<M: MassKind, const DAMPED: bool>(self);
}

/// Runs `pass` in its version for the runtime mass term and damping flag.
pub(super) fn with_terms(mass: MassTerm, damped: bool, pass: impl PredictPass) {
    match (mass, damped) {
        (MassTerm::None, false) => pass.run::<NoMass, false>(),
        (MassTerm::None, true) => pass.run::<NoMass, true>(),
        (MassTerm::Lumped, false) => pass.run::<LumpedMass, false>(),
        (MassTerm::Lumped, true) => pass.run::<LumpedMass, true>(),
        (MassTerm::Product, false) => pass.run::<MassProduct, false>(),
        (MassTerm::Product, true) => pass.run::<MassProduct, true>(),
    }
}

/// The tridiagonal predictor pass: [`predict_sweep`].
pub(super) struct Tridiagonal<'a> {
    pub sweep: PredictSweep<'a>,
    pub m: &'a [f64],
    pub c: [f64; 2],
    pub rows: RowCoefficients,
}

impl PredictPass for Tridiagonal<'_> {
    fn run<M: MassKind, const DAMPED: bool>(self) {
        predict_sweep::<M, DAMPED>(self.sweep, self.m, self.c, self.rows);
    }
}

/// The predictor pass of any banded K: [`predict_general`].
pub(super) struct General<'a> {
    pub sweep: PredictSweep<'a>,
    pub m: &'a [f64],
    pub c: [f64; 2],
    pub rows: RowCoefficients,
    pub stiffness: &'a SymBand,
    pub tmp: &'a mut [f64],
}

impl PredictPass for General<'_> {
    fn run<M: MassKind, const DAMPED: bool>(self) {
        predict_general::<M, DAMPED>(
            self.sweep,
            self.m,
            self.c,
            self.rows,
            self.stiffness,
            self.tmp,
        );
    }
}
/// The coefficients of a predictor row ([`predict_row`]): h(1 − γ), α_M, α_C, (α_K, 1 − α_K).
#[derive(Debug, Clone, Copy)]
pub(super) struct RowCoefficients {
    pub(super) cv: f64,
    pub(super) mass: f64,
    pub(super) damping: f64,
    pub(super) stiffness: [f64; 2],
}

/// One row (or two, [`F2`]) of the predictor (25g) without a_{k+1} and of the right-hand side of
/// (53) from `x` = (v_k, a_k, (1−α_L) F_{k+1} + α_L F_k, M_ii or (M a)_k, (C v)_k, (K q)_k,
/// K q̂): returns (v̂, b) with `b = F − α_M M a_k − α_C C v_k − α_K K q_k − (1−α_K) K q̂` (the
/// C v̂ term is subtracted by the caller). Terms that are zero (`M` = [`NoMass`], `DAMPED`
/// false) are left out: subtracting a zero changes no value.
#[inline(always)]
pub(super) fn predict_row<M: MassKind, const DAMPED: bool, T: Lane>(
    r: RowCoefficients,
    x: [T; 7],
) -> (T, T)
where
    f64: std::ops::Mul<T, Output = T>,
{
    let [v, a, f, m, cv, kq, kqh] = x;
    let v_hat = v + r.cv * a;
    let mut b = f;
    match M::TERM {
        MassTerm::None => {}
        MassTerm::Lumped => b = b - r.mass * (m * a),
        MassTerm::Product => b = b - r.mass * m,
    }
    if DAMPED {
        b = b - r.damping * cv;
    }
    (v_hat, b - r.stiffness[0] * kq - r.stiffness[1] * kqh)
}

/// The vectors of [`predict_sweep`] and [`predict_general`], all of length n: the state and
/// history at t_k, the load part of (53), the diagonals of a tridiagonal K (`k1[i]` =
/// K[i][i−1]; not read by [`predict_general`]) and the outputs q̂, v̂, b.
pub(super) struct PredictSweep<'a> {
    pub(super) q: &'a [f64],
    pub(super) v: &'a [f64],
    pub(super) a: &'a [f64],
    pub(super) f_rhs: &'a [f64],
    pub(super) cv: &'a [f64],
    pub(super) kq: &'a [f64],
    pub(super) k0: &'a [f64],
    pub(super) k1: &'a [f64],
    pub(super) q_hat: &'a mut [f64],
    pub(super) v_hat: &'a mut [f64],
    pub(super) b: &'a mut [f64],
}

/// The predictors (25f), (25g) without a_{k+1} and the right-hand side of (53) for a tridiagonal
/// K (n ≥ 2) in one sweep, `c` = (h, h²(½ − β)), `m` the diagonal of M or M a_k as `M` says
/// (not read for [`NoMass`]). The rows 1 … n − 2 go in pairs (i, i + 1) on two lanes ([`F2`]):
/// q̂ of a pair is formed once and kept for the next pair, which reads its upper value as
/// q̂_{i−1}, and the pair after gives q̂_{i+2}; K q̂ is formed row by row with the arithmetic of
/// [`SymBand::mul_into`] and b with that of [`predict_row`], so every value is the one a
/// stored q̂ and a separate product give.
pub(super) fn predict_sweep<M: MassKind, const DAMPED: bool>(
    p: PredictSweep<'_>,
    m: &[f64],
    c: [f64; 2],
    r: RowCoefficients,
) {
    let n = p.q.len();
    let [h, cq] = c;
    let (q, v, a, m) = (&p.q[..n], &p.v[..n], &p.a[..n], &m[..n]);
    let (f, cv, kq) = (&p.f_rhs[..n], &p.cv[..n], &p.kq[..n]);
    let (k0, k1) = (&p.k0[..n], &p.k1[..n]);
    let (q_hat, v_hat, b) = (&mut p.q_hat[..n], &mut p.v_hat[..n], &mut p.b[..n]);
    let qh = [0, 1, n - 2, n - 1].map(|j| q[j] + h * v[j] + cq * a[j]);
    let row = |i: usize, kqh: f64| {
        predict_row::<M, DAMPED, f64>(r, [v[i], a[i], f[i], m[i], cv[i], kq[i], kqh])
    };
    // Rows 0 and n − 1: two terms of K q̂.
    for (i, kqh, qi) in [
        (0, k0[0] * qh[0] + k1[1] * qh[1], qh[0]),
        (n - 1, k1[n - 1] * qh[2] + k0[n - 1] * qh[3], qh[3]),
    ] {
        q_hat[i] = qi;
        (v_hat[i], b[i]) = row(i, kqh);
    }
    let pairs = (n - 2) / 2;
    // The pairs (1, 2), (3, 4), …: every chunk slice has `pairs` elements (K[i+1][i] from
    // `k1[2..]`), so the loop indexes without bounds checks.
    fn two(x: &[f64], from: usize, pairs: usize) -> &[[f64; 2]] {
        &x[from..].as_chunks::<2>().0[..pairs]
    }
    let (qc, vc, ac, mc) = (
        two(q, 1, pairs),
        two(v, 1, pairs),
        two(a, 1, pairs),
        two(m, 1, pairs),
    );
    let (fc, cvc, kqc) = (two(f, 1, pairs), two(cv, 1, pairs), two(kq, 1, pairs));
    let (k0c, klc, kuc) = (two(k0, 1, pairs), two(k1, 1, pairs), two(k1, 2, pairs));
    let (qhc, vhc, bc) = (
        &mut q_hat[1..].as_chunks_mut::<2>().0[..pairs],
        &mut v_hat[1..].as_chunks_mut::<2>().0[..pairs],
        &mut b[1..].as_chunks_mut::<2>().0[..pairs],
    );
    let pair_at = |c: usize| Fx(qc[c]) + h * Fx(vc[c]) + cq * Fx(ac[c]);
    // q̂ below the pair, of the pair, and above it (the first row of the next pair, or for
    // the last pair q̂_{n−1} (n even) or q̂_{n−2} (n odd)).
    let mut below = qh[0];
    let mut cur = if pairs > 0 { pair_at(0) } else { Fx::default() };
    let last_above = if n.is_multiple_of(2) { qh[3] } else { qh[2] };
    for c in 0..pairs {
        let (next, above) = if c + 1 < pairs {
            let x = pair_at(c + 1);
            (x, x.0[0])
        } else {
            (Fx::default(), last_above)
        };
        let [lo, hi] = cur.0;
        let kqh = Fx(klc[c]) * Fx([below, lo]) + Fx(k0c[c]) * cur + Fx(kuc[c]) * Fx([hi, above]);
        let x = [
            Fx(vc[c]),
            Fx(ac[c]),
            Fx(fc[c]),
            Fx(mc[c]),
            Fx(cvc[c]),
            Fx(kqc[c]),
            kqh,
        ];
        let (vh, bb) = predict_row::<M, DAMPED, F2>(r, x);
        (qhc[c], vhc[c], bc[c]) = (cur.0, vh.0, bb.0);
        below = hi;
        cur = next;
    }
    if !n.is_multiple_of(2) && n >= 3 {
        // Row n − 2 of an odd n, after the pairs.
        let i = n - 2;
        let kqh = k1[i] * below + k0[i] * qh[2] + k1[i + 1] * qh[3];
        q_hat[i] = qh[2];
        (v_hat[i], b[i]) = row(i, kqh);
    }
}

/// The predictors and the right-hand side of (53) for any banded K (what [`predict_sweep`]
/// does for a tridiagonal one): q̂ stored, K q̂ formed by [`SymBand::mul_into`] into `tmp`.
pub(super) fn predict_general<M: MassKind, const DAMPED: bool>(
    p: PredictSweep<'_>,
    m: &[f64],
    c: [f64; 2],
    r: RowCoefficients,
    stiffness: &SymBand,
    tmp: &mut [f64],
) {
    let n = p.q.len();
    let [h, cq] = c;
    for ((qh, q), (v, a)) in p.q_hat[..n]
        .iter_mut()
        .zip(&p.q[..n])
        .zip(p.v[..n].iter().zip(&p.a[..n]))
    {
        *qh = q + h * v + cq * a;
    }
    stiffness.mul_into(p.q_hat, tmp);
    let (v, a, m, f) = (&p.v[..n], &p.a[..n], &m[..n], &p.f_rhs[..n]);
    let (cv, kq, kqh) = (&p.cv[..n], &p.kq[..n], &tmp[..n]);
    for (i, (vh, b)) in p.v_hat[..n].iter_mut().zip(&mut p.b[..n]).enumerate() {
        (*vh, *b) =
            predict_row::<M, DAMPED, f64>(r, [v[i], a[i], f[i], m[i], cv[i], kq[i], kqh[i]]);
    }
}

/// The vectors [`finish_sweep`] reads (t_{k+1}: `…1`, t_k: `…0`) and writes, all of length n.
pub(super) struct Sweep<'a> {
    pub(super) q1: &'a [f64],
    pub(super) q0: &'a [f64],
    pub(super) v1: &'a [f64],
    pub(super) v0: &'a [f64],
    pub(super) a1: &'a [f64],
    pub(super) a0: &'a [f64],
    pub(super) kq1: &'a [f64],
    pub(super) kq0: &'a [f64],
    pub(super) ma1: &'a [f64],
    pub(super) ma0: &'a [f64],
    /// γ F_{k+1} + (1 − γ) F_k.
    pub(super) fw: &'a [f64],
    pub(super) z0: &'a [f64],
    pub(super) kz0: &'a [f64],
    /// Diagonal of M (read for a lumped mass only, where `ma1`, `ma0` are not).
    pub(super) mass: &'a [f64],
    pub(super) z1: &'a mut [f64],
    pub(super) kz1: &'a mut [f64],
    /// v_{k+1} − v_k and v_{k+1} + v_k (written for a consistent mass only).
    pub(super) dv: &'a mut [f64],
    pub(super) sv: &'a mut [f64],
    /// c_n = ν/(½ + ν), c_m = (½ − ν)/(½ + ν).
    pub(super) filter: [f64; 2],
}

pub(super) const S_WORK_EXT: usize = 0;
pub(super) const S_DQ_K_DQ: usize = 1;
pub(super) const S_D_STRAIN: usize = 2;
pub(super) const S_DA_M_DA: usize = 3;
pub(super) const S_D_ATERM: usize = 4;
pub(super) const S_STRAIN: usize = 5;
pub(super) const S_ATERM: usize = 6;
pub(super) const S_D_KIN: usize = 7;
pub(super) const S_KIN: usize = 8;
pub(super) const S_DZ_K_DZ: usize = 9;
pub(super) const S_D_ZTERM: usize = 10;
pub(super) const S_ZTERM: usize = 11;
pub(super) const SUMS: usize = 12;

/// Which sums a pass of [`finish_sweep`] forms: those of q (with the z filter), or of a and v.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Part {
    /// The sums of q and the z filter.
    Q,
    /// The sums of a and v.
    Av,
}

/// A [`Part`] as a type (a parameter of [`finish_sweep`]).
pub(super) trait PartKind {
    /// The part.
    const PART: Part;
}

/// [`Part::Q`].
pub(super) struct QPart;
/// [`Part::Av`].
pub(super) struct AvPart;

impl PartKind for QPart {
    const PART: Part = Part::Q;
}
impl PartKind for AvPart {
    const PART: Part = Part::Av;
}

/// The z filter of a [`finish_sweep`]: none (ν = 0 or η = 0), z_{k+1} = c_n Δq (c_m = 0, α_m = 0),
/// or z_{k+1} = c_n Δq − c_m z_k.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Filter {
    /// No z filter.
    None,
    /// z_{k+1} = c_n Δq.
    Memoryless,
    /// z_{k+1} = c_n Δq − c_m z_k.
    WithMemory,
}

/// A [`Filter`] as a type (a parameter of [`finish_sweep`]).
pub(super) trait FilterKind {
    /// The filter.
    const FILTER: Filter;
}

/// [`Filter::None`].
pub(super) struct NoFilter;
/// [`Filter::Memoryless`].
pub(super) struct MemorylessFilter;
/// [`Filter::WithMemory`].
pub(super) struct FilterWithMemory;

impl FilterKind for NoFilter {
    const FILTER: Filter = Filter::None;
}
impl FilterKind for MemorylessFilter {
    const FILTER: Filter = Filter::Memoryless;
}
impl FilterKind for FilterWithMemory {
    const FILTER: Filter = Filter::WithMemory;
}

/// Whether the filter `F` forms z (any but [`Filter::None`]).
#[inline(always)]
pub(super) const fn filtered<F: FilterKind>() -> bool {
    !matches!(F::FILTER, Filter::None)
}

/// Whether `P` is the pass of q.
#[inline(always)]
pub(super) const fn q_part<P: PartKind>() -> bool {
    matches!(P::PART, Part::Q)
}

/// One pass over the dofs for part of the sums of a step (Lemma 2). [`QPart`]: the z filter (48),
/// `Δqᵀ F_{k,γ}`, `‖Δq‖²_K`, `(q_{k+1} + q_k)ᵀ K Δq`, `qᵀKq` (at t_{k+1}) and, with the
/// filters, `‖Δz‖²_K`, `(z_{k+1} + z_k)ᵀ K Δz` and `zᵀKz`. [`AvPart`]: `‖Δa‖²_M`,
/// `(a_{k+1} + a_k)ᵀ M Δa`, `aᵀMa` and, with a lumped mass, `(v_{k+1} + v_k)ᵀ M Δv` and `vᵀMv`
/// (with a consistent mass Δv and v_{k+1} + v_k for `SymBand::quad`). The two parts read
/// disjoint vectors, so splitting them costs no memory traffic, and each keeps its sums in
/// registers (all twelve in one loop did not fit the sixteen vector registers and were kept
/// in memory). The sums of H run in four interleaved partial sums (by dof index mod 4, the
/// order of `dot` and `SymBand::quad`, so H agrees bit for bit with
/// [`AlphaCore::algorithmic_energy`]), the others in two: round-off differences only from the
/// sequential sums. Returns the part's sums (the others zero).
pub(super) fn finish_sweep<F: FilterKind, const LUMPED: bool, P: PartKind>(
    w: &mut Sweep<'_>,
) -> [f64; SUMS] {
    let n = w.q1.len();
    let m = n / 4;
    let k = SweepCoefficients { filter: w.filter };
    // The dofs 0..4m as chunks of four (one lane per dof index mod 4): every chunk slice has
    // the same length m, so the loop below indexes without bounds checks and vectorises.
    fn quads(x: &[f64], m: usize) -> &[[f64; 4]] {
        &x.as_chunks::<4>().0[..m]
    }
    let ins = [
        quads(w.q1, m),
        quads(w.q0, m),
        quads(w.v1, m),
        quads(w.v0, m),
        quads(w.a1, m),
        quads(w.a0, m),
        quads(w.kq1, m),
        quads(w.kq0, m),
        quads(w.ma1, m),
        quads(w.ma0, m),
        quads(w.fw, m),
        quads(w.z0, m),
        quads(w.kz0, m),
        quads(w.mass, m),
    ];
    let (z1, kz1, dvs, svs) = (&mut *w.z1, &mut *w.kz1, &mut *w.dv, &mut *w.sv);
    let (z1q, kz1q, dvq, svq) = (
        &mut z1[..n].as_chunks_mut::<4>().0[..m],
        &mut kz1[..n].as_chunks_mut::<4>().0[..m],
        &mut dvs[..n].as_chunks_mut::<4>().0[..m],
        &mut svs[..n].as_chunks_mut::<4>().0[..m],
    );
    // The sums of H in four lanes (the order of `dot` and `SymBand::quad`), the others in two
    // (lanes l and l + 2 added first).
    let mut lanes = [F4::default(); SUMS];
    let mut pairs = [[0.0; 2]; SUMS];
    for c in 0..m {
        let x = std::array::from_fn(|j| Fx(ins[j][c]));
        let (t, out) = dof::<F, LUMPED, P, F4>(&k, x);
        for s in 0..SUMS {
            if !used::<F, LUMPED, P>(s) {
                continue;
            }
            if of_h(s) {
                lanes[s] = lanes[s] + t[s];
            } else {
                let u = t[s].0;
                pairs[s] = [pairs[s][0] + (u[0] + u[2]), pairs[s][1] + (u[1] + u[3])];
            }
        }
        if filtered::<F>() && q_part::<P>() {
            z1q[c] = out[0].0;
            kz1q[c] = out[1].0;
        }
        if !LUMPED && !q_part::<P>() {
            dvq[c] = out[2].0;
            svq[c] = out[3].0;
        }
    }
    let mut tail = [0.0; SUMS];
    let all = [
        w.q1, w.q0, w.v1, w.v0, w.a1, w.a0, w.kq1, w.kq0, w.ma1, w.ma0, w.fw, w.z0, w.kz0, w.mass,
    ];
    for i in 4 * m..n {
        let x = std::array::from_fn(|j| all[j][i]);
        let (t, out) = dof::<F, LUMPED, P, f64>(&k, x);
        for (s, acc) in tail.iter_mut().enumerate() {
            if used::<F, LUMPED, P>(s) {
                *acc += t[s];
            }
        }
        if filtered::<F>() && q_part::<P>() {
            z1[i] = out[0];
            kz1[i] = out[1];
        }
        if !LUMPED && !q_part::<P>() {
            dvs[i] = out[2];
            svs[i] = out[3];
        }
    }
    std::array::from_fn(|s| {
        if !used::<F, LUMPED, P>(s) {
            0.0
        } else if of_h(s) {
            let l = lanes[s].0;
            (l[0] + l[2]) + (l[1] + l[3]) + tail[s]
        } else {
            (pairs[s][0] + pairs[s][1]) + tail[s]
        }
    })
}

/// Whether sum `s` is one of H (55): qᵀKq, aᵀMa, vᵀMv, zᵀKz.
#[inline(always)]
pub(super) const fn of_h(s: usize) -> bool {
    matches!(s, S_STRAIN | S_ATERM | S_KIN | S_ZTERM)
}

/// The coefficients of [`dof`]: c_n = ν/(½ + ν), c_m = (½ − ν)/(½ + ν).
pub(super) struct SweepCoefficients {
    pub(super) filter: [f64; 2],
}

/// Whether sum `s` is formed by the variant and the part (the filter sums with filters, the
/// kinetic sums with a lumped mass).
#[inline(always)]
pub(super) const fn used<F: FilterKind, const LUMPED: bool, P: PartKind>(s: usize) -> bool {
    match s {
        S_WORK_EXT | S_DQ_K_DQ | S_D_STRAIN | S_STRAIN => q_part::<P>(),
        S_DZ_K_DZ | S_D_ZTERM | S_ZTERM => filtered::<F>() && q_part::<P>(),
        S_D_KIN | S_KIN => LUMPED && !q_part::<P>(),
        _ => !q_part::<P>(),
    }
}

/// The terms of one dof (or four, [`F4`]) of one part (`P`) for [`finish_sweep`] from
/// `x` = (q, q_k, v, v_k, a, a_k, Kq, (Kq)_k, Ma, (Ma)_k, γF + (1 − γ)F_k, z_k, (Kz)_k, M_ii)
/// (no index: t_{k+1}); returns the terms of the part's sums and (z, Kz, Δv, v + v_k) at
/// t_{k+1} (the part's entries; the others zero).
#[inline(always)]
pub(super) fn dof<F: FilterKind, const LUMPED: bool, P: PartKind, T: Lane>(
    k: &SweepCoefficients,
    x: [T; 14],
) -> ([T; SUMS], [T; 4])
where
    f64: std::ops::Mul<T, Output = T>,
{
    let [
        q1,
        q0,
        v1,
        v0,
        a1,
        a0,
        kq1,
        kq0,
        ma1,
        ma0,
        fw,
        z0,
        kz0,
        mass,
    ] = x;
    let mut t = [T::default(); SUMS];
    let mut out = [T::default(); 4];
    if q_part::<P>() {
        let [cn, cm] = k.filter;
        let dq = q1 - q0;
        t[S_WORK_EXT] = dq * fw;
        let dkq = kq1 - kq0;
        t[S_DQ_K_DQ] = dq * dkq;
        t[S_D_STRAIN] = (q1 + q0) * dkq;
        t[S_STRAIN] = q1 * kq1;
        if filtered::<F>() {
            let (z, kz) = if matches!(F::FILTER, Filter::WithMemory) {
                (cn * dq - cm * z0, cn * dkq - cm * kz0)
            } else {
                (cn * dq, cn * dkq)
            };
            let dkz = kz - kz0;
            t[S_DZ_K_DZ] = (z - z0) * dkz;
            t[S_D_ZTERM] = (z + z0) * dkz;
            t[S_ZTERM] = z * kz;
            out[0] = z;
            out[1] = kz;
        }
    } else {
        // A lumped mass: M a = m∘a (the product `SymBand::mul_into` forms), `ma` not read.
        let (ma1, ma0) = if LUMPED {
            (mass * a1, mass * a0)
        } else {
            (ma1, ma0)
        };
        let dma = ma1 - ma0;
        t[S_DA_M_DA] = (a1 - a0) * dma;
        t[S_D_ATERM] = (a1 + a0) * dma;
        t[S_ATERM] = a1 * ma1;
        let (dv, sv) = (v1 - v0, v1 + v0);
        if LUMPED {
            t[S_D_KIN] = mass * sv * dv;
            t[S_KIN] = mass * v1 * v1;
        }
        out[2] = dv;
        out[3] = sv;
    }
    (t, out)
}
