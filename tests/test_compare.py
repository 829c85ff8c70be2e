"""The comparator must be able to fail: tolerances come from formats.py and are not loose."""

import numpy as np
import pytest

from pipegen.core import formats
from pipegen.proof.compare import EDGE_MIN, compare_target, ulp_distance

RGBA8 = formats.get("rgba8")


def smooth_image(h=32, w=32):
    y, x = np.mgrid[0:h, 0:w]
    img = np.stack([x * 3, y * 3, (x + y) * 2, np.full_like(x, 255)], -1)
    return img.astype(np.uint8)


def test_one_code_in_interior_passes():
    a = smooth_image()
    b = a.copy()
    b[16, 16, 0] += 1
    assert compare_target("color", RGBA8, a, b).passed


def test_two_codes_in_interior_of_target_written_once_fails():
    a = smooth_image()
    b = a.copy()
    b[16, 16, 0] += 2
    c = compare_target("color", RGBA8, a, b, blended_passes=0)
    assert not c.passed and c.over == 1 and c.max_error == 2


def test_blended_passes_widen_the_unorm_tolerance():
    a = smooth_image()
    b = a.copy()
    b[16, 16, 0] += 2
    assert compare_target("color", RGBA8, a, b, blended_passes=1).passed


def test_one_bit_change_in_packed_index_target_fails():
    idx = formats.get("rgba8")
    a = np.zeros((16, 16, 4), np.uint8)
    a[4:12, 4:12] = (0b11000000, 0b01000000, 0, 0)
    b = a.copy()
    b[8, 8, 1] ^= 0b00010000
    tol = formats.Tolerance("exact", 0)
    c = compare_target("lightidx", idx, a, b, tolerance=tol)
    assert not c.passed and c.over == 1


def test_integer_targets_are_exact():
    fmt = formats.get("r32ui")
    a = np.arange(64, dtype=np.uint32).reshape(8, 8)
    b = a.copy()
    b[3, 3] += 1
    assert not compare_target("ids", fmt, a, b).passed


def edge_images(shift_rows):
    a = np.zeros((64, 64, 4), np.uint8)
    a[:, 32:] = 200
    b = a.copy()
    for r in shift_rows:           # the edge moved by one pixel on these rows
        b[r, 31] = 200
    return a, b


def test_edge_only_differences_pass_within_the_bound():
    a, b = edge_images(range(3))
    c = compare_target("color", RGBA8, a, b)
    assert c.passed and c.edge_admitted == 3 and c.over == 0


def test_edge_only_differences_fail_beyond_the_bound():
    a, b = edge_images(range(64))
    c = compare_target("color", RGBA8, a, b)
    assert c.edge_admitted == 64 > c.edge_bound >= EDGE_MIN
    assert not c.passed


def test_ulp_distance_handles_signed_zero_nan_inf_and_denormals():
    a = np.array([1.0, -0.0, np.nan, np.inf, 1e-40, 1.0], np.float32)
    b = np.array([np.nextafter(np.float32(1), np.float32(2)), 0.0, np.nan, np.inf, 0.0,
                  np.nan], np.float32)
    d = ulp_distance(a, b)
    assert list(d[:5]) == [1, 0, 0, 0, 0]
    assert d[5] == np.inf


@pytest.mark.parametrize("name", ["rgba16f", "r16f"])
def test_half_tolerance_has_absolute_floor(name):
    fmt = formats.get(name)
    shape = (8, 8, fmt.channels) if fmt.channels > 1 else (8, 8)
    a = np.zeros(shape, np.float16)
    b = a.copy()
    b[2, 2] = np.float16(2.0 ** -15)          # thousands of ulps from 0, but below the floor
    assert compare_target("accum", fmt, a, b).passed
    b[2, 2] = np.float16(0.01)
    assert not compare_target("accum", fmt, a, b).passed


def test_float32_differences_near_zero_count_in_ulps():
    """The backends interpolate bit-exactly, so a float32 target gets no range-relative
    slack: a small absolute difference near zero is thousands of ulps and fails."""
    fmt = formats.get("rgba32f")
    a = np.zeros((8, 8, 4), np.float32)
    a[..., 0] = np.linspace(-24, 24, 64).reshape(8, 8)
    b = a.copy()
    b[3, 3, 1] = 2e-5
    assert not compare_target("gpos", fmt, a, b).passed
    b[3, 3, 1] = 5e-7                          # below the format's 1e-6 absolute floor
    assert compare_target("gpos", fmt, a, b).passed
