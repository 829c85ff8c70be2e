"""``render`` a technique and assert what it renders: against the other backend, against its
float64 evaluation, against stored goldens (docs/testing.md).

Every comparison holds each target to the bound of the tolerance model (docs/tolerances.md):
the limit two float32 renders may differ by (``check``'s, for GL against CL and for a golden),
or the bound a float32 render may differ from the float64 evaluation by (``stress``'s).
Pixels where the technique's own code steps (a comparison, ``floor``, ``step``, ...) and the two
evaluations took different sides are *discontinuities*: counted apart, and allowed only up to
``max_discontinuities`` (0 unless the test says otherwise).

Each comparison is recorded (``records.py``) for the pytest plugin's report; a failure raises
``ComparisonFailure`` naming the target, its worst pixel (x, y counted from the top of the
picture, both values, the bound) and the error image written.
"""

from __future__ import annotations

import os
import shlex
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Optional, Union

import numpy as np

from pipegen.compiler.driver import Compiled, compile_file
from pipegen.core import formats
from pipegen.proof.clamps import ClampWarning, Clamped, clamped_values
from pipegen.scene import Scene, default_scene, load_scene
from pipegen.testing import records, settings

TechniqueLike = Union[str, os.PathLike, Compiled]
SceneLike = Union[str, os.PathLike, Scene, None]
TEST_SIZE = (64, 36)          # the default scene's size in a test: small, fast, 16:9


class ComparisonFailure(AssertionError):
    """A comparison failed; ``comparisons``: the records of every target compared."""

    def __init__(self, message: str, comparisons: list[records.Comparison]):
        super().__init__(message)
        self.comparisons = comparisons


@dataclass(frozen=True)
class TargetImage:
    """One target of a render: ``values`` as the backend returns them (codes in the format's
    dtype, or float64 values from the float64 evaluation), row 0 at the bottom."""
    name: str
    format: str
    values: np.ndarray

    def picture(self) -> np.ndarray:
        """(H, W, 3) uint8, top row first: what ``pipegen run`` would draw of it."""
        from pipegen.views.visualize import to_rgb8
        fmt = formats.get(self.format)
        hint = "stencil" if self.name.endswith(".stencil") else "auto"
        return np.ascontiguousarray(to_rgb8(self.values, fmt, hint)[::-1])


@dataclass
class Targets(Mapping):
    """A render's targets by name (``targets["color"].values``), with what made them."""
    technique: str
    backend: str
    scene: Scene
    compiled: Compiled = field(repr=False)
    images: dict[str, TargetImage] = field(repr=False)
    command: str = ""                          # a shell command that renders the same
    blend_counts: dict = field(default_factory=dict, repr=False)   # CL: fragments per pixel
    # CL: the values each target's format clamped in the frame (``proof.clamps.Clamped``:
    # ``clamped["galbedo"]``, ``clamped.passes("galbedo")``); None on GL, which never shows them
    clamped: Optional[Clamped] = field(default=None, repr=False)

    def __getitem__(self, name: str) -> TargetImage:
        return self.images[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self.images)

    def __len__(self) -> int:
        return len(self.images)

    def codes(self) -> dict[str, np.ndarray]:
        return {k: v.values for k, v in self.images.items()}


# -- loading -----------------------------------------------------------------------------------

_COMPILED: dict[tuple, Compiled] = {}
_SOURCES: dict[int, str] = {}                  # id(Compiled) -> the .pipe path it came from


def load_technique(technique: TechniqueLike, params: Optional[dict] = None) -> Compiled:
    """A compiled technique: a ``Compiled`` as given, or a ``.pipe`` path compiled (once per
    file version and parameters)."""
    if isinstance(technique, Compiled):
        if params and any(technique.params.get(k) != v for k, v in params.items()):
            raise ValueError("params differ from the ones this technique was compiled with: "
                             "pass its .pipe path (or compile_file(path, params=...))")
        return technique
    path = Path(technique).resolve()
    key = (str(path), path.stat().st_mtime_ns if path.exists() else 0,
           tuple(sorted((params or {}).items())))
    if key not in _COMPILED:
        compiled = compile_file(path, params=params)
        _COMPILED[key] = compiled
        _SOURCES[id(compiled)] = str(technique)
    return _COMPILED[key]


_VARIANTS: dict[tuple, tuple[Compiled, Compiled]] = {}


def for_scene(compiled: Compiled, scene: Scene, general: Optional[bool] = None) -> Compiled:
    """What the functions here render of ``scene``: the variant of ``compiled`` compiled for it
    (as ``pipegen run`` renders; its light table shrunk when the technique was given as a
    path), or the general build with ``general`` (None: ``settings.general``, set by ``pytest
    --pipegen-general``).  One variant object per technique and facts, so that its pipelines
    are built once."""
    from pipegen.compiler.driver import for_scene as variant
    from pipegen.scene.features import scene_features
    general = settings.general if general is None else general
    if general or compiled.specialisation is not None:
        return compiled
    key = (id(compiled), scene_features(scene).facts())
    if key not in _VARIANTS:          # the base is kept with it: its id stays its own
        special = variant(compiled, scene, path=_SOURCES.get(id(compiled)))
        _VARIANTS[key] = (compiled, special)
        if id(compiled) in _SOURCES:
            _SOURCES[id(special)] = _SOURCES[id(compiled)]
    return _VARIANTS[key][1]


def load_test_scene(scene: SceneLike = None, size: Optional[tuple[int, int]] = None) -> Scene:
    """The scene a test renders: a path (``.toml``, ``.gltf``/``.glb``), a ``Scene``, or None
    for the built-in default scene at ``TEST_SIZE``; ``size`` overrides its size."""
    if scene is None:
        s = default_scene().with_size(*(size or TEST_SIZE))
        return s
    s = scene if isinstance(scene, Scene) else load_scene(scene)
    return s.with_size(*size) if size else s


def _command(verb: str, compiled: Compiled, scene_arg: SceneLike, scene: Scene,
             extra: tuple[str, ...] = ()) -> str:
    words = ["pipegen", verb, _SOURCES.get(id(compiled), f"<{compiled.name}.pipe>")]
    if scene_arg is not None and not isinstance(scene_arg, Scene):
        words += ["--scene", str(scene_arg)]
    elif isinstance(scene_arg, Scene):
        words += ["--scene", f"<{scene.name}>"]
    words += ["--size", f"{scene.width}x{scene.height}"]
    for k, v in sorted(compiled.params.items()):
        words += ["-p", f"{k}={v}"]
    if compiled.specialisation is None:       # the commands render the variant without it
        words += ["--general"]
    return " ".join(shlex.quote(w) if not w.startswith("<") else w for w in words + list(extra))


# -- rendering ---------------------------------------------------------------------------------

_PIPES: dict[tuple, tuple[Compiled, Any]] = {}
_MAX_PIPES = 8


def _pipeline(compiled: Compiled, backend: str, precision: str = "f32"):
    key = (id(compiled), backend, precision)
    if key not in _PIPES:
        if len(_PIPES) >= _MAX_PIPES:
            _PIPES.pop(next(iter(_PIPES)))
        _PIPES[key] = (compiled, compiled.pipeline(backend, precision=precision))
    return _PIPES[key][1]


def render(technique: TechniqueLike, scene: SceneLike = None, backend: str = "gl",
           size: Optional[tuple[int, int]] = None, params: Optional[dict] = None,
           general: Optional[bool] = None) -> Targets:
    """Render ``technique`` on ``scene`` with ``backend`` ("gl", "cl"): its targets by name,
    with their formats.  The variant compiled for the scene, or with ``general`` the general
    build (``for_scene``)."""
    s = load_test_scene(scene, size)
    compiled = for_scene(load_technique(technique, params), s, general)
    pipe = _pipeline(compiled, backend)
    values = pipe.render(s)
    images = {}
    for key, v in values.items():
        base = key.partition(".")[0]
        images[key] = TargetImage(key, compiled.technique.target(base).format.name, v)
    counts = dict(getattr(pipe, "last_blend_counts", None) or {})
    clamped = clamped_values(pipe, compiled.technique.output)
    for line in clamped.warnings() if clamped is not None else ():
        if line.startswith("warning: "):    # once per pass and target (Python's warning filter)
            warnings.warn(f"{compiled.name}: {line[len('warning: '):]}", ClampWarning,
                          stacklevel=2)
    return Targets(compiled.name, backend, s, compiled, images,
                   _command("run", compiled, scene, s, ("--backend", backend)), counts,
                   clamped)


# -- messages ----------------------------------------------------------------------------------

def _channels(v: Any) -> str:
    a = np.atleast_1d(np.asarray(v))
    if a.dtype.kind == "f":
        return "(" + ", ".join(f"{x:.6g}" for x in a.tolist()) + ")"
    return "(" + ", ".join(str(x) for x in a.tolist()) + ")"


def _at(values: np.ndarray, xy: tuple[int, int]) -> Any:
    x, y = xy
    return values[values.shape[0] - 1 - y, x]


def _artifact(name: str) -> Path:
    from pipegen.core.outdir import safe_name
    test = settings.current_test.replace("/", "_").replace("::", "-") or "pipegen"
    return settings.artifacts() / safe_name(f"{test}-{name}", ".png")


def _save(path: Path, rgb_top_down: np.ndarray) -> str:
    from PIL import Image
    Image.fromarray(np.ascontiguousarray(rgb_top_down)).save(path)
    return str(path)


def _too_many_discontinuities(kind: str, technique: str, target: str, sides: str, count: int,
                              allowed: int, lines: list[str], command: str
                              ) -> records.Comparison:
    """The recorded failure of more discontinuities than ``max_discontinuities`` allows."""
    return records.record(records.Comparison(
        kind, technique, target, False, f"{count} discontinuities (allowed {allowed})",
        {"discontinuities": str(count)}, command=command,
        message=f"{count} px where {sides} took different sides of a step in the technique's "
                f"code (allowed: max_discontinuities={allowed}):\n" + "\n".join(lines)))


def _fail(what: str, failed: list[records.Comparison], every: list[records.Comparison]):
    raise ComparisonFailure(f"{what}\n" + "\n".join(c.message for c in failed), every)


# -- GL against CL -----------------------------------------------------------------------------

def assert_backends_agree(technique: TechniqueLike, scene: SceneLike = None,
                          size: Optional[tuple[int, int]] = None,
                          params: Optional[dict] = None, max_discontinuities: int = 0,
                          only: Optional[set] = None, general: Optional[bool] = None):
    """GL and CL render every target (``only``: these) within the tolerance model's limits;
    at most ``max_discontinuities`` pixels where they took different sides of a step of the
    technique's code (the variant compiled for the scene, or with ``general`` the general
    build).  Returns the ``proof.check.CheckResult``."""
    from pipegen.proof.check import check, error_image
    s = load_test_scene(scene, size)
    compiled = for_scene(load_technique(technique, params), s, general)
    result = check(compiled, s, max_discontinuities=max_discontinuities if only is None
                   else 1 << 62)          # counted below, over the targets asked for
    command = _command("check", compiled, scene, s)
    gl, cl = result.renders["gl"], result.renders["cl"]
    made, failed = [], []
    for row in result.rows:
        if only is not None and row.name.partition(".")[0] not in only:
            continue
        ok = row.passed
        unit = {"code": "codes", "ulp": "ulp", "exact": "exact"}[row.tolerance.units]
        limit = row.row()[4]
        numbers = {"max error": f"{row.row()[2]}", "limit": limit, "rmse": row.row()[3],
                   "over": str(row.over), "edges/bound": f"{row.edge_admitted}/{row.edge_bound}",
                   "discontinuities": str(row.discontinuity_count)}
        c = records.Comparison("backends", compiled.name, row.name, ok,
                               f"GL vs CL: max {row.row()[2]}, limit {limit}, {row.over} px "
                               f"over, {row.discontinuity_count} discontinuities",
                               numbers, command=command)
        err = error_image(row)[::-1]
        if not ok:
            xy = row.worst_pixel()
            path = _save(_artifact(f"backends-{row.name}"), err)
            c.artifacts["difference"] = path
            c.message = (f"target '{row.name}' ({row.format.name}): {row.over} px where GL and "
                         f"CL differ by more than the limit ({limit} {unit}); worst at "
                         f"(x={xy[0]}, y={xy[1]}): GL {_channels(_at(gl[row.name], xy))} vs CL "
                         f"{_channels(_at(cl[row.name], xy))} codes; error image: {path}")
            failed.append(c)
        if settings.keep_images:
            c.images["difference"] = err
        made.append(records.record(c))
    if failed:
        _fail(f"{compiled.name}: GL and CL disagree ({command})", failed, made)
    counted = [r for r in result.rows if only is None or r.name.partition(".")[0] in only]
    total = sum(r.discontinuity_count for r in counted)
    if total > max_discontinuities:
        lines = [f"  {r.name}: {d.describe()}" for r in counted for d in r.discontinuities]
        c = _too_many_discontinuities("backends", compiled.name, "discontinuities", "GL and CL",
                                      total, max_discontinuities, lines, command)
        _fail(f"{compiled.name}: discontinuities ({command})", [c], made + [c])
    return result



# -- against the float64 evaluation ---------------------------------------------------------

def assert_close_to_f64(technique: TechniqueLike, scene: SceneLike = None,
                        size: Optional[tuple[int, int]] = None, params: Optional[dict] = None,
                        backends: tuple[str, ...] = ("gl", "cl"), max_discontinuities: int = 0,
                        only: Optional[set] = None, general: Optional[bool] = None):
    """Every target (``only``: these) of each float32 backend within the tolerance model's
    bound of the technique's own float64 evaluation (what ``pipegen stress`` holds every case
    to); at most ``max_discontinuities`` pixels (per backend) on the other side of a step of
    the technique's code (the variant compiled for the scene, or with ``general`` the general
    build).  Returns the ``proof.precision.PrecisionResult``."""
    from pipegen.proof.precision import precision_check, ratio_image
    s = load_test_scene(scene, size)
    compiled = for_scene(load_technique(technique, params), s, general)
    result = precision_check(compiled, s, backends)
    command = _command("check", compiled, scene, s, ("--precision", "f64"))
    made, failed, disc = [], [], []
    for b, rows in result.rows.items():
        count = 0
        for row in rows:
            if only is not None and row.key.partition(".")[0] not in only:
                continue
            count += row.discontinuity_count
            err = row.units(row.worst_error)
            bound = "exact" if row.exact else row.units(row.bound_at_worst)
            numbers = {"backend": b, "max error": err, "bound there": bound,
                       "error / bound": f"{row.worst_ratio:.3g}", "over": str(row.over),
                       "edges/bound": f"{row.edges}/{row.edge_bound}",
                       "discontinuities": str(row.discontinuity_count)}
            c = records.Comparison("f64", compiled.name, f"{row.key} ({b})", row.passed,
                                   f"{b} vs f64: max {err} where the bound is {bound}, "
                                   f"{row.over} px over, {row.discontinuity_count} "
                                   f"discontinuities", numbers, command=command)
            picture = ratio_image(row)[::-1]
            if not row.passed:
                path = _save(_artifact(f"f64-{b}-{row.key}"), picture)
                c.artifacts["difference"] = path
                got, want = row.worst_values
                c.message = (f"target '{row.key}' ({row.format}) on {b}: {row.over} px over "
                             f"the bound of the float64 evaluation"
                             + (f", {row.nonfinite_mismatch} NaN/inf on one side only"
                                if row.nonfinite_mismatch else "")
                             + f"; worst at (x={row.worst_xy[0]}, y={row.worst_xy[1]}): "
                             f"{b} {_channels(got)} vs f64 {_channels(want)}, error {err}, "
                             f"bound {bound}; error image: {path}")
                failed.append(c)
            if settings.keep_images:
                c.images["difference"] = picture
            made.append(records.record(c))
            for d in row.discontinuities:
                disc.append(f"  {row.key} ({b}): {d.describe()}")
        if count > max_discontinuities and not failed:
            c = _too_many_discontinuities("f64", compiled.name, f"discontinuities ({b})",
                                          f"{b} and the float64 evaluation", count,
                                          max_discontinuities, disc, command)
            made.append(c)
            failed.append(c)
    if failed:
        from pipegen.proof.precision import within_note
        note = within_note(compiled, result)
        _fail(f"{compiled.name}: not within the bound of its float64 evaluation ({command})"
              + (f"; {note}" if note else ""), failed, made)
    return result


# -- against a reference (docs/accuracy.md, References) ----------------------------------------

def assert_close_to_reference(technique: TechniqueLike, scene: SceneLike = None,
                              reference: str = "self", samples: int = 1, *,
                              p99: Optional[float] = None, max: Optional[float] = None,
                              rmse: Optional[float] = None,
                              size: Optional[tuple[int, int]] = None,
                              params: Optional[dict] = None, backend: str = "cl",
                              general: Optional[bool] = None) -> dict:
    """The output of ``technique`` on ``backend`` within limits of a reference, in rgba8
    codes: ``reference`` "self" (the technique at its most accurate parameter values, in
    float64), "scene" (the float64 scene evaluation), "FILE.pipe[:name=value,...]" or None
    (``references.default_reference``), evaluated at ``samples`` x ``samples`` per pixel.
    ``p99``, ``max``, ``rmse``: the limits checked (those given; at least one); ``general``
    as ``render``'s.  Returns ``accuracy.codes_vs_reference``'s figures (rmse, p99, max,
    interior, worst pixels)."""
    from pipegen.proof.accuracy import codes_vs_reference, error_map_rgb, output_codes
    from pipegen.proof.references import choose_reference
    limits = {k: v for k, v in (("p99", p99), ("max", max), ("rmse", rmse)) if v is not None}
    if not limits:
        raise ValueError("give a limit: p99=, max= or rmse= (rgba8 codes)")
    s = load_test_scene(scene, size)
    base = load_technique(technique, params)
    compiled = for_scene(base, s, general)
    ref = choose_reference(reference, base, samples)     # the technique's, not the variant's
    targets = render(compiled, s, backend)
    codes = output_codes(compiled, {k: t.values for k, t in targets.items()})
    e = codes_vs_reference(codes, ref, s)
    over = {k: v for k, v in limits.items() if e[k] > v}
    command = _command("check", compiled, scene, s, (
        "--precision", "f64", "--reference", reference or ref.spec.kind,
        *(("--reference-samples", str(samples)) if samples != 1 else ())))
    numbers = {"reference": ref.label, "backend": backend,
               **{k: f"{e[k]:.3g} codes (limit {limits[k]:g})" if k in limits
                  else f"{e[k]:.3g} codes" for k in ("rmse", "p99", "max")}}
    output = compiled.technique.output
    c = records.Comparison("reference", compiled.name, f"{output} ({backend})", not over,
                           f"{backend} vs {ref.label}: rmse {e['rmse']:.3g}, p99 "
                           f"{e['p99']:.3g}, max {e['max']:.3g} codes", numbers,
                           command=command)
    picture = error_map_rgb(codes, ref.output_rgb(s))
    if settings.keep_images:
        c.images["difference"] = picture
    if over:
        path = _save(_artifact(f"reference-{backend}-{output}"), picture)
        c.artifacts["difference"] = path
        worst = "".join(f"; worst at (x={x}, y={y}): {backend} {got} vs reference {want}"
                        for x, y, got, want in e["worst"][:1])
        c.message = (f"target '{output}' on {backend} against {ref.describe()}: "
                     + ", ".join(f"{k} {e[k]:.3g} over the limit {v:g}"
                                 for k, v in over.items())
                     + f" (rgba8 codes){worst}; error map: {path}")
    records.record(c)
    if over:
        _fail(f"{compiled.name}: not within the limits of the reference {ref.label} "
              f"({command})", [c], [c])
    return e


# -- goldens -----------------------------------------------------------------------------------

UPDATE_HINT = ("pytest --pipegen-update-goldens (or PIPEGEN_UPDATE_GOLDENS=1) writes it; "
               "look at it before you commit it")


def golden_path(golden_dir: Path, key: str, values: np.ndarray) -> Path:
    """Where target ``key`` is stored: a PNG where PNG holds the values losslessly (8-bit
    codes with 1, 2, 3 or 4 channels, 16-bit codes with one), else a ``.npy``."""
    from pipegen.core.outdir import safe_name
    a = np.asarray(values)
    png = (a.dtype == np.uint8 and (a.ndim == 2 or a.shape[2] in (1, 2, 3, 4))) or \
        (a.dtype == np.uint16 and a.ndim == 2)
    return Path(golden_dir) / safe_name(key, ".png" if png else ".npy")


def write_golden(path: Path, values: np.ndarray) -> None:
    """Stored top row first (a PNG shows the picture upright); written atomically."""
    tmp = path.with_name(f".{path.name}.tmp")
    a = np.ascontiguousarray(np.asarray(values)[::-1])
    if path.suffix == ".png":
        from PIL import Image
        if a.ndim == 3 and a.shape[2] == 1:
            a = a[..., 0]
        Image.fromarray(a).save(tmp, format="PNG")
    else:
        with open(tmp, "wb") as f:
            np.save(f, a)
    os.replace(tmp, path)


def read_golden(path: Path, like: np.ndarray) -> np.ndarray:
    if path.suffix == ".png":
        from PIL import Image
        a = np.asarray(Image.open(path))
        if np.ndim(like) == 3 and a.ndim == 2:
            a = a[..., None]
        a = a.astype(np.asarray(like).dtype, copy=False)
    else:
        a = np.load(path)
    return np.ascontiguousarray(a[::-1])


def assert_matches_golden(targets: Targets, golden_dir: Union[str, os.PathLike], *,
                          only: Optional[set] = None, flip_mean: Optional[float] = None,
                          flip_percentile: Optional[tuple[float, float]] = None,
                          update: Optional[bool] = None) -> list[records.Comparison]:
    """Every target of ``targets`` (``only``: these) against its golden in ``golden_dir``,
    within the limits two float32 renders may differ by (the tolerance model's, as ``check``).
    With ``flip_mean`` (and/or ``flip_percentile=(p, threshold)``), colour targets are held to
    a ꟻLIP threshold instead: the mean ꟻLIP error (the p-th percentile of the ꟻLIP map) at
    most that.  ``update`` (default: ``settings.update_goldens``, set by
    ``pytest --pipegen-update-goldens``) writes the goldens instead of comparing; a missing
    golden otherwise fails, naming the command that writes it."""
    from pipegen.proof.check import compare_targets, error_image
    update = settings.update_goldens if update is None else update
    golden_dir = Path(golden_dir)
    compiled = targets.compiled
    test = settings.current_test
    command = f"pytest {shlex.quote(test)}" if test else targets.command
    keys = [k for k in sorted(targets) if only is None or k.partition(".")[0] in only]
    made, failed = [], []
    if update:
        golden_dir.mkdir(parents=True, exist_ok=True)
        for k in keys:
            path = golden_path(golden_dir, k, targets[k].values)
            write_golden(path, targets[k].values)
            made.append(records.record(records.Comparison(
                "golden", compiled.name, k, True, f"golden written: {path}",
                {"golden": str(path)}, command=command)))
        return made
    missing = [k for k in keys if not golden_path(golden_dir, k, targets[k].values).exists()]
    if missing:
        c = records.record(records.Comparison(
            "golden", compiled.name, ", ".join(missing), False, "no golden", {},
            command=command,
            message=f"no golden for {', '.join(repr(k) for k in missing)} in {golden_dir}: "
                    f"{UPDATE_HINT}"))
        _fail(f"{compiled.name}: missing goldens", [c], [c])
    golden = {}
    for k in keys:
        path = golden_path(golden_dir, k, targets[k].values)
        golden[k] = read_golden(path, targets[k].values)
        if golden[k].shape != targets[k].values.shape:
            c = records.record(records.Comparison(
                "golden", compiled.name, k, False, "size differs", {}, command=command,
                message=f"target '{k}': the render is {_shape(targets[k].values)} but the "
                        f"golden {path} is {_shape(golden[k])}; {UPDATE_HINT}"))
            _fail(f"{compiled.name}: golden of another size", [c], [c])
    got = {k: targets[k].values for k in keys}
    rows = compare_targets(compiled, got, golden, len(targets.scene.lights),
                           counts=targets.blend_counts)
    for row in rows:
        k = row.name
        fmt = formats.get(targets[k].format)
        flip = _flip(got[k], golden[k], fmt) if (flip_mean is not None or flip_percentile) \
            else None
        limit = row.row()[4]
        unit = {"code": "codes", "ulp": "ulp", "exact": "exact"}[row.tolerance.units]
        numbers = {"max error": row.row()[2], "limit": limit, "rmse": row.row()[3],
                   "over": str(row.over), "edges/bound": f"{row.edge_admitted}/{row.edge_bound}"}
        ok = row.passed
        if flip is not None:
            fmap, mean = flip
            numbers["ꟻLIP mean"] = f"{mean:.4f}"
            ok = flip_mean is None or mean <= flip_mean
            if flip_percentile:
                p, thr = flip_percentile
                value = float(np.percentile(fmap, p))
                numbers[f"ꟻLIP p{p:g}"] = f"{value:.4f}"
                ok = ok and value <= thr
        c = records.Comparison("golden", compiled.name, k, ok,
                               f"vs golden: max {row.row()[2]}, limit {limit}, {row.over} px "
                               f"over" + (f", ꟻLIP mean {flip[1]:.4f}" if flip else ""),
                               numbers, command=command)
        diff = error_image(row)[::-1]
        if not ok:
            xy = row.worst_pixel()
            c.artifacts["difference"] = _save(_artifact(f"golden-{k}"), diff)
            c.artifacts["actual"] = _save(_artifact(f"actual-{k}"), targets[k].picture())
            flips = ", ".join(f"{a} {b}" for a, b in numbers.items() if "LIP" in a)
            why = (f"{row.over} px differ from the golden by more than the limit "
                   f"({limit} {unit})") if flip is None else \
                f"ꟻLIP over its threshold ({flips})"
            c.message = (f"target '{k}' ({fmt.name}): {why}; worst at (x={xy[0]}, y={xy[1]}): "
                         f"render {_channels(_at(got[k], xy))} vs golden "
                         f"{_channels(_at(golden[k], xy))}, limit {limit} {unit}; error image: "
                         f"{c.artifacts['difference']}; if the change is intended: "
                         f"{UPDATE_HINT}")
            failed.append(c)
        if settings.keep_images:
            c.images["expected"] = TargetImage(k, fmt.name, golden[k]).picture()
            c.images["actual"] = targets[k].picture()
            c.images["difference"] = diff
            if flip is not None:
                c.images["flip"] = _magma(flip[0])
        made.append(records.record(c))
    if failed:
        _fail(f"{compiled.name} on {targets.backend} does not match its goldens in "
              f"{golden_dir}", failed, made)
    return made


def _shape(a: np.ndarray) -> str:
    a = np.asarray(a)
    return f"{a.shape[1]}x{a.shape[0]}" + (f"x{a.shape[2]}" if a.ndim == 3 else "") + \
        f" {a.dtype}"


def _flip(a: np.ndarray, b: np.ndarray, fmt: formats.Format):
    """(ꟻLIP map, mean) of two renders of a colour target (LDR, their first three channels
    as display values), or None for a target that is not colour."""
    if not fmt.is_normalized or np.ndim(a) != 3 or a.shape[2] < 3:
        return None
    import flip_evaluator
    ref = np.ascontiguousarray(fmt.dequantize(b)[::-1, :, :3].astype(np.float32))
    test = np.ascontiguousarray(fmt.dequantize(a)[::-1, :, :3].astype(np.float32))
    fmap, mean, _ = flip_evaluator.evaluate(ref, test, "LDR", applyMagma=False)
    return np.asarray(fmap, np.float64).reshape(ref.shape[:2]), float(mean)


def _magma(fmap: np.ndarray) -> np.ndarray:
    from matplotlib import colormaps
    rgb = colormaps["magma"](np.clip(fmap, 0.0, 1.0))[..., :3]
    return (rgb * 255 + 0.5).astype(np.uint8)
