# Landform's Blender add-on.
#
# A panel in the 3D view's sidebar (View3D > Sidebar > Landform, `panel.py`) picks a kind and one
# of the server's presets (`GET /v1/presets`), edits its main fields, runs it against a server
# URL and API key with its progress shown, and imports the result at the 3D cursor: the mesh,
# its levels of detail in a hidden collection, the heightmap as an image. Its HTTP is in
# `client.py`, on the standard library alone.
#
# And when a Landform glb is imported with File > Import > glTF 2.0 (or by the panel), the
# levels of detail `mesh.glb` carries (`MSFT_lod`, which
# Blender's importer does not read, so it makes every level a visible object on top of the full
# one) go into a collection of their own, hidden in the viewport and in renders: the scene
# shows each piece once, at full detail, and the collection's eye shows the levels. Each level object
# records which object it is a level of and its number, and each full object its
# `MSFT_screencoverage` hints, as custom properties.
#
# Install: zip this folder (`cd clients/blender && zip -r landform.zip landform`), then
# Edit > Preferences > Add-ons > Install… and tick "3D View: Landform terrain". Needs the glTF
# importer that ships with Blender (3.4 or later: its import hooks).
bl_info = {
    "name": "Landform terrain",
    "author": "Landform",
    "version": (0, 2, 0),
    "blender": (3, 4, 0),
    "location": "View3D > Sidebar > Landform; File > Import > glTF 2.0",
    "description": "Runs Landform terrain jobs from a panel and imports the result at the 3D cursor; "
    "imports Landform's glb files with their levels of detail in a hidden collection",
    "category": "3D View",
}

import bpy

from . import panel

# The collection the levels of detail go into.
LEVELS = "Landform levels of detail"


class glTF2ImportUserExtension:
    """Found by Blender's glTF importer on every enabled add-on that defines it."""

    def gather_import_scene_after_nodes_hook(self, gltf_scene, blender_scene, gltf):
        levels = []
        for index, node in enumerate(gltf.data.nodes or []):
            lod = (node.extensions or {}).get("MSFT_lod")
            if not lod:
                continue
            full = gltf.vnodes[index].blender_object
            coverage = (node.extras or {}).get("MSFT_screencoverage") if isinstance(node.extras, dict) else None
            if full is not None and coverage:
                full["landform_screen_coverage"] = [float(c) for c in coverage]
            for level, node_id in enumerate(lod.get("ids", []), start=1):
                obj = gltf.vnodes[node_id].blender_object
                if obj is None:
                    continue
                obj["landform_lod_of"] = full.name if full is not None else (node.name or "")
                obj["landform_lod_level"] = level
                levels.append(obj)
        if not levels:
            return
        collection = bpy.data.collections.new(LEVELS)
        collection.hide_render = True
        blender_scene.collection.children.link(collection)
        for obj in levels:
            for owner in list(obj.users_collection):
                owner.objects.unlink(obj)
            collection.objects.link(obj)
        for view_layer in blender_scene.view_layers:
            layer = view_layer.layer_collection.children.get(collection.name)
            if layer is not None:
                # Hidden, not excluded: the importer then selects every object it made.
                layer.hide_viewport = True


def register():
    panel.register()


def unregister():
    panel.unregister()
