"""Knobs worth sweeping (issue 10, item 7): parameters with allowed values in the shipped
techniques, and the language form that lets a parameter choose a packing scheme."""

from __future__ import annotations

from pathlib import Path

import pytest

from pipegen.compiler.driver import compile_file, compile_source
from pipegen.core.diagnostics import PipegenError

ROOT = Path(__file__).resolve().parents[1]


def allowed(technique: str) -> dict:
    tech = compile_file(ROOT / f"pipelines/{technique}.pipe").technique
    return {p.name: p.allowed for p in tech.params if p.allowed}


def test_shipped_knobs():
    assert allowed("inferred") == {
        "lbuffer_scale": (0.5, 0.625, 0.75, 1.0), "dsf": (True, False),
        "normal_encoding": ("kircher", "spheremap", "octahedral"),
        "normal_format": ("rg8", "rgb10a2", "rg16", "rg16f"),
        "lbuffer_format": ("rgba16f", "rgba32f")}
    assert allowed("lidr_bitplanes") == {"index_bits": (8, 16, 32)}
    assert allowed("deferred_calver") == {"lut_size": (64, 256, 1024, 4096),
                                          "tonemap": (False, True), "fog": (0, 1, 2),
                                          "dof_taps": (0, 4, 8, 16), "pcf_taps": (1, 4, 9, 16),
                                          "pcf_pattern": ("grid", "jittered"),
                                          "hdr_accumulate": ("blend", "copy_back")}
    assert allowed("forward") == {"pcf_taps": (1, 4, 9, 16), "pcf_pattern": ("grid", "jittered")}


@pytest.mark.parametrize("bits, capacity, constant", [(8, 4, 0.25), (16, 2, 0.0625),
                                                      (32, 1, 2.0 ** -8)])
def test_lidr_lights_per_pixel_follow_index_bits(bits, capacity, constant):
    """Trebilco's 1/2/4 lights per pixel: the blend constant and the unpacking loop follow."""
    c = compile_file(ROOT / "pipelines/lidr_bitplanes.pipe", {"index_bits": bits})
    slots = next(k for k in c.technique.packings if k.name == "slots")
    assert slots.capacity == capacity
    shade = next(p for p in c.technique.passes if p.name == "light_indices")
    assert shade.state.blend_constant == (constant,) * 4


@pytest.mark.parametrize("encoding", ["kircher", "spheremap", "octahedral"])
@pytest.mark.parametrize("fmt", ["rg8", "rgb10a2", "rg16", "rg16f"])
def test_inferred_normal_encoding_and_format(encoding, fmt):
    c = compile_file(ROOT / "pipelines/inferred.pipe",
                     {"normal_encoding": encoding, "normal_format": fmt})
    nrm = next(k for k in c.technique.packings if k.name == "nrm")
    assert nrm.scheme == encoding and c.technique.target("gnormal").format.name == fmt


BASE = """
technique knob "a packing chosen by a parameter"
param enc = octahedral in {kircher, octahedral}
param scale = 1.0
target gn : rg16f clear 0
output gn
PACK
pass p { draw scene writes gn fragment { gn = vec4(nrm.encode(normalize(normal)), 0.0, 0.0); } }
"""


def test_a_parameter_chooses_the_scheme():
    c = compile_source(BASE.replace("PACK", "pack nrm = enc(target: gn)"))
    assert next(k for k in c.technique.packings).scheme == "octahedral"
    c = compile_source(BASE.replace("PACK", "pack nrm = enc(target: gn)"), params={"enc": "kircher"})
    assert next(k for k in c.technique.packings).scheme == "kircher"


def test_a_number_parameter_is_not_a_scheme():
    with pytest.raises(PipegenError) as e:
        compile_source(BASE.replace("PACK", "pack nrm = scale(target: gn)"), "knob.pipe")
    text = e.value.render()
    assert "parameter 'scale' is a float, not a packing scheme" in text
    assert "knob.pipe:7:12" in text


def test_a_scheme_parameter_is_not_a_format():
    src = BASE.replace("target gn : rg16f", "target gn : enc").replace("PACK", "")
    with pytest.raises(PipegenError, match="parameter 'enc' holds the packing scheme "
                                           "'octahedral', not a format"):
        compile_source(src)
