"""The per-process Blender worker: builds the scene once, then renders
sequence plans one after the other, swapping in only the object."""

import os

import bpy

from blender_scripts import distractors, lights, materials, render, scene, world


def _clear_animation(obj):
    """Removes an object's keyframes and their action: a cleared action stays
    in bpy.data with no users, one more per sequence."""
    data = obj.animation_data
    action = data.action if data is not None else None
    obj.animation_data_clear()
    if action is not None and action.users == 0:
        bpy.data.actions.remove(action)


def _reset_factory():
    bpy.ops.wm.read_factory_settings(use_empty=True)


class Worker:
    """`geometry`: the room and table (planner's scene). `settings`: the
    engine and passes (RenderConfig)."""

    def __init__(self, geometry, settings):
        _reset_factory()
        self.settings = settings
        self.room = scene.Room(geometry)
        self.arm = scene.Arm()
        self.lights = lights.LightPool()
        self.world = world.World()
        self.distractors = distractors.Distractors()
        self.object_mat = bpy.data.materials.new("object")
        self.meshes = {}
        self.target = None
        self.head = None
        for obj in bpy.data.objects:
            if obj.name.startswith("table_"):
                obj.pass_index = render.INDEX_TABLE
        for obj in self.arm.parts:
            obj.pass_index = render.INDEX_HAND
        render.configure(settings)

    def has_mesh(self, object_id):
        return object_id in self.meshes

    def add_mesh(self, object_id, vertices, faces, smooth_angle_deg=35.0):
        """Caches a mesh from little-endian f64 xyz and u32 triangle bytes."""
        mesh = scene.mesh_from_bytes(object_id, vertices, faces, smooth_angle_deg)
        mesh.materials.append(self.object_mat)
        self.meshes[object_id] = mesh

    def _place_object(self, plan):
        mesh = self.meshes[plan["key"]["object"]]
        if self.target is None:
            self.target = bpy.data.objects.new("target", mesh)
            self.target.rotation_mode = "QUATERNION"
            self.target.pass_index = render.INDEX_OBJECT
            bpy.context.scene.collection.objects.link(self.target)
        elif self.target.data is not mesh:
            self.target.data = mesh
        pose = plan["object"]["pose"]
        self.target.location = pose["position"]
        self.target.rotation_quaternion = pose["rotation_wxyz"]
        self.target.scale = scene.axis_scale(plan["object"])

    def _apply_appearance(self, plan, object_color):
        a = plan["appearance"]
        materials.apply_surface(self.room.wall_mat, a["wall"])
        materials.apply_surface(self.room.floor_mat, a["floor"])
        materials.apply_surface(self.room.table_mat, a["table"])
        obj = a["object"]
        own = not (obj["randomized"] or obj.get("plausible", False))
        color = object_color if own else obj["color"]
        surface = obj.get("surface")
        materials.apply_plain(self.object_mat, color, obj["roughness"], surface=surface)
        scene.round_edges(self.target, float(surface["edge_radius_m"]) if surface else 0.0)
        self.lights.apply(a["lights"], aim_at=plan["object"]["pose"]["position"])
        self.world.apply(a.get("world"))
        self.room.open_to_sky(a.get("world") is not None or self.lights.has_sun(a["lights"]))
        render.set_exposure(self.settings, float(a["exposure"]))
        render.set_tone(self.settings, a.get("tone"))
        render.set_motion_blur(self.settings, a.get("motion_blur"))
        self.arm.set_hand_visible(bool(a["hand_visible"]))
        self.distractors.apply(plan.get("distractors", []))

    def prepare(self, plan, object_color):
        """Swaps in the sequence's object and applies its appearance."""
        self._place_object(plan)
        self._apply_appearance(plan, object_color)
        self.arm.set_intrinsics(plan["intrinsics"])

    def render_camera(self, plan, camera, out_dir, frame_files):
        """Renders every frame of a prepared `plan` from `camera` ("wrist" or
        "head") into `out_dir` under `frame_files`."""
        if len(frame_files) != len(plan["frames"]):
            raise ValueError("frame_files and plan frames differ in length")
        if camera == "wrist":
            view = None
        elif camera == "head":
            view = self._head_view(plan)
        else:
            raise ValueError(f"unknown camera '{camera}' (expected wrist or head)")
        bpy.context.scene.camera = self.arm.camera if view is None else view.camera
        try:
            self._render_frames(plan, view, out_dir, frame_files)
        finally:
            bpy.context.scene.camera = self.arm.camera
            self.arm.set_hand_visible(bool(plan["appearance"]["hand_visible"]))
            if self.head is not None:
                self.head.show_arm(False)

    def render(self, plan, out_dir, frame_files, object_color, head_out_dir=None):
        """Prepares `plan` and renders the wrist view, and the head view too
        when `head_out_dir` is given."""
        self.prepare(plan, object_color)
        self.render_camera(plan, "wrist", out_dir, frame_files)
        if head_out_dir is not None:
            self.render_camera(plan, "head", head_out_dir, frame_files)

    def _head_view(self, plan):
        missing = [f["index"] for f in plan["frames"] if not f.get("head_camera")]
        if missing:
            raise ValueError(f"frames {missing[:5]} have no head_camera pose")
        if self.head is None:
            self.head = scene.HeadCamera()
        self.head.set_intrinsics(plan["intrinsics"])
        sampled = plan.get("sampled", {})
        elbows = sampled.get("head_elbows")
        if elbows is not None and len(elbows) != len(plan["frames"]):
            raise ValueError(f"{len(elbows)} head_elbows for {len(plan['frames'])} frames")
        self.head.set_arm(sampled.get("head_shoulder"), elbows)
        # A head camera sees the hand whatever the wrist view's setting.
        self.arm.set_hand_visible(True, forearm=False)
        return self.head

    def _render_frames(self, plan, view, out_dir, frame_files):
        extra = render.extra_passes(self.settings)
        if self.settings.get("one_call", True) and not extra:
            self._render_animation(plan, view, out_dir, frame_files)
            return
        # Motion blur needs the path keyframed around each frame.
        keyed = bpy.context.scene.render.use_motion_blur
        moving = self._keyframe(plan, view) if keyed else []
        try:
            for i, (frame, name) in enumerate(zip(plan["frames"], frame_files)):
                if keyed:
                    bpy.context.scene.frame_set(frame["index"])
                else:
                    self.arm.set_pose(frame["camera"])
                    if view is not None:
                        view.set_pose(frame["head_camera"], frame["camera"], i)
                render.render_still()
                png = os.path.join(out_dir, name)
                exr = os.path.splitext(png)[0] + ".exr" if extra else None
                render.write_frame(png, exr)
        finally:
            for obj in moving:
                _clear_animation(obj)

    def _keyframe(self, plan, view):
        """Keys every planned pose of the moving objects; returns them."""
        moving = [self.arm.camera] + ([] if view is None else view.moving())
        for obj in moving:
            _clear_animation(obj)
        frames = plan["frames"]
        for i, frame in enumerate(frames):
            self.arm.set_pose(frame["camera"])
            if view is not None:
                view.set_pose(frame["head_camera"], frame["camera"], i)
            for obj in moving:
                obj.keyframe_insert("location", frame=frame["index"])
                obj.keyframe_insert("rotation_quaternion", frame=frame["index"])
                obj.keyframe_insert("scale", frame=frame["index"])
        first, last = frames[0]["index"], frames[-1]["index"]
        if [f["index"] for f in frames] != list(range(first, last + 1)):
            raise ValueError("frame indices are not consecutive")
        return moving

    def _render_animation(self, plan, view, out_dir, frame_files):
        frames = plan["frames"]
        moving = self._keyframe(plan, view)
        first, last = frames[0]["index"], frames[-1]["index"]
        stem = os.path.splitext(frame_files[0])[0]
        try:
            render.render_animation(out_dir, first, last, padding=len(stem))
        finally:
            for obj in moving:
                _clear_animation(obj)
        # Blender names files by frame number; rename if the plan's names differ.
        for frame, name in zip(frames, frame_files):
            made = os.path.join(out_dir, f"{frame['index']:0{len(stem)}d}.png")
            target = os.path.join(out_dir, name)
            if made != target:
                os.replace(made, target)
