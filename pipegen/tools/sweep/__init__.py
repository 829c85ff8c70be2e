"""``pipegen sweep``: render techniques over the cartesian product of their parameters, on
each backend, and measure frame time (with its spread), target memory and error against a
float64 reference.

    pipegen sweep FILE [FILE ...] [--scene S] [--size WxH] [-p NAME=V1,V2,...]...
                  [--backend gl,cl] [--frames N] [--jobs N] [--threads T]
                  [--reference R] [--reference-samples N] [--scheduler tcp://HOST:PORT]
                  -o DIR [--resume] [--force]

Variants.  ``-p NAME=V1,V2`` gives an axis (repeatable); without any ``-p`` every parameter
with declared allowed values (``param x = a in {a, b}``) is an axis, and so is every ``bool``
parameter (its type allows exactly ``false, true``).  Each file is swept over the axes it
declares (several files compare techniques on the same axes, e.g. the three LIDRs).

Two phases, never overlapping:

1. **Renders and errors** (``jobs.render_job``, one job per variant) in a local pool of worker
   processes (``--jobs``, default: the CPUs this process may use; ``worker.py``: they import
   only pipegen, so a sweep runs from a notebook or a script on standard input) or, with
   ``--scheduler``, on a Dask distributed cluster.  Per variant: a render on each backend, the
   ``check`` verdict (GL vs CL, target by target, ``check.compare_targets``), the f64
   evaluation (``compiled.pipeline("cl", precision="f64")``), errors of the output target
   against the reference (``--reference``: ``proof/references.py``, each technique's default
   without it; ``accuracy.codes_vs_reference``, with the worst pixels) and the f64 evaluation,
   mean ꟻLIP, an error map and the image.  Rendering is deterministic, so the pool and the
   cluster give the same numbers.
2. **Frame times** (``jobs.time_job``), after every render job has finished: one fresh process
   (on this machine, or on one Dask worker) with ``LP_NUM_THREADS`` and
   ``POCL_MAX_PTHREAD_COUNT`` set to ``--threads`` and its CPU affinity pinned to that many
   CPUs, builds every variant's pipelines, renders each once untimed (shader and kernel
   compilation), then times ``--frames`` rounds; each round times every variant once, in
   alternating order (forward, then backward), so drift on the machine hits all variants
   alike.  The figure is the median, with the interquartile range: rows whose ranges overlap
   are ties, never ranked (``pareto.py``).  GL: ``GLPipeline.frame`` (all passes,
   ``glFinish``, no read-back); CL: ``CLPipeline.frame`` (all passes, the queue drained, no
   read-back).  ``--frames 0`` skips this phase.

Outputs in DIR (an output folder like ``run``'s: see docs/cli.md): ``index.html`` (the report to
explore, ``report_html.py``), ``results.csv`` and ``results.json`` (one row per variant and
backend, ``result.COLUMNS`` then ``EXTRA_COLUMNS``; the JSON adds ``JSON_ONLY`` per row),
``table.txt`` (the printed table), ``pareto.png`` (frame time against error per backend, the
Pareto front and its ties drawn), ``errors/NN_<variant>_<backend>.png`` (error maps against the
reference, 0 black to ``accuracy.ERROR_MAP_VMAX`` codes white), ``images/`` (the outputs) and
``rows.jsonl`` (the journal).  Each variant's files and rows are committed as its render job
finishes (``journal.py``): the folder is valid after any row, Ctrl-C exits 130 with the rows so
far and the command to resume, and ``--resume`` renders only the variants missing, then times
every variant again.

The modules:

- ``variants.py``: ``Variant``, ``parse_axes``, ``declared_axes``, ``plan_variants``;
- ``jobs.py``: scene specs (a path or a pickled ``Scene``), ``render_job`` (phase 1),
  ``time_job`` and the timing process (phase 2; ``__main__.py`` runs it:
  ``python -m pipegen.tools.sweep``);
- ``pools.py``: the local pool and the Dask cluster; ``worker.py``: the local pool's
  processes; ``progress.py``: progress bars;
- ``result.py``: ``SweepResult``, the columns and the printed table;
- ``run.py``: ``run_sweep``, the two phases; ``commands.py``: each row's command;
- ``journal.py``: ``rows.jsonl``, the rows committed as they finish, ``--resume``;
- ``outputs.py``: ``results.csv``, ``results.json``, ``write_outputs``, ``load_result``;
  ``pareto.py``: ``pareto_front`` (with ties), ``pareto.png``; ``plot_svg.py`` and
  ``report_html.py``: ``index.html``;
- ``command.py``: the subcommand (``add_parser``, ``cmd_sweep``).

From Python::

    from pipegen.scene.load import load_scene
    from pipegen.tools.sweep.run import run_sweep
    from pipegen.tools.sweep.outputs import write_outputs
    result = run_sweep(["pipelines/inferred.pipe"], load_scene("examples/scenes/edges.toml"),
                       size=(320, 180), axes={"dsf": [False, True]}, reference="scene")
    print(result.summary())
    write_outputs(result, "out/sweep")
"""
