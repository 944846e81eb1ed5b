"""Distractor objects: a fixed pool of primitives (unit box, cylinder and
sphere meshes, scaled per plan), hidden unless the plan places them. They
get no object index, so no instance or part label ever covers them."""

import math

import bpy

from blender_scripts import materials

POOL_SIZE = 6


def _mesh(name, verts, faces, smooth=False):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    for poly in mesh.polygons:
        poly.use_smooth = smooth
    return mesh


def _unit_box():
    h = 0.5
    verts = [(x, y, z) for z in (-h, h) for y in (-h, h) for x in (-h, h)]
    faces = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (1, 3, 7, 5), (3, 2, 6, 7), (2, 0, 4, 6)]
    return _mesh("distractor_box", verts, faces)


def _unit_cylinder(segments=24):
    ring = [
        (0.5 * math.cos(2 * math.pi * i / segments), 0.5 * math.sin(2 * math.pi * i / segments))
        for i in range(segments)
    ]
    verts = [(x, y, -0.5) for x, y in ring] + [(x, y, 0.5) for x, y in ring]
    faces = [
        (i, (i + 1) % segments, segments + (i + 1) % segments, segments + i)
        for i in range(segments)
    ]
    faces.append(tuple(reversed(range(segments))))
    faces.append(tuple(range(segments, 2 * segments)))
    mesh = _mesh("distractor_cylinder", verts, faces)
    for poly in mesh.polygons[:segments]:
        poly.use_smooth = True
    return mesh


def _unit_sphere(rings=12, segments=24):
    verts = [(0.0, 0.0, -0.5)]
    for r in range(1, rings):
        phi = math.pi * r / rings - math.pi / 2
        for s in range(segments):
            theta = 2 * math.pi * s / segments
            verts.append(
                (
                    0.5 * math.cos(phi) * math.cos(theta),
                    0.5 * math.cos(phi) * math.sin(theta),
                    0.5 * math.sin(phi),
                )
            )
    verts.append((0.0, 0.0, 0.5))
    top = len(verts) - 1
    faces = [(0, 1 + (s + 1) % segments, 1 + s) for s in range(segments)]
    for r in range(rings - 2):
        a, b = 1 + r * segments, 1 + (r + 1) * segments
        faces += [
            (a + s, a + (s + 1) % segments, b + (s + 1) % segments, b + s) for s in range(segments)
        ]
    last = 1 + (rings - 2) * segments
    faces += [(last + s, last + (s + 1) % segments, top) for s in range(segments)]
    return _mesh("distractor_sphere", verts, faces, smooth=True)


def _own_material(obj, mat):
    """The object's own material in its slot (the unit meshes are shared)."""
    slot = obj.material_slots[0]
    slot.link = "OBJECT"
    slot.material = mat


class Distractors:
    def __init__(self):
        self.meshes = {"box": _unit_box(), "cylinder": _unit_cylinder(), "sphere": _unit_sphere()}
        for mesh in self.meshes.values():
            mesh.materials.append(None)  # one slot, filled per object
        self.objects = []
        for i in range(POOL_SIZE):
            mat = bpy.data.materials.new(f"distractor{i}")
            obj = bpy.data.objects.new(f"distractor{i}", self.meshes["box"])
            _own_material(obj, mat)
            obj.rotation_mode = "QUATERNION"
            obj.pass_index = 0
            obj.hide_render = True
            bpy.context.scene.collection.objects.link(obj)
            self.objects.append((obj, mat))

    def apply(self, specs):
        """Places the plan's distractors (a list of Distractor dicts)."""
        if len(specs) > POOL_SIZE:
            raise ValueError(f"{len(specs)} distractors in one plan (at most {POOL_SIZE})")
        for i, (obj, mat) in enumerate(self.objects):
            if i >= len(specs):
                obj.hide_render = True
                continue
            spec = specs[i]
            shape = spec["shape"]
            if shape not in self.meshes:
                raise ValueError(
                    f"unknown distractor shape '{shape}' (expected one of {sorted(self.meshes)})"
                )
            if obj.data is not self.meshes[shape]:
                obj.data = self.meshes[shape]
                _own_material(obj, mat)
            obj.location = spec["pose"]["position"]
            obj.rotation_quaternion = spec["pose"]["rotation_wxyz"]
            obj.scale = spec["size"]
            materials.apply_plain(mat, spec["color"], spec["roughness"])
            obj.hide_render = False
