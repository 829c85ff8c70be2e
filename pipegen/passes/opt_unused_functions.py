"""opt_unused_functions: drop functions no pass can reach.

Packing schemes generate a full set of pack/unpack functions and user code includes shared
libraries; a pass's shader should only carry what it calls.
"""

from __future__ import annotations

import dataclasses

from pipegen.ir import facts, nodes as ir


def run(tech: ir.Technique) -> ir.Technique:
    by_name = {f.name: f for f in tech.all_functions()}
    reachable: set[str] = set()
    # the calls as code_facts lists them: the bodies that stay are walked once per compile
    # (emission asks the same facts of them)
    work = [name for p in tech.passes for name in facts.code_facts(p.body).calls]
    while work:
        name = work.pop()
        if name in reachable or name not in by_name:
            continue
        reachable.add(name)
        work.extend(facts.code_facts(by_name[name].body).calls)

    packings = tuple(dataclasses.replace(
        p, functions=tuple(f for f in p.functions if f.name in reachable))
        for p in tech.packings)
    functions = tuple(f for f in tech.functions if f.name in reachable)
    return dataclasses.replace(tech, packings=packings, functions=functions)

