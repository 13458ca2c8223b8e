#!/usr/bin/env python3
"""The IFToMM benchmark A04 (Bricard's mechanism), written as a `lagrangian` spec.

Five uniform slender rods of mass m = 1 kg and length L = 1 m and the ground form a closed
loop of six revolute joints. At t = 0 (at rest) the rods run along the edges of a unit cube,
O = (0,0,0) → A = (1,0,0) → B = (1,−1,0) → C = (1,−1,1) → D = (0,−1,1) → E = (0,0,1), and the
ground closes the loop from E back to O; every joint axis is perpendicular to its two rods:
y at O, z at A, x at B, y at C, z at D, x at E. Gravity g = 9.81 m/s² along −y. The reference
point P3 is B.

Natural coordinates: the moving joint points A, B, C, D (12 coordinates; O and E are fixed).
A slender rod between points a and b has the kinetic energy (m/6)(|ȧ|² + ȧ·ḃ + |ḃ|²), so M is
constant: 2m/3 on the diagonal of each point, m/6 between the two ends of a rod. The potential
is m g (A_y + B_y + C_y + D_y). Each rod carries the axes of its two joints, perpendicular to
it and to each other: the axis at its far end is its first axis crossed with the rod
(u_A = A × ŷ, u_B = u_A × AB, u_C = BC × u_B, u_D = u_C × CD, u_E = DE × u_D, the signs giving
the initial axes above). The joints are:
five rod lengths, rod k ⟂ the axis of its first joint (five), and the last rod's axis at E
along x (two): 12 equations in 12 coordinates. Grübler's count gives no mobility; the
mechanism moves with one degree of freedom, so one joint is redundant at every configuration
(rank 11 of 12): `redundant_joints = true`.

Usage: bricard.py SCHEME [H] [T_END] > file.toml
"""
import sys


def header(how: str) -> str:
    """The module's description as TOML comments, and how the file was written."""
    text = __doc__.split("Usage:")[0].strip()
    lines = [("# " + line).rstrip() for line in text.splitlines()]
    return "\n".join(lines + [f"# ({how})", ""])


def sub(a, b):
    return [f"({x} - {y})" for x, y in zip(a, b)]


def cross(a, b):
    return [
        f"({a[1]}*{b[2]} - {a[2]}*{b[1]})",
        f"({a[2]}*{b[0]} - {a[0]}*{b[2]})",
        f"({a[0]}*{b[1]} - {a[1]}*{b[0]})",
    ]


def dot(a, b):
    return " + ".join(f"{x}*{y}" for x, y in zip(a, b))


def spec(scheme: str, h: float, t_end: float) -> str:
    pts = {p: [f"{p.lower()}{c}" for c in "xyz"] for p in "ABCD"}
    O = ["0", "0", "0"]
    E = ["0", "0", "L"]
    A, B, C, D = (pts[p] for p in "ABCD")
    rods = [sub(A, O), sub(B, A), sub(C, B), sub(D, C), sub(E, D)]
    axes = [["0", "1", "0"]]  # the axis at O
    axes.append(cross(A, ["0", "1", "0"]))  # u_A = A × ŷ
    for k in (1, 2, 3, 4):
        axes.append(cross(axes[k], rods[k]) if k % 2 == 1 else cross(rods[k], axes[k]))
    # Orientation of the next axis: u_B = u_A × d2, u_C = d3 × u_B, u_D = u_C × d4,
    # u_E = d5 × u_D (each one the first joint's axis crossed with the rod, signed so that
    # the initial axes are x at B, y at C, z at D, x at E).
    joints = []
    for k, rod in enumerate(rods):
        joints.append(f"{dot(rod, rod)} - L^2")
        joints.append(dot(rod, axes[k]))
    u_e = axes[5]
    joints.append(u_e[1])
    joints.append(u_e[2])
    names = [c for p in "ABCD" for c in pts[p]]
    q0 = [1, 0, 0, 1, -1, 0, 1, -1, 1, 0, -1, 1]
    entries = []
    for i in range(12):
        entries.append((i, i, "2*m/3"))
    for p in range(3):  # A–B, B–C, C–D
        for c in range(3):
            entries.append((3 * p + c, 3 * (p + 1) + c, "m/6"))
    entries.sort()
    out = [header(f"written by examples/benchmarks/bricard.py {scheme} {h} {t_end}"), f'name = "IFToMM A04: Bricard\'s mechanism, {scheme}"\n', "[model]", 'scene = "lagrangian"']
    out.append("coordinates = [" + ", ".join(f'"{x}"' for x in names) + "]")
    out.append("parameters = { m = 1.0, L = 1.0, g = 9.81 }")
    out.append("mass = { entries = [" + ", ".join(f'[{i}, {j}, "{e}"]' for i, j, e in entries) + "] }")
    out.append('potential = "m*g*(ay + by + cy + dy)"')
    out.append("q0 = [" + ", ".join(f"{v:.1f}" for v in q0) + "]")
    out.append("redundant_joints = true")
    for j in joints:
        out.append("\n[[model.constraints]]")
        out.append(f'expr = "{j}"')
    out.append("\n[integrator]")
    out.append(f'scheme = "{scheme}"')
    out.append("\n[time]")
    out.append(f"h = {h}")
    out.append(f"t_end = {t_end}")
    out.append("\n[output]")
    out.append("every = 10")
    out.append("probes = [3, 4, 5]                   # P3 = B: x, y, z")
    out.append("\n# Bounds for `signorini check` (the CI gate). The benchmark's reference solution of P3 is")
    out.append("# not reproduced here: the bounds are the ones the physics fixes, the joints held to")
    out.append("# Newton's tolerance with the redundant joint, and the energy kept.")
    out.append("[check]")
    out.append("max_position_residual = 1e-9")
    out.append("max_energy_growth = 1e-3")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    scheme = sys.argv[1] if len(sys.argv) > 1 else "soi2_generalized_alpha"
    h = float(sys.argv[2]) if len(sys.argv) > 2 else 1e-3
    t_end = float(sys.argv[3]) if len(sys.argv) > 3 else 10.0
    sys.stdout.write(spec(scheme, h, t_end))
