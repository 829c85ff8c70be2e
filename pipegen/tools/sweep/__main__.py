"""``python -m pipegen.tools.sweep``: the timing process ``jobs.time_job`` starts (a JSON job
on stdin, one JSON line on stdout)."""

import sys

from pipegen.tools.sweep.jobs import timing_main

if __name__ == "__main__":
    sys.exit(timing_main())
