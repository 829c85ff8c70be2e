"""``pipegen``: compile, run, check and describe rendering techniques.

Every user error is printed as ``file:line:col``, the line, a caret and a hint (or ``error: …``
and a hint when it is not about a place in a file), and exits with status 1; misuse of the
command line itself (an unknown option, a malformed ``--size`` or ``-p``) exits with 2,
argparse's convention.  A traceback reaching the user for bad input is a bug.

Output folders (``-o``) are checked before any work and written through ``outdir.OutputDir``:
pipegen never deletes or overwrites a file it did not write.

The parser is in ``parser.py`` (its help text in ``help_text.py``, the option types in
``arguments.py``), the subcommands in ``commands.py``; this module parses, runs the subcommand
and turns errors into messages and exit statuses.
"""

from __future__ import annotations

import gc
import sys

from pipegen.cli.arguments import join_negative_sizes
from pipegen.cli.parser import build_parser
from pipegen.core.diagnostics import PipegenError


def main(argv: list[str] | None = None) -> int:
    if argv is None:
        # the command's own process (not a call from Python): what the imports built lives
        # as long as the process, and frozen the collector no longer scans it at every full
        # collection of what a compile allocates (2-3 % of a compile's instructions)
        gc.freeze()
    argv = join_negative_sizes(sys.argv[1:] if argv is None else argv)
    parser = build_parser(argv[0] if argv else None)
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help(sys.stderr)
        return 2
    try:
        return args.func(args)
    except PipegenError as e:
        print(e.render(), file=sys.stderr)
        return 1
    except OSError as e:
        where = f": '{e.filename}'" if e.filename else ""
        print(f"error: {e.strerror or e}{where}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
