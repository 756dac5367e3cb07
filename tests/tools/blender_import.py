"""Import a .glb in Blender (background mode) and print what came in as one JSON line after ``IMPORTED``.

Usage: blender --background --factory-startup --python blender_import.py -- FILE.glb FPS
"""
import json
import sys

import bpy

path, fps = sys.argv[sys.argv.index("--") + 1], int(sys.argv[sys.argv.index("--") + 2])
bpy.context.scene.render.fps = fps
# 'SMOOTH' shading: the 'NORMALS' default of Debian's Blender 3.4 importer calls np.bool, gone from NumPy >= 1.24
bpy.ops.import_scene.gltf(filepath=path, import_shading="SMOOTH")
mesh = next(obj for obj in bpy.context.scene.objects if obj.type == "MESH")
print("IMPORTED " + json.dumps({
    "vertices": len(mesh.data.vertices), "polygons": len(mesh.data.polygons),
    "shape_keys": [key.name for key in mesh.data.shape_keys.key_blocks],
    "actions": [(action.name, list(action.frame_range), len(action.fcurves)) for action in bpy.data.actions],
}))
