"""The foreign world's light: daylight through the window and a warm pendant.

* A procedural sky (Blender's Sky Texture, Hosek-Wilkie or Preetham) as
  the world, seen and felt only through the window.
* The sun of that sky as a sun lamp in the same direction, whose colour
  follows its elevation.
* A light portal filling the window opening, which steers Cycles' world
  samples through it (training has no portal and no sky texture).
* A pendant lamp over the table, a shade with a small warm bulb
  (2200-2600 K, below training's 2700-6500 K), on in most sequences.
"""

import math

import bpy
from mathutils import Vector

from blender_scripts.foreign import materials, room


def _direction(d, window):
    """Unit vector towards the sun: outside the window's wall, off its
    normal by the drawn azimuth, at the drawn elevation."""
    _, inward, _ = room.window_frame(window, {"min_xy": [0, 0], "max_xy": [0, 0]})
    out = (-inward[0], -inward[1])
    a = math.radians(d["sun_off_normal_deg"])
    ox, oy = (
        out[0] * math.cos(a) - out[1] * math.sin(a),
        out[0] * math.sin(a) + out[1] * math.cos(a),
    )
    e = math.radians(d["sun_elevation_deg"])
    return Vector((ox * math.cos(e), oy * math.cos(e), math.sin(e)))


def _sun_temperature(elevation_deg):
    """Low sun is warmer: 4600 K at the horizon to 5800 K at 55 deg."""
    return 4600.0 + (5800.0 - 4600.0) * min(1.0, max(0.0, elevation_deg / 55.0))


class Lights:
    def __init__(self, geometry):
        self.room = geometry["room"]
        self.table = geometry["table"]
        self.world = bpy.data.worlds.new("f_sky")
        self.world.use_nodes = True
        nodes = self.world.node_tree.nodes
        nodes.clear()
        self.sky = nodes.new("ShaderNodeTexSky")
        self.background = nodes.new("ShaderNodeBackground")
        out = nodes.new("ShaderNodeOutputWorld")
        self.world.node_tree.links.new(self.sky.outputs["Color"], self.background.inputs["Color"])
        self.world.node_tree.links.new(self.background.outputs["Background"], out.inputs["Surface"])
        bpy.context.scene.world = self.world

        sun_data = bpy.data.lights.new("f_sun", "SUN")
        sun_data.angle = math.radians(0.55)
        sun_data.use_temperature = True
        self.sun = bpy.data.objects.new("f_sun", sun_data)
        bpy.context.scene.collection.objects.link(self.sun)

        portal = bpy.data.lights.new("f_portal", "AREA")
        portal.shape = "RECTANGLE"
        portal.size = 2 * room.WINDOW_HALF_WIDTH
        portal.size_y = room.WINDOW_TOP - room.WINDOW_SILL
        portal.cycles.is_portal = True
        self.portal = bpy.data.objects.new("f_portal", portal)
        bpy.context.scene.collection.objects.link(self.portal)

        bulb = bpy.data.lights.new("f_bulb", "POINT")
        bulb.shadow_soft_size = 0.03
        bulb.use_temperature = True
        self.bulb = bpy.data.objects.new("f_bulb", bulb)
        bpy.context.scene.collection.objects.link(self.bulb)
        self.shade_mat = bpy.data.materials.new("f_shade")
        materials.pendant_shade(self.shade_mat, (0.05, 0.09, 0.07))
        self.shade = self._shade()
        self.cord = room.tapered("f_cord", (0, 0, 0), 1.0, 0.004, 0.004, self.shade_mat, sides=6)

    def _shade(self, sides=24, r_top=0.05, r_bottom=0.18, height=0.16):
        """An open cone, wider at the bottom, hanging from its top."""
        ring = [
            (math.cos(2 * math.pi * i / sides), math.sin(2 * math.pi * i / sides))
            for i in range(sides)
        ]
        verts = [(r_bottom * c, r_bottom * s, -height) for c, s in ring]
        verts += [(r_top * c, r_top * s, 0.0) for c, s in ring]
        faces = [(i, (i + 1) % sides, sides + (i + 1) % sides, sides + i) for i in range(sides)]
        faces.append(tuple(range(sides, 2 * sides)))
        obj = room.mesh("f_shade", verts, faces, self.shade_mat, smooth=True)
        mod = obj.modifiers.new("shell", "SOLIDIFY")
        mod.thickness = 0.004
        return obj

    def apply(self, d):
        sky = d["sky"]
        direction = _direction(sky, d["window"])
        self.sky.sky_type = sky["type"]
        self.sky.turbidity = sky["turbidity"]
        self.sky.sun_direction = direction
        self.background.inputs["Strength"].default_value = sky["strength"]
        self.sun.rotation_mode = "QUATERNION"
        # A sun lamp shines along its -Z: point that axis away from the sun.
        self.sun.rotation_quaternion = (-direction).to_track_quat("-Z", "Y")
        self.sun.data.energy = sky["sun_strength"]
        self.sun.data.temperature = _sun_temperature(sky["sun_elevation_deg"])

        centre, inward, _ = room.window_frame(d["window"], self.room)
        self.portal.location = Vector(centre) + 0.01 * Vector(inward)
        self.portal.rotation_mode = "QUATERNION"
        # An area light emits along its -Z: into the room.
        self.portal.rotation_quaternion = Vector(inward).to_track_quat("-Z", "Z")

        lamp = d["lamp"]
        cx = (self.table["min_xy"][0] + self.table["max_xy"][0]) / 2 + lamp["offset"][0]
        cy = (self.table["min_xy"][1] + self.table["max_xy"][1]) / 2 + lamp["offset"][1]
        h = self.room["height"]
        z = h - lamp["drop_m"]
        self.shade.location = (cx, cy, z)
        self.cord.location = (cx, cy, z)
        self.cord.scale = (1.0, 1.0, h - z)
        self.bulb.location = (cx, cy, z - 0.07)
        self.bulb.data.energy = lamp["power_w"]
        self.bulb.data.temperature = lamp["temperature_k"]
        self.bulb.hide_render = not lamp["on"]
