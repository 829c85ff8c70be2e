"""The package's structure in figures: modules, import cycles, private names imported across
modules, and the largest files and functions (issue 23: the before and after of the house).

    python benchmarks/structure.py            # the summary
    python benchmarks/structure.py --all      # every cycle and every private import

Every import counts, wherever it stands: at module level, inside a function, or under
``TYPE_CHECKING`` (an import that closes a loop from inside a function is a cycle all the
same).  A cycle is a strongly connected component of two or more modules.  Imports of the
package itself (``from pipegen import x`` of the facade) are listed apart.
"""

from __future__ import annotations

import argparse
import ast
import collections
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "pipegen"


def modules(package_dir: Path) -> dict[str, Path]:
    """Dotted module name -> file, for every ``.py`` file under ``package_dir``."""
    out = {}
    for path in sorted(package_dir.rglob("*.py")):
        name = ".".join(path.relative_to(package_dir.parent).with_suffix("").parts)
        out[name.removesuffix(".__init__")] = path
    return out


def imports(name: str, path: Path, mods: dict[str, Path]):
    """(imported module, imported name, line) for each package import in ``path``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    is_package = path.name == "__init__.py"
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == PACKAGE:
                    yield _known(alias.name, mods), alias.name.rsplit(".", 1)[-1], node.lineno
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_package else name.split(".")[:-1]
                base = base[:len(base) - (node.level - 1)]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            if module.split(".")[0] != PACKAGE:
                continue
            for alias in node.names:
                full = f"{module}.{alias.name}"
                yield _known(full if full in mods else module, mods), alias.name, node.lineno


def _known(module: str, mods: dict[str, Path]) -> str:
    while module not in mods and "." in module:
        module = module.rsplit(".", 1)[0]
    return module


def strongly_connected(edges: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's algorithm, iteratively: the components of two or more nodes."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out = []
    for start in sorted(edges):
        if start in index:
            continue
        work = [(start, iter(sorted(edges[start])))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(edges.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    out.append(sorted(component))
    return out


def largest_functions(mods: dict[str, Path], count: int) -> list[tuple[int, str]]:
    sizes = []
    for path in mods.values():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                sizes.append((node.end_lineno - node.lineno + 1,
                              f"{path.relative_to(ROOT)}:{node.lineno} {node.name}"))
    return sorted(sizes, reverse=True)[:count]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--all", action="store_true", help="every cycle and private import")
    args = ap.parse_args()
    mods = modules(ROOT / PACKAGE)
    edges: dict[str, set[str]] = collections.defaultdict(set)
    private, facade = [], []
    for name, path in mods.items():
        edges[name]
        for target, imported, line in imports(name, path, mods):
            where = f"{path.relative_to(ROOT)}:{line}"
            if target == PACKAGE:            # the facade: a leaf reaching up to the top
                facade.append(f"{where} {imported}")
                continue
            if target == name:
                continue
            edges[name].add(target)
            if imported.startswith("_") and not imported.startswith("__"):
                private.append(f"{where} {imported} from {target}")
    cycles = strongly_connected(edges)
    lines = sorted(((sum(1 for _ in p.open(encoding="utf-8")), str(p.relative_to(ROOT)))
                    for p in mods.values()), reverse=True)
    show = None if args.all else 12
    print(f"modules                        {len(mods)}")
    print(f"import cycles                  {len(cycles)}")
    for c in cycles[:show]:
        print("  " + " <-> ".join(m.removeprefix(PACKAGE + ".") for m in c))
    print(f"private names across modules   {len(private)}")
    for p in private[:show]:
        print("  " + p)
    print(f"imports of the package facade  {len(facade)}")
    for p in facade[:show]:
        print("  " + p)
    print("largest files (lines)          " + ", ".join(f"{f} {n}" for n, f in lines[:5]))
    print("largest functions (lines)")
    for n, f in largest_functions(mods, 5):
        print(f"  {n:5d} {f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
