#!/usr/bin/env python3
"""The 1 000-sphere rigid-body benchmark of issue 29 (docs/rigid_benchmark.md).

    /usr/bin/python3 scripts/rigid_benchmark.py write-spec      # examples/rigid/spheres_1000.toml
    /usr/bin/python3 scripts/rigid_benchmark.py run [--rounds R] [--steps N] [--siconos-steps N]
        [--tolerances T1,T2,..] [--siconos-tolerance T] [--mujoco-solvers CG,Newton,PGS]
        [--no-signorini] [--no-mujoco] [--no-siconos]
    /usr/bin/python3 scripts/rigid_benchmark.py one mujoco STEPS [SOLVER]
    /usr/bin/python3 scripts/rigid_benchmark.py one siconos STEPS [TOLERANCE]

`run` builds the release bench once (cargo bench --no-run), then runs in rounds, one code after
the other, the same scene (read from the TOML) in Signorini
(crates/signorini-collision/benches/rigid_spheres.rs), MuJoCo (pip `mujoco`, MJCF written here:
elliptic cones, CG by default: its Newton solver's cost per step grows without bound on this
scene) and Siconos 4.4 (`python3-siconos`, mechanics with Bullet collision, MoreauJeanOSI + NSGS),
MuJoCo and Siconos each in a child process (`one`), and prints one JSON line per run: wall time
per step, contacts per step, solver iterations, energy at the start and the end, the load
average. Ratios are taken between runs of the same round only (the machine is shared).
`--tolerances` runs Signorini once per FC3D tolerance (the bench's `--tolerance T --accept-error
none`: every step solved to T, or the run fails), by default once with the spec's settings;
Siconos' NSGS runs at `--siconos-tolerance` (default the spec's `contact_solver.tolerance`).
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
        "# energy falling to rest, max_penetration staying 0 (a contact's velocity condition holds",
        "# from the 5 mm margin on: spheres stop within that distance of each other, before they",
        "# touch; see [model.contact]).",
        'name = "1000 spheres poured into a box"',
        "",
        "[model]",
        'scene = "rigid_bodies"',
        "",
        "[model.contact]",
        f"restitution = {E}",
        f"friction = {MU}",
        "# 5 mm finds the fastest spheres (about 4.6 m/s at landing) a step before they touch.",
        "# A contact enters the index set at predicted gap ≤ margin, so the pile stands on gaps",
        "# of up to 5 mm; with `activation = \"predicted_gap\"` in [integrator] (Siconos' rule,",
        "# ≤ 0) the spheres touch and the impacts leave up to 1.3 mm of penetration, and the",
        "# energy at 2 s is 1 761 J instead of 2 075 J (docs/rigid_benchmark.md, Round 20).",
        f"margin = {MARGIN}",
        "",
        "[integrator]",
        'scheme = "moreau_jean"',
        "",
        "[contact_solver]",
        "# Each step's friction problem is solved to 1e-3, Siconos' relative error of the",
        "# natural map (‖r − P_K(r − û)‖ / max(‖q‖, ‖r‖, ‖u‖)): contact stays hard (no",
        "# compliance) and the energy ledger closes at any tolerance; the tolerance bounds how",
        "# far each step's impulses are from Coulomb's law. The whole 2 s took 23 s at 1e-3,",
        "# 400 s at 1e-4 (the settling pile's problems need thousands of sweeps) and about an",
        "# hour at 1e-6 (with `accept_error = 1e-4`: 730 steps of the settling pile ended",
        "# within 1e-4 only); the energy at 2 s is 2 069–2 075 J at every tolerance",
        "# (docs/rigid_benchmark.md, Rounds 18 and 20).",
        "tolerance = 1e-3",
        "max_iterations = 10000",
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


def run_signorini(exe, steps, extra=()):
    out = subprocess.run([exe, SPEC, "--steps", str(steps), *extra], capture_output=True,
                         text=True, check=True)
    r = json.loads(out.stdout.strip().splitlines()[-1])
    return r


def sphere_energy(mass, inertia, positions, velocities, spins):
    """Σ ½ m‖v‖² + ½ I‖Ω‖² + m g z over the spheres (the energy of Signorini's `energy` column,
    potential −m g·x with g = (0, 0, −9.81))."""
    e = 0.0
    for (_, _, z), v, w in zip(positions, velocities, spins):
        e += 0.5 * mass * sum(x * x for x in v) + 0.5 * inertia * sum(x * x for x in w)
        e += mass * 9.81 * z
    return e


def run_mujoco(steps, solver="CG"):
    """MuJoCo: the same spheres as free bodies in MJCF, elliptic cones, `solver` (CG by
    default: Newton's cost per step grows without bound on this scene, docs/rigid_benchmark.md)."""
    import mujoco
    spec, spheres = scene()
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
    xml = (f'<mujoco><option timestep="{H}" gravity="0 0 -9.81" cone="elliptic" '
           f'solver="{solver}"/>'
           f'<worldbody>{walls}{"".join(bodies)}</worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mass = float(model.body_mass[1])
    inertia = float(model.body_inertia[1][0])

    def energy():
        q = data.qpos.reshape(-1, 7)
        v = data.qvel.reshape(-1, 6)
        return sphere_energy(mass, inertia, q[:, :3].tolist(), v[:, :3].tolist(),
                             v[:, 3:].tolist())

    e0 = energy()
    contacts, max_contacts, depth, iterations = 0, 0, 0.0, 0
    start = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(model, data)
        contacts += data.ncon
        max_contacts = max(max_contacts, data.ncon)
        iterations += int(data.solver_niter[0])
        if data.ncon:
            depth = max(depth, -float(data.contact.dist[:data.ncon].min()))
    seconds = time.perf_counter() - start
    return {"code": "mujoco", "version": mujoco.__version__, "solver": solver, "steps": steps,
            "seconds": seconds, "ms_per_step": 1e3 * seconds / steps,
            "contacts_per_step": contacts / steps, "max_contacts": max_contacts,
            "solver_iterations_per_step": iterations / steps, "max_penetration": depth,
            "energy_start": e0, "energy_end": energy()}


def spec_tolerance():
    """The FC3D tolerance of the committed scene (`contact_solver.tolerance`)."""
    with open(SPEC, "rb") as f:
        return float(tomllib.load(f)["contact_solver"]["tolerance"])


def run_siconos(steps, tolerance):
    """Siconos 4.4 mechanics: NewtonEulerDS spheres, Bullet collision, MoreauJeanOSI(θ = ½),
    FrictionContact(3) solved by NSGS at `tolerance` (at most 1 000 iterations); the same scene
    through MechanicsHdf5Runner."""
    import tempfile
    from siconos.io.mechanics_run import MechanicsHdf5Runner
    import siconos.numerics as sn
    import siconos.kernel as sk
    from siconos.mechanics.collision.bullet import SiconosBulletOptions
    from siconos.mechanics.collision.tools import Contactor
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
        io.add_object("ground", [Contactor("Ground")], translation=[0, 0, -0.05])
        io.add_object("wxm", [Contactor("WallX")], translation=[-HALF - 0.05, 0, 0.75])
        io.add_object("wxp", [Contactor("WallX")], translation=[HALF + 0.05, 0, 0.75])
        io.add_object("wym", [Contactor("WallY")], translation=[0, -HALF - 0.05, 0.75])
        io.add_object("wyp", [Contactor("WallY")], translation=[0, HALF + 0.05, 0.75])
        for k, b in enumerate(spheres):
            io.add_object(f"s{k}", [Contactor("Ball")], translation=b["position"],
                          velocity=[0, 0, 0, 0, 0, 0], mass=mass,
                          inertia=[inertia, inertia, inertia])
    options = SiconosBulletOptions()
    options.worldScale = 1.0
    options.contactBreakingThreshold = MARGIN
    # The kernel's wrapper of the options (the numerics one is refused by FrictionContact's
    # constructor in the Debian 4.4 bindings).
    solver = sk.solver_options_create(sn.SICONOS_FRICTION_3D_NSGS)
    solver.iparam[sn.SICONOS_IPARAM_MAX_ITER] = 1000
    solver.dparam[sn.SICONOS_DPARAM_TOL] = tolerance
    stats = {"contacts": 0, "max_contacts": 0, "iterations": 0, "residual_max": 0.0,
             "first": None, "last": None, "steps": 0}

    def energy(io):
        e = 0.0
        dss = io._nsds.dynamicalSystemsVector()
        for ds in dss:
            ds = sk.cast_NewtonEulerDS(ds)
            q, v = ds.q(), ds.twist()
            e += sphere_energy(mass, inertia, [q[:3]], [v[:3]], [v[3:]])
        return e, len(dss)

    def after_step(io):
        stats["last"] = time.perf_counter()
        if stats["first"] is None:
            stats["first"] = stats["last"]
        problem = io._simulation.oneStepNSProblem(0)
        m = problem.getSizeOutput() // 3
        stats["contacts"] += m
        stats["max_contacts"] = max(stats["max_contacts"], m)
        iterations, residual = 0, 0.0
        if m:
            so = problem.numericsSolverOptions()
            iterations = so.iparam[sn.SICONOS_IPARAM_ITER_DONE]
            residual = so.dparam[sn.SICONOS_DPARAM_RESIDU]
            stats["iterations"] += iterations
            stats["residual_max"] = max(stats["residual_max"], residual)
        stats["steps"] += 1
        # Progress on stderr, a line a step: a run stopped early still says how far it got.
        print(json.dumps({"step": stats["steps"], "contacts": int(m), "iterations": int(iterations),
                          "residual": float(residual), "seconds": stats["last"] - stats["first"]}),
              file=sys.stderr, flush=True)

    with MechanicsHdf5Runner(mode="r+", io_filename=path) as io:
        io.run(with_timer=False, bullet_options=options, face_class=None, edge_class=None,
               t0=0, T=steps * H, h=H, theta=0.5, Newton_max_iter=1,
               set_external_forces=None, solver_options=solver, numerics_verbose=False,
               output_frequency=10 ** 9, verbose=False, verbose_progress=False,
               end_run_iteration_hook=after_step)
        # Steps 2 to N only: the runner imports the scene's 1 005 objects into the simulation
        # during its first step (about 2 s), which is set-up, not stepping.
        seconds = stats["last"] - stats["first"]
        e1, bodies = energy(io)
    e0 = sum(sphere_energy(mass, inertia, [b["position"]], [[0, 0, 0]], [[0, 0, 0]])
             for b in spheres)
    return {"code": "siconos", "steps": steps, "tolerance": tolerance, "seconds": seconds,
            "ms_per_step": 1e3 * seconds / (steps - 1), "bodies": bodies,
            "contacts_per_step": stats["contacts"] / steps, "max_contacts": stats["max_contacts"],
            "solver_iterations_per_step": stats["iterations"] / steps,
            "residual_max": stats["residual_max"], "energy_start": e0, "energy_end": e1}


def run_one(code, steps, args):
    """One code in a child process, so that each gets a fresh interpreter and memory."""
    cmd = [sys.executable, os.path.abspath(__file__), "one", code, str(steps), *args]
    out = subprocess.run(cmd, capture_output=True, text=True)
    lines = [l for l in out.stdout.splitlines() if l.startswith("{")]
    if out.returncode != 0 or not lines:
        return {"code": code, "error": (out.stderr or out.stdout).strip()[-600:]}
    return json.loads(lines[-1])


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "write-spec":
        write_spec()
        return
    if len(sys.argv) > 1 and sys.argv[1] == "one":
        code, steps = sys.argv[2], int(sys.argv[3])
        if code == "mujoco":
            res = run_mujoco(steps, sys.argv[4] if len(sys.argv) > 4 else "CG")
        elif code == "siconos":
            res = run_siconos(steps, float(sys.argv[4]) if len(sys.argv) > 4 else spec_tolerance())
        else:
            raise SystemExit(f"unknown code {code}")
        print(json.dumps(res), flush=True)
        return
    args = sys.argv[2:]

    def opt(name, default):
        return args[args.index(name) + 1] if name in args else default

    rounds, steps = int(opt("--rounds", 2)), int(opt("--steps", int(round(T_END / H))))
    siconos_steps = int(opt("--siconos-steps", steps))
    mujoco_solvers = opt("--mujoco-solvers", "CG").split(",")
    tolerances = opt("--tolerances", "")
    tolerances = tolerances.split(",") if tolerances else [None]
    siconos_tolerance = opt("--siconos-tolerance", str(spec_tolerance()))
    codes = [c for c in ("signorini", "mujoco", "siconos") if f"--no-{c}" not in args]
    exe = bench_binary() if "signorini" in codes else None
    for r in range(rounds):
        runs = []
        for code in codes:
            if code == "signorini":
                for t in tolerances:
                    extra = [] if t is None else ["--tolerance", t, "--accept-error", "none"]
                    runs.append(("signorini", lambda e=extra: run_signorini(exe, steps, e)))
            elif code == "mujoco":
                for solver in mujoco_solvers:
                    runs.append(("mujoco", lambda s=solver: run_one("mujoco", steps, [s])))
            else:
                runs.append(("siconos", lambda: run_one("siconos", siconos_steps,
                                                        [siconos_tolerance])))
        for code, run in runs:
            try:
                res = run()
            except Exception as e:  # a failed code is reported, not hidden
                res = {"code": code, "error": repr(e)}
            res["round"] = r
            res["load_average"] = os.getloadavg()
            print(json.dumps(res), flush=True)


if __name__ == "__main__":
    main()
