#!/usr/bin/env python3
"""The IFToMM benchmark A02 (the N-four-bar mechanism), written as a `lagrangian` spec.

N four-bar loops side by side share their rockers: N + 1 rockers of length L pinned to the
ground at x = 0, L, …, NL, and N couplers, each joining the tips of two neighbouring rockers.
Every bar is a uniform rod of mass m and length L; gravity g acts along −y. At t = 0 the
rockers are vertical (φ = π/2), the couplers horizontal, and the tip of every rocker moves at
1 m/s towards +x (φ̇ = −1/L; B0, the tip of the first rocker, is the reference point).
Coordinates: the absolute angles φ_0 … φ_N of the rockers and ψ_1 … ψ_N of
the couplers, interleaved (φ_0, ψ_1, φ_1, ψ_2, …) so that M and g_q are banded.

Each loop i closes by two joints (x and y of the tip of rocker i reached through coupler i):
    L cos φ_{i−1} + L cos ψ_i − L cos φ_i − L = 0,   L sin φ_{i−1} + L sin ψ_i − L sin φ_i = 0.
Whenever the rockers are horizontal the N x-rows of g_q vanish together: the singular
positions of the benchmark. On the parallelogram branch every rocker keeps the angle θ(t) of
the one-degree-of-freedom pendulum
    I θ̈ = −V'(θ),  I = (N + 1) m L²/3 + N m L²,  V(θ) = m g L (3N + 1)/2 · sin θ,
    θ(0) = π/2, θ̇(0) = −1/L,
which is the exact solution the tests compare with.

Usage: n_four_bar.py N [SCHEME] [H] [T_END] > file.toml
"""
import sys


def header(how: str) -> str:
    """The module's description as TOML comments, and how the file was written."""
    text = __doc__.split("Usage:")[0].strip()
    lines = [("# " + line).rstrip() for line in text.splitlines()]
    return "\n".join(lines + [f"# ({how})", ""])


def spec(n: int, scheme: str, h: float, t_end: float, every: int) -> str:
    names = []
    for i in range(n + 1):
        names.append(f"p{i}")
        if i < n:
            names.append(f"s{i + 1}")
    index = {name: k for k, name in enumerate(names)}
    entries = []
    for i in range(n + 1):
        k = index[f"p{i}"]
        entries.append((k, k, "m*L^2/3 + m*L^2" if i < n else "m*L^2/3"))
        if i < n:
            c = index[f"s{i + 1}"]
            entries.append((k, c, f"m*L^2/2*cos(p{i} - s{i + 1})"))
            entries.append((c, c, "m*L^2/3"))
    mass = ", ".join(f'[{i}, {j}, "{e}"]' for (i, j, e) in entries)
    potential = " + ".join(
        [f"m*g*L/2*sin(p{i})" for i in range(n + 1)]
        + [f"m*g*(L*sin(p{i}) + L/2*sin(s{i + 1}))" for i in range(n)]
    )
    joints = []
    for i in range(1, n + 1):
        joints.append(f"L*cos(p{i - 1}) + L*cos(s{i}) - L*cos(p{i}) - L")
        joints.append(f"L*sin(p{i - 1}) + L*sin(s{i}) - L*sin(p{i})")
    q0 = ["1.5707963267948966" if name.startswith("p") else "0.0" for name in names]
    v0 = ["-1.0" if name.startswith("p") else "0.0" for name in names]
    out = [header(f"written by examples/benchmarks/n_four_bar.py {n} {scheme} {h} {t_end}")]
    out.append(f'name = "IFToMM A02: N-four-bar mechanism, N = {n}, {scheme}"\n')
    out.append("[model]")
    out.append('scene = "lagrangian"')
    out.append("coordinates = [" + ", ".join(f'"{x}"' for x in names) + "]")
    out.append("parameters = { m = 1.0, L = 1.0, g = 9.81 }")
    out.append("mass = { entries = [" + mass + "] }")
    out.append(f'potential = "{potential}"')
    out.append("q0 = [" + ", ".join(q0) + "]")
    out.append("v0 = [" + ", ".join(v0) + "]")
    for j in joints:
        out.append("\n[[model.constraints]]")
        out.append(f'expr = "{j}"')
    out.append("\n[integrator]")
    out.append(f'scheme = "{scheme}"')
    if scheme in ("soi2_hht", "hht_i3"):
        out.append("alpha = -0.05")
    out.append("\n[time]")
    out.append(f"h = {h}")
    out.append(f"t_end = {t_end}")
    out.append("\n[output]")
    out.append(f"every = {every}")
    out.append(f"probes = [0, 2, {2 * n}]              # the first, second and last rocker")
    out.append("\n# Bounds for `signorini check` (the CI gate): B0 = (L cos φ_0, L sin φ_0) against the")
    out.append("# exact parallelogram motion θ(t) (classical Runge–Kutta at h = 1e-4 on the 1-dof equation")
    out.append("# above; tests/soi2_hard_cases.rs integrates it again), within the benchmark's high-precision")
    out.append("# class, 1e-3 m, expressed on the angle φ_0 (|Δφ_0| = |ΔB0| for L = 1).")
    out.append("[check]")
    out.append("max_position_residual = 1e-9")
    out.append("max_energy_growth = 1e-4")
    for t, th in reference_angles(n, [t_end / 3, 2 * t_end / 3, t_end]):
        out.append("\n[[check.reference]]")
        out.append('column = "q_0"')
        out.append(f"t = {t!r}")
        out.append(f"value = {th!r}")
        out.append("tolerance = 1e-3")
    return "\n".join(out) + "\n"


def reference_angles(n: int, ts, h=1e-4):
    """θ(t) of the parallelogram branch by classical Runge–Kutta."""
    import math
    inertia = (n + 1) / 3 + n
    c = 9.81 * (3 * n + 1) / 2
    f = lambda th, w: (w, -c * math.cos(th) / inertia)
    th, w, t = math.pi / 2, -1.0, 0.0
    out = []
    for target in ts:
        while t < target - 1e-12:
            hh = min(h, target - t)
            k1 = f(th, w)
            k2 = f(th + hh / 2 * k1[0], w + hh / 2 * k1[1])
            k3 = f(th + hh / 2 * k2[0], w + hh / 2 * k2[1])
            k4 = f(th + hh * k3[0], w + hh * k3[1])
            th += hh / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            w += hh / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
            t += hh
        out.append((target, th))
    return out


if __name__ == "__main__":
    n = int(sys.argv[1])
    scheme = sys.argv[2] if len(sys.argv) > 2 else "soi2_generalized_alpha"
    h = float(sys.argv[3]) if len(sys.argv) > 3 else 1e-3
    t_end = float(sys.argv[4]) if len(sys.argv) > 4 else 3.0
    sys.stdout.write(spec(n, scheme, h, t_end, 10))
