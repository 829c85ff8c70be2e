"""``pipegen tune``: the cheapest parameter values of a technique whose error against a
reference stays within a budget (docs/accuracy.md, "`pipegen tune`").

- ``budget.py``: the budget (``"p99<=2, lights_dropped==0"``) parsed into ``Bound`` terms;
- ``measure.py``: one configuration measured (rendered, counted, cached): error figures
  against the reference on each scene, lights dropped, target memory, frame time;
- ``search.py``: the search (screen, corner, floors, cost-ordered walk with monotone pruning);
- ``command.py``: the subcommand, its printed report and ``DIR/tune.json``.
"""
