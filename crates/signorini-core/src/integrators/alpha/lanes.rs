//! The vector type of the α-family's sweeps: L dofs at once ([`Fx`]), and the dot product
//! whose summation order the sweeps reproduce.

/// L dofs at once, lane l for the l-th dof of a chunk: element-wise arithmetic that the
/// compiler maps to vector instructions (each lane computes exactly what a scalar would).
#[derive(Debug, Clone, Copy)]
pub(super) struct Fx<const L: usize>(pub(super) [f64; L]);

/// Four dofs (lane l for the dof index ≡ l mod 4), the finish sweep's unit.
pub(super) type F4 = Fx<4>;
/// Two dofs, the predictor sweep's unit.
pub(super) type F2 = Fx<2>;

impl<const L: usize> Default for Fx<L> {
    fn default() -> Self {
        Fx([0.0; L])
    }
}

impl<const L: usize> std::ops::Add for Fx<L> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Fx(std::array::from_fn(|l| self.0[l] + o.0[l]))
    }
}

impl<const L: usize> std::ops::Sub for Fx<L> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Fx(std::array::from_fn(|l| self.0[l] - o.0[l]))
    }
}

impl<const L: usize> std::ops::Mul for Fx<L> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Fx(std::array::from_fn(|l| self.0[l] * o.0[l]))
    }
}

impl<const L: usize> std::ops::Mul<Fx<L>> for f64 {
    type Output = Fx<L>;
    #[inline(always)]
    fn mul(self, o: Fx<L>) -> Fx<L> {
        Fx(o.0.map(|x| self * x))
    }
}

/// What [`dof`] and [`predict_row`] compute with: one dof (f64) or several ([`Fx`]).
pub(super) trait Lane:
    Copy
    + Default
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
where
    f64: std::ops::Mul<Self, Output = Self>,
{
}

impl Lane for f64 {}
impl<const L: usize> Lane for Fx<L> {}

pub(super) fn dot(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len());
    let (xc, yc) = (x[..n].chunks_exact(4), y[..n].chunks_exact(4));
    let mut tail = 0.0;
    for (a, b) in xc.remainder().iter().zip(yc.remainder()) {
        tail += a * b;
    }
    // Four interleaved partial sums: consecutive additions do not wait for each other (one
    // running sum is bound by the latency of one addition per dof); round-off differences only.
    let mut acc = [0.0; 4];
    for (a, b) in xc.zip(yc) {
        for l in 0..4 {
            acc[l] += a[l] * b[l];
        }
    }
    (acc[0] + acc[2]) + (acc[1] + acc[3]) + tail
}
