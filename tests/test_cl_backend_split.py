"""The OpenCL backend's scalar and wide paths share their definitions (issue 23): the wide path's
builtins are the prelude's own macros (``templates/cl_builtins.cl.j2``) rendered for the W-lane
types, with the scalar definitions' operations; and ``dot``, ``length``, ``cross``, ``mix`` and
the matrix products follow ``pipegen/ir/expand.py`` in the prelude and in the wide fragment
function alike, also when the expansion changes (a path with an order of its own fails).
Text only: no device."""

from __future__ import annotations

import re

import pytest

from pipegen.ir import expand
from pipegen.backends import templating
from pipegen.backends.opencl import expansions, programs, wide as cl_wide
from pipegen.backends.opencl.emit import emit_fragment
from pipegen.compiler.driver import compile_source

W = cl_wide.W

# one builtin per local, on per-pixel operands (the wide path keeps them varying)
ORDERS = """
technique wide_orders "dot, length, cross, mix and matrix products, one per local"
target hdr : rgba32f clear (0, 0, 0, 0)
output hdr

pass base {
  draw scene.opaque
  writes hdr
  fragment {
    vec3 n = normalize(normal);
    vec3 c = cross(n, world_pos);
    float d = dot(n, c);
    float l = length(c);
    vec3 m = mix(n, c, frag_coord.x);
    vec3 r = mat3(view) * n;
    vec3 s = n * mat3(proj);
    hdr = vec4(m + r + s, d + l);
  }
}
"""


def _macros():
    return templating.environment().get_template("cl_builtins.cl.j2").module


def _prelude() -> str:
    return programs.prelude_source.__wrapped__(16, "f32", False)   # not the cached text


# ---- the wide helpers are the prelude's macros --------------------------------------------

# (macro, arguments for the scalar type, arguments for the wide type); the scalar and the wide
# forms differ only in what the macro's parameters spell (qualifiers, parameter names, layout)
SHARED = [
    ("fmax", ("float",), (f"float{W}",)),
    ("fmin", ("float",), (f"float{W}",)),
    ("max", ("float",), (f"float{W}",)),
    ("min", ("float",), (f"float{W}",)),
    ("clamp", ("float",), (f"float{W}",)),
    ("intrinsic", ("float", "fma", "__builtin_fmaf", ["a", "b", "c"]),
     (f"float{W}", "fma", "__builtin_fmaf", ["a", "b", "c"])),
    ("intrinsic", ("float", "sqrt", "__builtin_sqrtf", ["a"]),
     (f"float{W}", "sqrt", "__builtin_sqrtf", ["a"])),
    ("intrinsic", ("float", "floor", "__builtin_floorf", ["x"]),
     (f"float{W}", "floor", "__builtin_floorf", ["a"])),
    ("fabs", ("float",), (f"float{W}",)),
    ("copysign", ("float", True), (f"float{W}", False)),
    ("max", ("int", ""), (f"int{W}",)),
    ("min", ("uint", ""), (f"uint{W}",)),
    ("clamp", ("int", ""), (f"int{W}",)),
    ("sub_sat", ("uint", ""), (f"uint{W}",)),
    ("abs", ("int",), (f"int{W}",)),
    ("abs", ("float",), (f"float{W}",)),
    ("sign", ("float",), (f"float{W}",)),
    ("sign", ("int",), (f"int{W}",)),
    ("smoothstep", ("float", "float"), (f"float{W}", f"float{W}")),
    ("exp2", ("float", "int"), (f"float{W}", f"int{W}")),
    ("log2", ("float", "int"), (f"float{W}", f"int{W}")),
]


@pytest.mark.parametrize("macro, scalar, wide", SHARED, ids=[
    f"{m}-{s[0]}" + (f"-{s[1]}" if m == "intrinsic" else "") for m, s, _ in SHARED])
def test_one_template_definition(macro, scalar, wide):
    """Each inline builtin of the wide helpers is the macro the prelude renders for the scalar
    type, rendered for the wide type: the two texts come from one definition."""
    m = getattr(_macros(), macro)
    scalar_text, wide_text = str(m(*scalar)), str(m(*wide))
    assert scalar_text in _prelude()
    assert wide_text in cl_wide.wide_helpers()
    assert scalar_text != wide_text


def test_templates_leave_the_builtins_to_the_macros():
    """Neither the wide helpers' template nor the prelude's spells a builtin the macros
    define (the prelude's vector forms, lifted component by component, and its double forms,
    the library's, are its own)."""
    env = templating.environment()
    builtin = r"(?:pg_b_\w+|pg_abs|pg_sign|pg_smoothstep|pg_exp2|pg_log2)\("
    head = r"^(?:PG_INL|static inline)(?: __attribute__\(\(overloadable\)\))? "
    wide_src = env.loader.get_source(env, "cl_wide_helpers.cl.j2")[0]
    prelude_src = env.loader.get_source(env, "cl_prelude.cl.j2")[0]
    assert not re.findall(head + r"\S+ " + builtin, wide_src, re.M)
    assert not re.findall(head + r"(?:float|int|uint) " + builtin, prelude_src, re.M)
    for src in (wide_src, prelude_src):
        assert '{% import "cl_builtins.cl.j2" as b %}' in src


def _balanced_args(text: str, start: int) -> tuple[list[str], int]:
    """The comma-separated arguments of the call whose "(" is at ``start``, and the index
    after its ")"."""
    args, depth, k = [], 0, start + 1
    part = []
    while True:
        ch = text[k]
        if ch == "(":
            depth += 1
        elif ch == ")":
            if depth == 0:
                args.append("".join(part).strip())
                return args, k + 1
            depth -= 1
        elif ch == "," and depth == 0:
            args.append("".join(part).strip())
            part = []
            k += 1
            continue
        part.append(ch)
        k += 1


def _as_scalar_ops(text: str) -> str:
    """A definition in the scalar spelling: the wide types as their lane types, pg_sel as
    C's ?: (c ? 1 : 0 as c), a lane test for NaN as __builtin_isnan, a library function per
    lane as one call, a splat as its value, the pg_b_ names as the routed ones, no
    qualifiers, one space."""
    text = re.sub(rf"(?<![A-Za-z0-9])(float|int|uint){W}\b", r"\1", text)   # as_float8 too
    text = re.sub(r"PGW_LANES\d\((\w+), \w+, ", r"\1(", text)
    text = re.sub(r"\((\w+) != \1\)", r"__builtin_isnan(\1)", text)
    while (k := text.find("pg_sel(")) >= 0:
        (e, t, c), end = _balanced_args(text, k + len("pg_sel"))
        text = text[:k] + (f"({c})" if " | " in c else c) + f" ? {t} : {e}" + text[end:]
    text = re.sub(r"\((?:float|int|uint)\)\(([\w.]+)\)", r"\1", text)
    text = re.sub(r"(\w+ [<>] \w+) \? 1 : 0", r"(\1)", text)     # C's comparison: 1 or 0
    text = text.replace("pg_b_", "").replace("const ", "")
    return re.sub(r"\s+", " ", text)


def _definitions(text: str) -> list[str]:
    """The function definitions of a C text, each from its first line to its closing brace."""
    out, current = [], None
    for line in text.splitlines():
        if line.startswith(("PG_INL ", "static inline ")):
            current = []
        if current is not None:
            current.append(line)
            joined = "\n".join(current)
            if joined.count("{") and joined.count("{") == joined.count("}"):
                out.append(joined)
                current = None
    return out


def test_wide_helpers_compute_the_scalar_operations():
    """Every inline builtin of the wide helpers, spelled for scalars, is a definition of the
    prelude: the same operations in the same order on each lane (the overloads taking a
    scalar operand, which only splat it, and floor, whose parameter is named otherwise,
    aside)."""
    scalar = {_as_scalar_ops(d) for d in _definitions(_prelude())}
    names = re.compile(r"pg_(b_\w+|abs|sign|smoothstep|exp2|log2)\(")
    matched = []
    for d in _definitions(cl_wide.wide_helpers()):
        head = d.split("{", 1)[0]
        name = names.search(head)
        if name is None or name.group(1) == "b_floor" or re.search(
                rf"float{W} \w+, const (float|int|uint) \w+\)", head):
            continue
        assert _as_scalar_ops(d) in scalar, d
        matched.append(name.group(1))
    # float8: fmax fmin max min clamp fma sqrt fabs copysign abs sign smoothstep exp2 log2;
    # int8 and uint8: max min clamp; uint8: sub_sat; int8: abs sign
    assert sorted(set(matched)) == sorted({
        "b_fmax", "b_fmin", "b_max", "b_min", "b_clamp", "b_fma", "b_sqrt", "b_fabs",
        "b_copysign", "b_sub_sat", "abs", "sign", "smoothstep", "exp2", "log2"})
    assert len(matched) == 23


# ---- dot, length, cross, mix and the matrix products: one order ---------------------------

def _tree(text: str):
    """A C expression of + - * and calls as a tree: (op, left, right), ("call", name, args)
    or a leaf's text; parentheses only group."""
    tokens = re.findall(r"[A-Za-z_][\w.]*(?:->\w+)*(?:\[\d+\])?(?:\.\w+)*|\d+\.?\d*f?|[-+*(),]",
                        text)
    pos = [0]

    def peek():
        return tokens[pos[0]] if pos[0] < len(tokens) else None

    def take():
        pos[0] += 1
        return tokens[pos[0] - 1]

    def atom():
        tok = take()
        if tok == "(":
            e = expr()
            assert take() == ")"
            return e
        if peek() == "(":
            take()
            args = [expr()]
            while peek() == ",":
                take()
                args.append(expr())
            assert take() == ")"
            return ("call", tok, tuple(args))
        return tok

    def term():
        e = atom()
        while peek() == "*":
            take()
            e = ("*", e, atom())
        return e

    def expr():
        e = term()
        while peek() in ("+", "-"):
            op = take()
            e = (op, e, term())
        return e

    e = expr()
    assert pos[0] == len(tokens), text
    return e


def _leaves(e, rename):
    if isinstance(e, str):
        return rename(e)
    if e[0] == "call":
        return ("call", e[1], tuple(_leaves(a, rename) for a in e[2]))
    return (e[0], _leaves(e[1], rename), _leaves(e[2], rename))


def _expected(e):
    """An ``expand`` tree as ``_tree`` spells one."""
    if isinstance(e, expand.Op):
        if e.op in expand.INFIX:
            return (e.op, _expected(e.args[0]), _expected(e.args[1]))
        return ("call", e.op, tuple(_expected(a) for a in e.args))
    return e


def _prelude_body(prelude: str, head: str) -> str:
    """The expression a prelude function or macro starting with ``head`` returns."""
    k = prelude.index(head)
    line = prelude[k:prelude.index("\n", k)]
    if line.startswith("#define"):
        return line.split(") ", 1)[1]
    body = prelude[k:prelude.index("}", k)]
    return body.split("return ", 1)[1].rsplit(";", 1)[0]


def _wide_locals(text: str) -> dict:
    """The wide function's varying locals: name -> value (the matrices named as one leaf)."""
    text = text.replace("pg_m3_from_m4(in->frame->view)", "VIEW").replace(
        "pg_m3_from_m4(in->frame->proj)", "PROJ")
    return dict(re.findall(rf"^\s*float{W} (\w+) = (.*);$", text, re.M))


def _check_one_order():
    """The prelude's functions and the wide path's expansions of ORDERS against ``expand``."""
    pre = _prelude()
    old = cl_wide.MIN_COST
    cl_wide.MIN_COST = 0
    try:
        tech = compile_source(ORDERS).technique
        frag = emit_fragment(tech, tech.passes[0])["fragment"]
    finally:
        cl_wide.MIN_COST = old
    assert cl_wide.MARK in frag
    wide_locals = _wide_locals(frag)

    def w(name):
        return _tree(wide_locals[name])
    xyz = "xyz"
    n = [f"pg_v_n_{c}" for c in xyz]
    c = [f"pg_v_c_{c}" for c in xyz]
    wp = [f"win->world_pos[{k}]" for k in range(3)]

    # dot: pg_dot(float3) sums p = a * b; the wide d = dot(n, c) sums the products in place
    products = {("*", f"a.{k}", f"b.{k}"): f"p.{k}" for k in xyz}
    want = _expected(expand.dot([f"a.{k}" for k in xyz], [f"b.{k}" for k in xyz]))

    def over_p(e):
        return products.get(e) or (e if isinstance(e, str) else (e[0], *map(over_p, e[1:])))
    assert _tree(_prelude_body(pre, "pg_dot(const float3")) == over_p(want)
    assert w("d") == _leaves(want, lambda s: {**dict(zip([f"a.{k}" for k in xyz], n)),
                                              **dict(zip([f"b.{k}" for k in xyz], c))}[s])
    # length = sqrt(dot(v, v)): the prelude through pg_dot, the wide path in place
    assert _tree(_prelude_body(pre, "#define pg_length")) == _expected(
        expand.length(["v"], dot_of=lambda a, b: expand.call("pg_dot", *a, *b)))
    assert w("l") == _expected(expand.length(c))
    # cross
    ab = {f"a.{k}": x for k, x in zip(xyz, n)} | {f"b.{k}": x for k, x in zip(xyz, wp)}
    cross = [_expected(t) for t in expand.cross([f"a.{k}" for k in xyz], [f"b.{k}" for k in xyz])]
    assert [_tree(t) for t in _prelude_body(pre, "float3 pg_cross(").removeprefix(
        "(float3)(").removesuffix(")").split(", ")] == cross
    assert [w(f"pg_v_c_{k}") for k in xyz] == [_leaves(t, ab.get) for t in cross]
    # mix
    mix = _expected(expand.mix("a", "b", "t"))
    assert _tree(_prelude_body(pre, "#define pg_mix")) == mix
    assert w("pg_v_m_x") == _leaves(mix, {"a": n[0], "b": c[0], "t": "win->frag_coord[0]"}.get)
    # m * v and v * m (mat3(view) * n, n * mat3(proj))
    mv = _expected(expand.matrix_vector([f"m.c[{k}]" for k in range(3)], [f"v.{k}" for k in xyz]))
    assert _tree(_prelude_body(pre, "float3 pg_m3_mul_v3(")) == mv
    for comp in xyz:         # leaves m.c[j] and v.x: VIEW's column j's component, n's x
        assert w(f"pg_v_r_{comp}") == _leaves(mv, lambda s: n[xyz.index(s[-1])] if s[0] == "v"
                                              else f"VIEW.c[{s[4]}].{comp}")
    vm = expand.vector_matrix(["v"], [[f"m.c[{k}]"] for k in range(3)],
                              dot_of=lambda a, b: expand.call("pg_dot", *a, *b))
    assert [_tree(t) for t in re.split(r", (?=pg_dot)", _prelude_body(
        pre, "float3 pg_v3_mul_m3(").removeprefix("(float3)(").removesuffix(")"))] == [
        _expected(t) for t in vm]
    for k, comp in enumerate(xyz):
        column = [f"PROJ.c[{k}].{c2}" for c2 in xyz]
        assert w(f"pg_v_s_{comp}") == _expected(expand.dot(n, column))
    return pre, frag


def test_both_paths_follow_the_expansion():
    """The prelude's pg_dot, pg_length, pg_cross, pg_mix, pg_m3_mul_v3 and pg_v3_mul_m3 and
    the wide path's dot, length, cross, mix, m * v and v * m have ``expand``'s trees."""
    _check_one_order()


def _left_dot(a, b):
    terms = [expand.mul(x, y) for x, y in zip(a, b)]
    acc = terms[0]
    for t in terms[1:]:
        acc = expand.add(acc, t)
    return acc


def test_both_paths_follow_a_changed_expansion(monkeypatch):
    """With other orders in ``expand`` (the dot summed left to right, the products of cross
    turned, mix's sum turned, m * v summed right to left), both paths change alike: neither
    has an order of its own."""
    before = _check_one_order()
    monkeypatch.setattr(expand, "dot", _left_dot)
    monkeypatch.setattr(expand, "cross", lambda a, b: (
        expand.sub(expand.mul(b[2], a[1]), expand.mul(b[1], a[2])),
        expand.sub(expand.mul(b[0], a[2]), expand.mul(b[2], a[0])),
        expand.sub(expand.mul(b[1], a[0]), expand.mul(b[0], a[1]))))
    monkeypatch.setattr(expand, "mix", lambda a, b, t: expand.add(
        expand.mul(expand.sub(b, a), t), a))
    monkeypatch.setattr(expand, "matrix_vector", lambda cols, v: _left_dot(
        list(reversed(cols)), list(reversed(v))))
    expansions.prelude_forms.cache_clear()       # built once a process: build it again
    after = _check_one_order()
    expansions.prelude_forms.cache_clear()
    assert after[0] != before[0] and after[1] != before[1]
