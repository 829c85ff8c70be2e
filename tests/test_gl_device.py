"""The GL backend's EGL device (issue 26 item 8): chosen by PIPEGEN_GL_DEVICE (an index, a part
of the renderer's name, or auto: the first hardware device), named in `pipegen run`'s output;
a device that is not there is a clear error.  Each case is a fresh process: the context is
made once per process."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FORWARD = str(ROOT / "pipelines/forward.pipe")
PROBE = ("from pipegen.runtime.gl import context as c; d = c.device(); "
         "print(d['index']); print(d['renderer']); print(d['why']); print(c.describe())")


def probe(device: str | None):
    env = dict(os.environ)
    env.pop("PIPEGEN_GL_DEVICE", None)
    if device is not None:
        env["PIPEGEN_GL_DEVICE"] = device
    return subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True,
                          env=env, timeout=120)


@pytest.mark.gl
def test_auto_takes_a_hardware_device_or_says_there_is_none():
    r = probe(None)
    assert r.returncode == 0, r.stderr
    index, renderer, why, described = r.stdout.splitlines()
    from pipegen.runtime.gl.context import is_software
    if is_software(renderer):           # this machine: Mesa's llvmpipe alone
        assert index == "0" and why.startswith("no hardware device: EGL lists 0: ")
    else:
        assert why == "the first hardware device EGL lists"
    assert described.startswith(renderer) and f"EGL device {index}: {why}" in described


@pytest.mark.gl
def test_an_index_or_a_name_picks_the_device():
    first = probe(None).stdout.splitlines()[1]
    r = probe("0")
    assert r.returncode == 0 and r.stdout.splitlines()[2] == "PIPEGEN_GL_DEVICE=0"
    word = first.split()[0]              # "llvmpipe" here
    r = probe(word.upper())              # a part of the renderer's name, any case
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines()[1] == first and r.stdout.splitlines()[2] == \
        f"PIPEGEN_GL_DEVICE={word.upper()}"


@pytest.mark.gl
def test_a_device_that_is_not_there_is_a_clear_error(tmp_path):
    env = dict(os.environ, PIPEGEN_GL_DEVICE="15")
    r = subprocess.run([sys.executable, "-m", "pipegen", "run", FORWARD, "--size", "32x18",
                        "-o", str(tmp_path / "out")], capture_output=True, text=True, env=env,
                       timeout=120)
    assert r.returncode == 1 and "Traceback" not in r.stderr
    assert "error: PIPEGEN_GL_DEVICE=15: no such EGL device (requested device index 15" in r.stderr
    assert "hint: PIPEGEN_GL_DEVICE is an EGL device index" in r.stderr
    env["PIPEGEN_GL_DEVICE"] = "no-such-renderer"
    r = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, env=env,
                       timeout=120)
    assert r.returncode != 0 and "no EGL device's renderer matches (devices: 0: " in r.stderr


@pytest.mark.gl
def test_run_names_the_device_it_renders_on(tmp_path):
    r = subprocess.run([sys.executable, "-m", "pipegen", "run", FORWARD, "--size", "32x18",
                        "-o", str(tmp_path / "out")], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    device = [l for l in r.stderr.splitlines() if l.startswith("  device: ")]
    assert len(device) == 1 and "EGL device 0: " in device[0], r.stderr


def test_renderer_names_shorten_as_tables_print_them():
    from pipegen.runtime.gl.context import renderer_name
    # as EGL reported them: Mesa here, the lent H200 (benchmarks/gpu_check.py, issue 26)
    assert renderer_name("llvmpipe (LLVM 15.0.6, 256 bits)") == "llvmpipe"
    assert renderer_name("NVIDIA H200/PCIe/SSE2") == "NVIDIA H200"
    assert renderer_name("AMD Radeon RX 7900 XTX (radeonsi, navi31, LLVM 15.0.7)") == \
        "AMD Radeon RX 7900 XTX"


@pytest.mark.gl
@pytest.mark.cl
def test_check_credits_each_table_to_the_device_that_rendered_it(tmp_path):
    """`check`'s verdict names the renderer the GL context is on, not a fixed "llvmpipe": on
    the lent GPU its tables said "GL (llvmpipe)" over the H200's figures."""
    r = subprocess.run([sys.executable, "-m", "pipegen", "check", FORWARD, "--size", "32x18",
                        "-o", str(tmp_path / "out")], capture_output=True, text=True, timeout=300)
    assert "Traceback" not in r.stderr, r.stderr
    renderer = probe(None).stdout.splitlines()[1]
    from pipegen.runtime.gl.context import renderer_name
    assert f"32x18, 8 lights: GL ({renderer_name(renderer)}) vs CL (PoCL)" in r.stdout


@pytest.mark.gl
@pytest.mark.cl
def test_check_says_when_gl_renders_off_the_devices_its_limits_were_measured_on(
        tmp_path, monkeypatch, capsys):
    """On a GPU `check`'s DISAGREE may be the device's arithmetic (on the lent H200 no row
    agreed on depth): both verdicts say so under their tables.  The renderer's name is
    stood in for here; llvmpipe gets no such note."""
    from pipegen.cli.main import main
    args = [FORWARD, "--size", "32x18", "-o", str(tmp_path / "out")]
    main(["check", *args])
    assert "is not the device these limits were measured on" not in capsys.readouterr().out
    from pipegen.runtime.gl import context
    monkeypatch.setattr(context, "short_name", lambda: "NVIDIA H200")
    for extra in ([], ["--precision", "f64"]):
        main(["check", *args, *extra])
        out = capsys.readouterr().out
        assert ("note: GL (NVIDIA H200) is not the device these limits were measured on "
                "(llvmpipe)") in out, out
        assert "CL (PoCL) is not" not in out
