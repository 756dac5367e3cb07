"""Play back .glb files in Blender (background mode) and write the evaluated mesh at chosen keys.

Usage: blender --background --factory-startup --python blender_playback.py -- REQUEST.json

REQUEST is ``{"files": [{"glb": PATH, "out": NPZ, "keys": {ANIMATION: [KEY INDEX, ...]}}]}``; an animation named
``""`` means the only one of a file without the workbench's takes. A workbench .glb is imported with the recipe of docs/export.md (run from there, so
the documented recipe is the tested one); a .glb without the workbench's takes is imported plainly at its
``asset.extras.frame_rate`` rounded. For each file the mesh is evaluated through the depsgraph (shape keys, slider
ranges and all) at the frame of each chosen key, and ``NPZ`` gets ``positions`` (n_keys, n_vertices, 3) in
Blender's coordinates (metres, +Z up) and ``frames`` (n_keys,); one line ``IMPORTED {json}`` per file says what
came in (vertices, polygons, shape keys with their slider ranges, actions with their frame ranges, scene rate).
"""

import json
import math
import re
import sys
from pathlib import Path

import bpy
import numpy as np

DOC = Path(__file__).resolve().parents[2] / "docs" / "export.md"
RECIPE = re.search(r"<!-- blender-recipe[^>]*-->\s*```python\n(.*?)```", DOC.read_text(), re.S).group(1)
recipe = {}
exec(compile(RECIPE, str(DOC), "exec"), recipe)


def evaluated_positions(face):
    """The face's vertices as Blender shows them at the current frame, shape (n_vertices, 3)."""
    evaluated = face.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    positions = np.empty(3 * len(mesh.vertices), dtype=np.float32)
    mesh.vertices.foreach_get("co", positions)
    evaluated.to_mesh_clear()
    return positions.reshape(-1, 3)


def play(item):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    extras = recipe["workbench_extras"](item["glb"])
    if "takes" in extras:
        face, extras = recipe["import_workbench_glb"](item["glb"])
    else:
        bpy.context.scene.render.fps = max(1, round(extras.get("frame_rate", 24)))
        bpy.ops.import_scene.gltf(filepath=item["glb"], import_shading="SMOOTH")
        face = bpy.context.view_layer.objects.active
    scene, animation_data = bpy.context.scene, face.data.shape_keys.animation_data
    tracks = {track.name: track.strips[0].action for track in animation_data.nla_tracks}
    positions, frames = [], []
    for name, indices in item["keys"].items():
        if "takes" in extras:
            recipe["show_take"](face, extras, [take["animation"] for take in extras["takes"]].index(name))
        else:
            animation_data.action = tracks[name] if name else next(iter(tracks.values()))
        keys = animation_data.action.fcurves[0].keyframe_points
        for index in indices:
            frame = keys[index].co.x  # a float32 frame, evaluated exactly there
            whole = math.floor(frame)
            scene.frame_set(whole, subframe=frame - whole)
            positions.append(evaluated_positions(face))
            frames.append(frame)
    np.savez(item["out"], positions=np.array(positions), frames=np.array(frames))
    blocks = face.data.shape_keys.key_blocks
    print(
        "IMPORTED "
        + json.dumps(
            {
                "glb": item["glb"],
                "vertices": len(face.data.vertices),
                "polygons": len(face.data.polygons),
                "shape_keys": [[block.name, block.slider_min, block.slider_max] for block in blocks],
                "actions": {name: list(action.frame_range) for name, action in tracks.items()},
                "fps": scene.render.fps,
                "fps_base": scene.render.fps_base,
                "frame_range": [scene.frame_start, scene.frame_end],
            }
        ),
        flush=True,
    )


request = json.loads(Path(sys.argv[sys.argv.index("--") + 1]).read_text())
for item in request["files"]:
    play(item)
