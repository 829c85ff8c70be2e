"""The tile bins of every light of a ``repeat per light`` group in three device buffers
(``DrawGeometry._group_bins``): one upload each for the group's tile lists, tile starts and
triangle rows, and per light views into them, instead of three buffers made per light
(deferred on many_lights: 243 uploads a frame for its 81 lights).

The raster kernel reads ``tile_list[group]``, ``tile_start[list]``, ``tile_start[list + 1]``
and ``tile_tris[k]`` for k between those two: a light's tile starts hold absolute offsets
into the group's triangle rows, so every light shares the one ``tile_tris`` buffer, and its
tile starts and tile list are sub-buffers of rows padded to the device's base address
alignment (what a sub-buffer's origin must be a multiple of).  A launch reads the same values
as from buffers of the light's own: nothing drawn changes."""

from __future__ import annotations

from typing import Optional

import numpy as np

__all__ = ["GroupBins", "LightBins"]


class GroupBins:
    """``starts`` (L, nlists + 1): each light's CSR starts into its own triangle rows, one
    list per ``band`` rows of a tile (``geometry.Bins``); ``first`` (L + 1,): where each
    light's rows begin in ``tile_tris`` (all lights' rows, by light, then list, then
    submission order; triangle indices); ``occupied`` (L, ntiles): the tiles with triangles;
    ``index``: the geometry buffers' row of each triangle (None: the same)."""

    def __init__(self, device, starts: np.ndarray, first: np.ndarray, occupied: np.ndarray,
                 tile_tris: np.ndarray, index: Optional[np.ndarray], band: int):
        lights, ntiles1 = starts.shape
        self.band = band
        ints = max(1, device.ctx.devices[0].mem_base_addr_align // 32)    # bits -> int32s
        self.start_row = -(-ntiles1 // ints) * ints
        self.list_row = -(-max(ntiles1 - 1, 1) // ints) * ints
        self.starts, self.first, self.tile_tris = starts, first, tile_tris
        self.occupied = occupied
        absolute = np.zeros((lights, self.start_row), np.int32)
        absolute[:, :ntiles1] = starts + first[:-1, None]
        owner, tiles = np.nonzero(occupied)        # by light, each light's tiles increasing
        self.active_n = np.count_nonzero(occupied, axis=1)
        self.active_at = np.concatenate([[0], np.cumsum(self.active_n)])
        self.tiles = tiles.astype(np.int32)
        lists = np.zeros((lights, self.list_row), np.int32)
        lists[owner, np.arange(len(tiles)) - self.active_at[owner]] = tiles
        rows = tile_tris if index is None or not len(index) else np.take(index, tile_tris)
        self.start_buf = device.buffer(absolute)
        self.list_buf = device.buffer(lists)
        self.tris_buf = device.buffer(np.ascontiguousarray(rows, np.int32) if len(rows)
                                      else np.zeros(1, np.int32))

    def light(self, j: int, tiles_x: int, triangles: int) -> "LightBins":
        """Light ``j``'s bins (``triangles``: how many of its triangles it draws)."""
        return LightBins(self, j, tiles_x, triangles)


class LightBins:
    """One light's bins in a ``GroupBins``: what ``geometry.Bins`` offers (``ntiles``,
    ``tiles_x``, ``triangles``, ``entries``, the three buffers, ``host``), its sub-buffers
    made when a launch first asks for them (a light whose volume covers no tile has none)."""

    def __init__(self, group: GroupBins, j: int, tiles_x: int, triangles: int):
        self.group, self.j = group, j
        self.band = group.band
        self.tiles_x = tiles_x
        self.triangles = triangles
        self.ntiles = int(group.active_n[j])
        self.entries = int(group.starts[j, -1])
        self.tile_tris = group.tris_buf
        self._list = self._start = None

    @property
    def tile_list(self):
        if self._list is None:
            g, row = self.group, self.group.list_row * 4
            self._list = g.list_buf.get_sub_region(self.j * row, row)
        return self._list

    @property
    def tile_start(self):
        if self._start is None:
            g, row = self.group, self.group.start_row * 4
            self._start = g.start_buf.get_sub_region(self.j * row, row)
        return self._start

    @property
    def host(self) -> tuple:
        """(tiles with triangles, tile starts, triangle indices) as ``Bins.host`` has them
        for bins of this light's own (tests)."""
        g, j = self.group, self.j
        own = g.tile_tris[g.first[j]:g.first[j + 1]]
        return (g.tiles[g.active_at[j]:g.active_at[j + 1]], g.starts[j],
                own if len(own) else np.zeros(1, np.int32))
