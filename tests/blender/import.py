# Imports glb files into Blender headless (Debian's Blender 3.4) as an artist would, with
# File > Import > glTF 2.0 and its defaults, and prints one JSON line per file: whether the
# import succeeded (and Blender's error if not), and per object its name, type, parent, scale
# and, for a mesh, its vertex and triangle counts. Used by tests/blender_import.rs.
#
#   blender -b --factory-startup -P tests/blender/import.py -- file.glb [...]
#
# With LANDFORM_BLENDER_ADDON set to a folder holding an add-on package (clients/blender), the
# `landform` add-on is enabled for every import, as a user who installed it would have it.
import json
import os
import sys

import numpy

# Blender 3.4's glTF importer still uses `numpy.bool`, which numpy removed.
numpy.bool = bool
import bpy  # noqa: E402

for path in sys.argv[sys.argv.index("--") + 1:]:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    addons = os.environ.get("LANDFORM_BLENDER_ADDON")
    if addons:
        import addon_utils

        if addons not in sys.path:
            sys.path.insert(0, addons)
        addon_utils.enable("landform", default_set=True)
    report = {"path": path}
    try:
        result = bpy.ops.import_scene.gltf(filepath=path)
        report["result"] = sorted(result)
    except Exception as error:  # the importer raises on files it cannot read
        report["error"] = str(error).strip().splitlines()[-1] if str(error).strip() else repr(error)
    objects = []
    for obj in bpy.data.objects:
        entry = {
            "name": obj.name,
            "type": obj.type,
            "parent": obj.parent.name if obj.parent else None,
            "scale": [round(v, 9) for v in obj.scale],
            "location": [round(v, 6) for v in obj.location],
            "shown": obj.visible_get(),
            "rendered": not obj.hide_render and not any(c.hide_render for c in obj.users_collection),
            "collections": sorted(c.name for c in obj.users_collection),
            "lod_of": obj.get("landform_lod_of"),
            "lod_level": obj.get("landform_lod_level"),
        }
        if obj.type == "MESH":
            mesh = obj.data
            mesh.calc_loop_triangles()
            entry["vertices"] = len(mesh.vertices)
            entry["triangles"] = len(mesh.loop_triangles)
            entry["uv_layers"] = len(mesh.uv_layers)
        objects.append(entry)
    report["objects"] = objects
    print("LANDFORM " + json.dumps(report), flush=True)
