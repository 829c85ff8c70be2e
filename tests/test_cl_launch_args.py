"""Kernel arguments are set with their scalar types declared (``cl_context.set_args``, every
launch of the CL runtime): a pipeline that renders one scene after another gives the same
targets as fresh pipelines, and pyopencl's own argument probing at every launch changes
nothing."""

from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.cl
pytest.importorskip("pyopencl")

ROOT = Path(__file__).resolve().parents[1]


def _scene(name):
    from pipegen import load_scene
    return load_scene(ROOT / "examples" / "scenes" / f"{name}.toml")


def _same(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for name in a:
        assert np.array_equal(a[name], b[name]), name


@pytest.mark.parametrize("technique", ["deferred", "lidr_bitplanes"])
def test_renders_in_a_row_match_fresh_pipelines_and_full_argument_setting(technique,
                                                                          monkeypatch):
    from pipegen import compile_file
    from pipegen.runtime.cl import context as cl_context
    compiled = compile_file(ROOT / "pipelines" / f"{technique}.pipe")
    first, second = _scene("mixed_lights"), _scene("street_lamps")
    reused = compiled.pipeline("cl", (96, 54))
    a1, b1, a2 = reused.render(first), reused.render(second), reused.render(first)
    _same(a1, a2)
    _same(b1, compiled.pipeline("cl", (96, 54)).render(second))
    monkeypatch.setattr(cl_context, "set_args", lambda kern, *args: kern.set_args(*args))
    _same(a1, compiled.pipeline("cl", (96, 54)).render(first))


def test_typed_arguments_take_numpy_scalars_only():
    """A Python number has no OpenCL type to declare: ``set_args`` refuses it."""
    import pyopencl as cl
    from pipegen.backends.opencl import programs as cl_programs
    from pipegen.runtime.cl import context as cl_context
    kern = cl.Kernel(cl_context.build_program(cl_programs.bin_program()), "pg_bin_starts")
    ctx, _ = cl_context.get_context()
    bufs = [cl.Buffer(ctx, cl.mem_flags.READ_WRITE, size=64) for _ in range(4)]
    scalars = [np.int32(2), np.int32(1), np.int32(1), np.int32(1), np.int32(3), np.int32(1)]
    with pytest.raises(TypeError, match="numpy scalars"):
        cl_context.set_args(kern, 1, *scalars, *bufs)
    cl_context.set_args(kern, np.int32(1), *scalars, *bufs)
    assert kern._pg_typed


def test_profile_drains_each_pass_and_changes_nothing():
    """``CLPipeline.profile``: one (pass, light, host_s, device_s) row per pass execution, in
    the schedule's order, and the same targets as an unprofiled frame."""
    from pipegen import compile_file
    from pipegen.runtime import draws
    compiled = compile_file(ROOT / "pipelines" / "deferred.pipe")
    scene = _scene("mixed_lights")
    pipe = compiled.pipeline("cl", (96, 54))
    plain = pipe.render(scene)
    pipe.profile = []
    _same(plain, pipe.render(scene))
    runs = list(draws.schedule(pipe.plan, pipe._selection))
    assert [(name, light) for name, light, _, _ in pipe.profile] == [
        (pipe.plan.passes[k].name, light) for k, light in runs]
    assert all(host >= 0 and dev >= 0 for _, _, host, dev in pipe.profile)


def test_vector_scalars_are_declared_and_reach_the_kernel():
    """``cltypes.make_int2`` values (0-d arrays) are declared with their vector type, as numpy
    scalars are (undeclared, pyopencl probes them at every call), and arrive intact."""
    import pyopencl as cl
    from pipegen.runtime.cl import context as cl_context
    ctx, queue = cl_context.get_context()
    kern = cl.Kernel(cl_context.build_program(
        "__kernel void k(__global int *o, const int2 s, const int n) "
        "{ o[0] = s.x; o[1] = s.y; o[2] = n; }"), "k")
    declared = []
    declare = kern.set_scalar_arg_dtypes
    kern.set_scalar_arg_dtypes = lambda dtypes: (declared.append(list(dtypes)), declare(dtypes))
    out = cl.Buffer(ctx, cl.mem_flags.READ_WRITE, size=64)
    size = cl.cltypes.make_int2(7, -3)
    cl_context.set_args(kern, out, size, np.int32(5))
    assert declared == [[None, size.dtype, np.dtype(np.int32)]]
    cl.enqueue_nd_range_kernel(queue, kern, (1,), (1,))
    got = np.zeros(3, np.int32)
    cl.enqueue_copy(queue, got, out)
    assert got.tolist() == [7, -3, 5]
