"""``python -m tipgeo.cli``: the ``tipgeo`` command."""

import sys

from . import main

sys.exit(main())
