"""``python -m pipegen``: the same as the ``pipegen`` command."""

import sys

from .cli import main

sys.exit(main())
