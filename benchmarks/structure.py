"""The package's structure in figures: modules, import cycles, private names used across
modules, breaches of the layer rule, and the largest files and functions (issue 23: the
before and after of the house).

    python benchmarks/structure.py                    # the working tree
    python benchmarks/structure.py --before 7053330   # a commit's package beside it
    python benchmarks/structure.py --all              # every cycle and every breach

Every import counts, wherever it stands: at module level, inside a function, or under
``TYPE_CHECKING`` (an import that closes a loop from inside a function is a cycle all the
same).  A cycle is a strongly connected component of two or more modules.  The rule and its
reader are ``pipegen/layers.py``; a commit from before the layers has no folders to place, so
its "layer breaches" count only the rule's other parts.
"""

from __future__ import annotations

import argparse
import ast
import subprocess
import sys
import tarfile
import tempfile
from io import BytesIO
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pipegen import layers  # noqa: E402


def measure(package_dir: Path) -> dict:
    mods, edges = layers.graph(package_dir)
    root = package_dir.parent
    private, facade = [], []
    for name, path in mods.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for imp in layers.imports(name, tree, path.name == "__init__.py", mods):
            where = f"{path.relative_to(root)}:{imp.line}"
            if imp.target == layers.PACKAGE and name != layers.PACKAGE:
                facade.append(f"{where} {imp.name}")
            elif imp.target != name and imp.name.startswith("_") and \
                    not imp.name.startswith("__"):
                private.append(f"{where} {imp.name} from {imp.target}")
    breaches = [v for v in layers.violations(package_dir)
                if "is in no layer" not in v and "import cycle" not in v]
    sizes = sorted(((sum(1 for _ in p.open(encoding="utf-8")), str(p.relative_to(root)))
                    for p in mods.values()), reverse=True)
    functions = []
    for path in mods.values():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                functions.append((node.end_lineno - node.lineno + 1,
                                  f"{path.relative_to(root)}:{node.lineno} {node.name}"))
    return {"modules": len(mods), "cycles": layers.strongly_connected(edges),
            "private": private, "facade": facade, "breaches": breaches,
            "files": sizes[:5], "functions": sorted(functions, reverse=True)[:5]}


def package_at(rev: str, into: Path) -> Path:
    """The ``pipegen/`` folder of commit ``rev``, extracted under ``into``."""
    data = subprocess.run(["git", "archive", "--format=tar", rev, "pipegen"], cwd=ROOT,
                          check=True, capture_output=True).stdout
    with tarfile.open(fileobj=BytesIO(data)) as tar:
        tar.extractall(into, filter="data")
    return into / "pipegen"


def report(title: str, m: dict, show: int | None) -> None:
    print(f"== {title}")
    print(f"modules                        {m['modules']}")
    print(f"import cycles                  {len(m['cycles'])}")
    for c in m["cycles"][:show]:
        print("  " + " <-> ".join(x.removeprefix("pipegen.") for x in c))
    print(f"private names across modules   {len(m['private'])}")
    for p in m["private"][:show]:
        print("  " + p)
    print(f"imports of the package facade  {len(m['facade'])}")
    for p in m["facade"][:show]:
        print("  " + p)
    print(f"breaches of the layer rule     {len(m['breaches'])}")
    for p in m["breaches"][:show]:
        print("  " + p)
    print("largest files (lines)")
    for n, f in m["files"]:
        print(f"  {n:5d} {f}")
    print("largest functions (lines)")
    for n, f in m["functions"]:
        print(f"  {n:5d} {f}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--before", metavar="REV", help="also measure pipegen/ at this commit")
    ap.add_argument("--all", action="store_true", help="every cycle and breach")
    args = ap.parse_args()
    show = None if args.all else 12
    if args.before:
        with tempfile.TemporaryDirectory() as tmp:
            report(f"before ({args.before})", measure(package_at(args.before, Path(tmp))),
                   show)
        print()
    report("now (working tree)", measure(ROOT / "pipegen"), show)
    return 0


if __name__ == "__main__":
    sys.exit(main())
