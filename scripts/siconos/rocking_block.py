#!/usr/bin/python3
"""Siconos' side of the nonlinear Moreau–Jean cross-check and speed comparison: the rocking block.

    apt-get install -y python3-siconos gcc
    /usr/bin/python3 scripts/siconos/rocking_block.py    # rewrites the rocking_block_* fixtures, prints speed

Model (the same as `RockingBlock` in crates/signorini-core/tests/nonlinear_siconos.rs, no damping):
a rigid block, m = 1, width w = 0.2, height hgt = 0.4, J = m (w² + hgt²)/12, coordinates (y, φ)
of its centre, gravity g = 9.81 as the constant external force −m g on y, two bottom
corners with gaps g± = y ± (w/2) sin φ − (hgt/2) cos φ (a C plugin, rocking_block_plugin.c),
q0 = ((hgt/2) cos 0.1 + (w/2) sin 0.1 + 0.005, 0.1), v0 = 0.

Siconos: LagrangianDS(q0, v0, M) with setFExtPtr, LagrangianScleronomousR(h, G0) per corner,
NewtonImpactNSL(e), MoreauJeanOSI(θ = ½) (its default γ = ½ for the predicted gap), LCP()
(Lemke), TimeStepping with Newton tolerance 1e-10 and at most 50 iterations.

Writes crates/signorini-core/tests/fixtures/siconos/rocking_block_e<E>.csv: one row per step
k = 0..steps, `step, t, q_0, q_1, v_0, v_1, p_0, p_1` (p = inter.lambda_(1)[0] per corner).
"""

import os
import subprocess
import sys
import tempfile
import time

import numpy as np
import siconos.kernel as sk

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.normpath(os.path.join(HERE, "..", "..", "crates", "signorini-core", "tests", "fixtures", "siconos"))
M, W, HGT, G = 1.0, 0.2, 0.4, 9.81
H, STEPS = 1e-3, 1000


def plugin():
    d = tempfile.mkdtemp()
    subprocess.run(["gcc", "-O2", "-shared", "-fPIC", "-o", os.path.join(d, "RBPlugin.so"),
                    os.path.join(HERE, "rocking_block_plugin.c"), "-lm"], check=True)
    return os.path.join(d, "RBPlugin")


def build(lib, e, steps):
    phi0 = 0.1
    q0 = [0.5 * HGT * np.cos(phi0) + 0.5 * W * np.sin(phi0) + 0.005, phi0]
    ds = sk.LagrangianDS(q0, [0.0, 0.0], np.diag([M, M * (W * W + HGT * HGT) / 12.0]))
    ds.setFExtPtr(np.array([-M * G, 0.0]))
    nsds = sk.NonSmoothDynamicalSystem(0.0, (steps + 10) * H)
    nsds.insertDynamicalSystem(ds)
    inters = []
    for k in (1, 2):
        rel = sk.LagrangianScleronomousR(f"{lib}:h{k}", f"{lib}:G{k}")
        inter = sk.Interaction(sk.NewtonImpactNSL(e), rel)
        nsds.link(inter, ds)
        inters.append(inter)
    osi = sk.MoreauJeanOSI(0.5)
    sim = sk.TimeStepping(nsds, sk.TimeDiscretisation(0.0, H), osi, sk.LCP())
    sim.setNewtonTolerance(1e-10)
    sim.setNewtonMaxIteration(50)
    return q0, ds, inters, sim, osi


def main():
    lib = plugin()
    for e, tag in [(0.0, "e0"), (0.5, "e05")]:
        q0, ds, inters, sim, osi = build(lib, e, STEPS)
        rows = [[0, 0.0] + q0 + [0.0, 0.0, 0.0, 0.0]]
        for k in range(1, STEPS + 1):
            sim.computeOneStep()
            q, v = np.array(ds.q()), np.array(ds.velocity())
            rows.append([k, sim.nextTime()] + list(q) + list(v) + [float(i.lambda_(1)[0]) for i in inters])
            sim.nextStep()
        os.makedirs(OUT, exist_ok=True)
        with open(os.path.join(OUT, f"rocking_block_{tag}.csv"), "w") as f:
            f.write("step,t,q_0,q_1,v_0,v_1,p_0,p_1\n")
            for r in rows:
                f.write(",".join([str(int(r[0]))] + [repr(float(x)) for x in r[1:]]) + "\n")
        # Speed: 5 s of simulated time (a Python loop over computeOneStep), best of three.
        best = float("inf")
        steps = int(round(5.0 / H))
        for _ in range(3):
            _, ds, _, sim, _ = build(lib, e, steps)
            t0 = time.perf_counter()
            for _k in range(steps):
                sim.computeOneStep()
                sim.nextStep()
            best = min(best, time.perf_counter() - t0)
        print(f'{{"bench":"siconos_rocking_block","e":{e},"h":{H},"steps":{steps},"seconds":{best:.4f},'
              f'"steps_per_s":{steps / best:.0f},"gamma":{osi.gamma()}}}')


if __name__ == "__main__":
    sys.exit(main())
