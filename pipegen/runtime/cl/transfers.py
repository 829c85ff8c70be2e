"""Host -> device writes that do not wait for the queue.

On PoCL 3.0 (the pocl-binary-distribution wheel) a "non-blocking" ``clEnqueueWriteBuffer`` or
``clEnqueueReadBuffer`` between a buffer and host memory returns only once every command
queued before it has run: ``enqueue_copy(queue, buf, array, is_blocking=False)`` queued behind
a 1.1 s kernel took 1.1 s to return (the buffer need not be one the kernel uses), while a
buffer-to-buffer copy, a fill, a kernel or a non-blocking ``clEnqueueMapBuffer`` return in
~0.1 ms.  ``write(queue, buf, host, dst_offset)`` therefore copies ``host`` into a new buffer at
once (``COPY_HOST_PTR``: no queue command) and queues a buffer-to-buffer copy; the host array
is free when it returns (no array to keep alive until the copy has run).

Read-backs stay ``enqueue_copy(..., is_blocking=False)``: a mapped read (map without waiting,
copy and unmap on ``wait()``) kept the host from waiting at each set-up and binning, but its
two extra queue commands a read cost more than the waits saved except on a heavily loaded
machine (frames interleaved in one process, LP_NUM_THREADS = POCL_MAX_PTHREAD_COUNT = 2: load
6-8, deferred_calver 160x90 0.80x, light_prepass 0.92x; load ~3, medians of 30:
deferred_calver 160x90 1.05x, inferred 1.07x, deferred_calver 640x360 1.11x).
"""

from __future__ import annotations

import numpy as np

__all__ = ["write"]


def write(queue, buf, host: np.ndarray, dst_offset: int = 0) -> None:
    """Queue the copy of ``host`` into ``buf`` at ``dst_offset`` bytes without waiting (the
    module docstring); ``host`` may change as soon as this returns."""
    import pyopencl as cl
    host = np.ascontiguousarray(host)
    if not host.nbytes:
        return
    staged = cl.Buffer(queue.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                       hostbuf=host)
    cl.enqueue_copy(queue, buf, staged, byte_count=host.nbytes, dst_offset=int(dst_offset))
