#!/usr/bin/python3
"""Reference trajectories from Siconos for the cross-check of our Moreau–Jean scheme.

Run with the Debian interpreter (the package `python3-siconos` installs into it):

    apt-get install -y python3-siconos
    /usr/bin/python3 scripts/siconos/reference.py

For each scene it writes, into crates/signorini-core/tests/fixtures/siconos/,

* `<name>.csv`  — one row per step k = 0..steps (row 0 is the initial state):
  `step, t, q_0..q_{n-1}, v_0..v_{n-1}, p_0` where `p_0 = inter.lambda_(1)[0]` is the
  impulse P_{k+1} of the step that reached row k (0 on row 0). Floats are written with
  Python's `repr` (shortest string that round-trips exactly).
* `<name>.json` — the exact parameters: a Signorini job spec (`spec`, which
  `tests/siconos_crosscheck.rs` runs as is) and how the Siconos model was built (`siconos`).

Scenes (offsets keep a contact from closing exactly on a step):

* `ball_e09_theta05` — m = 1, g = 9.81, q0 = 1 − 3.7e-4, e = 0.9, θ = ½, γ = 1, h = 0.005
* `ball_e05_theta1`  — same ball, e = 0.5, θ = 1, γ = 0.5 (passed explicitly), h = 0.005
* `bar_e0_theta05`   — fixed–free bar, 10 lumped elements, L = E = ρ = A = 1, uniform
  initial velocity 1 toward the obstacle, gap 0.1037, e = 0, θ = ½, γ = 1, h = 0.02
* `bar_e05_theta1_force` — same bar at rest, body force 1 per length toward the obstacle,
  gap 0.02037, e = 0.5, θ = 1, γ not passed (Siconos' default, which is ½), h = 0.02

Siconos model: LagrangianLinearTIDS(q0, v0, M, K, C = 0) with dense M and K and a constant
`FExt`; LagrangianLinearTIR(C = Gᵀ, e = offset) so y = Gᵀq + e is the gap;
NewtonImpactNSL(e); MoreauJeanOSI(θ[, γ]); LCP() (Lemke by default); TimeStepping.
"""

import json
import os
import sys

import numpy as np
import siconos
import siconos.kernel as sk

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.normpath(os.path.join(HERE, "..", "..", "crates", "signorini-core", "tests", "fixtures", "siconos"))


def bar_matrices(elements, length, young, density, area, body_force):
    """Fixed left end (node 0 removed), lumped mass, dofs = nodes 1..N.

    Same assembly as `scenes::Bar::build`: k_e = EA/h_e, m_e = ρAh_e/2 per element end,
    nodal load h_e/2 · f per element end."""
    n = elements
    he = length / elements
    ke = young * area / he
    me = density * area * he
    K = np.zeros((n, n))
    M = np.zeros((n, n))
    F = np.zeros(n)
    for e in range(elements):
        a, b = e - 1, e  # dofs of nodes e and e+1 (node 0 is fixed: dof −1)
        for i, j, s in [(a, a, 1.0), (b, b, 1.0), (a, b, -1.0), (b, a, -1.0)]:
            if i >= 0 and j >= 0:
                K[i, j] += s * ke
        for i in (a, b):
            if i >= 0:
                M[i, i] += me / 2.0
                F[i] += he / 2.0 * body_force
    return M, K, F


def simulate(M, K, F, C, offset, q0, v0, restitution, theta, gamma, h, steps):
    """Runs Siconos and returns rows [step, t, q..., v..., p]."""
    n = len(q0)
    M = np.array(M, dtype=float)
    ds = sk.LagrangianLinearTIDS(list(q0), list(v0), M, np.array(K, dtype=float), np.zeros_like(M))
    ds.setFExtPtr(np.array(F, dtype=float))
    rel = sk.LagrangianLinearTIR(np.array(C, dtype=float), np.array(offset, dtype=float))
    inter = sk.Interaction(sk.NewtonImpactNSL(restitution), rel)
    nsds = sk.NonSmoothDynamicalSystem(0.0, (steps + 10) * h)
    nsds.insertDynamicalSystem(ds)
    nsds.link(inter, ds)
    td = sk.TimeDiscretisation(0.0, h)
    osi = sk.MoreauJeanOSI(theta) if gamma is None else sk.MoreauJeanOSI(theta, gamma)
    lcp = sk.LCP()  # Lemke (SICONOS_LCP_LEMKE) by default
    sim = sk.TimeStepping(nsds, td, osi, lcp)
    rows = [[0, 0.0] + list(q0) + list(v0) + [0.0]]
    for k in range(1, steps + 1):
        sim.computeOneStep()
        t = sim.nextTime()
        q = np.array(ds.q()).copy()
        v = np.array(ds.velocity()).copy()
        p = float(inter.lambda_(1)[0])
        rows.append([k, t] + list(q) + list(v) + [p])
        sim.nextStep()
    assert len(rows[0]) == 2 * n + 3
    return rows, osi


def write(name, header, rows, sidecar):
    os.makedirs(OUT, exist_ok=True)
    with open(os.path.join(OUT, name + ".csv"), "w") as f:
        f.write(",".join(header) + "\n")
        for r in rows:
            f.write(",".join([str(int(r[0]))] + [repr(float(x)) for x in r[1:]]) + "\n")
    with open(os.path.join(OUT, name + ".json"), "w") as f:
        json.dump(sidecar, f, indent=2)
        f.write("\n")


def siconos_info(osi, gamma):
    return {
        "python_siconos_version": siconos.version,
        "debian_package": "python3-siconos 4.4.0+dfsg-2",
        "osi": "MoreauJeanOSI(theta)" if gamma is None else "MoreauJeanOSI(theta, gamma)",
        "osi_theta": osi.theta(),
        "osi_gamma": osi.gamma(),
        "osi_use_gamma": osi.useGamma(),
        "constraint_activation_threshold": osi.constraintActivationThreshold(),
        "nsl": "NewtonImpactNSL(e)",
        "ds": "LagrangianLinearTIDS(q0, v0, M, K, C = 0) dense, setFExtPtr(F)",
        "relation": "LagrangianLinearTIR(C = G^T, e = offset)",
        "osnsp": "LCP() (Lemke)",
        "impulse": "inter.lambda_(1)[0]",
    }


def ball(name, restitution, theta, gamma, h, steps, q0=1.0 - 3.7e-4, mass=1.0, gravity=9.81):
    rows, osi = simulate(
        [[mass]], [[0.0]], [-mass * gravity], [[1.0]], [0.0], [q0], [0.0], restitution, theta, gamma, h, steps
    )
    spec = {
        "name": name,
        "model": {"scene": "bouncing_ball", "mass": mass, "gravity": gravity, "q0": q0, "v0": 0.0,
                  "restitution": restitution},
        "integrator": {"scheme": "moreau_jean", "theta": theta, "activation": "predicted_gap",
                       "activation_gamma": osi.gamma()},
        "time": {"h": h, "steps": steps},
        "contact_solver": {"kind": "lemke"},
        "output": {"every": 1, "probes": [0]},
    }
    write(name, ["step", "t", "q_0", "v_0", "p_0"], rows, {"spec": spec, "siconos": siconos_info(osi, gamma)})
    return rows


def bar(name, elements, gap, restitution, initial_velocity, body_force, theta, gamma, h, steps):
    length = young = density = area = 1.0
    M, K, F = bar_matrices(elements, length, young, density, area, body_force)
    n = elements
    C = np.zeros((1, n))
    C[0, n - 1] = -1.0  # g = gap − u_N
    rows, osi = simulate(M, K, F, C, [gap], [0.0] * n, [initial_velocity] * n, restitution, theta, gamma, h, steps)
    spec = {
        "name": name,
        "model": {"scene": "bar", "elements": elements, "length": length, "young": young, "density": density,
                  "area": area, "mass_matrix": "lumped", "left": "fixed", "gap": gap, "restitution": restitution,
                  "initial_velocity": initial_velocity, "body_force": body_force},
        "integrator": {"scheme": "moreau_jean", "theta": theta, "activation": "predicted_gap",
                       "activation_gamma": osi.gamma()},
        "time": {"h": h, "steps": steps},
        "contact_solver": {"kind": "lemke"},
        "output": {"every": 1, "probes": list(range(n))},
    }
    header = ["step", "t"] + [f"q_{j}" for j in range(n)] + [f"v_{j}" for j in range(n)] + ["p_0"]
    write(name, header, rows, {"spec": spec, "siconos": siconos_info(osi, gamma)})
    return rows


def main():
    summary = {}
    for name, rows in [
        ("ball_e09_theta05", ball("ball_e09_theta05", 0.9, 0.5, 1.0, 0.005, 300)),
        ("ball_e05_theta1", ball("ball_e05_theta1", 0.5, 1.0, 0.5, 0.005, 300)),
        ("bar_e0_theta05", bar("bar_e0_theta05", 10, 0.1037, 0.0, 1.0, 0.0, 0.5, 1.0, 0.02, 150)),
        ("bar_e05_theta1_force", bar("bar_e05_theta1_force", 10, 0.02037, 0.5, 0.0, 1.0, 1.0, None, 0.02, 150)),
    ]:
        impacts = sum(1 for a, b in zip(rows, rows[1:]) if b[-1] > 0 and a[-1] <= 0)
        active = sum(1 for r in rows if r[-1] > 0)
        summary[name] = {"rows": len(rows), "impacts": impacts, "steps_with_impulse": active}
    json.dump(summary, sys.stdout)
    print()


if __name__ == "__main__":
    main()
