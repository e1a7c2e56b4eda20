#!/usr/bin/env python
"""Regenerate every figure and table of the study into ``results/`` and write ``results/REPORT.md``.

``python run_all.py [options]`` (``python run_all.py --help``; ``shapelib study`` is the same): a
thin entry over :mod:`shapelib.study.runner`, which holds the runner, and
:mod:`shapelib.study.notebooks`, the table of the study's notebooks. ``import run_all`` gives the
runner module itself, so ``run_all.run_one``, ``run_all.NOTEBOOKS``, ... are its own.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # this checkout's shapelib

from shapelib.study import runner  # noqa: E402

if __name__ == "__main__":
    sys.exit(runner.main())
else:
    sys.modules[__name__] = runner
