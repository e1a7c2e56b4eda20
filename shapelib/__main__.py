"""``python -m shapelib``: the command line (:mod:`shapelib.cli`)."""

import sys

try:
    from .cli import main
except KeyboardInterrupt:  # Ctrl-C while the libraries load: no traceback either
    print("shapelib: interrupted", file=sys.stderr)
    sys.exit(130)

sys.exit(main())
