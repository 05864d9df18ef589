# The Cryptomatte set: a small scene rendered by Blender's Cycles with its object and material
# cryptomattes, and Blender's own Cryptomatte node's mattes of it, as third-party truth for
# posthaste's `cryptomatte` node.
#
#   blender -b --factory-startup -P tests/cycles/make_cryptomatte_set.py -- --out samples/cryptomatte
#
# (--factory-startup is optional: the script starts from an empty factory scene itself.) Needs
# oiiotool on the PATH.
#
# Writes into OUT:
#   scene.exr                    multilayer float32 (ZIP): ViewLayer.Combined, and the
#                                cryptomattes ViewLayer.CryptoObject00..02 and
#                                ViewLayer.CryptoMaterial00..02 (depth 6: three rank layers of two
#                                ID/coverage pairs each), their manifests in the header
#   blender_matte_NAME.exr       the Matte output of Blender's Cryptomatte node (CompositorNode-
#                                CryptomatteV2, source: the render) for each matte in MATTES,
#                                one float32 channel "Y" (ZIP): Blender 3.4 writes an EXR as RGB
#                                or RGBA only, so its RGB file (R = G = B) goes through oiiotool
# Both come from one render: the compositor reads the render result that scene.exr is written
# from. Names with `.`, `[ ]`, `*` and `?` are in the scene on purpose: Blender keys them
# literally (its matte_id is a comma-separated list of names, no wildcards).
# CI never runs Blender; the files are checked in (samples/cryptomatte/).
import math
import os
import subprocess
import sys
import time

import bpy
from mathutils import Vector

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
OUT = "samples/cryptomatte"
if "--out" in argv:
    OUT = argv[argv.index("--out") + 1]
OUT = os.path.abspath(OUT)
os.makedirs(OUT, exist_ok=True)

WIDTH, HEIGHT, SAMPLES, DEPTH = 192, 108, 16, 6
FRAME = 1

# Short name -> (cryptomatte layer, the names keyed, as Blender's matte_id takes them).
MATTES = {
    "cube": ("CryptoObject", ["Cube"]),
    "ball001_pole1": ("CryptoObject", ["Ball.001", "Pole[1]"]),
    "star": ("CryptoObject", ["Star*"]),
    "chrome": ("CryptoMaterial", ["Chrome"]),
    "glass": ("CryptoMaterial", ["Glass?"]),
}


def material(name, color, roughness, metallic=0.0, transmission=0.0):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Transmission"].default_value = transmission
    return m


def add(obj_op, name, mat, smooth=False, **kw):
    obj_op(**kw)
    o = bpy.context.active_object
    o.name = name
    o.data.name = name + "_mesh"
    o.data.materials.append(mat)
    if smooth:
        bpy.ops.object.shade_smooth()
    return o


def build_scene():
    # From scratch: no default cube, light or camera.
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    floor = material("Floor", (0.5, 0.5, 0.45), 0.8)
    red = material("Red", (0.8, 0.08, 0.05), 0.4)            # Cube and Star*
    chrome = material("Chrome", (0.9, 0.9, 0.9), 0.1, 1.0)    # Ball.001 and Ball.002
    glass = material("Glass?", (0.9, 0.95, 1.0), 0.05, 0.0, 1.0)

    add(bpy.ops.mesh.primitive_plane_add, "Ground", floor, size=20, location=(0, 0, 0))
    add(bpy.ops.mesh.primitive_cube_add, "Cube", red, size=1.2, location=(-1.6, 0.6, 0.6),
        rotation=(0, 0, math.radians(30)))
    # Ball.001 in front of the pole and overlapping the cube's edge: shared edge pixels.
    add(bpy.ops.mesh.primitive_uv_sphere_add, "Ball.001", chrome, smooth=True, radius=0.55,
        location=(-0.55, -0.3, 0.55), segments=48, ring_count=24)
    add(bpy.ops.mesh.primitive_uv_sphere_add, "Ball.002", chrome, smooth=True, radius=0.4,
        location=(1.7, -0.2, 0.4), segments=48, ring_count=24)
    add(bpy.ops.mesh.primitive_cylinder_add, "Pole[1]", glass, smooth=False, radius=0.15,
        depth=2.4, location=(0.25, 0.9, 1.2), vertices=32)
    add(bpy.ops.mesh.primitive_cone_add, "Star*", red, radius1=0.5, radius2=0.0, depth=1.0,
        location=(1.0, 1.4, 0.5), vertices=5)

    bpy.ops.object.light_add(type='SUN', location=(0, 0, 10),
                             rotation=(math.radians(40), math.radians(15), math.radians(30)))
    sun = bpy.context.active_object
    sun.name = "Sun"
    sun.data.energy = 3.0
    world = bpy.data.worlds.new("World")
    scene.world = world
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.4, 0.55, 0.85, 1.0)

    bpy.ops.object.camera_add(location=(0.6, -6.5, 2.6))
    cam = bpy.context.active_object
    cam.name = "Camera"
    cam.data.lens = 40.0
    cam.data.sensor_width = 36.0
    target = Vector((0.0, 0.4, 0.6))
    cam.rotation_euler = (target - cam.location).to_track_quat('-Z', 'Y').to_euler()
    scene.camera = cam
    return scene


def render_settings(scene):
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = SAMPLES
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.seed = 1
    # Pixel filter left at its default: Blackman-Harris, 1.5 px.
    scene.render.resolution_x = WIDTH
    scene.render.resolution_y = HEIGHT
    scene.render.resolution_percentage = 100
    scene.render.use_motion_blur = False
    scene.render.use_stamp = False
    scene.frame_start = scene.frame_end = scene.frame_current = FRAME

    vl = scene.view_layers[0]
    vl.use_pass_combined = True
    vl.use_pass_z = False
    vl.use_pass_cryptomatte_object = True
    vl.use_pass_cryptomatte_material = True
    vl.use_pass_cryptomatte_asset = False
    vl.pass_cryptomatte_depth = DEPTH

    s = scene.render.image_settings
    s.file_format = 'OPEN_EXR_MULTILAYER'
    s.color_depth = '32'   # full float: the IDs are float32 bit patterns
    s.exr_codec = 'ZIP'
    s.color_mode = 'RGBA'
    return vl


def compositor(scene, vl):
    """Blender's Cryptomatte node (source: the render) per matte, each Matte output into a File
    Output node. No Composite node: with one, scene.exr would also hold a Composite.Combined
    layer (a copy of ViewLayer.Combined); the File Output node alone runs the compositor."""
    scene.use_nodes = True
    scene.render.use_compositing = True
    tree = scene.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    rl = tree.nodes.new("CompositorNodeRLayers")
    rl.scene = scene
    rl.layer = vl.name

    out = tree.nodes.new("CompositorNodeOutputFile")
    out.base_path = OUT + os.sep
    out.format.file_format = 'OPEN_EXR'
    out.format.color_depth = '32'
    out.format.exr_codec = 'ZIP'
    out.format.color_mode = 'RGB'  # Blender 3.4 writes no one-channel EXR ('BW' is not offered)
    out.file_slots.clear()
    for short, (layer, names) in MATTES.items():
        node = tree.nodes.new("CompositorNodeCryptomatteV2")
        node.source = 'RENDER'
        node.scene = scene
        node.layer_name = f"{vl.name}.{layer}"
        node.matte_id = ",".join(names)
        print(f"matte {short}: layer {node.layer_name!r} matte_id {node.matte_id!r} "
              f"entries {[e.name for e in node.entries] if hasattr(node, 'entries') else '?'}")
        tree.links.new(rl.outputs["Image"], node.inputs["Image"])
        out.file_slots.new(f"blender_matte_{short}")
        tree.links.new(node.outputs["Matte"], out.inputs[-1])


def main():
    scene = build_scene()
    vl = render_settings(scene)
    compositor(scene, vl)
    # The File Output node appends the frame number (and an extension only with
    # use_file_extension): its files are renamed below.
    scene.render.filepath = os.path.join(OUT, "scene.exr")
    scene.render.use_file_extension = False
    t0 = time.time()
    bpy.ops.render.render(write_still=True)
    seconds = time.time() - t0
    for short in MATTES:
        # The matte is in R, G and B alike: keep R, renamed, as the file's one channel.
        # (no extension: use_file_extension is off for scene.exr's sake)
        src = os.path.join(OUT, f"blender_matte_{short}{FRAME:04d}")
        subprocess.run(["oiiotool", src, "--ch", "Y=R", "-d", "float", "--compression", "zip",
                        "-o", os.path.join(OUT, f"blender_matte_{short}.exr")], check=True)
        os.remove(src)
    print(f"render time (Cycles CPU, {SAMPLES} samples, {WIDTH}x{HEIGHT}, with the "
          f"compositor and file writes): {seconds:.2f} s")
    print(f"Blender {bpy.app.version_string}")


main()
