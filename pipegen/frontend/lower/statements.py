"""Shader code, part 2: the statements of function and fragment bodies (declarations,
assignments, target writes, if, bounded for loops, return, discard) on top of the
expression checker."""

from __future__ import annotations

from pipegen.frontend import ast
from pipegen.ir import nodes as ir
from pipegen.ir.builtins import STAGE_INPUTS, binary_type, target_write_type
from pipegen.core.diagnostics import Span
from pipegen.frontend.lower.expressions import ExprChecker, conversion_hint, is_static
from pipegen.frontend.lower.names import RESERVED, Signature, a_or_an, error, shader_type


class BodyChecker(ExprChecker):
    """Type checks one function or fragment body and builds its IR."""

    # -- bodies ---------------------------------------------------------------------------------
    def function_body(self, sig: Signature) -> tuple[ir.Stmt, ...]:
        for (name, t), p in zip(sig.params, sig.decl.params):
            self._declare_local(p.name, t)
        body = self.block(sig.decl.body, new_scope=False)
        if not sig.ret.is_void and not _always_returns(sig.decl.body):
            raise error(sig.decl.name.span, f"function '{sig.name}' can reach its end without "
                        f"returning {a_or_an(sig.ret)}", "end every path with `return VALUE;`")
        return body

    def block(self, stmts: list[ast.Stmt], new_scope: bool = True) -> tuple[ir.Stmt, ...]:
        if new_scope:
            self.scopes.append({})
        try:
            return tuple(self.stmt(s) for s in stmts)
        finally:
            if new_scope:
                self.scopes.pop()

    # -- statements -------------------------------------------------------------------------------
    def stmt(self, s: ast.Stmt) -> ir.Stmt:
        method = getattr(self, "_stmt_" + type(s).__name__)
        return method(s)

    def _stmt_VarDecl(self, s: ast.VarDecl) -> ir.Stmt:
        t = shader_type(s.type)
        init = None
        if s.init is not None:
            init = self.expr(s.init)
            if init.type != t:
                raise error(s.init.span, f"cannot initialise {t} '{s.name.name}' with "
                            f"{a_or_an(init.type)}", conversion_hint(init.type, t))
        self._declare_local(s.name, t)
        return ir.Declare(s.name.name, t, init)

    def _stmt_Assign(self, s: ast.Assign) -> ir.Stmt:
        if isinstance(s.target, ast.Name) and s.target.name in self.low.targets:
            return self._output(s)
        target = self._lvalue(s.target)
        value = self.expr(s.value)
        if s.op == "=":
            ok = value.type == target.type
        else:
            ok = binary_type(s.op[0], target.type, value.type) == target.type
        if not ok:
            what = "assign" if s.op == "=" else f"apply '{s.op}' with"
            raise error(s.value.span,
                        f"cannot {what} {a_or_an(value.type)} to {a_or_an(target.type)}",
                        conversion_hint(value.type, target.type))
        return ir.Assign(target, s.op, value)

    def _stmt_ExprStmt(self, s: ast.ExprStmt) -> ir.Stmt:
        if not isinstance(s.expr, (ast.Call, ast.MethodCall)):
            raise error(s.span, "this statement has no effect",
                        "a statement is a declaration, an assignment or a call")
        value = self.expr(s.expr, allow_void=True)
        if not isinstance(value, ir.Call):   # a constructor, conversion or load()/sample()
            raise error(s.span, "this statement has no effect",
                        "use the value: assign it to a variable or a target")
        return ir.ExprStmt(value)

    def _stmt_If(self, s: ast.If) -> ir.Stmt:
        cond = self._condition(s.cond, "an if condition")
        then = self.block(s.then)
        other = self.block(s.other) if s.other is not None else ()
        return ir.If(cond, then, other)

    def _stmt_For(self, s: ast.For) -> ir.Stmt:
        t = shader_type(s.var_type)
        if t not in (ir.INT, ir.UINT):
            raise error(s.var_type.span, f"a loop counter is an int or a uint, not {t}",
                        "write `for (int i = 0; i < N; i++)`")
        start = self.expr(s.start)
        if start.type != t:
            raise error(s.start.span,
                        f"loop counter '{s.var.name}' is {a_or_an(t)}, but it starts at "
                        f"{a_or_an(start.type)}", conversion_hint(start.type, t))
        bound = self._loop_bound(s, t)
        if s.step_var.name != s.var.name or not (isinstance(s.step, ast.Number)
                                                 and s.step.value == 1):
            raise error(s.step_var.span, f"a loop steps its counter by one: "
                        f"`{s.var.name}++`", "loops are bounded: for (i = A; i < B; i++)")
        self.scopes.append({})
        self._declare_local(s.var, t, loop_var=True)
        self.loops += 1
        try:
            body = self.block(s.body)
        finally:
            self.loops -= 1
            self.scopes.pop()
        return ir.For(s.var.name, t, start, bound, body)

    def _loop_bound(self, s: ast.For, t: ir.Type) -> ir.Expr:
        c = s.cond
        if not (isinstance(c, ast.BinaryOp) and c.op == "<" and isinstance(c.left, ast.Name)
                and c.left.name == s.var.name):
            raise error(c.span, f"a loop condition has the form `{s.var.name} < BOUND`",
                        "loops are bounded: for (int i = A; i < B; i++)")
        bound = self.expr(c.right)
        # the bound's kind first: a counter retyped to match a run-time bound would only meet
        # this error next (`i < num_lights`: an int counter, a uint and run-time bound)
        if not is_static(bound):
            raise error(c.right.span, "the loop bound is not a constant or a parameter",
                        "loop to a constant bound and break early, e.g. "
                        "`if (uint(i) >= num_lights) break;`")
        if bound.type != t:
            raise error(c.right.span,
                        f"loop counter '{s.var.name}' is {a_or_an(t)}, but its bound is "
                        f"{a_or_an(bound.type)}", conversion_hint(bound.type, t))
        return bound

    def _stmt_Break(self, s: ast.Break) -> ir.Stmt:
        self._in_loop(s, "break")
        return ir.Break()

    def _stmt_Continue(self, s: ast.Continue) -> ir.Stmt:
        self._in_loop(s, "continue")
        return ir.Continue()

    def _in_loop(self, s: ast.Node, word: str) -> None:
        if not self.loops:
            raise error(s.span, f"`{word}` outside a loop", "use it inside a for loop")

    def _stmt_Return(self, s: ast.Return) -> ir.Stmt:
        want = self.ctx.ret
        if s.value is None:
            if not want.is_void:
                raise error(s.span, f"function '{self.ctx.function}' returns {a_or_an(want)}",
                            f"write `return VALUE;` with {a_or_an(want)} value")
            return ir.Return(None)
        if self.ctx.in_pass:
            raise error(s.value.span, "a fragment body returns no value",
                        "write `return;` to end the fragment, or `discard;` to drop it")
        value = self.expr(s.value)
        if want.is_void or value.type != want:
            raise error(s.value.span, f"function '{self.ctx.function}' returns "
                        f"{'nothing' if want.is_void else a_or_an(want)}, "
                        f"not {a_or_an(value.type)}",
                        conversion_hint(value.type, want) if not want.is_void
                        else "write `return;`")
        return ir.Return(value)

    def _stmt_Discard(self, s: ast.Discard) -> ir.Stmt:
        return ir.Discard()

    # -- assignments and outputs ------------------------------------------------------------------
    def _lvalue(self, e: ast.Expr) -> ir.Expr:
        root = e
        while isinstance(root, (ast.Field, ast.Subscript)):
            root = root.base
        if not isinstance(root, ast.Name):
            raise error(e.span, "this expression cannot be assigned to",
                        "assign to a local variable, one of its components or an element")
        local = self._lookup_local(root.name)
        if local is None:
            what = self._describe_global(root.name)
            raise error(root.span, f"cannot assign to {what}",
                        "only local variables and function parameters can be assigned")
        if local.loop_var:
            raise error(root.span, f"cannot assign to loop counter '{root.name}'",
                        "loops are bounded; use a separate variable")
        target = self.expr(e)
        if isinstance(target, ir.Swizzle) and len(set(target.components)) != \
                len(target.components):
            raise error(e.span, "a swizzle written to cannot repeat a component",
                        "write each component once, e.g. v.xy = …")
        return target

    def _describe_global(self, name: str) -> str:
        low = self.low
        if name in low.params:
            return f"parameter '{name}' (parameters are constant)"
        if name in STAGE_INPUTS:
            return f"stage input '{name}' (inputs are read-only)"
        if name in RESERVED:
            return f"'{name}' ({RESERVED[name]}, read-only)"
        if name in low.globals:
            return f"{low.globals[name].kind} '{name}'"
        return f"unknown name '{name}'"

    def _output(self, s: ast.Assign) -> ir.Stmt:
        name = s.target.name
        t = self.low.targets[name]
        ctx = self.ctx
        if not ctx.in_pass:
            raise error(s.target.span, f"function '{ctx.function}' writes target '{name}'",
                        "targets are written in fragment bodies; return the value instead")
        if not t.format.is_color:
            raise error(s.target.span, f"'{name}' is a depth target and cannot be written as "
                        f"a colour", f"depth is written by the depth test: "
                        f"`depth {name} less write`")
        if name not in ctx.writes:
            raise error(s.target.span, f"{ctx.describe()} writes target '{name}' but does not "
                        f"declare it", f"add `writes {name}` to the pass")
        if s.op != "=":
            raise error(s.target.span, f"target '{name}' can only be assigned with '='",
                        "targets are write-only: compute the value in a local first")
        value = self.expr(s.value)
        self.outputs.add(name)
        return ir.Output(name, _widen_output(value, t, s.value.span), s.span)


def _widen_output(value: ir.Expr, target: ir.Target, span: Span) -> ir.Expr:
    """A colour write's value as the target's write type (vec4 / uvec4), padded with zeros."""
    fmt = target.format
    want = target_write_type(fmt)
    t = value.type
    if t.scalar is not want.scalar or t.is_matrix or t.size < fmt.channels:
        options = [str(ir.Type(want.scalar, n)) for n in range(fmt.channels, 5)]
        accepted = ", ".join(options[:-1]) + " or " + options[-1] if len(options) > 1 \
            else options[0]
        if t.scalar is not want.scalar and not t.is_matrix:
            hint = conversion_hint(t, ir.Type(want.scalar, t.size))
        else:
            hint = f"the value needs at least {fmt.channels} components"
        raise error(span, f"target '{target.name}' ({fmt.name}) takes {a_or_an(accepted)}, "
                    f"not {a_or_an(t)}", hint)
    if t.size == 4:
        return value
    zero = ir.Const(want.element, 0.0 if want.scalar is ir.Scalar.FLOAT else 0)
    return ir.Construct(want, (value,) + (zero,) * (4 - t.size))


def _always_returns(stmts: list[ast.Stmt]) -> bool:
    if not stmts:
        return False
    last = stmts[-1]
    if isinstance(last, (ast.Return, ast.Discard)):
        return True
    if isinstance(last, ast.If) and last.other is not None:
        return _always_returns(last.then) and _always_returns(last.other)
    return False
