"""``python -m pipegen.cli``: the same as the ``pipegen`` command (and ``python -m pipegen``)."""

import sys

from pipegen.cli.main import main

sys.exit(main())
