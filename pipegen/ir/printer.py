"""The IR as text that reads like the ``.pipe`` language (``print_technique``).

What ``pipegen compile --dump-after PASS`` shows between passes: the parameters, light table,
targets, packings with the functions they generated, the functions, and the passes with their
draw, state, reads, writes and bodies, all in ``.pipe`` spelling (docs/language.md).  What the
IR holds that the language has no words for is a comment: a scene specialisation's facts and
cuts, a packing's constants, a parameter's value already substituted.  Calls keep the IR's
names (``slots_unpack``, not ``slots.unpack``); floats are the shortest decimal that reads back
as the same float32, as the emitters write them.

Every node kind of ``nodes.py`` has its printer here; a node without one is a ``TypeError``
(``tests/test_pass_manager.py`` walks the node classes).  Deterministic: no addresses, spans
or ids.
"""

from __future__ import annotations

from typing import Callable

from pipegen.core.float32 import f32_str
from pipegen.ir import nodes as ir

INDENT = "  "
WIDTH = 100                     # declarations longer than this continue on the next line

# C precedence (the language's), higher binds tighter
_PREC = {"||": 3, "&&": 5, "|": 6, "^": 7, "&": 8, "==": 9, "!=": 9, "<": 10, "<=": 10,
         ">": 10, ">=": 10, "<<": 11, ">>": 11, "+": 12, "-": 12, "*": 13, "/": 13, "%": 13}
_TERNARY, _UNARY, _ATOM = 2, 14, 15
_CLARIFY = {"&", "|", "^", "<<", ">>"}


def print_technique(tech: ir.Technique) -> str:
    """The whole technique as ``.pipe``-like text, ending with a newline."""
    out = [f'technique {tech.name} "{_escape(tech.title)}"']
    if tech.source:
        out.append(f"// from {tech.source}")
    if tech.scene is not None:
        out.append(f"// specialised for: {tech.scene.describe()}")
    out += [f"// {c.describe()}" for c in tech.cuts]
    out.append("")
    out += [param(p) for p in tech.params]
    if tech.lights.fields:
        out += _wrapped(f"lights[{tech.lights.capacity}] {{ ",
                        [f"{f.name}: {f.type}" for f in tech.lights.fields], " }")
    if tech.materials is not None:
        out += _wrapped("material { ", [f"{f.name}: {f.type} = {_material_default(f)}"
                                        for f in tech.materials.fields], " }")
    out.append("")
    out += [target(t) for t in tech.targets]
    out.append(f"output {tech.output}")
    for k in tech.packings:
        out += ["", *packing(k)]
    for f in tech.functions:
        out += ["", *function(f)]
    out += _passes(tech.passes)
    return "\n".join(out) + "\n"


# ---- declarations ------------------------------------------------------------------------------


def param(p: ir.Param) -> str:
    allowed = f" in {{{', '.join(_value(v) for v in p.allowed)}}}" if p.allowed else ""
    accurate = f" accurate {_value(p.accurate)}" if p.accurate is not None else ""
    return f"param {p.name} : {p.type} = {_value(p.default)}{allowed}{accurate}"


def target(t: ir.Target) -> str:
    text = f"target {t.name} : {t.format.name}"
    s = t.size
    if not s.relative:
        text += f" size {s.width} x {s.height}"
    elif s.scale != 1.0:
        text += f" size output * {_value(s.scale)}"
    if t.samples != 1:
        text += f" samples {t.samples}"
    clear = _clear(t.clear)
    return text + (f" clear {clear}" if clear else "")


def _clear(c: ir.Clear) -> str:
    """What ``clear`` sets: ``(r, g, b, a)``, ``depth D``, ``stencil S`` ("" for nothing)."""
    parts = []
    if c.color is not None:
        parts.append("(" + ", ".join(_value(v) for v in c.color) + ")")
    if c.depth is not None:
        parts.append(f"depth {_value(c.depth)}")
    if c.stencil is not None:
        parts.append(f"stencil {c.stencil}")
    return " ".join(parts)


def packing(k: ir.Packing) -> list[str]:
    options = ", ".join(f"{name}: {_option(v)}" for name, v in k.options)
    out = [f"pack {k.name} = {k.scheme}({options})"]
    facts = []
    if k.constants:
        facts.append("constants " + ", ".join(f"{name} = {expr(c)}" for name, c in k.constants))
    if k.capacity is not None:
        facts.append(f"capacity {k.capacity} lights per pixel")
    if k.error is not None:
        facts.append(f"error {_value(k.error)}")
    if facts:
        out.append("// " + "; ".join(facts))
    for f in k.functions:
        out += ["", *function(f)]
    return out


def function(f: ir.Function) -> list[str]:
    params = [f"{t} {name}" for name, t in f.params]
    return [*_wrapped(f"{f.ret} {f.name}(", params, ") {"), *block(f.body, 1), "}"]


def _material_default(f: ir.MaterialAttr) -> str:
    """A material field's default as the declaration writes it (``0``, ``0.5``, ``vec3(0, 1, 0)``)."""
    integer = f.type.scalar is not ir.Scalar.FLOAT
    values = [str(int(v)) if integer else repr(v) for v in f.default]
    return values[0] if len(values) == 1 else f"{f.type}({', '.join(values)})"


def _wrapped(head: str, items: list[str], tail: str) -> list[str]:
    """``head`` + the comma-separated ``items`` + ``tail``, continued on lines aligned under
    the first item where one line would pass ``WIDTH``."""
    lines, line = [], head
    for k, item in enumerate(items):
        piece = item + ("," if k + 1 < len(items) else tail)
        if line.strip() and len(line) + len(piece) + 1 > WIDTH and line != head:
            lines.append(line.rstrip())
            line = " " * len(head)
        line += piece + " "
    return lines + [line.rstrip() if items else head + tail]


# ---- passes ------------------------------------------------------------------------------------


def _passes(passes: tuple[ir.Pass, ...]) -> list[str]:
    """The passes, each repeat group inside its ``repeat per light`` block."""
    out: list[str] = []
    k = 0
    while k < len(passes):
        p = passes[k]
        if not p.repeat_per_light:
            out += ["", *pass_(p)]
            k += 1
            continue
        end = k
        while end < len(passes) and passes[end].repeat_group == p.repeat_group:
            end += 1
        group = passes[k:end]
        shared = len({q.repeat_types for q in group}) == 1
        types = "".join(" " + t for t in p.repeat_types) if shared else ""
        out += ["", f"repeat per light{types} {{  // group {p.repeat_group}"]
        for q in group:
            out += [INDENT + line for line in pass_(q, repeat_types=not shared)]
        out.append("}")
        k = end
    return out


def pass_(p: ir.Pass, repeat_types: bool = False) -> list[str]:
    """``p`` as a pass block; ``repeat_types``: say the light types it repeats for (a pass in
    a repeat group whose passes repeat for different types)."""
    lines = [f"draw {p.draw.describe()}"]
    if repeat_types and p.repeat_types:
        lines.append("// repeats for " + " ".join(p.repeat_types) + " lights")
    if p.reads:
        lines.append("reads " + ", ".join(p.reads))
    if p.writes:
        lines.append("writes " + ", ".join(p.writes))
    lines += _state(p)
    lines += [f"clear {name} {_clear(c)}" for name, c in p.clears]
    if p.body:
        lines += ["fragment {", *block(p.body, 1), "}"]
    return [f"pass {p.name} {{", *(INDENT + line for line in lines), "}"]


def _state(p: ir.Pass) -> list[str]:
    s = p.state
    out = []
    if p.depth_target:
        d = s.depth
        if d.enabled:
            text = f"depth {p.depth_target} {d.func.value} {'write' if d.write else 'nowrite'}"
            text += " clamp" if d.clamp else ""
            text += f" inside {d.inside.value}" if d.inside is not None else ""
        else:
            text = f"depth {p.depth_target} off" + (" clamp" if d.clamp else "")
        out.append(text)
    if s.stencil.enabled:
        if s.stencil.front == s.stencil.back:
            out.append(f"stencil {{ {_stencil(s.stencil.front)} }}")
        else:
            out.append(f"stencil front {{ {_stencil(s.stencil.front)} }}")
            out.append(f"stencil back {{ {_stencil(s.stencil.back)} }}")
    for name, b in s.blend:
        out += _blend(name, b)
    if s.blend_constant != (0.0, 0.0, 0.0, 0.0):
        out.append("blend constant (" + ", ".join(_value(v) for v in s.blend_constant) + ")")
    out.append(f"cull {s.cull.value}")
    if s.polygon_offset is not None:
        o = s.polygon_offset
        out.append(f"offset {_value(o.factor)} {_value(o.units)}")
    return out


def _stencil(f: ir.StencilFace) -> str:
    return (f"func {f.func.value} ref {f.ref} read {f.read_mask} write {f.write_mask} "
            f"fail {f.fail.value} zfail {f.zfail.value} pass {f.zpass.value}")


def blend_equation(e: ir.BlendEquation) -> str:
    """A blend equation as the language spells it: ``add(src_alpha, one_minus_src_alpha)``."""
    if e.op in (ir.BlendOp.MIN, ir.BlendOp.MAX):
        return e.op.value
    return f"{e.op.value}({e.src.value}, {e.dst.value})"


def _blend(name: str, b: ir.TargetBlend) -> list[str]:
    out = []
    if b.enabled:
        if b.rgb == b.alpha:
            out.append(f"blend {name} {blend_equation(b.rgb)}")
        else:
            out.append(f"blend {name} rgb {blend_equation(b.rgb)} alpha {blend_equation(b.alpha)}")
    if b.write_mask != (True, True, True, True):
        channels = "".join(c for c, on in zip("rgba", b.write_mask) if on)
        out.append(f"mask {name} {channels or 'none'}")
    return out


# ---- statements --------------------------------------------------------------------------------


def block(stmts, depth: int) -> list[str]:
    out: list[str] = []
    for s in stmts:
        out += statement(s, depth)
    return out


def statement(s: ir.Stmt, depth: int = 0) -> list[str]:
    printer = _STMTS.get(type(s))
    if printer is None:
        raise TypeError(f"the IR printer has no statement printer for {type(s).__name__}")
    return printer(s, depth)


def _line(depth: int, text: str) -> list[str]:
    return [INDENT * depth + text]


def _if(s: ir.If, depth: int) -> list[str]:
    out = _line(depth, f"if ({expr(s.cond)}) {{") + block(s.then, depth + 1)
    if s.other:
        out += _line(depth, "} else {") + block(s.other, depth + 1)
    return out + _line(depth, "}")


def _for(s: ir.For, depth: int) -> list[str]:
    head = (f"for ({s.type} {s.var} = {expr(s.start)}; {s.var} < {expr(s.bound)}; "
            f"{s.var}++) {{")
    return _line(depth, head) + block(s.body, depth + 1) + _line(depth, "}")


def _declare(s: ir.Declare, depth: int) -> list[str]:
    init = f" = {expr(s.init)}" if s.init is not None else ""
    return _line(depth, f"{s.type} {s.name}{init};")


def _return(s: ir.Return, depth: int) -> list[str]:
    return _line(depth, "return;" if s.value is None else f"return {expr(s.value)};")


_STMTS: dict[type, Callable[..., list[str]]] = {
    ir.Declare: _declare,
    ir.Assign: lambda s, d: _line(d, f"{expr(s.target)} {s.op} {expr(s.value)};"),
    ir.Output: lambda s, d: _line(d, f"{s.target} = {expr(s.value)};"),
    ir.If: _if,
    ir.For: _for,
    ir.Break: lambda s, d: _line(d, "break;"),
    ir.Continue: lambda s, d: _line(d, "continue;"),
    ir.Return: _return,
    ir.Discard: lambda s, d: _line(d, "discard;"),
    ir.ExprStmt: lambda s, d: _line(d, f"{expr(s.expr)};"),
}


# ---- expressions -------------------------------------------------------------------------------


def expr(e: ir.Expr) -> str:
    return _expr(e)[0]


def _expr(e: ir.Expr) -> tuple[str, int]:
    """``e`` as text and the precedence of its outermost operator."""
    printer = _EXPRS.get(type(e))
    if printer is None:
        raise TypeError(f"the IR printer has no expression printer for {type(e).__name__}")
    return printer(e)


def _operand(e: ir.Expr, above: int) -> str:
    """``e`` parenthesised unless its operator binds tighter than ``above``."""
    text, prec = _expr(e)
    return text if prec > above else f"({text})"


def _binary(e: ir.Binary) -> tuple[str, int]:
    prec = _PREC[e.op]
    # left-associative: a right operand of the same precedence keeps its parentheses, so the
    # IR's evaluation order shows (``a - (b - c)``)
    return (f"{_side(e.op, e.left, prec - 1)} {e.op} {_side(e.op, e.right, prec)}", prec)


def _side(op: str, e: ir.Expr, above: int) -> str:
    """An operand of ``op``, also parenthesised where C's precedence is easy to misread: bit
    operations mixed with other operators, ``&&`` inside ``||`` (as the emitters write it)."""
    if isinstance(e, ir.Binary) and e.op != op and (
            op in _CLARIFY or e.op in _CLARIFY or (op, e.op) == ("||", "&&")):
        return f"({expr(e)})"
    return _operand(e, above)


def _ternary(e: ir.Ternary) -> tuple[str, int]:
    return (f"{_operand(e.cond, _TERNARY)} ? {_operand(e.then, _TERNARY)} : "
            f"{_operand(e.other, _TERNARY - 1)}", _TERNARY)


def _args(args) -> str:
    return ", ".join(expr(a) for a in args)


def _light_field(e: ir.LightField) -> tuple[str, int]:
    if e.index is None:
        return f"light.{e.field}", _ATOM
    return f"lights[{expr(e.index)}].{e.field}", _ATOM


def _material_field(e: ir.MaterialField) -> tuple[str, int]:
    return f"materials[{expr(e.index)}].{e.field}", _ATOM


def _load(e: ir.Load) -> tuple[str, int]:
    where = "" if e.coord is None else f", {expr(e.coord)}"
    if e.sample is not None:
        return f"load_sample({e.target}{where}, {expr(e.sample)})", _ATOM
    return f"load({e.target}{where})", _ATOM


def const(e: ir.Const) -> tuple[str, int]:
    t, v = e.type, e.value
    if isinstance(v, tuple):
        return f"{t}({', '.join(_scalar(x, t.scalar) for x in _flat(v))})", _ATOM
    text = _scalar(v, t.scalar)
    return text, _UNARY if text.startswith("-") else _ATOM


def _flat(v) -> list:
    return [y for x in v for y in (_flat(x) if isinstance(x, tuple) else (x,))]


def _scalar(v, scalar) -> str:
    if scalar is ir.Scalar.BOOL or isinstance(v, bool):
        return "true" if v else "false"
    if scalar is ir.Scalar.UINT:
        return f"{v}u"
    if scalar is ir.Scalar.INT:
        return str(v)
    return f32_str(v)


_EXPRS: dict[type, Callable[..., tuple[str, int]]] = {
    ir.Const: const,
    ir.Var: lambda e: (e.name, _ATOM),
    ir.Unary: lambda e: (f"{e.op}{_operand(e.operand, _UNARY)}", _UNARY),
    ir.Binary: _binary,
    ir.Ternary: _ternary,
    ir.Call: lambda e: (f"{e.name}({_args(e.args)})", _ATOM),
    ir.Construct: lambda e: (f"{e.type}({_args(e.args)})", _ATOM),
    ir.Swizzle: lambda e: (f"{_operand(e.base, _UNARY)}.{e.components}", _ATOM),
    ir.Index: lambda e: (f"{_operand(e.base, _UNARY)}[{expr(e.index)}]", _ATOM),
    ir.LightField: _light_field,
    ir.MaterialField: _material_field,
    ir.Load: _load,
    ir.Sample: lambda e: (f"sample({e.target}, {expr(e.uv)})", _ATOM),
    ir.TargetSize: lambda e: (f"size({e.target})", _ATOM),
}


# ---- values ------------------------------------------------------------------------------------


def _value(v) -> str:
    """A declaration's number, flag or word as the language writes it (a float as Python
    reads it back: declarations hold doubles until a backend rounds them)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    return str(getattr(v, "name", v))


def _option(v) -> str:
    if isinstance(v, tuple):
        if all(isinstance(x, tuple) and len(x) == 2 and isinstance(x[0], str) for x in v):
            return "(" + ", ".join(f"{a}: {_option(b)}" for a, b in v) + ")"
        return "(" + ", ".join(_option(x) for x in v) + ")"
    return _value(v)


def _escape(text: str) -> str:
    return text.replace("\\", "\\\\").replace('"', '\\"')
