#!/usr/bin/python3
"""Siconos' friction test problems solved by our FC3D solvers (`signorini solve`) and by Siconos'
own (python3-siconos 4.4: fc3d_driver / fc2d_driver), at two tolerances; success and time per
problem, errors of both recomputed by one function (scripts/friction_fixtures.py's
natural_map_error, Siconos' formula), Dolan–Moré performance profiles drawn as SVG.

Usage:
  /usr/bin/python3 scripts/friction_benchmark.py --data DIR --bin target/release/signorini --out OUT
    [--timeout 20] [--tolerances 1e-8 1e-4] [--repeat 20 --repeat-below 0.1]

DIR holds the problem files (Siconos' numerics/src/FrictionContact/test/data/: `git show` them out
of a clone of github.com/siconos/siconos). Our time is the time `signorini solve` measures around
the core's solve alone (the core is compiled at opt-level 3 in every profile); Siconos' is the
wall time of the driver call. Each solve runs in its own process, killed after --timeout seconds
(a timeout counts as a failure). A solve succeeds when the recomputed error is <= the tolerance.
With --repeat N, a solve whose first run took less than --repeat-below seconds is run N times in
its process, on both sides alike (ours: `signorini solve --repeat N`; Siconos': the driver called
N times, each from r = u = 0 with fresh options), and its time is the fastest run: a first call
in a fresh process also pays for faulting in code and memory (40 µs for our one-contact solve
of 1.5 µs of work), which a time-stepping loop pays once.
Writes OUT/results.json, OUT/profile_TOL.svg and prints the tables of docs/friction_benchmark.md.
"""
import argparse
import json
import math
import multiprocessing as mp
import pathlib
import subprocess
import sys
import tempfile
import time

import h5py
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from friction_fixtures import natural_map_error, sparse  # noqa: E402

OURS = ["auto", "nsgs", "nsgs_aa", "nsn_ac", "prox"]
THEIRS = {
    "NSGS": "SICONOS_FRICTION_3D_NSGS",
    "NSN-AC": "SICONOS_FRICTION_3D_NSN_AC",
    "NSN-FB": "SICONOS_FRICTION_3D_NSN_FB",
    "PROX": "SICONOS_FRICTION_3D_PROX",
}
THEIRS_2D = {"NSGS": "SICONOS_FRICTION_2D_NSGS"}
# Smallest time a ratio or a profile takes: both sides time with nanosecond clocks
# (Rust's Instant, Python's perf_counter), and a repeated solve of one contact takes 0.5 µs.
TIMER_FLOOR = 1e-8


def problem_set(name):
    """The family a problem belongs to (the sets of the note's tables)."""
    for prefix in ["Rover", "Capsules", "Confeti", "NESpheres", "BoxesStack", "KaplasTower",
                   "RockPile", "OneObject", "FrictionContactProblem", "fc2d_granular",
                   "FC2D_SliderCrank", "LMGC", "Spheres", "spheres", "Box_Stacks", "FC3D_Example",
                   "FrictionContact3D"]:
        if name.startswith(prefix):
            return prefix
    return "other"


def read_problem(path):
    """(d, W, q, mu) by Siconos' reader (.dat; W sparse) or h5py (FCLib; W dense)."""
    with open(path, "rb") as f:
        magic = f.read(8)
    if magic == b"\x89HDF\r\n\x1a\n":
        f = h5py.File(path, "r")
        if "fclib_local" in f:
            g = f["fclib_local"]
            return int(g["spacedim"][0]), sparse(g["W"]), np.array(g["vectors/q"]), np.array(g["vectors/mu"])
        g = f["fclib_global"]
        m, h = sparse(g["M"]), sparse(g["H"])
        minv = np.diag(1.0 / np.diag(m))
        q = h.T @ minv @ np.array(g["vectors/f"]) + np.array(g["vectors/w"])
        return int(g["spacedim"][0]), h.T @ minv @ h, q, np.array(g["vectors/mu"])
    # Siconos' reader crashes the process on a file that is not a local problem: check the header
    # (d, nc, storage, rows, columns) first.
    head = path.read_text(errors="replace").split()[:5]
    try:
        d, nc, _, rows, columns = (int(x) for x in head)
    except ValueError:
        raise ValueError("not a friction problem header")
    if d not in (2, 3) or rows != d * nc or columns != d * nc:
        raise ValueError(f"header d={d} nc={nc} W {rows}x{columns}: not a local problem")
    import scipy.sparse  # noqa: F401  (Siconos' NM_triplet returns a scipy matrix)
    import siconos.numerics as sn
    p = sn.frictionContact_new_from_filename(str(path))
    return p.dimension, sn.NM_triplet(p.M).tocsr(), np.array(p.q), np.array(p.mu)


def siconos_worker(path, solver, tolerance, repeat, repeat_below, queue):
    import siconos.numerics as sn
    p = sn.frictionContact_new_from_filename(str(path))
    n = p.dimension * p.numberOfContacts
    ids = THEIRS if p.dimension == 3 else THEIRS_2D
    runs = []
    while True:
        r, u = np.zeros(n), np.zeros(n)
        options = sn.SolverOptions(getattr(sn, ids[solver]))
        options.dparam[sn.SICONOS_DPARAM_TOL] = tolerance
        options.iparam[sn.SICONOS_IPARAM_MAX_ITER] = 100000
        start = time.perf_counter()
        try:
            if p.dimension == 3:
                info = sn.fc3d_driver(p, r, u, options)
            else:
                info = sn.fc2d_driver(p, r, u, options)
        except RuntimeError as e:
            # fc2d_driver refuses W in CSparse storage (the granular-flow problems).
            queue.put({"refused": str(e).splitlines()[0][:200]})
            return
        runs.append(time.perf_counter() - start)
        if len(runs) >= repeat or runs[0] >= repeat_below:
            break
    queue.put({"info": int(info), "seconds": min(runs), "seconds_first": runs[0],
               "repeat": len(runs), "r": r.tolist(),
               "iterations": int(options.iparam[sn.SICONOS_IPARAM_ITER_DONE])})


def run_siconos(path, solver, tolerance, timeout, repeat=1, repeat_below=0.0):
    queue = mp.Queue()
    proc = mp.Process(target=siconos_worker,
                      args=(path, solver, tolerance, repeat, repeat_below, queue))
    proc.start()
    try:
        result = queue.get(timeout=timeout)
    except Exception:
        result = None
    proc.join(1)
    if proc.is_alive():
        proc.kill()
    return result


def run_ours(binary, path, solver, tolerance, timeout, out, repeat=1, repeat_below=0.0):
    first = run_ours_once(binary, path, solver, tolerance, timeout, out, 1)
    if repeat > 1 and first and first.get("seconds", math.inf) < repeat_below:
        again = run_ours_once(binary, path, solver, tolerance, timeout, out, repeat)
        if again:
            again["seconds_first"] = first["seconds"]
            return again
    return first


def run_ours_once(binary, path, solver, tolerance, timeout, out, repeat):
    try:
        done = subprocess.run([binary, "solve", str(path), "--json", "--solver", solver,
                               "--tolerance", repr(tolerance), "--out", str(out),
                               "--repeat", str(repeat)],
                              capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return None
    lines = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
    if not lines:
        return {"error_message": done.stderr.strip()[-300:]}
    line = lines[0]
    stem = path.name[:-len(path.suffix)] if path.suffix else path.name
    if stem.endswith(".hdf5"):
        stem = stem[:-5]
    solution = out / f"{stem}.hdf5"
    r = None
    if line["converged"] and solution.exists():
        r = np.array(h5py.File(solution, "r")["solution/r"]).tolist()
        solution.unlink()
    return {"seconds": line["seconds"], "iterations": line["iterations"], "solver": line["solver"],
            "converged": line["converged"], "r": r}


def profile_svg(results, tolerance, solvers, path):
    """Dolan–Moré: rho_s(tau) = share of problems solved within tau x the best time."""
    problems = sorted({k for k in results})
    best = {}
    for p in problems:
        times = [results[p][s]["seconds"] for s in solvers if results[p].get(s, {}).get("ok")]
        if times:
            best[p] = max(min(times), TIMER_FLOOR)
    taus = np.logspace(0, 4, 200)
    width, height, left, bottom = 640, 400, 60, 40
    colours = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2"]
    lines = []
    for k, s in enumerate(solvers):
        ratios = [results[p][s]["seconds"] / best[p] if results[p].get(s, {}).get("ok") else math.inf
                  for p in problems if p in best]
        total = len(problems)
        pts = []
        for t in taus:
            rho = sum(1 for r in ratios if r <= t) / total
            x = left + (width - left - 20) * math.log10(t) / 4
            y = height - bottom - (height - bottom - 20) * rho
            pts.append(f"{x:.1f},{y:.1f}")
        lines.append(f'<polyline fill="none" stroke="{colours[k % len(colours)]}" stroke-width="2" '
                     f'points="{" ".join(pts)}"/>'
                     f'<text x="{width - 150}" y="{40 + 16 * k}" fill="{colours[k % len(colours)]}" '
                     f'font-size="12">{s}</text>')
    axes = (f'<line x1="{left}" y1="{height - bottom}" x2="{width - 20}" y2="{height - bottom}" stroke="black"/>'
            f'<line x1="{left}" y1="20" x2="{left}" y2="{height - bottom}" stroke="black"/>')
    ticks = "".join(
        f'<text x="{left + (width - left - 20) * e / 4 - 8:.0f}" y="{height - bottom + 16}" font-size="11">1e{e}</text>'
        for e in range(5)) + "".join(
        f'<text x="{left - 30}" y="{height - bottom - (height - bottom - 20) * v + 4:.0f}" font-size="11">{v:.1f}</text>'
        for v in [0, 0.25, 0.5, 0.75, 1.0])
    title = (f'<text x="{left}" y="14" font-size="13">Performance profile at tolerance {tolerance:g}: '
             f'share of {len(problems)} problems solved within tau x the best time</text>')
    path.write_text(f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}">'
                    f'{title}{axes}{ticks}{"".join(lines)}'
                    f'<text x="{width / 2:.0f}" y="{height - 6}" font-size="12">tau</text></svg>\n')


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", required=True, type=pathlib.Path)
    ap.add_argument("--bin", required=True)
    ap.add_argument("--out", required=True, type=pathlib.Path)
    ap.add_argument("--timeout", type=float, default=20.0)
    ap.add_argument("--tolerances", type=float, nargs="+", default=[1e-8, 1e-4])
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--repeat", type=int, default=1,
                    help="runs of a short solve, both sides (the fastest counts)")
    ap.add_argument("--repeat-below", type=float, default=0.1,
                    help="a solve whose first run took less than this many seconds is repeated")
    ap.add_argument("--ours", nargs="*", default=OURS, help="our solvers to run")
    ap.add_argument("--report-only", action="store_true",
                    help="only merge the existing results_*.json, draw and print the tables")
    ap.add_argument("--side", choices=["ours", "siconos", "both"], default="both",
                    help="run one side only (results_SIDE.json); the profiles merge what exists")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    files = sorted(p for p in args.data.iterdir() if p.suffix in (".dat", ".hdf5")
                   # Global problems in Siconos' text format (GFC3D_*, gfc2d_*): no reader here.
                   and not p.name.lower().startswith(("gfc3d", "gfc2d")))
    if args.report_only:
        files = []
    if args.only:
        files = [p for p in files if p.name in args.only]
    everything = {}
    scratch = pathlib.Path(tempfile.mkdtemp())
    for path in files:
        try:
            d, w, q, mu = read_problem(path)
        except Exception as e:  # a global .dat problem or a file Siconos cannot read
            print(f"skip {path.name}: {e}", file=sys.stderr)
            continue
        if w.shape[0] != d * len(mu):
            print(f"skip {path.name}: not a local problem", file=sys.stderr)
            continue
        for tolerance in args.tolerances:
            row = {}
            for solver in (args.ours if args.side != "siconos" else []):
                res = run_ours(args.bin, path, solver, tolerance, args.timeout, scratch,
                               args.repeat, args.repeat_below)
                if res and res.get("r") is not None:
                    r = np.array(res["r"])
                    res["error"] = float(natural_map_error(d, w, q, mu, r))
                    res["ok"] = bool(res["error"] <= tolerance)
                elif res is not None:
                    res["ok"] = False
                row[f"ours {solver}"] = {k: v for k, v in (res or {"timeout": True, "ok": False}).items() if k != "r"}
            is_hdf5 = path.suffix == ".hdf5"
            for solver in (THEIRS if d == 3 else THEIRS_2D):
                if is_hdf5 or args.side == "ours":
                    break  # this Siconos build has no FCLib reader
                res = run_siconos(path, solver, tolerance, args.timeout, args.repeat,
                                  args.repeat_below)
                if res is not None and "refused" in res:
                    res["ok"] = False
                elif res is not None:
                    r = np.array(res["r"])
                    res["error"] = float(natural_map_error(d, w, q, mu, r))
                    res["ok"] = bool(res["error"] <= tolerance)
                row[f"siconos {solver}"] = {k: v for k, v in (res or {"timeout": True, "ok": False}).items() if k != "r"}
            everything.setdefault(str(tolerance), {})[path.name] = {
                "set": problem_set(path.name), "dimension": d, "contacts": len(mu), **row}
            print(path.name, tolerance, {k: (v.get("ok"), round(v.get("seconds", -1), 4)) for k, v in row.items()},
                  flush=True)
    if not args.report_only:
        (args.out / f"results_{args.side}.json").write_text(json.dumps(everything, indent=1))
    merged = {}
    for side in ["ours", "siconos", "both"]:
        f = args.out / f"results_{side}.json"
        if f.exists():
            for tol, problems in json.loads(f.read_text()).items():
                for name, row in problems.items():
                    merged.setdefault(tol, {}).setdefault(name, {}).update(row)
    (args.out / "results.json").write_text(json.dumps(merged, indent=1))
    for tolerance, results in merged.items():
        solvers = sorted({s for p in results.values() for s in p if s.startswith(("ours", "siconos"))})
        profile_svg(results, float(tolerance), solvers, args.out / f"profile_{tolerance}.svg")
        tables(results, tolerance, solvers)


def tables(results, tolerance, solvers):
    """Markdown: solved counts per set and solver; geometric mean of (our best time / Siconos'
    best time) per set over the problems both solved."""
    sets = sorted({row["set"] for row in results.values()})
    print(f"\n### Tolerance {tolerance}\n")
    print("| set | problems | " + " | ".join(solvers) + " | ours/Siconos best time (geo. mean) |")
    print("|---|---|" + "---|" * len(solvers) + "---|")
    for st in sets + ["all"]:
        rows = [r for r in results.values() if st in ("all", r["set"])]
        counts = [sum(1 for r in rows if r.get(s, {}).get("ok")) for s in solvers]
        ratios = []
        for r in rows:
            ours = [r[s]["seconds"] for s in solvers if s.startswith("ours") and r.get(s, {}).get("ok")]
            theirs = [r[s]["seconds"] for s in solvers if s.startswith("siconos") and r.get(s, {}).get("ok")]
            if ours and theirs:
                ratios.append(max(min(ours), TIMER_FLOOR) / max(min(theirs), TIMER_FLOOR))
        geo = f"{math.exp(sum(math.log(x) for x in ratios) / len(ratios)):.3g} ({len(ratios)})" if ratios else "–"
        print(f"| {st} | {len(rows)} | " + " | ".join(map(str, counts)) + f" | {geo} |")


if __name__ == "__main__":
    main()
