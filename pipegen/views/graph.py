"""``pipegen graph``: a technique's passes and targets as a graph (Graphviz DOT).

Passes are boxes in execution order (a ``repeat per light`` group in a dashed frame), targets
are cylinders labelled with their format and size; edges are writes (pass → target, "blend"
when the pass blends into it, "clear" for a target the pass only clears), reads
(target → pass, blue) and depth/stencil attachments (green: "depth test", "depth write",
"stencil" ...; both ways when the pass tests and writes).  A technique compiled for a scene
(``compile_file(..., scene=)``) is drawn as the general technique with what specialisation
culled greyed out, each culled pass or target labelled with its reason (also its tooltip in
an SVG); the title says what the variant assumes and what else was cut (branches, the light
table) and the target memory before and after.

``build_dot(compiled, size)`` returns the DOT text; ``write_graph(text, path)`` writes it as
``.dot``/``.gv``, or renders ``.svg``/``.png``/``.pdf`` with Graphviz's ``dot`` when it is
installed, and otherwise writes the DOT text beside (``G.dot``) and says so.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import textwrap
from pathlib import Path
from typing import Optional

from pipegen.core.diagnostics import PipegenError
from pipegen.core.units import format_bytes
from pipegen.ir import nodes as ir
from pipegen.ir.access import depth_use
from pipegen.ir.memory import specialisation_bytes, technique_bytes

TEXT_SUFFIXES = (".dot", ".gv")
RENDERED_SUFFIXES = (".svg", ".png", ".pdf")
SUFFIXES = TEXT_SUFFIXES + RENDERED_SUFFIXES

# colours: live, culled, reads, depth/stencil
INK, GREY, FAINT, READ, DEPTH = "#222222", "#9a9a9a", "#efefef", "#2060b0", "#2e7d32"
PASS_FILL, TARGET_FILL, OUTPUT_FILL = "#fff4d6", "#e3eefc", "#d4f0d4"


# ---- DOT ---------------------------------------------------------------------------------------


def _q(text: str, newline: str = "\\n") -> str:
    """A DOT string literal; a newline in ``text`` becomes ``newline`` (centred line break;
    ``\\l``: left-justified)."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", newline) + '"'


def _attrs(**kw) -> str:
    return "[" + ", ".join(f"{k}={_q(str(v))}" for k, v in kw.items() if v is not None) + "]"


def _wrap(text: str, width: int = 38) -> str:
    return "\n".join(textwrap.wrap(text, width, break_on_hyphens=False)) or text


def _pid(name: str) -> str:
    return _q("pass:" + name)


def _tid(name: str) -> str:
    return _q("target:" + name)


def build_dot(compiled, size: tuple[int, int] = (1280, 720), title: Optional[str] = None) -> str:
    """The DOT text of ``compiled``'s passes and targets at output size ``size``; with a
    specialisation, the general technique with the culled passes and targets greyed and
    labelled with their reasons."""
    spec = getattr(compiled, "specialisation", None)
    tech: ir.Technique = spec.general if spec is not None else compiled.technique
    cuts = spec.cuts if spec is not None else ()
    culled_pass = {c.name: c.reason for c in cuts if c.kind == "pass"}
    culled_target = {c.name: c.reason for c in cuts if c.kind == "target"}
    w, h = size

    heading = title or _title(compiled, tech, spec, size)
    heading = "\n".join(_wrap(line, 110) for line in heading.split("\n"))
    lines = [f"digraph {_q(tech.name)} {{",
             "  graph " + _attrs(rankdir="LR", fontname="Helvetica", fontsize="12",
                                 labelloc="t", labeljust="l", nodesep="0.25", ranksep="0.45")
             + ";",
             f"  label={_q(heading + chr(10), newline=chr(92) + 'l')};",
             "  node " + _attrs(fontname="Helvetica", fontsize="10") + ";",
             "  edge " + _attrs(fontname="Helvetica", fontsize="9", arrowsize="0.7") + ";"]

    # targets
    for t in tech.targets:
        tw, th = t.size.resolve(w, h)
        shape = f"{t.format.name}  {tw}x{th}" + (f"  x{t.samples}" if t.samples > 1 else "")
        label = f"{t.name}\n{shape}"
        is_output = t.name == tech.output
        if is_output:
            label += "\n(output)"
        if t.name in culled_target:
            reason = culled_target[t.name]
            lines.append(f"  {_tid(t.name)} " + _attrs(
                shape="cylinder", style="filled,dashed", fillcolor=FAINT, color=GREY,
                fontcolor=GREY, label=f"{label}\nculled: {_wrap(reason)}", tooltip=reason) + ";")
        else:
            lines.append(f"  {_tid(t.name)} " + _attrs(
                shape="cylinder", style="filled", color=INK,
                fillcolor=OUTPUT_FILL if is_output else TARGET_FILL,
                peripheries="2" if is_output else None, label=label,
                tooltip=f"{t.name}: {t.format.name}, {tw}x{th}") + ";")

    # passes, repeat groups framed
    groups: dict[int, list[str]] = {}
    order = []
    for k, p in enumerate(tech.passes, 1):
        label = f"{k}. {p.name}\ndraw {p.draw.describe()}"
        if p.name in culled_pass:
            reason = culled_pass[p.name]
            node = f"  {_pid(p.name)} " + _attrs(
                shape="box", style="filled,dashed,rounded", fillcolor=FAINT, color=GREY,
                fontcolor=GREY, label=f"{label}\nculled: {_wrap(reason)}", tooltip=reason) + ";"
        else:
            node = f"  {_pid(p.name)} " + _attrs(
                shape="box", style="filled,rounded", fillcolor=PASS_FILL, color=INK,
                label=label, tooltip=f"pass {p.name}: draw {p.draw.describe()}") + ";"
        if p.repeat_group is not None:
            groups.setdefault(p.repeat_group, []).append(node)
            if len(groups[p.repeat_group]) == 1:
                order.append(("group", p.repeat_group, p))
        else:
            order.append(("pass", node, p))
    for kind, item, p in order:
        if kind == "pass":
            lines.append(item)
            continue
        types = f" ({', '.join(p.repeat_types)} lights)" if p.repeat_types else ""
        lines.append(f"  subgraph {_q(f'cluster_repeat_{item}')} {{")
        lines.append("    graph " + _attrs(label=f"repeat per light{types}", style="dashed,rounded",
                                           color=GREY, fontcolor="#555555") + ";")
        lines += ["  " + n for n in groups[item]]
        lines.append("  }")

    # edges
    for p in tech.passes:
        dead = p.name in culled_pass
        pid = _pid(p.name)

        def edge(src: str, dst: str, colour: str, **kw) -> None:
            touched = kw.pop("targets", ())
            dim = dead or any(x in culled_target for x in touched)
            style = kw.pop("style", None)
            if dim:
                colour, style = GREY, "dashed"
                kw["fontcolor"] = GREY
            lines.append(f"  {src} -> {dst} " + _attrs(color=colour, style=style, **kw) + ";")

        cleared = {name for name, _ in p.clears}
        for t in p.writes:
            blend = p.state.blend_for(t).enabled
            edge(pid, _tid(t), INK, label="blend" if blend else None, targets=(t,))
        for t in sorted(cleared - set(p.writes) - {p.depth_target}):
            edge(pid, _tid(t), INK, label="clear", style="dotted", targets=(t,))
        for t in p.reads:
            edge(_tid(t), pid, READ, targets=(t,))
        if p.depth_target:
            tests, writes = depth_use(tech, p)
            d = p.depth_target
            if p.depth_target in cleared and not writes:
                writes = ["clear"]
            label = ", ".join(([f"{'+'.join(tests)} test"] if tests else [])
                              + ([f"{'+'.join(writes)} write"] if writes else []))
            if tests and writes:
                edge(pid, _tid(d), DEPTH, dir="both", label=label, targets=(d,))
            elif writes:
                edge(pid, _tid(d), DEPTH, label=label, targets=(d,))
            elif tests:
                edge(_tid(d), pid, DEPTH, label=label, style="dashed", targets=(d,))
    lines.append("}")
    return "\n".join(lines) + "\n"


def _title(compiled, tech: ir.Technique, spec, size) -> str:
    w, h = size
    head = f"{tech.name}: {tech.title}" if tech.title else tech.name
    legend = ("edges: black writes (blend: blended), blue reads, green depth/stencil"
              + ("; grey, dashed: culled, with the reason" if spec is not None else ""))
    if spec is None:
        return (f"{head}\ntargets at {w}x{h}: {format_bytes(technique_bytes(tech, w, h))}\n"
                f"{legend}")
    special = compiled.technique
    passes = sum(c.kind == "pass" for c in spec.cuts)
    targets = sum(c.kind == "target" for c in spec.cuts)
    branches = sum(c.kind == "branch" for c in spec.cuts)
    other = [c.describe() for c in spec.cuts if c.kind == "table"]
    before, after = specialisation_bytes(tech, special, w, h)
    out = [head, f"specialised for: {spec.facts.describe()}",
           f"culled (grey): {passes} of {len(tech.passes)} passes, {targets} of "
           f"{len(tech.targets)} targets; {branches} light-type branch"
           f"{'' if branches == 1 else 'es'} removed",
           *other,
           f"target memory at {w}x{h}: {format_bytes(before, 'MiB')} -> "
           f"{format_bytes(after, 'MiB')}", legend]
    return "\n".join(out)


# ---- writing -----------------------------------------------------------------------------------


def find_dot() -> Optional[str]:
    """Graphviz's ``dot`` executable, or None when it is not installed."""
    return shutil.which("dot")


def write_graph(dot_text: str, path) -> tuple[Path, bool]:
    """Write ``dot_text`` to ``path``: DOT text for ``.dot``/``.gv``; for ``.svg``/``.png``/
    ``.pdf`` rendered with ``dot`` when installed.  Returns (the file written, rendered);
    without ``dot`` the DOT text goes to ``path`` with the suffix ``.dot`` instead."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise PipegenError(None, f"cannot write a graph as '{path.suffix or path.name}'",
                           hint=f"name the output {', '.join('G' + s for s in SUFFIXES)}")
    if path.is_dir():
        raise PipegenError(None, f"output path '{path}' is a folder, not a file",
                           hint="pass a file name with -o, e.g. -o graph.svg")
    if not path.parent.is_dir():
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise PipegenError(None, f"cannot create folder '{path.parent}': "
                                     f"{e.strerror or e}") from None
    if suffix in TEXT_SUFFIXES:
        _atomic_write(path, dot_text.encode())
        return path, False
    dot = find_dot()
    if dot is None:
        text_path = path.with_suffix(".dot")
        _atomic_write(text_path, dot_text.encode())
        return text_path, False
    try:
        proc = subprocess.run([dot, f"-T{suffix[1:]}"], input=dot_text.encode(),
                              capture_output=True, timeout=120)
    except (OSError, subprocess.TimeoutExpired) as e:
        raise PipegenError(None, f"Graphviz's dot failed: {e}",
                           hint="write the DOT text instead: -o graph.dot") from None
    if proc.returncode != 0 or not proc.stdout:
        err = proc.stderr.decode(errors="replace").strip().splitlines()
        raise PipegenError(None, f"Graphviz's dot failed (exit {proc.returncode})"
                                 + (f": {err[-1]}" if err else ""),
                           hint="write the DOT text instead: -o graph.dot")
    _atomic_write(path, proc.stdout)
    return path, True


def _atomic_write(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
