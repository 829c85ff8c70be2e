"""The moderngl runtime: a headless GL context, formats, fixed-function state and its
transitions, and the pipeline that runs a technique's passes."""
