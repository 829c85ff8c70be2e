"""The CL runtime's frame structs (``pg_frame`` / ``pg_frame64``) are filled in one place:
matrices column-major, float32 the rounding of the float64 values, inverses derived."""
import numpy as np

from pipegen.runtime.cl.pipeline import FRAME64_DTYPE, FRAME_DTYPE, _frame_structs, _put_matrices


def _mats(seed):
    rng = np.random.default_rng(seed)
    return [rng.normal(size=(4, 4)) + 4 * np.eye(4) for _ in range(4)]


def test_frame_structs_layout():
    view, proj, pview, pproj = _mats(1)
    fr, f8 = _frame_structs(view, proj, pview, pproj, (1.0, 2.0, 3.0), (0.1, 0.2, 0.3),
                            (96, 54), 5, 2, 7, True)
    assert fr.dtype == FRAME_DTYPE and f8.dtype == FRAME64_DTYPE
    expect = {"view": view, "proj": proj, "inv_view": np.linalg.inv(view),
              "inv_proj": np.linalg.inv(proj), "prev_view": pview, "prev_proj": pproj}
    for name, m in expect.items():
        # column-major: element (row r, column c) at c * 4 + r
        assert np.array_equal(f8[name].reshape(4, 4).T, m)
        assert np.array_equal(fr[name].reshape(4, 4).T, m.astype(np.float32))
    for s, t in ((fr, np.float32), (f8, np.float64)):
        assert np.array_equal(s["camera_pos"], np.array([1, 2, 3, 0], t))
        assert np.array_equal(s["ambient"][:3], np.array([0.1, 0.2, 0.3], t))
        assert tuple(s["output_size"]) == (96, 54, 0, 0)
        assert (int(s["num_lights"]), int(s["light"]), int(s["light_rows"])) == (5, 2, 7)


def test_frame_structs_f32_only_and_put_matrices():
    view, proj, pview, pproj = _mats(2)
    fr, f8 = _frame_structs(view, proj, pview, pproj, (0, 0, 0), (0, 0, 0), (8, 8), 0, 0, 0,
                            False)
    assert f8 is None
    lview, lproj = _mats(3)[:2]
    sh = fr.copy()
    _put_matrices(sh, None, view=lview, proj=lproj)     # a shadow view: only view/proj change
    assert np.array_equal(sh["view"].reshape(4, 4).T, lview.astype(np.float32))
    assert np.array_equal(sh["proj"].reshape(4, 4).T, lproj.astype(np.float32))
    for name in ("inv_view", "inv_proj", "prev_view", "prev_proj", "camera_pos"):
        assert np.array_equal(sh[name], fr[name])
