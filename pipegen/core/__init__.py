"""The bottom layer: what every stage uses and that knows nothing of techniques.

``records`` (the small node classes), ``diagnostics`` (spans, ``PipegenError``, the
``file:line:col`` message with its caret), ``float32`` (float32 arithmetic and text),
``formats`` (the render-target formats: the one source of truth for codes, ranges and
rounding), ``sources`` (reading ``.pipe`` files and ``include``), ``outdir`` (output folders
pipegen owns, written atomically), ``package_files`` (shipped files and the cache folder),
``defaults`` (the default frame size and the version), ``units`` (byte counts as text).
"""
