"""Host <-> device copies that do not wait for the queue.

On PoCL 3.0 (the pocl-binary-distribution wheel) a "non-blocking" ``clEnqueueReadBuffer`` or
``clEnqueueWriteBuffer`` between a buffer and host memory returns only once every command
queued before it has run: ``enqueue_copy(queue, array, buf, is_blocking=False)`` queued behind a
1.1 s kernel took 1.1 s to return (the buffer need not be one the kernel uses), while a
non-blocking ``clEnqueueMapBuffer``, a buffer-to-buffer copy, a fill or a kernel return in
~0.1 ms.  The runtime queues a frame's vertex, set-up and binning work with read-backs of a
few host fields between them, meant to run while the host goes on; each read made the host
wait for everything queued so far, so host and device took turns.  Hence:

- ``Readback(queue, host, buf, src_offset)``: maps the bytes ``host`` will hold for reading
  without waiting; ``wait()`` waits for the map, copies into ``host`` and unmaps (as the
  event of a non-blocking copy, ``wait()`` before reading ``host``).
- ``write(queue, buf, host, dst_offset)``: ``host`` copied into a new buffer at once (a
  ``COPY_HOST_PTR`` buffer: no queue command), then a buffer-to-buffer copy queued; the host
  array is free when it returns.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Readback", "write"]


class Readback:
    """A device-to-host copy of ``host.nbytes`` bytes of ``buf`` from ``src_offset`` into
    ``host``, queued without waiting (the module docstring)."""

    def __init__(self, queue, host: np.ndarray, buf, src_offset: int = 0):
        import pyopencl as cl
        assert host.flags.c_contiguous, "a read-back fills a contiguous array"
        self.queue, self.host = queue, host
        self._mapped = self._event = None
        if host.nbytes:
            self._mapped, self._event = cl.enqueue_map_buffer(
                queue, buf, cl.map_flags.READ, int(src_offset), host.shape, host.dtype,
                is_blocking=False)

    def wait(self) -> None:
        """Wait for the copy: ``host`` holds the bytes afterwards (the buffer is unmapped)."""
        if self._mapped is None:
            return
        self._event.wait()
        self.host[...] = self._mapped
        self._mapped.base.release(self.queue)
        self._mapped = self._event = None


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
