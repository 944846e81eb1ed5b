"""The foreign world's render path: a Cycles integrator set up unlike
training's, a compositor for the lens, and the tone curve.

Integrator (training: light tree, 3 bounces, indirect clamp 3,
Blackman-Harris 1.5 px, OpenImageDenoise with albedo and normal guides and
the fast prefilter): path guiding on surfaces, no light tree, 8 bounces (4
diffuse, 4 glossy), reflective caustics, indirect clamp 10, a Gaussian
pixel filter 2 px wide, and OpenImageDenoise with the albedo guide only,
the accurate prefilter and balanced quality. The noise pattern's seed
follows the sequence. Only `samples`, `denoiser` (on or off),
`center_region`, `threads` and `png_compression` come from `[render]`.

Compositor (scene-linear, before the view transform): radial lens
distortion with dispersion, bloom, and a vignette; then the drawn ACES view
transform and look."""

import os
import zlib

import bpy
import numpy as np

from blender_scripts import render as engine

FILTER_WIDTH_PX = 2.0


def configure(settings):
    """Sets the engine up once; returns the compositor's `Lens`."""
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.render.use_persistent_data = False
    scene.render.threads_mode = "FIXED" if settings.get("threads", 0) else "AUTO"
    if settings.get("threads", 0):
        scene.render.threads = int(settings["threads"])
    for prop in dir(scene.render):
        if prop.startswith("use_stamp"):
            setattr(scene.render, prop, False)
    scene.render.film_transparent = False
    fmt = scene.render.image_settings
    fmt.file_format, fmt.color_mode, fmt.color_depth = "PNG", "RGB", "8"
    fmt.compression = int(settings.get("png_compression", 15))
    scene[engine.CENTER_REGION] = float(settings.get("center_region", 1.0))
    engine.apply_center_region(scene)

    c = scene.cycles
    c.device = "CPU"
    c.samples = int(settings["samples"])
    c.use_adaptive_sampling = False
    c.use_light_tree = False
    c.use_guiding = True
    c.use_surface_guiding = True
    c.use_volume_guiding = False
    # The same frames whatever the thread count.
    c.use_deterministic_guiding = True
    c.max_bounces = 8
    c.diffuse_bounces = 4
    c.glossy_bounces = 4
    c.transmission_bounces = 4
    c.transparent_max_bounces = 8
    c.volume_bounces = 0
    c.caustics_reflective = True
    c.caustics_refractive = False
    c.blur_glossy = 0.5
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 10.0
    c.pixel_filter_type = "GAUSSIAN"
    c.filter_width = FILTER_WIDTH_PX
    c.use_denoising = settings.get("denoiser", "openimagedenoise") != "none"
    if c.use_denoising:
        c.denoiser = "OPENIMAGEDENOISE"
        c.denoising_input_passes = "RGB_ALBEDO"
        c.denoising_prefilter = "ACCURATE"
        c.denoising_quality = "BALANCED"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.render.use_compositing = True
    return Lens(scene)


class Lens:
    """The compositor: Render Layers -> lens distortion -> bloom ->
    vignette -> output. Values are set per sequence (`apply`)."""

    def __init__(self, scene):
        tree = bpy.data.node_groups.new("f_lens", "CompositorNodeTree")
        tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
        scene.compositing_node_group = tree
        n, link = tree.nodes, tree.links.new
        layers = n.new("CompositorNodeRLayers")
        self.distort = n.new("CompositorNodeLensdist")
        self.distort.inputs["Type"].default_value = "Radial"
        self.distort.inputs["Fit"].default_value = True
        self.glare = n.new("CompositorNodeGlare")
        self.glare.inputs["Type"].default_value = "Bloom"
        self.glare.inputs["Threshold"].default_value = 1.5
        self.mask = n.new("CompositorNodeEllipseMask")
        self.mask.inputs["Size"].default_value = (0.85, 0.85)
        self.soften = n.new("CompositorNodeBlur")
        self.shade = n.new("ShaderNodeMix")
        self.shade.data_type = "RGBA"
        self.shade.blend_type = "MULTIPLY"
        out = n.new("NodeGroupOutput")
        link(layers.outputs["Image"], self.distort.inputs["Image"])
        link(self.distort.outputs["Image"], self.glare.inputs["Image"])
        link(self.mask.outputs["Mask"], self.soften.inputs["Image"])
        link(self.glare.outputs["Image"], self.shade.inputs[6])
        link(self.soften.outputs["Image"], self.shade.inputs[7])
        link(self.shade.outputs[2], out.inputs[0])

    def apply(self, cam):
        r = bpy.context.scene.render
        self.distort.inputs["Distortion"].default_value = cam["distortion"]
        self.distort.inputs["Dispersion"].default_value = cam["dispersion"]
        self.glare.inputs["Strength"].default_value = cam["bloom"]
        # The vignette: a soft ellipse, black outside, mixed in by strength.
        blur = 0.35 * max(r.resolution_x, r.resolution_y)
        self.soften.inputs["Size"].default_value = (blur, blur)
        self.shade.inputs["Factor"].default_value = cam["vignette"]


def set_tone(cam, stops):
    """The drawn view transform and look, and the metered exposure (Cycles
    scales the film, so no colour-management processor per value)."""
    scene = bpy.context.scene
    scene.view_settings.view_transform = cam["view_transform"]
    look = cam["look"]
    scene.view_settings.look = look if look == "None" else f"{cam['view_transform']} - {look}"
    scene.cycles.film_exposure = 2.0**stops


def set_shutter(readout_s, exposure_s, fps):
    """A rolling shutter: each row exposed for `exposure_s`, the rows read
    out top to bottom over `readout_s`, the first opening at the frame
    time. Cycles' shutter spans both, as a fraction of the frame interval."""
    r = bpy.context.scene.render
    span = readout_s + exposure_s
    r.use_motion_blur = True
    r.motion_blur_shutter = min(1.0, span * fps)
    r.motion_blur_position = "START"
    c = bpy.context.scene.cycles
    c.rolling_shutter_type = "TOP"
    c.rolling_shutter_duration = exposure_s / span


def meter(path):
    """Renders the current camera view small and plain (no compositor, no
    denoiser, no blur, the whole frame) into the EXR `path` and returns its
    scene-linear pixels (rows top to bottom)."""
    scene = bpy.context.scene
    r, c = scene.render, scene.cycles
    fmt = r.image_settings
    saved = (r.resolution_percentage, r.use_border, r.use_compositing, r.use_motion_blur,
             c.samples, c.use_denoising, c.film_exposure, r.filepath)  # fmt: skip
    try:
        r.resolution_percentage = 15
        r.use_border = False
        r.use_compositing = False
        r.use_motion_blur = False
        c.samples, c.use_denoising, c.film_exposure = 4, False, 1.0
        fmt.file_format, fmt.color_depth = "OPEN_EXR", "32"
        r.filepath = path
        bpy.ops.render.render(write_still=True)
        image = bpy.data.images.load(path)
        try:
            w, h = image.size
            pixels = np.empty(w * h * 4, dtype=np.float32)
            image.pixels.foreach_get(pixels)
        finally:
            bpy.data.images.remove(image)
        return pixels.reshape(h, w, 4)[::-1]
    finally:
        (r.resolution_percentage, r.use_border, r.use_compositing, r.use_motion_blur,
         c.samples, c.use_denoising, c.film_exposure, r.filepath) = saved  # fmt: skip
        fmt.file_format, fmt.color_mode, fmt.color_depth = "PNG", "RGB", "8"
        if os.path.exists(path):
            os.remove(path)


def set_seed(seed_string):
    bpy.context.scene.cycles.seed = zlib.crc32(seed_string.encode()) & 0x7FFFFFFF
