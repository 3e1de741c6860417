"""``python -m ambulo.cli <command> ...``: the same as the ``ambulo`` console script."""

import sys

from . import main

sys.exit(main())
