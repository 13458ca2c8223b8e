#!/usr/bin/env python3
"""Reference solution of IFToMM A05, the stiff flyball governor, independent of Signorini.

The equations of motion are written out by hand from the kinetic and potential energies stated
in a05_flyball_governor.toml (whose header derives them) and integrated by SciPy's Radau IIA
(order 5) and DOP853 at rtol = atol = 1e-12. Prints, as comments, both solutions' largest
difference at the check instants, then the spec's [[check.reference]] entries.

Coordinates: ps (shaft angle about the vertical z), th1, th2 (the rods' angles from the
downward vertical, outward positive), s (the slider's height).
Run: /usr/bin/python3 examples/benchmarks/flyball_governor.py (needs NumPy and SciPy).
"""
import math
import sys

import numpy as np
from scipy.integrate import solve_ivp

G = 9.81
RHO = 3000.0
M_BAR = RHO * 1.0 * 0.01 * 0.01          # shaft and rods: 1.0 x 0.01 x 0.01 m bricks, 0.3 kg
I_LONG = M_BAR / 3 * (0.005**2 + 0.5**2)  # about a transverse axis through the centre
I_AXIAL = M_BAR / 3 * (2 * 0.005**2)      # about the long axis
M_SLIDER = RHO * 0.1**3                  # 0.1 m cube, 3 kg
I_SLIDER = M_SLIDER / 3 * (2 * 0.05**2)
M_BALL = 5.0
K, C, L0 = 8e5, 4e4, 0.5
E = 0.05      # the rods' pins and the springs' slider ends are 0.05 m off the shaft's axis
H = 1.0       # height of the pins
A = 0.5       # the springs' rod ends: the rods' midpoints


def inertia_about_shaft(th):
    """The contribution of one rod and its ball to J, the inertia about the shaft's axis."""
    s, c = math.sin(th), math.cos(th)
    return (I_LONG * s * s + I_AXIAL * c * c + M_BAR * (E + A * s) ** 2
            + M_BALL * (E + s) ** 2)


def d_inertia_about_shaft(th):
    s, c = math.sin(th), math.cos(th)
    return (2 * (I_LONG - I_AXIAL) * s * c + 2 * M_BAR * (E + A * s) * A * c
            + 2 * M_BALL * (E + s) * c)


A_ROD = I_LONG + M_BAR * A * A + M_BALL   # the rod's and ball's inertia about the pin


def spring(th, s):
    """Length d of a spring and its derivatives ∂d/∂th, ∂d/∂s."""
    u, w = A * math.sin(th), H - A * math.cos(th) - s
    d = math.hypot(u, w)
    return d, (u * A * math.cos(th) + w * A * math.sin(th)) / d, -w / d


def rhs(_t, y):
    ps, th1, th2, s, dps, dth1, dth2, ds = y
    j = I_AXIAL + I_SLIDER + inertia_about_shaft(th1) + inertia_about_shaft(th2)
    dj1, dj2 = d_inertia_about_shaft(th1), d_inertia_about_shaft(th2)
    f_th, f_s = [0.0, 0.0], -M_SLIDER * G
    for k, (th, dth) in enumerate(((th1, dth1), (th2, dth2))):
        d, d_th, d_s = spring(th, s)
        rate = d_th * dth + d_s * ds
        tension = K * (d - L0) + C * rate          # the spring-damper's force along d
        gravity = (M_BAR * A + M_BALL * 1.0) * G * math.sin(th)
        f_th[k] = -tension * d_th - gravity
        f_s -= tension * d_s
    # ψ: d/dt (J ψ̇) = 0; θ_k: A θ̈_k = ½ ∂J/∂θ_k ψ̇² + f; s: m s̈ = f.
    ddps = -(dj1 * dth1 + dj2 * dth2) * dps / j
    ddth1 = (0.5 * dj1 * dps * dps + f_th[0]) / A_ROD
    ddth2 = (0.5 * dj2 * dps * dps + f_th[1]) / A_ROD
    dds = f_s / M_SLIDER
    return [dps, dth1, dth2, ds, ddps, ddth1, ddth2, dds]


CHECK_TIMES = [1.0, 2.5, 5.0, 7.5, 10.0]
# The spec's columns: q_3 = s, q_1 = th1, v_0 = ps_dot.
CHECK_COLUMNS = (("q_3", 3), ("q_1", 1), ("v_0", 4))


def main():
    y0 = [0.0, math.pi / 3, math.pi / 3, 0.5, 2 * math.pi, 0.0, 0.0, 0.0]
    times = sorted(set([0.5] + CHECK_TIMES))
    sols = {}
    for method in ("Radau", "DOP853"):
        # Radau's finite-difference Jacobian overflows in its trial steps on the stiff springs
        # (NumPy warns); the steps it keeps are unaffected: it agrees with DOP853 below.
        with np.errstate(over="ignore"):
            sol = solve_ivp(rhs, (0.0, 10.0), y0, method=method, t_eval=times, rtol=1e-12,
                            atol=1e-12)
        if not sol.success:
            sys.exit(f"{method}: {sol.message}")
        sols[method] = sol.y
    r, d = sols["Radau"], sols["DOP853"]
    print("# t      s (Radau)          th1                ps_dot             |Radau - DOP853|")
    for i, t in enumerate(times):
        print(f"# {t:5.1f}  {r[3, i]:.15f}  {r[1, i]:.15f}  {r[4, i]:.15f}  "
              f"{np.max(np.abs(r[:, i] - d[:, i])):.1e}")
    for t in CHECK_TIMES:
        i = times.index(t)
        for column, k in CHECK_COLUMNS:
            print(f"\n[[check.reference]]\ncolumn = \"{column}\"\nt = {t}\n"
                  f"value = {r[k, i]!r}\ntolerance = 1e-3")


if __name__ == "__main__":
    main()
