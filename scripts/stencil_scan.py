#!/usr/bin/env python3
"""Issue 14: scan WLS-2 collocation stencils on a 2D lattice by their lattice symbol.

For a node of a uniform lattice (spacing 1, horizon m), bond-based PD linearized
(c = 1, constant influence, partial volumes by subsampling) against WLS-2 (quadratic fit with
weight exp(-a d^2/r^2), the local operator of the same PD kernel): for each symmetric set of
lattice orbits (+-a, +-b), (+-b, +-a) it reports
  dt   = sqrt(max eig PD / max eig WLS): the WLS stable step over the standard scheme's,
  soft = min over |k| >= pi/2 of (least eig WLS(k)) / (least eig PD(k)): how much stiffness
         the stencil keeps at high wave numbers (0: a zero-energy mode; < 0: unstable),
  acc  = max relative difference of the symbols at k delta = 1.2 (accuracy proxy).
Usage: stencil_scan.py M [MAX_ORBITS]   (m = 4 takes seconds, m = 8 with 3 orbits minutes)
"""
import itertools
import sys

import numpy as np


def family(m):
    r = int(m) + 1
    return [(i, j) for i in range(-r, r + 1) for j in range(-r, r + 1)
            if (i, j) != (0, 0) and i * i + j * j <= (m + 0.5) ** 2]


def beta(p, m, n=20):
    s = (np.arange(n) + 0.5) / n - 0.5
    x, y = np.meshgrid(p[0] + s, p[1] + s)
    return np.mean(x ** 2 + y ** 2 <= m * m)


def pd_symbol(m, ks):
    fam = [(p, beta(p, m)) for p in family(m)]
    fam = [(np.array(p, float), b) for p, b in fam if b > 0]
    out = []
    for k in ks:
        mat = np.zeros((2, 2))
        for xi, b in fam:
            r = np.linalg.norm(xi)
            mat += b * np.outer(xi, xi) / r ** 3 * (1 - np.cos(k @ xi))
        out.append(mat)
    return out


def angular(axes):
    th = np.linspace(0, 2 * np.pi, 4001)[:-1]
    v = np.ones_like(th)
    for a in axes:
        v = v * (np.cos(th) if a == 0 else np.sin(th))
    return v.mean() * 2 * np.pi


def wls_blocks(offsets, m, a):
    xi = np.array(offsets, float) / m
    d = np.linalg.norm(xi, axis=1)
    w = np.exp(-a * d * d / d.max() ** 2)
    p = np.stack([np.ones(len(xi)), xi[:, 0], xi[:, 1], xi[:, 0] ** 2, xi[:, 0] * xi[:, 1],
                  xi[:, 1] ** 2], 1)
    q = np.linalg.solve(p.T @ (w[:, None] * p), (p * w[:, None]).T)
    hess = {(0, 0): 2 * q[3] / m ** 2, (0, 1): q[4] / m ** 2, (1, 0): q[4] / m ** 2,
            (1, 1): 2 * q[5] / m ** 2}
    blocks = np.zeros((len(xi), 2, 2))
    for i in range(2):
        for j in range(2):
            for (r, s), h in hess.items():
                blocks[:, i, j] += m ** 3 / 6 * angular([i, j, r, s]) * h
    return np.array(offsets, float), blocks


def wls_symbol(offsets, blocks, ks):
    return [-np.einsum('j,jab->ab', np.exp(1j * (offsets @ k)) - 1, blocks) for k in ks]


def orbit(p):
    i, j = p
    return sorted({(sa * x, sb * y) for x, y in [(i, j), (j, i)] for sa in (1, -1) for sb in (1, -1)})


def main():
    m = int(sys.argv[1])
    max_orbits = int(sys.argv[2]) if len(sys.argv) > 2 else 10
    reps = [(i, j) for i in range(0, m + 1) for j in range(0, i + 1) if 0 < i * i + j * j <= m * m]
    g = np.linspace(-np.pi, np.pi, 24, endpoint=False)
    ks = [np.array([a, b]) for a in g for b in g]
    pd = pd_symbol(m, ks)
    pd_max = max(np.linalg.eigvalsh(k).max() for k in pd)
    pd_min = [np.linalg.eigvalsh(k).min() for k in pd]
    high = [i for i, k in enumerate(ks) if np.linalg.norm(k) >= np.pi / 2]
    low = [np.array([1.2 / m * np.cos(t), 1.2 / m * np.sin(t)]) for t in np.linspace(0, np.pi / 4, 4)]
    pd_low = pd_symbol(m, low)
    rows = []
    for r in range(2, min(len(reps), max_orbits) + 1):
        for combo in itertools.combinations(reps, r):
            offsets = [(0, 0)] + [q for p in combo for q in orbit(p)]
            if len(offsets) > 33:
                continue
            for a in [6, 8, 10, 12, 14, 16]:
                try:
                    off, blocks = wls_blocks(offsets, m, a)
                except np.linalg.LinAlgError:
                    continue
                ev = [np.linalg.eigvals(k).real for k in wls_symbol(off, blocks, ks)]
                w_max = max(e.max() for e in ev)
                if w_max <= 0:
                    continue
                soft = min(ev[i].min() / pd_min[i] for i in high)
                acc = max(np.linalg.norm(x - y) / np.linalg.norm(y)
                          for x, y in zip(wls_symbol(off, blocks, low), pd_low))
                rows.append((len(offsets), np.sqrt(pd_max / w_max), soft, acc, a, combo))
    print("largest soft share with dt >= threshold, by set size")
    for threshold in [0.6, 0.7, 0.8, 0.9, 1.0]:
        for nc in [13, 17, 21, 25, 29, 33]:
            cand = [x for x in rows if x[1] >= threshold and x[0] <= nc]
            if cand:
                x = max(cand, key=lambda x: x[2])
                print(f"dt>={threshold} nc<={nc}: nc={x[0]} dt={x[1]:.3f} soft={x[2]:.2f} "
                      f"acc={x[3]:.2e} a={x[4]} orbits={list(x[5])}")


if __name__ == "__main__":
    main()
