#!/usr/bin/env python3
# SPDX-License-Identifier: MIT OR Apache-2.0
"""potpourri3d's multi-source heat-method distance as the distance peer of `decalbake bench --ribbons`.

Run with the peers' venv (`bash ../shared/peers/setup.sh`):

    ../shared/peers/.venv/bin/python benches/peers/ribbon_heat.py MESH.obj SOURCES.txt \
        [--out DIST.f64] [--fmm-out DIST.f64] [--reps 5] [--budget 20] [--t-coef 1.0]

MESH.obj: `v x y z` and `f a b c` lines (1-based; `a/b/c` forms read by their first index). Its
vertex order is the caller's: vertices no face uses (the bench writes every welded vertex, faces
without the degenerate ones) are left out of the solve and get NaN, and the ids keep their meaning.
SOURCES.txt: the source vertex ids, 0-based in MESH.obj's order, separated by white space. The
bench passes the mesh vertices the ribbon's curve passes nearest (its curve runs along mesh edges,
so they lie on the curve).

Builds `MeshHeatMethodDistanceSolver` (geometry-central's heat method: Laplacian, mass matrix and
the two factorisations; t = t_coef * mean edge length^2, robust intrinsic Laplacian) and calls
`compute_distance_multisource` on the sources. Timing as `../shared/peers` does it: one warm-up
call, then up to `--reps` timed calls within about `--budget` seconds (a call slower than the budget
is timed once, cold); the set-up (solver construction) and the solve are timed separately, medians
in milliseconds. Prints one JSON line; with `--out`, writes the distances of the last solve, one per
OBJ vertex, as raw little-endian float64 (`.npy` when the name ends so).

With `--fmm-out`, also potpourri3d's fast marching (`MeshFastMarchingDistanceSolver`) from the same
vertices, timed the same way (`"fmm"` in the JSON) and written alike. It is the referee of the heat
method's own error: fast marching is first order but exactly 0 on its sources, where the heat
method's distance (shifted so that its mean over the sources is 0) is not.
"""
import argparse
import importlib.metadata
import json
import statistics
import sys
import time

import numpy as np
import potpourri3d as pp3d


def timed(fn, reps, budget_s):
    """Warm-up, then up to `reps` timed runs within about `budget_s`; (last result, stats in ms)."""
    t0 = time.perf_counter()
    res = fn()
    first = time.perf_counter() - t0
    if first >= budget_s:
        return res, {"median_ms": first * 1e3, "min_ms": first * 1e3, "runs": 1, "cold_only": True}
    times = []
    for _ in range(max(1, min(reps, int(budget_s / max(first, 1e-9))))):
        t0 = time.perf_counter()
        res = fn()
        times.append(time.perf_counter() - t0)
    return res, {
        "median_ms": statistics.median(times) * 1e3,
        "min_ms": min(times) * 1e3,
        "runs": len(times),
        "warmup_ms": first * 1e3,
    }


def read_obj(path):
    """(V float64 n x 3, F int64 m x 3, 0-based) of a triangle OBJ."""
    verts, faces = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                verts.append(line[2:])
            elif line.startswith("f "):
                faces.append(" ".join(w.split("/")[0] for w in line[2:].split()))
    V = np.array(" ".join(verts).split(), dtype=np.float64).reshape(-1, 3)
    F = np.array(" ".join(faces).split(), dtype=np.int64).reshape(-1, 3) - 1
    return V, F


def write(path, d, used):
    """Distances `d` over the used vertices, NaN elsewhere, to `path` (raw <f8, or .npy)."""
    if not path:
        return
    dist = np.full(len(used), np.nan)
    dist[used] = d
    if path.endswith(".npy"):
        np.save(path, dist)
    else:
        dist.astype("<f8").tofile(path)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mesh")
    ap.add_argument("sources")
    ap.add_argument("--out")
    ap.add_argument("--fmm-out")
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--budget", type=float, default=20.0, help="seconds of timed runs per part")
    ap.add_argument("--t-coef", type=float, default=1.0)
    a = ap.parse_args(sys.argv[1:])

    t0 = time.perf_counter()
    V, F = read_obj(a.mesh)
    with open(a.sources) as f:
        sources = np.array(f.read().split(), dtype=np.int64)
    # Leave out the vertices no face uses (the solver wants none); map ids both ways.
    used = np.zeros(len(V), dtype=bool)
    used[F.reshape(-1)] = True
    new_id = np.full(len(V), -1, dtype=np.int64)
    new_id[used] = np.arange(int(used.sum()))
    Vc, Fc = np.ascontiguousarray(V[used]), new_id[F]
    src = new_id[sources]
    src = np.unique(src[src >= 0])
    load_ms = (time.perf_counter() - t0) * 1e3

    solver, setup = timed(
        lambda: pp3d.MeshHeatMethodDistanceSolver(Vc, Fc, t_coef=a.t_coef), a.reps, a.budget
    )
    d, solve = timed(lambda: solver.compute_distance_multisource(src), a.reps, a.budget)

    write(a.out, d, used)
    fmm = None
    if a.fmm_out:
        curves = [[(int(i), []) for i in src]]
        fm, fmm_setup = timed(lambda: pp3d.MeshFastMarchingDistanceSolver(Vc, Fc), a.reps, a.budget)
        f, fmm_solve = timed(lambda: fm.compute_distance(curves), a.reps, a.budget)
        write(a.fmm_out, np.asarray(f).reshape(-1), used)
        fmm = {"setup": fmm_setup, "solve": fmm_solve}
    print(json.dumps({
        "peer": "pp3d_heat_multisource",
        "potpourri3d": importlib.metadata.version("potpourri3d"),
        "vertices": int(used.sum()), "faces": int(len(F)), "unused_vertices": int(len(V) - used.sum()),
        "sources": int(len(src)), "t_coef": a.t_coef, "load_ms": load_ms,
        "setup": setup, "solve": solve,
        "nan": int(np.isnan(d).sum()), "max_distance": float(np.nanmax(d)) if len(d) else None,
        "fmm": fmm,
    }))


if __name__ == "__main__":
    main()
