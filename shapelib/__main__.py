"""``python -m shapelib``: the command line (:mod:`shapelib.cli`)."""

import sys

from .cli import main

sys.exit(main())
