"""The ``pipegen`` command (``main``, in ``main.py``); its parser is in ``parser.py``, its
subcommands in ``commands.py``."""

from pipegen.cli.main import main  # noqa: F401 (the console script's entry point)
