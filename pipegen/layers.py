"""The package's architecture as data, and the import rule that keeps it (docs/internals.md).

Every folder under ``pipegen/`` is a stage, and the stages stand in layers, bottom to top::

    core -> ir -> packing -> frontend | passes | scene -> reference -> views -> backends
         -> runtime -> compiler -> proof -> tools | testing -> cli

**The rule.**  A module imports (at module level, inside a function or under
``TYPE_CHECKING``: all count) only from its own folder or from an earlier layer.  Folders on one
layer (``frontend``, ``passes``, ``scene``; ``tools``, ``testing``) never import each other.  No name starting with
``_`` crosses modules, neither imported nor read as ``module._name``.  No module imports the
package facade (``pipegen/__init__.py``), which sits above everything with ``__main__`` and this
file.  The only imports by string are the backend registry's (emitters and runtimes named as
data, so that compiling never imports moderngl or pyopencl); the facades that give names on
first use import them with plain statements (``core/lazy.py``).  And no
two modules import each other, through any chain: the import graph has no strongly connected
component.  Two more walls: the runtimes and the float64 reference never import each other
(though ``reference`` is below ``runtime``: a bug in one must not hide in the other), and
moderngl, PyOpenGL and pyopencl are imported in ``runtime/`` only (compiling works on any
machine).

``violations(package_dir)`` lists every breach as ``file:line: what``; tests/test_layers.py
holds the package to an empty list and plants breaches in a copy to show each one is caught;
``benchmarks/structure.py`` prints the figures.  This module imports nothing from pipegen.
"""

from __future__ import annotations

import ast
from pathlib import Path
from typing import Iterator, NamedTuple

PACKAGE = "pipegen"

LAYERS: tuple[tuple[str, ...], ...] = (
    ("core",),
    ("ir",),
    ("packing",),
    ("frontend", "passes", "scene"),
    ("reference",),
    ("views",),
    ("backends",),
    ("runtime",),
    ("compiler",),
    ("proof",),
    ("tools", "testing"),
    ("cli",),
)

# modules outside the layers: the facade, ``python -m pipegen`` and this description
ABOVE_ALL = {PACKAGE, f"{PACKAGE}.__main__", f"{PACKAGE}.layers"}

# the modules allowed to import by string (importlib.import_module, __import__)
STRING_IMPORTERS = {f"{PACKAGE}.backends.registry"}

# folders that never import each other, whatever their layers
APART = {("runtime", "reference"), ("reference", "runtime")}

# the libraries that need a GL or OpenCL driver, and the folder that alone may import them
DEVICE_LIBRARIES = ("moderngl", "OpenGL", "pyopencl")
DEVICE_FOLDER = "runtime"

LAYER_OF = {folder: k for k, folders in enumerate(LAYERS) for folder in folders}


class Import(NamedTuple):
    target: str        # the pipegen module imported (or whose name is imported)
    name: str          # the name bound: a module's last part or an imported attribute
    line: int


def modules(package_dir: Path) -> dict[str, Path]:
    """Dotted module name -> file, for every ``.py`` file under ``package_dir``."""
    out = {}
    for path in sorted(package_dir.rglob("*.py")):
        name = ".".join(path.relative_to(package_dir.parent).with_suffix("").parts)
        out[name.removesuffix(".__init__")] = path
    return out


def _known(module: str, mods: dict[str, Path]) -> str:
    while module not in mods and "." in module:
        module = module.rsplit(".", 1)[0]
    return module


def imports(name: str, tree: ast.AST, is_package: bool, mods: dict[str, Path]) -> Iterator[Import]:
    """Every import of a package module in ``tree`` (module ``name``), wherever it stands."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == PACKAGE:
                    yield Import(_known(alias.name, mods), alias.name.rsplit(".", 1)[-1],
                                 node.lineno)
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
                yield Import(_known(full if full in mods else module, mods), alias.name,
                             node.lineno)


def _module_aliases(tree: ast.AST, mods: dict[str, Path]) -> set[str]:
    """Local names bound to package modules (``from pipegen.ir import nodes as ir``)."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and \
                node.module.split(".")[0] == PACKAGE:
            for alias in node.names:
                if f"{node.module}.{alias.name}" in mods:
                    out.add(alias.asname or alias.name)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.asname and alias.name.split(".")[0] == PACKAGE:
                    out.add(alias.asname)
    return out


def _device_imports(tree: ast.AST) -> Iterator[tuple[int, str]]:
    for node in ast.walk(tree):
        names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                 [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level
                 else [])
        for name in names:
            if name.split(".")[0] in DEVICE_LIBRARIES:
                yield node.lineno, name.split(".")[0]


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def layer(module: str) -> str | None:
    """The folder (``"ir"``, ``"runtime"``…) a module belongs to; None above the layers."""
    if module in ABOVE_ALL:
        return None
    return module.split(".")[1]


def graph(package_dir: Path) -> tuple[dict[str, Path], dict[str, set[str]]]:
    """The modules and the import graph between them (module -> modules it imports)."""
    mods = modules(package_dir)
    edges: dict[str, set[str]] = {name: set() for name in mods}
    for name, path in mods.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for imp in imports(name, tree, path.name == "__init__.py", mods):
            if imp.target != name:
                edges[name].add(imp.target)
    return mods, edges


def violations(package_dir: Path) -> list[str]:
    """Every breach of the rule in the package at ``package_dir``, as ``file:line: what``."""
    mods = modules(package_dir)
    root = package_dir.parent
    out = []
    edges: dict[str, set[str]] = {name: set() for name in mods}
    for name, path in mods.items():
        where = str(path.relative_to(root))
        tree = ast.parse(path.read_text(encoding="utf-8"))
        mine = layer(name)
        for imp in imports(name, tree, path.name == "__init__.py", mods):
            at = f"{where}:{imp.line}"
            if imp.target == name:
                continue
            edges[name].add(imp.target)
            if imp.target == PACKAGE and name != PACKAGE:
                out.append(f"{at}: imports the package facade ({imp.name}); import the module "
                           f"that defines it")
                continue
            if _private(imp.name):
                out.append(f"{at}: imports the private name {imp.name} from {imp.target}")
            theirs = layer(imp.target)
            if mine is None or theirs is None or theirs == mine:
                continue
            if (mine, theirs) in APART:
                out.append(f"{at}: {mine}/ imports {imp.target}; {mine}/ and {theirs}/ never "
                           f"import each other")
            elif theirs not in LAYER_OF or mine not in LAYER_OF:
                unknown = theirs if theirs not in LAYER_OF else mine
                out.append(f"{at}: folder {unknown!r} is in no layer (pipegen/layers.py)")
            elif LAYER_OF[theirs] == LAYER_OF[mine]:
                out.append(f"{at}: {mine}/ imports its sibling {theirs}/ ({imp.target}); "
                           f"folders on one layer never import each other")
            elif LAYER_OF[theirs] > LAYER_OF[mine]:
                out.append(f"{at}: {mine}/ imports {imp.target}, from the later layer "
                           f"{theirs}/")
        if mine != DEVICE_FOLDER:
            for line, lib in _device_imports(tree):
                out.append(f"{where}:{line}: imports {lib} outside {DEVICE_FOLDER}/")
        aliases = _module_aliases(tree, mods)
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and \
                    node.value.id in aliases and _private(node.attr):
                out.append(f"{where}:{node.lineno}: reads the private name "
                           f"{node.value.id}.{node.attr} of another module")
            if isinstance(node, ast.Call) and name not in STRING_IMPORTERS and (
                    (isinstance(node.func, ast.Attribute) and node.func.attr == "import_module")
                    or (isinstance(node.func, ast.Name) and node.func.id == "__import__")):
                out.append(f"{where}:{node.lineno}: imports by string; only the backend "
                           f"registry does")
    for component in strongly_connected(edges):
        out.append(f"{mods[component[0]].relative_to(root)}: import cycle "
                   + " <-> ".join(component))
    return out


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
