"""A fixed pool of lights, switched on and set from the plan per sequence
(creating and deleting lights would invalidate Cycles' persistent data).

Training draws point, spot and area lamps; the `unseen_look` condition has
a sun and a ring of small area lights (`ring`) of its own."""

import bpy

# Kind -> (Blender light type, pool size).
POOL = {
    "point": ("POINT", 4),
    "spot": ("SPOT", 4),
    "area": ("AREA", 4),
    "sun": ("SUN", 1),
    "ring": ("AREA", 8),
}
KINDS = tuple(POOL)


class LightPool:
    def __init__(self):
        self.pool = {kind: [] for kind in KINDS}
        for kind, (light_type, size) in POOL.items():
            for i in range(size):
                data = bpy.data.lights.new(f"{kind}{i}", type=light_type)
                obj = bpy.data.objects.new(f"{kind}{i}", data)
                bpy.context.scene.collection.objects.link(obj)
                obj.hide_render = True
                if kind == "ring":
                    obj.visible_camera = False
                self.pool[kind].append(obj)

    def apply(self, lights, aim_at):
        """Switches on one pooled light per plan light, aimed at `aim_at`."""
        used = {kind: 0 for kind in KINDS}
        for obj in (o for objs in self.pool.values() for o in objs):
            obj.hide_render = True
        for spec in lights:
            kind = spec["kind"]
            if kind not in self.pool:
                raise ValueError(f"unknown light kind '{kind}' (expected one of {KINDS})")
            if used[kind] >= len(self.pool[kind]):
                raise ValueError(f"more than {len(self.pool[kind])} '{kind}' lights in one plan")
            obj = self.pool[kind][used[kind]]
            used[kind] += 1
            obj.hide_render = False
            obj.location = spec["position"]
            _aim(obj, aim_at)
            data = obj.data
            data.energy = float(spec["power_w"])
            data.color = tuple(float(c) for c in spec["tint"])
            data.use_shadow = True
            if kind == "area":
                data.size = 0.5
            elif kind == "ring":
                data.size = 0.12
            elif kind == "sun":
                data.angle = 0.02  # soft shadow edge, radians
            elif kind == "spot":
                data.spot_size = 1.4
                data.spot_blend = 0.5
                data.shadow_soft_size = 0.1
            else:
                data.shadow_soft_size = 0.15

    def has_sun(self, lights):
        return any(spec["kind"] == "sun" for spec in lights)


def _aim(obj, target):
    """Points the light's -Z axis at `target`."""
    from mathutils import Vector

    direction = Vector(target) - obj.location
    obj.rotation_mode = "QUATERNION"
    obj.rotation_quaternion = direction.to_track_quat("-Z", "Y")
