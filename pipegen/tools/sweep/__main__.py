"""``python -m pipegen.tools.sweep``: the timing process ``jobs.time_job`` starts (a JSON job
on stdin, one JSON line on stdout).  A failure ends it with one ``error:`` line on stderr (a
``PipegenError`` as pipegen prints one; anything else named by its type), which the parent
reports: never a traceback (``PIPEGEN_TRACEBACK=1`` prints one too)."""

import os
import sys
import traceback

from pipegen.tools.sweep.jobs import timing_main


def main() -> int:
    try:
        return timing_main()
    except KeyboardInterrupt:
        return 130
    except Exception as e:                  # noqa: B902 - reported by the parent, in one line
        from pipegen.core.diagnostics import PipegenError
        if os.environ.get("PIPEGEN_TRACEBACK"):
            traceback.print_exc()
        text = e.render() if isinstance(e, PipegenError) else f"error: {type(e).__name__}: {e}"
        print(text.replace("\n", " / "), file=sys.stderr, flush=True)
        return 1


if __name__ == "__main__":
    sys.exit(main())
