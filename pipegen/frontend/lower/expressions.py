"""Shader code, part 1: scopes of local names and the type checking of expressions
(names, operators, swizzles, light fields, calls of user functions, builtins and targets,
constructors) into IR expressions.  ``statements._BodyChecker`` adds the statements."""

from __future__ import annotations

from typing import Optional

from pipegen.frontend import ast
from pipegen.ir import nodes as ir
from pipegen.ir.builtins import (
    BUILTINS, LIGHT_FIELDS, LIGHT_INDEX, STAGE_INPUTS, TARGET_FUNCTIONS, TYPE_NAMES, Where,
    binary_type, describe_overloads, resolve_builtin, target_read_type, unary_type)
from pipegen.core.diagnostics import Span
from pipegen.core.records import replace
from pipegen.core.formats import FORMATS
from pipegen.packing.base import SCHEMES
from pipegen.frontend.lower.names import (
    A_or_An, Lowering, Context, Local, Uses, a_or_an, did_you_mean, error, listing,
    reserved_meaning, shader_type)


# the expressions that keep where the user wrote them (``span``, not compared, not printed):
# the ones a discontinuity can sit in (comparisons, step/floor/..., float-to-int conversions)
SPANNED = (ir.Binary, ir.Call, ir.Construct)


class ExprChecker:
    """Type checks the expressions of one function or fragment body and builds their IR."""

    def __init__(self, low: Lowering, ctx: Context):
        self.low = low
        self.ctx = ctx
        self.scopes: list[dict[str, Local]] = [{}]
        self.loops = 0
        self.uses = Uses()
        self.outputs: set[str] = set()       # targets this body writes

    # -- local names ---------------------------------------------------------------------------
    def _declare_local(self, name: ast.Name, t: ir.Type, loop_var: bool = False) -> None:
        n = name.name
        prev = self._lookup_local(n)
        if prev is not None:
            raise error(name.span, f"'{n}' is already declared (line {prev.span.line})",
                        "rename this variable; names are not shadowed")
        clash = reserved_meaning(n) or (a_or_an(self.low.globals[n].kind)
                                         if n in self.low.globals else None)
        if clash:
            raise error(name.span, f"'{n}' is already {clash}",
                        f"rename this variable (e.g. '{n}_')")
        self.scopes[-1][n] = Local(t, name.span, loop_var)

    def _lookup_local(self, name: str) -> Optional[Local]:
        for scope in reversed(self.scopes):
            if name in scope:
                return scope[name]
        return None

    # -- expressions ----------------------------------------------------------------------------
    def expr(self, e: ast.Expr, allow_void: bool = False) -> ir.Expr:
        method = getattr(self, "_expr_" + type(e).__name__)
        result = method(e)
        if result.type.is_void and not allow_void:
            raise error(e.span, "this call returns no value", "use it as a statement")
        if type(result) in SPANNED and result.span is None:
            # where the user wrote it: a discontinuity (proof/discontinuity.py) is reported there
            result = replace(result, span=e.span)
        return result

    def _condition(self, e: ast.Expr, what: str) -> ir.Expr:
        cond = self.expr(e)
        if cond.type != ir.BOOL:
            raise error(e.span, f"{what} must be a bool, not {a_or_an(cond.type)}",
                        "compare explicitly, e.g. `x != 0u` or `v > 0.0`")
        return cond

    def _expr_Number(self, e: ast.Number) -> ir.Expr:
        t = {"float": ir.FLOAT, "int": ir.INT, "uint": ir.UINT}[e.kind]
        return ir.Const(t, e.value)

    def _expr_Bool(self, e: ast.Bool) -> ir.Expr:
        return ir.Const(ir.BOOL, e.value)

    def _expr_Name(self, e: ast.Name) -> ir.Expr:
        n = e.name
        local = self._lookup_local(n)
        if local is not None:
            return ir.Var(n, local.type, "local")
        low = self.low
        if n in low.params:
            p = low.params[n]
            if p.type == ir.VOID:
                what = ("a format" if p.default in FORMATS else "a packing scheme"
                        if p.default in SCHEMES else "a word")
                raise error(e.span, f"parameter '{n}' holds {what} ('{p.default}'), "
                            f"not a value", "word parameters choose formats and packing "
                            "schemes in declarations, and passes and targets in conditions "
                            f"(`pass NAME if {n} == WORD {{ … }}`)")
            return ir.Var(n, p.type, "param")
        if n in STAGE_INPUTS:
            return self._stage_input(e)
        if n in low.targets:
            raise error(e.span, f"target '{n}' is not a value",
                        f"read it with load({n}) or sample({n}, uv); write it with `{n} = …;`")
        if n == "light":
            raise error(e.span, "`light` is read by field", "e.g. light.position, light.index")
        if n == "lights":
            raise error(e.span, "`lights` is read by index and field", "e.g. lights[i].position")
        if n in low.pack_specs:
            raise error(e.span, f"packing '{n}' is not a value",
                        f"call its functions ({n}.fn(…)) or read its constants ({n}.name)")
        if n in low.signatures or n in BUILTINS:
            raise error(e.span, f"function '{n}' is not a value", f"call it: {n}(…)")
        raise error(e.span, f"unknown name '{n}'", did_you_mean(n, self._visible_names(),
                                                                "declare it before use"))

    def _visible_names(self) -> list[str]:
        names = [n for scope in self.scopes for n in scope]
        names += [n for n, p in self.low.params.items() if p.type != ir.VOID]
        names += list(STAGE_INPUTS)
        return names

    def _stage_input(self, e: ast.Name) -> ir.Expr:
        inp = STAGE_INPUTS[e.name]
        if inp.where is Where.SCENE:
            if self.ctx.in_pass and self.ctx.draw is not ir.DrawKind.SCENE:
                raise error(e.span, f"'{e.name}' exists only in scene draws, and "
                            f"{self.ctx.describe()} does not draw the scene",
                            "store it in a target in a scene pass and load() it here")
            self.uses.scene.append((e.name, e.span))
        if e.name == "sample_id":
            if self.ctx.in_pass and self.ctx.samples == 1:
                raise error(e.span, f"'sample_id' is the sample being shaded, and "
                            f"{self.ctx.describe()} draws into single-sampled targets",
                            "declare its attachments with `samples N` (N > 1), or drop "
                            "sample_id")
            self.uses.sample_id.append(e.span)
        return ir.Var(e.name, inp.type, "input")

    def _expr_UnaryOp(self, e: ast.UnaryOp) -> ir.Expr:
        if e.op == "-" and isinstance(e.operand, ast.Number):
            # A negative literal is a literal (matters for folding and for -2147483648).
            t = self._expr_Number(e.operand).type
            value = -e.operand.value
            return ir.Const(t, value & 0xFFFFFFFF if t == ir.UINT else value)
        operand = self.expr(e.operand)
        t = unary_type(e.op, operand.type)
        if t is None:
            raise error(e.span, f"operator '{e.op}' does not apply to {a_or_an(operand.type)}",
                        {"!": "'!' negates a bool", "~": "'~' inverts an int or uint"}.get(
                           e.op, "'-' negates a number or vector"))
        return operand if e.op == "+" else ir.Unary(e.op, operand, t)

    def _expr_BinaryOp(self, e: ast.BinaryOp) -> ir.Expr:
        if e.op in ("==", "!=") and self._word_param_side(e):
            # `WORD_PARAM == WORD` in shader code: the parameter's value is known when the
            # technique is compiled, so the comparison is a constant (as in pass conditions)
            from pipegen.frontend.lower.conditions import parameter_value
            return ir.Const(ir.BOOL, bool(parameter_value(e, self.low.params)))
        left, right = self.expr(e.left), self.expr(e.right)
        t = binary_type(e.op, left.type, right.type)
        if t is None:
            raise error(e.span, f"operator '{e.op}' cannot combine {a_or_an(left.type)} and "
                        f"{a_or_an(right.type)}", _operator_hint(e.op, left.type, right.type))
        return ir.Binary(e.op, left, right, t)

    def _word_param_side(self, e: ast.BinaryOp) -> bool:
        """Whether a side of ``e`` names a word parameter (no local of that name)."""
        return any(isinstance(s, ast.Name) and self._lookup_local(s.name) is None
                   and s.name in self.low.params and self.low.params[s.name].type == ir.VOID
                   for s in (e.left, e.right))

    def _expr_Conditional(self, e: ast.Conditional) -> ir.Expr:
        cond = self._condition(e.cond, "a ?: condition")
        then, other = self.expr(e.then), self.expr(e.other)
        if then.type != other.type:
            raise error(e.span, f"the branches of ?: differ: {then.type} and {other.type}",
                        conversion_hint(other.type, then.type))
        return ir.Ternary(cond, then, other, then.type)

    def _expr_Subscript(self, e: ast.Subscript) -> ir.Expr:
        if isinstance(e.base, ast.Name) and e.base.name == "materials" \
                and self._lookup_local("materials") is None:
            raise error(e.span, "a material is read by field",
                        "e.g. materials[id].model; the `material { … }` block lists the fields")
        if isinstance(e.base, ast.Name) and e.base.name == "lights" \
                and self._lookup_local("lights") is None:
            raise error(e.span, "a light is read by field",
                        "e.g. lights[i].position; the schema lists the fields")
        base = self.expr(e.base)
        if not (base.type.is_vector or base.type.is_matrix):
            raise error(e.base.span, f"{A_or_An(base.type)} cannot be indexed",
                        "index a vector (v[i]) or a matrix column (m[i])")
        index = self._index_value(e.index)
        n = base.type.mat or base.type.size
        if isinstance(index, ir.Const) and not 0 <= index.value < n:
            raise error(e.index.span,
                        f"index {index.value} is out of range for {a_or_an(base.type)}",
                        f"valid indices are 0 to {n - 1}")
        return ir.Index(base, index, base.type.element)

    def _index_value(self, e: ast.Expr) -> ir.Expr:
        index = self.expr(e)
        if index.type not in (ir.INT, ir.UINT):
            raise error(e.span, f"an index is an int or a uint, not {a_or_an(index.type)}",
                        conversion_hint(index.type, ir.INT))
        return index

    def _expr_Field(self, e: ast.Field) -> ir.Expr:
        base = e.base
        if isinstance(base, ast.Name) and self._lookup_local(base.name) is None:
            if base.name == "light":
                return self._light_field(None, e)
            if base.name == "material":
                return self._material_field(None, e)
            if base.name in self.low.pack_specs:
                return self.low.pack_constant(base, e.name)
        if isinstance(base, ast.Subscript) and isinstance(base.base, ast.Name) \
                and base.base.name == "lights" and self._lookup_local("lights") is None:
            return self._light_field(self._index_value(base.index), e)
        if isinstance(base, ast.Subscript) and isinstance(base.base, ast.Name) \
                and base.base.name == "materials" and self._lookup_local("materials") is None:
            return self._material_field(self._index_value(base.index), e)
        value = self.expr(base)
        return self._swizzle(value, e)

    def _light_field(self, index: Optional[ir.Expr], e: ast.Field) -> ir.Expr:
        name = e.name.name
        if index is None:
            if self.ctx.in_pass and not self.ctx.has_light:
                raise error(e.base.span, f"`light` is only bound in light draws and repeat-per-"
                            f"light passes, and {self.ctx.describe()} is neither",
                            "index the light table instead: lights[i].FIELD, or add "
                            "`repeat per light` to the pass")
            self.uses.light.append(e.base.span)
            if name == LIGHT_INDEX:
                return ir.LightField(None, LIGHT_INDEX, ir.UINT)
        t = self.low.lights.field_type(name)
        if t is None:
            schema = [f.name for f in self.low.lights.fields]
            if name in LIGHT_FIELDS:
                hint = f"add `{name}: {LIGHT_FIELDS[name]}` to the `lights[…] {{ … }}` schema"
            else:
                hint = did_you_mean(name, schema + ([LIGHT_INDEX] if index is None else []),
                                    f"the schema declares: {listing(schema)}")
            raise error(e.name.span, f"lights have no field '{name}'", hint)
        return ir.LightField(index, name, t)

    def _material_field(self, index: Optional[ir.Expr], e: ast.Field) -> ir.Expr:
        """``material.FIELD`` (the drawn object's record: index None) or
        ``materials[id].FIELD`` (any object's, e.g. an id a G-buffer stored)."""
        name = e.name.name
        table = self.low.materials
        if table is None:
            raise error(e.span, "this technique declares no material fields",
                        f"declare them at the top level, e.g. `material {{ {name}: float = 0 }}`")
        t = table.field_type(name)
        if t is None:
            schema = [f.name for f in table.fields]
            raise error(e.name.span, f"materials have no field '{name}'",
                        did_you_mean(name, schema, f"the material block declares: {listing(schema)}"))
        if index is None:
            if self.ctx.in_pass and self.ctx.draw is not ir.DrawKind.SCENE:
                raise error(e.base.span, f"`material` is the drawn object's, and "
                            f"{self.ctx.describe()} does not draw the scene",
                            "store object_id in a target in a scene pass and read "
                            "materials[id].FIELD here")
            index = self._stage_input(ast.Name("object_id", span=e.base.span))
        return ir.MaterialField(index, name, t)

    def _swizzle(self, value: ir.Expr, e: ast.Field) -> ir.Expr:
        name = e.name.name
        if not value.type.is_vector:
            raise error(e.name.span, f"{A_or_An(value.type)} has no field '{name}'",
                        "swizzles (.x, .rgb, …) apply to vectors")
        for sets in ("xyzw", "rgba", "stpq"):
            if all(c in sets for c in name):
                comps = "".join("xyzw"[sets.index(c)] for c in name)
                break
        else:
            raise error(e.name.span, f"'{name}' is not a swizzle",
                        "use components from one of xyzw, rgba, stpq")
        if len(comps) > 4:
            raise error(e.name.span, f"a swizzle has at most 4 components, not {len(comps)}",
                        "shorten it")
        too_far = [c for c in comps if "xyzw".index(c) >= value.type.size]
        if too_far:
            bad = name[comps.index(too_far[0])]
            raise error(e.name.span, f"{A_or_An(value.type)} has no component '{bad}'",
                        f"{A_or_An(value.type)} has {value.type.size} components")
        if comps == "xyzw"[:value.type.size]:
            return value       # .xyz of a vec3 is the vector itself
        t = value.type.element if len(comps) == 1 else value.type.with_size(len(comps))
        return ir.Swizzle(value, comps, t)

    # -- calls ------------------------------------------------------------------------------------
    def _expr_Call(self, e: ast.Call) -> ir.Expr:
        name = e.func.name
        if self._lookup_local(name) is not None:
            raise error(e.func.span, f"'{name}' is a variable, not a function",
                        "rename the variable or the function")
        if name in TYPE_NAMES:
            return self._construct(e)
        if name in TARGET_FUNCTIONS:
            return self._target_call(e)
        if name in self.low.signatures:
            return self._user_call(name, e.func.span, e.args, e.span)
        if name in BUILTINS:
            return self._builtin_call(e)
        raise error(e.func.span, f"unknown function '{name}'",
                    did_you_mean(name, list(BUILTINS) + list(self.low.signatures)
                                 + list(TARGET_FUNCTIONS),
                                 "builtins: " + " ".join(sorted(BUILTINS))))

    def _expr_MethodCall(self, e: ast.MethodCall) -> ir.Expr:
        obj = e.obj
        if not (isinstance(obj, ast.Name) and obj.name in self.low.pack_specs):
            shown = obj.name if isinstance(obj, ast.Name) else "this value"
            raise error(obj.span, f"'{shown}' is not a packing, so it has no functions",
                        "only packings have functions: PACK.fn(…)")
        fn = f"{obj.name}_{e.method.name}"
        sig = self.low.signatures.get(fn)
        if sig is None or sig.pack != obj.name:
            own = [s.name[len(obj.name) + 1:] for s in self.low.signatures.values()
                   if s.pack == obj.name]
            raise error(e.method.span, f"packing '{obj.name}' has no function "
                        f"'{e.method.name}'", did_you_mean(e.method.name, own,
                                                           f"its functions: {listing(own)}"))
        return self._user_call(fn, e.method.span, e.args, e.span,
                               shown=f"{obj.name}.{e.method.name}")

    def _user_call(self, name: str, name_span: Span, args: list[ast.Expr], span: Span,
                   shown: Optional[str] = None) -> ir.Expr:
        sig = self.low.signatures[name]
        shown = shown or name
        values = [self.expr(a) for a in args]
        if len(values) != len(sig.params):
            raise error(name_span, f"'{shown}' takes {len(sig.params)} argument(s), "
                        f"not {len(values)}", f"{shown}({_params_text(sig.params)})")
        for (pname, pt), value, arg in zip(sig.params, values, args):
            if value.type != pt:
                raise error(arg.span, f"argument '{pname}' of '{shown}' is {a_or_an(pt)}, not "
                            f"{a_or_an(value.type)}", conversion_hint(value.type, pt))
        self._note_call(name, name_span)
        return ir.Call(name, tuple(values), sig.ret, builtin=False)

    def _note_call(self, name: str, span: Span) -> None:
        """Record a call; in a pass, check now what the callee needs (it is transitive)."""
        self.uses.calls.append((name, span))
        if not self.ctx.in_pass:
            return
        needs = self.low.uses[name]
        ctx = self.ctx
        if needs.scene and ctx.draw is not ir.DrawKind.SCENE:
            input_name, where = needs.scene[0]
            raise error(span, f"'{name}' reads scene input '{input_name}' (line {where.line}), "
                        f"which {ctx.describe()} does not have",
                        "pass the value in as an argument, or call it from a scene pass")
        if needs.light and not ctx.has_light:
            raise error(span, f"'{name}' reads `light` (line {needs.light[0].line}), which is "
                        f"not bound in {ctx.describe()}",
                        "call it from a light draw or a `repeat per light` pass")
        for target, where in needs.reads.items():
            if target not in ctx.reads:
                raise error(span, f"'{name}' reads target '{target}' (line {where.line}), "
                            f"which pass '{ctx.pass_name}' does not declare",
                            f"add `reads {target}` to the pass")
        if needs.sample_id and ctx.samples == 1:
            raise error(span, f"'{name}' reads sample_id (line {needs.sample_id[0].line}), "
                        f"and {ctx.describe()} draws into single-sampled targets",
                        "call it from a pass whose attachments have `samples N` (N > 1)")
        for target, where in needs.sample_reads.items():
            self._note_target_read(target, True, span, f"'{name}' (line {where.line})")
        for target, where in needs.resolved_reads.items():
            self._note_target_read(target, False, span, f"'{name}' (line {where.line})")

    def _note_target_read(self, target: str, per_sample: bool, span: Span,
                          who: str = "this pass") -> None:
        """Record a read of ``target`` per sample or through its resolve; in a pass, the two
        kinds of read of one target are an error (a runtime binds one of them)."""
        mine, other = (self.uses.sample_reads, self.uses.resolved_reads) if per_sample else (
            self.uses.resolved_reads, self.uses.sample_reads)
        mine.setdefault(target, span)
        if self.ctx.in_pass and target in other:
            first = "load_sample" if not per_sample else "load/sample"
            raise error(span, f"{who} reads multisampled target '{target}' per sample and "
                        f"resolved: pass '{self.ctx.pass_name}' also reads it with {first} "
                        f"(line {other[target].line})",
                        "read its samples with load_sample only (average them for the "
                        "resolve), or read the resolve in another pass")

    def _builtin_call(self, e: ast.Call) -> ir.Expr:
        name = e.func.name
        args = tuple(self.expr(a) for a in e.args)
        t = resolve_builtin(name, [a.type for a in args])
        if t is None:
            types = ", ".join(str(a.type) for a in args)
            raise error(e.func.span, f"no version of '{name}' takes ({types})",
                        f"there are {describe_overloads(name)}; genType is float or vec2-4, "
                        f"genIType/genUType int/uint or ivec/uvec; no implicit conversions: "
                        f"write 1.0, not 1")
        return ir.Call(name, args, t, builtin=True)

    def _target_call(self, e: ast.Call) -> ir.Expr:
        name = e.func.name
        arity = {"load": (1, 2), "load_sample": (2, 3), "sample": (2,), "size": (1,)}[name]
        if len(e.args) not in arity or not isinstance(e.args[0], ast.Name):
            raise error(e.span, f"'{name}' is called as {TARGET_FUNCTIONS[name].split(':')[0]}",
                        "its first argument is the name of a target")
        target = self._read_target(e.args[0])
        fmt = self.low.targets[target].format
        if name == "size":
            return ir.TargetSize(target, ir.IVEC2)
        if name == "load_sample":
            return self._load_sample(e, target)
        if self.low.targets[target].samples > 1:
            self._note_target_read(target, False, e.span)
        if name == "load":
            coord = self._typed_arg(e.args[1], ir.IVEC2, "a load coordinate") \
                if len(e.args) == 2 else None
            return ir.Load(target, coord, target_read_type(fmt))
        if fmt.is_integer:
            raise error(e.span, f"integer target '{target}' cannot be sampled",
                        f"read texels with load({target}) or load({target}, ivec2(…))")
        uv = self._typed_arg(e.args[1], ir.VEC2, "a sample coordinate")
        return ir.Sample(target, uv, target_read_type(fmt))

    def _load_sample(self, e: ast.Call, target: str) -> ir.Expr:
        """``load_sample(T, s)`` / ``load_sample(T, ivec2, s)``: sample s of a multisampled
        colour target."""
        t = self.low.targets[target]
        if t.samples == 1 or not t.format.is_color:
            what = "a depth target" if not t.format.is_color else "single-sampled"
            raise error(e.args[0].span, f"load_sample reads the samples of a multisampled "
                        f"colour target, and '{target}' is {what}",
                        f"read it with load({target}), or declare it `samples N` (N > 1)"
                        if t.format.is_color else "copy the depth into a multisampled "
                        "colour target (e.g. r32f, frag_coord.z) and read that")
        coord = self._typed_arg(e.args[1], ir.IVEC2, "a load coordinate") \
            if len(e.args) == 3 else None
        sample = self._typed_arg(e.args[-1], ir.INT, "a sample index")
        self._note_target_read(target, True, e.span)
        return ir.Load(target, coord, target_read_type(t.format), sample)

    def _typed_arg(self, e: ast.Expr, t: ir.Type, what: str) -> ir.Expr:
        value = self.expr(e)
        if value.type != t:
            raise error(e.span, f"{what} is {a_or_an(t)}, not {a_or_an(value.type)}",
                        conversion_hint(value.type, t))
        return value

    def _read_target(self, name: ast.Name) -> str:
        n = name.name
        if n not in self.low.targets:
            raise error(name.span, f"unknown target '{n}'",
                        did_you_mean(n, self.low.targets, "declare it with `target`"))
        ctx = self.ctx
        if ctx.in_pass and n not in ctx.reads:
            raise error(name.span, f"{ctx.describe()} reads target '{n}' but does not "
                        f"declare it", f"add `reads {n}` to the pass")
        self.uses.reads.setdefault(n, name.span)
        return n

    # -- constructors -----------------------------------------------------------------------------
    def _construct(self, e: ast.Call) -> ir.Expr:
        t = shader_type(e.func)
        args = [self.expr(a) for a in e.args]
        if not args:
            raise error(e.span, f"{t}() needs arguments", f"e.g. {t}(0)")
        if any(a.type.is_matrix for a in args) and not t.is_matrix:
            raise error(e.span, f"{A_or_An(t)} cannot be built from a matrix",
                        "index the matrix (m[i]) for a column")
        if t.is_scalar:
            return self._construct_scalar(t, args, e)
        if t.is_matrix:
            return self._construct_matrix(t, args, e)
        return self._construct_vector(t, args, e)

    def _construct_scalar(self, t: ir.Type, args: list[ir.Expr], e: ast.Call) -> ir.Expr:
        if len(args) != 1 or not args[0].type.is_scalar:
            raise error(e.span, f"{t}(…) converts one scalar",
                        "take a component first, e.g. float(v.x)")
        return _convert(args[0], t.scalar)

    def _construct_vector(self, t: ir.Type, args: list[ir.Expr], e: ast.Call) -> ir.Expr:
        if len(args) == 1:
            a = args[0]
            if a.type.is_scalar:
                return ir.Construct(t, (_convert(a, t.scalar),))
            if a.type.size < t.size:
                raise error(e.span, f"{t}(…) needs {t.size} components; {a_or_an(a.type)} has "
                            f"{a.type.size}", f"add the missing ones, e.g. {t}(v, 1.0)"
                            if t.scalar is ir.Scalar.FLOAT else "add the missing components")
            if a.type.size > t.size:     # vec3(v4): keep the leading components
                a = ir.Swizzle(a, "xyzw"[:t.size], a.type.with_size(t.size))
            return _convert(a, t.scalar)
        count = sum(a.type.size for a in args)
        if count != t.size:
            raise error(e.span, f"{t}(…) needs {t.size} components, but the arguments have "
                        f"{count}", "use a swizzle to pass fewer components, e.g. v.xy")
        return ir.Construct(t, tuple(_convert(a, t.scalar) for a in args))

    def _construct_matrix(self, t: ir.Type, args: list[ir.Expr], e: ast.Call) -> ir.Expr:
        n = t.mat
        column = ir.Type(ir.Scalar.FLOAT, n)
        if len(args) == 1 and args[0].type == t:
            return args[0]
        if len(args) == 1 and (args[0].type == ir.FLOAT or args[0].type.is_matrix):
            return ir.Construct(t, (args[0],))
        if len(args) == n and all(a.type == column for a in args):
            return ir.Construct(t, tuple(args))
        if len(args) == n * n and all(a.type == ir.FLOAT for a in args):
            cols = tuple(ir.Construct(column, tuple(args[i * n:(i + 1) * n]))
                         for i in range(n))
            return ir.Construct(t, cols)
        raise error(e.span, f"{t}(…) takes a float (diagonal), a matrix, {n} vec{n} columns "
                    f"or {n * n} floats", "no implicit conversions: write 1.0, not 1")


def _convert(value: ir.Expr, scalar: ir.Scalar) -> ir.Expr:
    """``value`` with its components converted to ``scalar`` (literals folded)."""
    t = value.type
    if t.scalar is scalar:
        return value
    target = ir.Type(scalar, t.size)
    if isinstance(value, ir.Const) and t.is_scalar:
        return ir.Const(target, _convert_literal(value.value, scalar))
    return ir.Construct(target, (value,))


def _convert_literal(v, scalar: ir.Scalar):
    if scalar is ir.Scalar.FLOAT:
        return float(v)
    if scalar is ir.Scalar.BOOL:
        return bool(v)
    if scalar is ir.Scalar.UINT and not isinstance(v, float):
        return int(v) & 0xFFFFFFFF       # uint(-1) wraps, as in GLSL
    return int(v)                        # float -> int truncates toward zero


def is_static(e: ir.Expr) -> bool:
    """Known at compile time: literals, parameters, packing constants and arithmetic on them."""
    if isinstance(e, ir.Const):
        return True
    if isinstance(e, ir.Var):
        return e.kind == "param"
    if isinstance(e, ir.Unary):
        return is_static(e.operand)
    if isinstance(e, ir.Binary):
        return is_static(e.left) and is_static(e.right)
    if isinstance(e, ir.Construct):
        return all(is_static(a) for a in e.args)
    if isinstance(e, ir.Ternary):
        return is_static(e.cond) and is_static(e.then) and is_static(e.other)
    return False


def _params_text(params: list[tuple[str, ir.Type]]) -> str:
    return ", ".join(f"{t} {n}" for n, t in params)


def conversion_hint(have: ir.Type, want: ir.Type) -> str:
    if have.is_void or want.is_void:
        return "check the value's type"
    if have.scalar is not want.scalar and have.size == want.size and not have.is_matrix:
        return f"no implicit conversions: write {want}(…) to convert"
    if have.is_vector and want.is_scalar:
        return "take one component with a swizzle, e.g. .x"
    if have.is_vector and want.is_vector and have.size > want.size:
        return f"keep the leading components with a swizzle, e.g. .{'xyzw'[:want.size]}"
    if want.is_vector and have.size < want.size:
        if want.scalar is ir.Scalar.FLOAT:
            return f"build the {want}, e.g. {want}(value, 1.0)" if have.size > 1 \
                else f"build the {want} with {want}(value)"
        return f"build it with {want}(…)"
    return f"the expected type is {want}"


def _operator_hint(op: str, a: ir.Type, b: ir.Type) -> str:
    if a.scalar is not b.scalar and {a.scalar, b.scalar} <= {ir.Scalar.FLOAT, ir.Scalar.INT,
                                                             ir.Scalar.UINT}:
        return "no implicit conversions between int, uint and float: write float(i), 1.0, 2u"
    if a.is_vector and b.is_vector and a.size != b.size:
        return "the vectors have different sizes; use a swizzle (.xyz) or a constructor"
    if op in ("&&", "||") or op == "!":
        return "logical operators take bools"
    if op in ("&", "|", "^", "<<", ">>", "%"):
        return f"'{op}' applies to int and uint values"
    if op in ("<", "<=", ">", ">="):
        return "comparisons take two scalars of the same type"
    return f"'{op}' needs operands of matching types"
