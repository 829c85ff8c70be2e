"""``runtime/cl/transfers.py``: read-backs through a mapped buffer and writes staged in a buffer
of their own land the bytes a blocking copy would, behind kernels that write the same buffer,
at offsets, and with an empty array."""

import numpy as np
import pytest

pytestmark = pytest.mark.cl
cl = pytest.importorskip("pyopencl")

KERNEL = "__kernel void fill(__global int *a, int v) { a[get_global_id(0)] = v + get_global_id(0); }"


def test_readback_and_write_move_the_bytes_of_blocking_copies():
    from pipegen.runtime.cl import context as cl_context
    from pipegen.runtime.cl.transfers import Readback, write
    ctx, queue = cl_context.get_context()
    fill = cl.Kernel(cl_context.build_program(KERNEL), "fill")
    buf = cl.Buffer(ctx, cl.mem_flags.READ_WRITE, 4096)
    cl_context.set_args(fill, buf, np.int32(1000))
    cl.enqueue_nd_range_kernel(queue, fill, (1024,), (16,))
    staged = np.arange(-40, -30, dtype=np.int32)
    write(queue, buf, staged, dst_offset=64)           # ints 16..25, behind the kernel
    staged[:] = 7                                      # free once write returns
    head, middle, none = np.empty(20, np.int32), np.empty(6, np.int32), np.empty(0, np.int32)
    reads = [Readback(queue, head, buf), Readback(queue, middle, buf, src_offset=4 * 22),
             Readback(queue, none, buf)]
    for r in reads:
        r.wait()
    r.wait()                                           # a second wait changes nothing
    want = 1000 + np.arange(1024, dtype=np.int32)
    want[16:26] = np.arange(-40, -30)
    assert np.array_equal(head, want[:20])
    assert np.array_equal(middle, want[22:28])
    blocking = np.empty(1024, np.int32)
    cl.enqueue_copy(queue, blocking, buf)
    assert np.array_equal(blocking, want)
