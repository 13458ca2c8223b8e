#!/usr/bin/env python3
"""IFToMM A02 (the N-four-bar mechanism) under the index-3 augmented Lagrangian formulation
with mass-orthogonal projections and the trapezoidal rule, ALI3-P: the alternative to a
rank-revealing factorisation that issue 27 asks to compare (docs/benchmarks.md, "The
rank-revealing solve, chosen on evidence").

ALI3-P is the method the benchmark's authors ran on it:
  E. Bayo, R. Ledesma, "Augmented Lagrangian and mass-orthogonal projection methods for
  constrained multibody dynamics", Nonlinear Dynamics 9 (1996) 113-130,
  doi:10.1007/BF01833296;
  M. Gonzalez, D. Dopico, U. Lugris, J. Cuadrado, "A benchmarking system for MBS simulation
  software: problem standardization and performance measurement", Multibody System Dynamics
  16 (2006) 179-190, doi:10.1007/s11044-006-9020-9.

Per step: the trapezoidal rule's q' and q'' as functions of q_{n+1}; Newton on
(h^2/4) [M q'' + c + grad V + Phi_q^T (lambda* + alpha Phi)] = 0 with the tangent
M + (h^2/4) alpha Phi_q^T Phi_q (the damping and stiffness terms of the exact tangent dropped,
as in the benchmark's implementations), lambda* += alpha Phi after each iterate; then the
velocities and accelerations projected onto the constraint manifold with the same matrix. The
matrix is n x n, symmetric positive definite whatever the rank of Phi_q: no step needs a
rank-revealing factorisation.

The model and its initial state are the ones `benches/n_four_bar.rs` and
`examples/benchmarks/n_four_bar.py` write (m = L = 1, g = 9.81; the rockers at pi/2, the
first rocker's tip at unit speed); the exact motion is the parallelogram branch's one
degree of freedom, integrated by classical Runge-Kutta at 1e-4, as in
`tests/soi2_hard_cases.rs`.

    python3 scripts/ali3p_n_four_bar.py [--loops 40] [--t-end 20] [--h 1e-3] [--alpha 1e9]
        [--tolerance 1e-10] [--tangent approximate|exact]

prints the largest error of the point B0 (the first rocker's tip) against the exact motion,
the largest angle between rockers, the energy drift, Newton's iterates a step and the
largest constraint violation, over the whole run and over the steps next to the horizontal
passages (where Phi_q loses N rows of rank).
"""

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.linalg import cho_factor, cho_solve

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "examples" / "benchmarks"))
from n_four_bar import reference_angles  # noqa: E402

M_, L_, G_ = 1.0, 1.0, 9.81


class FourBar:
    """Coordinates [p0, s1, p1, s2, ..., sN, pN]: p_i the rockers' angles, s_i the couplers'."""

    def __init__(self, loops):
        self.N = loops
        self.n = 2 * loops + 1
        self.p = np.arange(0, self.n, 2)  # p_0 .. p_N
        self.s = np.arange(1, self.n, 2)  # s_1 .. s_N
        self.a = M_ * L_**2 / 2.0  # coefficient of cos(p_i - s_{i+1}) in M
        diag = np.full(self.n, M_ * L_**2 / 3.0)
        diag[self.p[:-1]] += M_ * L_**2
        self.diag = diag

    def mass(self, q):
        m = np.diag(self.diag)
        p, s = self.p[:-1], self.s
        c = self.a * np.cos(q[p] - q[s])
        m[p, s] = c
        m[s, p] = c
        return m

    def forces(self, q, v):
        """-c(q, q') - grad V(q): the smooth force."""
        f = np.zeros(self.n)
        p, s = self.p[:-1], self.s
        sn = self.a * np.sin(q[p] - q[s])
        f[p] -= sn * v[s] ** 2
        f[s] += sn * v[p] ** 2
        f[self.p] -= M_ * G_ * L_ / 2.0 * np.cos(q[self.p])
        f[p] -= M_ * G_ * L_ * np.cos(q[p])
        f[s] -= M_ * G_ * L_ / 2.0 * np.cos(q[s])
        return f

    def phi(self, q):
        pm, s, pi = q[self.p[:-1]], q[self.s], q[self.p[1:]]
        out = np.empty(2 * self.N)
        out[0::2] = L_ * (np.cos(pm) + np.cos(s) - np.cos(pi)) - L_
        out[1::2] = L_ * (np.sin(pm) + np.sin(s) - np.sin(pi))
        return out

    def phi_q(self, q):
        j = np.zeros((2 * self.N, self.n))
        rows = np.arange(self.N)
        for col, sign in ((self.p[:-1], 1.0), (self.s, 1.0), (self.p[1:], -1.0)):
            j[2 * rows, col] = -sign * L_ * np.sin(q[col])
            j[2 * rows + 1, col] = sign * L_ * np.cos(q[col])
        return j

    def phi_dot_q_v(self, q, v):
        """(d/dt Phi_q) q'."""
        out = np.zeros(2 * self.N)
        for col, sign in ((self.p[:-1], 1.0), (self.s, 1.0), (self.p[1:], -1.0)):
            out[0::2] -= sign * L_ * np.cos(q[col]) * v[col] ** 2
            out[1::2] -= sign * L_ * np.sin(q[col]) * v[col] ** 2
        return out

    def energy(self, q, v):
        pot = M_ * G_ * L_ / 2.0 * np.sin(q[self.p]).sum()
        pot += M_ * G_ * (L_ * np.sin(q[self.p[:-1]]) + L_ / 2.0 * np.sin(q[self.s])).sum()
        return 0.5 * v @ self.mass(q) @ v + pot


def exact_angle(loops, ts):
    """theta(t) of the parallelogram branch, from the example generator's reference."""
    return np.array([th for _, th in reference_angles(loops, ts)])


def run(loops, t_end, h, alpha, tolerance, exact_tangent, max_iterations=25):
    mb = FourBar(loops)
    n = mb.n
    q = np.zeros(n)
    q[mb.p] = math.pi / 2
    v = np.zeros(n)
    v[mb.p] = -1.0
    # Consistent start: q'' and lambda from the index-1 system.
    m, jq = mb.mass(q), mb.phi_q(q)
    kkt = np.block([[m, jq.T], [jq, np.zeros((2 * loops, 2 * loops))]])
    rhs = np.concatenate([mb.forces(q, v), -mb.phi_dot_q_v(q, v)])
    sol = np.linalg.lstsq(kkt, rhs, rcond=None)[0]
    a, lam = sol[:n], sol[n:]
    steps = int(round(t_end / h))
    ts, b0, e0 = [0.0], [q[0]], mb.energy(q, v)
    rockers = [0.0]
    drift, iterations, worst_phi, passage_iterations, failed = 0.0, [], 0.0, [], None
    started = time.process_time()
    for k in range(1, steps + 1):
        qd_hat = 2.0 / h * q + v
        qdd_hat = 4.0 / h**2 * q + 4.0 / h * v + a
        q1 = q + h * v + h * h / 2.0 * a
        def residual(q1):
            v1 = 2.0 / h * q1 - qd_hat
            a1 = 4.0 / h**2 * q1 - qdd_hat
            m1, jq, ph = mb.mass(q1), mb.phi_q(q1), mb.phi(q1)
            return h * h / 4.0 * (m1 @ a1 - mb.forces(q1, v1) + jq.T @ (lam + alpha * ph))

        for it in range(1, max_iterations + 1):
            f = residual(q1)
            if exact_tangent:
                # Central differences of the residual: M, c, grad V and Phi_qq^T (lambda* +
                # alpha Phi) differentiated too (relative error ~1e-10 of the tangent).
                tangent = np.empty((n, n))
                for j in range(n):
                    e = np.zeros(n)
                    e[j] = 1e-6
                    tangent[:, j] = (residual(q1 + e) - residual(q1 - e)) / 2e-6
                dq = np.linalg.solve(tangent, f)
            else:
                m1, jq = mb.mass(q1), mb.phi_q(q1)
                tangent = m1 + h * h / 4.0 * alpha * jq.T @ jq
                dq = cho_solve(cho_factor(tangent), f)
            q1 = q1 - dq
            lam = lam + alpha * mb.phi(q1)
            if np.abs(dq).max() <= tolerance * (1.0 + np.abs(q1).max()):
                break
        else:
            failed = k
            break
        iterations.append(it)
        # Mass-orthogonal projections of the velocities and accelerations.
        v1 = 2.0 / h * q1 - qd_hat
        a1 = 4.0 / h**2 * q1 - qdd_hat
        m1, jq = mb.mass(q1), mb.phi_q(q1)
        tangent = m1 + h * h / 4.0 * alpha * jq.T @ jq
        chol = cho_factor(tangent)
        v1 = cho_solve(chol, m1 @ v1)
        a1 = cho_solve(chol, m1 @ a1 - h * h / 4.0 * alpha * jq.T @ mb.phi_dot_q_v(q1, v1))
        q, v, a = q1, v1, a1
        t = k * h
        ts.append(t)
        b0.append(q[0])
        rockers.append(np.abs(q[mb.p] - q[0]).max())
        worst_phi = max(worst_phi, np.abs(mb.phi(q)).max())
        drift = max(drift, abs(mb.energy(q, v) - e0) / abs(e0))
        # Within 0.05 rad of a horizontal position: the steps next to a passage.
        if abs(math.remainder(q[0], math.pi)) < 0.05:
            passage_iterations.append(it)
    cpu = time.process_time() - started
    th = exact_angle(loops, ts)
    b0 = np.array(b0)
    point = np.hypot(np.cos(b0) - np.cos(th), np.sin(b0) - np.sin(th)).max()
    return {
        "loops": loops,
        "steps": len(iterations),
        "failed_at_step": failed,
        "point": point,
        "parallel": max(rockers),
        "drift": drift,
        "iterations": np.mean(iterations) if iterations else float("nan"),
        "passage_steps": len(passage_iterations),
        "passage_iterations": np.mean(passage_iterations) if passage_iterations else 0.0,
        "max_phi": worst_phi,
        "cpu": cpu,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--loops", type=int, default=40)
    ap.add_argument("--t-end", type=float, default=20.0)
    ap.add_argument("--h", type=float, default=1e-3)
    ap.add_argument("--alpha", type=float, default=1e9)
    ap.add_argument("--tolerance", type=float, default=1e-10)
    ap.add_argument(
        "--tangent",
        choices=["approximate", "exact"],
        default="approximate",
        help="Newton's matrix: M + (h^2/4) alpha Phi_q^T Phi_q (the benchmark's), or the "
        "residual's full derivative by central differences",
    )
    args = ap.parse_args()
    r = run(args.loops, args.t_end, args.h, args.alpha, args.tolerance, args.tangent == "exact")
    print(
        "| N | h | alpha | tangent | steps | B0 error (m) | rockers parallel (rad) | energy drift "
        "| Newton it/step | steps near a passage | it/step there | max abs Phi | CPU s (numpy) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    fail = f" (failed at step {r['failed_at_step']})" if r["failed_at_step"] else ""
    print(
        f"| {r['loops']} | {args.h:g} | {args.alpha:g} | {args.tangent} | {r['steps']}{fail} | {r['point']:.2e} "
        f"| {r['parallel']:.1e} | {r['drift']:.1e} | {r['iterations']:.2f} "
        f"| {r['passage_steps']} | {r['passage_iterations']:.2f} | {r['max_phi']:.1e} "
        f"| {r['cpu']:.1f} |"
    )


if __name__ == "__main__":
    main()
