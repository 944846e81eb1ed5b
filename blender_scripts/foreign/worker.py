"""The foreign world's worker: the same interface as training's
(`blender_scripts/worker.py`: has_mesh, add_mesh, prepare, render_camera,
render), with this package's scene and render path. It reads from the plan
only the object, its pose and scale, the camera poses and intrinsics, and
the stream seed its own draws come from (draw.py); the plan's appearance,
distractors and sensor are training's and play no part here."""

import os
import struct
import tempfile

import bpy

from blender_scripts.foreign import camera, draw, lights, materials, render, room
from blender_scripts.scene import axis_scale, mesh_from_bytes


def _reset():
    bpy.ops.wm.read_factory_settings(use_empty=True)


def _strip_render_times(png):
    """Removes the text chunks Cycles' render statistics leave in a PNG that
    went through the compositor (render and synchronisation times), so the
    same inputs give the same bytes."""
    with open(png, "rb") as f:
        data = f.read()
    out, i = [data[:8]], 8
    while i < len(data):
        n = struct.unpack(">I", data[i : i + 4])[0]
        chunk = data[i : i + 12 + n]
        if not (chunk[4:8] == b"tEXt" and chunk[8:15] == b"cycles."):
            out.append(chunk)
        i += 12 + n
    stripped = b"".join(out)
    if len(stripped) != len(data):
        with open(png, "wb") as f:
            f.write(stripped)


class Worker:
    def __init__(self, geometry, settings):
        _reset()
        if settings.get("engine", "cycles") != "cycles":
            raise ValueError("the foreign world renders with Cycles only")
        extra = [p for p in settings.get("passes", ["rgb"]) if p != "rgb"]
        if extra:
            raise ValueError(f"the foreign world renders rgb only, not {extra}")
        self.settings = settings
        self.room = room.Room(geometry)
        self.lights = lights.Lights(geometry)
        self.camera = camera.Camera()
        self.object_mat = bpy.data.materials.new("f_object")
        self.meshes = {}
        self.target = None
        self.lens = render.configure(settings)

    def has_mesh(self, object_id):
        return object_id in self.meshes

    def add_mesh(self, object_id, vertices, faces, smooth_angle_deg=30.0):
        """Caches a mesh from little-endian f64 xyz and u32 triangle bytes."""
        mesh = mesh_from_bytes(f"f_{object_id}", vertices, faces, smooth_angle_deg)
        mesh.materials.append(self.object_mat)
        self.meshes[object_id] = mesh

    def _place_object(self, plan):
        mesh = self.meshes[plan["key"]["object"]]
        if self.target is None:
            self.target = bpy.data.objects.new("f_target", mesh)
            self.target.rotation_mode = "QUATERNION"
            bpy.context.scene.collection.objects.link(self.target)
        elif self.target.data is not mesh:
            self.target.data = mesh
        pose = plan["object"]["pose"]
        self.target.location = pose["position"]
        self.target.rotation_quaternion = pose["rotation_wxyz"]
        self.target.scale = axis_scale(plan["object"])

    def prepare(self, plan, object_color, color_range=None):
        """Swaps in the object and applies this world's draws for the plan
        (`color_range`: the catalog's plausible colours of the object)."""
        d = draw.draw(plan, object_color, color_range)
        self._place_object(plan)
        self.room.apply(d)
        self.lights.apply(d)
        finish = materials.finish_of(plan["key"]["object"])
        materials.object_finish(self.object_mat, finish, d["object"]["color"], d["object"]["wear"])
        self.camera.apply(d, plan["intrinsics"])
        cam = d["camera"]
        self.lens.apply(cam)
        render.set_seed(d["seed"])
        # Auto exposure, metered from the first frame's view.
        self.camera.set_pose(plan["frames"][0]["camera"])
        metered = camera.centre_weighted(render.meter(self._meter_path()))
        stops, seconds = camera.exposure(metered, cam["exposure_bias"])
        render.set_tone(cam, stops)
        render.set_shutter(cam["readout_s"], seconds, plan["fps"])
        self.exposure = {"metered": metered, "stops": stops, "seconds": seconds}

    def _meter_path(self):
        return os.path.join(tempfile.gettempdir(), f"grasp-gen-meter-{os.getpid()}.exr")

    def render_camera(self, plan, camera_name, out_dir, frame_files):
        if camera_name != "wrist":
            raise ValueError(
                f"the foreign world renders the wrist camera only, not '{camera_name}'"
            )
        if len(frame_files) != len(plan["frames"]):
            raise ValueError("frame_files and plan frames differ in length")
        frames = plan["frames"]
        indices = [f["index"] for f in frames]
        first, last = indices[0], indices[-1]
        if indices != list(range(first, last + 1)):
            raise ValueError("frame indices are not consecutive")
        cam = self.camera.camera
        self._clear(cam)
        for frame in frames:
            self.camera.set_pose(frame["camera"])
            for prop in ("location", "rotation_quaternion"):
                cam.keyframe_insert(prop, frame=frame["index"])
        stem = os.path.splitext(frame_files[0])[0]
        scene = bpy.context.scene
        scene.frame_start, scene.frame_end = first, last
        scene.render.filepath = os.path.join(out_dir, "#" * len(stem))
        scene.render.use_file_extension = True
        try:
            bpy.ops.render.render(animation=True)
        finally:
            self._clear(cam)
        for frame, name in zip(frames, frame_files):
            made = os.path.join(out_dir, f"{frame['index']:0{len(stem)}d}.png")
            target = os.path.join(out_dir, name)
            if made != target:
                os.replace(made, target)
            _strip_render_times(target)

    @staticmethod
    def _clear(obj):
        data = obj.animation_data
        action = data.action if data is not None else None
        obj.animation_data_clear()
        if action is not None and action.users == 0:
            bpy.data.actions.remove(action)

    def render(self, plan, out_dir, frame_files, object_color, head_out_dir=None, color_range=None):
        self.prepare(plan, object_color, color_range)
        self.render_camera(plan, "wrist", out_dir, frame_files)
        if head_out_dir is not None:
            raise ValueError("the foreign world has no head camera")
