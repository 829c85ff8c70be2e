"""Kept for pipeline modules written by earlier ``pipegen compile`` runs, which import
``GLPipeline`` from here; the pipeline lives in ``runtime/gl/pipeline.py``."""

from pipegen.runtime.gl.pipeline import GLPipeline  # noqa: F401 (re-exported)
