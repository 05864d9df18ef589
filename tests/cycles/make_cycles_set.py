# The Cycles bench set: scenes that stress the post-processing nodes, rendered by Blender's
# Cycles with every pass the nodes read, Cycles' own truths (motion blur, depth of field, ambient
# occlusion) and Blender's own compositor nodes on the same frames (Vector Blur, Defocus).
#
#   blender -b --factory-startup -P tests/cycles/make_cycles_set.py -- OUT_DIR [--quick]
#       [--only-unfiltered | --noise | --glint | --fog | --ssr | --relight] [--shots yard,closeup] [--scale K] [--skip-ao]
#
# --shots renders only the shots named (the others' files, times and calibrations are kept);
# --scale K multiplies the passes' and the truths' samples (not the AO pass's) by K: the
# close-up's errors are near its renders' own noise at 1024 / 2048 samples (docs/ACCURACY.md),
# so it is rendered at 4x; --skip-ao keeps the shot's AO truths as they are.
#
# Writes, per shot, into OUT_DIR:
#   SHOT.passes.exr         multilayer: Combined, Depth, Normal, Position, Vector, DiffCol, AO
#                           (distance 1 m), Mist; no camera matrices (Blender writes none); the
#                           stamp's Lens in the header
#   SHOT.passes_unfiltered.exr   Depth, Normal, Position, Vector with a 0.01 px pixel filter
#   SHOT.mb_s050.exr        Cycles motion blur, shutter 0.5 frame, centred (the truth)
#   SHOT.mb_s100.exr        shutter 1.0
#   SHOT.dof_fA.exr         Cycles depth of field at the two f-stops of the shot
#   SHOT.ao_d1.exr / ao_d2.exr   Cycles' AO pass alone at 1 m and 2 m
#   SHOT.blender_vblur_s050.exr / _s100   Blender's Vector Blur node on the passes
#   SHOT.blender_defocus_fA.exr            Blender's Defocus node (Z buffer, the scene camera),
#                                          its f-stop calibrated (blender_calibration.txt)
# and with --fog, for the yard alone:
#   yard.fog_exp.exr        the yard through homogeneous fog (fog's exp model)
#   yard.fog_height.exr     the yard through exponential height fog (fog's height model)
# and with --ssr, per shot:
#   SHOT.ssr_sky.exr        multilayer: Combined with every object hidden from glossy rays (glossy
#                           surfaces reflect the world alone), Depth, Normal, Position, DiffCol and
#                           shader AOVs albedo (the base colour), roughness and metallic
#   SHOT.ssr_truth.exr      Combined, everything visible to glossy rays (the same seed)
#   world.exr               the world alone as an equirectangular panorama (what the input reflects)
#   chrome_probe.exr        a reflection probe: a panorama from the chrome ball's centre, the ball
#                           hidden, with its distances (Depth)
# and with --relight, for the yard alone (after --ssr):
#   yard.relight_fill.exr   Combined lit by a second sun alone, direct light only
#   yard.relight_truth.exr  yard.ssr_sky.exr's Combined plus that: the relight node's truth
#   relight_fill.txt        the second sun's direction (toward it), colour and strength
# and render_times.txt. Stored as half-float EXRs, depth, position and motion as float (oiiotool).
# CI never runs Blender; the files are checked in (samples/cycles/).
import math
import os
import subprocess
import sys
import time

import bpy

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
OUT = os.path.abspath(argv[0] if argv else "samples/cycles")
QUICK = "--quick" in argv
# Only the unfiltered data passes (to add them to a set made before they were).
ONLY_UNFILTERED = "--only-unfiltered" in argv
# Only a second render of each shot's sharp frame and its motion-blur and depth-of-field truths
# with another seed, into OUT_DIR/noise/, to measure the renders' own noise (not checked in).
NOISE = "--noise" in argv
# Only the yard's sun glint (a 16x16 border around it) at 32x the samples: its sharp frame and
# its depth-of-field truths, into OUT_DIR/glint/ (the glint's render noise is of the size of the
# differences between methods at the set's counts).
GLINT = "--glint" in argv
# Only the yard seen through fog (yard.fog_exp.exr, yard.fog_height.exr): the fog node's truths.
FOG = "--fog" in argv
# Only the reflections' frames (SHOT.ssr_sky.exr, SHOT.ssr_truth.exr, world.exr): the ssr node's
# input and truth.
SSR = "--ssr" in argv
PROBE_ONLY = "--probe-only" in argv  # with --ssr: only chrome_probe.exr and world.exr
# Only the yard lit by a second sun alone (yard.relight_fill.exr), and the relight node's truth,
# the ssr input plus that light (yard.relight_truth.exr); after --ssr.
RELIGHT = "--relight" in argv
MIST_ONLY = "--mist-only" in argv  # with --fog: only Blender's Mist calibration, on fog truths made before


def option(name, default):
    return argv[argv.index(name) + 1] if name in argv else default


SHOTS = option("--shots", "yard,closeup").split(",")
SCALE = int(option("--scale", "1"))
SKIP_AO = "--skip-ao" in argv
FOG_KINDS = option("--fog-kinds", "exp,height").split(",")  # with --fog: which fogs
os.makedirs(OUT, exist_ok=True)

WIDTH, HEIGHT = (160, 90) if QUICK else (320, 180)
PASS_SAMPLES = (16 if QUICK else 1024) * SCALE
TRUTH_SAMPLES = (16 if QUICK else 2048) * SCALE
AO_SAMPLES = 16 if QUICK else 1024
FRAME = 2  # the shot frame: frame 1 is the previous frame of the motion vectors

times = []


def material(name, color, roughness, metallic=0.0):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    return m


def checker(m, scale, dark):
    """A procedural checker in object space times the base colour: texture for the blurs to
    move and defocus (a flat colour blurs into itself)."""
    nodes, links = m.node_tree.nodes, m.node_tree.links
    tex = nodes.new("ShaderNodeTexChecker")
    tex.inputs["Scale"].default_value = scale
    tex.inputs["Color1"].default_value = m.node_tree.nodes["Principled BSDF"].inputs[
        "Base Color"].default_value[:]
    c = tex.inputs["Color1"].default_value
    tex.inputs["Color2"].default_value = (c[0] * dark, c[1] * dark, c[2] * dark, 1.0)
    coord = nodes.new("ShaderNodeTexCoord")
    links.new(coord.outputs["Object"], tex.inputs["Vector"])
    links.new(tex.outputs["Color"], nodes["Principled BSDF"].inputs["Base Color"])
    return m


def add(obj_op, name, mat, **kw):
    obj_op(**kw)
    o = bpy.context.active_object
    o.name = name
    o.data.materials.append(mat)
    return o


def build_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    grey = checker(material("ground", (0.55, 0.55, 0.5), 0.8), 60.0, 0.45)
    clay = material("clay", (0.7, 0.35, 0.2), 0.6)
    white = checker(material("white", (0.8, 0.8, 0.8), 0.5), 4.0, 0.5)
    chrome = material("chrome", (0.9, 0.9, 0.9), 0.12, 1.0)
    gold = material("gold", (1.0, 0.75, 0.35), 0.25, 1.0)
    blue = material("blue", (0.15, 0.3, 0.8), 0.35)

    add(bpy.ops.mesh.primitive_plane_add, "ground", grey, size=60, location=(0, 0, 0))
    # Contact shadows and creases: a wall, steps and boxes resting on the ground and each other.
    add(bpy.ops.mesh.primitive_cube_add, "wall", white, size=1, location=(0, 4, 1.5),
        scale=(8, 0.4, 3))
    add(bpy.ops.mesh.primitive_cube_add, "step1", clay, size=1, location=(-2.5, 2.6, 0.25),
        scale=(2, 2, 0.5))
    add(bpy.ops.mesh.primitive_cube_add, "step2", clay, size=1, location=(-2.5, 3.0, 0.75),
        scale=(2, 1.2, 0.5))
    add(bpy.ops.mesh.primitive_cube_add, "box", white, size=1, location=(2.2, 2.0, 0.5),
        rotation=(0, 0, 0.5))
    # Thin features: poles and a fence of slats.
    for i in range(5):
        add(bpy.ops.mesh.primitive_cylinder_add, f"pole{i}", white, radius=0.03, depth=2.2,
            location=(-4.0 + 0.35 * i, 1.0, 1.1))
    for i in range(8):
        add(bpy.ops.mesh.primitive_cube_add, f"slat{i}", clay, size=1,
            location=(3.4 + 0.18 * i, 3.2, 0.6), scale=(0.05, 0.05, 1.2))
    # Glossy spheres, one resting on the ground (contact) and one on the box.
    add(bpy.ops.mesh.primitive_uv_sphere_add, "chrome_ball", chrome, radius=0.6,
        location=(0.3, 1.2, 0.6), segments=64, ring_count=32)
    add(bpy.ops.mesh.primitive_uv_sphere_add, "gold_ball", gold, radius=0.3,
        location=(2.2, 2.0, 1.3), segments=48, ring_count=24)
    for o in bpy.data.objects:
        if o.type == 'MESH' and o.name.endswith("ball"):
            bpy.context.view_layer.objects.active = o
            bpy.ops.object.shade_smooth()
    # Fast motion: a spinning cube and a sphere crossing the frame.
    spin = add(bpy.ops.mesh.primitive_cube_add, "spinner", blue, size=0.8,
               location=(-1.0, 0.2, 0.4))
    spin.rotation_mode = 'XYZ'
    for f, angle in ((1, 0.0), (2, 0.6), (3, 1.2)):
        spin.rotation_euler = (0, 0, angle)
        spin.keyframe_insert("rotation_euler", frame=f)
    runner = add(bpy.ops.mesh.primitive_uv_sphere_add, "runner", blue, radius=0.35,
                 location=(1.5, -0.3, 0.35), segments=48, ring_count=24)
    bpy.context.view_layer.objects.active = runner
    bpy.ops.object.shade_smooth()
    for f, x in ((1, 1.9), (2, 1.5), (3, 1.1)):
        runner.location.x = x
        runner.keyframe_insert("location", frame=f)
    for o in bpy.data.objects:
        if o.animation_data and o.animation_data.action:
            for fc in o.animation_data.action.fcurves:
                for k in fc.keyframe_points:
                    k.interpolation = 'LINEAR'

    # Sun and sky; the sky is seen at the top of the frame (infinite depth).
    bpy.ops.object.light_add(type='SUN', location=(0, 0, 10), rotation=(0.7, 0.2, 2.3))
    bpy.context.active_object.data.energy = 3.0
    bpy.context.active_object.data.angle = math.radians(2.0)
    world = bpy.data.worlds.new("sky")
    scene.world = world
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.45, 0.6, 0.9, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    world.mist_settings.start = 2.0
    world.mist_settings.depth = 20.0
    world.light_settings.distance = 1.0  # the AO pass's distance

    bpy.ops.object.camera_add()
    cam = bpy.context.active_object
    cam.name = "camera"
    cam.data.lens = 35.0
    cam.data.sensor_width = 36.0
    cam.data.clip_start = 0.1
    scene.camera = cam
    return scene, cam


def set_shot(scene, cam, shot):
    cam.animation_data_clear()
    if shot == "yard":
        # A moving camera: dollies sideways and pans a little over frames 1-3.
        for f, x in ((1, -0.6), (2, 0.0), (3, 0.6)):
            cam.location = (x, -7.0, 2.2)
            cam.rotation_euler = (math.radians(78), 0.0, math.radians(-2.0 * x))
            cam.keyframe_insert("location", frame=f)
            cam.keyframe_insert("rotation_euler", frame=f)
        cam.data.lens = 35.0
        cam.data.dof.focus_distance = 4.0
        stops = (1.4, 2.8)
    else:  # "closeup": depth of field on the chrome ball, the wall and sky behind; a slow pan
        for f in (1, 2, 3):
            cam.location = (1.0, -1.3, 0.8)
            cam.rotation_euler = (math.radians(85.6), 0.0, math.radians(15.6 + 0.5 * (f - 2)))
            cam.keyframe_insert("location", frame=f)
            cam.keyframe_insert("rotation_euler", frame=f)
        cam.data.lens = 70.0
        cam.data.dof.focus_distance = 2.6
        stops = (1.4, 4.0)
    for fc in cam.animation_data.action.fcurves:
        for k in fc.keyframe_points:
            k.interpolation = 'LINEAR'
    return stops


def base_settings(scene, samples):
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.seed = 7
    scene.cycles.max_bounces = 4
    scene.render.threads_mode = 'AUTO'
    scene.render.resolution_x = WIDTH
    scene.render.resolution_y = HEIGHT
    scene.render.resolution_percentage = 100
    scene.render.filter_size = 1.5  # Blackman-Harris, Cycles' default
    scene.render.fps = 24
    scene.frame_set(FRAME)
    scene.render.use_motion_blur = False
    scene.camera.data.dof.use_dof = False
    scene.render.use_compositing = False
    scene.use_nodes = False
    scene.render.use_stamp = False
    scene.render.use_stamp_lens = True
    scene.render.use_stamp_camera = True
    vl = scene.view_layers[0]
    for p in ("z", "normal", "position", "vector", "diffuse_color", "ambient_occlusion", "mist"):
        setattr(vl, "use_pass_" + p, False)


def render(scene, path, fmt):
    s = scene.render.image_settings
    s.file_format = fmt
    s.color_depth = '32'
    s.exr_codec = 'ZIP'
    s.color_mode = 'RGBA'
    scene.render.filepath = path
    t0 = time.time()
    bpy.ops.render.render(write_still=True)
    dt = time.time() - t0
    times.append((os.path.basename(path), scene.cycles.samples, dt))
    print(f"cycles set: {path}: {dt:.1f} s", flush=True)


# Stored as half-float except the passes whose precision the nodes need (a half position is 8 mm
# off at 10 m, a third of a pixel here: the camera solve would see it).
FLOAT_CHANNELS = ["ViewLayer.Depth.Z"] + [f"ViewLayer.{p}.{c}" for p in ("Position", "Vector")
                                          for c in "XYZW"[:4 if p == "Vector" else 3]]


def to_half(path):
    args = ["oiiotool", path, "-d", "half"]
    for c in FLOAT_CHANNELS:
        args += ["-d", f"{c}=float"]
    args += ["--compression", "zip", "-o", path]
    subprocess.run(args, check=True)


def rms_rgb(a, b):
    """RMS error over RGB of two EXRs, as oiiotool --diff prints it."""
    r = subprocess.run(["oiiotool", a, "--ch", "R,G,B", b, "--ch", "R,G,B", "--diff"],
                       capture_output=True, text=True)
    for line in r.stdout.splitlines():
        if "RMS error" in line:
            return float(line.split("=")[1])
    raise RuntimeError(r.stdout + r.stderr)


calibration = []


def blender_defocus(scene, shot, stops):
    """Blender's Defocus node on the passes (Z buffer, the scene camera's lens and focus), with
    its f-stop calibrated as a user would match a reference: the node's f-stop is not the
    lens's (Blender's depth-to-radius mapping is not a thin lens), so for each of Cycles'
    f-stops the node's is scanned in half-stops up to 64 times it, and the one closest to
    Cycles' truth (RMSE over RGB) is kept; the choice is written to blender_calibration.txt.
    This favours Blender: its row is its best case."""
    scene.use_nodes = True
    scene.render.use_compositing = True
    tree = scene.node_tree
    tree.nodes.clear()
    image = tree.nodes.new("CompositorNodeImage")
    image.image = bpy.data.images.load(os.path.join(OUT, f"{shot}.passes.exr"))
    df = tree.nodes.new("CompositorNodeDefocus")
    df.use_zbuffer = True
    df.blur_max = 64.0
    df.threshold = 1.0
    df.use_preview = False
    df.scene = scene
    comp = tree.nodes.new("CompositorNodeComposite")
    tree.links.new(image.outputs["Combined"], df.inputs["Image"])
    tree.links.new(image.outputs["Depth"], df.inputs["Z"])
    tree.links.new(df.outputs["Image"], comp.inputs["Image"])
    s = scene.render.image_settings
    s.file_format = 'OPEN_EXR'
    s.color_depth = '32'
    s.exr_codec = 'ZIP'
    s.color_mode = 'RGBA'
    trial = os.path.join(OUT, "defocus_trial.exr")
    for fstop in stops:
        truth = os.path.join(OUT, f"{shot}.dof_f{fstop:g}.exr")
        best = None
        for i in range(13):
            df.f_stop = fstop * 2 ** (i / 2)
            scene.render.filepath = trial
            bpy.ops.render.render(write_still=True)  # no Render Layers node: compositing only
            err = rms_rgb(trial, truth)
            if best is None or err < best[0]:
                best = (err, df.f_stop)
                os.replace(trial, os.path.join(OUT, f"{shot}.blender_defocus_f{fstop:g}.exr"))
        calibration.append((shot, fstop, best[1], best[0]))
        print(f"cycles set: {shot} Defocus for f/{fstop:g}: node f-stop {best[1]:.3g}, "
              f"RMSE {best[0]:.4f}", flush=True)
    if os.path.exists(trial):
        os.remove(trial)
    scene.use_nodes = False
    scene.render.use_compositing = False
    bpy.data.images.remove(image.image)


def compositor(scene, shot, stops):
    """Blender's own Vector Blur on the render's passes, at the truth's shutter."""
    scene.use_nodes = True
    scene.render.use_compositing = True
    tree = scene.node_tree
    tree.nodes.clear()
    rl = tree.nodes.new("CompositorNodeRLayers")
    out = tree.nodes.new("CompositorNodeOutputFile")
    out.base_path = OUT
    out.format.file_format = 'OPEN_EXR'
    out.format.color_depth = '32'
    out.format.exr_codec = 'ZIP'
    out.file_slots.clear()
    for shutter in (0.5, 1.0):
        vb = tree.nodes.new("CompositorNodeVecBlur")
        vb.factor = shutter
        vb.samples = 32
        tree.links.new(rl.outputs["Image"], vb.inputs["Image"])
        tree.links.new(rl.outputs["Depth"], vb.inputs["Z"])
        tree.links.new(rl.outputs["Vector"], vb.inputs["Speed"])
        name = f"{shot}.blender_vblur_s{int(shutter * 100):03d}."
        out.file_slots.new(name)
        tree.links.new(vb.outputs["Image"], out.inputs[name])


def noise_renders(scene, cam):
    """The sharp frame and every truth but the AO passes again with another seed: their RMSE
    against the set's is sqrt(2) times each render's noise."""
    out = os.path.join(OUT, "noise")
    os.makedirs(out, exist_ok=True)
    for shot in SHOTS:
        stops = set_shot(scene, cam, shot)
        base_settings(scene, PASS_SAMPLES)
        scene.cycles.seed = 8
        render(scene, os.path.join(out, f"{shot}.sharp_seed8.exr"), 'OPEN_EXR')
        base_settings(scene, TRUTH_SAMPLES)
        scene.cycles.seed = 8
        scene.render.use_motion_blur = True
        scene.cycles.motion_blur_position = 'CENTER'
        for shutter in (0.5, 1.0):
            scene.render.motion_blur_shutter = shutter
            scene.cycles.seed = 8
            render(scene, os.path.join(out, f"{shot}.mb_s{int(shutter * 100):03d}_seed8.exr"),
                   'OPEN_EXR')
        scene.render.use_motion_blur = False
        cam.data.dof.use_dof = True
        for fstop in stops:
            cam.data.dof.aperture_fstop = fstop
            scene.cycles.seed = 8
            render(scene, os.path.join(out, f"{shot}.dof_f{fstop:g}_seed8.exr"), 'OPEN_EXR')
        cam.data.dof.use_dof = False


# The yard's glint: pixel (178, 66) from the top left of the 320x180 frame.
GLINT_BOX = (170, 58, 186, 74)  # x0, y0, x1, y1, pixels from the top left


def glint_renders(scene, cam):
    """The yard's glint, a 16x16 border render at 32x the samples (of the sharp frame and of
    both depth-of-field truths), cropped to the border."""
    out = os.path.join(OUT, "glint")
    os.makedirs(out, exist_ok=True)
    stops = set_shot(scene, cam, "yard")
    x0, y0, x1, y1 = GLINT_BOX

    def border():
        scene.render.use_border = True
        scene.render.use_crop_to_border = True
        scene.render.border_min_x = x0 / WIDTH
        scene.render.border_max_x = x1 / WIDTH
        scene.render.border_min_y = 1.0 - y1 / HEIGHT  # Blender's border starts at the bottom
        scene.render.border_max_y = 1.0 - y0 / HEIGHT

    base_settings(scene, PASS_SAMPLES * 32)
    border()
    render(scene, os.path.join(out, "yard.glint_sharp.exr"), 'OPEN_EXR')
    base_settings(scene, TRUTH_SAMPLES * 16)
    border()
    cam.data.dof.use_dof = True
    for fstop in stops:
        cam.data.dof.aperture_fstop = fstop
        render(scene, os.path.join(out, f"yard.glint_dof_f{fstop:g}.exr"), 'OPEN_EXR')
    cam.data.dof.use_dof = False
    scene.render.use_border = False


# The fog the fog node models: extinction and emission along camera rays only, so that every
# surface is lit as in the sharp frame (the node fogs what the camera saw; it does not darken
# the sun or the sky on the surfaces). An absorbing, emitting medium of extinction s(p) and
# emission s(p) c has, along a ray to a surface of radiance L at distance d, the radiance
# T L + (1 - T) c with T = exp(-integral of s): exactly the models' composite, whatever s is.
FOG_COLOR = (0.75, 0.78, 0.82)
FOG_EXP_DENSITY = 0.08  # 1/m
FOG_HEIGHT_DENSITY = 0.3  # 1/m at z = 0
FOG_HEIGHT_FALLOFF = 1.0  # the density falls by exp(-1) per metre of height (Blender's z is up)


def fog_material(name, density):
    """Homogeneous absorption of extinction `density` and emission `density` FOG_COLOR."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nodes, links = m.node_tree.nodes, m.node_tree.links
    nodes.remove(nodes["Principled BSDF"])
    absorb = nodes.new("ShaderNodeVolumeAbsorption")
    absorb.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)  # extinction = density
    emit = nodes.new("ShaderNodeEmission")
    emit.inputs["Color"].default_value = (*FOG_COLOR, 1.0)
    # Only camera rays meet the medium: a ray that leaves a surface inside the box (a shadow
    # ray, a reflection, a bounce) still carries the box on its volume stack whatever the
    # box's ray visibility, and would be dimmed by it; its density is 0 for them.
    path = nodes.new("ShaderNodeLightPath")
    dens = nodes.new("ShaderNodeMath")
    dens.operation = 'MULTIPLY'
    dens.inputs[1].default_value = density
    links.new(path.outputs["Is Camera Ray"], dens.inputs[0])
    links.new(dens.outputs[0], absorb.inputs["Density"])
    links.new(dens.outputs[0], emit.inputs["Strength"])
    # Homogeneous: integrated exactly (Cycles would otherwise ray march the Light Path node's
    # output in steps sized by the box, up to its step limit: 12 m of fog at most).
    m.cycles.homogeneous_volume = True
    add_shader = nodes.new("ShaderNodeAddShader")
    links.new(absorb.outputs[0], add_shader.inputs[0])
    links.new(emit.outputs[0], add_shader.inputs[1])
    links.new(add_shader.outputs[0], nodes["Material Output"].inputs["Volume"])
    return m


def fog_slab(name, x, y, z0, z1, half, density):
    """A box of fog from height z0 to z1, met by camera rays alone."""
    bpy.ops.mesh.primitive_cube_add(size=1, location=(x, y, 0.5 * (z0 + z1)),
                                    scale=(2 * half, 2 * half, z1 - z0))
    box = bpy.context.active_object
    box.name = name
    # Visible to every ray (fog_material gives other rays no density): a volume box hidden
    # from all rays but the camera's darkened the lit surfaces by up to 7 % in Cycles 3.4,
    # even at density 0.
    box.data.materials.append(fog_material(name, density))
    return box


def fog_boxes(cam, kind):
    """The fog around the camera and everything it sees.

    exp: one box, 400 m of fog beyond any surface (the sky's transmittance is exp(-32)).
    height: s0 exp(-k z) as horizontal slabs of homogeneous fog, each of the exponential's mean
    density over its heights (Cycles integrates a homogeneous medium exactly; the density
    itself, ray marched, took 460 s for 16 samples at 160x90). A ray that crosses a slab whole
    meets exactly the exponential's optical depth there, since its path per unit of height is
    constant; only the slab a ray ends in is approximated, so the slabs are 5 cm thick up to
    3.05 m, where every surface lies (above it only the sky's rays end, at infinity), the ground
    (z = 0) is a slab boundary, and the camera sits inside a 1 cm slab. Below the ground lies
    one dense slab: the rays that pass the ground's edge have met an optical depth of 11 or
    more before it."""
    x, y, zc = cam.location
    if kind == "exp":
        return [fog_slab("fog", x, y, zc - 400.0, zc + 400.0, 400.0, FOG_EXP_DENSITY)]
    s0, k = FOG_HEIGHT_DENSITY, FOG_HEIGHT_FALLOFF

    def mean(z0, z1):
        return s0 * (math.exp(-k * z0) - math.exp(-k * z1)) / (k * (z1 - z0))

    edges = [i * 0.05 for i in range(int(round((zc - 0.005) / 0.05)) + 1)]
    edges += [zc - 0.005, zc + 0.005]
    z = (math.floor((zc + 0.005) / 0.05) + 1) * 0.05
    for top, step in ((3.05, 0.05), (6.0, 0.25), (30.0, 1.0)):  # no surface above 3 m
        while z < top - 1e-9:
            edges.append(z)
            z += step
    edges.append(30.0)
    edges = sorted(set(round(e, 6) for e in edges))
    # Neighbouring slabs do not touch, so that no ray meets two faces at one distance (a
    # precaution): each keeps 0.5 mm off its neighbours, its density scaled so that a crossing
    # meets the optical depth of its whole height.
    gap = 0.0005
    boxes = [fog_slab("fog_below", x, y, -20.0, -gap, 600.0, s0 * math.exp(k))]
    for i in range(len(edges) - 1):
        z0, z1 = edges[i], edges[i + 1]
        boxes.append(fog_slab(f"fog{i}", x, y, z0 + gap, z1 - gap, 600.0,
                              mean(z0, z1) * (z1 - z0) / (z1 - z0 - 2 * gap)))
    return boxes


def blender_mist(scene, kind):
    """Blender's own way to fog a render in its compositor: the Mist pass as the factor of a Mix
    of the sharp frame (the set's passes) toward the fog colour. The Mist pass has no
    exponential or height falloff, so, as a user matching a reference would, its falloff
    (quadratic, linear, inverse quadratic) and depth (0.5-128 m in half-octaves, start 0) are
    scanned and the setting closest to Cycles' truth (RMSE over RGB) kept; the choice is
    written to blender_mist_calibration.txt. This favours Blender: its row is its best case."""
    base_settings(scene, 16)
    scene.cycles.max_bounces = 0  # only the Mist pass of this render is used
    scene.view_layers[0].use_pass_mist = True
    scene.use_nodes = True
    scene.render.use_compositing = True
    tree = scene.node_tree
    tree.nodes.clear()
    rl = tree.nodes.new("CompositorNodeRLayers")
    image = tree.nodes.new("CompositorNodeImage")
    image.image = bpy.data.images.load(os.path.join(OUT, "yard.passes.exr"))
    mix = tree.nodes.new("CompositorNodeMixRGB")
    mix.blend_type = 'MIX'
    mix.inputs[2].default_value = (*FOG_COLOR, 1.0)
    comp = tree.nodes.new("CompositorNodeComposite")
    tree.links.new(rl.outputs["Mist"], mix.inputs[0])
    tree.links.new(image.outputs["Combined"], mix.inputs[1])
    tree.links.new(mix.outputs["Image"], comp.inputs["Image"])
    s = scene.render.image_settings
    s.file_format = 'OPEN_EXR'
    s.color_depth = '32'
    s.exr_codec = 'ZIP'
    s.color_mode = 'RGBA'
    truth = os.path.join(OUT, f"yard.fog_{kind}.exr")
    trial = os.path.join(OUT, "mist_trial.exr")
    mist = scene.world.mist_settings
    saved = (mist.start, mist.depth, mist.falloff)
    best = None
    for falloff in ('QUADRATIC', 'LINEAR', 'INVERSE_QUADRATIC'):
        for i in range(17):
            mist.start, mist.depth, mist.falloff = 0.0, 0.5 * 2 ** (i / 2), falloff
            scene.render.filepath = trial
            bpy.ops.render.render(write_still=True)
            err = rms_rgb(trial, truth)
            if best is None or err < best[0]:
                best = (err, falloff, mist.depth)
                os.replace(trial, os.path.join(OUT, f"yard.blender_mist_{kind}.exr"))
    if os.path.exists(trial):
        os.remove(trial)
    mist.start, mist.depth, mist.falloff = saved
    mist_calibration.append((kind, best[1], best[2], best[0]))
    print(f"cycles set: Mist for fog {kind}: {best[1].lower()} over {best[2]:.3g} m, "
          f"RMSE {best[0]:.4f}", flush=True)
    scene.use_nodes = False
    scene.render.use_compositing = False
    bpy.data.images.remove(image.image)


mist_calibration = []


def fog_renders(scene, cam):
    set_shot(scene, cam, "yard")
    scene.frame_set(FRAME)
    # Camera rays start at the near clip, and the fog with them: 1 mm instead of 10 cm, so that
    # the medium begins at the eye as the models' does (T was 0.8 % high at 0.1 m); nothing
    # lies that close, the image is otherwise the same.
    cam.data.clip_start = 0.001
    for kind in FOG_KINDS:
        if not MIST_ONLY:
            boxes = fog_boxes(cam, kind)
            # Every ray crosses the height fog's hundred slab boundaries: 1 h 7 min for 2048
            # samples, so a quarter of them (its noise is measured in docs/ACCURACY.md).
            base_settings(scene, TRUTH_SAMPLES if kind == "exp" else TRUTH_SAMPLES // 4)
            # A slab's faces are transparent surfaces to every ray, and a ray stops after
            # transparent_max_bounces of them (8 by default): camera rays crossing dozens of
            # slabs were cut before the surface (the ground showed the fog's emission alone),
            # and so were the sun's shadow rays from the ground (it went dark).
            scene.cycles.transparent_max_bounces = 1024
            render(scene, os.path.join(OUT, f"yard.fog_{kind}.exr"), 'OPEN_EXR')
            for box in boxes:
                bpy.data.objects.remove(box, do_unlink=True)
        blender_mist(scene, kind)
    for kind in FOG_KINDS:
        for name in (f"yard.fog_{kind}.exr", f"yard.blender_mist_{kind}.exr"):
            if not MIST_ONLY or "mist" in name:
                to_half(os.path.join(OUT, name))
    old = [l for l in kept("blender_mist_calibration.txt", lambda l: "")
           if l.split()[0][len("yard.fog_"):] not in FOG_KINDS]
    write_table("blender_mist_calibration.txt",
                "# Blender's Mist pass mixed toward the fog colour: the falloff and depth (start 0)\n"
                "# closest to Cycles' fog truth\n# truth falloff depth_m rmse_rgb\n", old,
                [f"yard.fog_{kind} {falloff.lower()} {depth:.4g} {err:.5f}\n"
                 for kind, falloff, depth, err in mist_calibration])


def material_aovs(scene):
    """Shader AOVs albedo (colour), roughness and metallic (values) fed from each material's
    Principled BSDF, the passes a renderer rarely writes: read as posthaste's albedo and
    material passes (docs/CONVENTIONS.md). The base colour, not DiffCol: Cycles' DiffCol is
    the diffuse weight, black on a metal."""
    vl = scene.view_layers[0]
    for name, kind in (("albedo", 'COLOR'), ("roughness", 'VALUE'), ("metallic", 'VALUE')):
        aov = vl.aovs.add()
        aov.name = name
        aov.type = kind
    for m in bpy.data.materials:
        if not m.use_nodes or "Principled BSDF" not in m.node_tree.nodes:
            continue
        nodes, links = m.node_tree.nodes, m.node_tree.links
        bsdf = nodes["Principled BSDF"]
        for name, socket, out in (("albedo", "Base Color", "Color"),
                                  ("roughness", "Roughness", "Value"),
                                  ("metallic", "Metallic", "Value")):
            aov = nodes.new("ShaderNodeOutputAOV")
            aov.name = name  # Blender 3.4: the node's name is the AOV's
            src = bsdf.inputs[socket]
            if src.is_linked:
                links.new(src.links[0].from_socket, aov.inputs[out])
            elif out == "Color":
                aov.inputs[out].default_value = src.default_value[:]
            else:
                aov.inputs[out].default_value = src.default_value


def ssr_renders(scene, cam):
    """The reflections' input and truth. Cycles' glossy surfaces reflect everything; with every
    object hidden from glossy rays they reflect the world alone, as the rasterizer's beauty
    reflects its sky alone: the ssr node's input. The truth is the same render with the
    objects visible (the same seed, so the two differ by the reflections, not by noise)."""
    material_aovs(scene)
    meshes = [o for o in bpy.data.objects if o.type == 'MESH']
    for shot in [] if PROBE_ONLY else SHOTS:
        set_shot(scene, cam, shot)
        base_settings(scene, PASS_SAMPLES)
        vl = scene.view_layers[0]
        for p in ("z", "normal", "position", "diffuse_color"):
            setattr(vl, "use_pass_" + p, True)
        for o in meshes:
            o.visible_glossy = False
        render(scene, os.path.join(OUT, f"{shot}.ssr_sky.exr"), 'OPEN_EXR_MULTILAYER')
        for o in meshes:
            o.visible_glossy = True
        base_settings(scene, PASS_SAMPLES)
        render(scene, os.path.join(OUT, f"{shot}.ssr_truth.exr"), 'OPEN_EXR')
        for name in (f"{shot}.ssr_sky.exr", f"{shot}.ssr_truth.exr"):
            to_half(os.path.join(OUT, name))
    # A reflection probe at the chrome ball's centre: what the ball's reflected rays see, the
    # ball itself hidden, as a panorama with distances (Cycles' Depth pass is the distance along
    # the ray for a panoramic camera). Unrotated, Blender's equirectangular camera lays world
    # directions out as the ssr node's environment input does (shading/ssr/environment.h).
    base_settings(scene, PASS_SAMPLES)
    scene.view_layers[0].use_pass_z = True
    chrome = bpy.data.objects["chrome_ball"]
    chrome.visible_camera = False
    cam.animation_data_clear()
    cam.location = chrome.location
    cam.rotation_euler = (0.0, 0.0, 0.0)
    cam.data.type = 'PANO'
    cam.data.cycles.panorama_type = 'EQUIRECTANGULAR'
    scene.render.resolution_x, scene.render.resolution_y = 512, 256
    render(scene, os.path.join(OUT, "chrome_probe.exr"), 'OPEN_EXR_MULTILAYER')
    to_half(os.path.join(OUT, "chrome_probe.exr"))
    chrome.visible_camera = True
    cam.data.type = 'PERSP'
    # What the input's glossy surfaces reflect: the world, as a panorama from the camera with
    # every object hidden (the ssr node's world input).
    base_settings(scene, 16)
    for o in meshes:
        o.visible_camera = False
    cam.data.type = 'PANO'
    cam.data.cycles.panorama_type = 'EQUIRECTANGULAR'
    scene.render.resolution_x, scene.render.resolution_y = 64, 32
    render(scene, os.path.join(OUT, "world.exr"), 'OPEN_EXR')
    to_half(os.path.join(OUT, "world.exr"))
    cam.data.type = 'PERSP'
    for o in meshes:
        o.visible_camera = True


# The relight node's fill light: a second sun from the camera's left, warm, low.
FILL_TOWARD = (-0.55, -0.65, 0.52)
FILL_COLOR = (1.0, 0.8, 0.6)
FILL_STRENGTH = 2.0


def relight_renders(scene, cam):
    """The yard lit by a second sun alone, direct light only (no world, the scene's sun dark, no
    bounces: what the relight node adds), and the node's truth, the ssr input (every surface
    lit by the scene) plus that light."""
    import mathutils
    set_shot(scene, cam, "yard")
    base_settings(scene, PASS_SAMPLES)
    scene.cycles.max_bounces = 0
    scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    for o in bpy.data.objects:
        if o.type == 'LIGHT':
            o.data.energy = 0.0
    bpy.ops.object.light_add(type='SUN', location=(0, 0, 10))
    fill = bpy.context.active_object
    toward = mathutils.Vector(FILL_TOWARD).normalized()
    fill.rotation_euler = toward.to_track_quat('Z', 'Y').to_euler()  # the sun shines along -Z
    fill.data.energy = FILL_STRENGTH
    fill.data.color = FILL_COLOR
    fill.data.angle = math.radians(0.5)
    render(scene, os.path.join(OUT, "yard.relight_fill.exr"), 'OPEN_EXR')
    truth = os.path.join(OUT, "yard.relight_truth.exr")
    subprocess.run(["oiiotool", os.path.join(OUT, "yard.ssr_sky.exr"), "--ch",
                    "R=ViewLayer.Combined.R,G=ViewLayer.Combined.G,B=ViewLayer.Combined.B,"
                    "A=ViewLayer.Combined.A",
                    os.path.join(OUT, "yard.relight_fill.exr"), "--ch", "R,G,B,A=0", "--add",
                    "-d", "half", "--compression", "zip", "-o", truth], check=True)
    to_half(os.path.join(OUT, "yard.relight_fill.exr"))
    with open(os.path.join(OUT, "relight_fill.txt"), "w") as f:
        f.write("# the relight node's fill light: a Blender sun; direction toward it (world, Z up),"
                "\n# colour, strength (irradiance at normal incidence, W/m^2)\n")
        f.write(f"direction {toward.x:.6f} {toward.y:.6f} {toward.z:.6f}\n")
        f.write("color {} {} {}\nstrength {}\n".format(*FILL_COLOR, FILL_STRENGTH))


def kept(name, shot_of):
    """The lines of OUT/name whose shot (shot_of(line)) was not rendered (--shots keeps them)."""
    path = os.path.join(OUT, name)
    if not os.path.exists(path):
        return []
    with open(path) as f:
        return [l for l in f if not l.startswith("#") and shot_of(l) not in SHOTS]


def write_table(name, header, old_lines, new_lines):
    """OUT/name: the header, the lines kept from before, then this run's."""
    with open(os.path.join(OUT, name), "w") as f:
        f.write(header)
        f.writelines(old_lines)
        f.writelines(new_lines)


def write_times():
    """render_times.txt: this run's renders, and the earlier lines of files not rendered again."""
    fresh = {name for name, _, _ in times}
    old_times = [l for l in kept("render_times.txt", lambda l: "") if l.split()[0] not in fresh]
    write_table("render_times.txt",
                f"# {bpy.app.version_string}, Cycles on the CPU, {os.cpu_count()} threads, "
                f"{WIDTH}x{HEIGHT}\n# file samples seconds\n", old_times,
                [f"{name} {samples} {dt:.1f}\n" for name, samples, dt in times])


def main():
    scene, cam = build_scene()
    if FOG:
        fog_renders(scene, cam)
        write_times()
        return
    if SSR:
        ssr_renders(scene, cam)
        write_times()
        return
    if RELIGHT:
        relight_renders(scene, cam)
        write_times()
        return
    if NOISE:
        noise_renders(scene, cam)
        return
    if GLINT:
        glint_renders(scene, cam)
        return
    for shot in SHOTS:
        stops = set_shot(scene, cam, shot)
        # The passes (and Blender's compositor nodes on them).
        base_settings(scene, PASS_SAMPLES)
        vl = scene.view_layers[0]
        for p in ("z", "normal", "position", "vector", "diffuse_color", "ambient_occlusion", "mist"):
            setattr(vl, "use_pass_" + p, True)
        if not ONLY_UNFILTERED:
            compositor(scene, shot, stops)
            render(scene, os.path.join(OUT, f"{shot}.passes.exr"), 'OPEN_EXR_MULTILAYER')
        # The same data passes without the pixel filter (0.01 px: every sample at the pixel's
        # centre, so depth, normals, positions and motion are one surface's, exact), to measure
        # what the filtered passes of a production render cost each node.
        base_settings(scene, 16)
        scene.use_nodes = False
        scene.render.use_compositing = False
        scene.render.filter_size = 0.01
        for p in ("z", "normal", "position", "vector"):
            setattr(vl, "use_pass_" + p, True)
        render(scene, os.path.join(OUT, f"{shot}.passes_unfiltered.exr"), 'OPEN_EXR_MULTILAYER')
        if ONLY_UNFILTERED:
            continue
        # The file output node appends the frame number: drop it.
        for f in os.listdir(OUT):
            if f.startswith(shot + ".blender_") and f.endswith(f"{FRAME:04d}.exr"):
                os.replace(os.path.join(OUT, f), os.path.join(OUT, f[:-len(f"{FRAME:04d}.exr")] + "exr"))
        # Truths: beauty only.
        base_settings(scene, TRUTH_SAMPLES)
        scene.render.use_motion_blur = True
        scene.cycles.motion_blur_position = 'CENTER'
        for shutter in (0.5, 1.0):
            scene.render.motion_blur_shutter = shutter
            render(scene, os.path.join(OUT, f"{shot}.mb_s{int(shutter * 100):03d}.exr"),
                   'OPEN_EXR')
        scene.render.use_motion_blur = False
        cam.data.dof.use_dof = True
        for fstop in stops:
            cam.data.dof.aperture_fstop = fstop
            render(scene, os.path.join(OUT, f"{shot}.dof_f{fstop:g}.exr"), 'OPEN_EXR')
        cam.data.dof.use_dof = False
        base_settings(scene, TRUTH_SAMPLES)
        blender_defocus(scene, shot, stops)
        if SKIP_AO:
            continue
        # Cycles' AO pass alone at two distances (no bounces: only the AO pass is kept).
        base_settings(scene, AO_SAMPLES)
        scene.cycles.max_bounces = 0
        vl.use_pass_ambient_occlusion = True
        for dist in (1.0, 2.0):
            scene.world.light_settings.distance = dist
            render(scene, os.path.join(OUT, f"{shot}.ao_d{int(dist)}.exr"),
                   'OPEN_EXR_MULTILAYER')
        scene.world.light_settings.distance = 1.0
    for f in sorted(os.listdir(OUT)):
        if (f.endswith(".exr") and f.split(".")[0] in SHOTS and
                (not ONLY_UNFILTERED or "_unfiltered" in f)):
            to_half(os.path.join(OUT, f))
    write_times()
    if ONLY_UNFILTERED:
        return
    write_table("blender_calibration.txt",
                "# Blender's Defocus: the node f-stop closest to Cycles' truth at each lens f-stop\n"
                "# shot lens_fstop node_fstop rmse_rgb\n",
                kept("blender_calibration.txt", lambda l: l.split()[0]),
                [f"{shot} {fstop:g} {node_fstop:.4g} {err:.5f}\n"
                 for shot, fstop, node_fstop, err in calibration])


main()
