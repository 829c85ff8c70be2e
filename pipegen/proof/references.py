"""References: what a technique's output error is measured against (issue 25; docs/accuracy.md,
"References").

- ``scene``: pipegen's float64 evaluation of the scene (``accuracy.scene_reference``: the
  shipped Blinn-Phong lighting, exact shadows, translucent layers).  The truth for techniques
  that shade with the shipped lighting library; for any other shading it measures how unlike
  Blinn-Phong the technique is.
- ``self``: the technique itself evaluated in float64 (``Compiled.pipeline("cl",
  precision="f64")``) with every parameter that declares ``accurate VALUE`` set to that value
  (the others as given): the error of a cheaper setting against the best the technique can do.
- ``FILE.pipe[:name=value,...]``: any technique, evaluated in float64 the same way; its output
  target is what the output is compared with.

Each may be supersampled (``samples`` N): evaluated at N*W x N*H and box-filtered over N x N
blocks.  :func:`default_reference` picks ``scene`` for techniques whose code calls the shipped
lighting library and ``self`` otherwise, and says how it decided.

Images are float64 display values before clamping, top row first (``reference.metrics``);
``targets`` keeps the renders' row order (row 0 at the bottom).
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Optional

from pipegen.core.diagnostics import PipegenError, Span
from pipegen.core.sources import library_dir
from pipegen.ir import nodes as ir
from pipegen.ir.walk import walk_exprs

if TYPE_CHECKING:    # numpy is imported where an image is made: the CLI's parser reads the
    import numpy as np   # help texts here, and `pipegen compile` never loads numpy

KINDS = ("scene", "self", "technique")
MAX_SAMPLES = 8                 # 8x8 float64 evaluations per pixel is already minutes
SYNTAX = "scene, self or FILE.pipe[:name=value,...]"
# the command-line options' help (check, sweep, stress, tune share them): what R may be
REFERENCE_HELP = ("scene (pipegen's float64 scene evaluation, the shipped Blinn-Phong "
                  "lighting), self (the technique in float64 at the values its parameters "
                  "declare `accurate`) or FILE.pipe[:name=value,...] (any technique, in "
                  "float64) (default: scene for techniques shaded by the shipped lighting "
                  "library, else self; docs/accuracy.md)")
SAMPLES_HELP = (f"evaluate the reference at N x N samples per pixel and average them (a box "
                f"filter), 1..{MAX_SAMPLES} (default: 1)")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
# the library files that spell the lighting equation the scene reference evaluates
LIGHTING_FILES = ("lighting.pipe", "light_buffer.pipe")


@dataclass(frozen=True)
class ReferenceSpec:
    """A reference as the user named it (``parse_reference``) or as ``default_reference``
    chose it; ``why`` says how a default was decided ("" when named)."""

    kind: str                                   # "scene" | "self" | "technique"
    path: Optional[str] = None                  # the .pipe of a "technique" reference
    params: dict = field(default_factory=dict)  # its parameters, as written (strings)
    samples: int = 1                            # N: N x N samples per pixel, box-filtered
    why: str = ""

    @property
    def label(self) -> str:
        """Short, for table columns and csv: ``scene``, ``self``, ``ref.pipe:k=v``, with
        ``@2x2`` when supersampled."""
        if self.kind == "technique":
            text = os.path.basename(self.path or "")
            if self.params:
                text += ":" + ",".join(f"{k}={v}" for k, v in self.params.items())
        else:
            text = self.kind
        return text + (f"@{self.samples}x{self.samples}" if self.samples > 1 else "")


def _arg_error(text: str, column: int, width: int, message: str, hint: str) -> PipegenError:
    """An error in ``--reference TEXT``, with a caret under the offending characters."""
    span = Span("--reference", 1, column, 1, column + max(1, width), text)
    return PipegenError(span, message, hint=hint)


def check_samples(samples) -> int:
    """``--reference-samples N``: an integer from 1 to MAX_SAMPLES."""
    try:
        n = int(samples)
        ok = n == samples or str(samples).strip() == str(n)
    except (TypeError, ValueError):
        ok = False
    if not ok or not 1 <= n <= MAX_SAMPLES:
        raise PipegenError(None, f"reference samples must be an integer from 1 to "
                                 f"{MAX_SAMPLES}, not {samples!r}",
                           hint="--reference-samples 2 evaluates the reference at 2x2 samples "
                                "per pixel and averages them")
    return n


def parse_reference(text: str, samples: int = 1) -> ReferenceSpec:
    """``scene``, ``self`` or ``FILE.pipe[:name=value,...]`` (a path relative to the current
    folder) as a ``ReferenceSpec``; a ``PipegenError`` with a caret on bad text."""
    n = check_samples(samples)
    raw = str(text)
    s = raw.strip()
    start = raw.find(s) + 1 if s else 1
    if s in ("scene", "self"):
        return ReferenceSpec(s, samples=n)
    if not s:
        raise _arg_error(raw, 1, 1, "the reference is empty", f"name one: {SYNTAX}")
    head, sep, tail = s.rpartition(".pipe:")
    path = head + ".pipe" if sep else s
    if not path.endswith(".pipe"):
        raise _arg_error(raw, start, len(s), f"not a reference: {s!r}",
                         f"a reference is {SYNTAX}, e.g. --reference self or "
                         f"--reference ref.pipe:bands=8")
    params: dict = {}
    if sep:
        column = start + len(path) + 1
        for item in tail.split(","):
            name, eq, value = (x.strip() for x in item.partition("="))
            if not eq or not _NAME.match(name) or not value:
                raise _arg_error(raw, column, len(item), f"not a parameter setting: {item!r}",
                                 "after FILE.pipe: write name=value pairs separated by commas, "
                                 "e.g. ref.pipe:bands=8,normal_format=rgba16f")
            if name in params:
                raise _arg_error(raw, column, len(item), f"parameter '{name}' is set twice",
                                 "give each parameter once")
            params[name] = value
            column += len(item) + 1
    if not Path(path).is_file():
        raise _arg_error(raw, start, len(path), f"no such technique file: {path}",
                         f"a reference is {SYNTAX}; a path is relative to the current folder "
                         f"({os.getcwd()})")
    return ReferenceSpec("technique", path, params, n)


# -- the default ---------------------------------------------------------------------------


def _in_library(file: Optional[str]) -> Optional[str]:
    """The library file name when ``file`` is one of the shipped lighting files: the
    library's own, or a copy of it (a source checkout's ``pipelines/common`` next to an
    installed package: same name, same text)."""
    lib = library_dir()
    if not file or lib is None or file.startswith("<"):
        return None
    p = Path(file)
    if p.name not in LIGHTING_FILES:
        return None
    shipped = lib / p.name
    try:
        same = p.resolve() == shipped.resolve() or p.read_bytes() == shipped.read_bytes()
    except OSError:
        return None
    return p.name if same else None


def lighting_calls(tech: ir.Technique) -> list[ir.Function]:
    """The functions of the shipped lighting library (``common/lighting.pipe``,
    ``common/light_buffer.pipe``) the technique's passes call, directly or through other
    functions; those a pass calls itself first.  Any of them counts, geometry helpers
    (``attenuation``, ``world_from_depth``) too: a technique built on the library is taken to
    approximate its equation (Calver's deferred shading tabulates it in textures and reaches
    the library only through ``world_from_depth``)."""
    functions = {f.name: f for f in tech.all_functions()}

    def calls(stmts) -> set[str]:
        return {e.name for e in walk_exprs(stmts) if isinstance(e, ir.Call) and not e.builtin}

    direct = {c for p in tech.passes for c in calls(p.body)}
    reached, todo = set(), list(direct)
    while todo:
        name = todo.pop()
        if name in reached or name not in functions:
            continue
        reached.add(name)
        todo += calls(functions[name].body)
    # those a pass calls itself first: the one .why names is the one a reader finds
    return [functions[n] for n in sorted(reached, key=lambda n: (n not in direct, n))
            if _in_library(functions[n].span.file if functions[n].span else None)]


def default_reference(compiled) -> ReferenceSpec:
    """``scene`` when the technique's output is shaded by the shipped lighting library (its
    passes reach a function of :func:`lighting_calls`), else ``self``; ``.why`` says which
    function decided it, or that none was found."""
    found = lighting_calls(compiled.technique)
    files = " or ".join("common/" + n for n in LIGHTING_FILES)
    if found:
        f = found[0]
        where = f"{f.span.file}:{f.span.line}" if f.span else "the library"
        return ReferenceSpec("scene", why=(
            f"{compiled.name} calls the shipped lighting library ({f.name}, {where}), whose "
            f"equation the scene reference evaluates in float64; a technique that shades "
            f"otherwise: --reference self"))
    return ReferenceSpec("self", why=(
        f"{compiled.name} calls no function of the shipped lighting library ({files}): "
        f"its own shading is measured against itself at its most accurate parameter values"))


def choose_reference(text: Optional[str], compiled, samples: int = 1,
                     recompile: Optional[Callable[[dict], object]] = None) -> "Reference":
    """``--reference TEXT --reference-samples N`` for ``compiled``: the reference named, or
    with ``text`` None the :func:`default_reference` (its ``why`` kept), N samples each way."""
    if text is None:
        spec = default_reference(compiled)
        spec = ReferenceSpec(spec.kind, spec.path, spec.params, check_samples(samples), spec.why)
    else:
        spec = parse_reference(text, samples)
    ref = Reference(spec, compiled, recompile)
    ref.technique()                  # compiled now: its errors before any rendering
    return ref


# -- the reference ---------------------------------------------------------------------------


def box_filter(image: np.ndarray, n: int) -> np.ndarray:
    """The mean of each n x n block of an (n*H, n*W, C) image: (H, W, C)."""
    import numpy as np
    if n == 1:
        return np.asarray(image, np.float64)
    a = np.asarray(image, np.float64)
    h, w = a.shape[0] // n, a.shape[1] // n
    return a.reshape(h, n, w, n, *a.shape[2:]).mean(axis=(1, 3))


def output_values_rgb(technique: ir.Technique, values: dict) -> np.ndarray:
    """The float64 evaluation's output target as display RGB (H, W, 3) float64, bottom row
    first, unquantised: the stored values' first three channels (missing ones 0), as
    ``accuracy.f64_output_codes`` reads them before quantising."""
    import numpy as np
    v = np.asarray(values[technique.output], np.float64)
    if v.ndim == 2:
        v = v[..., None]
    out = np.zeros(v.shape[:2] + (3,))
    out[..., :min(3, v.shape[2])] = v[..., :3]
    return out


class Reference:
    """A reference made concrete for the technique under test (``compiled``).  Evaluations
    are cached per scene object.  ``recompile(params) -> Compiled`` compiles the technique
    under test with other parameter values (for ``self``); by default its ``.pipe`` file is
    compiled again (``technique.source``)."""

    def __init__(self, spec: ReferenceSpec, compiled,
                 recompile: Optional[Callable[[dict], object]] = None):
        assert spec.kind in KINDS, spec.kind
        self.spec = spec
        self.compiled = compiled
        self._recompile = recompile
        self._evaluated = None
        self._cache: dict = {}

    @property
    def label(self) -> str:
        return self.spec.label

    @property
    def samples(self) -> int:
        return self.spec.samples

    def accurate_params(self) -> dict:
        """For ``self``: the parameters declaring ``accurate``, at that value."""
        return {p.name: p.accurate for p in self.compiled.technique.params
                if p.accurate is not None}

    def describe(self) -> str:
        s = self.spec
        if s.kind == "scene":
            text = ("scene: pipegen's float64 scene evaluation (Blinn-Phong, the shipped "
                    "lighting)")
        elif s.kind == "self":
            acc = self.accurate_params()
            text = (f"self: {self.compiled.name} at its most accurate values ("
                    + ", ".join(f"{k}={_show(v)}" for k, v in acc.items()) + "), float64"
                    if acc else f"self: {self.compiled.name} at its given values (no "
                                f"parameter declares `accurate`), float64")
        else:
            text = s.path + (" (" + ", ".join(f"{k}={v}" for k, v in s.params.items()) + ")"
                             if s.params else "") + ", float64"
        if s.samples > 1:
            text += f", {s.samples}x{s.samples} supersampled (box filter)"
        return text

    # -- the compiled reference technique (self / technique) --------------------------------

    def technique(self):
        """The ``Compiled`` evaluated in float64 (``self``/``technique``); None for ``scene``."""
        if self.spec.kind == "scene":
            return None
        if self._evaluated is None:
            self._evaluated = self._compile()
        return self._evaluated

    def _compile(self):
        try:
            return self._compile_it()
        except PipegenError as e:        # say whose error it is: the reference's
            raise PipegenError(e.span, f"the reference {self.label}: {e.message}",
                               e.hint) from None

    def _compile_it(self):
        from pipegen.compiler.driver import compile_file
        if self.spec.kind == "technique":
            return compile_file(self.spec.path, dict(self.spec.params) or None)
        acc = self.accurate_params()
        given = {p.name: p.default for p in self.compiled.technique.params}
        if all(given.get(k) == v for k, v in acc.items()):
            return self.compiled                 # already at its most accurate values
        params = {**self.compiled.params, **acc}
        if self._recompile is not None:
            return self._recompile(params)
        source = self.compiled.technique.source
        if not source or not Path(source).is_file():
            raise PipegenError(None, f"cannot recompile {self.compiled.name} at its most "
                                     f"accurate values: its source file {source!r} is not at hand",
                               hint="compile it from a .pipe file (compile_file), or give "
                                    "Reference a recompile function")
        return compile_file(source, params)

    def _f64(self, scene) -> dict:
        key = ("f64", id(scene), scene.width, scene.height)
        if key not in self._cache:
            pipe = self.technique().pipeline("cl", precision="f64")
            try:
                self._cache[key] = (scene, pipe.render(scene))
            finally:
                getattr(pipe, "release", lambda: None)()
        return self._cache[key][1]

    def _scene_ref(self, scene):
        key = ("scene", id(scene), scene.width, scene.height)
        if key not in self._cache:
            from pipegen.proof.accuracy import scene_reference
            self._cache[key] = (scene, scene_reference(scene))
        return self._cache[key][1]

    def _sampled(self, scene):
        """The scene the reference is evaluated on: N*W x N*H when supersampled."""
        n = self.spec.samples
        if n == 1:
            return scene
        key = ("fine", id(scene), scene.width, scene.height)
        if key not in self._cache:
            self._cache[key] = (scene, scene.with_size(scene.width * n, scene.height * n))
        return self._cache[key][1]

    # -- what the error is measured against ------------------------------------------------

    def output_rgb(self, scene) -> np.ndarray:
        """float64 (H, W, 3), top row first, display values before clamping, at the scene's
        size (supersampled: the box filter of each N x N block)."""
        fine = self._sampled(scene)
        if self.spec.kind == "scene":
            rgb = self._scene_ref(fine).rgb
        else:
            tech = self.technique().technique
            rgb = output_values_rgb(tech, self._f64(fine))[::-1]
            if rgb.shape[:2] != (fine.height, fine.width):
                raise PipegenError(None, f"the reference {self.label}: its output "
                                         f"'{tech.output}' is {rgb.shape[1]}x{rgb.shape[0]}, "
                                         f"not the scene's {fine.width}x{fine.height}",
                                   hint="a reference's output target is sized with the "
                                        "output (`size output`, the default)")
        return box_filter(rgb, self.spec.samples)

    def notes(self, scene) -> list[str]:
        """What the reference technique will not render of ``scene`` (``mismatches``):
        its figures there measure that too."""
        other = self.technique()
        if other is None:
            return []
        return [f"the reference {self.label} will not render all of the scene: {m.message}"
                for m in other.mismatches(scene)]

    def targets(self, scene) -> Optional[dict]:
        """float64 values of every target of the reference technique at the scene's size (row
        0 at the bottom, as renders; never supersampled); None for ``scene``."""
        if self.spec.kind == "scene":
            return None
        return self._f64(scene)

    def target_at(self, scene, name: str, shape) -> tuple[Optional[np.ndarray], str]:
        """float64 values of the reference technique's target ``name`` with ``shape``'s
        height and width, and a note: a target sized relative to the output is evaluated
        on the scene resized so that it comes out that size (the same texel centres as a
        render's target of that size, e.g. a G-buffer at ``lbuffer_scale 0.625`` against
        the reference's at 1.0); otherwise (None, why).  None for ``scene``."""
        tech = self.technique()
        if tech is None:
            return None, "the scene reference has no targets"
        target = next((t for t in tech.technique.targets if t.name == name), None)
        if target is None:
            return None, f"the reference {self.label} has no target '{name}'"
        h, w = int(shape[0]), int(shape[1])
        if target.size.resolve(scene.width, scene.height) == (w, h):
            return self._f64(scene)[name], ""
        if not target.size.relative:
            return None, (f"the reference's '{name}' is {target.size.width}x"
                          f"{target.size.height}, not {w}x{h}")
        s = target.size.scale
        out = (max(1, round(w / s)), max(1, round(h / s)))
        if target.size.resolve(*out) != (w, h):
            return None, f"no output size gives the reference's '{name}' {w}x{h}"
        key = ("resized", id(scene), scene.width, scene.height, out)
        if key not in self._cache:
            import dataclasses
            cams = [scene.camera, scene.prev_camera]
            keep = [dataclasses.replace(c, aspect=c.aspect or scene.aspect) for c in cams]
            resized = dataclasses.replace(scene.with_size(*out), camera=keep[0],
                                          previous_camera=keep[1])
            self._cache[key] = (scene, resized)
        note = (f"the reference evaluated at {out[0]}x{out[1]} with the output's aspect "
                f"ratio, where its '{name}' is {w}x{h} as here")
        return self._f64(self._cache[key][1])[name], note

    def silhouette(self, scene) -> Optional[np.ndarray]:
        """bool (H, W), top row first: the scene reference's edges (silhouettes, creases,
        translucent outlines), for interior figures; None for other references.  Supersampled:
        a pixel is an edge when any of its samples is."""
        if self.spec.kind != "scene":
            return None
        import numpy as np
        fine = self._scene_ref(self._sampled(scene)).silhouette
        return box_filter(fine[..., None].astype(np.float64), self.spec.samples)[..., 0] > 0

    def edges(self, scene) -> np.ndarray:
        """bool (H, W), top row first: the pixels left out of the interior figures.  The
        scene reference's :meth:`silhouette`; for a technique reference the scene geometry's
        (``reference.metrics.silhouette_mask``: the same objects, whatever shades them)."""
        found = self.silhouette(scene)
        if found is not None:
            return found
        key = ("edges", id(scene), scene.width, scene.height)
        if key not in self._cache:
            from pipegen.reference.metrics import silhouette_mask
            self._cache[key] = (scene, silhouette_mask(scene))
        return self._cache[key][1]


def _show(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    return f"{v:g}" if isinstance(v, float) else str(v)
