# The add-on's panel (View3D > Sidebar > Landform): pick a kind and one of the server's presets
# (`GET /v1/presets`), edit its main fields, run it against a server, follow its progress and
# import the result at the 3D cursor.
#
# A run's HTTP (submit, polls of `GET /v1/jobs/{id}`, downloads) happens in a thread of its own
# (`client.Run`); a `bpy.app.timers` callback copies its progress into the scene's settings,
# redraws the panel, and once the artifacts are downloaded imports them in Blender's main
# thread. `bpy.ops.landform.run(wait=True)` (or `run_blocking()`) does the same in the caller's
# thread, for scripts and headless tests.
import json

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty

from . import client as api

# The kinds offered before presets are loaded (the server's: `POST /v1/jobs/{kind}`).
KINDS = ("bulldoze", "carve-coast", "deform-terrain", "erode", "grow-cave", "weather-column")
NO_PRESET = "NONE"

# Loaded presets: {kind: [preset, ...]}, in the server's order. Module state, not saved with
# the file: press "Load presets" again after opening one.
_presets = {}
# Enum items handed to Blender must stay referenced from Python (a Blender requirement for
# dynamic items), so each list is kept here.
_items = {"kinds": [], "presets": {}}
# The run in flight, by scene name.
_runs = {}


def presets_of(kind):
    return _presets.get(kind, [])


def preset(kind, name):
    for p in presets_of(kind):
        if p.get("name") == name:
            return p
    return None


def set_presets(items):
    """Replaces the loaded presets with the server's list."""
    _presets.clear()
    for p in items:
        if isinstance(p, dict) and p.get("kind") and p.get("name"):
            _presets.setdefault(p["kind"], []).append(p)
    _items["presets"].clear()


def _kind_items(self, context):
    kinds = list(_presets) or list(KINDS)
    items = [(k, k, f"POST /v1/jobs/{k}") for k in kinds]
    _items["kinds"] = items
    return items


def _preset_items(self, context):
    kind = self.kind
    if kind not in _items["presets"]:
        items = []
        for p in presets_of(kind):
            label = p.get("label") or ""
            items.append((p["name"], p["name"], label[:400]))
        if not items:
            items = [(NO_PRESET, "(no presets: load them)", "Press Load presets, or run the kind's defaults")]
        _items["presets"][kind] = items
    return _items["presets"][kind]


def _kind_changed(self, context):
    items = _preset_items(self, context)
    if items and items[0][0] != self.preset:
        self.preset = items[0][0]
    else:
        _preset_changed(self, context)


def _preset_changed(self, context):
    """Fills the panel's fields from the chosen preset's body."""
    p = preset(self.kind, self.preset)
    body = p["body"] if p else {}
    self.seed = _clamp_int(body.get("seed", 0))
    fractal = api.fractal_of(body)
    self.has_fractal = fractal is not None
    if fractal is not None:
        self.size = _clamp_int(fractal.get("size", 257))
        self.cell_size = float(fractal.get("cell_size", 1.0))
        self.relief = float(fractal.get("relief", 120.0))
        self.terrain_seed = _clamp_int(fractal.get("seed", 7))
    self.lods = body.get("lods") != []
    self.preset_label = (p.get("label") or "") if p else ""


def _clamp_int(value):
    try:
        return max(0, min(int(value), 2**31 - 1))
    except (TypeError, ValueError):
        return 0


class LandformSettings(bpy.types.PropertyGroup):
    server_url: StringProperty(name="Server", description="The Landform server's base URL", default=api.DEFAULT_URL)
    api_key: StringProperty(
        name="API key",
        description="Sent as `Authorization: Bearer KEY` (servers run with --api-keys); empty: none",
        subtype="PASSWORD",
        default="",
    )
    kind: EnumProperty(name="Kind", description="The job kind", items=_kind_items, update=_kind_changed)
    preset: EnumProperty(name="Preset", description="One of the server's example requests", items=_preset_items, update=_preset_changed)
    preset_label: StringProperty(name="Label", default="")
    seed: IntProperty(name="Seed", description="The request's `seed`", min=0, default=0)
    lods: BoolProperty(name="Levels of detail", description="Off: `lods: []` (no levels)", default=True)
    has_fractal: BoolProperty(name="Fractal terrain", default=False, options={"HIDDEN"})
    size: IntProperty(
        name="Size", description="terrain.fractal.size: samples along each side", min=0, soft_min=2, soft_max=4097, default=257
    )
    cell_size: FloatProperty(
        name="Cell size", description="terrain.fractal.cell_size: metres between samples", min=0.0, soft_min=0.01, default=1.0, unit="LENGTH"
    )
    relief: FloatProperty(
        name="Relief", description="terrain.fractal.relief: height range in metres", min=0.0, default=120.0, unit="LENGTH"
    )
    terrain_seed: IntProperty(name="Terrain seed", description="terrain.fractal.seed", min=0, default=7)
    override_text: StringProperty(
        name="JSON override",
        description="A text block holding a JSON object merged over the request (it wins over the fields above)",
        default="",
    )
    # Where the last run is.
    job_id: StringProperty(name="Job", default="")
    running: BoolProperty(name="Running", default=False)
    progress: FloatProperty(name="Progress", subtype="FACTOR", min=0.0, max=1.0, default=0.0)
    stage: StringProperty(name="Stage", default="")
    message: StringProperty(name="Message", default="")
    failed: BoolProperty(name="Failed", default=False)


def settings(context):
    return context.scene.landform


def fields_of(s):
    fields = {"seed": s.seed, "lods": s.lods}
    if s.has_fractal:
        fields.update(size=s.size, cell_size=round(s.cell_size, 6), relief=round(s.relief, 6), terrain_seed=s.terrain_seed)
    return fields


def request_body(s):
    """The body the panel would post: preset, fields, then the JSON override."""
    p = preset(s.kind, s.preset)
    override = None
    if s.override_text:
        text = bpy.data.texts.get(s.override_text)
        if text is None:
            raise ValueError(f"no text block named {s.override_text!r}")
        override = api.parse_override(text.as_string())
    return api.build_body(p["body"] if p else {}, fields_of(s), override)


def client_of(s):
    return api.Client(s.server_url, s.api_key)


# --- Importing ----------------------------------------------------------------------------------


def _view3d_override():
    """A window and 3D view to run the glTF importer in from a timer (no context of its own)."""
    wm = bpy.context.window_manager
    for window in getattr(wm, "windows", []):
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                region = next((r for r in area.regions if r.type == "WINDOW"), None)
                return {"window": window, "area": area, "region": region}
    return None


def import_result(scene, job, files):
    """Imports a finished job's downloaded `mesh.glb` (the glTF importer; the add-on's hook puts
    the levels of detail in their hidden collection) with its top-level objects moved by the 3D
    cursor, and its `heightmap.png` as an image named after the job. Returns (objects, image)."""
    before = set(bpy.data.objects)
    if "mesh.glb" in files:
        override = _view3d_override() if bpy.context.window is None else None
        if override:
            with bpy.context.temp_override(**override):
                bpy.ops.import_scene.gltf(filepath=files["mesh.glb"])
        else:
            bpy.ops.import_scene.gltf(filepath=files["mesh.glb"])
    new = [o for o in bpy.data.objects if o not in before]
    cursor = scene.cursor.location.copy()
    for obj in new:
        obj["landform_job"] = job["id"]
        if obj.parent is None or obj.parent not in new:
            obj.location = obj.location + cursor
    image = None
    if "heightmap.png" in files:
        name = f"{job['id']} heightmap"
        old = bpy.data.images.get(name)
        if old is not None:
            bpy.data.images.remove(old)
        image = bpy.data.images.load(files["heightmap.png"], check_existing=False)
        image.name = name
        image.colorspace_settings.name = "Non-Color"  # 16-bit heights, not colours
        image.pack()  # the downloaded file is removed after importing
        image["landform_job"] = job["id"]
        for key in ("z_min", "z_max"):
            value = (job.get("result") or {}).get(key)
            if isinstance(value, (int, float)):
                image["landform_" + key] = float(value)
    return new, image


# --- Runs -------------------------------------------------------------------------------------


def _redraw():
    wm = bpy.context.window_manager
    for window in getattr(wm, "windows", []):
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()


def _apply(s, snap):
    s.progress = snap["fraction"]
    s.stage = snap["stage"] or ""
    s.message = snap["message"] or ""
    if snap["job_id"]:
        s.job_id = snap["job_id"]


def finish(scene, run):
    """The end of a run, in the main thread: imports a downloaded result, or records why not.
    Returns (objects, image) on success, raises `api.ApiError`/`RuntimeError` otherwise."""
    s = scene.landform
    _apply(s, run.snapshot())
    s.running = False
    _runs.pop(scene.name, None)
    try:
        if run.state != "downloaded":
            s.failed = True
            s.message = str(run.error or run.state)
            if isinstance(run.error, api.ApiError):
                raise run.error
            raise RuntimeError(s.message)
        try:
            objects, image = import_result(scene, run.job, run.files)
        except Exception as error:
            s.failed = True
            s.message = f"import failed: {error}"
            raise
        meshes = [o for o in objects if o.type == "MESH" and o.get("landform_lod_of") is None]
        s.failed = False
        s.stage = "imported"
        s.message = f"{len(meshes)} object(s)" + (f", image {image.name!r}" if image else "")
        return objects, image
    finally:
        run.cleanup()


def _tick(scene_name):
    """The timer: copies a run's progress into its scene's settings, and finishes it."""
    run = _runs.get(scene_name)
    scene = bpy.data.scenes.get(scene_name)
    if run is None or scene is None:
        return None
    if not run.finished:
        _apply(scene.landform, run.snapshot())
        _redraw()
        return 0.2
    try:
        finish(scene, run)
    except Exception as error:  # shown in the panel (a timer has no operator to report with)
        print(f"Landform: {error}")
        _popup(str(error))
    _redraw()
    return None


def _popup(message):
    """An error popup in the first window, if there is one (never headless)."""
    wm = bpy.context.window_manager
    windows = list(getattr(wm, "windows", []))
    if bpy.app.background or not windows:  # headless Blender keeps a window it cannot draw
        return

    def draw(menu, context):
        for line in _wrap(message, 70)[:8]:
            menu.layout.label(text=line)

    try:
        with bpy.context.temp_override(window=windows[0]):
            wm.popup_menu(draw, title="Landform", icon="ERROR")
    except Exception:
        pass


@bpy.app.handlers.persistent
def _on_load(_):
    """A run does not outlive the file it was started in: its timer ends, its settings say so."""
    _runs.clear()
    for scene in bpy.data.scenes:
        s = getattr(scene, "landform", None)
        if s is not None and s.running:
            s.running = False
            s.message = "interrupted (file loaded)"


def start(scene, kind, body):
    """Starts a run in a thread, followed by a timer. Returns the `api.Run`."""
    s = scene.landform
    run = api.Run(client_of(s), kind, body)
    _runs[scene.name] = run
    s.running, s.failed, s.job_id = True, False, ""
    s.progress, s.stage, s.message = 0.0, "submitting", ""
    run.start()
    bpy.app.timers.register(lambda: _tick(scene.name), first_interval=0.1)
    return run


def run_blocking(scene, kind=None, body=None, timeout=600):
    """Runs the panel's request (or `kind` and `body`) to the end in this thread and imports it.
    Returns (job, objects, image); raises `api.ApiError` for a problem+json answer."""
    s = scene.landform
    kind = kind or s.kind
    body = request_body(s) if body is None else body
    run = api.Run(client_of(s), kind, body, timeout=timeout)
    _runs[scene.name] = run
    s.running, s.failed, s.job_id = True, False, ""
    s.progress, s.stage, s.message = 0.0, "submitting", ""
    run.run()
    objects, image = finish(scene, run)
    return run.job, objects, image


# --- Operators ----------------------------------------------------------------------------------


class LANDFORM_OT_load_presets(bpy.types.Operator):
    bl_idname = "landform.load_presets"
    bl_label = "Load presets"
    bl_description = "Read the server's example requests (GET /v1/presets)"

    def execute(self, context):
        s = settings(context)
        try:
            items = client_of(s).presets()
        except api.ApiError as error:
            s.failed, s.message = True, str(error)
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        set_presets(items)
        kinds = list(_presets)
        if kinds:
            s.kind = s.kind if s.kind in kinds else kinds[0]
        _kind_changed(s, context)
        s.failed, s.message = False, f"{len(items)} presets"
        self.report({"INFO"}, f"Landform: {len(items)} presets of {len(kinds)} kinds")
        return {"FINISHED"}


class LANDFORM_OT_run(bpy.types.Operator):
    bl_idname = "landform.run"
    bl_label = "Run"
    bl_description = "Submit the request, follow its progress and import the result at the 3D cursor"

    wait: BoolProperty(
        name="Wait", description="Block until the job is done and imported (scripts, headless)", default=False,
        options={"SKIP_SAVE"},
    )

    @classmethod
    def poll(cls, context):
        return context.scene is not None and context.scene.name not in _runs

    def execute(self, context):
        s = settings(context)
        try:
            body = request_body(s)
        except ValueError as error:
            s.failed, s.message = True, str(error)
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        if not self.wait:
            start(context.scene, s.kind, body)
            return {"FINISHED"}
        try:
            job, objects, image = run_blocking(context.scene, s.kind, body)
        except (api.ApiError, RuntimeError) as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Landform: job {job['id']}: {s.message}")
        return {"FINISHED"}


class LANDFORM_OT_cancel(bpy.types.Operator):
    bl_idname = "landform.cancel"
    bl_label = "Cancel"
    bl_description = "Cancel the running job (POST /v1/jobs/{id}/cancel)"

    @classmethod
    def poll(cls, context):
        return context.scene is not None and context.scene.name in _runs

    def execute(self, context):
        run = _runs.get(context.scene.name)
        if run is None:
            return {"CANCELLED"}
        try:
            run.cancel()
        except api.ApiError as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        settings(context).message = "cancelling"
        return {"FINISHED"}


class LANDFORM_OT_body_to_text(bpy.types.Operator):
    bl_idname = "landform.body_to_text"
    bl_label = "Body to text"
    bl_description = "Write the request the panel would send into a new text block and use it as the JSON override"

    def execute(self, context):
        s = settings(context)
        try:
            body = request_body(s)
        except ValueError as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        text = bpy.data.texts.new(f"landform-{s.kind}-{s.preset}.json")
        text.write(json.dumps(body, indent=2) + "\n")
        s.override_text = text.name
        return {"FINISHED"}


class LANDFORM_PT_panel(bpy.types.Panel):
    bl_idname = "LANDFORM_PT_panel"
    bl_label = "Landform"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Landform"

    def draw(self, context):
        layout = self.layout
        s = settings(context)
        col = layout.column(align=True)
        col.prop(s, "server_url")
        col.prop(s, "api_key")
        layout.operator("landform.load_presets", icon="FILE_REFRESH")

        col = layout.column()
        if not _presets:
            col.label(text="No presets loaded yet", icon="INFO")
        col.prop(s, "kind")
        col.prop(s, "preset")
        if s.preset_label:
            box = col.box()
            box.scale_y = 0.7
            for line in _wrap(s.preset_label, 40)[:4]:
                box.label(text=line)
        col.prop(s, "seed")
        col.prop(s, "lods")
        if s.has_fractal:
            sub = col.column(align=True)
            sub.label(text="Fractal terrain")
            sub.prop(s, "size")
            sub.prop(s, "cell_size")
            sub.prop(s, "relief")
            sub.prop(s, "terrain_seed")
        row = col.row(align=True)
        row.prop_search(s, "override_text", bpy.data, "texts", text="JSON")
        row.operator("landform.body_to_text", text="", icon="TEXT")

        row = layout.row(align=True)
        row.scale_y = 1.4
        row.operator("landform.run", icon="PLAY")
        row.operator("landform.cancel", icon="CANCEL")

        col = layout.column(align=True)
        col.prop(s, "progress", slider=True, text=s.stage or "Progress")
        if s.message:
            row = col.row()
            row.alert = s.failed
            row.label(text=s.message, icon="ERROR" if s.failed else "INFO")
        if s.job_id:
            col.label(text=f"Job {s.job_id}")


def _wrap(text, width):
    lines, line = [], ""
    for word in text.split():
        if line and len(line) + 1 + len(word) > width:
            lines.append(line)
            line = word
        else:
            line = f"{line} {word}".strip()
    if line:
        lines.append(line)
    return lines


CLASSES = (
    LandformSettings,
    LANDFORM_OT_load_presets,
    LANDFORM_OT_run,
    LANDFORM_OT_cancel,
    LANDFORM_OT_body_to_text,
    LANDFORM_PT_panel,
)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.landform = PointerProperty(type=LandformSettings)
    if _on_load not in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.append(_on_load)


def unregister():
    for scene_name, run in list(_runs.items()):
        try:
            run.cancel()
        except Exception:
            pass
    _runs.clear()
    if _on_load in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(_on_load)
    if hasattr(bpy.types.Scene, "landform"):
        del bpy.types.Scene.landform
    for cls in reversed(CLASSES):
        if cls.is_registered:
            bpy.utils.unregister_class(cls)
