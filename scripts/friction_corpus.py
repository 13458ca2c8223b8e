#!/usr/bin/env python3
"""Writes the friction fixture corpus crates/signorini-core/tests/fixtures/friction/*.json.

Planar friction problems U = W P + q with the Signorini–Coulomb law per contact (ordering
(n_1, t_1, n_2, t_2, ...), see crates/signorini-core/src/friction/mod.rs), built backwards from a
known solution as scripts/lcp_corpus.py does for LCPs: per contact one case of the law,
  "sep":   P = 0,                       U_n > 0, U_t anything
  "stick": P_n > 0, |P_t| < mu P_n,     U = 0
  "slide+": P_n > 0, P_t = -mu P_n,     U_n = 0, U_t > 0
  "slide-": P_n > 0, P_t = +mu P_n,     U_n = 0, U_t < 0
then q = U - W P. W is symmetric positive definite, and mu is kept where the solution is unique:
mu_max kappa(W) <= 1/2 with kappa bounded by Gershgorin's discs (De Saxce's inequalities give
uniqueness for mu_max kappa(W) < 1, docs/friction.md), or any mu for uncoupled contacts with
diagonal 2x2 blocks. So every solver must return the known P (and U).
Deterministic (fixed seed); standard library only:  python3 scripts/friction_corpus.py
"""
import json
import pathlib
import random

OUT = pathlib.Path(__file__).resolve().parent.parent / "crates/signorini-core/tests/fixtures/friction"
rng = random.Random(20261130)


def gershgorin_kappa(w):
    lo = min(w[i][i] - sum(abs(x) for j, x in enumerate(w[i]) if j != i) for i in range(len(w)))
    hi = max(w[i][i] + sum(abs(x) for j, x in enumerate(w[i]) if j != i) for i in range(len(w)))
    assert lo > 0, "not diagonally dominant"
    return hi / lo


def coupled(m, radius):
    """SPD, diagonally dominant: diagonal in [1, 1.2], off-diagonal row sums <= radius."""
    n = 2 * m
    w = [[0.0] * n for _ in range(n)]
    for i in range(n):
        w[i][i] = rng.uniform(1.0, 1.2)
        for j in range(i):
            w[i][j] = w[j][i] = rng.uniform(-1, 1) * radius / (n - 1)
    return w


def uncoupled(m):
    n = 2 * m
    return [[rng.uniform(0.5, 2.0) if i == j else 0.0 for j in range(n)] for i in range(n)]


def chain_delassus(m, k=1e3, ky=1e2, h=1e-3, theta=0.5):
    """[G T]^T (M + theta^2 h^2 K)^-1 [G T] of examples/chain_rough_wall.toml (unit masses, dofs
    (x_i, y_i), springs k along the wall and ky across it): with G, T selecting y_i and x_i, the
    inverse of the iteration matrix itself, reordered (n_i, t_i) = (y_i, x_i)."""
    n = 2 * m
    a = [[1.0 if i == j else 0.0 for j in range(n)] for i in range(n)]
    c = theta * theta * h * h
    for i in range(1, m):
        for d, kk in ((0, k), (1, ky)):
            p, q = 2 * (i - 1) + d, 2 * i + d
            a[p][p] += c * kk
            a[q][q] += c * kk
            a[p][q] -= c * kk
            a[q][p] -= c * kk
    inv = [[1.0 if i == j else 0.0 for j in range(n)] for i in range(n)]
    for col in range(n):
        piv = a[col][col]
        for j in range(n):
            a[col][j] /= piv
            inv[col][j] /= piv
        for r in range(n):
            if r != col:
                f = a[r][col]
                for j in range(n):
                    a[r][j] -= f * a[col][j]
                    inv[r][j] -= f * inv[col][j]
    order = []
    for i in range(m):
        order += [2 * i + 1, 2 * i]  # (n_i, t_i) = (y_i, x_i)
    return [[inv[r][s] for s in order] for r in order]


def problem(name, w, mu, cases, note):
    m = len(cases)
    p = [0.0] * (2 * m)
    u = [0.0] * (2 * m)
    for c, kind in enumerate(cases):
        pn = rng.uniform(0.2, 2.0)
        if kind == "sep":
            u[2 * c] = rng.uniform(0.1, 2.0)
            u[2 * c + 1] = rng.uniform(-2.0, 2.0)
        elif kind == "stick":
            p[2 * c] = pn
            p[2 * c + 1] = rng.uniform(-0.8, 0.8) * mu[c] * pn
        elif kind == "slide+":
            p[2 * c] = pn
            p[2 * c + 1] = -mu[c] * pn
            u[2 * c + 1] = rng.uniform(0.1, 2.0)
        elif kind == "slide-":
            p[2 * c] = pn
            p[2 * c + 1] = mu[c] * pn
            u[2 * c + 1] = -rng.uniform(0.1, 2.0)
        else:
            raise ValueError(kind)
    n = 2 * m
    q = [u[i] - sum(w[i][j] * p[j] for j in range(n)) for i in range(n)]
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / f"{name}.json").write_text(json.dumps(
        {"note": note, "mu": mu, "w": w, "q": q, "p": p, "u": u, "cases": cases}, indent=1) + "\n")


def main():
    # One contact, each case, several mu (uncoupled: unique for any mu).
    for kind in ("sep", "stick", "slide+", "slide-"):
        for mu in (0.1, 0.8, 2.5):
            problem(f"single_{kind.replace('+', 'p').replace('-', 'm')}_mu{mu}", uncoupled(1), [mu], [kind],
                    f"one contact, {kind}, mu = {mu}")
    # Uncoupled contacts, mixed cases, large mu.
    problem("uncoupled_5", uncoupled(5), [0.3, 1.0, 2.0, 0.6, 1.5],
            ["stick", "slide+", "sep", "slide-", "stick"], "five uncoupled contacts, mixed cases")
    # Coupled, mu in the uniqueness regime.
    for m, radius, cases in (
        (2, 0.2, ["stick", "slide+"]),
        (3, 0.2, ["slide-", "sep", "stick"]),
        (4, 0.15, ["slide+", "slide+", "stick", "sep"]),
        (6, 0.1, ["stick", "slide-", "sep", "slide+", "stick", "slide-"]),
    ):
        w = coupled(m, radius)
        mu_max = 0.5 / gershgorin_kappa(w)
        mu = [rng.uniform(0.3, 1.0) * mu_max for _ in range(m)]
        problem(f"coupled_{m}", w, mu, cases, f"{m} coupled contacts, mu_max kappa(W) <= 1/2")
    # The chain of examples/chain_rough_wall.toml: its Delassus operator with tangent rows.
    for m, cases in ((4, ["slide+", "slide+", "stick", "stick"]), (8, ["slide+"] * 3 + ["stick"] * 3 + ["sep", "slide-"])):
        w = chain_delassus(m)
        mu_max = 0.5 / gershgorin_kappa(w)
        problem(f"chain_rough_wall_{m}", w, [min(0.3, mu_max)] * m, cases,
                f"Delassus operator of the chain on a rough wall, {m} masses")


if __name__ == "__main__":
    main()
