# Render a Landform glb in Blender (Debian's blender 3.4, headless) from a viewpoint of our
# own choosing, lit by a lamp beside the eye: what a player standing there would see, drawn
# by an importer and renderer that are not ours.
#
#   blender -b -P scripts/render_glb.py -- mesh.glb out.png EYE_X EYE_Y EYE_Z AT_X AT_Y AT_Z [sun]
#
# Several glbs separated by commas render together (tiles side by side).
#
# With `sun` the scene is lit as outdoors instead: a sun 35° above the horizon from behind the
# eye's left shoulder and a grey sky (terrain seen from a player's height).
#
# Points are glTF coordinates (metres, y up). Cycles on the CPU, 24 samples, no denoiser
# (Debian builds Blender without OpenImageDenoise). Needs python3-numpy: Blender 3.4's glTF
# importer still uses `numpy.bool`, which numpy removed.
#
# With LANDFORM_BLENDER_ADDON set to clients/blender, the `landform` add-on is enabled first
# (levels of detail then import hidden, as its users see them). LANDFORM_RENDER_SIZE=WxH sets
# the picture's size (800x600 by default).
import os
import sys

import numpy

numpy.bool = bool
import bpy  # noqa: E402
import mathutils  # noqa: E402

argv = sys.argv[sys.argv.index("--") + 1:]
glb, out = argv[0], argv[1]
eye = [float(v) for v in argv[2:5]]
target = [float(v) for v in argv[5:8]]
outdoors = len(argv) > 8 and argv[8] == "sun"
bpy.ops.wm.read_factory_settings(use_empty=True)
if os.environ.get("LANDFORM_BLENDER_ADDON"):
    import addon_utils

    sys.path.insert(0, os.environ["LANDFORM_BLENDER_ADDON"])
    addon_utils.enable("landform", default_set=True)
for path in glb.split(","):
    bpy.ops.import_scene.gltf(filepath=path)


def to_blender(p):
    # The importer turns glTF's y-up into Blender's z-up: (x, y, z) -> (x, -z, y).
    return mathutils.Vector((p[0], -p[2], p[1]))


camera_data = bpy.data.cameras.new("camera")
camera_data.lens = 18
# A new camera sees 100 m; terrain is kilometres across.
camera_data.clip_start = 0.1
camera_data.clip_end = 100000.0
camera = bpy.data.objects.new("camera", camera_data)
bpy.context.scene.collection.objects.link(camera)
camera.location = to_blender(eye)
camera.rotation_euler = (to_blender(target) - to_blender(eye)).to_track_quat("-Z", "Y").to_euler()
bpy.context.scene.camera = camera
if outdoors:
    lamp_data = bpy.data.lights.new("sun", "SUN")
    lamp_data.energy = 4.0
    lamp = bpy.data.objects.new("sun", lamp_data)
    view = to_blender(target) - to_blender(eye)
    view.z = 0
    # Light travels along -Z of the lamp: from behind-left of the eye, 35° up.
    left = mathutils.Vector((-view.y, view.x, 0)).normalized()
    towards = (view.normalized() + 0.6 * -left).normalized()
    towards.z = -0.7
    lamp.rotation_euler = towards.to_track_quat("-Z", "Y").to_euler()
else:
    lamp_data = bpy.data.lights.new("lamp", "POINT")
    lamp_data.energy = 400
    lamp_data.shadow_soft_size = 0.3
    lamp = bpy.data.objects.new("lamp", lamp_data)
    lamp.location = to_blender(eye) + mathutils.Vector((0.1, 0.1, 0.4))
bpy.context.scene.collection.objects.link(lamp)
world = bpy.data.worlds.new("world")
world.use_nodes = True
world.node_tree.nodes["Background"].inputs[1].default_value = 0.6 if outdoors else 0.02
bpy.context.scene.world = world
scene = bpy.context.scene
scene.render.engine = "CYCLES"
scene.cycles.device = "CPU"
scene.cycles.samples = 24
scene.cycles.use_denoising = False
# LANDFORM_RENDER_SIZE=WxH renders smaller (CI's smoke run of this script).
width, height = (int(v) for v in os.environ.get("LANDFORM_RENDER_SIZE", "800x600").split("x"))
scene.render.resolution_x = width
scene.render.resolution_y = height
scene.render.filepath = out
bpy.ops.render.render(write_still=True)
