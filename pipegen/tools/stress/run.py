"""Run stress cases: each scene on GL, CL and the float64 evaluation, every target of both
float32 backends against the float64 values within the bound of ``bounds.py``.

``Stress(compiled)`` holds one pipeline per backend (built once, reused for every case);
``Stress.run_case(case) -> CaseResult``.  A case the technique cannot render as the scene asks
(``features.mismatches``: light types, translucency, light-index capacity, the light table) is
rendered where possible and reported with its mismatches and dropped lights, its bounds not
counted (``status == "unsupported"``).
"""

from __future__ import annotations

import dataclasses
import itertools
import time
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from pipegen.core import formats as F
from pipegen.core.diagnostics import PipegenError
from pipegen.tools.stress import bounds as B
from pipegen.tools.stress.cases import Case

EDGE_FRACTION = 0.005        # as compare.py: coverage differences admitted on edges
EDGE_MIN = 4
BACKENDS = ("gl", "cl")


@dataclass
class TargetResult:
    key: str
    format: str
    backend: str
    exact: bool
    worst_ratio: float            # max error / bound over pixels not admitted as edges
    worst_error: float            # value units (exact targets: differing codes)
    bound_at_worst: float
    over: int                     # pixels over the bound, not admitted
    edges: int                    # pixels over the bound admitted as coverage differences
    edge_bound: int
    nonfinite_mismatch: int       # NaN/inf on one side only
    ratio_map: np.ndarray = field(repr=False, default=None)   # (H, W) error / bound
    output: bool = False          # the technique's output (or its depth/stencil): pass/fail;
    #                               other targets are reported (warn), not failed

    @property
    def passed(self) -> bool:
        return self.over == 0 and self.edges <= self.edge_bound and self.nonfinite_mismatch == 0

    def units(self, value: float) -> str:
        fmt = F.get(self.format)
        if self.exact:
            return f"{value:.0f} codes"
        if fmt.is_normalized or fmt.kind is F.Kind.DEPTH_STENCIL:
            top = max(fmt.max_codes)
            return f"{value * top:.3g} codes"
        return f"{value:.3g}"


@dataclass
class CaseResult:
    case: str
    description: str
    technique: str
    size: tuple[int, int]
    status: str                   # ok | warn | FAIL | unsupported | not rendered
    targets: list[TargetResult] = field(default_factory=list)
    nonfinite: dict = field(default_factory=dict)        # backend -> (nan, inf)
    agree: Optional[bool] = None                          # GL vs CL within §7's tolerance
    disagree: list[str] = field(default_factory=list)
    mismatches: list[str] = field(default_factory=list)
    dropped: str = "-"
    seconds: float = 0.0
    images: dict = field(default_factory=dict, repr=False)   # for the report's PNGs
    scene: object = field(default=None, repr=False)

    @property
    def worst(self) -> Optional[TargetResult]:
        rows = [t for t in self.targets if not t.exact]
        return max(rows, key=lambda t: t.worst_ratio) if rows else None

    @property
    def failed(self) -> bool:
        return self.status == "FAIL"


def _finite_counts(values: dict, f64: bool) -> tuple[int, int]:
    nan = inf = 0
    for k, v in values.items():
        a = np.asarray(v)
        if a.dtype.kind != "f" or k.endswith(".stencil"):
            continue
        nan += int(np.isnan(a).sum())
        inf += int(np.isinf(a).sum())
    return nan, inf


def _neighbour_stack(a: np.ndarray) -> np.ndarray:
    h, w = a.shape[:2]
    pad = [(1, 1), (1, 1)] + [(0, 0)] * (a.ndim - 2)
    p = np.pad(a, pad, mode="edge")
    return np.stack([p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
                     for dy in (-1, 0, 1) for dx in (-1, 0, 1)])


def _error(got: np.ndarray, want: np.ndarray) -> np.ndarray:
    """|got - want| with NaN matching only NaN, infinities only themselves (inf otherwise)."""
    with np.errstate(invalid="ignore", over="ignore"):
        e = np.abs(got - want)
    both_nan = np.isnan(got) & np.isnan(want)
    same_inf = np.isinf(got) & np.isinf(want) & (np.sign(got) == np.sign(want))
    e = np.where(both_nan | same_inf, 0.0, e)
    return np.where(np.isnan(e), np.inf, e)


def compare_values(key: str, fmt: F.Format, backend: str, got_codes: np.ndarray,
                   f64: np.ndarray, bound: np.ndarray, exact: bool) -> TargetResult:
    if exact:
        want = np.asarray(fmt.quantize(f64) if not key.endswith(".stencil") and
                          not fmt.is_integer else f64).astype(np.float64)
        got = np.asarray(got_codes).astype(np.float64)
        bound = np.zeros(got.shape)
    else:
        got = F.flush_denormals(np.asarray(got_codes)) if fmt.kind is F.Kind.FLOAT \
            else np.asarray(got_codes)
        got = fmt.dequantize(got)
        want = np.asarray(f64, np.float64)
    err = _error(got, want)
    nonfinite = int((np.isinf(err) & ~(np.isinf(got) & np.isinf(want))).sum())
    tiny = 1e-12 * np.maximum(np.abs(np.where(np.isfinite(want), want, 0.0)), 1e-30)
    ratio = err / np.maximum(bound, tiny) if not exact else np.where(err > 0, np.inf, 0.0)
    ratio = np.where(err == 0, 0.0, ratio)
    px_ratio = ratio.max(axis=-1) if ratio.ndim == 3 else ratio
    bad = px_ratio > 1.0
    admitted = np.zeros_like(bad)
    if bad.any():
        # a coverage difference: next to a jump of the float64 image much larger than the
        # bound, and each image's value found in the other's 3x3 neighbourhood
        nb_want = _neighbour_stack(want)
        nb_got = _neighbour_stack(got)
        lim = bound if not exact else np.zeros_like(err)
        def within(e):
            e = np.where(np.isnan(e), np.inf, e)
            ok = e <= lim[None] * (1 + 1e-9)
            return ok.all(axis=-1) if ok.ndim == 4 else ok
        with np.errstate(invalid="ignore"):
            jump = np.abs(nb_want - want[None])
            jump = np.where(np.isnan(jump), np.inf, jump)
            jmax = jump.max(axis=0)
            jmax = jmax.max(axis=-1) if jmax.ndim == 3 else jmax
            lmax = lim.max(axis=-1) if lim.ndim == 3 else lim
            edge = jmax > 0 if exact else jmax > 4 * lmax
            m1 = within(np.abs(nb_want - got[None])).any(axis=0)
            m2 = within(np.abs(nb_got - want[None])).any(axis=0)
        admitted = bad & edge & m1 & m2
    rest = np.where(admitted, 0.0, px_ratio)
    if rest.size:
        k = np.unravel_index(int(np.argmax(rest)), rest.shape)
        e_px = err.max(axis=-1)[k] if err.ndim == 3 else err[k]
        b_px = bound.max(axis=-1)[k] if bound.ndim == 3 else bound[k]
        if err.ndim == 3:
            c = int(np.argmax(ratio[k]))
            e_px, b_px = err[k][c], bound[k][c]
        worst = float(rest[k])
    else:
        worst, e_px, b_px = 0.0, 0.0, 0.0
    edge_bound = max(EDGE_MIN, int(EDGE_FRACTION * bad.size))
    return TargetResult(key, fmt.name, backend, exact, worst, float(e_px), float(b_px),
                        int((bad & ~admitted).sum()), int(admitted.sum()), edge_bound,
                        nonfinite, px_ratio)


def max_coordinate(scene) -> float:
    m = float(np.max(np.abs(scene.camera.position)))
    for o in scene.objects:
        if len(o.positions):
            m = max(m, float(np.abs(o.positions).max()))
    for l in scene.lights:
        if l.type != "directional":
            m = max(m, float(np.max(np.abs(l.position))))
    return m


def _change(got, want) -> np.ndarray:
    d = _error(np.asarray(got, np.float64), np.asarray(want, np.float64))
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


class Stress:
    def __init__(self, compiled, per_channel: bool = True):
        """``per_channel``: perturb each channel of the read targets in turn (2 renders per
        channel and level of reads); False: all channels at once (2 renders per level)."""
        from pipegen.compiler.capabilities import capabilities
        self.compiled = compiled
        self.per_channel = per_channel
        self.info = B.plan_targets(compiled)
        self.depth = B.read_depth(self.info)
        self.pipes = {b: compiled.pipeline(b) for b in BACKENDS}
        self.f64 = compiled.pipeline("cl", precision="f64")
        self.caps = capabilities(compiled.technique)

    # -- bounds ----------------------------------------------------------------------------
    def bounds(self, scene, f64: dict, blends: dict) -> tuple[dict, dict]:
        """Per target key: the bound (value units, the f64 array's shape), and its parts."""
        local, parts = {}, {}
        for key, v in f64.items():
            base, _, aspect = key.partition(".")
            t = self.info[base]
            if aspect:
                local[key] = np.zeros(np.shape(v))
                continue
            local[key] = B.local_bound(t, v, blends.get(base))
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
                pos[k] = pos[k] + _change(got[k], f64[k])
        # the float32 view transform of vertices errs by ulps of M in view space: the image
        # of a surface at view distance z moves by an angle of about delta / z.  Measured
        # with the camera turned by THETA (yaw, pitch), scaled per pixel to delta / z
        z = self._view_distance(scene, f64)
        if z is not None:
            for axis in range(2):
                got = self.f64.render(turned(scene, THETA, axis))
                for k in measured:
                    scale = _fit(delta / np.maximum(z, scene.camera.near) / THETA, f64[k])
                    pos[k] = pos[k] + _change(got[k], f64[k]) * scale
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
                        change[k] = np.maximum(change[k], _change(got[k], f64[k]))
                        if sign < 0:
                            prop[k] = prop[k] + change[k]
            reads = {k: B.SAFETY * v for k, v in prop.items()}
            total = {k: local[k] + pos[k] + reads[k] for k in local}
        for k in total:
            parts[k] = {"local": float(np.max(local[k])) if np.size(local[k]) else 0.0,
                        "position": float(np.max(pos[k])) if np.size(pos[k]) else 0.0,
                        "reads": float(np.max(reads[k])) if np.size(reads[k]) else 0.0}
        return total, parts

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

    # -- lights dropped ----------------------------------------------------------------------
    def dropped(self, scene) -> str:
        caps = self.caps
        if not caps.index_packings and not caps.slot_packings:
            return "-"
        from pipegen.reference.lighting import lights_per_pixel
        from pipegen.reference.raster import rasterize
        g = rasterize(scene)
        out = []
        rules = {r[0]: r[1:] for r in caps.index_rules}
        for pack, scheme, capacity, types in caps.index_packings:
            faces, bank = rules.get(pack, ("back", None))      # features.capabilities
            sub = dataclasses.replace(scene, lights=tuple(
                l for i, l in enumerate(scene.lights) if l.type in types and
                (bank is None or i % bank[0] == bank[1])))
            if not sub.lights:
                continue
            n = lights_per_pixel(g, sub, conservative=True, faces=faces,
                                 sky=faces == "front" and scene.has_translucent) - capacity
            n = np.maximum(n, 0)
            out.append(f"{pack}: <={int(n.max())}/px on {int((n > 0).sum())} px")
        for pack, slots, types in caps.slot_packings:
            lost = self.pipes["cl"].dropped_lights.get(pack, [])
            if lost:
                sub = dataclasses.replace(scene, lights=tuple(scene.lights[i] for i in lost))
                n = lights_per_pixel(g, sub)
                out.append(f"{pack}: {len(lost)} lights, <={int(n.max())}/px on "
                           f"{int((n > 0).sum())} px")
            else:
                out.append(f"{pack}: 0")
        return "; ".join(out) or "0"

    # -- one case ----------------------------------------------------------------------------
    def run_case(self, case: Case, keep_images: bool = True) -> CaseResult:
        t0 = time.perf_counter()
        scene = case.scene
        res = CaseResult(case.name, case.description, self.compiled.name,
                         (scene.width, scene.height), "ok", scene=scene)
        res.mismatches = [m.message for m in self.compiled.mismatches(scene)]
        try:
            renders = {b: self.pipes[b].render(scene) for b in BACKENDS}
            f64 = self.f64.render(scene)
        except PipegenError as e:
            res.status = "not rendered"
            res.mismatches.append(e.message if hasattr(e, "message") else str(e))
            res.seconds = time.perf_counter() - t0
            return res
        blends = getattr(self.pipes["cl"], "last_blend_counts", {}) or {}
        res.nonfinite = {b: _finite_counts(renders[b], False) for b in BACKENDS}
        res.nonfinite["f64"] = _finite_counts(f64, True)
        from pipegen.proof.check import compare_targets
        rows = compare_targets(self.compiled, renders["gl"], renders["cl"], len(scene.lights),
                               counts=blends)
        res.agree = all(r.passed for r in rows)
        res.disagree = [r.name for r in rows if not r.passed]
        res.dropped = self.dropped(scene)
        bound, parts = self.bounds(scene, f64, blends)
        for b in BACKENDS:
            for key in sorted(renders[b]):
                base, _, aspect = key.partition(".")
                t = self.info[base]
                exact = t.exact or aspect == "stencil"
                row = compare_values(key, t.format, b, renders[b][key], f64[key],
                                     bound[key], exact)
                row.output = base == self.compiled.technique.output
                res.targets.append(row)
        if keep_images:
            res.images = {"gl": renders["gl"], "f64": f64, "bound": bound, "parts": parts}
        if res.mismatches:
            res.status = "unsupported"
        elif not res.agree or any(not t.passed and t.output for t in res.targets):
            res.status = "FAIL"
        elif any(not t.passed for t in res.targets):
            res.status = "warn"
        res.seconds = time.perf_counter() - t0
        return res
