"""The static scene, built once per worker: room, table, forearm and hand
with the wrist camera, and an empty slot for the sequence's object.

World frame: metres, Z up, floor at z = 0. Camera frame (Blender): looks
along local -Z, +Y up in the image.
"""

import bpy
import numpy as np
from mathutils import Vector

from blender_scripts import materials, render

# Hand and forearm in the camera frame. The camera sits below the wrist,
# looking along the forearm, so the hand's back and fingers enter the top of
# the image while the forearm stays behind the camera.
HAND_OFFSET = (0.0, 0.0, -0.02)
# Lowest point of the fingers above the hand root, and their distance ahead.
FINGER_TIP = 0.0075
FINGER_REACH = 0.19


def _face_uv(verts, face):
    """Planar UVs in metres, projected along the face's dominant normal axis."""
    a, b, c = (verts[i] for i in face[:3])
    u = [b[k] - a[k] for k in range(3)]
    v = [c[k] - a[k] for k in range(3)]
    n = [
        abs(u[1] * v[2] - u[2] * v[1]),
        abs(u[2] * v[0] - u[0] * v[2]),
        abs(u[0] * v[1] - u[1] * v[0]),
    ]
    axis = n.index(max(n))
    keep = [k for k in range(3) if k != axis]
    return [(verts[i][keep[0]], verts[i][keep[1]]) for i in face]


def mesh_object(name, verts, faces, material=None, uv=True):
    """An object from polygons, with planar UVs in metres."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    if uv:
        layer = mesh.uv_layers.new(name="UVMap")
        loop = 0
        for face in faces:
            for coord in _face_uv(verts, face):
                layer.data[loop].uv = coord
                loop += 1
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    if material is not None:
        mesh.materials.append(material)
    return obj


def axis_scale(placed):
    """The placed object's scale along its frame's X, Y, Z: the plan's
    `scale` times its `proportions` (grasp-schema's
    `ObjectPlacement::axis_scale`), for both scene builders."""
    scale = placed.get("scale", 1.0)
    return tuple(scale * p for p in placed.get("proportions", (1.0, 1.0, 1.0)))


def round_edges(obj, radius_m):
    """Rounds `obj`'s edges sharper than 30 degrees to about `radius_m`
    (metres in the world; the modifier works before the object's scale),
    or keeps them sharp at 0: an ObjectSurface's `edge_radius_m`."""
    mod = obj.modifiers.get("round_edges")
    if radius_m <= 0.0:
        if mod is not None:
            obj.modifiers.remove(mod)
        return
    if mod is None:
        mod = obj.modifiers.new("round_edges", "BEVEL")
        mod.limit_method = "ANGLE"
        mod.angle_limit = np.radians(30.0)
        mod.segments = 3
        mod.use_clamp_overlap = True
    mean_scale = sum(abs(s) for s in obj.scale) / 3.0
    mod.width = radius_m / max(mean_scale, 1e-6)


def mesh_from_bytes(name, vertices, faces, smooth_angle_deg):
    """A smooth-shaded mesh from the Rust side's little-endian f64 xyz and u32
    triangle bytes, sharp past `smooth_angle_deg`; both workers build their
    target objects with it."""
    v = np.frombuffer(vertices, dtype="<f8").astype(np.float32)
    f = np.frombuffer(faces, dtype="<u4").astype(np.int32)
    if v.size % 3 or f.size % 3:
        raise ValueError(f"mesh '{name}': byte lengths are not whole triangles")
    if f.size and f.max() >= v.size // 3:
        raise ValueError(f"mesh '{name}': face index {f.max()} out of range")
    mesh = bpy.data.meshes.new(name)
    mesh.vertices.add(v.size // 3)
    mesh.vertices.foreach_set("co", v)
    n = f.size // 3
    mesh.loops.add(f.size)
    mesh.loops.foreach_set("vertex_index", f)
    mesh.polygons.add(n)
    mesh.polygons.foreach_set("loop_start", np.arange(0, f.size, 3, dtype=np.int32))
    mesh.polygons.foreach_set("use_smooth", np.ones(n, dtype=bool))
    mesh.update(calc_edges=True)
    mesh.validate()
    mesh.set_sharp_from_angle(angle=np.radians(smooth_angle_deg))
    return mesh


def box(name, lo, hi, material=None):
    """An axis-aligned box from its two corners."""
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    verts = [
        (x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
        (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1),
    ]  # fmt: skip
    faces = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    return mesh_object(name, verts, faces, material)


def cylinder(name, radius, length, segments=16, material=None):
    """A capped cylinder along local +Z from z = 0 to z = length, smooth shaded."""
    import math

    ring = [
        (
            radius * math.cos(2 * math.pi * i / segments),
            radius * math.sin(2 * math.pi * i / segments),
        )
        for i in range(segments)
    ]
    verts = [(x, y, 0.0) for x, y in ring] + [(x, y, length) for x, y in ring]
    faces = [
        (i, (i + 1) % segments, segments + (i + 1) % segments, segments + i)
        for i in range(segments)
    ]
    faces.append(tuple(reversed(range(segments))))
    faces.append(tuple(range(segments, 2 * segments)))
    obj = mesh_object(name, verts, faces, material, uv=False)
    for poly in obj.data.polygons[:segments]:
        poly.use_smooth = True
    return obj


class Room:
    """Floor, four walls, ceiling with a lamp, and a table, from the planner's
    scene geometry (so what is planned and what is drawn agree)."""

    def __init__(self, geometry):
        room = geometry["room"]
        table = geometry["table"]
        self.wall_mat = bpy.data.materials.new("wall")
        self.floor_mat = bpy.data.materials.new("floor")
        self.table_mat = bpy.data.materials.new("table")
        ceiling_mat = bpy.data.materials.new("ceiling")
        materials.apply_plain(ceiling_mat, (0.8, 0.8, 0.8), 0.9)
        leg_mat = bpy.data.materials.new("table_leg")
        materials.apply_plain(leg_mat, (0.05, 0.05, 0.05), 0.4, metallic=0.8)

        (x0, y0), (x1, y1) = room["min_xy"], room["max_xy"]
        h = room["height"]
        mesh_object(
            "floor",
            [(x0, y0, 0), (x1, y0, 0), (x1, y1, 0), (x0, y1, 0)],
            [(0, 1, 2, 3)],
            self.floor_mat,
        )
        self.ceiling = mesh_object(
            "ceiling",
            [(x0, y0, h), (x0, y1, h), (x1, y1, h), (x1, y0, h)],
            [(0, 1, 2, 3)],
            ceiling_mat,
        )
        corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
        for i in range(4):
            (ax, ay), (bx, by) = corners[i], corners[(i + 1) % 4]
            verts = [(ax, ay, 0), (bx, by, 0), (bx, by, h), (ax, ay, h)]
            mesh_object(f"wall{i}", verts, [(0, 1, 2, 3)], self.wall_mat)

        lamp_mat = bpy.data.materials.new("lamp")
        materials.emission(lamp_mat, 6.0)
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        lamp = cylinder("ceiling_lamp", 0.25, 0.04, segments=24, material=lamp_mat)
        lamp.location = (cx, cy, h - 0.04)
        self.lamp = lamp

        (tx0, ty0), (tx1, ty1) = table["min_xy"], table["max_xy"]
        top, thick = table["height"], table["thickness"]
        box("table_top", (tx0, ty0, top - thick), (tx1, ty1, top), self.table_mat)
        leg = 0.05
        inset = 0.05
        for i, (lx, ly) in enumerate(
            [
                (tx0 + inset, ty0 + inset),
                (tx1 - inset - leg, ty0 + inset),
                (tx1 - inset - leg, ty1 - inset - leg),
                (tx0 + inset, ty1 - inset - leg),
            ]
        ):
            box(f"table_leg{i}", (lx, ly, 0.0), (lx + leg, ly + leg, top - thick), leg_mat)

    def open_to_sky(self, is_open):
        """Hides the ceiling and its lamp while world light or a sun shines."""
        self.ceiling.hide_render = is_open
        self.lamp.hide_render = is_open


class Arm:
    """The wrist camera with a simple forearm and prosthetic hand rigidly
    attached: the camera is below the wrist, the hand above and ahead."""

    def __init__(self):
        cam_data = bpy.data.cameras.new("wrist_camera")
        self.camera = bpy.data.objects.new("wrist_camera", cam_data)
        self.camera.rotation_mode = "QUATERNION"
        bpy.context.scene.collection.objects.link(self.camera)
        bpy.context.scene.camera = self.camera

        shell = bpy.data.materials.new("hand_shell")
        materials.apply_plain(shell, (0.03, 0.03, 0.035), 0.35)
        sleeve = bpy.data.materials.new("sleeve")
        materials.apply_plain(sleeve, (0.12, 0.16, 0.25), 0.8)
        self.parts = []
        # Every hand part hangs from one root, raised or lowered per camera
        # so the fingers just enter the top of the image (set_intrinsics).
        self.hand_root = bpy.data.objects.new("hand_root", None)
        bpy.context.scene.collection.objects.link(self.hand_root)
        self.hand_root.parent = self.camera
        ox, oy, oz = HAND_OFFSET
        # Forearm: behind the camera, along +Z of the camera frame.
        forearm = cylinder("forearm", 0.04, 0.30, material=sleeve)
        forearm.location = (ox, oy, oz + 0.02)
        self._attach(forearm)
        self.forearm = forearm
        # Palm: a flat box ahead of the wrist, back of the hand facing the camera.
        palm = box("palm", (-0.042, -0.012, -0.10), (0.042, 0.022, 0.0), shell)
        palm.location = (ox, oy + 0.01, oz)
        self._attach(palm)
        for i, x in enumerate((-0.030, -0.010, 0.010, 0.030)):
            finger = cylinder(f"finger{i}", 0.0085, 0.075, material=shell)
            finger.rotation_euler = (3.14159265, 0.0, 0.0)  # point along -Z
            finger.location = (ox + x, oy + 0.016, oz - 0.095)
            self._attach(finger)
        thumb = cylinder("thumb", 0.010, 0.06, material=shell)
        thumb.rotation_euler = (2.5, 0.6, 0.0)
        thumb.location = (ox - 0.045, oy - 0.005, oz - 0.03)
        self._attach(thumb)

    def _attach(self, obj):
        obj.parent = self.hand_root
        self.parts.append(obj)

    def set_hand_visible(self, visible, forearm=True):
        """Shows or hides the hand; `forearm=False` hides the forearm anyway
        (it runs along the wrist camera's axis, which only the wrist view
        can assume: seen from the head it would float in front of the eyes)."""
        for obj in self.parts:
            obj.hide_render = not visible
        self.forearm.hide_render = not (visible and forearm)

    def set_intrinsics(self, k):
        """Pinhole intrinsics (pixels) of the wrist camera and the image size."""
        apply_intrinsics(self.camera.data, k)
        # Finger tips (FINGER_TIP below the root, FINGER_REACH ahead) at 80 %
        # of the upper half-height of the image.
        tan_half = (k["height"] / 2) / k["fy"]
        self.hand_root.location = (0.0, 0.8 * tan_half * FINGER_REACH - FINGER_TIP, 0.0)

    def set_pose(self, pose):
        set_pose(self.camera, pose)


class HeadCamera:
    """The egocentric camera: a second camera with the wrist camera's
    intrinsics, posed from the plan's `head_camera` poses, and the arm it
    sees: a sleeve from the wrist camera to the planned shoulder (the wrist
    view's forearm runs along its own camera axis and is hidden here)."""

    def __init__(self):
        data = bpy.data.cameras.new("head_camera")
        self.camera = bpy.data.objects.new("head_camera", data)
        self.camera.rotation_mode = "QUATERNION"
        bpy.context.scene.collection.objects.link(self.camera)
        sleeve_mat = bpy.data.materials.get("sleeve")
        # Unit-length cylinders along +Z, stretched between the joints.
        self.links = [
            cylinder(f"head_view_{name}", radius, 1.0, material=sleeve_mat)
            for name, radius in (("forearm", 0.04), ("upper_arm", 0.05))
        ]
        for link in self.links:
            link.rotation_mode = "QUATERNION"
        self.joints = None
        self.show_arm(False)

    def set_intrinsics(self, k):
        apply_intrinsics(self.camera.data, k)

    def set_arm(self, shoulder, elbows):
        """The planned shoulder and per-frame elbows (None: no arm)."""
        self.joints = None if shoulder is None or elbows is None else (shoulder, elbows)

    def show_arm(self, visible):
        for link in self.links:
            link.hide_render = not visible

    def moving(self):
        return [self.camera, *self.links]

    def set_pose(self, pose, wrist_pose, frame_index):
        set_pose(self.camera, pose)
        self.show_arm(self.joints is not None)
        if self.joints is None:
            return
        shoulder, elbows = self.joints
        wrist, elbow = Vector(wrist_pose["position"]), Vector(elbows[frame_index])
        for link, (a, b) in zip(self.links, ((wrist, elbow), (elbow, Vector(shoulder)))):
            span = b - a
            link.location = a
            link.rotation_quaternion = span.to_track_quat("Z", "Y")
            link.scale = (1.0, 1.0, max(span.length, 1e-3))


def set_pose(obj, pose):
    obj.location = pose["position"]
    obj.rotation_quaternion = pose["rotation_wxyz"]


def apply_intrinsics(cam, k):
    """Pinhole intrinsics (pixels) to Blender's sensor/shift model, and the
    scene's image size."""
    w, h = k["width"], k["height"]
    cam.sensor_fit = "HORIZONTAL" if w >= h else "VERTICAL"
    cam.sensor_width = 36.0
    cam.sensor_height = 36.0
    if w >= h:
        cam.lens = cam.sensor_width * k["fx"] / w
    else:
        cam.lens = cam.sensor_height * k["fy"] / h
    big = max(w, h)
    cam.shift_x = (w / 2 - k["cx"]) / big
    cam.shift_y = (k["cy"] - h / 2) / big
    cam.clip_start = k["clip_near"]
    cam.clip_end = k["clip_far"]
    scene = bpy.context.scene
    scene.render.resolution_x = w
    scene.render.resolution_y = h
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = 1.0
    scene.render.pixel_aspect_y = k["fx"] / k["fy"] if k["fy"] else 1.0
    render.apply_center_region(scene)
