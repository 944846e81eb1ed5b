"""The foreign world's room: a furnished kitchen-office built around the
planner's table footprint and room bounds, so what is planned and what is
drawn agree where it matters (the table top the objects stand on).

Floor, plaster walls with skirting, a window in one of three walls (open
onto the sky), a ceiling, a kitchen counter with cabinet fronts, a
bookshelf, a chair, and a table of its own build: a bevelled top exactly
over the planned slab, an apron, tapered round legs and, for cloth tops, a
tablecloth hanging over the edges. World frame: metres, Z up, the user on
the table's -X side."""

import math

import bpy

from blender_scripts.foreign import materials as m

WINDOW_HALF_WIDTH = 0.9
WINDOW_SILL = 0.9
WINDOW_TOP = 2.2
WALL_THICKNESS = 0.12


def mesh(name, verts, faces, mat=None, smooth=False):
    data = bpy.data.meshes.new(name)
    data.from_pydata(verts, [], faces)
    data.update()
    if smooth:
        for p in data.polygons:
            p.use_smooth = True
    obj = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(obj)
    if mat is not None:
        data.materials.append(mat)
    return obj


def block(name, lo, hi, mat=None, bevel=0.0):
    """An axis-aligned block from two corners, optionally with rounded edges."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    verts = [(x, y, z) for z in (z0, z1) for y in (y0, y1) for x in (x0, x1)]
    faces = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    obj = mesh(name, verts, faces, mat)
    if bevel > 0.0:
        mod = obj.modifiers.new("round", "BEVEL")
        mod.width = bevel
        mod.segments = 3
        for p in obj.data.polygons:
            p.use_smooth = True
    return obj


def tapered(name, base, top, r_base, r_top, mat=None, sides=14):
    """A round, tapered post from `base` (x, y, z) up to height `top`."""
    x, y, z = base
    ring = [
        (math.cos(2 * math.pi * i / sides), math.sin(2 * math.pi * i / sides)) for i in range(sides)
    ]
    verts = [(x + r_base * c, y + r_base * s, z) for c, s in ring]
    verts += [(x + r_top * c, y + r_top * s, top) for c, s in ring]
    faces = [(i, (i + 1) % sides, sides + (i + 1) % sides, sides + i) for i in range(sides)]
    faces += [tuple(reversed(range(sides))), tuple(range(sides, 2 * sides))]
    obj = mesh(name, verts, faces, mat)
    for p in obj.data.polygons[:sides]:
        p.use_smooth = True
    return obj


def window_frame(wall, room):
    """Where the window's opening lies: its centre, inward normal and the
    axis along the wall, for `wall` in ahead | left | right."""
    (_, y0), (x1, y1) = room["min_xy"], room["max_xy"]
    z = (WINDOW_SILL + WINDOW_TOP) / 2
    if wall == "ahead":
        return (x1, 0.0, z), (-1.0, 0.0, 0.0), (0.0, 1.0, 0.0)
    if wall == "left":
        return (0.0, y1, z), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0)
    if wall == "right":
        return (0.0, y0, z), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0)
    raise ValueError(f"unknown window wall '{wall}'")


class Room:
    """Builds every window variant once; `apply` shows the drawn one and
    sets the materials."""

    def __init__(self, geometry):
        room, table = geometry["room"], geometry["table"]
        self.room = room
        new = bpy.data.materials.new
        self.wall_mat, self.floor_mat, self.table_mat = (
            new("f_wall"),
            new("f_floor"),
            new("f_table"),
        )
        self.trim_mat, self.ceiling_mat = new("f_trim"), new("f_ceiling")
        self.leg_mat, self.counter_mat, self.worktop_mat = (
            new("f_leg"),
            new("f_counter"),
            new("f_worktop"),
        )
        self.shelf_mat, self.chair_mat = new("f_shelf"), new("f_chair")
        self.book_mats = [new(f"f_book{i}") for i in range(7)]
        (x0, y0), (x1, y1) = room["min_xy"], room["max_xy"]
        h = room["height"]
        mesh("f_floor", [(x0, y0, 0), (x1, y0, 0), (x1, y1, 0), (x0, y1, 0)], [(0, 1, 2, 3)],
             self.floor_mat)  # fmt: skip
        mesh("f_ceiling", [(x0, y0, h), (x0, y1, h), (x1, y1, h), (x1, y0, h)], [(0, 1, 2, 3)],
             self.ceiling_mat)  # fmt: skip
        self.walls = {w: self._wall(w) for w in ("ahead", "left", "right")}
        t = WALL_THICKNESS
        block("f_wall_behind", (x0 - t, y0 - t, 0), (x0, y1 + t, h), self.wall_mat)
        for i, (lo, hi) in enumerate(
            [((x0, y0, 0), (x0 + 0.015, y1, 0.09)), ((x1 - 0.015, y0, 0), (x1, y1, 0.09)),
             ((x0, y0, 0), (x1, y0 + 0.015, 0.09)), ((x0, y1 - 0.015, 0), (x1, y1, 0.09))]
        ):  # fmt: skip
            block(f"f_skirting{i}", lo, hi, self.trim_mat)
        self._table(table)
        self.counters = {w: self._counter(w) for w in ("ahead", "left")}
        self._shelf()
        self.chair = self._chair(table)
        self.counter_mug = tapered("f_counter_mug", (0, 0, 0), 0.1, 0.04, 0.045, self.book_mats[0])

    def _wall(self, wall):
        """The wall with its window opening: four blocks round the hole and
        a painted frame with a mullion, as one group hidden together."""
        (x0, y0), (x1, y1) = self.room["min_xy"], self.room["max_xy"]
        h, t, w = self.room["height"], WALL_THICKNESS, WINDOW_HALF_WIDTH
        parts = []
        if wall == "ahead":
            span, fixed = (y0, y1), (x1, x1 + t)

            def piece(name, a, b, z0, z1, mat=self.wall_mat):
                return block(name, (fixed[0], a, z0), (fixed[1], b, z1), mat)
        else:
            side = y1 if wall == "left" else y0
            span = (x0, x1)
            fixed = (side, side + t) if wall == "left" else (side - t, side)

            def piece(name, a, b, z0, z1, mat=self.wall_mat):
                return block(name, (a, fixed[0], z0), (b, fixed[1], z1), mat)

        parts.append(piece(f"f_{wall}_below", span[0], span[1], 0, WINDOW_SILL))
        parts.append(piece(f"f_{wall}_above", span[0], span[1], WINDOW_TOP, h))
        parts.append(piece(f"f_{wall}_l", span[0], -w, WINDOW_SILL, WINDOW_TOP))
        parts.append(piece(f"f_{wall}_r", w, span[1], WINDOW_SILL, WINDOW_TOP))
        f = 0.05
        parts.append(piece(f"f_{wall}_sill", -w, w, WINDOW_SILL, WINDOW_SILL + f, self.trim_mat))
        parts.append(piece(f"f_{wall}_head", -w, w, WINDOW_TOP - f, WINDOW_TOP, self.trim_mat))
        parts.append(piece(f"f_{wall}_jl", -w, -w + f, WINDOW_SILL, WINDOW_TOP, self.trim_mat))
        parts.append(piece(f"f_{wall}_jr", w - f, w, WINDOW_SILL, WINDOW_TOP, self.trim_mat))
        parts.append(
            piece(f"f_{wall}_mullion", -0.02, 0.02, WINDOW_SILL, WINDOW_TOP, self.trim_mat)
        )
        mid = (WINDOW_SILL + WINDOW_TOP) / 2
        parts.append(piece(f"f_{wall}_transom", -w, w, mid + 0.25, mid + 0.28, self.trim_mat))
        # Without the window: a plain wall.
        plain = piece(f"f_{wall}_plain", span[0], span[1], 0, h)
        return parts, plain

    def _table(self, table):
        (tx0, ty0), (tx1, ty1) = table["min_xy"], table["max_xy"]
        top, thick = table["height"], table["thickness"]
        self.top = block("table_f_top", (tx0, ty0, top - thick), (tx1, ty1, top), self.table_mat,
                         bevel=min(0.006, thick / 4))  # fmt: skip
        apron, inset = 0.09, 0.05
        z0, z1 = top - thick - apron, top - thick
        for i, (lo, hi) in enumerate(
            [((tx0 + inset, ty0 + inset, z0), (tx1 - inset, ty0 + inset + 0.02, z1)),
             ((tx0 + inset, ty1 - inset - 0.02, z0), (tx1 - inset, ty1 - inset, z1)),
             ((tx0 + inset, ty0 + inset, z0), (tx0 + inset + 0.02, ty1 - inset, z1)),
             ((tx1 - inset - 0.02, ty0 + inset, z0), (tx1 - inset, ty1 - inset, z1))]
        ):  # fmt: skip
            block(f"table_f_apron{i}", lo, hi, self.leg_mat)
        r = 0.075
        for i, (x, y) in enumerate([(tx0 + r, ty0 + r), (tx1 - r, ty0 + r), (tx1 - r, ty1 - r),
                                    (tx0 + r, ty1 - r)]):  # fmt: skip
            tapered(f"table_f_leg{i}", (x, y, 0.0), top - thick, 0.018, 0.028, self.leg_mat)
        # A tablecloth's overhang: thin panels hanging 5 mm off the edges.
        d, hang, e = 0.005, 0.22, 0.002
        self.drape = [
            block("table_f_drape0", (tx0 - d - e, ty0 - d, top - hang), (tx0 - d, ty1 + d, top), self.table_mat),
            block("table_f_drape1", (tx1 + d, ty0 - d, top - hang), (tx1 + d + e, ty1 + d, top), self.table_mat),
            block("table_f_drape2", (tx0 - d, ty0 - d - e, top - hang), (tx1 + d, ty0 - d, top), self.table_mat),
            block("table_f_drape3", (tx0 - d, ty1 + d, top - hang), (tx1 + d, ty1 + d + e, top), self.table_mat),
        ]  # fmt: skip

    def _counter(self, wall):
        """A kitchen counter against `wall` (ahead or left), 2.4 m long."""
        x1, y1 = self.room["max_xy"]
        depth, height, half = 0.6, 0.88, 1.2
        objs = []
        if wall == "ahead":
            lo, hi = (x1 - depth, -half, 0.1), (x1, half, height - 0.04)
            top = ((x1 - depth - 0.03, -half - 0.02, height - 0.04), (x1, half + 0.02, height))
            fronts = [((x1 - depth - 0.02, -half + 0.6 * i + 0.005, 0.12),
                       (x1 - depth, -half + 0.6 * (i + 1) - 0.005, height - 0.06)) for i in range(4)]  # fmt: skip
        else:
            lo, hi = (-half, y1 - depth, 0.1), (half, y1, height - 0.04)
            top = ((-half - 0.02, y1 - depth - 0.03, height - 0.04), (half + 0.02, y1, height))
            fronts = [((-half + 0.6 * i + 0.005, y1 - depth - 0.02, 0.12),
                       (-half + 0.6 * (i + 1) - 0.005, y1 - depth, height - 0.06)) for i in range(4)]  # fmt: skip
        objs.append(block(f"f_counter_{wall}", lo, hi, self.counter_mat))
        objs.append(block(f"f_worktop_{wall}", *top, self.worktop_mat, bevel=0.004))
        for i, (a, b) in enumerate(fronts):
            objs.append(block(f"f_front_{wall}{i}", a, b, self.counter_mat, bevel=0.003))
        return objs, top[1]

    def _shelf(self):
        """A bookshelf against the wall behind the user's right."""
        y0 = self.room["min_xy"][1]
        x, y = -1.6, y0 + 0.02
        for i, z in enumerate((0.05, 0.5, 0.95, 1.4, 1.85)):
            block(f"f_shelf{i}", (x, y, z), (x + 1.0, y + 0.32, z + 0.025), self.shelf_mat)
        for s, dx in enumerate((0.0, 0.98)):
            block(
                f"f_shelf_side{s}", (x + dx, y, 0.0), (x + dx + 0.02, y + 0.32, 1.9), self.shelf_mat
            )
        k = 0
        for z in (0.075, 0.525, 0.975, 1.425):
            px = x + 0.04
            for j in range(9):
                w, ht = 0.025 + 0.02 * ((j * 7 + k) % 3), 0.2 + 0.05 * ((j * 5 + k) % 4)
                block(f"f_book{k}", (px, y + 0.04, z), (px + w, y + 0.26, z + ht),
                      self.book_mats[k % len(self.book_mats)])  # fmt: skip
                px += w + 0.004
                k += 1

    def _chair(self, table):
        (_, ty0), _ = table["min_xy"], table["max_xy"]
        cx, cy = 0.1, ty0 - 0.45
        objs = [block("f_chair_seat", (cx - 0.21, cy - 0.2, 0.44), (cx + 0.21, cy + 0.2, 0.47),
                      self.chair_mat, bevel=0.01)]  # fmt: skip
        for i, (dx, dy) in enumerate([(-0.18, -0.17), (0.18, -0.17), (0.18, 0.17), (-0.18, 0.17)]):
            objs.append(
                tapered(
                    f"f_chair_leg{i}", (cx + dx, cy + dy, 0.0), 0.44, 0.013, 0.016, self.leg_mat
                )
            )
        objs.append(block("f_chair_back", (cx - 0.2, cy - 0.22, 0.47), (cx + 0.2, cy - 0.19, 0.9),
                          self.chair_mat, bevel=0.01))  # fmt: skip
        return objs

    def apply(self, d):
        """Shows the drawn window wall and counter, and sets the materials."""
        for wall, (parts, plain) in self.walls.items():
            opened = wall == d["window"]
            for p in parts:
                p.hide_render = not opened
            plain.hide_render = opened
        counter_wall = "left" if d["window"] == "ahead" else "ahead"
        for wall, (objs, _) in self.counters.items():
            for o in objs:
                o.hide_render = wall != counter_wall
        hi = self.counters[counter_wall][1]
        self.counter_mug.location = (hi[0] - 0.35, hi[1] - 0.5, hi[2]) if counter_wall == "ahead" else (
            -0.4, hi[1] - 0.3, hi[2])  # fmt: skip
        self.counter_mug.hide_render = not d["clutter"]["mug_on_counter"]
        for o in self.chair:
            o.hide_render = not d["clutter"]["chair"]
        cloth = d["table"]["kind"] == "cloth"
        for o in self.drape:
            o.hide_render = not cloth
        m.table_material(self.table_mat, d["table"])
        m.floor_material(self.floor_mat, d["floor"])
        m.plaster(self.wall_mat, d["wall_hsv"])
        m.plaster(self.ceiling_mat, (0.1, 0.02, 0.92))
        m.plain(self.trim_mat, (0.8, 0.8, 0.78), roughness=0.35, coat=0.3)
        if d["table"]["kind"] in ("stone", "laminate"):
            m.brushed_metal(self.leg_mat, (0.55, 0.55, 0.56), 0.35)
        else:
            m.wood(self.leg_mat, (0.07, 0.6, 0.3), 1.0, 0.0, 0.5)
        m.plain(self.counter_mat, m.linear(d["clutter"]["counter_srgb"]), roughness=0.4, coat=0.5)
        m.stone(self.worktop_mat, (0.1, 0.05, 0.3), roughness=0.2)
        m.wood(self.shelf_mat, (0.08, 0.35, 0.75), 1.2, 0.0, 0.55, varnish=0.2)
        m.cloth(self.chair_mat, (0.58, 0.35, 0.3))
        for mat, rgb in zip(self.book_mats, d["clutter"]["books_srgb"]):
            m.plain(mat, m.linear(rgb), roughness=0.6)
