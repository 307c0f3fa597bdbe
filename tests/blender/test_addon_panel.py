# The Blender add-on's panel against a real `landform serve`, headless in Debian's Blender 3.4.
# Run by scripts/blender-addon-tests, which starts the server (with an API key) and points
# BLENDER_USER_SCRIPTS and BLENDER_USER_CONFIG at a temporary directory:
#
#   blender -b --factory-startup --python-exit-code 1 -P tests/blender/test_addon_panel.py -- URL KEY
#
# It installs the add-on from a zip as a user would (Preferences > Add-ons > Install…), loads the
# server's presets, runs a bulldoze preset (its fractal terrain shrunk to 65 × 65) through the
# operator, and checks what it imported against the job's own `mesh.glb`, read here with
# struct and json: the full-resolution object's vertex count, its place at the 3D cursor, the
# levels of detail in their hidden collection, the heightmap image; then the non-blocking path
# (the timer's work, driven by hand: headless Blender runs no timers), a cancel, errors that
# name the server's bad field, and unregistering.
import json
import os
import struct
import sys
import tempfile
import time
import urllib.request
import zipfile

import numpy

# Blender 3.4's glTF importer still uses `numpy.bool`, which numpy removed.
numpy.bool = bool
import addon_utils  # noqa: E402
import bpy  # noqa: E402

STARTED = time.monotonic()
REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ARGV = sys.argv[sys.argv.index("--") + 1:]
URL, KEY = ARGV[0], ARGV[1] if len(ARGV) > 1 else ""
LEVELS = "Landform levels of detail"
CURSOR = (10.0, 0.0, -5.0)
CHECKS = []


def check(condition, what):
    if not condition:
        raise AssertionError(what)
    CHECKS.append(what)
    print(f"ok   {what}", flush=True)


def get(path, raw=False):
    request = urllib.request.Request(URL + path, headers={"Authorization": f"Bearer {KEY}"} if KEY else {})
    with urllib.request.urlopen(request, timeout=30) as response:
        data = response.read()
    return data if raw else json.loads(data)


def glb_document(data):
    """The JSON chunk of a binary glTF."""
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    assert magic == b"glTF" and version == 2 and length == len(data), (magic, version, length)
    chunk_length, chunk_type = struct.unpack_from("<I4s", data, 12)
    assert chunk_type == b"JSON", chunk_type
    return json.loads(data[20:20 + chunk_length].decode("utf-8"))


def node_vertices(doc, node):
    mesh = doc["meshes"][node["mesh"]]
    return sum(doc["accessors"][p["attributes"]["POSITION"]]["count"] for p in mesh["primitives"])


def full_and_level_nodes(doc):
    """The full-resolution mesh nodes and the level nodes: a node another node's `MSFT_lod.ids`
    lists is a level of it, every other node with a mesh is a full piece."""
    levels = set()
    for node in doc.get("nodes", []):
        levels.update(((node.get("extensions") or {}).get("MSFT_lod") or {}).get("ids", []))
    nodes = doc.get("nodes", [])
    full = [n for i, n in enumerate(nodes) if "mesh" in n and i not in levels]
    return full, [nodes[i] for i in sorted(levels)]


def expect_error(fields, *, operator="run"):
    """Runs an operator that must fail; returns Blender's report."""
    try:
        getattr(bpy.ops.landform, operator)(**({"wait": True} if operator == "run" else {}))
    except RuntimeError as error:
        report = str(error)
    else:
        raise AssertionError(f"landform.{operator} succeeded, expected an error naming {fields}")
    for field in fields:
        assert field in report, f"{field!r} not in {report!r}"
    return report


bpy.ops.wm.read_factory_settings(use_empty=True)

# --- Install from a zip into the temporary user scripts folder, then enable. --------------------
user_scripts = bpy.utils.user_resource("SCRIPTS")
check(
    os.environ.get("BLENDER_USER_SCRIPTS") and os.path.realpath(user_scripts) == os.path.realpath(os.environ["BLENDER_USER_SCRIPTS"]),
    f"Blender's user scripts folder is the temporary one ({user_scripts})",
)
work = tempfile.mkdtemp(prefix="landform-addon-test-")
archive = os.path.join(work, "landform.zip")
source = os.path.join(REPO, "clients", "blender", "landform")
with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as z:
    for name in sorted(os.listdir(source)):
        if name.endswith(".py"):
            z.write(os.path.join(source, name), f"landform/{name}")
check(bpy.ops.preferences.addon_install(filepath=archive) == {"FINISHED"}, "the zip installs")
check(bpy.ops.preferences.addon_enable(module="landform") == {"FINISHED"}, "the add-on enables")
import landform  # noqa: E402

check(os.path.realpath(landform.__file__).startswith(os.path.realpath(user_scripts)), f"it runs from the installed copy ({landform.__file__})")
info = addon_utils.module_bl_info(landform)
check(info["name"] == "Landform terrain" and info["category"] == "3D View" and tuple(info["version"]) >= (0, 2, 0), f"bl_info {info['name']!r} {info['category']!r} {info['version']}")
check(hasattr(bpy.types, "LANDFORM_PT_panel") and bpy.types.LANDFORM_PT_panel.bl_category == "Landform", "the sidebar panel is registered, tab Landform")
check(bpy.types.LANDFORM_PT_panel.bl_space_type == "VIEW_3D" and bpy.types.LANDFORM_PT_panel.bl_region_type == "UI", "in the 3D view's sidebar")
for op in ("load_presets", "run", "cancel", "body_to_text"):
    check(hasattr(bpy.ops.landform, op), f"operator landform.{op}")

scene = bpy.context.scene
s = scene.landform
check(s.server_url == "http://127.0.0.1:8080" and s.bl_rna.properties["api_key"].subtype == "PASSWORD", "defaults: URL, a password key")
s.server_url = URL

# --- The key: refused without, presets with. ------------------------------------------------------
if KEY:
    report = expect_error([], operator="load_presets")
    check(s.failed, f"without the key: {report}")
    s.api_key = KEY
check(bpy.ops.landform.load_presets() == {"FINISHED"}, "load presets")
server_presets = get("/v1/presets")["items"]
bulldoze_names = [p["name"] for p in server_presets if p["kind"] == "bulldoze"]
enum_kinds = [i[0] for i in landform.panel._kind_items(s, bpy.context)]
check(sorted(enum_kinds) == sorted({p["kind"] for p in server_presets}), f"kinds from the presets: {enum_kinds}")
s.kind = "bulldoze"
offered = [i[0] for i in landform.panel._preset_items(s, bpy.context)]
check(offered == bulldoze_names and len(offered) > 0, f"bulldoze presets filtered by kind: {offered}")
s.kind = "grow-cave"
check(not s.has_fractal, f"a grow-cave preset ({s.preset}) has no fractal terrain fields")
s.kind = "bulldoze"
name = "ziggurat" if "ziggurat" in offered else offered[0]
s.preset = name
body = next(p["body"] for p in server_presets if p["kind"] == "bulldoze" and p["name"] == name)
fractal = (body.get("terrain") or {}).get("fractal")
check(s.has_fractal == (fractal is not None), f"preset {name}: fractal fields shown {s.has_fractal}")
if fractal is not None:
    check(s.size == fractal["size"] and abs(s.relief - fractal["relief"]) < 1e-6, f"fields filled from the preset: size {s.size}, relief {s.relief}")
    s.size = 65  # a quick run
check(s.seed == body.get("seed", 0), f"seed {s.seed}")
s.seed = 5
sent = landform.panel.request_body(s)
check(sent["seed"] == 5 and (fractal is None or sent["terrain"]["fractal"]["size"] == 65), "the fields go into the request")
check(sent["operations"] == body["operations"], "the rest is the preset's")

merge = landform.client.deep_merge
check(
    merge({"terrain": {"fractal": {"size": 9}}, "a": [1]}, {"terrain": {"fractal": None, "job": "x"}, "a": [2]})
    == {"terrain": {"job": "x"}, "a": [2]},
    "the JSON override merges as a JSON merge patch",
)


class Layout:
    """Stands in for the panel's UILayout (headless Blender draws nothing) and checks each call:
    properties that exist, icons Blender knows, operators that are registered."""

    ICONS = set(bpy.types.UILayout.bl_rna.functions["label"].parameters["icon"].enum_items.keys())
    drawn = []

    def __getattr__(self, name):
        if name in ("column", "row", "box", "split"):
            return lambda *a, **k: Layout()
        raise AttributeError(name)

    def __setattr__(self, name, value):
        pass  # alert, scale_y, enabled …

    def _icon(self, kw):
        assert kw.get("icon", "NONE") in self.ICONS, kw

    def prop(self, data, name, **kw):
        assert name in data.bl_rna.properties, name
        self._icon(kw)
        Layout.drawn.append(name)

    def prop_search(self, data, name, search_data, search_name, **kw):
        assert name in data.bl_rna.properties and hasattr(search_data, search_name), (name, search_name)
        Layout.drawn.append(name)

    def operator(self, idname, **kw):
        module, op = idname.split(".")
        assert op in dir(getattr(bpy.ops, module)), idname
        self._icon(kw)
        Layout.drawn.append(idname)

    def label(self, **kw):
        self._icon(kw)


class Panel:
    layout = Layout()


bpy.types.LANDFORM_PT_panel.draw(Panel(), bpy.context)
check(
    {"server_url", "api_key", "kind", "preset", "seed", "size", "relief", "override_text", "progress",
     "landform.load_presets", "landform.run", "landform.cancel"} <= set(Layout.drawn),
    f"the panel draws {Layout.drawn}",
)

# --- Run it, blocking, and import at the cursor. --------------------------------------------------
scene.cursor.location = CURSOR
t = time.monotonic()
check(bpy.ops.landform.run(wait=True) == {"FINISHED"}, "run (wait=True)")
print(f"     run took {time.monotonic() - t:.1f} s", flush=True)
job = get(f"/v1/jobs/{s.job_id}")
check(job["status"] == "succeeded" and job["request"]["seed"] == 5, f"job {job['id']} succeeded with seed 5")
check(s.progress == 1.0 and not s.failed and not s.running, f"progress 1, {s.stage}: {s.message}")
artifacts = {a["name"]: a for a in job["artifacts"]}
doc = glb_document(get(artifacts["mesh.glb"]["href"], raw=True))
full_nodes, level_nodes = full_and_level_nodes(doc)
check(len(full_nodes) == 1 and len(level_nodes) == 3, f"the glb: {len(full_nodes)} full node, {len(level_nodes)} levels")
want = node_vertices(doc, full_nodes[0])
if "mesh" in (job.get("result") or {}):
    check(job["result"]["mesh"]["vertices"] == want, f"the result states the glb's {want} vertices")
imported = [o for o in bpy.data.objects if o.get("landform_job") == job["id"]]
full = [o for o in imported if o.type == "MESH" and o.get("landform_lod_of") is None]
levels = [o for o in imported if o.get("landform_lod_level") is not None]
check(len(full) == 1, f"one full object imported: {[o.name for o in full]}")
terrain = full[0]
check(len(terrain.data.vertices) == want, f"{terrain.name}: {len(terrain.data.vertices)} vertices, the glb's full node {want}")
translation = full_nodes[0].get("translation", [0.0, 0.0, 0.0])
pivot = (translation[0], -translation[2], translation[1])  # glTF y-up → Blender z-up
where = tuple(terrain.location)
check(all(abs(w - (c + p)) < 1e-4 for w, c, p in zip(where, CURSOR, pivot)), f"at the cursor: {where} = {CURSOR} + pivot {pivot}")
check(terrain.visible_get() and terrain.parent is None, "shown, top level")
check(len(levels) == 3 and all(not o.visible_get() for o in levels), f"3 levels, hidden: {[o.name for o in levels]}")
collections = {c.name for o in levels for c in o.users_collection}
check(len(collections) == 1 and next(iter(collections)).startswith(LEVELS), f"levels in their collection {collections}")
collection = bpy.data.collections[next(iter(collections))]
check(collection.hide_render and collection.name in scene.collection.children, "the collection is in the scene, not rendered")
for obj in levels:
    node = next(n for n in level_nodes if n.get("name") == obj.name)
    check(len(obj.data.vertices) == node_vertices(doc, node), f"{obj.name}: {len(obj.data.vertices)} vertices as its node")
    check(all(abs(a - b) < 1e-4 for a, b in zip(obj.location, where)), f"{obj.name} moved with it")
image = bpy.data.images.get(f"{job['id']} heightmap")
if "heightmap.png" in artifacts:
    check(image is not None and tuple(image.size) == (65, 65) and image.packed_file is not None, f"heightmap image {image and image.name} {tuple(image.size) if image else None}, packed")
else:
    check(image is None, "no heightmap, no image")

# --- The non-blocking path: the timer's callback, driven by hand. ---------------------------------
scene.cursor.location = (0.0, 0.0, 0.0)
s.seed = 6
check(bpy.ops.landform.run() == {"FINISHED"}, "run (non-blocking)")
check(s.running and scene.name in landform.panel._runs, "running, the run is followed")
seen = []
deadline = time.monotonic() + 60
while landform.panel._tick(scene.name) is not None:
    seen.append((round(s.progress, 3), s.stage))
    assert time.monotonic() < deadline, seen
    time.sleep(0.05)
check(not s.running and not s.failed and s.progress == 1.0, f"done by the timer: {s.stage}, {s.message}; {len(seen)} ticks, stages {sorted({st for _, st in seen})}")
second = [o for o in bpy.data.objects if o.get("landform_job") == s.job_id and o.get("landform_lod_of") is None]
check(len(second) == 1 and abs(second[0].location.x - pivot[0]) < 1e-4, "imported too, at the cursor (0, 0, 0)")

# --- Cancel: a long job, cancelled at once. -------------------------------------------------------
s.preset = name
s.seed = 7
s.lods = False
if s.has_fractal:
    s.size = 1025
check(bpy.ops.landform.run() == {"FINISHED"}, "run a long one")
check(bpy.ops.landform.cancel() == {"FINISHED"}, "cancel")
deadline = time.monotonic() + 60
while landform.panel._tick(scene.name) is not None:
    assert time.monotonic() < deadline, (s.stage, s.message)
    time.sleep(0.05)
check(s.failed and "cancel" in s.message.lower(), f"cancelled: {s.message}")
check(get(f"/v1/jobs/{s.job_id}")["status"] == "cancelled", "the server says cancelled")
check(bpy.ops.landform.cancel.poll() is False, "nothing left to cancel")

# --- Errors name the server's field. --------------------------------------------------------------
s.lods = True
s.size = 1
report = expect_error(["terrain.fractal.size", "Invalid request"])
check(s.failed and "terrain.fractal.size" in s.message, f"size 1: {report}")
s.size = 65
text = bpy.data.texts.new("override.json")
text.write('{"terrain": {"fractal": {"relief": -1}}}')
s.override_text = text.name
report = expect_error(["terrain.fractal.relief"])
check(True, f"JSON override relief -1: {report}")
text.clear()
text.write("{not json")
report = expect_error(["not JSON"])
check(True, f"a broken override is refused before sending: {report}")
s.override_text = ""
s.server_url = "http://127.0.0.1:9"
report = expect_error(["Cannot reach"])
check(True, f"no server: {report}")
s.server_url = URL
check(bpy.ops.landform.body_to_text() == {"FINISHED"} and json.loads(bpy.data.texts[s.override_text].as_string())["seed"] == 7, "body to text")

# --- Unregister. ---------------------------------------------------------------------------------
check(bpy.ops.preferences.addon_disable(module="landform") == {"FINISHED"}, "the add-on disables")
check(not hasattr(bpy.types, "LANDFORM_PT_panel") and not hasattr(bpy.types.Scene, "landform"), "panel and settings unregistered")
check("run" not in dir(bpy.ops.landform), "operators unregistered")
check(bpy.ops.preferences.addon_enable(module="landform") == {"FINISHED"} and hasattr(bpy.types, "LANDFORM_PT_panel"), "and enables again")
bpy.ops.preferences.addon_disable(module="landform")

print(f"PASS {len(CHECKS)} checks in {time.monotonic() - STARTED:.1f} s", flush=True)
