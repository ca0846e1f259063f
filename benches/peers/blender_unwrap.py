#!/usr/bin/env python3
# SPDX-License-Identifier: MIT OR Apache-2.0
"""Blender's automatic unwraps as a peer of `decalbake unwrap` (`decalbake bench --unwrap --peers`).

Run with Blender as a Python module (`bash ../shared/peers/setup.sh --bpy`):

    ../shared/peers/.venv-bpy/bin/python benches/peers/blender_unwrap.py MESH.glb OUT.glb \
        [--method smart|angle]

Imports MESH.glb (vertices merged, so the surface is whole), replaces its UV maps by one new map,
and unwraps it the way a Blender user would without drawing seams:
  smart  Smart UV Project (charts by the angle between faces, each projected flat, then packed);
  angle  Smart UV Project's islands as seams, then Unwrap (angle based) and Pack Islands, the usual
         next step for less stretch.
Writes OUT.glb with that map as TEXCOORD_0 (the bench measures it with decalbake's own quality
measure, so both sides are scored alike) and prints one JSON line: the unwrap's time (the
operators only, not the import or export) and the number of UV islands.
"""
import argparse
import json
import math
import os
import sys
import time

import bpy
from bpy_scene import import_joined


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mesh")
    ap.add_argument("out")
    ap.add_argument("--method", choices=["smart", "angle"], default="smart")
    a = ap.parse_args(sys.argv[1:])

    obj = import_joined(os.path.abspath(a.mesh), merge_vertices=True)
    while obj.data.uv_layers:
        obj.data.uv_layers.remove(obj.data.uv_layers[0])
    obj.data.uv_layers.new(name="UVMap")

    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    t0 = time.perf_counter()
    bpy.ops.uv.smart_project(angle_limit=math.radians(66.0), island_margin=0.002)
    if a.method == "angle":
        bpy.ops.uv.select_all(action="SELECT")
        bpy.ops.uv.seams_from_islands()
        bpy.ops.uv.unwrap(method="ANGLE_BASED", margin=0.002)
        bpy.ops.uv.pack_islands(margin=0.002)
    seconds = time.perf_counter() - t0
    bpy.ops.object.mode_set(mode="OBJECT")

    import bmesh

    bm = bmesh.new()
    bm.from_mesh(obj.data)
    uv = bm.loops.layers.uv.active
    islands = _islands(bm, uv)
    bm.free()

    bpy.ops.export_scene.gltf(
        filepath=os.path.abspath(a.out),
        export_format="GLB",
        use_selection=True,
        export_texcoords=True,
        export_normals=False,
        export_materials="NONE",
    )
    print(json.dumps({"peer": "blender", "method": a.method, "version": bpy.app.version_string,
                      "seconds": seconds, "islands": islands, "faces": len(obj.data.polygons)}))


def _islands(bm, uv):
    """UV islands: faces joined across edges whose two sides have the same UVs."""
    parent = list(range(len(bm.faces)))

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    bm.faces.ensure_lookup_table()
    for e in bm.edges:
        if len(e.link_faces) != 2:
            continue
        f, g = e.link_faces
        same = True
        for v in e.verts:
            a = next(l for l in f.loops if l.vert == v)[uv].uv
            b = next(l for l in g.loops if l.vert == v)[uv].uv
            if (a - b).length > 1e-6:
                same = False
        if same:
            parent[find(f.index)] = find(g.index)
    return len({find(i) for i in range(len(bm.faces))})


if __name__ == "__main__":
    main()
