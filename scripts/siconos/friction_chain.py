#!/usr/bin/python3
"""Siconos' side of the friction speed comparison: MoreauJeanOSI with FrictionContact(2) (NSGS)
on the chain pressed and dragged against a rough wall (examples/chain_rough_wall.toml, N masses),
against the same chain without friction (LCP, Lemke).

    /usr/bin/python3 scripts/siconos/friction_chain.py            # N = 4, 20, 50
    /usr/bin/python3 scripts/siconos/friction_chain.py 4 20       # chosen N

The chain: N unit masses with dofs (x_i, y_i) (x along the wall, y the gap), springs 1e3 between
neighbours along the wall and 1e2 across it, a force of -10 on every y_i and of 5 N on the last
x (20 N for N = 4), at rest on the wall; h = 1e-3, theta = 1/2, 40 000 / N steps (the steps of
crates/signorini-core/benches/friction_steps.rs). With friction: one Interaction per mass,
LagrangianLinearTIR with the rows (y_i, x_i), NewtonImpactFrictionNSL(0, 0, 0.3, 2),
FrictionContact(2) with SICONOS_FRICTION_2D_NSGS at tolerance 1e-12. Without: NewtonImpactNSL(0)
on the row y_i, LCP() (Lemke). Timing: the loop computeOneStep(); nextStep() only, best of 3.
One JSON line per (N, problem) on stdout, with the final x of the pulled mass (to check that
both codes integrate the same motion).
"""

import json
import os
import sys
import time

import numpy as np
import siconos
import siconos.kernel as sk
import siconos.numerics as sn

H = 1e-3
MU = 0.3


def matrices(n):
    M = np.eye(2 * n)
    K = np.zeros((2 * n, 2 * n))
    for i in range(1, n):
        for d, k in ((0, 1e3), (1, 1e2)):
            a, b = 2 * (i - 1) + d, 2 * i + d
            K[a, a] += k
            K[b, b] += k
            K[a, b] -= k
            K[b, a] -= k
    F = np.zeros(2 * n)
    F[1::2] = -10.0
    F[2 * (n - 1)] = 5.0 * n
    return M, K, F


def run(n, steps, friction):
    M, K, F = matrices(n)
    ds = sk.LagrangianLinearTIDS([0.0] * (2 * n), [0.0] * (2 * n), M, K, np.zeros((2 * n, 2 * n)))
    ds.setFExtPtr(F)
    nsds = sk.NonSmoothDynamicalSystem(0.0, (steps + 10) * H)
    nsds.insertDynamicalSystem(ds)
    for i in range(n):
        if friction:
            C = np.zeros((2, 2 * n))
            C[0, 2 * i + 1] = 1.0
            C[1, 2 * i] = 1.0
            law = sk.NewtonImpactFrictionNSL(0.0, 0.0, MU, 2)
            rel = sk.LagrangianLinearTIR(C)
        else:
            C = np.zeros((1, 2 * n))
            C[0, 2 * i + 1] = 1.0
            law = sk.NewtonImpactNSL(0.0)
            rel = sk.LagrangianLinearTIR(C)
        nsds.link(sk.Interaction(law, rel), ds)
    osi = sk.MoreauJeanOSI(0.5)
    if friction:
        osnspb = sk.FrictionContact(2, sn.SICONOS_FRICTION_2D_NSGS)
        osnspb.numericsSolverOptions().dparam[sn.SICONOS_DPARAM_TOL] = 1e-12
        osnspb.numericsSolverOptions().iparam[sn.SICONOS_IPARAM_MAX_ITER] = 100000
    else:
        osnspb = sk.LCP()
    sim = sk.TimeStepping(nsds, sk.TimeDiscretisation(0.0, H), osi, osnspb)
    sim.initialize()
    t1 = time.perf_counter()
    for _ in range(steps):
        sim.computeOneStep()
        sim.nextStep()
    wall = time.perf_counter() - t1
    return wall, float(np.array(ds.q())[2 * (n - 1)])


def main():
    ns = [int(a) for a in sys.argv[1:]] or [4, 20, 50]
    for n in ns:
        steps = 40000 // n
        for friction in (False, True):
            best, x = min(run(n, steps, friction) for _ in range(3))
            print(json.dumps({
                "code": "siconos",
                "version": siconos.version,
                "scene": "chain_rough_wall",
                "masses": n,
                "problem": "FrictionContact(2) NSGS" if friction else "LCP Lemke",
                "steps": steps,
                "wall_s": round(best, 4),
                "steps_per_s": round(steps / best, 1),
                "x_pulled_final": x,
                "load_avg_1min": os.getloadavg()[0],
            }), flush=True)


if __name__ == "__main__":
    main()
