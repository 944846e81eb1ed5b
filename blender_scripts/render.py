"""Engine settings and frame output."""

import os

import bpy

ENGINES = {"cycles": "CYCLES", "workbench": "BLENDER_WORKBENCH", "eevee": "BLENDER_EEVEE"}
PASSES = ("rgb", "depth", "instance", "part")
# Object pass indices written to the `instance` pass (IndexOB).
INDEX_OBJECT, INDEX_HAND, INDEX_TABLE = 1, 2, 3
# Scene property holding `center_region` (see apply_center_region).
CENTER_REGION = "grasp_center_region"
# Cycles' GPU backends, by their `[render] device` names.
GPU_BACKENDS = ("cuda", "optix", "hip", "oneapi", "metal")


def configure(settings):
    """Applies the engine settings (a RenderConfig-derived dict) once."""
    scene = bpy.context.scene
    engine = settings["engine"]
    if engine not in ENGINES:
        raise ValueError(f"unknown engine '{engine}' (expected one of {sorted(ENGINES)})")
    scene.render.engine = ENGINES[engine]
    # No persistent data: Cycles' state kept from a worker's earlier
    # sequences leaked into later ones, so a frame depended on which
    # sequences its worker had rendered before (half the unseen_look frames
    # changed between a 1- and a 2-worker render). Without it both are
    # byte-identical, for about 8 % more render time (docs/rendering.md).
    scene.render.use_persistent_data = bool(settings.get("persistent_data", False))
    scene.render.threads_mode = "FIXED" if settings.get("threads", 0) else "AUTO"
    if settings.get("threads", 0):
        scene.render.threads = int(settings["threads"])
    # No date, render time or names in the PNG metadata: identical inputs
    # must give identical files.
    for prop in dir(scene.render):
        if prop.startswith("use_stamp"):
            setattr(scene.render, prop, False)
    scene.render.film_transparent = False
    scene.render.use_motion_blur = False
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.color_depth = "8"
    scene.render.image_settings.compression = int(settings.get("png_compression", 15))
    scene.view_settings.view_transform = settings.get("view_transform", "AgX")
    scene.view_settings.look = "None"
    scene[CENTER_REGION] = float(settings.get("center_region", 1.0))
    apply_center_region(scene)
    if engine == "cycles":
        _cycles(scene, settings)
    elif engine == "workbench":
        _workbench(scene, settings)
    else:
        scene.eevee.taa_render_samples = int(settings["samples"])
    layer = bpy.context.view_layer
    passes = settings.get("passes", ["rgb"])
    unknown = [p for p in passes if p not in PASSES]
    if unknown:
        raise ValueError(f"unknown passes {unknown} (expected some of {PASSES})")
    # The part labels are computed in Rust from the depth, and from the object
    # index where the engine has one (Cycles).
    layer.use_pass_z = "depth" in passes or "part" in passes
    layer.use_pass_object_index = "instance" in passes or ("part" in passes and engine == "cycles")


def apply_center_region(scene):
    """Renders only the centred square whose side is the configured fraction
    of the shorter image side (the rest stays black): the part a model that
    crops the centre looks at. Called again whenever the image size changes."""
    fraction = scene.get(CENTER_REGION, 1.0)
    r = scene.render
    r.use_border = fraction < 1.0
    r.use_crop_to_border = False
    if r.use_border:
        short = min(r.resolution_x, r.resolution_y)
        half_x = fraction * short / r.resolution_x / 2
        half_y = fraction * short / r.resolution_y / 2
        r.border_min_x, r.border_max_x = 0.5 - half_x, 0.5 + half_x
        r.border_min_y, r.border_max_y = 0.5 - half_y, 0.5 + half_y


def cycles_gpu_devices():
    """The GPU devices Cycles sees, per backend ({"cuda": [names], ...}; an
    empty list where the machine or this build has none). The choice among
    them is made in Rust (generator/src/render/device.rs)."""
    prefs = bpy.context.preferences.addons["cycles"].preferences
    prefs.refresh_devices()
    found = {}
    for backend in GPU_BACKENDS:
        kind = backend.upper()
        # The list includes the CPU beside the GPUs; keep the GPUs only.
        found[backend] = [d.name for d in prefs.get_devices_for_type(kind) if d.type == kind]
    return found


def use_device(device):
    """Renders Cycles on `device` ("cpu" or a GPU backend name) with all of
    that backend's GPUs and not the CPU beside them, so the record names one
    device."""
    scene = bpy.context.scene
    if device == "cpu":
        scene.cycles.device = "CPU"
        return
    kind = device.upper()
    prefs = bpy.context.preferences.addons["cycles"].preferences
    prefs.compute_device_type = kind
    for d in prefs.get_devices_for_type(kind):
        d.use = d.type == kind
    if prefs.compute_device_type != kind or not prefs.has_active_device():
        raise ValueError(f"Cycles did not switch to {device} ({prefs.compute_device_type})")
    scene.cycles.device = "GPU"


def _cycles(scene, s):
    c = scene.cycles
    # The CPU until the worker picks a device (use_device; the choice is
    # made in generator/src/render/device.rs).
    c.device = "CPU"
    c.samples = int(s["samples"])
    c.use_adaptive_sampling = s.get("adaptive_threshold", 0.0) > 0.0
    if c.use_adaptive_sampling:
        c.adaptive_threshold = float(s["adaptive_threshold"])
    denoiser = s.get("denoiser", "openimagedenoise")
    c.use_denoising = denoiser != "none"
    if c.use_denoising:
        c.denoiser = "OPENIMAGEDENOISE"
        c.denoising_input_passes = "RGB_ALBEDO_NORMAL"
        c.denoising_prefilter = s.get("denoising_prefilter", "FAST")
        c.denoising_quality = s.get("denoising_quality", "HIGH")
    b = s["bounces"]
    c.max_bounces = int(b["total"])
    c.diffuse_bounces = int(b["diffuse"])
    c.glossy_bounces = int(b["glossy"])
    c.transmission_bounces = int(b["transmission"])
    c.transparent_max_bounces = int(b["transparent"])
    c.volume_bounces = 0
    c.caustics_reflective = False
    c.caustics_refractive = False
    c.blur_glossy = 1.0
    c.sample_clamp_indirect = float(s.get("clamp_indirect", 3.0))
    c.use_light_tree = True
    c.seed = int(s.get("seed", 0))
    c.tile_size = 2048
    scene.render.filter_size = 1.5


def _workbench(scene, s):
    shading = scene.display.shading
    shading.light = "STUDIO"
    shading.color_type = "MATERIAL"
    shading.show_shadows = True
    shading.show_cavity = False
    scene.display.render_aa = "8" if int(s["samples"]) >= 8 else "OFF"


# Non-Cycles engines round the exposure to this many stops (see set_exposure).
EXPOSURE_STEP = 0.05


def set_exposure(settings, stops):
    """Applies the camera exposure. Every distinct view-transform exposure
    makes Blender's colour management build and keep a new display processor
    (about 2.9 MiB each with AgX), so a worker grew by that much per sequence.
    Cycles scales the film instead (`film_exposure`, the same linear factor
    before the view transform); other engines round to EXPOSURE_STEP stops,
    which bounds the cached processors (21 over the default +-0.5 stops)."""
    scene = bpy.context.scene
    if settings["engine"] == "cycles":
        scene.view_settings.exposure = 0.0
        scene.cycles.film_exposure = 2.0**stops
    else:
        scene.view_settings.exposure = round(stops / EXPOSURE_STEP) * EXPOSURE_STEP


def set_tone(settings, tone):
    """The plan's view transform and look, or the render settings' view
    transform with no look. Few distinct pairs exist, so Blender's cache of
    colour-management processors stays small."""
    view = bpy.context.scene.view_settings
    if tone is None:
        view.view_transform = settings.get("view_transform", "AgX")
        view.look = "None"
    else:
        view.view_transform = tone["view_transform"]
        view.look = tone["look"]


def set_motion_blur(settings, blur):
    """Camera motion blur along the keyframed path (`blur`: a MotionBlur
    dict or None). Only Cycles and EEVEE blur; Workbench ignores it."""
    r = bpy.context.scene.render
    r.use_motion_blur = blur is not None and settings["engine"] != "workbench"
    if r.use_motion_blur:
        r.motion_blur_shutter = float(blur["shutter"])
        r.motion_blur_position = "CENTER"


def extra_passes(settings):
    return [p for p in settings.get("passes", ["rgb"]) if p != "rgb"]


def write_frame(png_path, exr_path=None):
    """Saves the last render as PNG, and as multilayer EXR (depth, masks) if asked."""
    scene = bpy.context.scene
    image = bpy.data.images["Render Result"]
    image.save_render(png_path, scene=scene)
    if exr_path:
        fmt = scene.render.image_settings
        fmt.media_type = "MULTI_LAYER_IMAGE"  # Blender 5: selects multilayer EXR
        fmt.file_format = "OPEN_EXR_MULTILAYER"
        fmt.color_depth = "32"
        try:
            image.save_render(exr_path, scene=scene)
        finally:
            fmt.media_type = "IMAGE"
            fmt.file_format = "PNG"
            fmt.color_mode = "RGB"
            fmt.color_depth = "8"


def render_still():
    bpy.ops.render.render(write_still=False)


def render_animation(out_dir, first, last, padding):
    """Renders frames first..last in one call; Blender names them by number."""
    scene = bpy.context.scene
    scene.frame_start = first
    scene.frame_end = last
    scene.render.filepath = os.path.join(out_dir, "#" * padding)
    scene.render.use_file_extension = True
    bpy.ops.render.render(animation=True)
