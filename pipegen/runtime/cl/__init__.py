"""The PoCL runtime: the OpenCL context, triangle set-up (host and device), binning, the
draws' geometry, targets, and the pipeline that runs a technique's kernels."""
