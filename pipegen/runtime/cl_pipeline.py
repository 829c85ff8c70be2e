"""Kept for pipeline modules written by earlier ``pipegen compile`` runs, which import
``CLPipeline`` from here; the pipeline lives in ``runtime/cl/pipeline.py``."""

from pipegen.runtime.cl.pipeline import CLPipeline  # noqa: F401 (re-exported)
