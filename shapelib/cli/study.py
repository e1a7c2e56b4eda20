"""``shapelib study``: ``run_all.py`` of the source checkout, with the same options."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from ._common import CLIError


def find_run_all() -> Path | None:
    """``run_all.py`` of the source checkout this package was imported from, or None."""
    from ..study import is_checkout

    root = Path(__file__).resolve().parents[2]
    return root / "run_all.py" if is_checkout(root) else None


def cmd_study(run_all_args) -> int:
    """``shapelib study ARGS``: ``run_all.py ARGS`` of the source checkout, every option passed
    through unchanged (``shapelib study --help`` is run_all.py's help)."""
    script = find_run_all()
    if script is None:
        raise CLIError("`shapelib study` runs run_all.py from a source checkout, and this shapelib is installed "
                       f"from {Path(__file__).resolve().parents[1]} without one; clone the repository, `pip install -e .` "
                       "there and run it from that checkout")
    argv = [sys.executable, str(script), *run_all_args]
    sys.stdout.flush()
    sys.stderr.flush()
    os.execv(sys.executable, argv)  # run_all.py's own signal handling sees Ctrl-C / SIGTERM directly


def register(add) -> None:
    """List ``study`` in ``shapelib --help``; :func:`shapelib.cli.main` hands everything after ``study``
    to run_all.py, which parses its own options."""
    add("study", "regenerate the study's figures and tables: run_all.py with the same options "
        "(needs a source checkout; `shapelib study --help` lists them)").set_defaults(func=lambda a: cmd_study([]))
