"""Packing schemes: options, capacities, and the numerical hard cases of DESIGN.md §8.

The numpy mirrors (``schemes.numpy_impl``) stand in for the shaders; ``TestAgainstGL`` checks
them against the generated source compiled and run by llvmpipe when a GL context exists.
"""

from __future__ import annotations

import itertools
import re

import numpy as np
import pytest

from pipegen.core import formats
from pipegen.ir import nodes as ir
from pipegen.packing import light_index, measurement, schemes
from pipegen.packing.capacity import capacity_table, format_capacity_table
from pipegen.core.diagnostics import PipegenError, Span

F32 = np.float32
SPAN = Span("t.pipe", 3, 1)
RGBA8 = formats.get("rgba8")


def fmt(name):
    return formats.get(name)


def build(scheme, options=None, target=None, name="p"):
    return schemes.build(name, scheme, options or {}, fmt(target) if target else None, SPAN)


def impl(scheme, options=None, target=None):
    return schemes.numpy_impl(scheme, options or {}, fmt(target) if target else None)


def unorm_read(values, target="rgba8"):
    """What a shader reads back after writing ``values`` (..., N) into ``target``."""
    f = fmt(target)
    values = np.asarray(values, np.float64)
    n = values.shape[-1]
    padded = np.zeros(values.shape[:-1] + (max(n, f.channels),))
    padded[..., :n] = values
    stored = f.dequantize(f.quantize(padded[..., :f.channels]))
    out = np.zeros_like(padded)
    out[..., :f.channels] = stored
    return out[..., :n].astype(F32)


def unorm_read1(values, target):
    """``unorm_read`` for scalar values (one channel)."""
    return unorm_read(np.asarray(values)[..., None], target)[..., 0]


def decode_all(unpack, v, capacity):
    return np.stack([unpack(v, k) for k in range(capacity)])


ALL_OPTIONS = [
    ("bitplanes", {"index_bits": 8}, "rgba8"),
    ("max_pairs", {}, "rgba8"),
    ("channel_slots", {"slots": 4}, "rgba8"),
    ("split16", {}, "rg8"),
    ("bitfield", {"fields": [("object", 8), ("group", 8)]}, "rg16"),
    ("kircher", {}, "rg16"),
    ("spheremap", {}, "rg16"),
    ("octahedral", {}, "rg16"),
]


# =============================================================================================
# API, options and errors
# =============================================================================================


class TestBuild:
    @pytest.mark.parametrize("scheme, options, target", ALL_OPTIONS)
    def test_every_function_is_defined_once_with_the_pack_prefix(self, scheme, options, target):
        spec = build(scheme, options, target, name="pk")
        defined = re.findall(r"^(?:vec[234]|uint|float|int) (\w+)\(", spec.functions_source,
                             re.MULTILINE)
        assert defined == [f"pk_{fn}" for fn in spec.functions]
        assert set(spec.functions) == set(impl(scheme, options, target))

    @pytest.mark.parametrize("scheme, options, target", ALL_OPTIONS)
    def test_source_is_plausible_shader_text(self, scheme, options, target):
        src = re.sub(r"//[^\n]*", "", build(scheme, options, target).functions_source)
        assert src.count("{") == src.count("}") and src.count("(") == src.count(")")
        assert not re.search(r"\d[eE][-+]?\d", src), "no exponent literals"
        assert "while" not in src and "#" not in src

    @pytest.mark.parametrize("scheme, options, target", ALL_OPTIONS)
    def test_parses_with_the_front_end(self, scheme, options, target):
        syntax = pytest.importorskip("pipegen.frontend.parse")
        if not hasattr(syntax, "parse"):
            pytest.skip("pipegen.frontend.parse.parse not there yet")
        spec = build(scheme, options, target, name="pk")
        module = syntax.parse('technique t "x"\n' + spec.functions_source, "packing.pipe")
        names = [getattr(item.name, "name", item.name) for item in module.items
                 if type(item).__name__ == "FunctionDef"]
        assert names == [f"pk_{fn}" for fn in spec.functions]

    @pytest.mark.parametrize("B, target, capacity", [
        (8, "rgba8", 4), (8, "rg8", 2), (4, "rgba8", 8), (4, "r8", 2), (8, "r8", 1),
        (16, "rgba8", 2), (16, "rg8", 1), (4, "rg8", 4)])
    def test_bitplane_capacity_is_the_papers(self, B, target, capacity):
        spec = build("bitplanes", {"index_bits": B, "target": "lightidx"}, target)
        assert spec.capacity == capacity
        assert spec.constants["capacity"] == (ir.INT, capacity)
        b = B // fmt(target).channels
        assert spec.constants["blend_constant"] == (ir.FLOAT, 2.0 ** -b)

    def test_other_capacities_and_constants(self):
        assert build("max_pairs", {}, "rgba8").capacity == 4
        assert build("channel_slots", {"slots": 3}, "rgba8").constants["capacity"] == (ir.INT, 3)
        assert build("channel_slots", {}, "rg8").capacity == 2
        assert build("bitfield", {"fields": {"a": 3, "b": 5}}).constants == {"bits": (ir.INT, 8)}
        # Measured: 0.5039 of a 16-bit step, a little over the ideal half step 2^-17
        # (float32 rounding of x*65535+0.5; docs/encodings.md, test_packing_exhaustive.py).
        error = build("split16").error
        assert error > 2.0 ** -17 and error * 65535 == pytest.approx(0.5039, abs=5e-5)
        assert build("kircher").error is None

    def test_notes_say_what_the_passes_must_do(self):
        notes = " ".join(build("max_pairs", {}, "rgba8").notes)
        assert "two passes" in notes and "stencil" in notes
        notes = " ".join(build("bitplanes", {"index_bits": 8}, "rgba8").notes)
        assert "constant_color" in notes and "0.25" in notes and "Trebilco's table" in notes

    def test_format_name_as_target_option(self):
        spec = schemes.build("s", "bitplanes", {"index_bits": 4, "target": "rg8"}, None, SPAN)
        assert spec.capacity == 4

    @pytest.mark.parametrize("scheme, options, target, message", [
        ("bitplanes", {"index_bits": 6}, "rgba8", "cannot fit"),      # 6 bits over 4 channels
        ("bitplanes", {"index_bits": 12}, "rgba8", "cannot fit"),     # 3 bits per channel
        ("bitplanes", {"index_bits": 16}, "r8", "cannot fit"),        # 16 bits in one byte
        ("bitplanes", {"index_bits": 8}, "rgba16f", "not bit-exact"),
        ("bitplanes", {"index_bits": 8}, "rgba16", "not bit-exact"),
        ("bitplanes", {"index_bits": 8}, "rgb10a2", "not bit-exact"),
        ("bitplanes", {"index_bits": 8}, "r32ui", "cannot fit"),
        ("bitplanes", {"index_bits": 8}, None, "needs a target"),
        ("bitplanes", {}, "rgba8", "needs the option 'index_bits'"),
        ("bitplanes", {"index_bits": "8"}, "rgba8", "must be an integer"),
        ("bitplanes", {"index_bits": 8, "bits_per_write": 2}, "rgba8", "no option"),
        ("max_pairs", {}, "rg8", "cannot fit"),
        ("max_pairs", {}, "rgba16f", "cannot fit"),
        ("channel_slots", {"slots": 5}, "rgba8", "cannot fit"),
        ("channel_slots", {"slots": 3}, "rg8", "cannot fit"),
        ("split16", {}, "r8", "cannot fit"),
        ("bitfield", {"fields": [("object", 8), ("group", 9)]}, "r16", "wider than"),
        ("bitfield", {"fields": [("id", 11)]}, "r16f", "wider than"),   # half: 10 exact bits
        ("bitfield", {"fields": [("id", 24)]}, "r32f", "wider than"),   # float32 math: 23
        ("bitfield", {"fields": [("a", 20), ("b", 13)]}, None, "wider than a uint"),
        ("bitfield", {"fields": [("a", 8), ("a", 8)]}, None, "twice"),
        ("bitfield", {"fields": [("float", 8)]}, None, "reserved"),
        ("bitfield", {"fields": [("a", 0)]}, None, "positive"),
        ("bitfield", {}, None, "needs fields"),
        ("kircher", {}, "r16f", "cannot fit"),                         # one channel
        ("octahedral", {}, "r8", "cannot fit"),
        ("spheremap", {}, "r32ui", "cannot fit"),
        ("spheremap", {}, "d32f", "cannot fit"),
        ("zigzag", {}, None, "unknown packing scheme"),
    ])
    def test_bad_options(self, scheme, options, target, message):
        with pytest.raises(PipegenError) as info:
            build(scheme, options, target)
        assert message in info.value.message
        assert info.value.span == SPAN

    def test_errors_carry_hints(self):
        with pytest.raises(PipegenError) as info:
            build("bitplanes", {"index_bits": 6}, "rgba8")
        assert "4, 8, 16, 32" in info.value.hint


class TestCapacityTable:
    PAPER = [  # (lights per fragment, scene lights, surfaces) — Trebilco 2007, in order
        (2, 15, "1 x 8bit channel"), (4, 15, "2 x 8bit channels"), (8, 15, "1 x RGBA8 surface"),
        (16, 15, "2 x RGBA8 surfaces (2 render targets)"),
        (1, 255, "1 x 8bit channel"), (2, 255, "2 x 8bit channels"),
        (4, 255, "1 x RGBA8 surface"), (8, 255, "2 x RGBA8 surfaces (2 render targets)"),
        (16, 255, "4 x RGBA8 surfaces (4 render targets)"),
        (1, 65535, "2 x 8bit channels"), (2, 65535, "1 x RGBA8 surface"),
        (4, 65535, "2 x RGBA8 surfaces (2 render targets)"),
        (8, 65535, "4 x RGBA8 surfaces (4 render targets)"),
    ]

    def test_reproduces_the_paper(self):
        rows = capacity_table()
        assert [(r.lights_per_fragment, r.scene_lights, r.surfaces) for r in rows] == self.PAPER
        two_pass = [(r.index_bits, r.channels) for r in rows if r.stencil]
        assert two_pass == [(4, 8), (8, 16)]          # the rows that need the stencil trick
        assert {r.passes for r in rows if r.stencil} == {2}

    def test_generated_rows_agree_with_build(self):
        for r in capacity_table():
            if r.bitplanes:
                target = {1: "r8", 2: "rg8", 4: "rgba8"}[r.channels]
                assert build("bitplanes", {"index_bits": r.index_bits}, target).capacity \
                    == r.lights_per_fragment

    def test_markdown(self):
        text = format_capacity_table(capacity_table())
        assert text.count("\n") == 2 + 12
        assert "| 4 | 255 | 1 x RGBA8 surface | light index split into 4x2bit values |" in text


# =============================================================================================
# Light-index decoding under perturbation
# =============================================================================================


PERTURB = np.array([-0.49, -0.3, -0.01, 0.0, 0.01, 0.3, 0.49])


class TestDecodeRobustness:
    def test_round_to_nearest_survives_049_codes_the_papers_ceil_does_not(self):
        codes = np.arange(256, dtype=np.float64)
        x = ((codes[:, None] + PERTURB[None, :]) / 255.0).astype(F32)
        ours = np.floor(x * F32(255) + F32(0.5))
        assert np.array_equal(ours, np.broadcast_to(codes[:, None], x.shape))
        trebilco = np.ceil(x * F32(254.5))
        exact = PERTURB == 0.0
        # Exact values decode fine with ceil(x*254.5)...
        assert np.array_equal(trebilco[:, exact][:, 0], codes)
        # ...but a value that comes in high is pushed to the next code.
        wrong = trebilco[:, PERTURB > 0] != codes[:, None]
        assert wrong[:250, -1].all()                   # +0.49 breaks every code below 250
        assert wrong[1:6, 0].all()                     # even +0.01 breaks codes 1..5
        assert trebilco[1, PERTURB == 0.49][0] == 2

    @pytest.mark.parametrize("B, target", [(8, "rgba8"), (4, "rgba8"), (8, "rg8"), (4, "r8")])
    def test_bitplanes_unpack_under_perturbation(self, B, target):
        spec = build("bitplanes", {"index_bits": B}, target)
        f = impl("bitplanes", {"index_bits": B}, target)
        rng = np.random.default_rng(B)
        lights = rng.integers(1, 2 ** B, size=(spec.capacity, 4096))
        v = light_index.emulate_bitplanes(lights, B, target).astype(np.float64)
        noise = rng.choice(PERTURB, size=v.shape) / 255.0
        noise[..., fmt(target).channels:] = 0.0
        got = decode_all(f["unpack"], (v + noise).astype(F32), spec.capacity)
        assert np.array_equal(got, lights[::-1])

    def test_pairs_and_slots_unpack_under_perturbation(self):
        rng = np.random.default_rng(3)
        for scheme, options in [("max_pairs", {}), ("channel_slots", {"slots": 4})]:
            f = impl(scheme, options, "rgba8")
            index = rng.integers(1, 256, size=2000)
            v = f["value"](index).astype(np.float64)
            v = v + rng.choice(PERTURB, size=v.shape) / 255.0
            assert np.array_equal(f["unpack"](v.astype(F32), 0), index)


# =============================================================================================
# Bit planes: blend emulation
# =============================================================================================


BITPLANE_CASES = [(8, "rgba8"), (8, "rg8"), (4, "rgba8"), (4, "r8"), (4, "rg8"), (16, "rgba8"),
                  (8, "r8")]


class TestBitPlanes:
    @pytest.mark.parametrize("B, target", BITPLANE_CASES)
    def test_plane_value_is_the_index_in_high_bits(self, B, target):
        f = impl("bitplanes", {"index_bits": B}, target)
        C = fmt(target).channels
        b = B // C
        index = np.arange(2 ** B, dtype=np.uint32)
        codes = RGBA8.quantize(f["plane_value"](index))
        assert np.all(codes[:, C:] == 0)
        assert np.all(codes[:, :C] % (1 << (8 - b)) == 0)      # only the top b bits
        back = sum((codes[:, c].astype(np.uint32) >> (8 - b)) << (c * b) for c in range(C))
        assert np.array_equal(back, index)

    @pytest.mark.parametrize("mode", ["exact", "unorm8"])
    @pytest.mark.parametrize("B, target", BITPLANE_CASES)
    def test_exact_up_to_capacity(self, B, target, mode):
        cap = build("bitplanes", {"index_bits": B}, target).capacity
        f = impl("bitplanes", {"index_bits": B}, target)
        rng = np.random.default_rng(7)
        for n in range(1, cap + 1):
            lights = rng.integers(1, 2 ** B, size=(n, 3000))
            lights[:, 0] = 2 ** B - 1                     # every bit set
            lights[:, 1] = 1
            v = light_index.emulate_bitplanes(lights, B, target, mode)
            got = decode_all(f["unpack"], v, cap)
            assert np.array_equal(got[:n], lights[::-1]), (n, mode)
            assert np.all(got[n:] == 0)                   # the rest reads as empty

    def test_exhaustive_pairs_in_r8(self):
        lights = np.array(list(itertools.product(range(1, 16), repeat=2))).T
        v = light_index.emulate_bitplanes(lights, 4, "r8", "unorm8")
        f = impl("bitplanes", {"index_bits": 4}, "r8")
        assert np.array_equal(decode_all(f["unpack"], v, 2), lights[::-1])

    def test_empty_pixel_reads_zero(self):
        f = impl("bitplanes", {"index_bits": 8}, "rgba8")
        assert all(f["unpack"](np.zeros(4, F32), k) == 0 for k in range(-1, 6))

    # --- beyond capacity: what really happens ------------------------------------------------

    @pytest.mark.parametrize("mode", ["exact", "unorm8"])
    def test_over_capacity_drops_the_oldest_cleanly_when_its_chunks_are_low(self, mode):
        # Index 0b01010101: every 2-bit chunk is 1 < 2, so shifting it out rounds down.
        lights = [0b01010101, 7, 200, 33, 129]
        v = light_index.emulate_bitplanes(lights, 8, "rgba8", mode)
        got = decode_all(impl("bitplanes", {"index_bits": 8}, "rgba8")["unpack"], v, 4)
        assert list(got) == [129, 33, 200, 7]

    @pytest.mark.parametrize("mode", ["exact", "unorm8"])
    def test_over_capacity_a_high_chunk_carries_into_the_next_oldest(self, mode):
        # The oldest index 3 has chunk 0b11 in red: shifting it out rounds up, adding 1 to
        # red's remaining bits, i.e. to the low chunk of the next-oldest light.
        lights = [3, 1, 1, 1, 1]
        v = light_index.emulate_bitplanes(lights, 8, "rgba8", mode)
        got = decode_all(impl("bitplanes", {"index_bits": 8}, "rgba8")["unpack"], v, 4)
        assert list(got) == [1, 1, 1, 2]

    def test_over_capacity_carry_ripples_and_saturates(self):
        f = impl("bitplanes", {"index_bits": 8}, "rgba8")
        # Red chunks of the retained lights are all 0b11: the carry ripples through them into
        # the newest light's chunk ...
        v = light_index.emulate_bitplanes([3, 3, 3, 3, 1], 8, "rgba8", "unorm8")
        assert RGBA8.quantize(v)[0] == 0b10000000
        assert list(decode_all(f["unpack"], v, 4)) == [2, 0, 0, 0]
        # ... and saturates at 255 when there is nothing left to carry into.
        v = light_index.emulate_bitplanes([255] * 5, 8, "rgba8", "unorm8")
        assert np.all(RGBA8.quantize(v) == 255)

    @pytest.mark.parametrize("B, target", [(8, "rgba8"), (4, "rgba8"), (16, "rgba8"), (4, "r8")])
    def test_over_capacity_statistics(self, B, target):
        """One light over capacity: the retained lights survive exactly when the dropped
        light's chunk has its top bit clear in every channel (fixed-point blend)."""
        cap = build("bitplanes", {"index_bits": B}, target).capacity
        C = fmt(target).channels
        b = B // C
        rng = np.random.default_rng(11)
        lights = rng.integers(1, 2 ** B, size=(cap + 1, 20000))
        v = light_index.emulate_bitplanes(lights, B, target, "unorm8")
        got = decode_all(impl("bitplanes", {"index_bits": B}, target)["unpack"], v, cap)
        intact = np.all(got == lights[::-1][:cap], axis=0)
        oldest = lights[0].astype(np.uint32)
        clean = np.all([((oldest >> (c * b)) >> (b - 1)) & 1 == 0 for c in range(C)], axis=0)
        assert np.all(intact[clean])
        # A carry corrupts the pixel unless the channel saturates back to the right value.
        assert np.mean(intact[~clean]) < 0.01
        # How often that is: indices 1..2^B-1 whose chunks all have the top bit clear.
        everyone = np.arange(1, 2 ** B, dtype=np.uint32)
        low = np.all([((everyone >> (c * b)) >> (b - 1)) & 1 == 0 for c in range(C)], axis=0)
        assert abs(clean.mean() - low.mean()) < 0.02

    def test_float_and_fixed_point_blends_differ_only_beyond_capacity(self):
        rng = np.random.default_rng(5)
        for n in (1, 2, 3, 4, 5, 6):
            lights = rng.integers(1, 256, size=(n, 5000))
            a = light_index.emulate_bitplanes(lights, 8, "rgba8", "exact")
            b = light_index.emulate_bitplanes(lights, 8, "rgba8", "unorm8")
            assert np.array_equal(a, b) == (n <= 4)

    def test_blend_constant_quantises_to_a_power_of_two_code(self):
        # Why the fixed-point blend is still exact: round(255 * 2^-b) = 2^(8-b), so
        # dst * const / 255 = (dst >> b) * 256/255, which rounds back to dst >> b.
        for b in (1, 2, 4, 8):
            assert round(255 * 2.0 ** -b) == 2 ** (8 - b)


# =============================================================================================
# MAX-blended pairs with the stencil
# =============================================================================================


class TestMaxPairs:
    def decode(self, lights):
        f = impl("max_pairs", {}, "rgba8")
        v = unorm_read(light_index.emulate_max_pairs(lights))
        return [int(f["unpack"](v, k)) for k in range(4)]

    def test_pair_is_index_and_complement(self):
        p = impl("max_pairs", {}, "rgba8")["pair"](np.array([0, 1, 128, 255]))
        codes = RGBA8.quantize(np.concatenate([p, p], -1))
        assert codes[:, 0].tolist() == [0, 1, 128, 255]
        assert codes[:, 1].tolist() == [255, 254, 127, 0]

    @pytest.mark.parametrize("lights, expected", [
        ([], [0, 0, 0, 0]),
        ([7], [7, 0, 0, 0]),                   # one light: 1-G equals R, reported once
        ([7, 200], [200, 7, 0, 0]),
        ([200, 7], [200, 7, 0, 0]),
        ([7, 200, 9], [200, 7, 9, 0]),
        ([7, 200, 9, 42], [200, 7, 42, 9]),
        ([1, 255, 255 - 1, 2], [255, 1, 254, 2]),
        ([255], [255, 0, 0, 0]),
        ([1], [1, 0, 0, 0]),
    ])
    def test_up_to_four_lights(self, lights, expected):
        assert self.decode(lights) == expected

    def test_every_set_of_up_to_four_lights_survives(self):
        rng = np.random.default_rng(2)
        for n in range(1, 5):
            for _ in range(300):
                lights = rng.choice(np.arange(1, 256), size=n, replace=False).tolist()
                got = self.decode(lights)
                assert sorted(i for i in got if i) == sorted(lights)

    def test_beyond_four_the_stencil_keeps_the_first_two_and_the_extremes_of_the_rest(self):
        lights = [10, 20, 30, 5, 250, 40]
        # Pass 1 takes 10 and 20; pass 2 takes every later light, MAX keeps 250 and (as 1-x) 5.
        assert self.decode(lights) == [20, 10, 250, 5]

    def test_the_papers_printed_channel_mapping_is_wrong(self):
        v = unorm_read(light_index.emulate_max_pairs([7, 200]))
        codes = np.rint(v * 255).astype(int)
        paper_index3 = codes[1]                  # "Index3 = Green"
        assert paper_index3 == 255 - 7           # not an index that was written
        assert self.decode([7, 200])[:2] == [200, 7]

    def test_value_fills_both_pairs(self):
        v = impl("max_pairs", {}, "rgba8")["value"](np.array(9))
        assert np.allclose(v, [9 / 255, 246 / 255, 9 / 255, 246 / 255])

    def test_rgba16_addresses_65535_lights(self):
        f = impl("max_pairs", {}, "rgba16")
        index = np.array([1, 300, 65535])
        v = unorm_read(f["value"](index), "rgba16")
        assert f["unpack"](v, 0).tolist() == index.tolist()


# =============================================================================================
# CPU-sorted channel slots
# =============================================================================================


class TestChannelSlots:
    def test_value_unpack_round_trip(self):
        f = impl("channel_slots", {"slots": 4}, "rgba8")
        index = np.arange(256)
        v = unorm_read(f["value"](index))
        for k in range(4):
            assert np.array_equal(f["unpack"](v, k), index)
        assert np.all(f["unpack"](v, 4) == 0) and np.all(f["unpack"](v, -1) == 0)

    def test_fewer_slots_than_channels(self):
        f = impl("channel_slots", {"slots": 2}, "rgba8")
        v = unorm_read(f["value"](np.array([5])))
        assert f["unpack"](v, 1).tolist() == [5] and f["unpack"](v, 2).tolist() == [0]

    def test_greedy_sort_and_drop(self):
        # Five lights at one spot overlap each other: four slots take four, the fifth drops.
        centers = np.zeros((5, 3))
        sets, dropped = light_index.sort_lights_into_slots(centers, np.ones(5), 4)
        assert sets == [[0], [1], [2], [3]] and dropped == [4]

    def test_disjoint_lights_share_the_first_slot(self):
        centers = np.array([[0, 0, 0], [3, 0, 0], [6, 0, 0], [1, 0, 0]], dtype=float)
        sets, dropped = light_index.sort_lights_into_slots(centers, np.ones(4), 2)
        assert sets == [[0, 1, 2], [3]] and dropped == []

    def test_touching_spheres_count_as_overlapping(self):
        centers = np.array([[0, 0, 0], [2, 0, 0]], dtype=float)
        sets, _ = light_index.sort_lights_into_slots(centers, np.ones(2), 2)
        assert sets == [[0], [1]]
        sets, _ = light_index.sort_lights_into_slots(centers, np.full(2, 0.999), 2)
        assert sets == [[0, 1], []]

    def test_no_set_holds_overlapping_lights(self):
        rng = np.random.default_rng(4)
        centers = rng.uniform(-10, 10, size=(200, 3))
        radii = rng.uniform(0.5, 3.0, size=200)
        sets, dropped = light_index.sort_lights_into_slots(centers, radii, 4)
        placed = sorted(i for s in sets for i in s)
        assert sorted(placed + dropped) == list(range(200)) and dropped
        for s in sets:
            for i, j in itertools.combinations(s, 2):
                assert np.linalg.norm(centers[i] - centers[j]) > radii[i] + radii[j]
        for i in dropped:   # each dropped light overlaps an earlier light in every set
            for s in sets:
                assert any(np.linalg.norm(centers[i] - centers[j]) <= radii[i] + radii[j]
                           for j in s if j < i)


# =============================================================================================
# split16 and bitfield
# =============================================================================================


class TestSplit16:
    def test_every_code_round_trips_through_rg8(self):
        f = impl("split16")
        x = np.arange(65536, dtype=F32) / F32(65535)
        stored = unorm_read(f["pack"](x), "rg8")
        assert np.array_equal(f["unpack"](stored), x)
        codes = fmt("rg8").quantize(f["pack"](x)).astype(int)
        assert np.array_equal(codes[:, 0] * 256 + codes[:, 1], np.arange(65536))

    @pytest.mark.parametrize("target", ["rg8", "rgba8", "rg16", "rg16f"])
    def test_error_bound_for_any_value(self, target):
        f = impl("split16")
        x = np.random.default_rng(0).uniform(0, 1, 200000).astype(F32)
        stored = unorm_read(f["pack"](x), target)
        err = np.abs(f["unpack"](stored).astype(np.float64) - x)
        assert err.max() <= build("split16", {}, target).error + 1e-7

    def test_clamps_out_of_range(self):
        f = impl("split16")
        got = f["unpack"](unorm_read(f["pack"](np.array([-1.0, 2.0], F32)), "rg8"))
        assert got.tolist() == [0.0, 1.0]


class TestBitfield:
    OPTS = {"fields": [("object", 8), ("group", 8)]}

    def test_kircher_dsf_id_round_trip_through_r16(self):
        f = impl("bitfield", self.OPTS)
        obj, grp = np.meshgrid(np.arange(256), np.arange(256))
        v = f["pack"](obj.ravel(), grp.ravel())
        assert np.array_equal(v, (obj.ravel() << 8) | grp.ravel())
        stored = unorm_read1(f["to_unorm"](v), "r16")
        back = f["from_unorm"](stored)
        assert np.array_equal(back, v)
        assert np.array_equal(f["object_of"](back), obj.ravel())
        assert np.array_equal(f["group_of"](back), grp.ravel())

    def test_fields_are_masked_to_their_width(self):
        f = impl("bitfield", self.OPTS)
        v = f["pack"](np.array([0x1FF]), np.array([0x3FF]))
        assert v.tolist() == [0xFFFF]
        assert f["object_of"](v).tolist() == [255]

    def test_three_fields_and_dict_syntax(self):
        f = impl("bitfield", {"fields": {"a": 3, "b": 5, "c": 3}})
        v = f["pack"](np.array([5]), np.array([17]), np.array([6]))
        assert v.tolist() == [(5 << 8) | (17 << 3) | 6]
        assert [f[n + "_of"](v).tolist()[0] for n in "abc"] == [5, 17, 6]
        spec = build("bitfield", {"fields": {"a": 3, "b": 5, "c": 3}}, name="ids")
        assert "uint ids_pack(uint a, uint b, uint c)" in spec.functions_source
        assert "uint ids_b_of(uint v)" in spec.functions_source

    @pytest.mark.parametrize("target, bits", [("r16f", 10), ("r32f", 23), ("r8", 8)])
    def test_widest_field_a_float_or_unorm_channel_holds(self, target, bits):
        build("bitfield", {"fields": [("id", bits)]}, target)   # fits
        f = impl("bitfield", {"fields": [("id", bits)]})
        v = np.arange(2 ** bits, dtype=np.uint32) if bits <= 16 else \
            np.random.default_rng(1).integers(0, 2 ** bits, 100000).astype(np.uint32)
        stored = unorm_read1(f["to_unorm"](v), target)
        assert np.array_equal(f["from_unorm"](stored), v)


# =============================================================================================
# Normal encodings
# =============================================================================================


def unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def round_trip(scheme, n, target=None):
    f = impl(scheme)
    e = f["encode"](np.asarray(n, F32))
    if target is not None:
        e = unorm_read(e, target)
    return f["decode"](e)


def near(axis_angle_deg, around=(0.0, 0.0, -1.0), azimuths=8):
    """Unit vectors at the given angles from ``around`` (the -z pole by default)."""
    out = []
    for t in np.radians(axis_angle_deg):
        for a in np.linspace(0, 2 * np.pi, azimuths, endpoint=False):
            out.append((np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), -np.cos(t)))
    return np.array(out)


NORMAL_SCHEMES = ["kircher", "spheremap", "octahedral"]


class TestNormals:
    @pytest.mark.parametrize("scheme", NORMAL_SCHEMES)
    def test_singular_pole_decodes_to_itself(self, scheme):
        n = np.array([[0.0, 0.0, -1.0], [-0.0, -0.0, -1.0]], F32)
        for target in (None, "rg8", "rg16", "rg16f"):
            d = round_trip(scheme, n, target)
            assert np.all(np.isfinite(d))
            assert np.allclose(d, [[0, 0, -1]] * 2, atol=1e-6), (scheme, target)

    @pytest.mark.parametrize("scheme", NORMAL_SCHEMES)
    def test_near_the_pole_no_nan_and_small_error(self, scheme):
        n = near([1e-9, 1e-6, 1e-4, 1e-2, 0.1, 1.0, 5.0])
        d = round_trip(scheme, n)
        assert np.all(np.isfinite(d))
        assert np.allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-5)
        # In float32, the pole's neighbourhood is resolved to within a degree at worst.
        assert measurement.angular_error_deg(n, d).max() < 1.0

    @pytest.mark.parametrize("scheme", NORMAL_SCHEMES)
    def test_decode_of_any_stored_value_is_a_unit_vector(self, scheme):
        g = np.linspace(0.0, 1.0, 257, dtype=F32)
        e = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
        d = impl(scheme)["decode"](e)
        assert np.all(np.isfinite(d))
        assert np.allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-5)

    @pytest.mark.parametrize("scheme", NORMAL_SCHEMES)
    def test_encodes_into_unit_square(self, scheme):
        n = measurement.fibonacci_sphere(20000, hemisphere=scheme == "kircher")
        e = impl(scheme)["encode"](n.astype(F32))
        assert e.min() >= -1e-6 and e.max() <= 1 + 1e-6

    def test_kircher_is_eq_1_to_3(self):
        n = unit(np.array([[0.3, -0.2, 0.9], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]))
        h = unit(n + [0, 0, 1])                                     # eq. 1
        e = impl("kircher")["encode"](n.astype(F32))
        assert np.allclose(e * 2 - 1, h[:, :2], atol=1e-6)
        z = np.sqrt(1 - np.sum(h[:, :2] ** 2, -1))                  # eq. 2
        ref = np.stack([2 * z * h[:, 0], 2 * z * h[:, 1], 2 * z * z - 1], -1)   # eq. 3
        assert np.allclose(ref, n, atol=1e-12)
        assert np.allclose(impl("kircher")["decode"](e), n, atol=1e-6)

    def test_kircher_and_spheremap_store_the_same_values(self):
        n = measurement.fibonacci_sphere(5000).astype(F32)
        assert np.allclose(impl("kircher")["encode"](n), impl("spheremap")["encode"](n),
                           atol=2e-6)

    def test_octahedral_seams(self):
        f = impl("octahedral")
        eps = np.array([1e-7, 1e-4, 1e-2])
        for s in eps:
            for y in (0.3, 0.7, -0.5):
                # x = ±s below the equator: the two sides land on opposite edges of the square.
                a, b = unit([[s, y, -0.6], [-s, y, -0.6]]).astype(F32)
                ea, eb = f["encode"](np.stack([a, b]))
                assert abs(ea[0] - eb[0]) > 0.4 and abs(ea[1] - eb[1]) < 1e-3
                for target in (None, "rg8", "rg16"):
                    d = round_trip("octahedral", np.stack([a, b]), target)
                    tol = {None: 1e-3, "rg8": 1.2, "rg16": 0.01}[target]
                    assert measurement.angular_error_deg([a, b], d).max() < tol
        # The square's edges fold onto themselves: (±1, t) and (±1, -t) are one normal, and
        # likewise (t, ±1) and (-t, ±1).
        for t in np.linspace(-1, 1, 21):
            fsq = np.array([[1, t], [1, -t], [-1, t], [-1, -t],
                            [t, 1], [-t, 1], [t, -1], [-t, -1]], F32)
            d = f["decode"](fsq * F32(0.5) + F32(0.5)).reshape(4, 2, 3)
            assert np.allclose(d[:, 0], d[:, 1], atol=1e-6)

    def test_octahedral_signed_zeros_and_corners(self):
        f = impl("octahedral")
        n = np.array([[0.0, -0.0, 1.0], [-0.0, 0.0, -1.0], [-0.0, -0.0, -1.0], [0.0, 1.0, -0.0],
                      [-1.0, -0.0, 0.0]], F32)
        assert np.allclose(f["decode"](f["encode"](n)), n, atol=1e-6)
        corners = np.array([[0, 0], [0, 1], [1, 0], [1, 1]], F32)
        assert np.allclose(f["decode"](corners), [[0, 0, -1]] * 4, atol=1e-6)
        assert np.allclose(f["encode"](np.zeros((1, 3), F32)), [[0.5, 0.5]])   # no NaN

    @pytest.mark.parametrize("scheme, target, bound", [
        ("kircher", "rg8", 1.0), ("kircher", "rg16", 0.005), ("kircher", "rg16f", 0.25),
        ("octahedral", "rg8", 1.0), ("octahedral", "rg16", 0.005),
        ("octahedral", "rg16f", 0.26),
        ("spheremap", "rg8", 13.0), ("spheremap", "rg16", 1.0), ("spheremap", "rg16f", 6.5),
    ])
    def test_measured_error(self, scheme, target, bound):
        # rg16f bounds include llvmpipe's truncating half store (formats.half_toward_zero).
        spec = build(scheme, {}, target)
        assert 0 < spec.error < bound
        assert any("degrees" in note for note in spec.notes)
        # The reported bound holds for fresh random normals as well.
        n = unit(np.random.default_rng(9).normal(size=(50000, 3)))
        if scheme == "kircher":
            n[:, 2] = np.abs(n[:, 2])
        d = round_trip(scheme, n, target)
        assert measurement.angular_error_deg(n, d).max() <= spec.error * 1.05

    def test_spheremap_is_only_bad_far_from_the_camera(self):
        whole = measurement.normal_error("spheremap", "rg8")
        front = measurement.normal_error("spheremap", "rg8", hemisphere=True)
        assert front < 1.0 < whole
        assert front == pytest.approx(measurement.normal_error("kircher", "rg8"), rel=1e-4)


# =============================================================================================
# The generated source against the mirrors, on llvmpipe
# =============================================================================================


VERTEX = "#version 330\nin vec2 p;\nvoid main() { gl_Position = vec4(p, 0.0, 1.0); }\n"


def run_glsl(ctx, source, main, inputs: np.ndarray, out_uint=False):
    """Run ``main`` (GLSL body using ``vec4 a`` = the pixel's input) over one pixel per row of
    ``inputs`` (N, 4) float32; returns (N, 4) float32 or uint32 outputs."""
    import moderngl
    n = len(inputs)
    w = 256
    h = (n + w - 1) // w
    data = np.zeros((h * w, 4), F32)
    data[:n] = inputs
    src_tex = ctx.texture((w, h), 4, data.tobytes(), dtype="f4")
    out_type = "uvec4" if out_uint else "vec4"
    fs = ("#version 330\nuniform sampler2D src;\nout " + out_type + " o;\n" + source +
          "\nvoid main() {\n    vec4 a = texelFetch(src, ivec2(gl_FragCoord.xy), 0);\n" + main +
          "\n}\n")
    prog = ctx.program(vertex_shader=VERTEX, fragment_shader=fs)
    vbo = ctx.buffer(np.array([-1, -1, 3, -1, -1, 3], dtype="f4"))
    vao = ctx.vertex_array(prog, [(vbo, "2f", "p")])
    dst = ctx.texture((w, h), 4, dtype="u4" if out_uint else "f4")
    fbo = ctx.framebuffer([dst])
    fbo.use()
    src_tex.use(0)
    prog["src"] = 0
    vao.render(moderngl.TRIANGLES)
    out = np.frombuffer(fbo.read(components=4, dtype="u4" if out_uint else "f4"),
                        np.uint32 if out_uint else F32).reshape(-1, 4)[:n]
    for obj in (vao, vbo, prog, fbo, dst, src_tex):
        obj.release()
    return out


@pytest.mark.gl
class TestAgainstGL:
    def test_bitplanes(self, gl):
        src = build("bitplanes", {"index_bits": 8}, "rgba8", name="bp").functions_source
        f = impl("bitplanes", {"index_bits": 8}, "rgba8")
        index = np.arange(256)
        got = run_glsl(gl, src, "o = bp_plane_value(uint(a.x));",
                       np.stack([index, 0 * index, 0 * index, 0 * index], -1).astype(F32))
        assert np.array_equal(got, f["plane_value"](index))
        rng = np.random.default_rng(0)
        v = light_index.emulate_bitplanes(rng.integers(1, 256, size=(4, 5000)), 8, "rgba8")
        v = (v + rng.choice(PERTURB, size=v.shape) / 255.0).astype(F32)
        got = run_glsl(gl, src, "o = uvec4(bp_unpack(a, 0), bp_unpack(a, 1), bp_unpack(a, 2), "
                       "bp_unpack(a, 3));", v, out_uint=True)
        assert np.array_equal(got.T, decode_all(f["unpack"], v, 4))

    def test_pairs_slots_split16_bitfield(self, gl):
        rng = np.random.default_rng(1)
        v = rng.integers(0, 256, size=(3000, 4)).astype(F32) / F32(255)
        for scheme, options in [("max_pairs", {}), ("channel_slots", {"slots": 3})]:
            src = build(scheme, options, "rgba8", name="q").functions_source
            got = run_glsl(gl, src, "o = uvec4(q_unpack(a, 0), q_unpack(a, 1), q_unpack(a, 2), "
                           "q_unpack(a, 3));", v, out_uint=True)
            assert np.array_equal(got.T, decode_all(impl(scheme, options, "rgba8")["unpack"],
                                                    v, 4))
        src = build("split16", name="s").functions_source
        x = rng.uniform(-0.1, 1.1, size=(3000, 4)).astype(F32)
        got = run_glsl(gl, src, "o = vec4(s_pack(a.x), s_unpack(a.yz), 0.0);", x)
        f = impl("split16")
        assert np.array_equal(got[:, :2], f["pack"](x[:, 0]))
        assert np.array_equal(got[:, 2], f["unpack"](x[:, 1:3]))
        src = build("bitfield", {"fields": [("object", 8), ("group", 8)]}, name="id") \
            .functions_source
        ab = rng.integers(0, 1024, size=(3000, 4)).astype(F32)
        got = run_glsl(gl, src, "uint v = id_pack(uint(a.x), uint(a.y));\n"
                       "o = uvec4(v, id_object_of(v), id_group_of(v), "
                       "id_from_unorm(id_to_unorm(v)));", ab, out_uint=True)
        f = impl("bitfield", {"fields": [("object", 8), ("group", 8)]})
        packed = f["pack"](ab[:, 0].astype(np.uint32), ab[:, 1].astype(np.uint32))
        assert np.array_equal(got[:, 0], packed)
        assert np.array_equal(got[:, 1], f["object_of"](packed))
        assert np.array_equal(got[:, 3], packed)

    @pytest.mark.parametrize("scheme", NORMAL_SCHEMES)
    def test_normals(self, gl, scheme):
        src = build(scheme, name="nm").functions_source
        f = impl(scheme)
        n = np.concatenate([measurement.fibonacci_sphere(4000), near([0, 1e-6, 1e-3, 1.0]),
                            [[0, 0, 1], [1, 0, 0], [0, -1, 0], [0, 1e-7, -1], [-1e-7, 0, -1]]])
        n = np.concatenate([n, np.zeros((len(n), 1))], -1).astype(F32)
        got = run_glsl(gl, src, "o = vec4(nm_encode(a.xyz), 0.0, 0.0);", n)
        assert np.all(np.isfinite(got))
        assert np.allclose(got[:, :2], f["encode"](n[:, :3]), atol=2e-6)
        g = np.linspace(0, 1, 64, dtype=F32)
        e = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
        e4 = np.concatenate([e, np.zeros_like(e)], -1)
        got = run_glsl(gl, src, "o = vec4(nm_decode(a.xy), 0.0);", e4)
        assert np.all(np.isfinite(got))
        assert np.allclose(got[:, :3], f["decode"](e), atol=2e-6)

    @pytest.mark.parametrize("B, target", [(8, "rgba8"), (4, "rgba8"), (8, "rg8"), (4, "r8")])
    def test_llvmpipe_blends_like_the_fixed_point_emulation(self, gl, B, target):
        """Trebilco's blend on the real rasteriser: exact up to capacity, and beyond it the
        carry behaviour of ``blend_bitplanes(mode="unorm8")``, bit for bit."""
        import moderngl
        try:
            import os
            os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
            from OpenGL import GL
        except Exception as exc:
            pytest.skip(f"no PyOpenGL: {exc}")
        spec = build("bitplanes", {"index_bits": B}, target, name="bp")
        C = fmt(target).channels
        b = B // C
        w, h, L = 128, 64, spec.capacity + 2
        rng = np.random.default_rng(B + C)
        lights = rng.integers(1, 2 ** B, size=(L, h * w))
        fs = ("#version 330\nuniform sampler2D src;\nout vec4 o;\n" + spec.functions_source +
              "\nvoid main() { o = bp_plane_value(uint(texelFetch(src, "
              "ivec2(gl_FragCoord.xy), 0).r)); }\n")
        prog = gl.program(vertex_shader=VERTEX, fragment_shader=fs)
        vbo = gl.buffer(np.array([-1, -1, 3, -1, -1, 3], dtype="f4"))
        vao = gl.vertex_array(prog, [(vbo, "2f", "p")])
        dst = gl.texture((w, h), C, dtype="f1")
        fbo = gl.framebuffer([dst])
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        gl.enable(moderngl.BLEND)
        try:
            gl.blend_func = (moderngl.ONE, 0x8001)        # GL_CONSTANT_COLOR
            c = spec.constants["blend_constant"][1]
            try:
                while GL.glGetError() != GL.GL_NO_ERROR:   # PyOpenGL checks glGetError after
                    pass                                    # each call: clear stale errors
                GL.glBlendColor(c, c, c, c)
            except Exception as exc:
                pytest.skip(f"PyOpenGL cannot reach the context: {exc!r}"[:2000])
            for n in range(L):
                tex = gl.texture((w, h), 1, lights[n].astype(F32).tobytes(), dtype="f4")
                tex.use(0)
                prog["src"] = 0
                vao.render(moderngl.TRIANGLES)
                tex.release()
                codes = np.frombuffer(fbo.read(components=C, dtype="f1"), np.uint8)
                want = light_index.emulate_bitplanes(lights[:n + 1], B, target, "unorm8")
                assert np.array_equal(codes.reshape(-1, C), RGBA8.quantize(want)[:, :C]), n
        finally:
            gl.blend_func = moderngl.DEFAULT_BLENDING
            gl.disable(moderngl.BLEND)
            for obj in (vao, vbo, prog, fbo, dst):
                obj.release()
