"""Every class of user error, through the real command line: ``file:line:col``, the source
line, a caret under the reported column, a hint; exit status 1; no traceback; no output."""

import re
import subprocess
import sys

import pytest

BASE = """\
technique t "error fixture"
lights[8] {{ position: vec3, radius: float, color: vec3 }}
target color : rgba8 clear (0, 0, 0, 1)
target ds : d24s8 clear depth 1.0 stencil 0
target dz : d32f clear depth 1.0
target idx : rgba8 clear 0
target hdr : rgba16f clear 0
{decls}
pass main {{
  draw scene.opaque
  writes color
  depth ds less write
{state}
  fragment {{
{body}
  }}
}}
"""


def fixture(decls="", state="", body="    color = vec4(albedo, 1.0);"):
    return BASE.format(decls=decls, state=state, body=body)


# (id, source, line of the error (1-based), text the caret must point at, words in message)
CASES = [
    ("syntax", fixture(body="    color = vec4(albedo 1.0);"), 15, "1.0", "expected"),
    ("unknown_name", fixture(body="    color = vec4(albdo, 1.0);"), 15, "albdo", "albdo"),
    ("unknown_format", fixture(decls="target gbuf : rgba9"), 8, "rgba9", "rgba9"),
    ("unknown_builtin", fixture(body="    color = vec4(saturate(albedo), 1.0);"), 15,
     "saturate", "saturate"),
    ("type_mismatch", fixture(body="    float x = albedo;\n    color = vec4(x);"), 15,
     "albedo", "vec3"),
    ("undeclared_write", fixture(body="    idx = vec4(1.0);"), 15, "idx", "idx"),
    ("packing_cannot_fit", fixture(decls="target n1 : r16f\npack n = kircher(target: n1)"),
     9, "kircher", "fit"),
    ("stencil_without_stencil_target",
     fixture(state="  stencil { func equal ref 1 }").replace("depth ds less write",
                                                               "depth dz less write"),
     13, "stencil", "stencil"),
    ("bitplanes_not_bit_exact", fixture(decls="pack s = bitplanes(index_bits: 8, target: hdr)"),
     8, "bitplanes", "bit-exact"),
]


def run_compile(tmp_path, source):
    src = tmp_path / "bad.pipe"
    src.write_text(source)
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "pipegen.cli", "compile", str(src), "-o",
                           str(out)], capture_output=True, text=True, timeout=120)
    return proc, src, out


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_error_is_located_and_explained(tmp_path, case):
    _, source, line, token, word = case
    proc, src, out = run_compile(tmp_path, source)
    err = proc.stderr
    assert proc.returncode == 1, err
    assert "Traceback" not in err
    assert not out.exists(), "no output folder may be left behind"
    m = re.search(re.escape(str(src)) + r":(\d+):(\d+): error: (.*)", err)
    assert m, err
    assert int(m.group(1)) == line, err
    assert word.lower() in m.group(3).lower() or word.lower() in err.lower(), err
    col = int(m.group(2))
    src_line = source.splitlines()[line - 1]
    assert src_line[col - 1:].startswith(token), (src_line, col, err)
    lines = err.splitlines()
    quoted = next(i for i, l in enumerate(lines) if l.endswith(src_line))
    caret = lines[quoted + 1]
    gutter = lines[quoted].index(src_line)
    assert caret.index("^") - gutter == col - 1, err
    assert any(l.startswith("hint:") for l in lines), err


def test_missing_file_is_an_error_not_a_traceback(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "pipegen.cli", "compile",
                           str(tmp_path / "nope.pipe"), "-o", str(tmp_path / "o")],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert "no such file" in proc.stderr


def test_existing_output_survives_a_failed_compile(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("previous build")
    src = tmp_path / "bad.pipe"
    src.write_text(fixture(body="    color = vec4(albdo, 1.0);"))
    proc = subprocess.run([sys.executable, "-m", "pipegen.cli", "compile", str(src), "-o",
                           str(out)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1
    assert (out / "keep.txt").read_text() == "previous build"
