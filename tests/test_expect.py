"""Expectations inside a .pipe (issue 24 item 4): `expect` lines parsed and lowered with their
errors at file:line:col (caret and hint), `pipegen test` (one line per expectation, exit 0 / 1 /
2), and the pytest plugin collecting a .pipe file's expectations as items."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from pipegen.compiler.driver import compile_file, compile_source
from pipegen.core.diagnostics import PipegenError
from pipegen.ir import nodes as ir

ROOT = Path(__file__).resolve().parents[1]

# A tiny technique of our own: normals into an rgba8 target, a hard threshold into another
# (a discontinuity where float32 and float64 fall on different sides of it).
TINY = textwrap.dedent("""\
    technique tiny "normals and a threshold"
    target color : rgba8 clear (0, 0, 0, 1)
    target band  : rgba8 clear (0, 0, 0, 1)
    target ds    : d24s8 clear depth 1.0
    output color

    pass shade {
      draw scene.opaque
      writes color, band
      depth ds less write
      fragment {
        vec3 n = normalize(normal);
        color = vec4(n * 0.5 + 0.5, 1.0);
        band = vec4(step(0.3, n.y * 0.5 + 0.5), 0.0, 0.0, 1.0);
      }
    }
    """)


def tiny(tmp_path: Path, *expects: str, name: str = "tiny.pipe") -> Path:
    path = tmp_path / name
    path.write_text(TINY + "\n".join(expects) + "\n")
    return path


# -- the syntax and its lowering ---------------------------------------------------------------

def test_every_form_lowers_to_an_expectation(tmp_path):
    (tmp_path / "scenes").mkdir()
    scene = tmp_path / "scenes" / "hard.toml"
    scene.write_text("")
    path = tiny(tmp_path,
                "expect color agrees gl cl",
                "expect color vs f64",
                "expect color vs f64 p99.9 <= 2.5   // a comment after it",
                "expect band vs f64 discontinuities <= 40; expect mismatches == 0",
                'expect lights_dropped < 1 on "scenes/hard.toml" at 96x64',
                "expect color agrees cl gl rmse < 0.5 at 32 x 18")
    got = compile_file(path).technique.expectations
    E = ir.Expectation
    assert got == (
        E("color", "agrees", ("gl", "cl"), text="color agrees gl cl"),
        E("color", "vs", ("f64",), text="color vs f64"),
        E("color", "vs", ("f64",), "p99.9", "<=", 2.5, text="color vs f64 p99.9 <= 2.5"),
        E("band", "vs", ("f64",), "discontinuities", "<=", 40,
          text="band vs f64 discontinuities <= 40"),
        E("mismatches", "count", (), None, "==", 0, text="mismatches == 0"),
        E("lights_dropped", "count", (), None, "<", 1, str(scene), (96, 64),
          text='lights_dropped < 1 on "scenes/hard.toml" at 96x64'),
        E("color", "agrees", ("cl", "gl"), "rmse", "<", 0.5, None, (32, 18),
          text="color agrees cl gl rmse < 0.5 at 32x18"),
    )
    assert [e.span.line for e in got] == [17, 18, 19, 20, 20, 21, 22]


def test_expectations_are_not_emitted(tmp_path):
    """The same technique with and without expectations emits the same code."""
    plain = compile_source(TINY, str(tmp_path / "a.pipe"))
    expecting = compile_source(TINY + "expect color agrees gl cl\nexpect color vs f64\n",
                               str(tmp_path / "a.pipe"))
    assert expecting.technique.expectations and not plain.technique.expectations
    for backend in ("gl", "cl"):
        a, b = plain.plan(backend), expecting.plan(backend)
        assert [p.code for p in a.passes] == [p.code for p in b.passes]


def test_expect_is_a_keyword_only_at_the_top_level(tmp_path):
    """`expect` stays a name in shader code and as a function's name."""
    text = TINY.replace("vec3 n = normalize(normal);",
                        "float expect = 1.0; vec3 n = normalize(normal) * expect;")
    text += "float expect2(float expect) { return expect; }\nexpect color vs f64\n"
    assert len(compile_source(text, str(tmp_path / "a.pipe")).technique.expectations) == 1


def error_of(tmp_path: Path, line: str) -> PipegenError:
    with pytest.raises(PipegenError) as e:
        compile_file(tiny(tmp_path, line))
    return e.value


@pytest.mark.parametrize("line, at, message, hint", [
    ("expect colr agrees gl cl", "colr", "unknown target 'colr'", "did you mean 'color'?"),
    ("expect color agrees gl gles", "gles", "unknown backend 'gles'", "did you mean 'gl'?"),
    ("expect color agrees gl f64", "f64", "unknown backend 'f64'", "expect color vs f64"),
    ("expect color agrees gl gl", "gl", "backend 'gl' is named twice", "agrees gl cl"),
    ("expect color agrees gl", "gl", "name two", "agrees gl cl"),
    ("expect color vs f64 p98 <= 2", "p98", "unknown statistic 'p98'", "did you mean 'p99'?"),
    ("expect color vs f64 median <= 2", "median", "unknown statistic 'median'",
     "statistics: max, p50, p90, p95, p99, p99.9, rmse, discontinuities, over"),
    ("expect color vs gl", "gl", "unknown reference 'gl'", "agrees gl cl"),
    ("expect lights == 0", "lights", "unknown count 'lights'",
     "did you mean 'lights_dropped'?"),
    ("expect color == 0", "color", "'color' is a target", "expect color agrees gl cl"),
    ("expect mismatches agrees gl cl", "mismatches", "'mismatches' is a count",
     "expect mismatches == 0"),
    ("expect band vs f64 over <= 1.5", "1.5", "'over' counts", "write e.g. 1"),
    ('expect color agrees gl cl on "missing.toml"', '"missing.toml"',
     "scene file 'missing.toml' not found", "relative to the .pipe file's folder"),
    ("expect color vs f64 at 0x36", "0x36", "at least 1x1, not 0x36", "at 96x64"),
    ("expect color vs f64 p99 2", "2", "unexpected number '2'; expected a comparison",
     "p99 <= 2"),
    ("expect color", None, "the expectation ends here; expected 'agrees', 'vs' or a "
     "comparison", "expect color agrees gl cl"),
    ("expect color vs f64 at 96x64 on", None, "the expectation ends here; expected the scene "
     "file", 'on "scenes/hard.toml"'),
    ("expect color vs f64 at 96x64 at 8x8", "at", "'at' is given twice", "one size"),
    ("expect color vs f64 soon", "<end>", "the expectation ends here; expected a comparison",
     "p99 <= 2"),
    ("expect color vs f64 @", "@", "unexpected '@' in an expectation", "double quotes"),
    ("expect color vs f64 on scene.toml", "scene.toml",
     "unexpected word 'scene.toml'; expected the scene file, a string in double quotes",
     'on "scenes/hard.toml"'),
])
def test_a_bad_expectation_is_an_error_at_its_word(tmp_path, line, at, message, hint):
    e = error_of(tmp_path, line)
    text = e.render()
    assert message in e.message and hint in e.hint, text
    assert e.span.file.endswith("tiny.pipe") and e.span.line == 17, text
    source_line, caret = text.splitlines()[1:3]
    assert source_line.endswith(line)
    start = e.span.column - 1
    if at == "<end>":
        assert e.span.column == len(line) + 1, text
    elif at is not None:
        assert line[start:start + len(at)] == at, text
        assert caret.count("^") == len(at), text
    assert "Traceback" not in text


def test_expect_alone_on_its_line_is_a_syntax_error(tmp_path):
    e = error_of(tmp_path, "expect\ntarget more : rgba8")
    assert (e.span.line, e.span.column) == (18, 1)
    assert "expected an expectation on the same line" in e.message


def test_an_included_file_holds_no_expectations(tmp_path):
    (tmp_path / "lib.pipe").write_text("expect color vs f64\n")
    path = tmp_path / "a.pipe"
    path.write_text(TINY.replace('output color', 'output color\ninclude "lib.pipe"'))
    with pytest.raises(PipegenError) as e:
        compile_file(path)
    assert "not a test expectation" in e.value.message
    assert e.value.span.file.endswith("lib.pipe")


# -- pipegen test ------------------------------------------------------------------------------

def pipegen_test(cwd: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pipegen.cli", "test", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


def test_pipegen_test_counts_without_rendering(tmp_path):
    """Counts need no backend: the default scene's 8 point lights are ignored by a technique
    without a light table (one mismatch), and no light set drops a light."""
    tiny(tmp_path, "expect lights_dropped == 0", "expect mismatches == 1",
         "expect mismatches < 1 at 96x64")
    proc = pipegen_test(tmp_path, "tiny.pipe")
    assert proc.returncode == 1, proc.stderr
    assert proc.stdout.splitlines() == [
        "tiny.pipe:17: expect lights_dropped == 0 ... ok (lights_dropped = 0)",
        "tiny.pipe:18: expect mismatches == 1 ... ok (mismatches = 1 (8 point lights are "
        "ignored (the technique has no light table)))",
        "tiny.pipe:19: expect mismatches < 1 at 96x64 ... FAILED: mismatches = 1 (8 point "
        "lights are ignored (the technique has no light table)), expected < 1"]
    assert proc.stderr == "error: 1 of 3 expectations failed (tiny.pipe:19)\n"


def test_lights_dropped_counts_what_no_light_set_takes(tmp_path):
    """lidr_cpu_sort sorts lights into 4 sets of non-overlapping ones; stress_overlap's 20
    lights overlap: 16 fit no set (the count `run` warns about, as a mismatch)."""
    text = (ROOT / "pipelines/lidr_cpu_sort.pipe").read_text()
    scene = ROOT / "examples/scenes/stress_overlap.toml"
    path = tmp_path / "sorted.pipe"
    path.write_text(text + f'\nexpect lights_dropped == 16 on "{scene}"\n'
                           f'expect lights_dropped == 0\n')
    from pipegen.testing.expectations import check_file
    outcomes = list(check_file(path))
    assert [o.passed for o in outcomes] == [True, True], [o.line() for o in outcomes]
    assert "slots: lights 4, 5, 6, 7," in outcomes[0].detail


@pytest.mark.gl
@pytest.mark.cl
def test_pipegen_test_passes_and_fails_with_the_numbers(tmp_path):
    """On the 64x36 default scene: GL and CL agree on `color`; both are within half a code of
    the float64 evaluation (unorm8 rounding: |code - 255 v| <= 0.5), so `max < 0.4` fails on
    both with the numbers; `band` thresholds fract(x * 3000), where float32 and float64 fall
    on different sides at a few pixels: discontinuities, reported at the expression."""
    tiny(tmp_path, "expect color agrees gl cl", "expect color vs f64 p99 <= 0.5")
    proc = pipegen_test(tmp_path, "tiny.pipe")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("tiny.pipe:17: expect color agrees gl cl ... ok (gl-cl: max ")
    assert lines[1].startswith("tiny.pipe:18: expect color vs f64 p99 <= 0.5 ... ok (p99: gl ")
    assert lines[-1] == "2 expectations hold"

    text = TINY.replace("step(0.3, n.y * 0.5 + 0.5)", "step(0.5, fract(world_pos.x * 3000.0))")
    (tmp_path / "band.pipe").write_text(
        text + "expect color vs f64 max < 0.4\nexpect band vs f64\n"
               "expect band vs f64 discontinuities <= 60\n")
    proc = pipegen_test(tmp_path, "band.pipe", "tiny.pipe")
    assert proc.returncode == 1
    out = proc.stdout.splitlines()
    import re
    assert re.fullmatch(r"band\.pipe:17: expect color vs f64 max < 0\.4 \.\.\. FAILED: max: "
                        r"gl 0\.5\d*, cl 0\.5\d* codes; expected < 0\.4 \(fails on gl, cl\)",
                        out[0]), out[0]
    assert out[1].startswith("band.pipe:18: expect band vs f64 ... FAILED: discontinuities (gl ")
    assert "none allowed without `discontinuities <= N`" in out[1]
    assert "at `fract(world_pos.x * 3000.0)` (" in out[1] and "band.pipe:14:" in out[1]
    counts = [int(n) for n in re.findall(r"(?:gl|cl) (\d+) px", out[1])]
    assert len(counts) == 2 and all(1 <= n <= 60 for n in counts), out[1]
    assert out[2].startswith("band.pipe:19: expect band vs f64 discontinuities <= 60 ... ok")
    assert [line.split(" ... ")[1][:2] for line in out[3:5]] == ["ok", "ok"]
    assert proc.stderr == "error: 2 of 5 expectations failed (band.pipe:17, band.pipe:18)\n"


def test_pipegen_test_files_without_expectations_and_with_errors(tmp_path):
    (tmp_path / "plain.pipe").write_text(TINY)
    tiny(tmp_path, "expect mismatches == 1")
    proc = pipegen_test(tmp_path, "plain.pipe", "tiny.pipe")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[0].startswith("plain.pipe: no expectations (write e.g.")
    assert proc.stdout.splitlines()[-1] == "1 expectation holds"

    proc = pipegen_test(tmp_path, "plain.pipe")          # nothing tested at all: an error
    assert proc.returncode == 1
    assert "error: no expectations in plain.pipe: nothing was tested" in proc.stderr

    tiny(tmp_path, "expect colr agrees gl cl", name="bad.pipe")
    proc = pipegen_test(tmp_path, "bad.pipe", "tiny.pipe")
    assert proc.returncode == 1
    assert proc.stderr.splitlines() == [
        "bad.pipe:17:8: error: unknown target 'colr'",
        "   17 | expect colr agrees gl cl",
        "      |        ^^^^",
        "hint: did you mean 'color'?",
        "error: 1 file with errors (bad.pipe)"]
    assert proc.stdout.startswith("tiny.pipe:17: expect mismatches == 1 ... ok")

    proc = pipegen_test(tmp_path, "tiny.pipe", "-p", "steps=4")   # -p applies to every file
    assert proc.returncode == 1 and "error: unknown parameter 'steps'" in proc.stderr

    proc = pipegen_test(tmp_path)                          # misuse: no file
    assert proc.returncode == 2 and "the following arguments are required: FILE" in proc.stderr
    assert "Traceback" not in proc.stderr


# -- pytest collects a .pipe file's expectations -------------------------------------------------

def run_pytest(cwd: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pytest", "-n0", "-p", "no:cacheprovider",
                           "-p", "no:randomly", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=600)


def test_pytest_collects_expectations_as_items(tmp_path):
    tiny(tmp_path, "expect mismatches == 1", "expect lights_dropped > 0",
         "expect color agrees gl cl")
    (tmp_path / "plain.pipe").write_text(TINY)                   # not collected
    (tmp_path / "conftest.py").write_text(
        "def pytest_collection_modifyitems(items):\n"
        "    for i in items:\n"
        "        print('MARKS', i.name, sorted((m.name, m.args) for m in i.iter_markers()))\n")
    proc = run_pytest(tmp_path, "--collect-only", "-q", "-s")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "MARKS line 17: expect mismatches == 1 []" in proc.stdout
    assert ("MARKS line 19: expect color agrees gl cl [('pipegen_requires', ('gl', 'cl'))]"
            in proc.stdout)
    ids = [line for line in proc.stdout.splitlines() if "::" in line]
    assert ids == ["tiny.pipe::line 17: expect mismatches == 1",
                   "tiny.pipe::line 18: expect lights_dropped > 0",
                   "tiny.pipe::line 19: expect color agrees gl cl"]

    proc = run_pytest(tmp_path, "tiny.pipe", "-k", "not agrees")
    assert proc.returncode == 1, proc.stdout
    assert "1 failed, 1 passed, 1 deselected" in proc.stdout
    failure = proc.stdout.split("= FAILURES =")[1].split("short test summary")[0]
    assert ("tiny.pipe:18: expect lights_dropped > 0 ... FAILED: lights_dropped = 0, "
            "expected > 0") in failure
    assert "Traceback" not in failure and "raise " not in failure and ".py:" not in failure


def test_a_pipe_file_that_does_not_compile_is_a_collection_error(tmp_path):
    tiny(tmp_path, "expect color vs f64 p98 <= 2")
    proc = run_pytest(tmp_path, "tiny.pipe")
    assert proc.returncode == 2, proc.stdout
    assert "ERROR collecting tiny.pipe" in proc.stdout
    assert "tiny.pipe:17:21: error: unknown statistic 'p98'" in proc.stdout
    assert "hint: did you mean 'p99'?" in proc.stdout and "Traceback" not in proc.stdout


def test_each_check_is_recorded_for_the_report(tmp_path):
    from pipegen.testing import records
    from pipegen.testing.expectations import check_file
    records.take()
    outcomes = list(check_file(tiny(tmp_path, "expect mismatches == 0")))
    taken = [c for c in records.take() if c.kind == "expect"]
    assert len(taken) == 1 and not taken[0].passed and not outcomes[0].passed
    c = taken[0]
    assert c.technique == "tiny" and c.summary.endswith("tiny.pipe:17: expect mismatches == 0")
    assert c.numbers == {"result": "mismatches = 1 (8 point lights are ignored (the technique "
                                   "has no light table)), expected == 0"}
    assert c.message == outcomes[0].line() and c.command.startswith("pipegen test ")
