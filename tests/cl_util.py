"""Helpers for the OpenCL reference tests: hand-built plans and scenes of raw triangles.

``TriScene`` draws triangles given directly in clip space (identity view and projection, so a
vertex ``(x, y, z)`` is clip ``(x, y, z, 1)``; pass ``view``/``proj`` for a real camera).  Each triangle's
object id is its index, and the "light table" holds one RGBA value per triangle, so a fragment
function ``out->o_color = in->lights[in->object_id]`` gives every triangle its own colour with
one compiled program (the table is data, not code).
"""

from __future__ import annotations

import numpy as np

from pipegen.scene import Geometry

FLAT_COLOR = ("static inline bool pg_fragment(const pg_in *in, pg_out *out) {\n"
              "    out->o_color = in->lights[in->object_id * PG_LIGHT_ROWS];\n"
              "    return true;\n}\n")


class _Camera:
    position = (0.0, 0.0, 0.0)

    def __init__(self, view=None, proj=None):
        self._view = np.eye(4) if view is None else np.asarray(view, np.float64)
        self._proj = np.eye(4) if proj is None else np.asarray(proj, np.float64)

    def view_matrix(self):
        return self._view

    def projection(self, aspect):
        return self._proj


class TriScene:
    def __init__(self, width, height, tris, colors=None, view=None, proj=None, ids=None):
        self.width, self.height = int(width), int(height)
        self.tris = np.asarray(tris, np.float64).reshape(-1, 3).astype(np.float32)
        n = len(self.tris) // 3
        self.colors = np.zeros((max(n, 1), 4), np.float32) if colors is None else \
            np.asarray(colors, np.float32).reshape(-1, 4)
        self.ids = np.arange(n) if ids is None else np.asarray(ids)
        self.camera = _Camera(view, proj)
        self.lights = ()
        self.ambient = np.zeros(3)

    @property
    def aspect(self):
        return self.width / self.height

    def geometry(self, material=()):
        V = len(self.tris)
        z = np.zeros((V, 3), np.float32)
        ids = np.zeros((V, 2), np.float32)
        ids[:, 0] = np.repeat(self.ids, 3)
        return Geometry(self.tris, z, z + 1, z, ids)

    def light_table(self, fields, capacity):
        t = np.zeros((capacity, len(fields), 4), np.float32)
        n = min(capacity, len(self.colors))
        t[:n, 0] = self.colors[:n]
        return t


def target(name, fmt, clear_color=None, clear_depth=None, clear_stencil=None, samples=1):
    return {"name": name, "format": fmt, "scale": 1.0, "width": 0, "height": 0,
            "samples": samples, "clear_color": clear_color, "clear_depth": clear_depth,
            "clear_stencil": clear_stencil}


def make_pass(name="p", writes=("color",), depth_target=None, state=None, fragment=FLAT_COLOR,
              inputs=("object_id",), discard=False, draw=None, reads=()):
    st = {"depth": {"func": "always", "write": False, "clamp": False},
          "stencil": {}, "blend": {}, "blend_constant": [0, 0, 0, 0], "cull": "none",
          "polygon_offset": None}
    st.update(state or {})
    return {"name": name,
            "draw": draw or {"kind": "scene", "material": [], "volume": None, "light_types": [],
                             "light_set": None, "scissor": False},
            "repeat_group": None, "clears": [], "writes": list(writes), "reads": list(reads),
            "depth_target": depth_target, "state": st,
            "cl": {"fragment": fragment, "inputs": list(inputs), "discard": discard,
                   "sampled": []}}


def make_plan(targets, passes, capacity=256):
    return {"technique": "test", "title": "test", "backend": "cl", "params": {},
            "lights": {"capacity": capacity, "fields": [["color", "vec4"]]},
            "output": targets[0]["name"], "targets": list(targets), "passes": list(passes),
            "light_sets": {}}


def quad(x0, y0, x1, y1, z=0.0):
    """Two ccw triangles covering the NDC rectangle [x0, x1] x [y0, y1] at depth z."""
    return [[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y0, z], [x1, y1, z], [x0, y1, z]]


def pixel_quad(width, height, c0, r0, c1, r1, z=0.0):
    """A quad covering whole pixels: columns c0..c1-1 and rows r0..r1-1 (GL row order, as in
    the arrays ``render`` returns: row 0 is window y 0, the bottom row)."""
    x0, x1 = 2.0 * c0 / width - 1.0, 2.0 * c1 / width - 1.0
    y0, y1 = 2.0 * r0 / height - 1.0, 2.0 * r1 / height - 1.0
    return quad(x0, y0, x1, y1, z)


def fullscreen(z=0.0, ccw=True):
    t = [[-1, -1, z], [3, -1, z], [-1, 3, z]]
    return t if ccw else [t[0], t[2], t[1]]
