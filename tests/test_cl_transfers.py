"""``runtime/cl/transfers.write``: host rows staged in a buffer of their own land where a
blocking write puts them, behind a kernel writing the same buffer, at an offset, and the host
array may change as soon as it returns; an empty array queues nothing."""

import numpy as np
import pytest

pytestmark = pytest.mark.cl
cl = pytest.importorskip("pyopencl")

KERNEL = "__kernel void fill(__global int *a, int v) { a[get_global_id(0)] = v + get_global_id(0); }"


def test_staged_writes_land_where_blocking_writes_do():
    from pipegen.runtime.cl import context as cl_context
    from pipegen.runtime.cl.transfers import write
    ctx, queue = cl_context.get_context()
    fill = cl.Kernel(cl_context.build_program(KERNEL), "fill")
    buf = cl.Buffer(ctx, cl.mem_flags.READ_WRITE, 4096)
    cl_context.set_args(fill, buf, np.int32(1000))
    cl.enqueue_nd_range_kernel(queue, fill, (1024,), (16,))
    staged = np.arange(-40, -30, dtype=np.int32)
    write(queue, buf, staged, dst_offset=64)           # ints 16..25, behind the kernel
    staged[:] = 7                                      # free once write returns
    write(queue, buf, np.empty(0, np.int32), dst_offset=0)
    got = np.empty(1024, np.int32)
    cl.enqueue_copy(queue, got, buf)
    want = 1000 + np.arange(1024, dtype=np.int32)
    want[16:26] = np.arange(-40, -30)
    assert np.array_equal(got, want)
