//! Reference models of Jay & Negrut (2008) §8 and a slider-crank. Each struct is both the
//! scene's `[model]` parameters in the job spec and the [`ConstrainedModel`].

use super::{ConstrainedModel, Dims, ExactValues, InitialValues, Scalar};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// `scene = "jay_negrut_test"`: the nonlinear test problem (15), nonconstant mass, one
/// holonomic and one nonholonomic constraint, f nonlinear in λ and ψ. Exact solution
/// `y = (eᵗ, e⁻²ᵗ)`, `z = (eᵗ, −2e⁻²ᵗ)`, `λ = e⁻ᵗ`, `ψ = eᵗ`.
///
/// The initial values default to the paper's (`y₀ = (1, 1)`, `z₀ = (1, −2)`, `λ₀ = ψ₀ = 1`);
/// they can be overridden (to test the consistency check).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct JayNegrutTest {
    /// y₀ override (2 entries).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub y0: Option<Vec<f64>>,
    /// z₀ override (2 entries).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub z0: Option<Vec<f64>>,
}

impl ConstrainedModel for JayNegrutTest {
    fn dims(&self) -> Dims {
        Dims {
            n: 2,
            holonomic: 1,
            nonholonomic: 1,
        }
    }

    /// (15b) left: `[[y₁, y₂ − e⁻²ᵗ], [sin(y₁ − eᵗ), y₁y₂]]`.
    fn mass<T: Scalar>(&self, t: T, y: &[T], m: &mut [T]) {
        m[0] = y[0];
        m[1] = y[1] - (t * -2.0).exp();
        m[2] = (y[0] - t.exp()).sin();
        m[3] = y[0] * y[1];
    }

    /// (15b) right.
    fn force<T: Scalar>(&self, t: T, y: &[T], z: &[T], lambda: &[T], psi: &[T], f: &mut [T]) {
        let (l, p) = (lambda[0], psi[0]);
        f[0] = t.exp() * (y[0] * z[1] + y[1] * z[0] * 2.0) + (t * 2.0).exp() * y[0] * l
            - y[0] * z[1] * p
            - 2.0;
        f[1] = (-t).exp() * (y[1] * z[1] * 0.5 - y[0] * z[0] * y[1] * z[1] * 2.0 + y[1] * l * l)
            - y[0] * y[1] * z[0] * p.powi(3)
            + (t * 3.0).exp();
    }

    /// (15c): `y₁² y₂ − 1`.
    fn g<T: Scalar>(&self, _t: T, y: &[T], out: &mut [T]) {
        out[0] = y[0] * y[0] * y[1] - 1.0;
    }

    /// (15e): `y₁ z₁ z₂ + 2`.
    fn k<T: Scalar>(&self, _t: T, y: &[T], z: &[T], out: &mut [T]) {
        out[0] = y[0] * z[0] * z[1] + 2.0;
    }

    fn initial(&self) -> InitialValues {
        InitialValues {
            t: 0.0,
            y: self.y0.clone().unwrap_or_else(|| vec![1.0, 1.0]),
            z: self.z0.clone().unwrap_or_else(|| vec![1.0, -2.0]),
            lambda: vec![1.0],
            psi: vec![1.0],
        }
    }

    fn exact(&self, t: f64) -> Option<ExactValues> {
        let (e, e2) = (t.exp(), (-2.0 * t).exp());
        Some(ExactValues {
            y: vec![e, e2],
            z: vec![e, -2.0 * e2],
            a: vec![e, 4.0 * e2],
            lambda: vec![(-t).exp()],
            psi: vec![e],
        })
    }
}

/// `scene = "pendulum"`: the pendulum (16) of Fig. 3, y = (x, y, θ), a torsional spring k and
/// damper c at the pin. Defaults are Fig. 3's: m = 5, L = 2, k = 3000, c = 100, g = 9.81,
/// θ(0) = 3π/2, θ'(0) = 10; (x, y) and their velocities follow from the constraints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct Pendulum {
    /// m > 0.
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub mass: f64,
    /// L > 0.
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub length: f64,
    /// Spring stiffness k ≥ 0 (rest angle 3π/2).
    #[schemars(range(min = 0.0))]
    pub stiffness: f64,
    /// Damping coefficient c ≥ 0.
    #[schemars(range(min = 0.0))]
    pub damping: f64,
    /// Gravitational acceleration g.
    pub gravity: f64,
    /// θ(0).
    pub theta0: f64,
    /// θ'(0).
    pub omega0: f64,
    /// y₀ override (3 entries); the default follows from θ(0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub y0: Option<Vec<f64>>,
    /// z₀ override (3 entries); the default follows from θ(0), θ'(0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub z0: Option<Vec<f64>>,
}

impl Default for Pendulum {
    fn default() -> Self {
        Self {
            mass: 5.0,
            length: 2.0,
            stiffness: 3000.0,
            damping: 100.0,
            gravity: 9.81,
            theta0: 1.5 * PI,
            omega0: 10.0,
            y0: None,
            z0: None,
        }
    }
}

impl ConstrainedModel for Pendulum {
    fn dims(&self) -> Dims {
        Dims {
            n: 3,
            holonomic: 2,
            nonholonomic: 0,
        }
    }

    /// (16b) left: diag(m, m, mL²/3).
    fn mass<T: Scalar>(&self, _t: T, _y: &[T], m: &mut [T]) {
        m.fill(T::zero());
        m[0] = T::from(self.mass);
        m[4] = T::from(self.mass);
        m[8] = T::from(self.mass * self.length * self.length / 3.0);
    }

    /// (16b) right: `(0, −mg, −c z₃ − k(y₃ − 3π/2)) − g_yᵀ λ`.
    fn force<T: Scalar>(&self, _t: T, y: &[T], z: &[T], lambda: &[T], _psi: &[T], f: &mut [T]) {
        let l = self.length;
        let (s, co) = (y[2].sin(), y[2].cos());
        f[0] = -lambda[0];
        f[1] = -lambda[1] - self.mass * self.gravity;
        f[2] = z[2] * -self.damping - (y[2] - 1.5 * PI) * self.stiffness - s * l * lambda[0]
            + co * l * lambda[1];
    }

    /// (16c): `(y₁ − L cos y₃, y₂ − L sin y₃)`.
    fn g<T: Scalar>(&self, _t: T, y: &[T], out: &mut [T]) {
        out[0] = y[0] - y[2].cos() * self.length;
        out[1] = y[1] - y[2].sin() * self.length;
    }

    /// `[[1, 0, L sin y₃], [0, 1, −L cos y₃]]` (closed form).
    fn g_y<T: Scalar>(&self, _t: T, y: &[T], out: &mut [T]) {
        out.fill(T::zero());
        out[0] = T::one();
        out[2] = y[2].sin() * self.length;
        out[4] = T::one();
        out[5] = y[2].cos() * -self.length;
    }

    /// (16d): `(z₁ + L sin(y₃) z₃, z₂ − L cos(y₃) z₃)` (closed form).
    fn g_dot<T: Scalar>(&self, _t: T, y: &[T], z: &[T], out: &mut [T]) {
        out[0] = z[0] + y[2].sin() * z[2] * self.length;
        out[1] = z[1] - y[2].cos() * z[2] * self.length;
    }

    fn additive(&self) -> bool {
        true
    }

    /// Gravity m g y₂ plus the spring ½k(y₃ − 3π/2)².
    fn potential(&self, _t: f64, y: &[f64]) -> f64 {
        self.mass * self.gravity * y[1] + 0.5 * self.stiffness * (y[2] - 1.5 * PI).powi(2)
    }

    fn damping_force(&self, _t: f64, _y: &[f64], z: &[f64], out: &mut [f64]) {
        out[0] = 0.0;
        out[1] = 0.0;
        out[2] = -self.damping * z[2];
    }

    fn initial(&self) -> InitialValues {
        let (l, th, om) = (self.length, self.theta0, self.omega0);
        InitialValues {
            t: 0.0,
            y: self
                .y0
                .clone()
                .unwrap_or_else(|| vec![l * th.cos(), l * th.sin(), th]),
            z: self
                .z0
                .clone()
                .unwrap_or_else(|| vec![-l * th.sin() * om, l * th.cos() * om, om]),
            lambda: vec![0.0; 2],
            psi: Vec::new(),
        }
    }
}

/// `scene = "slider_crank"`: a planar slider-crank of rigid bodies in absolute coordinates
/// (floating frame), under gravity −y. y = (x₁, y₁, φ₁, x₂, y₂, φ₂, x₃, y₃): crank centre and
/// angle, rod centre and angle, slider position. Constraints (7): the crank is pinned to the
/// ground at O = (0, 0) (rows 1–2: their velocity rows are the velocity of the pin O, the
/// quantity of the paper's Figs. 6–7), crank tip pinned to the rod (3–4), rod end pinned to the
/// slider (5–6), the slider moves on y = 0 (7). Crank and rod are uniform bars (I = mL²/12).
/// One degree of freedom; consistent initial conditions follow from the crank angle and speed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct SliderCrank {
    /// Crank length r > 0 (default 0.2 m).
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub crank_length: f64,
    /// Crank mass (default 1 kg).
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub crank_mass: f64,
    /// Rod length l ≥ r (default 0.5 m).
    pub rod_length: f64,
    /// Rod mass (default 1.5 kg).
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub rod_mass: f64,
    /// Slider mass (default 1 kg).
    #[schemars(extend("exclusiveMinimum" = 0.0))]
    pub slider_mass: f64,
    /// Gravitational acceleration (default 9.81).
    pub gravity: f64,
    /// Initial crank angle θ₀ (default π/4).
    pub crank_angle: f64,
    /// Initial crank angular velocity θ'₀ (default 6 rad/s).
    pub crank_speed: f64,
}

impl Default for SliderCrank {
    fn default() -> Self {
        Self {
            crank_length: 0.2,
            crank_mass: 1.0,
            rod_length: 0.5,
            rod_mass: 1.5,
            slider_mass: 1.0,
            gravity: 9.81,
            crank_angle: PI / 4.0,
            crank_speed: 6.0,
        }
    }
}

impl ConstrainedModel for SliderCrank {
    fn dims(&self) -> Dims {
        Dims {
            n: 8,
            holonomic: 7,
            nonholonomic: 0,
        }
    }

    fn mass<T: Scalar>(&self, _t: T, _y: &[T], m: &mut [T]) {
        m.fill(T::zero());
        let d = [
            self.crank_mass,
            self.crank_mass,
            self.crank_mass * self.crank_length.powi(2) / 12.0,
            self.rod_mass,
            self.rod_mass,
            self.rod_mass * self.rod_length.powi(2) / 12.0,
            self.slider_mass,
            self.slider_mass,
        ];
        for (i, v) in d.into_iter().enumerate() {
            m[i * 8 + i] = T::from(v);
        }
    }

    /// Gravity − g_yᵀ λ (closed-form g_y).
    fn force<T: Scalar>(&self, t: T, y: &[T], _z: &[T], lambda: &[T], _psi: &[T], f: &mut [T]) {
        f.fill(T::zero());
        f[1] = T::from(-self.crank_mass * self.gravity);
        f[4] = T::from(-self.rod_mass * self.gravity);
        f[7] = T::from(-self.slider_mass * self.gravity);
        let mut gy = [T::zero(); 7 * 8];
        self.g_y(t, y, &mut gy);
        for (q, &l) in lambda.iter().enumerate() {
            for j in 0..8 {
                f[j] -= gy[q * 8 + j] * l;
            }
        }
    }

    fn g<T: Scalar>(&self, _t: T, y: &[T], out: &mut [T]) {
        let (hr, hl) = (0.5 * self.crank_length, 0.5 * self.rod_length);
        let (s1, c1) = (y[2].sin(), y[2].cos());
        let (s2, c2) = (y[5].sin(), y[5].cos());
        out[0] = y[0] - c1 * hr;
        out[1] = y[1] - s1 * hr;
        out[2] = y[0] + c1 * hr - y[3] + c2 * hl;
        out[3] = y[1] + s1 * hr - y[4] + s2 * hl;
        out[4] = y[3] + c2 * hl - y[6];
        out[5] = y[4] + s2 * hl - y[7];
        out[6] = y[7];
    }

    /// Closed form of the derivative of [`Self::g`], 7×8 row-major.
    fn g_y<T: Scalar>(&self, _t: T, y: &[T], out: &mut [T]) {
        let (hr, hl) = (0.5 * self.crank_length, 0.5 * self.rod_length);
        let (s1, c1) = (y[2].sin() * hr, y[2].cos() * hr);
        let (s2, c2) = (y[5].sin() * hl, y[5].cos() * hl);
        out.fill(T::zero());
        let one = T::one();
        // Row q, column j at q·8 + j.
        out[0] = one;
        out[2] = s1;
        out[8 + 1] = one;
        out[8 + 2] = -c1;
        out[16] = one;
        out[16 + 2] = -s1;
        out[16 + 3] = -one;
        out[16 + 5] = -s2;
        out[24 + 1] = one;
        out[24 + 2] = c1;
        out[24 + 4] = -one;
        out[24 + 5] = c2;
        out[32 + 3] = one;
        out[32 + 5] = -s2;
        out[32 + 6] = -one;
        out[40 + 4] = one;
        out[40 + 5] = c2;
        out[40 + 7] = -one;
        out[48 + 7] = one;
    }

    /// g_y z in closed form (g does not depend on t).
    fn g_dot<T: Scalar>(&self, _t: T, y: &[T], z: &[T], out: &mut [T]) {
        let (hr, hl) = (0.5 * self.crank_length, 0.5 * self.rod_length);
        let (s1, c1) = (y[2].sin() * hr, y[2].cos() * hr);
        let (s2, c2) = (y[5].sin() * hl, y[5].cos() * hl);
        out[0] = z[0] + s1 * z[2];
        out[1] = z[1] - c1 * z[2];
        out[2] = z[0] - s1 * z[2] - z[3] - s2 * z[5];
        out[3] = z[1] + c1 * z[2] - z[4] + c2 * z[5];
        out[4] = z[3] - s2 * z[5] - z[6];
        out[5] = z[4] + c2 * z[5] - z[7];
        out[6] = z[7];
    }

    fn additive(&self) -> bool {
        true
    }

    fn potential(&self, _t: f64, y: &[f64]) -> f64 {
        self.gravity * (self.crank_mass * y[1] + self.rod_mass * y[4] + self.slider_mass * y[7])
    }

    fn initial(&self) -> InitialValues {
        let (r, l, th, om) = (
            self.crank_length,
            self.rod_length,
            self.crank_angle,
            self.crank_speed,
        );
        let (s, c) = th.sin_cos();
        // Rod from the crank tip A = r(cos θ, sin θ) to the slider B = (x_B, 0): l sin φ = −r sin θ.
        let phi = (-r * s / l).asin();
        let (sp, cp) = phi.sin_cos();
        let phi_dot = -r * c * om / (l * cp);
        let xb = r * c + l * cp;
        let xb_dot = -r * s * om - l * sp * phi_dot;
        let y = vec![
            0.5 * r * c,
            0.5 * r * s,
            th,
            r * c + 0.5 * l * cp,
            r * s + 0.5 * l * sp,
            phi,
            xb,
            0.0,
        ];
        let z = vec![
            -0.5 * r * s * om,
            0.5 * r * c * om,
            om,
            -r * s * om - 0.5 * l * sp * phi_dot,
            r * c * om + 0.5 * l * cp * phi_dot,
            phi_dot,
            xb_dot,
            0.0,
        ];
        InitialValues {
            t: 0.0,
            y,
            z,
            lambda: vec![0.0; 7],
            psi: Vec::new(),
        }
    }
}
