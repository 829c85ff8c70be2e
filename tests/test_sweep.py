"""``pipegen sweep`` (issue 10, parts 3-6): variants, the files it writes, what must hold in
``results.csv``, and the Dask cluster giving the local pool's numbers.

Sizes are tiny so the sweeps stay within seconds.  The inferred sweep runs at 128x72: at 64x36
an L-buffer texel is as wide as the edges scene's thinnest bars, and the error is no longer
monotonic in ``lbuffer_scale`` (0.5 maps 2x2 pixels to a texel exactly, 0.625 does not).
"""

from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pipegen.core.diagnostics import PipegenError
from pipegen.tools.sweep.outputs import csv_text
from pipegen.tools.sweep.pareto import pareto_front
from pipegen.tools.sweep.result import COLUMNS
from pipegen.tools.sweep.variants import declared_axes, parse_axes, plan_variants

ROOT = Path(__file__).resolve().parents[1]
INFERRED = str(ROOT / "pipelines/inferred.pipe")
LIDRS = [str(ROOT / f"pipelines/{n}.pipe")
         for n in ("lidr_cpu_sort", "lidr_max_stencil", "lidr_bitplanes")]


def pipegen(*args, timeout=240):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "pipegen", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, env=env, timeout=timeout)


def read_rows(folder: Path) -> list[dict]:
    with open(folder / "results.csv", newline="") as f:
        return list(csv.DictReader(f))


def num(text: str) -> float:
    return float(text) if text != "" else math.nan


# -- no backend ---------------------------------------------------------------------------------


def test_axes_parse_values_and_merge():
    axes = parse_axes(["lbuffer_scale=0.5,1.0", "dsf=true", "dsf=false,true"])
    assert axes == {"lbuffer_scale": [0.5, 1.0], "dsf": [True, False]}
    with pytest.raises(PipegenError, match="NAME=V1,V2"):
        parse_axes(["lbuffer_scale"])


def test_declared_axes_are_allowed_values_and_bools():
    from pipegen.compiler.driver import compile_file
    tech = compile_file(INFERRED).technique
    axes = declared_axes(tech)
    assert axes["lbuffer_scale"] == [0.5, 0.625, 0.75, 1.0] and set(axes["dsf"]) == {True, False}
    assert axes == {p.name: list(p.allowed) if p.allowed else [False, True]
                    for p in tech.params if p.allowed or p.type.scalar.value == "bool"}
    # without -p: the cartesian product of the declared axes (lidr_bitplanes: index_bits)
    variants, _ = plan_variants([LIDRS[2]])
    assert [v.params for v in variants] == [(("index_bits", b),) for b in (8, 16, 32)]
    variants, _ = plan_variants([INFERRED], parse_axes(["lbuffer_scale=0.5,1.0",
                                                        "dsf=false,true"]))
    assert len(variants) == 4
    assert variants[0].params == (("lbuffer_scale", 0.5), ("dsf", False))
    assert variants[0].label == "inferred lbuffer_scale=0.5 dsf=false"


def test_several_files_share_the_axes_they_declare():
    variants, _ = plan_variants([INFERRED, *LIDRS], parse_axes(["lbuffer_scale=0.5,1.0",
                                                                "index_bits=8,32"]))
    assert [v.technique for v in variants] == ["inferred", "inferred", "lidr_cpu_sort",
                                               "lidr_max_stencil", "lidr_bitplanes",
                                               "lidr_bitplanes"]
    assert [v.params for v in variants[2:]] == [(), (), (("index_bits", 8),),
                                                (("index_bits", 32),)]


def test_unknown_axis_and_disallowed_value_are_errors():
    with pytest.raises(PipegenError, match="no technique given has a parameter 'nope'"):
        plan_variants([INFERRED], {"nope": [1]})
    with pytest.raises(PipegenError):
        plan_variants([INFERRED], {"lbuffer_scale": [0.3]})


def test_pareto_labels_name_what_tells_the_points_apart():
    """A parameter set to one value wherever it appears (shadow_size=768 on every technique)
    is left out of the plot's labels; the ones that vary stay, led by the technique's name
    when the sweep has several files; long labels wrap."""
    from pipegen.tools.sweep.pareto import point_labels
    rows = [{"technique": "a", "params": "taps=1 size=768"},
            {"technique": "a", "params": "taps=4 size=768"},
            {"technique": "b", "params": "size=768"},
            {"technique": "c", "params": ""}]
    got = point_labels(rows, several_files=True)
    assert [got[id(r)] for r in rows] == ["a taps=1", "a taps=4", "b", "c"]
    one = point_labels(rows[:2], several_files=False)
    assert [one[id(r)] for r in rows[:2]] == ["taps=1", "taps=4"]
    pair = [{"technique": "t", "params": "alpha=1 beta=2 gamma=3"},
            {"technique": "t", "params": "alpha=2 beta=3 gamma=4"}]
    assert point_labels(pair, several_files=False, width=16)[id(pair[0])] == \
        "alpha=1 beta=2\ngamma=3"


def test_pareto_front():
    pts = [(1.0, 10.0), (2.0, 5.0), (3.0, 6.0), (0.5, 20.0), (2.0, 4.0), (math.nan, 1.0)]
    assert pareto_front(pts) == [3, 0, 4]


def test_csv_has_the_required_columns_first():
    row = dict(technique="t", params="a=1", backend="gl", frame_ms=math.nan, target_bytes=4,
               rmse_scene=1.5, p99_scene=2.0, max_scene=3.0, flip_scene=0.1, rmse_f64=math.nan,
               p99_f64=math.nan, max_f64=math.nan, agree=None, cpu_ms=math.nan, rmse_interior=0.2,
               max_interior=1.0, file="t.pipe", width=2, height=1, notes="")
    header, line = csv_text([row]).splitlines()
    assert header.split(",")[:len(COLUMNS)] == COLUMNS
    assert line.startswith("t,a=1,gl,,4,1.5,2.0,3.0,0.1,,,,")


def test_help_shows_examples_and_defaults(capsys):
    from pipegen.cli.main import main
    with pytest.raises(SystemExit) as e:
        main(["sweep", "--help"])
    assert e.value.code == 0
    text = capsys.readouterr().out
    examples = text[text.index("examples:"):]
    assert {line.split()[1] for line in examples.splitlines()
            if line.strip().startswith("pipegen ")} == {"sweep"}
    flat = " ".join(text.split())
    for d in ("(default: 5; 0: no timing)", "(default: gl,cl;", "default: 2)",
              "pipegen[dask]", "1280x720 for the built-in scene"):
        assert d in flat, d


def test_command_line_misuse():
    r = pipegen("sweep", INFERRED, "--backend", "vulkan", "-o", "x")
    assert r.returncode == 2 and "bad backend list" in r.stderr
    r = pipegen("sweep", ROOT / "examples/scenes/edges.toml", "-o", "/tmp/never-written")
    assert r.returncode == 1 and "scene file" in r.stderr
    assert not Path("/tmp/never-written/results.csv").exists()
    r = pipegen("sweep", INFERRED, "--reference", "ref.pipe:x", "-o", "/tmp/never-written")
    assert r.returncode == 1 and "not a parameter setting: 'x'" in r.stderr
    assert "1 | ref.pipe:x" in r.stderr and "Traceback" not in r.stderr
    assert not Path("/tmp/never-written").exists()


# -- sweeps (subprocesses: renders on GL and CL) -------------------------------------------------


@pytest.fixture(scope="module")
def inferred_sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep") / "inferred"
    # the L-buffer axes only: the normal encodings and formats make 96 more variants each
    r = pipegen("sweep", INFERRED, "--scene", ROOT / "examples/scenes/edges.toml",
                "-p", "lbuffer_scale=0.5,0.625,0.75,1.0", "-p", "dsf=false,true",
                "--size", "128x72", "--frames", "1", "--jobs", "2", "--no-progress", "-o", out)
    assert r.returncode == 0, r.stderr
    return out, r.stdout


@pytest.mark.gl
@pytest.mark.cl
def test_inferred_sweep_writes_its_files(inferred_sweep):
    out, stdout = inferred_sweep
    for name in ("results.csv", "results.json", "table.txt", "pareto.png", "index.html"):
        assert (out / name).stat().st_size > 0, name
    assert len(list((out / "images").glob("*.png"))) == 16
    assert (out / "pareto.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    maps = sorted((out / "errors").glob("*.png"))
    assert len(maps) == 16
    assert {m.name for m in maps} >= {"00_inferred_lbuffer_scale-0.5_dsf-false_gl.png",
                                      "07_inferred_lbuffer_scale-1_dsf-true_cl.png"}
    rows = read_rows(out)
    assert len(rows) == 16 and list(rows[0])[:len(COLUMNS)] == COLUMNS
    meta = json.loads((out / "results.json").read_text())
    assert len(meta["rows"]) == 16 and (meta["width"], meta["height"]) == (128, 72)
    assert "frame times: median of 1 frames" in meta["timing"] and "pinned" in meta["timing"]
    assert "lbuffer_scale=0.625 dsf=true" in stdout and "frame times:" in stdout
    for r in rows:
        assert num(r["frame_ms"]) > 0 and num(r["cpu_ms"]) > 0 and int(r["target_bytes"]) > 0
        assert 0 < num(r["flip_scene"]) < 1
        # one frame: its quartiles are itself; the default reference of a shipped technique
        assert num(r["frame_ms_q1"]) == num(r["frame_ms"]) == num(r["frame_ms_q3"])
        assert r["reference"] == "scene" and r["pareto"] in ("true", "false")
        # GL never shows what its formats clamp; on CL nothing is clamped in this scene
        assert r["clamped"] == ("0" if r["backend"] == "cl" else "")
        # the device each worker rendered on, as the plots name it (here: llvmpipe, PoCL)
        from pipegen.runtime.gl.context import short_name
        assert r["device"] == ("CL (PoCL)" if r["backend"] == "cl" else f"GL ({short_name()})")
    assert any("1 timed frame per variant" in n for n in meta["notes"])
    # the scene reference has no targets: the intermediate targets against the variant's own
    # float64 evaluation (precision alone), said so
    for r in meta["rows"]:
        assert r["targets"] and {e["against"] for e in r["targets"]} == {"f64"}
    assert "vs f64: the variant's own float64 evaluation" in stdout


@pytest.mark.gl
@pytest.mark.cl
def test_inferred_sweep_error_falls_as_lbuffer_scale_rises(inferred_sweep):
    rows = read_rows(inferred_sweep[0])
    for dsf in ("true", "false"):
        for backend in ("gl", "cl"):
            sel = [r for r in rows if r["backend"] == backend and f"dsf={dsf}" in r["params"]]
            sel.sort(key=lambda r: float(r["params"].split()[0].split("=")[1]))
            rmse = [num(r["rmse_scene"]) for r in sel]
            assert len(rmse) == 4 and rmse == sorted(rmse, reverse=True), (dsf, backend, rmse)
            assert rmse[-1] < 1.0 < rmse[0]              # full resolution: ~ the rounding


@pytest.mark.gl
@pytest.mark.cl
def test_inferred_sweep_dsf_beats_bilinear_and_backends_agree(inferred_sweep):
    rows = read_rows(inferred_sweep[0])
    by = {(r["params"], r["backend"]): r for r in rows}
    for scale in ("0.5", "0.625", "0.75"):
        dsf = num(by[(f"lbuffer_scale={scale} dsf=true", "gl")]["rmse_scene"])
        bilinear = num(by[(f"lbuffer_scale={scale} dsf=false", "gl")]["rmse_scene"])
        assert dsf < bilinear
    assert all(r["agree"] == "true" for r in rows), [r["notes"] for r in rows]
    # agreeing backends: the same error against the same reference, within a code
    for (params, b), r in by.items():
        if b == "gl":
            assert abs(num(r["rmse_scene"]) - num(by[(params, "cl")]["rmse_scene"])) < 1.0


@pytest.mark.gl
@pytest.mark.cl
def test_inferred_sweep_f64_error_is_at_most_the_scene_error(inferred_sweep):
    out = inferred_sweep[0]
    rows = read_rows(out)
    if all(r["rmse_f64"] == "" for r in rows):
        notes = json.loads((out / "results.json").read_text())["notes"]
        assert any("f64" in n for n in notes), notes      # says why the columns are empty
        pytest.skip("the f64 evaluation is not available in this compiler yet")
    for r in rows:
        assert num(r["rmse_f64"]) <= num(r["rmse_scene"]), r
        assert num(r["p99_f64"]) <= max(num(r["p99_scene"]), 1.0), r


@pytest.mark.gl
@pytest.mark.cl
def test_lidr_sweep_trades_capacity_for_error(tmp_path):
    """The three LIDRs side by side, lidr_bitplanes over index_bits 8/16/32 (4/2/1 lights per
    pixel): the same image within capacity, error growing as the packing drops lights."""
    out = tmp_path / "lidr"
    r = pipegen("sweep", *LIDRS, "--scene", ROOT / "examples/scenes/many_lights.toml",
                "-p", "index_bits=8,16,32",
                "--size", "64x36", "--frames", "0", "--no-progress", "-o", out)
    assert r.returncode == 0, r.stderr
    assert "frame times: not measured (--frames 0)" in r.stdout
    rows = read_rows(out)
    assert [(x["technique"], x["params"], x["backend"]) for x in rows] == [
        (t, p, b) for t, p in (("lidr_cpu_sort", ""), ("lidr_max_stencil", ""),
                               ("lidr_bitplanes", "index_bits=8"),
                               ("lidr_bitplanes", "index_bits=16"),
                               ("lidr_bitplanes", "index_bits=32"))
        for b in ("gl", "cl")]
    assert all(x["agree"] == "true" for x in rows), [x["notes"] for x in rows]
    assert all(x["frame_ms"] == "" and num(x["rmse_scene"]) >= 0 for x in rows)
    rmse = [num(x["rmse_scene"]) for x in rows]
    # within capacity (at most 4 lights per pixel): nearly the same image from every packing
    assert max(rmse[:6]) - min(rmse[:6]) < 0.5, rmse
    # 2 and 1 lights per pixel: lights dropped, error grows
    assert rmse[5] + 1 < rmse[7] < rmse[9], rmse
    assert "holds 1: lights will be dropped" in rows[9]["notes"]
    assert len(list((out / "errors").glob("*.png"))) == 10 and (out / "pareto.png").exists()


@pytest.mark.gl
@pytest.mark.cl
def test_dask_local_cluster_gives_the_local_pool_results():
    distributed = pytest.importorskip("distributed")
    from pipegen.tools.sweep.run import run_sweep

    kw = dict(scene=str(ROOT / "examples/scenes/edges.toml"), size=(64, 36),
              axes=parse_axes(["lbuffer_scale=0.5,1.0", "dsf=true"]), frames=0,
              progress=False)
    local = run_sweep([INFERRED], jobs=2, **kw)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        remote = run_sweep([INFERRED], scheduler=cluster.scheduler_address, **kw)
    assert "Dask cluster" in remote.where and "local process pool" in local.where

    def strip(rows):
        return [{k: v for k, v in r.items() if k != "frame_ms"} for r in rows]

    assert strip(remote.rows) == strip(local.rows)
    assert remote.maps == local.maps


@pytest.mark.gl
@pytest.mark.cl
def test_the_sweep_reports_each_intermediate_attribute_in_its_own_units(tmp_path):
    """The user's question (issue 25): which G-buffer layout keeps normals best?  Against
    ``self`` (inferred at lbuffer_scale 1, its targets unquantised as in every float64
    evaluation; the reference evaluated where its G-buffer has this one's size) each row gives
    the decoded normal's error in degrees, within the encoding's measured bound."""
    from pipegen.packing.error_tables import NORMAL_ERRORS
    out = tmp_path / "layouts"
    r = pipegen("sweep", INFERRED, "--scene", ROOT / "examples/scenes/edges.toml",
                "-p", "normal_format=rg8,rg16", "--reference", "self", "--size", "64x36",
                "--frames", "0", "--jobs", "2", "--no-progress", "-o", out)
    assert r.returncode == 0, r.stderr
    assert "gnormal.xy normal (deg)" in r.stdout and "ds depth (world)" in r.stdout
    rows = json.loads((out / "results.json").read_text())["rows"]
    normal = {}
    for row in rows:
        by = {e["attribute"]: e for e in row["targets"]}
        e = by["gnormal.xy normal (kircher)"]
        assert e["against"] == "self" and e["units"] == "degrees" and len(e["worst"]) > 0
        assert "evaluated at" in e["note"]              # the reference resized, not resampled
        normal[row["params"], row["backend"]] = e["max"]
        # the object ids and the depth are the same at every layout
        assert by["gdsf.y object (bitfield id)"]["differing"] == 0
        assert by["gds depth as world position"]["p99"] < 1e-3
    for b in ("gl", "cl"):
        rg8, rg16 = normal["normal_format=rg8", b], normal["normal_format=rg16", b]
        assert 0.1 < rg8 <= NORMAL_ERRORS[("kircher", "rg8", "hemisphere")][0] + 0.01
        assert rg16 < 0.1 * rg8
    csv_rows = read_rows(out)
    assert all("gnormal.xy normal (kircher) p99" in c["target_errors"] for c in csv_rows)
