"""``WideEmitter``: renders ``pg_fragment_w``, the fragment code of a pass for ``W`` pixels per
call, from the IR (statements and functions: ``statements``; expressions: ``expressions``)."""

from __future__ import annotations

from typing import Optional

from pipegen.ir import nodes as ir
from pipegen.backends.opencl.wide.expressions import WideExpressions
from pipegen.backends.opencl.wide.statements import WideStatements
from pipegen.backends.opencl.wide.values import MARK, W, Val


class WideEmitter(WideStatements, WideExpressions):
    """The lowering of one pass (``tech``, ``pass_``) through ``lang`` (``OpenCLLanguage``: the
    scalar dialect, whose spellings of literals, inputs and builtins it shares)."""

    def __init__(self, tech: ir.Technique, pass_: ir.Pass, lang, too_many=lambda gathers: False,
                 shared: Optional[dict] = None):
        self.tech, self.pass_, self.lang = tech, pass_, lang
        # specialised functions rendered for the technique's other passes: (dialect, id of the
        # function, flags) -> (the function, kept so its id stays its own; its ``emitted``
        # entries; its return shape; its lane_gathers)
        self.shared = {} if shared is None else shared
        # whether the pass body's count of rows gathered lane by lane rules the wide form out
        # (wide_fragment's test): rendering stops as soon as what it counted passes it
        self.too_many_gathers = too_many
        # the functions being rendered for a call: (the caller's count before the call, the
        # call's loop weight), outermost first (count_gathers)
        self.callers: list[tuple[int, int]] = []
        self.functions: dict = {}
        # what the emitted text holds: the structs and specialised functions the current
        # render uses (a discarded render's additions are taken back, see _function_body)
        self.out_funcs: dict[str, str] = {}      # specialised name -> source
        self.structs: dict[str, str] = {}
        self.func_ret: dict[str, Val] = {}       # specialised name -> return shape (all renders)
        # specialised name -> the (table: "structs" or "out_funcs", key, text) entries its
        # emission added, itself last: a function a discarded render emitted is put back
        # without rendering it again
        self.emitted: dict[str, list] = {}
        self.rows, self.path = None, ()     # the body's light-row loads (light_rows.py)
        self.func_gathers: dict[str, int] = {}   # specialised name -> its lane_gathers
        self.pass_gathers = 0       # table rows a pixel of the pass gathers lane by lane

    # ---- entry -------------------------------------------------------------------------------
    def fragment(self, functions) -> str:
        self.functions = {f.name: f for f in functions}
        body = self._function_body(self.pass_.body, {}, main=True)
        self.pass_gathers = self.lane_gathers
        # inlined at every call (PoCL's clang kept it out of line, called once per batch and
        # light inside a run of lights drawn once per row, cl_pass.cl.j2's pg_once): multi-pass
        # forward's light pass 121 -> 109 ms at 640x360 (three alternated runs each), the other
        # wide passes' frames within noise or 3-5 % faster, kernel builds 2 % longer
        lines = [f"static inline __attribute__((always_inline)) int{W} pg_fragment_w("
                 "const pg_in *in, const pgw_in *win, pgw_out *out) {",
                 f"    int{W} pg_live = (int{W})(-1);", *body,
                 "    return pg_live;", "}"]
        parts = [MARK] + list(self.structs.values()) + list(self.out_funcs.values())
        return "\n\n".join(parts + ["\n".join(lines)]) + "\n"
