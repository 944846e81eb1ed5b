"""The foreign world's camera and the hand it sees.

The pinhole part is the plan's (intrinsics and poses, applied exactly as
training does, since the plan's in-view checks and labels assume it); the
rest of the camera model is this world's own (see render.py for the
compositor): barrel distortion with lateral chromatic aberration,
vignetting, bloom, a rolling shutter with the shutter opening at the frame
time, an ACES tone curve, and an auto exposure (a centre-weighted meter
locked at the reach's start, setting the exposure time too) instead of
training's random exposure.

The hand is another prosthesis than training's: a rounded shell palm with
two-segment fingers and capsule tips, in a light grey, bone or graphite
shell, its fingertips entering the top of the image."""

import math

import bpy
import numpy as np

from blender_scripts import scene as plan_camera
from blender_scripts.foreign import materials, room

# Fingertips at this fraction of the image's upper half-height (training's
# hand: 0.8), FINGER_REACH ahead of the camera, bent this far towards the view.
TIP_FRACTION = 0.72
FINGER_REACH = 0.17
FINGER_BEND_DEG = 12.0
# The meter's target (scene-linear mid-grey) and the exposure time at 0 stops.
MID_GREY = 0.18
BASE_EXPOSURE_S = 1 / 120


def _sphere(name, radius, mat, segments=12, rings=8):
    verts, faces = [], []
    for j in range(1, rings):
        t = math.pi * j / rings
        for i in range(segments):
            p = 2 * math.pi * i / segments
            verts.append((radius * math.sin(t) * math.cos(p), radius * math.sin(t) * math.sin(p),
                          radius * math.cos(t)))  # fmt: skip
    top, bottom = len(verts), len(verts) + 1
    verts += [(0, 0, radius), (0, 0, -radius)]
    for j in range(rings - 2):
        for i in range(segments):
            a, b = j * segments + i, j * segments + (i + 1) % segments
            faces.append((a, b, b + segments, a + segments))
    for i in range(segments):
        faces.append((top, (i + 1) % segments, i))
        last = (rings - 2) * segments
        faces.append((bottom, last + i, last + (i + 1) % segments))
    return room.mesh(name, verts, faces, mat, smooth=True)


class Camera:
    def __init__(self):
        data = bpy.data.cameras.new("f_wrist_camera")
        self.camera = bpy.data.objects.new("f_wrist_camera", data)
        self.camera.rotation_mode = "QUATERNION"
        bpy.context.scene.collection.objects.link(self.camera)
        bpy.context.scene.camera = self.camera
        self.shell = bpy.data.materials.new("f_hand_shell")
        self.joint = bpy.data.materials.new("f_hand_joint")
        materials.plain(self.joint, (0.09, 0.09, 0.1), roughness=0.75)
        self.root = bpy.data.objects.new("f_hand_root", None)
        bpy.context.scene.collection.objects.link(self.root)
        self.root.parent = self.camera
        self.parts = []
        # Camera frame: looking along -Z, +Y up in the image. The hand hangs
        # above the camera, its fingers pointing along -Z.
        palm = room.block(
            "f_palm", (-0.045, -0.005, -0.11), (0.045, 0.03, 0.0), self.shell, bevel=0.012
        )
        self._attach(palm)
        self.fingers = []
        for i, x in enumerate((-0.033, -0.011, 0.011, 0.033)):
            base = bpy.data.objects.new(f"f_finger{i}", None)
            bpy.context.scene.collection.objects.link(base)
            base.location = (x, 0.012, -0.11)
            self._attach(base)
            for k, (length, radius) in enumerate(((0.035, 0.0095), (0.028, 0.0085))):
                seg = room.tapered(f"f_finger{i}_{k}", (0, 0, 0), length, radius, radius * 0.95,
                                   self.shell)  # fmt: skip
                seg.rotation_euler = (math.pi, 0.0, 0.0)
                seg.location = (0.0, 0.0, -0.035 * k)
                seg.parent = base
                self.parts.append(seg)
            tip = _sphere(f"f_tip{i}", 0.0085, self.joint)
            tip.location = (0.0, 0.0, -0.063)
            tip.parent = base
            self.parts.append(tip)
            self.fingers.append(base)
        thumb = room.tapered("f_thumb", (0, 0, 0), 0.055, 0.011, 0.009, self.shell)
        thumb.rotation_euler = (2.3, 0.7, 0.0)
        thumb.location = (-0.05, 0.0, -0.035)
        self._attach(thumb)

    def _attach(self, obj):
        obj.parent = self.root
        self.parts.append(obj)

    def apply(self, d, k):
        """The hand's shell and visibility, and the plan's intrinsics."""
        hand = d["hand"]
        materials.plain(self.shell, materials.linear(hand["shell"]), roughness=0.45, coat=0.3)
        for obj in self.parts:
            obj.hide_render = not hand["visible"]
        plan_camera.apply_intrinsics(self.camera.data, k)
        bend = math.radians(FINGER_BEND_DEG)
        for f in self.fingers:
            f.rotation_euler = (-bend, 0.0, 0.0)
        tan_half = (k["height"] / 2) / k["fy"]
        # The bent fingers' tips sit about this much below their base.
        drop = 0.063 * math.sin(bend) + 0.0085
        self.root.location = (0.0, TIP_FRACTION * tan_half * FINGER_REACH + drop - 0.012, 0.0)

    def set_pose(self, pose):
        plan_camera.set_pose(self.camera, pose)


def exposure(mean_luminance, bias):
    """The auto exposure, locked at the reach's start: the stops that bring
    the metered, centre-weighted mean luminance (scene-linear) to mid-grey,
    plus the drawn bias, within +-6 stops; and the exposure time that goes
    with it (a 30 fps camera: 1/120 s at 0 stops, longer in dim light, at
    most 1/30 s)."""
    stops = math.log2(MID_GREY / max(mean_luminance, 1e-6)) + bias
    stops = max(-6.0, min(6.0, stops))
    seconds = max(1 / 1000, min(1 / 30, BASE_EXPOSURE_S * 2.0**stops))
    return stops, seconds


def centre_weighted(pixels):
    """Mean luminance of an RGB(A) float image, weighted by a Gaussian
    centred on the image (sigma: a third of its size)."""
    h, w = pixels.shape[:2]
    y = (np.arange(h) - (h - 1) / 2) / (h / 3)
    x = (np.arange(w) - (w - 1) / 2) / (w / 3)
    weight = np.exp(-0.5 * (y[:, None] ** 2 + x[None, :] ** 2))
    lum = pixels[..., 0] * 0.2126 + pixels[..., 1] * 0.7152 + pixels[..., 2] * 0.0722
    return float((lum * weight).sum() / weight.sum())
