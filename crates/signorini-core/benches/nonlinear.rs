//! Per-step cost of the nonlinear Moreau–Jean time-stepping on a rocking block (hand-written
//! `LagrangianSystem`: coordinates (y, φ), two corner gaps, frictionless floor), and on a
//! double pendulum without contacts (M(q) and Coriolis forces: Newton does more than one
//! iterate per step).
//!
//! ```text
//! cargo bench -p signorini-core --bench nonlinear
//! ```
//!
//! Prints one JSON line per case: steps/s, Newton iterates per step (mean and max), LCP size
//! (largest) and the share of steps that solved an LCP.

// Only the core library must stay pure (clippy.toml): a benchmark times itself and prints.
#![allow(clippy::disallowed_macros, clippy::disallowed_methods)]

use signorini_core::integrators::OutputOptions;
use signorini_core::lcp::LcpOptions;
use signorini_core::nonlinear::LagrangianSystem;
use signorini_core::nonlinear::generalized_alpha::JointedSystem;
use signorini_core::nonlinear::moreau_jean::{
    NonlinearMoreauJean, NonlinearMoreauJeanParams, NonlinearRunStats, NonlinearState,
};
use signorini_core::nonlinear::run::run_nonlinear;
use signorini_core::observer::{Observer, StepRecord};
use std::ops::ControlFlow;
use std::time::Instant;

/// A rigid block (width w, height hgt, mass m) on a rigid floor: the centre's height y and the
/// tilt φ (x stays put: the frictionless floor pushes only vertically), gaps
/// g± = y ± (w/2) sin φ − (hgt/2) cos φ of the two bottom corners, a light rotational damping.
struct RockingBlock {
    m: f64,
    w: f64,
    hgt: f64,
    g: f64,
    damping: f64,
    e: f64,
}

impl RockingBlock {
    fn inertia(&self) -> f64 {
        self.m * (self.w * self.w + self.hgt * self.hgt) / 12.0
    }
}

/// No joints (the defaults).
impl JointedSystem for RockingBlock {}

impl LagrangianSystem for RockingBlock {
    fn dofs(&self) -> usize {
        2
    }
    fn contacts(&self) -> usize {
        2
    }
    fn initial(&self) -> (Vec<f64>, Vec<f64>) {
        let phi0: f64 = 0.1;
        let y0 = 0.5 * self.hgt * phi0.cos() + 0.5 * self.w * phi0.sin() + 0.005;
        (vec![y0, phi0], vec![0.0, 0.0])
    }
    fn mass(&self, _: &[f64], out: &mut [f64]) {
        out.copy_from_slice(&[self.m, 0.0, 0.0, self.inertia()]);
    }
    fn forces(&self, _: f64, _: &[f64], v: &[f64], out: &mut [f64]) {
        out.copy_from_slice(&[-self.m * self.g, -self.damping * v[1]]);
    }
    fn force_jacobians(&self, _: f64, _: &[f64], _: &[f64], dq: &mut [f64], dv: &mut [f64]) {
        dq.fill(0.0);
        dv.copy_from_slice(&[0.0, 0.0, 0.0, -self.damping]);
    }
    fn applied_forces(&self, _: f64, _: &[f64], v: &[f64], out: &mut [f64]) {
        out.copy_from_slice(&[0.0, -self.damping * v[1]]);
    }
    fn potential(&self, _: f64, q: &[f64]) -> f64 {
        self.m * self.g * q[0]
    }
    fn gaps(&self, _: f64, q: &[f64], out: &mut [f64]) {
        let (s, c) = q[1].sin_cos();
        out[0] = q[0] + 0.5 * self.w * s - 0.5 * self.hgt * c;
        out[1] = q[0] - 0.5 * self.w * s - 0.5 * self.hgt * c;
    }
    fn gap_jacobian(&self, _: f64, q: &[f64], out: &mut [f64]) {
        let (s, c) = q[1].sin_cos();
        out.copy_from_slice(&[
            1.0,
            0.5 * self.w * c + 0.5 * self.hgt * s,
            1.0,
            -0.5 * self.w * c + 0.5 * self.hgt * s,
        ]);
    }
    fn gap_rates(&self, _: f64, _: &[f64], out: &mut [f64]) {
        out.fill(0.0);
    }
    fn restitution(&self, _: usize) -> f64 {
        self.e
    }
}

/// A double pendulum in absolute angles, point masses on massless rods; no contact.
struct DoublePendulum;

/// No joints (the defaults).
impl JointedSystem for DoublePendulum {}

impl LagrangianSystem for DoublePendulum {
    fn dofs(&self) -> usize {
        2
    }
    fn contacts(&self) -> usize {
        0
    }
    fn initial(&self) -> (Vec<f64>, Vec<f64>) {
        (vec![1.5, 2.0], vec![0.0, 0.0])
    }
    fn mass(&self, q: &[f64], out: &mut [f64]) {
        let c = 0.35 * (q[0] - q[1]).cos();
        out.copy_from_slice(&[1.5, c, c, 0.245]);
    }
    fn forces(&self, _: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
        let s = (q[0] - q[1]).sin();
        out[0] = -1.5 * 9.81 * q[0].sin() - 0.35 * s * v[1] * v[1];
        out[1] = -0.35 * 9.81 * q[1].sin() + 0.35 * s * v[0] * v[0];
    }
    fn force_jacobians(&self, _: f64, q: &[f64], v: &[f64], dq: &mut [f64], dv: &mut [f64]) {
        let (s, c) = (q[0] - q[1]).sin_cos();
        dq.copy_from_slice(&[
            -1.5 * 9.81 * q[0].cos() - 0.35 * c * v[1] * v[1],
            0.35 * c * v[1] * v[1],
            0.35 * c * v[0] * v[0],
            -0.35 * 9.81 * q[1].cos() - 0.35 * c * v[0] * v[0],
        ]);
        dv.copy_from_slice(&[0.0, -0.7 * s * v[1], 0.7 * s * v[0], 0.0]);
    }
    fn applied_forces(&self, _: f64, _: &[f64], _: &[f64], out: &mut [f64]) {
        out.fill(0.0);
    }
    fn potential(&self, _: f64, q: &[f64]) -> f64 {
        -1.5 * 9.81 * q[0].cos() - 0.35 * 9.81 * q[1].cos()
    }
    fn gaps(&self, _: f64, _: &[f64], _: &mut [f64]) {}
    fn gap_jacobian(&self, _: f64, _: &[f64], _: &mut [f64]) {}
    fn gap_rates(&self, _: f64, _: &[f64], _: &mut [f64]) {}
    fn restitution(&self, _: usize) -> f64 {
        0.0
    }
}

/// Counts records, keeps nothing (the benchmark measures the integrator, not the output).
struct Count(u64);

impl Observer for Count {
    fn observe(&mut self, _: &StepRecord<'_>) -> ControlFlow<()> {
        self.0 += 1;
        ControlFlow::Continue(())
    }
}

/// Best of three runs of `steps` steps: (seconds, stats).
fn time<S: JointedSystem>(system: &S, h: f64, steps: u64) -> (f64, NonlinearRunStats) {
    let mut best = f64::INFINITY;
    let mut stats = NonlinearRunStats::default();
    for _ in 0..3 {
        let mut scheme = NonlinearMoreauJean::new(
            system,
            NonlinearMoreauJeanParams::default(),
            h,
            LcpOptions::default(),
        )
        .expect("valid parameters");
        let mut state = NonlinearState::initial(system);
        let output = OutputOptions {
            every: u64::MAX,
            probes: vec![],
        };
        let t0 = Instant::now();
        stats = run_nonlinear(
            system,
            &mut scheme,
            &mut state,
            steps,
            &output,
            &mut Count(0),
        )
        .expect("run");
        best = best.min(t0.elapsed().as_secs_f64());
        std::hint::black_box(&state);
    }
    (best, stats)
}

fn report(name: &str, e: f64, h: f64, steps: u64, seconds: f64, stats: &NonlinearRunStats) {
    println!(
        "{{\"bench\":\"{name}\",\"e\":{e},\"h\":{h},\"steps\":{steps},\"seconds\":{seconds:.4},\"steps_per_s\":{:.0},\"newton_mean\":{:.3},\"newton_max\":{},\"lcp_max_size\":{},\"lcp_steps_share\":{:.3},\"impacts\":{}}}",
        steps as f64 / seconds,
        stats.newton_iterations_mean,
        stats.newton_iterations_max,
        stats.lcp_max_size,
        stats.lcp_solves as f64 / steps as f64,
        stats.impacts,
    );
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let t_end = if quick { 0.5 } else { 5.0 };
    for e in [0.0, 0.5] {
        for h in [1e-3, 1e-4] {
            let block = RockingBlock {
                m: 1.0,
                w: 0.2,
                hgt: 0.4,
                g: 9.81,
                damping: 1e-3,
                e,
            };
            let steps = (t_end / h) as u64;
            let (seconds, stats) = time(&block, h, steps);
            report(
                "nonlinear_moreau_jean_rocking_block",
                e,
                h,
                steps,
                seconds,
                &stats,
            );
        }
    }
    for h in [1e-3, 1e-4] {
        let steps = (t_end / h) as u64;
        let (seconds, stats) = time(&DoublePendulum, h, steps);
        report(
            "nonlinear_moreau_jean_double_pendulum",
            0.0,
            h,
            steps,
            seconds,
            &stats,
        );
    }
}
