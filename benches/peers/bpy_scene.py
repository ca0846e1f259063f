# SPDX-License-Identifier: MIT OR Apache-2.0
"""What the Blender peers share: a glTF model imported into an empty scene as one mesh object."""
import bpy


def import_joined(path, **options):
    """Empties the scene, imports the glTF at `path` (importer `options` passed on), joins its mesh
    objects into one and returns it (the active object)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=path, **options)
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    bpy.ops.object.select_all(action="DESELECT")
    for o in meshes:
        o.select_set(True)
    bpy.context.view_layer.objects.active = meshes[0]
    if len(meshes) > 1:
        bpy.ops.object.join()
    return bpy.context.view_layer.objects.active
