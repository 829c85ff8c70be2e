"""The OpenCL C backend: the per-pixel kernels and the 8-pixel wide path."""
