"""``pipegen sweep``: render techniques over the cartesian product of their parameters, on
each backend, and measure frame time, target memory and error against float64 references.

    pipegen sweep FILE [FILE ...] [--scene S] [--size WxH] [-p NAME=V1,V2,...]...
                  [--backend gl,cl] [--frames N] [--jobs N] [--threads T]
                  [--scheduler tcp://HOST:PORT] -o DIR [--force]

Variants.  ``-p NAME=V1,V2`` gives an axis (repeatable); without any ``-p`` every parameter
with declared allowed values (``param x = a in {a, b}``) is an axis, and so is every ``bool``
parameter (its type allows exactly ``false, true``).  Each file is swept over the axes it
declares (several files compare techniques on the same axes, e.g. the three LIDRs).

Two phases, never overlapping:

1. **Renders and errors** (``jobs.render_job``, one job per variant) in a local process pool
   (``--jobs``, default: the CPUs this process may use) or, with ``--scheduler``, on a Dask
   distributed cluster.  Per variant: a render on each backend, the ``check`` verdict (GL vs
   CL, target by target, ``check.compare_targets``), the f64 evaluation
   (``compiled.pipeline("cl", precision="f64")``, where the compiler offers it), errors of the
   output target against the scene reference and the f64 evaluation (``proof/accuracy.py``), mean
   ꟻLIP, and an error map.  Rendering is deterministic, so the pool and the cluster give the
   same numbers.
2. **Frame times** (``jobs.time_job``), after every render job has finished: one fresh process
   (on this machine, or on one Dask worker) with ``LP_NUM_THREADS`` and
   ``POCL_MAX_PTHREAD_COUNT`` set to ``--threads`` and its CPU affinity pinned to that many
   CPUs, builds every variant's pipelines, renders each once untimed (shader and kernel
   compilation), then times ``--frames`` rounds; each round times every variant once, in
   alternating order (forward, then backward), so drift on the machine hits all variants
   alike.  The figure is the median.  GL: ``GLPipeline.frame`` (all passes, ``glFinish``, no
   read-back); CL: ``CLPipeline.render`` (all passes and the read-back of every target: the CL
   runtime has no frame without read-back).  ``--frames 0`` skips this phase.

Outputs in DIR (an output folder like ``run``'s: see docs/cli.md): ``results.csv`` and
``results.json`` (one row per variant and backend, ``result.COLUMNS``), ``table.txt`` (the printed
table), ``pareto.png`` (frame time against scene error per backend, the Pareto front drawn),
``errors/NN_<variant>_<backend>.png`` (error maps against the scene reference, 0 black to
``accuracy.ERROR_MAP_VMAX`` codes white).

The modules:

- ``variants.py``: ``Variant``, ``parse_axes``, ``declared_axes``, ``plan_variants``;
- ``jobs.py``: scene specs, ``render_job`` (phase 1), ``time_job`` and the timing process
  (phase 2; ``__main__.py`` runs it: ``python -m pipegen.tools.sweep``);
- ``pools.py``: the local process pool and the Dask cluster; ``progress.py``: progress bars;
- ``result.py``: ``SweepResult``, the columns and the printed table;
- ``run.py``: ``run_sweep``, the two phases in memory;
- ``outputs.py``: ``results.csv``, ``results.json``, ``write_outputs``, ``load_result``;
  ``pareto.py``: ``pareto_front``, ``pareto.png``;
- ``command.py``: the subcommand (``add_parser``, ``cmd_sweep``).

From Python::

    from pipegen.tools.sweep.run import run_sweep
    from pipegen.tools.sweep.outputs import write_outputs
    result = run_sweep(["pipelines/inferred.pipe"], size=(320, 180), axes={"dsf": [False, True]})
    print(result.summary())
    write_outputs(result, "out/sweep")
"""
