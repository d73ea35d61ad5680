#!/usr/bin/env python3
"""Issue 14: stability of the hybrid's Ω_s/Ω_w coupling on a small 2D lattice (lattice model).

A square N x N lattice (spacing 1, horizon m), Ω_s a band of width ceil(1.2 m) along its edges
(linearized bond-based PD, full-volume bonds), Ω_w inside (WLS-2 rows of a stencil from
stencil_scan.py). Rows are coupled as in the papers (each row its own scheme, "force"), or
symmetrically ("energy": Ω_w pairs inside Ω_w take the WLS weights, every pair touching Ω_s the
PD bond). Prints the largest growth rate Re sqrt(eig) of u'' = K u (lattice units; 0: stable),
then with the interface damping v' = K u − c L D L v (L the lattice Laplacian, D a band of
BAND hops around the interface, c = kappa * omega_max) the largest Re of the first-order
system and the damping rates of the lowest modes.
Usage: coupling_spectrum.py M N STENCIL BAND KAPPAS   e.g. 4 24 fast4 2 0,0.005,0.01
STENCIL: fast4 (m = 4 orbits of medium-fast), fast8 (paper-fast), d3_8 (the papers' δ/3 at m = 8),
compact4 (a compact m = 4 set)
"""
import importlib.util
import os
import sys

import numpy as np

here = os.path.dirname(os.path.abspath(__file__))
spec = importlib.util.spec_from_file_location("scan", os.path.join(here, "stencil_scan.py"))
scan = importlib.util.module_from_spec(spec)
spec.loader.exec_module(scan)

STENCILS = {"fast4": ([(1, 1), (2, 1), (3, 0)], 6), "fast8": ([(3, 3), (4, 1), (4, 2)], 6),
            "d3_8": ([(3, 0), (3, 3), (5, 0), (5, 3), (5, 5), (8, 0)], 16),
            "compact4": ([(1, 0), (1, 1), (2, 1), (3, 0), (2, 2)], 16)}


def main():
    m, n_side, name, hops = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], float(sys.argv[4])
    kappas = [float(k) for k in sys.argv[5].split(",")]
    orbits, a = STENCILS[name]
    offsets = [(0, 0)] + [q for p in orbits for q in scan.orbit(p)]
    offs, blocks = scan.wls_blocks(offsets, m, a)
    wls = {tuple(int(v) for v in o): b for o, b in zip(offs, blocks) if tuple(o) != (0, 0)}
    pd = {p: scan.beta(p, m) * np.outer(p, p) / np.linalg.norm(p) ** 3 for p in scan.family(m)}
    band = int(np.ceil(1.2 * m))
    depth = lambda i, j: min(i, j, n_side - 1 - i, n_side - 1 - j)
    standard = lambda i, j: depth(i, j) < band
    index = lambda i, j: i * n_side + j
    n = n_side * n_side

    def stiffness(mode):
        k = np.zeros((2 * n, 2 * n))

        def pair(r, c, blk):
            k[2 * r:2 * r + 2, 2 * c:2 * c + 2] += blk
            k[2 * r:2 * r + 2, 2 * r:2 * r + 2] -= blk
        for i in range(n_side):
            for j in range(n_side):
                inside = lambda p: 0 <= i + p[0] < n_side and 0 <= j + p[1] < n_side
                if standard(i, j):
                    for p, blk in pd.items():
                        if inside(p):
                            pair(index(i, j), index(i + p[0], j + p[1]), blk)
                    continue
                for c, blk in wls.items():
                    if mode == "force" or not standard(i + c[0], j + c[1]):
                        pair(index(i, j), index(i + c[0], j + c[1]), blk)
                if mode == "energy":
                    for p, blk in pd.items():
                        if inside(p) and standard(i + p[0], j + p[1]):
                            pair(index(i, j), index(i + p[0], j + p[1]), blk)
        return k

    for mode in ["force", "energy"]:
        k = stiffness(mode)
        ev = np.linalg.eigvals(k)
        growth = np.max(np.real(np.sqrt(ev.astype(complex))))
        print(f"{name} m={m} N={n_side} {mode} coupling: largest growth rate {growth:.3e}, "
              f"|K - K^T| {np.abs(k - k.T).max():.1e}")
    k = stiffness("force")
    omega_max = np.sqrt(-np.linalg.eigvals(k).real.min())
    lap = np.zeros((n, n))
    for i in range(n_side):
        for j in range(n_side):
            for di, dj in [(1, 0), (0, 1)]:
                if i + di < n_side and j + dj < n_side:
                    r, c = index(i, j), index(i + di, j + dj)
                    lap[r, r] += 1
                    lap[c, c] += 1
                    lap[r, c] -= 1
                    lap[c, r] -= 1
    d = np.array([abs(depth(i, j) - band + 0.5) <= hops for i in range(n_side)
                  for j in range(n_side)], float)
    damping = np.kron(lap @ np.diag(d) @ lap, np.eye(2))
    for kappa in kappas:
        system = np.block([[np.zeros((2 * n, 2 * n)), np.eye(2 * n)],
                           [k, -kappa * omega_max * damping]])
        ev = np.linalg.eigvals(system)
        om = np.abs(ev.imag)
        low = [(om[q], ev[q].real) for q in np.argsort(om) if om[q] > 1e-6][:8:2]
        print(f"  damped, kappa = {kappa}: largest Re {ev.real.max():.2e}; lowest modes "
              f"(omega, Re): " + " ".join(f"({w:.3f}, {re:.1e})" for w, re in low))


if __name__ == "__main__":
    main()
