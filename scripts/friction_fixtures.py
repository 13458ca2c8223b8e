#!/usr/bin/python3
"""Reference values of the friction problem fixtures (tests/fixtures/friction/), as Siconos reads them.

`.dat` files are read by Siconos' own reader (python3-siconos 4.4:
`frictionContact_new_from_filename`), and solved by Siconos' NSGS at 1e-10 so that the test can
check that our error function gives Siconos' error at Siconos' solution. The Debian build of
Siconos has no FCLib interface, so the HDF5 files are read with h5py, following fclib.c's layout
(global problems reduced to W = H^T M^-1 H, q = H^T M^-1 f + w, as Siconos'
globalFrictionContact_reformulation_FrictionContact does).

Usage: /usr/bin/python3 scripts/friction_fixtures.py  (writes tests/fixtures/friction/siconos_values.json)
"""
import json
import pathlib

import h5py
import numpy as np
import siconos.numerics as sn

HERE = pathlib.Path(__file__).resolve().parent.parent / "tests" / "fixtures" / "friction"


def project_cone(mu, x):
    """Euclidean projection on {|x_t| <= mu x_n} (Siconos' projectionOnCone)."""
    n, t = x[0], x[1:]
    tn = np.linalg.norm(t)
    if tn <= mu * n:
        return x.copy()
    if mu * tn <= -n:
        return np.zeros_like(x)
    a = (n + mu * tn) / (1.0 + mu * mu)
    return np.concatenate(([a], mu * a * t / tn))


def natural_map_error(d, w, q, mu, r):
    """||r - P_K(r - (u + mu |u_t| e_n))|| / max(||q||, ||r||, ||u||), u = W r + q: Siconos'
    fc2d_compute_error / fc3d_compute_error, written again (python3-siconos does not wrap the 2D one)."""
    u = w @ r + q
    total = 0.0
    for c in range(len(mu)):
        rc, uc = r[d * c:d * c + d], u[d * c:d * c + d]
        x = rc - uc
        x[0] -= mu[c] * np.linalg.norm(uc[1:])
        total += float(np.sum((rc - project_cone(mu[c], x)) ** 2))
    scale = max(np.linalg.norm(q), np.linalg.norm(r), np.linalg.norm(u))
    error = np.sqrt(total)
    return error / scale if scale > np.finfo(float).eps else error


def sample_positions(n):
    """A few (row, column) positions: corners, the first block, and a spread of diagonal ones."""
    picks = [(0, 0), (1, 0), (0, 1), (1, 1), (n - 1, n - 1), (n - 2, n - 1)]
    picks += [(k, k) for k in range(0, n, max(1, n // 7))]
    return sorted(set(picks))


def from_dat(path):
    p = sn.frictionContact_new_from_filename(str(path))
    d, nc = p.dimension, p.numberOfContacts
    n = d * nc
    q = np.array(p.q)
    mu = np.array(p.mu)
    frob = 0.0
    dense = np.zeros((n, n))
    for i in range(n):
        for j in range(n):
            dense[i, j] = sn.NM_get_value(p.M, i, j)
    frob = float(np.linalg.norm(dense))
    entries = [[i, j, float(dense[i, j])] for i, j in sample_positions(n)]
    # Siconos' NSGS solution and its error (Siconos' own function in 3D, checked against ours).
    r = np.zeros(n)
    u = np.zeros(n)
    if d == 3:
        options = sn.SolverOptions(sn.SICONOS_FRICTION_3D_NSGS)
        options.dparam[sn.SICONOS_DPARAM_TOL] = 1e-10
        options.iparam[sn.SICONOS_IPARAM_MAX_ITER] = 100000
        info = sn.fc3d_driver(p, r, u, options)
        _, error = sn.fc3d_compute_error(p, r, u, 1e-10, options, float(np.linalg.norm(q)))
        _, error_at_zero = sn.fc3d_compute_error(
            p, np.zeros(n), np.zeros(n), 1e-10, options, float(np.linalg.norm(q))
        )
        assert abs(error - natural_map_error(d, dense, q, mu, r)) <= 1e-12 * max(1.0, error) + 1e-15
    else:
        options = sn.SolverOptions(sn.SICONOS_FRICTION_2D_NSGS)
        options.dparam[sn.SICONOS_DPARAM_TOL] = 1e-10
        options.iparam[sn.SICONOS_IPARAM_MAX_ITER] = 100000
        try:
            info = sn.fc2d_driver(p, r, u, options)
        except RuntimeError:
            # fc2d_driver takes dense and sparse-block W only (not CSparse storage).
            info = None
        error = natural_map_error(d, dense, q, mu, r)
        error_at_zero = natural_map_error(d, dense, q, mu, np.zeros(n))
    return {
        "reader": "siconos",
        "dimension": d,
        "contacts": nc,
        "q_head": q[:3].tolist(),
        "q_norm": float(np.linalg.norm(q)),
        "mu_head": mu[:3].tolist(),
        "w_frobenius": frob,
        "w_entries": entries,
        "error_at_zero": float(error_at_zero),
        "siconos_nsgs_info": info,
        "siconos_nsgs_r": r.tolist(),
        "siconos_nsgs_error": float(error),
    }


def sparse(group):
    m, n, nz = int(group["m"][0]), int(group["n"][0]), int(group["nz"][0])
    p, i, x = np.array(group["p"]), np.array(group["i"]), np.array(group["x"])
    a = np.zeros((m, n))
    if nz >= 0:
        for k in range(nz):
            a[i[k], p[k]] += x[k]
    elif nz == -1:
        for col in range(n):
            for k in range(p[col], p[col + 1]):
                a[i[k], col] += x[k]
    else:
        for row in range(m):
            for k in range(p[row], p[row + 1]):
                a[row, i[k]] += x[k]
    return a


def from_hdf5(path):
    f = h5py.File(path, "r")
    if "fclib_local" in f:
        g = f["fclib_local"]
        d = int(g["spacedim"][0])
        w = sparse(g["W"])
        q = np.array(g["vectors/q"])
        mu = np.array(g["vectors/mu"])
    else:
        g = f["fclib_global"]
        d = int(g["spacedim"][0])
        m = sparse(g["M"])
        h = sparse(g["H"])
        minv = np.diag(1.0 / np.diag(m))
        w = h.T @ minv @ h
        q = h.T @ minv @ np.array(g["vectors/f"]) + np.array(g["vectors/w"])
        mu = np.array(g["vectors/mu"])
    n = w.shape[0]
    return {
        "reader": "h5py",
        "dimension": d,
        "contacts": len(mu),
        "q_head": q[:3].tolist(),
        "q_norm": float(np.linalg.norm(q)),
        "mu_head": mu[:3].tolist(),
        "w_frobenius": float(np.linalg.norm(w)),
        "w_entries": [[i, j, float(w[i, j])] for i, j in sample_positions(n)],
    }


def main():
    values = {}
    for path in sorted(HERE.iterdir()):
        if path.suffix == ".dat":
            values[path.name] = from_dat(path)
        elif path.suffix == ".hdf5":
            values[path.name] = from_hdf5(path)
    (HERE / "siconos_values.json").write_text(json.dumps(values, indent=1) + "\n")


if __name__ == "__main__":
    main()
