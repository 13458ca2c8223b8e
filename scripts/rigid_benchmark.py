#!/usr/bin/env python3
"""The 1 000-sphere rigid-body benchmark of issue 29 (docs/rigid_benchmark.md).

    /usr/bin/python3 scripts/rigid_benchmark.py write-spec      # examples/rigid/spheres_1000.toml
    /usr/bin/python3 scripts/rigid_benchmark.py run [--rounds R] [--steps N] [--siconos-steps N]

`run` builds the release bench once (cargo bench --no-run), then runs in rounds, interleaved, the
same scene (read from the TOML) in Signorini (crates/signorini-collision/benches/rigid_spheres.rs),
MuJoCo (pip `mujoco`, MJCF written here: elliptic cones, Newton solver) and Siconos 4.4
(`python3-siconos`, mechanics with Bullet collision, MoreauJeanOSI + NSGS), and prints one JSON
line per run with its wall time per step and contacts per step, then the load average. Ratios are
taken between runs of the same round only (the machine is shared).
"""

import json
import math
import os
import subprocess
import sys
import time
import tomllib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SPEC = os.path.join(ROOT, "examples", "rigid", "spheres_1000.toml")

# The scene: N = 10 × 10 × 10 spheres of radius R on a lattice of pitch 2.2 R, each nudged
# sideways by a deterministic jitter so the pile does not stay a lattice, above the floor of a
# square box of half width HALF (walls are half-spaces), poured under gravity.
R, DENSITY, HALF, PITCH = 0.05, 1000.0, 0.6, 0.11
MU, E, MARGIN, H, T_END = 0.3, 0.0, 5e-3, 1e-3, 2.0


def jitter(i):
    """A deterministic number in [-1, 1) (a linear congruential generator)."""
    x = (1103515245 * (i + 12345) + 12345) % 2**31
    return 2.0 * x / 2**31 - 1.0


def write_spec():
    lines = [
        "# 1 000 spheres poured into a box (issue 29, the scaling case): a 10 × 10 × 10 lattice of",
        "# balls (r = 5 cm, pitch 11 cm, nudged sideways by up to 4 mm) released at rest above the",
        "# floor of a 1.2 m square box, μ = 0.3, e = 0, 2 s at h = 1 ms. Written by",
        "# scripts/rigid_benchmark.py write-spec; the benchmark of docs/rigid_benchmark.md runs it",
        "# here and in MuJoCo and Siconos. What to look at: contacts growing as the pile settles,",
        "# max_penetration, energy falling to rest.",
        'name = "1000 spheres poured into a box"',
        "",
        "[model]",
        'scene = "rigid_bodies"',
        "",
        "[model.contact]",
        f"restitution = {E}",
        f"friction = {MU}",
        f"margin = {MARGIN}",
        "",
        "[integrator]",
        'scheme = "moreau_jean"',
        "",
        "[contact_solver]",
        "tolerance = 1e-6",
        "",
        "[time]",
        f"h = {H}",
        f"t_end = {T_END}",
        "",
        "[output]",
        "every = 100",
    ]
    k = 0
    for iz in range(10):
        for iy in range(10):
            for ix in range(10):
                x = (ix - 4.5) * PITCH + 0.004 * jitter(3 * k)
                y = (iy - 4.5) * PITCH + 0.004 * jitter(3 * k + 1)
                z = R + 0.01 + iz * PITCH
                lines += [
                    "",
                    "[[model.bodies]]",
                    f'name = "s{k}"',
                    f'shape = {{ kind = "sphere", radius = {R} }}',
                    f"density = {DENSITY}",
                    f"position = [{x:.6f}, {y:.6f}, {z:.6f}]",
                ]
                k += 1
    walls = [
        ("floor", [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
        ("wall_xm", [-HALF, 0.0, 0.0], [1.0, 0.0, 0.0]),
        ("wall_xp", [HALF, 0.0, 0.0], [-1.0, 0.0, 0.0]),
        ("wall_ym", [0.0, -HALF, 0.0], [0.0, 1.0, 0.0]),
        ("wall_yp", [0.0, HALF, 0.0], [0.0, -1.0, 0.0]),
    ]
    for name, p, n in walls:
        lines += [
            "",
            "[[model.bodies]]",
            f'name = "{name}"',
            f'shape = {{ kind = "half_space", normal = [{n[0]}, {n[1]}, {n[2]}] }}',
            f"position = [{p[0]}, {p[1]}, {p[2]}]",
        ]
    with open(SPEC, "w") as f:
        f.write("\n".join(lines) + "\n")


def scene():
    with open(SPEC, "rb") as f:
        spec = tomllib.load(f)
    spheres = [b for b in spec["model"]["bodies"] if b["shape"]["kind"] == "sphere"]
    return spec, spheres


def bench_binary():
    out = subprocess.run(
        ["cargo", "bench", "-p", "signorini-collision", "--bench", "rigid_spheres", "--no-run",
         "--message-format", "json"],
        cwd=ROOT, capture_output=True, text=True, check=True)
    for line in out.stdout.splitlines():
        msg = json.loads(line)
        if msg.get("reason") == "compiler-artifact" and msg["target"]["name"] == "rigid_spheres" \
                and msg.get("executable"):
            return msg["executable"]
    raise SystemExit("no bench executable")


def run_signorini(exe, steps):
    out = subprocess.run([exe, SPEC, "--steps", str(steps)], capture_output=True, text=True,
                         check=True)
    r = json.loads(out.stdout.strip().splitlines()[-1])
    return r


def run_mujoco(steps):
    import mujoco
    import numpy as np
    spec, spheres = scene()
    g = 9.81
    bodies = []
    for b in spheres:
        x, y, z = b["position"]
        bodies.append(
            f'<body pos="{x} {y} {z}"><freejoint/>'
            f'<geom type="sphere" size="{R}" density="{DENSITY}" friction="{MU} 0.005 0.0001"/></body>')
    walls = (f'<geom type="plane" size="{HALF} {HALF} 0.1" friction="{MU} 0.005 0.0001"/>'
             f'<geom type="box" pos="{-HALF - 0.05} 0 0.75" size="0.05 {HALF + 0.1} 0.75"/>'
             f'<geom type="box" pos="{HALF + 0.05} 0 0.75" size="0.05 {HALF + 0.1} 0.75"/>'
             f'<geom type="box" pos="0 {-HALF - 0.05} 0.75" size="{HALF + 0.1} 0.05 0.75"/>'
             f'<geom type="box" pos="0 {HALF + 0.05} 0.75" size="{HALF + 0.1} 0.05 0.75"/>')
    xml = (f'<mujoco><option timestep="{H}" gravity="0 0 {-g}" cone="elliptic" solver="Newton"/>'
           f'<worldbody>{walls}{"".join(bodies)}</worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    contacts = 0
    start = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(model, data)
        contacts += data.ncon
    seconds = time.perf_counter() - start
    return {"code": "mujoco", "version": mujoco.__version__, "steps": steps, "seconds": seconds,
            "ms_per_step": 1e3 * seconds / steps, "contacts_per_step": contacts / steps}


def run_siconos(steps):
    """Siconos 4.4 mechanics: NewtonEulerDS spheres, Bullet collision, MoreauJeanOSI(θ = ½),
    FrictionContact(3) solved by NSGS; the same scene through MechanicsHdf5Runner."""
    import tempfile
    from siconos.io.mechanics_run import MechanicsHdf5Runner
    import siconos.numerics as sn
    import siconos.kernel as sk
    from siconos.mechanics.collision.bullet import SiconosBulletOptions
    spec, spheres = scene()
    directory = tempfile.mkdtemp(prefix="siconos_spheres_")
    path = os.path.join(directory, "spheres.hdf5")
    mass = DENSITY * 4.0 / 3.0 * math.pi * R ** 3
    inertia = 0.4 * mass * R * R
    with MechanicsHdf5Runner(mode="w", io_filename=path) as io:
        io.add_primitive_shape("Ball", "Sphere", (R,))
        io.add_primitive_shape("Ground", "Box", (2 * HALF + 0.2, 2 * HALF + 0.2, 0.1))
        io.add_primitive_shape("WallX", "Box", (0.1, 2 * HALF + 0.2, 1.5))
        io.add_primitive_shape("WallY", "Box", (2 * HALF + 0.2, 0.1, 1.5))
        io.add_Newton_impact_friction_nsl("contact", mu=MU, e=E)
        io.add_object("ground", [sk.Contactor("Ground")], translation=[0, 0, -0.05])
        io.add_object("wxm", [sk.Contactor("WallX")], translation=[-HALF - 0.05, 0, 0.75])
        io.add_object("wxp", [sk.Contactor("WallX")], translation=[HALF + 0.05, 0, 0.75])
        io.add_object("wym", [sk.Contactor("WallY")], translation=[0, -HALF - 0.05, 0.75])
        io.add_object("wyp", [sk.Contactor("WallY")], translation=[0, HALF + 0.05, 0.75])
        for k, b in enumerate(spheres):
            io.add_object(f"s{k}", [sk.Contactor("Ball")], translation=b["position"],
                          velocity=[0, 0, 0, 0, 0, 0], mass=mass,
                          inertia=[inertia, inertia, inertia])
    options = SiconosBulletOptions()
    options.worldScale = 1.0
    options.contactBreakingThreshold = MARGIN
    solver = sk.SolverOptions(sn.SICONOS_FRICTION_3D_NSGS)
    solver.iparam[sn.SICONOS_IPARAM_MAX_ITER] = 1000
    solver.dparam[sn.SICONOS_DPARAM_TOL] = 1e-6
    with MechanicsHdf5Runner(mode="r+", io_filename=path) as io:
        start = time.perf_counter()
        io.run(with_timer=False, bullet_options=options, face_class=None, edge_class=None,
               t0=0, T=steps * H, h=H, theta=0.5, Newton_max_iter=1,
               set_external_forces=None, solver_options=solver, numerics_verbose=False,
               output_frequency=10 ** 9, verbose=False)
        seconds = time.perf_counter() - start
    return {"code": "siconos", "steps": steps, "seconds": seconds,
            "ms_per_step": 1e3 * seconds / steps}


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "write-spec":
        write_spec()
        return
    args = sys.argv[2:]

    def opt(name, default):
        return int(args[args.index(name) + 1]) if name in args else default

    rounds, steps = opt("--rounds", 2), opt("--steps", int(round(T_END / H)))
    siconos_steps = opt("--siconos-steps", steps)
    codes = [c for c in ("signorini", "mujoco", "siconos") if f"--no-{c}" not in args]
    exe = bench_binary() if "signorini" in codes else None
    for r in range(rounds):
        for code in codes:
            try:
                if code == "signorini":
                    res = run_signorini(exe, steps)
                elif code == "mujoco":
                    res = run_mujoco(steps)
                else:
                    res = run_siconos(siconos_steps)
            except Exception as e:  # a failed code is reported, not hidden
                res = {"code": code, "error": repr(e)}
            res["round"] = r
            res["load_average"] = os.getloadavg()
            print(json.dumps(res), flush=True)


if __name__ == "__main__":
    main()
