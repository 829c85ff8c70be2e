"""The ``pipegen`` command (``main``); its parser and subcommands are in ``main``."""

from pipegen.cli.main import main  # noqa: F401 (the console script's entry point)
