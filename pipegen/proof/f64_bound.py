"""The bound of the tolerance model for a target of a float32 render against the float64
evaluation, per pixel: the local terms of ``tolerance.py`` (store, blends, arithmetic), for a
depth attachment the error of its triangles' float32 planes (``depth_planes.py``), plus the two
measured ones, positions and reads (docs/tolerances.md).

``F64Bound(compiled)`` holds the float64 pipeline (built once); ``.bounds(scene, f64, blends)``
measures the terms by rendering the float64 evaluation perturbed: the lights and the camera
moved and turned by float32 ulps of the scene's largest coordinate, and every ``load``/``sample``
of a target seeing it plus (and minus) its own bound.
"""

from __future__ import annotations

import dataclasses
import itertools
from typing import Optional

import numpy as np

from pipegen.proof import tolerance as B
from pipegen.proof.f64_compare import error


def max_coordinate(scene) -> float:
    m = float(np.max(np.abs(scene.camera.position)))
    for o in scene.objects:
        if len(o.positions):
            m = max(m, float(np.abs(o.positions).max()))
    for l in scene.lights:
        if l.type != "directional":
            m = max(m, float(np.max(np.abs(l.position))))
    return m


def value_change(got, want) -> np.ndarray:
    d = error(np.asarray(got, np.float64), np.asarray(want, np.float64))
    return np.where(np.isfinite(d), d, 0.0)


THETA = 1e-4     # radians: the camera turn of the view-transform measurement


def turned(scene, theta: float, axis: int):
    """The camera turned by ``theta`` about its up (axis 0) or side (axis 1) direction."""
    cam = scene.camera
    eye = np.asarray(cam.position, np.float64)
    f = np.subtract(cam.target, eye)
    dist = np.linalg.norm(f)
    f = f / dist
    side = np.cross(f, cam.up)
    side = side / np.linalg.norm(side)
    up = np.cross(side, f)
    shift = side if axis == 0 else up
    target = eye + dist * (f + theta * shift)
    return dataclasses.replace(scene, camera=dataclasses.replace(cam, target=tuple(target)))


def _fit(scale: np.ndarray, like: np.ndarray) -> np.ndarray:
    """A per-pixel (H, W) map sampled (nearest) at the shape of ``like``, with a trailing
    axis for channels."""
    h, w = np.shape(like)[:2]
    sh, sw = scale.shape
    ys = np.minimum((np.arange(h) + 0.5) * sh / h, sh - 1).astype(int)
    xs = np.minimum((np.arange(w) + 0.5) * sw / w, sw - 1).astype(int)
    out = scale[ys][:, xs]
    return out[..., None] if np.ndim(like) == 3 else out


def moved(scene, delta: float, axis: int):
    """The scene with its lights and camera (position and target) moved by ``delta`` along
    world axis ``axis``: relative to them, the surfaces moved by -delta."""
    e = np.zeros(3)
    e[axis] = delta
    lights = tuple(dataclasses.replace(l, position=tuple(np.add(l.position, e)))
                   if l.type != "directional" else l for l in scene.lights)
    cam = scene.camera
    cam = dataclasses.replace(cam, position=tuple(np.add(cam.position, e)),
                              target=tuple(np.add(cam.target, e)))
    return dataclasses.replace(scene, lights=lights, camera=cam)


class _ReadPerturbation:
    """Makes a float64 pipeline's ``load``/``sample`` of target R see R + delta[R]: the target
    is overwritten before each pass that reads it and restored after."""

    def __init__(self, pipe, deltas: dict):
        self.pipe, self.deltas = pipe, deltas
        self._orig = pipe._run_pass

    def __enter__(self):
        pipe, deltas, orig = self.pipe, self.deltas, self._orig

        def run(k, light, *prepared):
            p = pipe.plan.passes[k]
            saved = {}
            for r in p.reads:
                if r not in deltas:
                    continue
                cur = pipe.store.read(pipe.store.targets[r])
                saved[r] = cur
                pipe.store.write(r, cur[r] + deltas[r], None)
            orig(k, light, *prepared)
            for r, cur in saved.items():
                if r not in p.writes and r != p.depth_target:
                    pipe.store.write(r, cur[r], None)
        pipe._run_pass = run
        return self

    def __exit__(self, *exc):
        self.pipe._run_pass = self._orig
        return False


class F64Bound:
    def __init__(self, compiled, per_channel: bool = True, f64_pipe=None):
        """``per_channel``: perturb each channel of the read targets in turn (2 renders per
        channel and level of reads); False: all channels at once (2 renders per level)."""
        self.compiled = compiled
        self.per_channel = per_channel
        self.info = B.plan_targets(compiled)
        self.depth = B.read_depth(self.info)
        self.f64 = f64_pipe or compiled.pipeline("cl", precision="f64")
        self.part_maps: dict = {}     # the last bounds' terms per pixel: key -> {term: array}

    # -- the bound --------------------------------------------------------------------------
    def bounds(self, scene, f64: dict, blends: dict) -> tuple[dict, dict]:
        """Per target key: the bound (value units, the f64 array's shape), and its parts."""
        local, parts = {}, {}
        planes = self._depth_planes(scene, f64)
        for key, v in f64.items():
            base, _, aspect = key.partition(".")
            t = self.info[base]
            if aspect:
                local[key] = np.zeros(np.shape(v))
                continue
            local[key] = B.local_bound(t, v, blends.get(base))
            if key in planes:       # a depth attachment: its triangles' float32 planes
                local[key] = local[key] + planes[key]
        # positions: lights and camera moved by POSITION_ULPS ulps of the largest coordinate
        # along x, y and z in turn (= the surface moved the other way); the first-order change
        # over the box |error_i| <= delta is the sum of the three changes
        delta = B.POSITION_ULPS * float(B.ulp32(max_coordinate(scene)))
        measured = [k for k in f64 if not k.endswith(".stencil")
                    and not self.info[k.partition(".")[0]].exact]
        pos = {k: np.zeros(np.shape(v)) for k, v in f64.items()}
        for axis in range(3):
            got = self.f64.render(moved(scene, delta, axis))
            for k in measured:
                pos[k] = pos[k] + value_change(got[k], f64[k])
        # the float32 view transform of vertices errs by ulps of M in view space: the image
        # of a surface at view distance z moves by an angle of about delta / z.  Measured
        # with the camera turned by THETA (yaw, pitch), scaled per pixel to delta / z
        z = self._view_distance(scene, f64)
        if z is not None:
            for axis in range(2):
                got = self.f64.render(turned(scene, THETA, axis))
                for k in measured:
                    scale = _fit(delta / np.maximum(z, scene.camera.near) / THETA, f64[k])
                    pos[k] = pos[k] + value_change(got[k], f64[k]) * scale
        total = {k: local[k] + pos[k] for k in local}
        reads = {k: np.zeros(np.shape(v)) for k, v in f64.items()}
        readers = sorted({r for t in self.info.values() for r in t.reads
                          if r in f64 and not self.info[r].exact})
        sampled = {r for t in self.info.values() for r in t.sampled}
        channels = max((np.shape(f64[r])[2] if np.ndim(f64[r]) == 3 else 1 for r in readers),
                       default=0)
        for _ in range(self.depth if readers else 0):
            prop = {k: np.zeros(np.shape(v)) for k, v in f64.items()}
            groups = range(channels) if self.per_channel else [None]
            for c, sign in itertools.product(groups, (1.0, -1.0)):
                # channel c of every read target, in turn, both ways (a clamp or max() may
                # flatten one side): per channel the larger change, summed over channels
                if sign > 0:
                    change = {k: np.zeros(np.shape(f64[k])) for k in measured}
                deltas = {}
                for r in readers:
                    d = total[r] + (B.resample_term(f64[r]) if r in sampled else 0.0)
                    if c is None:
                        pass
                    elif d.ndim == 3:
                        if c >= d.shape[2]:
                            continue
                        d = np.where(np.arange(d.shape[2]) == c, d, 0.0)
                    elif c:
                        continue
                    deltas[r] = sign * d
                with _ReadPerturbation(self.f64, deltas):
                    got = self.f64.render(scene)
                for k in measured:
                    if self.info[k.partition(".")[0]].reads:
                        change[k] = np.maximum(change[k], value_change(got[k], f64[k]))
                        if sign < 0:
                            prop[k] = prop[k] + change[k]
            reads = {k: B.SAFETY * v for k, v in prop.items()}
            total = {k: local[k] + pos[k] + reads[k] for k in local}
        # per pixel, for the line that says why a bound broke (``why.why_over``)
        self.part_maps = {k: {"local": local[k], "position": pos[k], "reads": reads[k],
                              "total": total[k]} for k in total}
        for k in total:
            parts[k] = {"local": float(np.max(local[k])) if np.size(local[k]) else 0.0,
                        "position": float(np.max(pos[k])) if np.size(pos[k]) else 0.0,
                        "reads": float(np.max(reads[k])) if np.size(reads[k]) else 0.0}
        return total, parts

    def _depth_planes(self, scene, f64: dict) -> dict:
        """Per depth target: the float32 plane error of the triangle that drew each pixel
        (``depth_planes.plane_error``), from the float64 evaluation's set-up of ``scene``
        (rendered again when its last frame was of another scene)."""
        from pipegen.proof.depth_planes import plane_error
        pipe = self.f64
        if pipe.last_scene is not scene:
            pipe.render(scene)
        out = {}
        for name in {target for target, _, _ in pipe.depth_draws}:
            v = f64.get(name)
            if v is None or np.ndim(v) != 2:
                continue
            out[name] = plane_error([(t, c) for n, t, c in pipe.depth_draws if n == name], v)
        return out

    def _view_distance(self, scene, f64: dict) -> Optional[np.ndarray]:
        """View distance of the visible surface per output pixel (from the first depth
        target at output size; sky: the far plane), or None without a depth target."""
        w, h = scene.width, scene.height
        for key, v in f64.items():
            t = self.info.get(key)
            if t is not None and t.is_depth and np.shape(v) == (h, w):
                n, f = scene.camera.near, scene.camera.far
                d = np.clip(np.asarray(v, np.float64), 0.0, 1.0)
                return n * f / (f - d * (f - n))
        return None

