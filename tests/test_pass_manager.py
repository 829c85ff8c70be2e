"""The pass manager (issue 23): pipelines are data run in order, fixpoint groups settle or fail
naming themselves, the verifier runs after each pass, ``pipegen compile --dump-after`` prints
the IR between passes (``ir/printer.py``, which prints every node kind), and passes never call
passes (``spec_shadows`` only folds the shadow tiles; dead code and unread reads are passes of
their own)."""

from __future__ import annotations

import ast
import dataclasses
import subprocess
import sys
import typing
from pathlib import Path

import pytest

from pipegen.compiler.driver import compile_file, compile_source
from pipegen.compiler.specialise import clear_cache
from pipegen.frontend import parse as syntax
from pipegen.ir import nodes as ir
from pipegen.ir.printer import expr, print_technique, statement
from pipegen.passes import opt_dead_code, opt_unread_reads, pipelines
from pipegen.passes.manager import (
    ALL, Fixpoint, InternalError, Pass, Watch, pass_names, run_pipeline)
from pipegen.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted((ROOT / "pipelines").glob("*.pipe"))
FORWARD = ROOT / "pipelines/forward.pipe"
SMALL = ROOT / "examples/scenes/small.toml"        # point lights only, no shadows

TINY = """
technique tiny "one pass"
target color : rgba8 clear 0
target extra : rgba8 clear 0
output color
pass fill { draw fullscreen writes extra fragment { extra = vec4(0.5); } }
pass shade { draw fullscreen reads extra writes color
             fragment { color = load(extra) * 2.0; } }
"""


def tiny() -> ir.Technique:
    return compile_source(TINY).technique


def retitle(suffix: str):
    def run(tech):
        return dataclasses.replace(tech, title=tech.title + suffix)
    return run


# ---- pipelines are data, run in order ----------------------------------------------------------


def test_a_pipeline_runs_its_passes_in_order_and_records_them():
    seen = []

    def step(name):
        def run(tech):
            seen.append(name)
            return tech
        return Pass(name, run)
    pipeline = (step("a"), step("b"), ("c", step("c").run), step("a"))
    out, ran = run_pipeline(pipeline, tiny())
    assert seen == ran == ["a", "b", "c", "a"]
    assert pass_names(pipeline) == ["a", "b", "c"]


def scene_run(names: list[str]) -> bool:
    """Whether ``names`` is one run of ``pipelines.SCENE``: its passes in order, each fixpoint
    group's passes repeated whole one or more times."""
    rest = list(names)
    for step in pipelines.SCENE:
        group = [p.name for p in step.steps] if isinstance(step, Fixpoint) else [step.name]
        rounds = 0
        while rest[:len(group)] == group and (rounds == 0 or isinstance(step, Fixpoint)):
            rest, rounds = rest[len(group):], rounds + 1
        if rounds == 0:
            return False
    return not rest


def test_the_compiler_pipelines_are_data():
    for pipeline in (pipelines.GENERAL, pipelines.SCENE):
        assert isinstance(pipeline, tuple)
        assert all(isinstance(s, (Pass, Fixpoint)) for s in pipeline)
    assert pass_names(pipelines.GENERAL) == ["specialise", "fold", "prune", "hoist"]
    assert compile_file(FORWARD).phases_run == ["lower", "validate", "specialise", "fold",
                                                "prune", "hoist"]
    clear_cache()
    special = compile_file(FORWARD, scene=load_scene(SMALL))
    runs = special.phases_run
    start = runs.index("assume_scene") + 1
    assert scene_run(runs[start:]), runs
    assert not scene_run(runs[start - 1:]) and not scene_run(runs[start:-1])   # it can fail


def test_a_fixpoint_group_stops_when_nothing_changes():
    def shorten(tech):                 # drops a character until the title is 3 long
        return dataclasses.replace(tech, title=tech.title[:-1]) if len(tech.title) > 3 else tech
    group = Fixpoint("shrink", (Pass("shorten", shorten), Pass("same", lambda t: t)), cap=10)
    out, ran = run_pipeline((group,), dataclasses.replace(tiny(), title="abcdef"))
    assert out.title == "abc"
    # three rounds change the title, the fourth finds nothing to do
    assert ran == ["shorten", "same"] * 4


def test_a_fixpoint_group_that_never_settles_is_an_internal_error_naming_it():
    group = Fixpoint("grow", (Pass("append", retitle("!")),), cap=5)
    with pytest.raises(InternalError, match=r"pass group `grow` did not settle in 5 rounds "
                                            r"\(append\)"):
        run_pipeline((group,), tiny())


def test_the_verifier_runs_after_each_pass_and_names_the_pass_that_broke_the_ir():
    def lose_a_target(tech):           # `shade` now reads a target that does not exist
        return dataclasses.replace(tech, targets=tuple(t for t in tech.targets
                                                       if t.name != "extra"))
    pipeline = (Pass("fine", lambda t: t), Pass("breaks", lose_a_target),
                Pass("after", lambda t: t))
    with pytest.raises(InternalError, match=r"after pass `breaks`: IR invariant violated"):
        run_pipeline(pipeline, tiny(), verify_each=True)
    out, ran = run_pipeline(pipeline, tiny())          # unverified: nobody looks
    assert ran == ["fine", "breaks", "after"]


def test_progress_and_dumps_are_reported_per_pass():
    events = []
    pipeline = (Pass("a", retitle("a")), Fixpoint("g", (Pass("b", lambda t: t),)),
                Pass("c", retitle("c")))
    run_pipeline(pipeline, tiny(), progress=lambda n: events.append(("progress", n)),
                 dump_after={"a", "b"}, dump=lambda n, t: events.append(("dump", n, t.title)))
    assert events == [("progress", "a"), ("dump", "a", "one passa"), ("progress", "b"),
                      ("dump", "b", "one passa"), ("progress", "c")]
    dumped = []
    run_pipeline(pipeline, tiny(), dump_after=ALL, dump=lambda n, t: dumped.append(n))
    assert dumped == ["a", "b", "c"]


def test_compile_file_shows_the_passes_to_a_watch():
    names, dumps = [], []
    watch = Watch(progress=names.append, dump_after=frozenset({"fold"}),
                  dump=lambda n, t: dumps.append(print_technique(t)))
    clear_cache()
    compile_file(FORWARD, scene=load_scene(SMALL), watch=watch)
    # the general pipeline, again with the light table shrunk, then the scene pipeline
    general = pass_names(pipelines.GENERAL)
    assert names[:2 * len(general)] == general + general and scene_run(names[2 * len(general):])
    # after fold: twice in the general pipelines, then once per round of the scene's fixpoint
    rounds = names[2 * len(general):].count("fold")
    assert rounds >= 2 and len(dumps) == 2 + rounds and "specialised for: point" in dumps[-1]


# ---- the general passes that spec_shadows no longer runs itself --------------------------------


def test_dead_code_drops_what_follows_a_top_level_return():
    tech = compile_source(TINY.replace(
        "output color", "output color\nfloat half_() { return 0.5; }").replace(
        "* 2.0", "* half_()")).technique
    f, shade = tech.functions[0], tech.passes[1]
    dead = ir.Declare("z", ir.FLOAT, ir.Const(ir.FLOAT, 1.0))
    tech = dataclasses.replace(
        tech, functions=(dataclasses.replace(f, body=f.body + (dead,)),),
        passes=(tech.passes[0], dataclasses.replace(shade, body=shade.body + (
            ir.Return(None), dead))))
    out = opt_dead_code.run(tech)
    assert out.functions[0].body == f.body
    assert out.passes[1].body == shade.body + (ir.Return(None),)
    assert opt_dead_code.run(out) is out            # nothing left to do: the same technique


def test_unread_reads_drops_only_targets_no_code_reads():
    tech = tiny()
    shade = tech.passes[1]
    unread = dataclasses.replace(shade, body=(ir.Output("color", ir.Const(ir.VEC4, (
        1.0, 1.0, 1.0, 1.0))),))
    out = opt_unread_reads.run(dataclasses.replace(tech, passes=(tech.passes[0], unread)))
    assert out.passes[1].reads == ()
    assert opt_unread_reads.run(tech) is tech       # `shade` still loads `extra`


def test_a_scene_without_shadows_culls_the_shadow_maps_through_the_pipeline():
    clear_cache()
    tech = compile_file(FORWARD, scene=load_scene(SMALL)).technique
    shadow_factor = next(f for f in tech.functions if f.name == "shadow_factor")
    assert shadow_factor.body == (ir.Return(ir.Const(ir.FLOAT, 1.0)),)
    assert [p.name for p in tech.passes] == ["shade"]
    assert tech.passes[0].reads == ()
    assert "shadow_atlas" not in [t.name for t in tech.targets]


def test_spec_shadows_calls_no_other_pass():
    source = (ROOT / "pipegen/passes/spec_shadows.py").read_text()
    imported = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            imported |= {f"{node.module}.{a.name}" for a in node.names}
        elif isinstance(node, ast.Import):
            imported |= {a.name for a in node.names}
    passes = {f"pipegen.passes.{p.stem}" for p in (ROOT / "pipegen/passes").glob("*.py")}
    assert not {m for m in imported if m.startswith("pipegen.passes")} & (passes | {
        "pipegen.passes"}), imported


# ---- the printer -------------------------------------------------------------------------------


def _every_node() -> list:
    """One instance of every expression and statement class of ``nodes.py``."""
    x, i = ir.Var("x", ir.FLOAT), ir.Var("i", ir.INT)
    v = ir.Var("v", ir.VEC4)
    exprs = [
        ir.Const(ir.FLOAT, -1.5), x, ir.Unary("-", x, ir.FLOAT),
        ir.Binary("+", x, ir.Binary("-", x, ir.Const(ir.FLOAT, 1.0), ir.FLOAT), ir.FLOAT),
        ir.Ternary(ir.Const(ir.BOOL, True), x, x, ir.FLOAT),
        ir.Call("sqrt", (x,), ir.FLOAT), ir.Construct(ir.VEC4, (x,)),
        ir.Swizzle(v, "xyz", ir.VEC3), ir.Index(v, i, ir.FLOAT),
        ir.LightField(i, "radius", ir.FLOAT), ir.MaterialField(i, "rim", ir.FLOAT),
        ir.Load("t", None, ir.VEC4),
        ir.Sample("t", ir.Var("uv", ir.VEC2), ir.VEC4), ir.TargetSize("t", ir.IVEC2)]
    stmts = [
        ir.Declare("y", ir.FLOAT, x), ir.Assign(x, "+=", x), ir.Output("t", v),
        ir.If(ir.Const(ir.BOOL, False), (ir.Break(),), (ir.Continue(),)),
        ir.For("k", ir.INT, ir.Const(ir.INT, 0), ir.Const(ir.INT, 4), (ir.Discard(),)),
        ir.Return(None), ir.ExprStmt(ir.Call("f", (), ir.VOID, builtin=False))]
    return exprs + stmts + [ir.Break(), ir.Continue(), ir.Discard()]


def test_the_printer_prints_every_expression_and_statement_kind():
    nodes = _every_node()
    kinds = set(typing.get_args(ir.Expr)) | set(typing.get_args(ir.Stmt))
    assert {type(n) for n in nodes} == kinds, "a node kind of nodes.py the test does not build"
    text = "\n".join(expr(n) if type(n) in typing.get_args(ir.Expr) else
                     "\n".join(statement(n)) for n in nodes)
    for piece in ("-1.5", "-x", "x + (x - 1.0)", "true ? x : x", "sqrt(x)", "vec4(x)",
                  "v.xyz", "v[i]", "lights[i].radius", "materials[i].rim", "load(t)", "sample(t, uv)", "size(t)",
                  "float y = x;", "x += x;", "t = v;", "} else {", "continue;",
                  "for (int k = 0; k < 4; k++) {", "discard;", "return;", "f();"):
        assert piece in text, piece
    with pytest.raises(TypeError, match="no expression printer for object"):
        expr(object())


def test_precedence_and_evaluation_order_show():
    a, b, c = (ir.Var(n, ir.INT) for n in "abc")
    assert expr(ir.Binary("-", a, ir.Binary("-", b, c, ir.INT), ir.INT)) == "a - (b - c)"
    assert expr(ir.Binary("-", ir.Binary("-", a, b, ir.INT), c, ir.INT)) == "a - b - c"
    assert expr(ir.Binary("*", ir.Binary("+", a, b, ir.INT), c, ir.INT)) == "(a + b) * c"
    assert expr(ir.Binary("&", ir.Binary("+", a, b, ir.INT), c, ir.INT)) == "(a + b) & c"
    assert expr(ir.Unary("-", ir.Const(ir.INT, -2), ir.INT)) == "-(-2)"
    assert expr(ir.Const(ir.UINT, 3)) == "3u"


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_every_shipped_technique_prints_general_and_specialised(path):
    clear_cache()
    for compiled in (compile_file(path), compile_file(path, scene=load_scene(SMALL))):
        text = print_technique(compiled.technique)
        assert text == print_technique(compiled.technique)       # deterministic
        assert " at 0x" not in text and "Span(" not in text
        for p in compiled.technique.passes:
            assert f"pass {p.name} {{" in text
        syntax.parse(text, f"{path.stem}.ir")                     # reads like .pipe
    assert "// specialised for: point" in text


# ---- pipegen compile --dump-after --------------------------------------------------------------


def cli(*args):
    return subprocess.run([sys.executable, "-m", "pipegen", "compile", *args],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)


def test_dump_after_prints_the_ir_then_compiles(tmp_path):
    r = cli("pipelines/forward.pipe", "--dump-after", "fold", "-o", str(tmp_path / "out"))
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("// after fold\ntechnique forward ")
    assert r.stdout.count("// after ") == 1
    assert "pass shade {" in r.stdout and "float shadow_factor(uint i, vec3 p, vec3 n) {" in r.stdout
    assert "technique forward: " in r.stdout                       # then the report
    assert (tmp_path / "out/report.txt").exists()


def test_dump_after_all_with_a_scene(tmp_path):
    r = cli("pipelines/forward.pipe", "--scene", "examples/scenes/small.toml",
            "--dump-after", "all", "--backend", "gl", "-o", str(tmp_path / "out"))
    assert r.returncode == 0, r.stderr
    heads = [line for line in r.stdout.splitlines() if line.startswith("// after ")]
    general = [f"// after {n}" for n in pass_names(pipelines.GENERAL)]
    assert heads[:2 * len(general)] == general * 2
    assert scene_run([h.removeprefix("// after ") for h in heads[2 * len(general):]]), heads
    last = r.stdout[r.stdout.index("// after cull_unread"):]
    assert "// pass `shadow_maps` culled: " in last and "pass shadow_maps {" not in last


@pytest.mark.parametrize("args, words", [
    (["--dump-after", "flod"], ["unknown pass 'flod'", "specialise, fold, prune",
                                "cull_unread", "(or all)"]),
    (["--dump-after", "cull_unread"], ["cull_unread: runs only with --scene",
                                       "the passes are specialise, fold, prune"]),
])
def test_an_unknown_pass_is_a_usage_error_listing_the_passes(tmp_path, args, words):
    r = cli("pipelines/forward.pipe", *args, "-o", str(tmp_path / "out"))
    assert r.returncode == 2 and not r.stdout
    for w in words:
        assert w in r.stderr, r.stderr
    assert not (tmp_path / "out").exists()
