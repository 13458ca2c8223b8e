#!/usr/bin/env python3
"""Writes the LCP fixture corpus crates/signorini-core/tests/fixtures/lcp/*.json.

Each problem is built backwards from a known solution: pick z* >= 0 and w* >= 0 with
z*_i w*_i = 0 (some indices degenerate: both zero), a matrix M, and set q = w* - M z*.
For P-matrices the solution is unique, so every solver must return z*.
Deterministic (fixed seed); standard library only:  python3 scripts/lcp_corpus.py
"""
import json
import pathlib
import random

OUT = pathlib.Path(__file__).resolve().parent.parent / "crates/signorini-core/tests/fixtures/lcp"
rng = random.Random(20261122)


def spd(n, delta):
    b = [[rng.uniform(-1, 1) for _ in range(n)] for _ in range(n)]
    return [[sum(b[k][i] * b[k][j] for k in range(n)) + (delta if i == j else 0.0) for j in range(n)] for i in range(n)]


def nonsymmetric_p(n):
    # Strictly diagonally dominant with positive diagonal: a P-matrix, not symmetric.
    m = [[rng.uniform(-1, 1) for _ in range(n)] for _ in range(n)]
    for i in range(n):
        m[i][i] = sum(abs(x) for x in m[i]) + 0.5
    return m


def delassus_chain(n, k=100.0, h=1e-3, theta=0.5):
    # W = G^T (M + theta^2 h^2 K)^-1 G with G = I for a unit-mass chain: the LCPs of the chain scene.
    a = [[(1.0 if i == j else 0.0) + theta * theta * h * h * kij for j, kij in enumerate(row)] for i, row in enumerate(
        [[(2 * k if 0 < i < n - 1 else k) if i == j else (-k if abs(i - j) == 1 else 0.0) for j in range(n)] for i in range(n)])]
    # Invert by Gauss-Jordan.
    inv = [[1.0 if i == j else 0.0 for j in range(n)] for i in range(n)]
    for c in range(n):
        p = a[c][c]
        for j in range(n):
            a[c][j] /= p
            inv[c][j] /= p
        for r in range(n):
            if r != c:
                f = a[r][c]
                for j in range(n):
                    a[r][j] -= f * a[c][j]
                    inv[r][j] -= f * inv[c][j]
    return inv


def problem(name, m, pattern, note):
    n = len(m)
    z = [0.0] * n
    w = [0.0] * n
    for i, kind in enumerate(pattern):
        if kind == "z":
            z[i] = rng.uniform(0.1, 2.0)
        elif kind == "w":
            w[i] = rng.uniform(0.1, 2.0)
        # "0": degenerate, both zero
    q = [w[i] - sum(m[i][j] * z[j] for j in range(n)) for i in range(n)]
    symmetric = all(abs(m[i][j] - m[j][i]) < 1e-15 for i in range(n) for j in range(n))
    doc = {"note": note, "m": m, "q": q, "z": z, "symmetric": symmetric}
    (OUT / f"{name}.json").write_text(json.dumps(doc, indent=1) + "\n")


OUT.mkdir(parents=True, exist_ok=True)
problem("scalar_active", [[2.0]], "z", "one contact, impulse needed")
problem("scalar_inactive", [[2.0]], "w", "one contact, separating (q > 0)")
problem("scalar_degenerate", [[2.0]], "0", "one contact exactly grazing: z = w = 0")
problem("spd_3_mixed", spd(3, 0.2), "zwz", "3 contacts, two closed")
problem("spd_5_all_active", spd(5, 0.1), "zzzzz", "every contact closed")
problem("spd_6_degenerate", spd(6, 0.3), "z0wz0w", "degenerate indices (z_i = w_i = 0)")
problem("spd_8_ill_conditioned", spd(8, 1e-4), "zzwzwzzw", "nearly singular Delassus operator")
problem("spd_12_mixed", spd(12, 0.5), "zwzwzwzzwwz0", "largest size enumeration accepts")
problem("nonsymmetric_4", nonsymmetric_p(4), "zwzz", "non-symmetric P-matrix (Lemke and enumeration only)")
problem("nonsymmetric_7", nonsymmetric_p(7), "wzzwz0z", "non-symmetric P-matrix with a degenerate index")
problem("chain_delassus_10", delassus_chain(10), "zzzzzwwwww", "chain scene: half the masses against the wall")
problem("chain_delassus_30", delassus_chain(30), "z" * 20 + "w" * 10, "chain scene, 30 contacts (Lemke, PGS)")
print(f"wrote {len(list(OUT.glob('*.json')))} problems to {OUT}")
