"""``python -m tipgeo``: the ``tipgeo`` command."""

import sys

from .cli import main

sys.exit(main())
