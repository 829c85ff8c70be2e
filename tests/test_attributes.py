"""Intermediate targets measured in their own terms (proof/attributes.py, issue 25 item 2):
what each target holds, read from the code that writes it; a depth's world position checked
against the world position deferred.pipe stores; a normal's error through its packing within
the encoding's measured bound; a bitfield field compared field by field."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipegen.compiler.driver import compile_file
from pipegen.packing.error_tables import NORMAL_ERRORS
from pipegen.proof.attributes import attribute_errors, attributes, compare_attribute, values_lookup
from pipegen.scene.load import load_scene

ROOT = Path(__file__).resolve().parents[1]
INFERRED = str(ROOT / "pipelines/inferred.pipe")
DEFERRED = str(ROOT / "pipelines/deferred.pipe")
EDGES = ROOT / "examples/scenes/edges.toml"


def test_what_each_target_holds_is_read_from_the_code_that_writes_it():
    inferred = {a.label: a for a in attributes(compile_file(INFERRED).technique)}
    # gnormal = vec4(nrm.encode(...), 0, 0); gdsf = vec4(depth, id.to_unorm(id.pack(...)), ..)
    assert inferred["gnormal.xy normal (kircher)"].channels == (0, 1)
    assert inferred["gdsf.y object (bitfield id)"].via_unorm
    assert {"gdsf.y group (bitfield id)", "gdsf.x", "gds depth as world position",
            "ds depth as world position", "lbuf", "gmaterial"} <= set(inferred)
    assert "color" not in {a.target for a in inferred.values()}      # the output: an image
    octa = attributes(compile_file(INFERRED, {"normal_encoding": "octahedral",
                                              "normal_format": "rgb10a2"}).technique)
    assert {a.label for a in octa if a.target == "gnormal"} == \
        {"gnormal.xy normal (octahedral)", "gnormal.zw"}
    # deferred.pipe stores its normal unpacked: its channels as values, in value units
    deferred = {a.label: a for a in attributes(compile_file(DEFERRED).technique)}
    assert deferred["gnormal"].kind == "values" and deferred["gpos"].kind == "values"
    assert deferred["ds depth as world position"].kind == "depth"


@pytest.mark.cl
def test_a_depth_reconstructs_the_world_position_deferred_stores():
    """deferred.pipe writes the world position (gpos, rgba32f) and the depth (ds, d24s8) of the
    same fragments: the depth's world position, through the scene camera, is gpos to within
    what 24 bits of depth hold at these distances."""
    c = compile_file(DEFERRED)
    scene = load_scene(EDGES).with_size(64, 36)
    got = c.pipeline("cl").render(scene)
    depth = next(a for a in attributes(c.technique) if a.target == "ds")
    ds_fmt = next(t.format for t in c.technique.targets if t.name == "ds")
    drawn = got["gpos"][..., 3] == 1.0
    assert drawn.mean() > 0.5
    from pipegen.proof.attributes import _decoded
    world, how = _decoded(depth, ds_fmt, ds_fmt.dequantize(got["ds"]), scene)
    assert how == "distance"
    miss = np.linalg.norm(world - got["gpos"][..., :3].astype(np.float64), axis=-1)[drawn]
    # d24: a step of 6e-8 in window depth is z^2 / near * 1.2e-7 in view depth (z <= 20 here)
    assert np.percentile(miss, 99) < 2e-3 and miss.max() < 1e-2, miss.max()


@pytest.mark.cl
def test_a_packed_normal_errs_within_its_encodings_measured_bound():
    """inferred's view normal through kircher into rg8, against its own float64 evaluation
    (the encode and decode exact, no quantisation): the error is the encoding's, at most the
    measured maximum over the camera-facing hemisphere (docs/encodings.md), plus float32."""
    c = compile_file(INFERRED, {"normal_format": "rg8"})
    scene = load_scene(EDGES).with_size(64, 36)
    got = c.pipeline("cl").render(scene)
    f64 = c.pipeline("cl", precision="f64").render(scene)
    errors, notes = attribute_errors(c.technique, got, c.technique, values_lookup(f64), scene)
    by = {e.attribute: e for e in errors}
    assert notes == []
    normal = by["gnormal.xy normal (kircher)"]
    bound, mean = NORMAL_ERRORS[("kircher", "rg8", "hemisphere")]
    assert normal.units == "degrees" and 0.1 < normal.p99 <= normal.max <= bound + 0.01
    assert 0.5 * mean < normal.rmse < 2 * mean
    # ids are exact: every field equal; a float channel's error within half a code
    assert by["gdsf.y object (bitfield id)"].differing == 0
    assert by["gdsf.y group (bitfield id)"].max == 0
    assert by["gdsf.x"].units == "codes" and by["gdsf.x"].max <= 0.5 + 1e-3


def test_a_field_is_compared_field_by_field_and_located():
    """One pixel's object id off by 3 (group unchanged): the object field differs there by 3
    steps, at its coordinates from the top; the group field not at all."""
    c = compile_file(INFERRED)
    tech = c.technique
    by = {a.label: a for a in attributes(tech)}
    fmt = next(t.format for t in tech.targets if t.name == "gdsf")
    word = np.full((4, 5), (7 << 8) | 2, np.uint32)
    want = np.stack([np.zeros((4, 5)), word / 65535.0], -1)
    bad = word.copy()
    bad[1, 3] = (10 << 8) | 2                        # row 1 from the bottom: y 2 from the top
    got = np.stack([np.zeros((4, 5)), bad / 65535.0], -1)
    scene = load_scene(EDGES)
    obj = compare_attribute(by["gdsf.y object (bitfield id)"], fmt, got,
                            by["gdsf.y object (bitfield id)"], fmt, want, scene)
    assert (obj.max, obj.differing, obj.pixels) == (3.0, 1, 20)
    assert obj.worst == [[3, 2, [10.0], [7.0]]]
    group = compare_attribute(by["gdsf.y group (bitfield id)"], fmt, got,
                              by["gdsf.y group (bitfield id)"], fmt, want, scene)
    assert group.max == 0 and group.worst == []
