"""What a ``CLPipeline`` and its parts (``geometry.DrawGeometry``) run on: the process's OpenCL
context and queue (``context.get_context``), the pipeline's programs (one per pass), and the
helpers both use to make device buffers and kernel objects.

``Device(ctx, queue, programs)``: ``buffer(array)`` copies an array to a new device buffer;
``kernel(k, name)`` is pass ``k``'s kernel ``name``, one object per (pass, name) for the
device's lifetime (``scene_vertex_kernel(names)``: the vertex kernel of a union of scene
passes' varyings); ``dummy`` and ``zeros4`` are placeholder buffers for arguments a kernel
does not read (``dummy``) or reads as zeros (``zeros4``: one float4 row, the attributes a
draw does not have).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from pipegen.backends.opencl.programs import scene_vertex_program
from pipegen.runtime.cl import context as cl_context
from pipegen.runtime.cl.targets import device_buffer

__all__ = ["Device"]


class Device:
    def __init__(self, ctx, queue, programs: Sequence):
        self.ctx = ctx
        self.queue = queue
        self.programs = tuple(programs)
        self.kernels: dict = {}
        self.dummy = self.buffer(np.zeros(4, np.int32))
        self.zeros4 = self.buffer(np.zeros((1, 4), np.float32))

    def buffer(self, array: np.ndarray):
        """A read-write device buffer holding a copy of ``array`` (``targets.device_buffer``)."""
        return device_buffer(self.ctx, array)

    def kernel(self, k: int, name: str):
        """Kernel objects are cached: pyopencl builds an argument invoker per Kernel object
        (and ``context.set_args`` declares its scalar types once)."""
        kern = self.kernels.get((k, name))
        if kern is None:
            import pyopencl as cl
            kern = self.kernels[(k, name)] = cl.Kernel(self.programs[k], name)
        return kern

    def scene_vertex_kernel(self, names: tuple[str, ...]):
        """The scene vertex kernel computing the varyings ``names`` (``programs
        .scene_vertex_program``), one object per union."""
        kern = self.kernels.get(("scene_vertex", names))
        if kern is None:
            import pyopencl as cl
            prog = cl_context.build_program(scene_vertex_program(names))
            kern = self.kernels[("scene_vertex", names)] = cl.Kernel(prog, "pg_vertex")
        return kern
