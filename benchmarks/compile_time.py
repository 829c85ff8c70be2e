"""Compile time: ``pipegen compile pipelines/X.pipe -o DIR`` as a fresh process, exactly what a
user waits for (interpreter start, imports, parser, lowering, emission, files), and the same
compile repeated inside one process.

    python benchmarks/compile_time.py [--repeat 5] [--parse-only] [technique ...]

Columns, per technique:

- fresh process: best and median wall time of ``--repeat`` runs of ``pipegen compile``, and
  the best CPU time (the best is the figure to compare on a shared machine: other load only
  ever adds time; the runs go in rounds over the techniques, so that a burst of other work
  spoils one run of a technique rather than all of them).  Each is the first compile in its
  process, with the on-disk caches warm (bytecode, parser, syntax trees, compiled templates);
- just edited: the same for a copy of the technique with a new comment each run, what a user
  waits for right after changing a file: its own tree is not cached (the parser is loaded and
  it is parsed), the library's are;
- cold: the first run of all, with the parser, syntax-tree and template caches empty (for the
  first technique listed, the bytecode too);
- in one process: one long-lived process compiles every technique (``compile_file``,
  ``Compiled.write``, the report: what the command does after its imports): the first compile
  of each there, and the best of ``--repeat`` more (warm: what a test run or a sweep pays).

Before the table: the floor of a fresh process (best of ``--repeat``): ``python -c pass``
(interpreter start and the site-packages ``.pth`` hooks of this environment) and the
interpreter with every module a compile imports.  Target (issue 26 item 7): under 0.2 s per
technique.

``--parse-only`` times ``syntax.parse`` of the technique in a fresh process instead;
``--stages`` prints where the time of one ``compile`` goes, in a fresh process (imports, front
end, emission); ``--many-passes`` times ``compile_source`` in this process on forward.pipe with
100, 200 and 400 trivial full-screen passes added and prints how the time grows with the count
(linear: about 2x per doubling).  ``--against TREE`` compares this checkout with another one
(``git worktree add TREE REV``), fresh processes of the two in turn, best of ``--repeat`` each;
``--instructions`` adds each compile's instruction count (valgrind's callgrind), the figure to
compare on a shared machine.

The runs use compiled bytecode, as an installed pipegen does (pip writes the ``.pyc`` files):
``PYTHONDONTWRITEBYTECODE`` is unset and ``PYTHONPYCACHEPREFIX`` points at a temporary folder,
filled by the cold runs, and ``PIPEGEN_CACHE_DIR`` at another (the parser, syntax-tree and
template caches; the user's own cache is left alone).  ``--no-bytecode`` measures with every
module compiled from source in every run instead (``PYTHONDONTWRITEBYTECODE=1`` and no ``.pyc``
anywhere).

Figures (issue 26 item 7), second round.  Before: f7c9dd1; after: fa1ca60.  What changed:
opt_hoist_invariants walks each body once per compile and keeps what it found across its lift
rounds; specialise_params, opt_fold_constants and lower_mix_constant keep the bodies they do
not change as the same objects (passes/bodies.py), so a body's code facts and light-row plans
are worked out once; a body's light-row plan is made once for every pass and both backends
(cstyle.row_plan); the CL wide path stops rendering a pass once its rows gathered lane by lane
rule the wide form out, and keeps what a render learnt of the return; the material layout once
per pass, the report once per compile; build_parser builds only the subcommand named; the
command freezes what its imports built for the collector (gc.freeze); the IR printer is
imported only to word a warning.  The emitted text is unchanged.  (A first round, 6ad8ea5 to
its successor, cut 3-9 %; the techniques have grown since.)

    git worktree add /tmp/before f7c9dd1
    ln -s ../templates /tmp/before/pipegen/templates
    ln -s ../grammar /tmp/before/pipegen/grammar
    LP_NUM_THREADS=2 POCL_MAX_PTHREAD_COUNT=2 python benchmarks/compile_time.py \\
        --against /tmp/before --instructions

Instructions of one ``pipegen compile`` in a fresh process with warm caches (callgrind: a count
the machine's load does not change), in millions, and the best wall time of 5 runs, the two
trees' runs in turn (load average 1.7 before, 3.8 after, from other work: the wall ratios
scatter around the instruction ratios, 0.71-1.10):

    technique            instructions (M)            fresh process, best of 5 (s)
                         before   after            before  after  ratio
    deferred               930.4   836.5  -10.1 %     0.292  0.249   0.85
    deferred_calver       1714.9  1406.5  -18.0 %     0.432  0.360   0.83
    forward               1139.8   894.5  -21.5 %     0.315  0.289   0.92
    forward_multipass      748.7   686.1   -8.4 %     0.239  0.241   1.01
    inferred              1291.0  1115.9  -13.6 %     0.482  0.419   0.87
    lidr_bitplanes        1156.6   903.1  -21.9 %     0.386  0.336   0.87
    lidr_cpu_sort         1269.4   998.8  -21.3 %     0.443  0.361   0.81
    lidr_max_stencil      1161.0   912.2  -21.4 %     0.433  0.368   0.85
    lidr_msaa_texture     1066.2   858.8  -19.5 %     0.367  0.344   0.94
    lidr_nearest_edge     1242.2   951.5  -23.4 %     0.348  0.307   0.88
    lidr_shadow_indexed   1517.5  1095.3  -27.8 %     0.452  0.319   0.71
    lidr_shadow_prepass   1922.4  1345.8  -30.0 %     0.513  0.420   0.82
    lidr_shadow_volumes   1169.4   914.8  -21.8 %     0.263  0.219   0.83
    lidr_transparent      1562.5  1154.1  -26.1 %     0.551  0.440   0.80
    light_prepass         1010.9   884.1  -12.5 %     0.328  0.362   1.10

Every technique runs 8-30 % fewer instructions (21 % fewer in all).  The floor: ``python -c
pass`` 144 M; the interpreter with every module a compile imports (``import pipegen.cli.main,
pipegen.compiler.driver, pipegen.backends.glsl, pipegen.backends.opencl.emit,
pipegen.backends.templating``) 436 M before, 438 M after: jinja2 87 M of it, the standard
library's modules 62 M, pipegen's own about 145 M (ir/nodes.py 38 M and frontend/ast.py 21 M,
their ~130 record classes going through ``dataclass``).

Third round, be3f10a -> c14b4b1 (``--against`` as above, ``--repeat 5``, all 15 techniques,
load 1.0-2.7): the wide emitter keeps the user functions it specialised for one pass for the
technique's other passes, and eight frozen classes of the IR's layouts, lifetimes and traffic
are records.  Instructions 2-7 % fewer (deferred_calver 1408.7 -> 1309.2 M, lidr_shadow_prepass
1387.0 -> 1300.2 M, light_prepass 887.2 -> 836.7 M, lidr_shadow_volumes 945.1 -> 921.6 M);
wall ratios 0.81-1.13 on the loaded machine.  The emitted text is unchanged.

The 0.2 s target is still not met by a fresh process: here today ``python -c pass`` takes
0.05-0.08 s and the imports bring it to 0.16-0.19 s, so a compile would have to stay within
about 100 M instructions beyond the imports' 438 M, where it takes 250-970 M.  A warm compile
in one process meets it (0.19 s at most, deferred_calver).  What is left: the walks over the
IR (ir/walk.py's ``child_exprs`` and what is built on it: the light-row plans, the code facts,
the verifier, the passes) are the largest single cost, then the two emitters' per-node Python;
core/records.py's classes still go through ``dataclass`` at import; core/outdir.py hashes each
output four times (the folder checks before and while writing, the staged file, the file it
replaces: 35 M of forward's 900 M), which is what keeps it from overwriting a file someone
changed, so it was left as it is.

Fourth round (2026-12-04), 3405f3f: each record class's compiled ``__init__`` is kept in the
user's cache folder (``core/code_cache.py``) instead of compiled again by every process.
``--against`` the tree before, ``--instructions --repeat 5``: deferred_calver 1245.2 -> 1227.6
M instructions, best of 5 0.254 -> 0.249 s; lidr_shadow_prepass 1221.8 -> 1202.0 M, 0.249 ->
0.242 s.  The whole table then (``--repeat 5``, load 0.7, ``python -c pass`` 0.044 s, the
compile's imports 0.120 s): twelve techniques 0.148-0.199 s, three over 0.2 s
(deferred_calver 0.229, lidr_shadow_prepass 0.221, lidr_shadow_indexed 0.206).  Where a fresh
compile of deferred_calver goes (py-spy, 12 runs, 11,494 samples at 2 kHz): imports 55 % of
the samples (jinja2 15 %, the bytecode of ~250 modules 10 %: pipegen's 1.17 MB of ``.pyc``,
the standard library's 0.81, jinja2's 0.66), the front end 14 %, emission 18 % (the CL wide
fragment code 5 %, template rendering 8 %).  A collector paused while a cached syntax tree
is unpickled (5 ms against 11-17 ms in a process that had compiled once) changed nothing
measurable in the whole compile (the collections come after it instead) and was not kept.

Fifth round (2026-12-04, evening), 9286064 -> d72a0db: ``walk.child_exprs`` keeps each IR
node's operands on the node once worked out and reads only the fields declared to hold
expressions; ``pyrepr`` builds each plan container's one-line text once; ``records.replace``
copies a record's fields without ``__init__``.  ``--against`` the tree before,
``--instructions --repeat 5`` (load 1.0-1.4), instructions in millions and the best wall time:

    technique            before    after            before  after
    deferred              788.5    768.1  -2.6 %     0.128  0.126
    deferred_calver      1229.4   1131.1  -8.0 %     0.166  0.166
    forward               837.6    780.4  -6.8 %     0.131  0.128
    forward_multipass     653.1    639.6  -2.1 %     0.113  0.112
    inferred              985.9    926.8  -6.0 %     0.139  0.135
    lidr_bitplanes        857.3    807.8  -5.8 %     0.142  0.136
    lidr_cpu_sort         945.2    884.0  -6.5 %     0.146  0.144
    lidr_max_stencil      863.0    811.8  -5.9 %     0.145  0.150
    lidr_msaa_texture     786.7    744.9  -5.3 %     0.133  0.130
    lidr_nearest_edge     869.0    812.8  -6.5 %     0.137  0.135
    lidr_shadow_indexed  1039.7    957.3  -7.9 %     0.170  0.166
    lidr_shadow_prepass  1204.7   1097.7  -8.9 %     0.169  0.165
    lidr_shadow_volumes   870.1    820.6  -5.7 %     0.142  0.137
    lidr_transparent     1035.6    958.7  -7.4 %     0.170  0.168
    light_prepass         794.7    764.3  -3.8 %     0.144  0.138

The whole table right after (the runs now in rounds over the techniques, load 1.2-1.8,
``python -c pass`` 0.036 s, the imports 0.098 s): 0.110-0.162 s best of 5 (lidr_shadow_prepass
0.162, deferred_calver 0.160), every technique under the 0.2 s target.  The tree before had
taken 0.134-0.201 s in the run of this script 35 minutes earlier: the machine's drift moved
the wall times more than the change did.  Tried and not kept, for no fewer instructions: the
collector's young generation at 20,000 allocations in the command's own process (62 of a
compile's collections gone, no wall time saved in fresh processes), each frozen record's
hash kept on it, each statement's parts and nested bodies kept on it for ``walk_exprs`` and
``walk_stmts``, a stack instead of nested generators in ``_walk_expr``.  Then e7aa776:
``rewrite_expr`` reads the declared expression fields too (``--against`` bbaaa86,
``--instructions --repeat 3``): deferred_calver 1131.5 -> 1117.8 M, lidr_shadow_prepass
1098.2 -> 1081.9 M, forward 781.4 -> 765.0 M.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ALL = sorted(p.stem for p in (ROOT / "pipelines").glob("*.pipe"))
TARGET = 0.2            # seconds, every shipped technique (issue 26 item 7)


def _pipegen_command() -> list[str]:
    """The installed ``pipegen`` script next to this interpreter, else ``python -m``."""
    script = Path(sys.executable).with_name("pipegen")
    if script.exists():
        return [str(script)]
    return [sys.executable, "-m", "pipegen.cli"]


def time_run(cmd: list[str], env: dict, cwd: Path = ROOT) -> tuple[float, float]:
    """(wall, CPU) seconds of one run; the CPU time (user + system of the child) is the steadier
    figure on a machine other work shares."""
    cpu0 = _children_cpu()
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                          text=True, env=env)
    elapsed = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{proc.stderr}")
    return elapsed, _children_cpu() - cpu0


def _children_cpu() -> float:
    try:
        import resource
    except ImportError:        # Windows: no CPU figure
        return 0.0
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


STAGES = r"""
import sys, time
T = [("start", time.perf_counter(), time.process_time())]
def mark(name): T.append((name, time.perf_counter(), time.process_time()))
import jinja2; mark("import jinja2")
from pipegen.cli import parser as cli, technique_args; mark("import pipegen.cli.main (rest)")
argv = ["compile", sys.argv[1], "-o", sys.argv[2], "--force"]
args = cli.build_parser(argv[0]).parse_args(argv); mark("cli.build_parser + parse_args")
from pipegen.core.outdir import OutputDir
out = OutputDir(args.out, "compile", args.force); mark("output folder checked")
import pipegen.compiler.driver; mark("import pipegen.compiler.driver (rest)")
c = technique_args.compile_from_args(args); mark("parse (or load trees), lower, phases")
c.write(out, ("gl", "cl"), args.size); mark("emit GL + CL, write files")
c.report(args.size); mark("report")
print(f"  {'stage':<34} {'wall ms':>8} {'CPU ms':>7}")
for (_, w0, c0), (name, w1, c1) in zip(T, T[1:]):
    print(f"  {name:<34} {1000 * (w1 - w0):8.1f} {1000 * (c1 - c0):7.1f}")
print(f"  {'total (after interpreter start)':<34} {1000 * (T[-1][1] - T[0][1]):8.1f} "
      f"{1000 * (T[-1][2] - T[0][2]):7.1f}")
print("  imported: numpy", "yes" if "numpy" in sys.modules else "no", "| lark",
      "yes" if "lark" in sys.modules else "no", "| parser loaded:",
      "yes" if "pipegen.frontend.syntax_tree" in sys.modules and
      sys.modules["pipegen.frontend.syntax_tree"].lalr_parser.cache_info().currsize
      else "no (every syntax tree was cached)")
"""


WARM = r"""
import json, sys, tempfile, time
T0 = time.perf_counter()
from pipegen.compiler.driver import compile_file
from pipegen.core.outdir import OutputDir
import pipegen.backends.glsl, pipegen.backends.opencl.emit, pipegen.backends.templating
imports = time.perf_counter() - T0
repeat, names = int(sys.argv[1]), sys.argv[2:]
tmp = tempfile.mkdtemp(prefix="pipegen-warm-")
def one(name, tag):
    # what `pipegen compile` does after its imports: compile, write the folder, the report
    t = time.perf_counter()
    c = compile_file(f"pipelines/{name}.pipe")
    c.write(OutputDir(f"{tmp}/{name}{tag}", "compile", True), ("gl", "cl"), None)
    c.report((1280, 720))
    return time.perf_counter() - t
out = {"imports": imports}
for name in names:
    first = one(name, "first")
    out[name] = (first, min(one(name, str(i)) for i in range(repeat)))
print(json.dumps(out))
"""


def in_process(names: list[str], repeat: int, env: dict) -> dict:
    """One process compiles every technique: for each its first compile there (the compile
    code and templates already loaded by the techniques before it, except for the first)
    and the best of ``repeat`` more (warm: what a test run or a sweep pays per compile)."""
    import json
    proc = subprocess.run([sys.executable, "-c", WARM, str(repeat), *names], cwd=ROOT,
                          env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"in-process compile failed:\n{proc.stderr}")
    return json.loads(proc.stdout)


def floor(env: dict, repeat: int) -> tuple[float, float]:
    """Best of ``repeat`` fresh processes: the interpreter alone (``python -c pass``: its
    start-up and site-packages' ``.pth`` hooks) and the interpreter with every module a
    compile imports; what is left of a compile's time is the compile's own work."""
    imports = ("import pipegen.cli.main, pipegen.compiler.driver, pipegen.backends.glsl, "
               "pipegen.backends.opencl.emit, pipegen.backends.templating")
    bare = min(time_run([sys.executable, "-c", "pass"], env)[0] for _ in range(repeat))
    loaded = min(time_run([sys.executable, "-c", imports], env)[0] for _ in range(repeat))
    return bare, loaded


def many_passes(repeat: int) -> int:
    """Best of ``repeat`` in-process compiles of forward.pipe plus N trivial passes."""
    sys.path.insert(0, str(ROOT))
    from pipegen.compiler.driver import compile_source
    forward = (ROOT / "pipelines" / "forward.pipe").read_text()
    path = str(ROOT / "pipelines" / "forward.pipe")
    best = {}
    print(f"{'passes added':>12} {'best s':>8} {'x previous':>10}")
    for n in (100, 200, 400):
        extra = "".join(f"\npass extra{k} {{ draw fullscreen writes color "
                        f"fragment {{ color = vec4(float({k}) * 0.001); }} }}" for k in range(n))
        times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            compile_source(forward + extra, path)
            times.append(time.perf_counter() - t0)
        best[n] = min(times)
        ratio = f"{best[n] / best[n // 2]:10.2f}" if n // 2 in best else f"{'':10}"
        print(f"{n:12d} {best[n]:8.3f} {ratio}")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--parse-only", action="store_true",
                    help="time `import pipegen.frontend.parse; parse(file)` in a fresh process")
    ap.add_argument("--stages", action="store_true",
                    help="where the time of one compile goes (after the timed runs)")
    ap.add_argument("--no-bytecode", action="store_true",
                    help="compile every module from source in every run")
    ap.add_argument("--many-passes", action="store_true",
                    help="compile time against the number of passes (in this process)")
    ap.add_argument("--against", metavar="TREE",
                    help="compare with another checkout (git worktree add TREE REV): fresh "
                         "processes of the two run in turn")
    ap.add_argument("--instructions", action="store_true",
                    help="with --against: also count each compile's instructions (valgrind)")
    ap.add_argument("techniques", nargs="*", default=ALL)
    args = ap.parse_args()
    if args.many_passes:
        return many_passes(args.repeat)
    if args.against:
        return against(Path(args.against).resolve(), args.techniques, args.repeat,
                       args.instructions)

    base = _pipegen_command()
    print(f"load average before: {_load()}")
    with tempfile.TemporaryDirectory(prefix="pipegen-bench-") as tmp:
        env = dict(os.environ)
        if args.no_bytecode:
            env["PYTHONDONTWRITEBYTECODE"] = "1"
            env["PYTHONPYCACHEPREFIX"] = f"{tmp}/no-pycache"
        else:
            env.pop("PYTHONDONTWRITEBYTECODE", None)
            env["PYTHONPYCACHEPREFIX"] = f"{tmp}/pycache"
        env["PIPEGEN_CACHE_DIR"] = f"{tmp}/cache"     # the parser, trees, templates: our own
        edited = Path(tmp) / "edited"
        edited.mkdir()
        # One run per technique, and one of an edited copy: writes the bytecode and fills the
        # parser cache and the syntax-tree cache (what a user pays once: "cold" below; the
        # first technique's run also writes the bytecode and the template cache).
        cold = {}
        for name in args.techniques:
            cold[name] = time_run(base + ["compile", f"pipelines/{name}.pipe", "-o",
                                          f"{tmp}/warm"], env)[0]
            time_run(base + ["compile", _edit(name, edited, "warm"), "-o", f"{tmp}/warm"], env)
        bare, loaded = floor(env, args.repeat)
        print(f"fresh process, best of {args.repeat}: `python -c pass` {bare:.3f} s, with the "
              f"compile's imports {loaded:.3f} s")
        warm = {} if args.parse_only else in_process(args.techniques, args.repeat, env)
        worst = worst_edited = worst_warm = 0.0
        # in rounds, each technique once per round (a fresh run, then an edited one): a burst
        # of other work on the shared machine then spoils one run of a technique, not all of
        # its runs, and the best of them is the machine's unloaded figure
        runs: dict[str, list] = {name: [] for name in args.techniques}
        edits: dict[str, list] = {name: [] for name in args.techniques}
        from tqdm import tqdm
        bar = tqdm(total=args.repeat * len(args.techniques), file=sys.stderr, unit="technique",
                   desc="rounds", leave=False)
        for i in range(args.repeat):
            for name in args.techniques:
                bar.update()
                if args.parse_only:
                    cmd = [sys.executable, "-c", "import sys; from pipegen.frontend.parse import "
                           "parse; parse(open(sys.argv[1]).read(), sys.argv[1])",
                           f"pipelines/{name}.pipe"]
                else:
                    cmd = base + ["compile", f"pipelines/{name}.pipe", "-o", f"{tmp}/{name}"]
                runs[name].append(time_run(cmd, env))
                # the technique as the user just changed it: its own syntax tree is not cached
                # yet (the parser is loaded and the file parsed), its includes' trees are
                edits[name].append(time_run(base + ["compile", _edit(name, edited, str(i)), "-o",
                                                   f"{tmp}/{name}-edited"], env)[0])
        bar.close()
        print(f"{'':<20} {'fresh process (pipegen compile)':^31}   {'just edited':^18}   "
              f"{'cold':>6}   {'in one process':^17}")
        print(f"{'technique':<20} {'best s':>7} {'median s':>9} {'best CPU s':>11}   "
              f"{'best s':>8} {'median s':>9}   {'s':>6}   {'first s':>8} {'warm s':>8}")
        for name in args.techniques:
            times = [wall for wall, _ in runs[name]]
            worst = max(worst, min(times))
            worst_edited = max(worst_edited, min(edits[name]))
            first, best_warm = warm.get(name, (float("nan"), float("nan")))
            worst_warm = max(worst_warm, best_warm)
            print(f"{name:<20} {min(times):>7.3f} {statistics.median(times):>9.3f} "
                  f"{min(cpu for _, cpu in runs[name]):>11.3f}   {min(edits[name]):>8.3f} "
                  f"{statistics.median(edits[name]):>9.3f}   {cold[name]:>6.3f}   {first:>8.3f} "
                  f"{best_warm:>8.3f}")
        print(f"slowest technique, fresh process (best of {args.repeat}): {worst:.3f} s "
              f"({'meets' if worst < TARGET else 'misses'} the {TARGET} s target); just "
              f"edited: {worst_edited:.3f} s; warm in one process: {worst_warm:.3f} s "
              f"({'meets' if worst_warm < TARGET else 'misses'} it)")
        print(f"load average after: {_load()}")
        if args.stages:
            name = args.techniques[0]
            print(f"stages of one compile of {name} (in-process, bytecode cached):")
            subprocess.run([sys.executable, "-c", STAGES, f"pipelines/{name}.pipe",
                            f"{tmp}/stages"], cwd=ROOT, env=env, check=True)
    return 0


def against(tree: Path, names: list[str], repeat: int, instructions: bool) -> int:
    """``pipegen compile`` of each technique as a fresh process, by this checkout and by
    ``tree`` in turn (so that the machine's drift falls on both alike): best wall and CPU
    times of ``repeat`` runs each and their ratios; with ``instructions`` also the
    instructions of one compile each (callgrind: a count the machine's load does not
    change).  Each tree runs as ``python -m pipegen.cli`` (from a folder of neither, so that
    PYTHONPATH picks the tree) with its own bytecode and caches, warmed first; both compile
    this checkout's ``pipelines/``."""
    for folder in ("templates", "grammar"):
        if not (tree / "pipegen" / folder).exists():
            # the editable install maps pipegen.templates to this checkout's folder
            raise SystemExit(f"{tree}/pipegen/{folder} is missing: ln -s ../{folder} "
                             f"{tree}/pipegen/{folder}")
    if instructions and shutil.which("valgrind") is None:
        raise SystemExit("--instructions needs valgrind")
    trees = {"this": ROOT, "other": tree}
    with tempfile.TemporaryDirectory(prefix="pipegen-against-") as tmp:
        envs = {}
        for label, root in trees.items():
            env = dict(os.environ, PYTHONPATH=str(root), PYTHONPYCACHEPREFIX=f"{tmp}/pyc-{label}",
                       PIPEGEN_CACHE_DIR=f"{tmp}/cache-{label}")
            env.pop("PYTHONDONTWRITEBYTECODE", None)
            envs[label] = env

        def cmd(label: str, name: str) -> list[str]:
            return [sys.executable, "-m", "pipegen.cli", "compile",
                    str(ROOT / "pipelines" / f"{name}.pipe"), "-o", f"{tmp}/{label}-{name}"]

        def run(label: str, name: str) -> tuple[float, float]:
            return time_run(cmd(label, name), envs[label], cwd=Path(tmp))

        for name in names:                    # bytecode, parser, trees, templates
            for label in trees:
                run(label, name)
        print(f"this checkout: {ROOT}; other: {tree}; load average before: {_load()}")
        print(f"{'technique':<20} {'other s':>8} {'this s':>7} {'ratio':>6}   {'other CPU':>9} "
              f"{'this CPU':>8} {'ratio':>6}" + ("   other M   this M   ratio" if instructions
                                                  else ""))
        for name in names:
            runs: dict[str, list] = {label: [] for label in trees}
            for _ in range(repeat):
                for label in trees:
                    runs[label].append(run(label, name))
            (ow, oc), (tw, tc) = ((min(w for w, _ in runs[k]), min(c for _, c in runs[k]))
                                  for k in ("other", "this"))
            line = f"{name:<20} {ow:8.3f} {tw:7.3f} {tw / ow:6.2f}   {oc:9.3f} {tc:8.3f} " \
                   f"{tc / oc:6.2f}"
            if instructions:
                oi, ti = (_instructions(cmd(k, name), envs[k], Path(tmp)) / 1e6
                          for k in ("other", "this"))
                line += f"   {oi:7.1f}  {ti:7.1f}  {ti / oi:6.2f}"
            print(line)
        print(f"load average after: {_load()}")
    return 0


def _instructions(cmd: list[str], env: dict, cwd: Path) -> int:
    """Instructions one run of ``cmd`` executes (valgrind's callgrind)."""
    proc = subprocess.run(["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null",
                           *cmd], cwd=cwd, env=env, capture_output=True, text=True)
    found = re.search(r"Collected : (\d+)", proc.stderr)
    if proc.returncode != 0 or found is None:
        raise SystemExit(f"valgrind {' '.join(cmd)} failed:\n{proc.stderr[-2000:]}")
    return int(found.group(1))


def _edit(name: str, folder: Path, tag: str) -> str:
    """A copy of technique ``name`` with a comment added (text no compile has seen before)."""
    path = folder / f"{name}-{tag}-{os.getpid()}-{time.time_ns()}.pipe"
    path.write_text((ROOT / "pipelines" / f"{name}.pipe").read_text()
                    + f"\n// edited {time.time_ns()}\n")
    return str(path)


def _load() -> str:
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg()) + f" ({os.cpu_count()} CPUs)"
    except OSError:
        return "unknown"


if __name__ == "__main__":
    sys.exit(main())
