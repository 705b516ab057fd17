#!/usr/bin/env python3
"""Which coarse operator would make CDA multigrid grid-independent on the vacuum cloud?

A study script for issue 15's acceptance 2 (not part of the tests or the figures). It builds
the CDA operator of FLD Eq 32 (face coefficient = arithmetic mean of the two voxels' D,
D = 1/(3 max(sigma_t, sigma_eps)), zero Dirichlet layer) on a cloud like
`solvers::scenes::vacuum_cloud` (unit cube, sphere of radius 0.35, sigma_t = 20, albedo 0.9
inside; outside sigma_t = --outside, 0 = vacuum floored at sigma_eps = 1e-3) and counts the
multigrid cycles to a relative residual of 1e-6 for three coarse operators:

* `rediscretised`: what `solvers::fld::multigrid` does (the coarse D is the full-weighting
  mean of the fine D, i.e. the harmonic coarse sigma; absorption by full weighting; the same
  7-point stencil on 2h), trilinear prolongation, restriction = its transpose / 8;
* `galerkin-linear`: A_c = P^T A P with trilinear P (27-point coarse stencils);
* `galerkin-operator`: A_c = P^T A P with an operator-dependent P: the odd points of each
  axis, one axis after the other, are interpolated with weights proportional to the
  operator's (collapsed) couplings to their two neighbouring planes along that axis (flux
  continuity), so a voxel strongly tied to the vacuum takes the vacuum's correction;
* `galerkin-series`: as `galerkin-operator`, but the coarse levels' interpolation weights
  come from face coefficients coarsened alongside (the two fine faces a coarse face spans in
  series, full weighting across) instead of the Galerkin stencils' collapsed couplings;
* `series`: rediscretised, but with directional coarse face coefficients instead of one D
  per coarse voxel: the 7-point coarse stencil takes the face coefficients of
  `galerkin-series` (a coarse voxel can then conduct towards the vacuum and insulate towards
  the cloud), the absorption by full weighting, trilinear prolongation, R = P^T / 8;
* `series-op`: as `series` with the operator-dependent prolongation of `galerkin-series`
  (weights from the same face coefficients);
* `ruge-stuben`: pyamg's classical algebraic multigrid on the fine operator (coarse points
  chosen by strength of connection, so the coarsening follows the interface), as a bound on
  what coarsening adapted to the coefficients can do; `F-cg` then runs V-cycles with CG
  (pyamg's algebraic hierarchy has no F-cycle here).

Grids are n = 2^k + 1 voxels per axis including the layer (every axis vertex-coarsened, as
`Axis` does for odd interior counts); the coarsest level has at most 5^3 voxels and is
solved exactly. Smoother: one symmetric lexicographic Gauss-Seidel sweep before and after
(pyamg), so two sweeps each side as the red-black F(2, 2) of the crate. Cycles: `V` plain,
`F-cg` F-cycles as a preconditioner of conjugate gradients (the role the crate's Krylov
acceleration of depth 3 plays). The rediscretised `F-cg` counts reproduce the crate's
`multigrid_scaling` CDA cloud counts within a cycle or two (module docs of
`solvers::fld::multigrid`).

Needs numpy, scipy and pyamg (`python3 -m venv v && v/bin/pip install numpy scipy pyamg`).
Usage: scripts/mg-coarse-operators.py [--n 33,65,129] [--outside 0,0.2] [--cycles V,F-cg]
"""

import argparse
import sys
import time

import numpy as np
import pyamg
import scipy.sparse as sp
from pyamg.relaxation.smoothing import change_smoothers

SIGMA_EPS = 1e-3


def medium(n, outside):
    """sigma_t, albedo and emission of the cloud on n^3 voxels of the unit cube."""
    x = (np.arange(n) + 0.5) / n
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    inside = (X - 0.5) ** 2 + (Y - 0.5) ** 2 + (Z - 0.5) ** 2 <= 0.35**2
    sigma_t = np.where(inside, 20.0, outside)
    albedo = np.where(inside | (outside > 0), 0.9, 0.0)
    # A smooth positive emission inside (the crate's is Perlin noise; the rate of a cycle
    # does not depend on it).
    emission = np.where(inside, 0.5 + 0.5 * np.sin(7 * X) * np.cos(5 * Y) * np.sin(6 * Z + 1), 0.0)
    return sigma_t, albedo, emission


def operator(h, d, absorb):
    """CSR matrix of -div(k grad) + absorb on the interior voxels, k_face = (D_p + D_q)/2."""
    return face_operator(fine_faces(h, d), absorb)


def full_weighting(v, skip=None):
    """Vertex full weighting (1/4, 1/2, 1/4 per axis, but axis `skip`) of a field with its
    layer; the coarse layer copies the fine one."""
    for axis in range(3):
        if axis == skip:
            continue
        v = np.moveaxis(v, axis, 0)
        out = np.empty(((v.shape[0] + 1) // 2,) + v.shape[1:])
        out[1:-1] = 0.25 * v[1:-2:2] + 0.5 * v[2:-1:2] + 0.25 * v[3::2]
        out[0], out[-1] = v[0], v[-1]
        v = np.moveaxis(out, 0, axis)
    return v


def collapsed_couplings(a, m):
    """The operator's couplings to the neighbouring planes of each axis, collapsed: per axis
    (left, right), -sum of a[p, q] over the 9 voxels q of the plane p -/+ e_axis next to p
    (the 7-point fine operator has one of them, a 27-point Galerkin operator nine)."""
    strides = (m * m, m, 1)
    couplings = []
    for axis, s in enumerate(strides):
        others = [strides[t] for t in range(3) if t != axis]
        shifts = [u * others[0] + v * others[1] for u in (-1, 0, 1) for v in (-1, 0, 1)]
        left = np.zeros(m**3)
        right = np.zeros(m**3)
        for t in shifts:
            lo, hi = -s + t, s + t
            left[max(0, -lo):m**3 - max(0, lo)] -= a.diagonal(lo)
            right[max(0, -hi):m**3 - max(0, hi)] -= a.diagonal(hi)
        couplings.append((left.reshape(m, m, m), right.reshape(m, m, m)))
    return couplings


def fine_faces(h, d):
    """Per axis, the face coefficients (D_p + D_q)/2 / h^2 between voxel i and i + 1 along
    it (length n - 1 on that axis, n on the others)."""
    n = d.shape[0]
    faces = []
    for axis in range(3):
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[axis], hi[axis] = slice(0, n - 1), slice(1, n)
        faces.append(0.5 * (d[tuple(lo)] + d[tuple(hi)]) / h**2)
    return faces


def series_faces(faces):
    """Coarse face coefficients from fine ones: the two fine faces a coarse face spans
    along its axis in series (harmonic mean), full weighting across; /4 for the 2h spacing."""
    out = []
    for axis, k in enumerate(faces):
        k = np.moveaxis(k, axis, 0)
        series = 2 * k[0::2] * k[1::2] / (k[0::2] + k[1::2])
        series = np.moveaxis(full_weighting(series, skip=0), 0, axis)
        out.append(series / 4.0)
    return out


def face_couplings(faces, m):
    """(left, right) couplings of the interior voxels along each axis from face coefficients."""
    out = []
    for axis, k in enumerate(faces):
        sel_l = [slice(1, m + 1)] * 3
        sel_r = [slice(1, m + 1)] * 3
        sel_l[axis], sel_r[axis] = slice(0, m), slice(1, m + 1)
        out.append((k[tuple(sel_l)], k[tuple(sel_r)]))
    return out


def prolongation(couplings, m, operator_dependent):
    """P from the (m - 1)/2 coarse interior points per axis to the m fine ones, one axis
    after the other (x, then y, then z); `couplings` ((left, right) per axis on the fine
    interior) weight the operator-dependent interpolation."""
    mc = (m - 1) // 2
    p = sp.identity(mc**3, format="csr")
    shape = [mc, mc, mc]
    for axis in range(3):
        out_shape = list(shape)
        out_shape[axis] = m
        out_index = np.arange(np.prod(out_shape)).reshape(out_shape)
        in_index = np.arange(np.prod(shape)).reshape(shape)
        # Fine positions of the transverse axes: refined axes (< axis) are fine already,
        # the others still coarse (coarse c sits on fine interior index 2c + 1).
        sel = []
        for t in range(3):
            if t == axis:
                sel.append(slice(None))
            else:
                sel.append(slice(None) if t < axis else slice(1, m, 2))
        left, right = (c[tuple(sel)] for c in couplings[axis])
        rows, cols, vals = [], [], []
        for i in range(m):
            dst = np.take(out_index, i, axis=axis).ravel()
            if i % 2 == 1:
                rows.append(dst)
                cols.append(np.take(in_index, i // 2, axis=axis).ravel())
                vals.append(np.ones(dst.size))
                continue
            kl = np.take(left, i, axis=axis).ravel()
            kr = np.take(right, i, axis=axis).ravel()
            if operator_dependent:
                wl, wr = kl / (kl + kr), kr / (kl + kr)
            else:
                wl, wr = np.full(dst.size, 0.5), np.full(dst.size, 0.5)
            for c, w in ((i // 2 - 1, wl), (i // 2, wr)):
                if 0 <= c < mc:
                    rows.append(dst)
                    cols.append(np.take(in_index, c, axis=axis).ravel())
                    vals.append(w)
        step = sp.csr_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(out_index.size, in_index.size),
        )
        p = (step @ p).tocsr()
        shape = out_shape
    return p


def face_operator(faces, absorb):
    """CSR matrix of the 7-point operator with the given face coefficients (per axis, between
    voxel i and i + 1 along it, already divided by h^2) plus `absorb` on the diagonal."""
    n = absorb.shape[0]
    m = n - 2
    index = -np.ones((n, n, n), dtype=np.int64)
    index[1:-1, 1:-1, 1:-1] = np.arange(m**3).reshape(m, m, m)
    inner = (slice(1, -1),) * 3
    diag = absorb[inner].copy()
    rows, cols, vals = [], [], []
    for axis, k in enumerate(faces):
        for step in (-1, 1):
            nb = list(inner)
            nb[axis] = slice(1 + step, n - 1 + step)
            face = list(inner)
            face[axis] = slice(0, m) if step == -1 else slice(1, m + 1)
            kk = k[tuple(face)]
            diag += kk
            j = index[tuple(nb)]
            keep = j >= 0
            rows.append(index[inner][keep])
            cols.append(j[keep])
            vals.append(-kk[keep])
    rows.append(np.arange(m**3))
    cols.append(np.arange(m**3))
    vals.append(diag.ravel())
    return sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(m**3, m**3)
    )


def geometric(n, h, d, absorb, a, kind):
    """The geometric hierarchy of coarse operator `kind` over the fine operator `a`."""
    levels = []
    m = n - 2
    faces = fine_faces(h, d)
    while m > 3:
        level = pyamg.multilevel.MultilevelSolver.Level()
        level.A = a
        if kind in ("galerkin-series", "series", "series-op"):
            couplings = face_couplings(faces, m)
            faces = series_faces(faces)
        else:
            couplings = collapsed_couplings(a, m)
        operator_dependent = kind in ("galerkin-operator", "galerkin-series", "series-op")
        p = prolongation(couplings, m, operator_dependent)
        level.P = p
        if kind in ("series", "series-op"):
            level.R = (p.T / 8.0).tocsr()
            absorb = full_weighting(absorb)
            a = face_operator(faces, absorb)
        elif kind == "rediscretised":
            level.R = (p.T / 8.0).tocsr()
            h, d, absorb = 2 * h, full_weighting(d), full_weighting(absorb)
            a = operator(h, d, absorb)
        else:
            level.R = p.T.tocsr()
            a = (p.T @ a @ p).tocsr()
        levels.append(level)
        m = (m - 1) // 2
    coarsest = pyamg.multilevel.MultilevelSolver.Level()
    coarsest.A = a
    levels.append(coarsest)
    return pyamg.multilevel.MultilevelSolver(levels, coarse_solver="splu")


def hierarchy(n, outside, kind):
    sigma_t, albedo, emission = medium(n, outside)
    h = 1.0 / n
    d = 1.0 / (3.0 * np.maximum(sigma_t, SIGMA_EPS))
    absorb = sigma_t * (1.0 - albedo)
    a = operator(h, d, absorb)
    if kind == "ruge-stuben":
        solver = pyamg.ruge_stuben_solver(a, max_coarse=100)
    else:
        solver = geometric(n, h, d, absorb, a, kind)
    gs = ("gauss_seidel", {"sweep": "symmetric", "iterations": 1})
    change_smoothers(solver, presmoother=gs, postsmoother=gs)
    return solver, emission[1:-1, 1:-1, 1:-1].ravel()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", default="33,65,129")
    ap.add_argument("--outside", default="0,0.2")
    ap.add_argument("--operators", default="rediscretised,galerkin-linear,galerkin-operator,galerkin-series")
    ap.add_argument("--cycles", default="V,F-cg")
    ap.add_argument("--tolerance", type=float, default=1e-6)
    ap.add_argument("--max-cycles", type=int, default=200)
    args = ap.parse_args()
    print("outside,n,operator,cycle,cycles,last_rate,seconds")
    for outside in map(float, args.outside.split(",")):
        for n in map(int, args.n.split(",")):
            if (n - 1) & (n - 2) != 0:
                sys.exit(f"--n {n}: must be 2^k + 1")
            for kind in args.operators.split(","):
                solver, b = hierarchy(n, outside, kind)
                for cycle in args.cycles.split(","):
                    res = []
                    t = time.time()
                    solver.solve(
                        b,
                        x0=np.zeros_like(b),
                        tol=args.tolerance,
                        maxiter=args.max_cycles,
                        cycle="V" if kind == "ruge-stuben" else cycle[0],
                        accel="cg" if cycle.endswith("cg") else None,
                        residuals=res,
                    )
                    rate = res[-1] / res[-2] if len(res) > 1 else float("nan")
                    print(
                        f"{outside},{n},{kind},{cycle},{len(res) - 1},{rate:.3f},"
                        f"{time.time() - t:.2f}",
                        flush=True,
                    )


if __name__ == "__main__":
    main()
