#!/usr/bin/python3
"""Siconos' side of the speed comparison: MoreauJeanOSI on the `bar` scene.

    /usr/bin/python3 scripts/siconos/bench.py            # N = 100 and N = 1000
    /usr/bin/python3 scripts/siconos/bench.py 100 2000   # N = 100 and N = 2000, default steps
    /usr/bin/python3 scripts/siconos/bench.py --compare  # Signorini, C loop, Siconos side by side

`--compare [N ...]` (default N = 100 1000) runs, for each N, Signorini's own bench
(`cargo bench -p signorini-core --bench moreau_jean -- --elements N,...`), the C-loop reference
`benches/reference/moreau_jean_bar.c` (built with the system `cc -O2` into a temporary directory
when `cc` is on the PATH, skipped otherwise) and this Siconos bench, and prints one table of
steps/s with the ratios Signorini/C and Signorini/Siconos (all three on-CPU time; the load
average is printed with it). Signorini and the C loop run the default index set (24) with
gap 1e-3 + 1e-7 and 2·10⁷/N steps; the Siconos scene below runs fewer steps (its cost grows as
N²): steps/s of the three are per step of the same bar, the same scheme and the same contact.

Scene (the same as this Signorini job spec, see docs/siconos.md):

    [model]
    scene = "bar"
    elements = N          # 100 and 1000
    length = 1.0
    young = 1.0
    density = 1.0
    area = 1.0
    mass_matrix = "lumped"
    left = "fixed"
    gap = 0.0010037       # 1e-3 + 3.7e-6, so the contact does not close exactly on a step
    restitution = 0.0
    initial_velocity = 1.0
    [integrator]
    scheme = "moreau_jean"
    theta = 0.5
    activation = "predicted_gap"
    activation_gamma = 0.5   # Siconos' default γ (MoreauJeanOSI(0.5) is built without γ)
    [time]
    h = 1e-4
    steps = STEPS         # 20 000 for N = 100, 200 for N = 1000 (see STEPS below)
    [contact_solver]
    kind = "lemke"

Siconos: LagrangianLinearTIDS with dense M (lumped, diagonal), dense K (tridiagonal) and C = 0;
LagrangianLinearTIR(C = Gᵀ = −e_N, e = gap); NewtonImpactNSL(0); MoreauJeanOSI(0.5); LCP()
(Lemke); TimeStepping. The contact closes at step 11; at N = 1000 it stays closed for the whole
run (190 of 200 steps with an impulse), at N = 100 (t_end = 2) about half the steps have one.

Timing: wall clock of the loop `computeOneStep(); nextStep()` only (model set-up and the first
factorisation of W, done in TimeStepping's initialisation, are reported apart as `setup_s`).
`cpu_s` is the process CPU time of the same loop (less sensitive to other jobs on a shared
machine than the wall clock; `load_avg_1min` says how busy the machine was). One JSON line per N
on stdout.
"""

import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]

GAP = 1e-3 + 3.7e-6
H = 1e-4
STEPS = {100: 20000, 1000: 200}


def bar_matrices(n, length=1.0, young=1.0, density=1.0, area=1.0):
    he = length / n
    ke = young * area / he
    me = density * area * he
    K = np.zeros((n, n))
    M = np.zeros((n, n))
    for e in range(n):
        a, b = e - 1, e
        for i, j, s in [(a, a, 1.0), (b, b, 1.0), (a, b, -1.0), (b, a, -1.0)]:
            if i >= 0 and j >= 0:
                K[i, j] += s * ke
        for i in (a, b):
            if i >= 0:
                M[i, i] += me / 2.0
    return M, K


def bench(n, steps):
    import siconos
    import siconos.kernel as sk

    t0 = time.perf_counter()
    M, K = bar_matrices(n)
    ds = sk.LagrangianLinearTIDS([0.0] * n, [1.0] * n, M, K, np.zeros((n, n)))
    C = np.zeros((1, n))
    C[0, n - 1] = -1.0
    inter = sk.Interaction(sk.NewtonImpactNSL(0.0), sk.LagrangianLinearTIR(C, np.array([GAP])))
    nsds = sk.NonSmoothDynamicalSystem(0.0, (steps + 10) * H)
    nsds.insertDynamicalSystem(ds)
    nsds.link(inter, ds)
    osi = sk.MoreauJeanOSI(0.5)
    sim = sk.TimeStepping(nsds, sk.TimeDiscretisation(0.0, H), osi, sk.LCP())
    sim.initialize()
    setup = time.perf_counter() - t0
    with_impulse = 0
    t1 = time.perf_counter()
    c1 = time.process_time()
    for _ in range(steps):
        sim.computeOneStep()
        sim.nextStep()
        with_impulse += inter.lambda_(1)[0] > 0.0
    wall = time.perf_counter() - t1
    cpu = time.process_time() - c1
    q = np.array(ds.q())
    v = np.array(ds.velocity())
    return {
        "code": "siconos",
        "version": siconos.version,
        "scene": "bar",
        "elements": n,
        "dofs": n,
        "h": H,
        "gap": GAP,
        "theta": 0.5,
        "gamma": osi.gamma(),
        "steps": steps,
        "t_end": steps * H,
        "setup_s": round(setup, 4),
        "wall_s": round(wall, 4),
        "steps_per_s": round(steps / wall, 1),
        "us_per_step": round(1e6 * wall / steps, 2),
        "cpu_s": round(cpu, 4),
        "cpu_steps_per_s": round(steps / cpu, 1),
        "load_avg_1min": os.getloadavg()[0],
        "steps_with_impulse": int(with_impulse),
        "q_tip_final": float(q[-1]),
        "v_tip_final": float(v[-1]),
        "q_0_final": float(q[0]),
    }


def json_lines(text):
    return [json.loads(line) for line in text.splitlines() if line.startswith("{")]


def signorini(ns):
    """Steps/s of `cargo bench -p signorini-core --bench moreau_jean` per N."""
    out = subprocess.run(
        ["cargo", "bench", "-q", "-p", "signorini-core", "--bench", "moreau_jean", "--",
         "--elements", ",".join(str(n) for n in ns)],
        cwd=ROOT, check=True, capture_output=True, text=True,
    ).stdout
    return {r["elements"]: r for r in json_lines(out)}


def c_reference(ns):
    """Steps/s of the C loop per N, or {} without a C compiler."""
    cc = shutil.which("cc")
    if cc is None:
        print("# no `cc` on the PATH: the C-loop reference is skipped", file=sys.stderr)
        return {}
    with tempfile.TemporaryDirectory() as tmp:
        exe = os.path.join(tmp, "moreau_jean_bar")
        src = ROOT / "benches" / "reference" / "moreau_jean_bar.c"
        subprocess.run([cc, "-O2", "-o", exe, str(src)], check=True)
        out = subprocess.run([exe, *map(str, ns)], check=True, capture_output=True, text=True).stdout
    return {r["elements"]: r for r in json_lines(out)}


def compare(ns):
    ours = signorini(ns)
    c = c_reference(ns)
    try:
        sic = {n: bench(n, STEPS.get(n, max(200, int(2e6 / n)))) for n in ns}
    except ImportError:
        print("# Siconos is not importable (apt-get install -y python3-siconos, /usr/bin/python3)",
              file=sys.stderr)
        sic = {}
    print(f"# load average (1 min): {os.getloadavg()[0]:.2f}; steps/s from on-CPU time")
    print(f"{'N':>7} {'signorini':>12} {'C loop':>12} {'siconos':>10} {'sig/C':>7} {'sig/siconos':>12}")
    for n in ns:
        s = ours[n]["steps_per_s"]
        cs = c.get(n, {}).get("steps_per_s")
        ss = sic.get(n, {}).get("cpu_steps_per_s")
        cell = lambda x, w: f"{x:>{w}.0f}" if x else f"{'—':>{w}}"
        ratio = lambda x, w: f"{s / x:>{w}.2f}" if x else f"{'—':>{w}}"
        print(f"{n:>7} {s:>12.0f} {cell(cs, 12)} {cell(ss, 10)} {ratio(cs, 7)} {ratio(ss, 12)}")


def main():
    args = sys.argv[1:]
    if args[:1] == ["--compare"]:
        compare([int(a) for a in args[1:]] or [100, 1000])
        return
    ns = [int(a) for a in args] or [100, 1000]
    for n in ns:
        steps = STEPS.get(n, max(200, int(2e6 / n)))
        print(json.dumps(bench(n, steps)), flush=True)


if __name__ == "__main__":
    main()
