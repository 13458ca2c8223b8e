#!/usr/bin/python3
"""Siconos' side of the string benchmark (issue 19): MoreauJeanOSI + LCP on the `string` scene
with a contact at every node, the `plucked` case of crates/signorini-core/benches/string_contacts.rs:

    /usr/bin/python3 scripts/siconos/string_bench.py               # N = 10, 30, 100, 300, 1000
    /usr/bin/python3 scripts/siconos/string_bench.py 100 300       # chosen N
    BUDGET_S=120 /usr/bin/python3 scripts/siconos/string_bench.py  # stop after a run past 120 s
    /usr/bin/python3 scripts/siconos/string_bench.py --compare     # both codes, side by side

`--compare [N ...]` (default N = 10 30 100 300) runs, in one go, Signorini's string bench on the
same window (`cargo bench -p signorini-core --bench string_contacts -- --siconos N ...`: the
same scene, Moreau–Jean θ = ½, 200 untimed steps to t = 4 ms, then STEPS(N) timed, best of 3)
and this Siconos bench for each N (N grows until a Siconos run takes more than BUDGET_S), and
prints one table: µs per step of both (wall clock; Siconos' on-CPU time too) and the ratios
Siconos/Signorini. Signorini's side is its banded path (`auto`: banded above 200 contacts, Lemke
on the dense W below), Siconos' the dense LCP.

Scene (the Signorini spec; examples/string_bridge.toml with a flat obstacle):

    [model]
    scene = "string"
    nodes = N
    length = 1.0
    tension = 100.0
    linear_density = 0.01
    pluck = { position = 0.3, amplitude = 0.002 }
    obstacle = { offset = 1e-5, curvature = 0.0, restitution = 0.0 }
    [integrator]
    scheme = "moreau_jean"
    theta = 0.5
    [time]
    h = 2e-5

Siconos 4.4: LagrangianLinearTIDS with dense M (ρΔx I) and K ((T/Δx) tridiag(−1, 2, −1)), C = 0;
one Interaction per node, LagrangianLinearTIR(C = e_jᵀ, e = offset), NewtonImpactNSL(0);
MoreauJeanOSI(0.5); LCP() (Lemke, dense: its Python binding takes dense matrices only);
TimeStepping. Siconos' index set is its own (the predicted gap with γ = ½, see docs/siconos.md), so
the trajectories are close, not equal; the point is the cost per step.

Timing: wall clock and process CPU of `computeOneStep(); nextStep()` only, over STEPS(N) steps
from t = 0.004 s (the string reaches the obstacle near t = 0.0045 s: every measured step has
contacts in the index set), after the same number of free steps run untimed. One JSON line per
N; N grows until a run takes more than BUDGET_S seconds (default 60).
"""

import json
import os
import pathlib
import subprocess
import sys
import time

import numpy as np
import siconos
import siconos.kernel as sk

H = 2e-5
L, T, RHO = 1.0, 100.0, 0.01
OFFSET = 1e-5
PLUCK_X, PLUCK_A = 0.3, 0.002
WARM_T = 0.004


def steps_for(n):
    return max(20, min(2000, int(2e5 / n)))


def string(n):
    dx = L / (n + 1)
    x = dx * np.arange(1, n + 1)
    q0 = np.where(x <= PLUCK_X, PLUCK_A * x / PLUCK_X, PLUCK_A * (L - x) / (L - PLUCK_X))
    M = RHO * dx * np.eye(n)
    K = np.zeros((n, n))
    kt = T / dx
    for j in range(n):
        K[j, j] = 2.0 * kt
        if j > 0:
            K[j, j - 1] = K[j - 1, j] = -kt
    return q0, M, K


def bench(n):
    steps = steps_for(n)
    warm = int(round(WARM_T / H))
    t0 = time.perf_counter()
    q0, M, K = string(n)
    ds = sk.LagrangianLinearTIDS(list(q0), [0.0] * n, M, K, np.zeros((n, n)))
    nsds = sk.NonSmoothDynamicalSystem(0.0, (warm + steps + 10) * H)
    nsds.insertDynamicalSystem(ds)
    inters = []
    for j in range(n):
        C = np.zeros((1, n))
        C[0, j] = 1.0
        inter = sk.Interaction(sk.NewtonImpactNSL(0.0), sk.LagrangianLinearTIR(C, np.array([OFFSET])))
        nsds.link(inter, ds)
        inters.append(inter)
    osi = sk.MoreauJeanOSI(0.5)
    sim = sk.TimeStepping(nsds, sk.TimeDiscretisation(0.0, H), osi, sk.LCP())
    sim.initialize()
    setup = time.perf_counter() - t0
    for _ in range(warm):
        sim.computeOneStep()
        sim.nextStep()
    t1 = time.perf_counter()
    c1 = time.process_time()
    for _ in range(steps):
        sim.computeOneStep()
        sim.nextStep()
    wall = time.perf_counter() - t1
    cpu = time.process_time() - c1
    hit = sum(1 for i in inters if i.lambda_(1)[0] > 0.0)
    q = np.array(ds.q())
    return {
        "code": "siconos",
        "version": siconos.version,
        "scene": "string",
        "nodes": n,
        "contacts": n,
        "h": H,
        "theta": 0.5,
        "steps": steps,
        "t_start": warm * H,
        "setup_s": round(setup, 3),
        "wall_s": round(wall, 3),
        "steps_per_s": round(steps / wall, 1),
        "us_per_step": round(1e6 * wall / steps, 1),
        "cpu_s": round(cpu, 3),
        "load_avg_1min": os.getloadavg()[0],
        "impulses_last_step": hit,
        "q_min_final": float(q.min()),
    }


ROOT = pathlib.Path(__file__).resolve().parents[2]


def signorini(ns):
    """Signorini's µs per step on the Siconos window, per N."""
    out = subprocess.run(
        ["cargo", "bench", "-q", "-p", "signorini-core", "--bench", "string_contacts", "--",
         "--siconos", *map(str, ns)],
        cwd=ROOT, check=True, capture_output=True, text=True,
    ).stdout
    rows = [json.loads(line) for line in out.splitlines() if line.startswith("{")]
    return {r["nodes"]: r for r in rows if r.get("window") == "siconos"}


def compare(ns):
    ours = signorini(ns)
    budget = float(os.environ.get("BUDGET_S", "60"))
    sic = {}
    for n in ns:
        t = time.perf_counter()
        sic[n] = bench(n)
        print(json.dumps(sic[n]), file=sys.stderr, flush=True)
        if time.perf_counter() - t > budget:
            break
    print(f"# load average (1 min): {os.getloadavg()[0]:.2f}; Siconos {siconos.version}; "
          f"µs per step, plucked string, Moreau-Jean theta = 1/2, h = {H}, from t = {WARM_T} s")
    print(f"{'N':>6} {'steps':>6} {'signorini':>10} {'iter/step':>10} {'siconos wall':>13} "
          f"{'siconos cpu':>12} {'wall ratio':>11} {'cpu ratio':>10}")
    for n in ns:
        s, it = ours[n]["us_per_step"], ours[n]["iterations_per_step"]
        head = f"{n:>6} {ours[n]['steps']:>6} {s:>10.2f} {it:>10.2f}"
        c = sic.get(n)
        if c is None:
            print(f"{head} {'—':>13} {'—':>12} {'—':>11} {'—':>10}")
            continue
        cpu = 1e6 * c["cpu_s"] / c["steps"]
        print(f"{head} {c['us_per_step']:>13.1f} {cpu:>12.1f} "
              f"{c['us_per_step'] / s:>11.0f} {cpu / s:>10.0f}")


def main():
    if sys.argv[1:2] == ["--compare"]:
        compare([int(a) for a in sys.argv[2:]] or [10, 30, 100, 300])
        return
    ns = [int(a) for a in sys.argv[1:]] or [10, 30, 100, 300, 1000]
    budget = float(os.environ.get("BUDGET_S", "60"))
    for n in ns:
        t = time.perf_counter()
        print(json.dumps(bench(n)), flush=True)
        if time.perf_counter() - t > budget:
            break


if __name__ == "__main__":
    main()
