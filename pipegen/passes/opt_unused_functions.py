"""opt_unused_functions: drop functions no pass can reach.

Packing schemes generate a full set of pack/unpack functions and user code includes shared
libraries; a pass's shader should only carry what it calls.
"""

from __future__ import annotations

import dataclasses

from pipegen.ir import nodes as ir, walk as irwalk


def run(tech: ir.Technique) -> ir.Technique:
    by_name = {f.name: f for f in tech.all_functions()}
    reachable: set[str] = set()
    work = [c.name for p in tech.passes for c in _user_calls(p.body)]
    while work:
        name = work.pop()
        if name in reachable or name not in by_name:
            continue
        reachable.add(name)
        work.extend(c.name for c in _user_calls(by_name[name].body))

    packings = tuple(dataclasses.replace(
        p, functions=tuple(f for f in p.functions if f.name in reachable))
        for p in tech.packings)
    functions = tuple(f for f in tech.functions if f.name in reachable)
    return dataclasses.replace(tech, packings=packings, functions=functions)


def called_functions(stmts) -> set[str]:
    return {c.name for c in _user_calls(stmts)}


def _user_calls(stmts):
    return (e for e in irwalk.walk_exprs(stmts) if isinstance(e, ir.Call) and not e.builtin)
