#!/usr/bin/env python3
# SPDX-License-Identifier: MIT OR Apache-2.0
"""Blender 5.0's Cycles "Selected to Active" bake of a decalbake job's decals: the peer of
`decalbake bake` for whole-process timings (`benches/peers/blender_vs_decalbake.sh`).

Run with Blender as a Python module (`bash ../shared/peers/setup.sh --bpy`), after one
`decalbake bake JOB.json` has written the bake report (where each decal landed):

    ../shared/peers/.venv-bpy/bin/python benches/peers/blender_decals.py JOB.json REPORT.json \
        --out OUT.png [--samples 4] [--padding N] [--extrusion E]

What it does, the way a Blender user would bake decals without an add-on:
  * imports the job's mesh (glTF importer; several mesh objects are joined) and bakes into its
    UV map `uv_set` (TEXCOORD_0 by default) into a new float RGBA image of the job's size;
  * for every decal layer, a quad of the layer's `size` at the report's `frame.center`, spanned
    by `frame.axis_u` (the image's +x) and `frame.axis_v` (the image's +y, up), lifted along
    `frame.normal` by 1e-4 of the bounding-box diagonal times (1 + layer index), so later layers
    lie above earlier ones; glTF's +Y-up coordinates become Blender's +Z-up (x, -z, y). The quad
    is a 16 x 16 grid without the cells where the image is fully transparent, so a decal's empty
    corners do not hide the decals under it;
  * each quad's material: Mix(Transparent, Emission(image colour)) by image alpha x `opacity`;
  * a copy of the mesh moved in along its normals by E, transparent, so every texel's ray hits
    something (otherwise Blender's margin smears decal edges into the texels no decal covers);
  * bakes COMBINED (emission only, film transparent: premultiplied colour and alpha) with Cycles
    on the CPU, "Selected to Active" (quads and copy selected, mesh active), `--samples` samples
    (adaptive sampling and denoising off), cage extrusion E (default: the largest `frame.depth`,
    half the decal's larger side unless the layer sets `depth`), ray distance 3E, margin = the
    job's padding (16 by default, "full" = the texture's size), margin type "extend";
  * composes the bake over the job's base in linear light with numpy: `texture.base` "material"
    (the imported material's base-colour texture, resized to the job's size; its Base Color
    value when it has none; mid grey without a material), an image path or a linear RGBA colour;
    saves an 8-bit sRGB RGBA PNG.
Prints one JSON line: seconds for `import bpy`, the glTF import, the set-up (quads, materials,
images), the bake, the composite, the save, and the total since the process started.

What Blender cannot reproduce (or this script does not):
  * overlapping decals: a bake ray takes the colour and alpha of the first surface it meets and
    does not go on through transparency (Cycles' bake rays end there; checked on 5.0.1), so where
    a later decal's partly transparent texels (a glow, an antialiased edge, a partly empty grid
    cell) cover an earlier decal, the earlier one is lost there instead of showing through;
  * blend modes other than "normal" (multiply, screen, overlay, add, ...): every layer is baked
    as "normal" (the JSON line counts the layers whose mode was replaced);
  * decalbake's non-planar maps (`method` expmap, the default, lscm, hybrid) wrap the image along
    the surface; a flat quad is a planar decal, and Selected to Active projects it along each
    texel's surface normal, not along the decal's normal: it stretches and blurs (4 random samples
    over a stretched footprint) where the surface turns away from the quad, and the surface more
    than E above or 2E below the quad gets nothing;
  * decals whose quads cross each other (different normals) overlap in whatever order the rays
    meet them there, not job order;
  * the `depth` limit and facing test of planar decals (a ray may reach a quad through a thin part
    of the model), `mask`, `warp`, material channels (normal, roughness, ...), strokes, ribbons,
    text and SVG images (such layers are skipped and counted), `texture.base` "transfer"
    (the material's texture is used), a base-colour factor combined with a texture (the texture
    alone is used), 16-bit and EXR output;
  * padding: Blender extends the baked decals (and their alpha) into the margin before the base
    is composed, decalbake pads the composed texture; Cycles samples texels at random positions,
    decalbake on a fixed grid. Frames are read as scene coordinates (a node transform is not
    applied again).
"""
import time

T_START = time.perf_counter()

import argparse  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
import sys  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402
from bpy_scene import import_joined  # noqa: E402

T_BPY = time.perf_counter()


def to_blender(v):
    """glTF (+Y up) to Blender (+Z up), as the glTF importer converts."""
    return (v[0], -v[2], v[1])


def srgb_to_linear(c):
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c):
    c = np.clip(c, 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)


# Look-up tables for the composite: 8-bit sRGB to linear, linear (16-bit steps) to sRGB.
SRGB8_TO_LINEAR = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)
LINEAR16_TO_SRGB = linear_to_srgb(np.arange(65536) / 65535.0).astype(np.float32)


def pixels(img):
    a = np.empty(img.size[0] * img.size[1] * 4, np.float32)
    img.pixels.foreach_get(a)
    return a.reshape(img.size[1], img.size[0], 4)


CELLS = 16  # a decal's quad is a CELLS x CELLS grid without its fully transparent cells


def opaque_cells(img):
    """[row from the bottom, column]: whether the cell has a texel with alpha (grown by a texel)."""
    w, h = img.size
    al = pixels(img)[..., 3] > 0.5 / 255
    pad = np.zeros((h + 2, w + 2), bool)
    pad[1:-1, 1:-1] = al
    grown = pad[:-2, 1:-1] | pad[2:, 1:-1] | pad[1:-1, :-2] | pad[1:-1, 2:] | al
    ys = np.minimum(np.arange(h) * CELLS // h, CELLS - 1)
    xs = np.minimum(np.arange(w) * CELLS // w, CELLS - 1)
    out = np.zeros((CELLS, CELLS), bool)
    np.logical_or.at(out, (ys[:, None], xs[None, :]), grown)
    return out


def upstream_image(socket, depth=0):
    """The Image Texture node feeding `socket` (through a few nodes), or None."""
    if depth > 4 or not socket.is_linked:
        return None
    node = socket.links[0].from_node
    if node.type == "TEX_IMAGE" and node.image is not None:
        return node.image
    for s in node.inputs:
        img = upstream_image(s, depth + 1)
        if img is not None:
            return img
    return None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("job")
    ap.add_argument("report")
    ap.add_argument("--out", required=True)
    ap.add_argument("--samples", type=int, default=4)
    ap.add_argument("--padding", type=int, default=None, help="margin in texels (default: the job's)")
    ap.add_argument("--extrusion", type=float, default=None,
                    help="cage extrusion, model units (default: the largest frame depth, half the "
                         "decal's larger side unless the layer sets depth)")
    a = ap.parse_args(sys.argv[1:])

    job_path = os.path.abspath(a.job)
    job_dir = os.path.dirname(job_path)
    job = json.load(open(job_path))
    report = json.load(open(a.report))
    tex = job.get("texture", {})
    width, height = int(tex.get("width", 2048)), int(tex.get("height", 2048))
    padding = tex.get("padding", 16)
    if a.padding is not None:
        padding = a.padding
    margin = max(width, height) if padding == "full" else int(padding)
    uv_set = job.get("uv_set", 0)
    uv_set = uv_set if isinstance(uv_set, int) else (uv_set[0] if isinstance(uv_set, list) else 0)

    # --- import ---------------------------------------------------------------------------
    t0 = time.perf_counter()
    low = import_joined(os.path.join(job_dir, job["mesh"]))
    t_import = time.perf_counter() - t0

    # --- scene set-up ---------------------------------------------------------------------
    t0 = time.perf_counter()
    base = tex.get("base", "material")
    base_img, base_rgba = None, None
    if isinstance(base, list):
        base_rgba = [float(x) for x in base] + [1.0] * (4 - len(base))
    elif isinstance(base, str) and base != "material":
        base_img = bpy.data.images.load(os.path.join(job_dir, base))
    else:  # "material" (or a transfer, not reproduced: the material's texture)
        mat = low.active_material
        if mat is None or mat.node_tree is None:
            base_rgba = [0.5, 0.5, 0.5, 1.0]
        else:
            bsdf = next((n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED"), None)
            if bsdf is None:
                base_rgba = [0.5, 0.5, 0.5, 1.0]
            else:
                base_img = upstream_image(bsdf.inputs["Base Color"])
                if base_img is None:
                    base_rgba = list(bsdf.inputs["Base Color"].default_value)

    uvs = low.data.uv_layers
    uvs.active = uvs[min(uv_set, len(uvs) - 1)]
    uv_name = uvs.active.name
    bake_img = bpy.data.images.new("decal_bake", width, height, alpha=True, float_buffer=True)
    bake_mat = bpy.data.materials.new("decal_bake_target")
    node = bake_mat.node_tree.nodes.new("ShaderNodeTexImage")
    node.image = bake_img
    bake_mat.node_tree.nodes.active = node
    low.data.materials.clear()
    low.data.materials.append(bake_mat)

    mn = np.array(report["mesh"]["bbox_min"], float)
    mx = np.array(report["mesh"]["bbox_max"], float)
    lift0 = 1e-4 * float(np.linalg.norm(mx - mn))
    images, cells, planes, skipped, replaced_blend, depth_max = {}, {}, [], 0, 0, 0.0
    for i, (layer, lrep) in enumerate(zip(job["layers"], report["layers"])):
        image = layer.get("image")
        if layer.get("kind", "decal") != "decal" or not image or image.lower().endswith(".svg"):
            skipped += 1
            continue
        if layer.get("blend", "normal") != "normal":
            replaced_blend += 1
        f = lrep["frame"]
        w, h = f.get("size", layer.get("size"))
        depth_max = max(depth_max, float(f.get("depth", 0.5 * max(w, h))))
        c = np.array(to_blender(f["center"]), float)
        u = np.array(to_blender(f["axis_u"]), float)
        v = np.array(to_blender(f["axis_v"]), float)
        n = np.array(to_blender(f["normal"]), float)
        c = c + n * lift0 * (1 + i)
        if image not in cells:
            cells[image] = opaque_cells(bpy.data.images.load(os.path.join(job_dir, image),
                                                             check_existing=True))
        me = bpy.data.meshes.new(f"decal{i}")
        g = CELLS
        st = [(x / g, y / g) for y in range(g + 1) for x in range(g + 1)]
        verts = [tuple(c + (s - 0.5) * w * u + (t - 0.5) * h * v) for s, t in st]
        faces = [(y * (g + 1) + x, y * (g + 1) + x + 1, (y + 1) * (g + 1) + x + 1,
                  (y + 1) * (g + 1) + x) for y in range(g) for x in range(g) if cells[image][y, x]]
        me.from_pydata(verts, [], faces)
        uv = me.uv_layers.new(name="UVMap")
        # Blender's image origin is bottom-left: +t is the image's up (axis_v).
        uv.data.foreach_set("uv", np.array([st[k] for fc in faces for k in fc], np.float32).ravel())

        key = (image, float(layer.get("opacity", 1.0)))
        if key not in images:
            m = bpy.data.materials.new(f"decal_{len(images)}")
            nt = m.node_tree
            for nd in list(nt.nodes):
                nt.nodes.remove(nd)
            out = nt.nodes.new("ShaderNodeOutputMaterial")
            ti = nt.nodes.new("ShaderNodeTexImage")
            ti.image = bpy.data.images.load(os.path.join(job_dir, image), check_existing=True)
            ti.image.alpha_mode = "STRAIGHT"
            ti.extension = "CLIP"
            ti.interpolation = "Linear"
            em = nt.nodes.new("ShaderNodeEmission")
            tr = nt.nodes.new("ShaderNodeBsdfTransparent")
            mix = nt.nodes.new("ShaderNodeMixShader")
            op = nt.nodes.new("ShaderNodeMath")
            op.operation = "MULTIPLY"
            op.inputs[1].default_value = key[1]
            nt.links.new(ti.outputs["Color"], em.inputs["Color"])
            nt.links.new(ti.outputs["Alpha"], op.inputs[0])
            nt.links.new(op.outputs[0], mix.inputs[0])
            nt.links.new(tr.outputs[0], mix.inputs[1])
            nt.links.new(em.outputs[0], mix.inputs[2])
            nt.links.new(mix.outputs[0], out.inputs["Surface"])
            images[key] = m
        me.materials.append(images[key])
        ob = bpy.data.objects.new(f"decal{i}", me)
        bpy.context.scene.collection.objects.link(ob)
        planes.append(ob)

    sc = bpy.context.scene
    sc.render.engine = "CYCLES"
    sc.cycles.device = "CPU"
    sc.cycles.samples = a.samples
    sc.cycles.use_adaptive_sampling = False
    sc.cycles.use_denoising = False
    sc.render.film_transparent = True
    sc.render.dither_intensity = 0.0
    ext = a.extrusion if a.extrusion is not None else (depth_max or 10 * lift0)

    # Under the decals, a copy of the mesh moved in along its normals by the cage extrusion, with
    # a transparent material, selected too: every texel's ray then hits something (so the margin
    # grows the UV islands; without it Blender counts the texels no decal covers as outside and
    # extends the decals' edges into them), and only after every quad a decal's ray could reach.
    shell = low.copy()
    shell.data = low.data.copy()
    shell.data.materials.clear()
    nv = len(shell.data.vertices)
    co = np.empty(nv * 3, np.float32)
    nor = np.empty(nv * 3, np.float32)
    shell.data.vertices.foreach_get("co", co)
    shell.data.vertex_normals.foreach_get("vector", nor)
    shell.data.vertices.foreach_set("co", co - ext * nor)
    sm = bpy.data.materials.new("decal_none")
    nt = sm.node_tree
    for nd in list(nt.nodes):
        nt.nodes.remove(nd)
    nt.links.new(nt.nodes.new("ShaderNodeBsdfTransparent").outputs[0],
                 nt.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    shell.data.materials.append(sm)
    sc.collection.objects.link(shell)
    bpy.ops.object.select_all(action="DESELECT")
    for ob in planes + [shell]:
        ob.select_set(True)
    low.select_set(True)
    bpy.context.view_layer.objects.active = low
    t_setup = time.perf_counter() - t0

    # --- bake -----------------------------------------------------------------------------
    t0 = time.perf_counter()
    bpy.ops.object.bake(type="COMBINED", pass_filter={"EMIT"}, use_selected_to_active=True,
                        cage_extrusion=ext, max_ray_distance=3 * ext, margin=margin,
                        margin_type="EXTEND", use_clear=True, target="IMAGE_TEXTURES",
                        save_mode="INTERNAL")
    t_bake = time.perf_counter() - t0

    # --- composite over the base (linear light) -------------------------------------------
    t0 = time.perf_counter()
    dec = pixels(bake_img)  # premultiplied linear RGB, alpha
    if base_img is not None:
        if tuple(base_img.size) != (width, height):
            base_img = base_img.copy()
            base_img.scale(width, height)
        b = pixels(base_img)
        if not base_img.is_float:  # a byte image's pixels are its stored (sRGB) values
            b[..., :3] = SRGB8_TO_LINEAR[(b[..., :3] * 255.0 + 0.5).astype(np.uint8)]
    else:
        b = np.broadcast_to(np.array(base_rgba, np.float32), dec.shape)
    alpha = dec[..., 3:4]
    res = np.empty_like(dec)
    lin = dec[..., :3] + b[..., :3] * (1.0 - alpha)
    np.clip(lin, 0.0, 1.0, out=lin)
    res[..., :3] = LINEAR16_TO_SRGB[(lin * 65535.0 + 0.5).astype(np.uint16)]
    res[..., 3:4] = alpha + b[..., 3:4] * (1.0 - alpha)
    out_img = bpy.data.images.new("decal_out", width, height, alpha=True)
    out_img.pixels.foreach_set(res.ravel())
    t_comp = time.perf_counter() - t0

    t0 = time.perf_counter()
    out_img.filepath_raw = os.path.abspath(a.out)
    out_img.file_format = "PNG"
    out_img.save()
    t_save = time.perf_counter() - t0

    print(json.dumps({
        "peer": "blender", "blender": bpy.app.version_string, "job": a.job,
        "texture": [width, height], "samples": a.samples, "margin": margin,
        "cage_extrusion": ext, "max_ray_distance": 3 * ext, "lift": lift0,
        "layers": len(planes), "layers_skipped": skipped, "blend_as_normal": replaced_blend,
        "threads": sc.render.threads, "faces": len(low.data.polygons),
        "bpy_import_s": T_BPY - T_START, "import_s": t_import, "setup_s": t_setup,
        "bake_s": t_bake, "composite_s": t_comp, "save_s": t_save,
        "total_s": time.perf_counter() - T_START,
    }))


if __name__ == "__main__":
    main()
