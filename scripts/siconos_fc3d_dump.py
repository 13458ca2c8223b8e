#!/usr/bin/env python3
"""Siconos' FC3D solvers on a friction problem the rigid bench dumped (docs/rigid_benchmark.md).

    /usr/bin/python3 scripts/siconos_fc3d_dump.py FILE.dat [SOLVER ...] [--tolerance T]
        [--max-iterations N] [--shuffle]

FILE.dat is a Siconos `.dat` problem (W, q, μ) as the bench's `--dump K FILE` writes it, and
FILE.dat.start the warm start the time step gave its own solver (one number a line); every
solve starts from it. SOLVER names Siconos' `SICONOS_FRICTION_3D_<SOLVER>` (default NSGS; e.g.
NSGS ADMM VI_EG NSN_AC PROX). `--shuffle` visits the contacts in a random order in NSGS
(`SICONOS_FRICTION_3D_NSGS_SHUFFLE`). Prints one JSON line per solver: Siconos' return code
(0: converged), its iterations, its error (the same relative natural-map error as
`signorini solve`) and the seconds, so that a problem `signorini solve` does not solve can be
tried with the reference code's solvers on the same data. Needs Debian's python3-siconos.
"""

import json
import sys
import time

import numpy as np
import siconos.numerics as sn


def main():
    args = sys.argv[1:]
    if not args or args[0].startswith("-"):
        sys.exit(__doc__)
    path, solvers = args[0], []
    tolerance, max_iterations, shuffle = 1e-6, 2000, False
    rest = iter(args[1:])
    for a in rest:
        if a == "--tolerance":
            tolerance = float(next(rest))
        elif a == "--max-iterations":
            max_iterations = int(next(rest))
        elif a == "--shuffle":
            shuffle = True
        else:
            solvers.append(a)
    problem = sn.frictionContact_new_from_filename(path)
    start = np.loadtxt(path + ".start")
    for name in solvers or ["NSGS"]:
        options = sn.SolverOptions(getattr(sn, "SICONOS_FRICTION_3D_" + name))
        options.iparam[sn.SICONOS_IPARAM_MAX_ITER] = max_iterations
        options.dparam[sn.SICONOS_DPARAM_TOL] = tolerance
        if shuffle and name == "NSGS":
            options.iparam[sn.SICONOS_FRICTION_3D_NSGS_SHUFFLE] = 1
        r, u = start.copy(), np.zeros_like(start)
        t0 = time.perf_counter()
        info = sn.fc3d_driver(problem, r, u, options)
        print(json.dumps({
            "file": path, "solver": name, "shuffle": shuffle and name == "NSGS",
            "contacts": int(problem.numberOfContacts), "info": int(info),
            "iterations": int(options.iparam[sn.SICONOS_IPARAM_ITER_DONE]),
            "error": float(options.dparam[sn.SICONOS_DPARAM_RESIDU]),
            "seconds": time.perf_counter() - t0}), flush=True)


if __name__ == "__main__":
    main()
