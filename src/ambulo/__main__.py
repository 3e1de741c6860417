"""``python -m ambulo <command> ...``: the same as the ``ambulo`` console script."""

import sys

from .cli import main

sys.exit(main())
