"""``python -m pipegen``: the same as the ``pipegen`` command."""

import sys

from pipegen.cli.main import main

sys.exit(main())
