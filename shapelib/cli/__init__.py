"""The ``shapelib`` command line: landmark files in, aligned shapes, distance matrices and geodesics out.

Subcommands (``shapelib <command> --help`` shows an example for each)::

    shapelib info FILE
    shapelib align FILE -o OUT [--size S] [--slide SLIDERS.csv|curves [--slide-criterion C]]
    shapelib distances FILE --metric M [--sigma2 S|auto] [--rtol R] [--jobs N | --scheduler ADDRESS]
                           [--store D.zarr [--max-blocks N]] [--no-progress] -o D.csv
    shapelib geodesic FILE --from ID --to ID --metric M --sigma2 S|auto -o path.csv [--plot P.png] [--animate A.gif]
    shapelib mean FILE --metric M --sigma2 S [--size S] [--jobs N | --scheduler ADDRESS] -o mean.tps [--plot P.png]
    shapelib pca FILE --metric M --sigma2 S [--size S] [--n-components K] -o scores.csv [--plot modes.png]
    shapelib test FILE --covariates C.csv --by GROUP --metric M [--sigma2 S|auto] [--permutations P] [-o T.csv]
    shapelib regress FILE --covariates C.csv --by COLUMN [--log] --metric M [--sigma2 S|auto] [-o T.csv]
    shapelib study [run_all.py options: --quick, --only NAME, -p NAME=VALUE, -j N, --force, --list, ...]

Files are read by :func:`shapelib.io.read_landmarks` (``.tps``, ``.csv``, ``.npy``, ``.npz``). Bad
input ends the command with one line ``shapelib: error: …`` on stderr (naming the file, specimen,
landmark or parameter) and exit status 1; usage errors exit with 2, as argparse does. A Ctrl-C
ends it with ``shapelib: interrupted`` and status 130; ``distances --max-blocks N`` stopping before
the matrix is complete exits with status 75 (``EX_TEMPFAIL``: rerun to resume), writing no ``-o``.
A geodesic (``geodesic``, or a pair of ``distances`` without ``--rtol``) whose solver did not
converge is written, said in a warning, and the command exits with status 4 (:data:`EXIT_UNCONVERGED`).
``shapelib study`` is ``run_all.py`` itself: its help, usage errors and exit codes are run_all's.

Each command group is one module of this package with a ``register(add)`` function that adds its
subcommands; a new command is a new module and one line in :data:`COMMAND_MODULES`.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import warnings

from ._common import EXIT_STOPPED, EXIT_UNCONVERGED, PROG, CLIError, parse_assignment, scale_warning_in_cli_words
from .study import cmd_study, find_run_all

__all__ = ["main", "build_parser", "parse_assignment", "CLIError", "EXIT_STOPPED", "EXIT_UNCONVERGED", "PROG",
           "find_run_all", "cmd_study", "COMMAND_MODULES"]

#: the command groups, in the order ``shapelib --help`` lists them: each module's ``register(add)``
#: adds its subcommands, where ``add(name, help, epilog=None)`` returns a new subparser
COMMAND_MODULES = (
    "info",        # info, align
    "distances",   # distances, geodesic
    "intrinsic",   # mean, pca
    "effects",     # test, regress
    "pointsets",   # register
    "study",       # study (run_all.py)
)


def build_parser() -> argparse.ArgumentParser:
    from .._version import __version__

    parser = argparse.ArgumentParser(
        prog=PROG, description="Landmark shape analysis with information geometry (Peter & Rangarajan).",
        epilog="examples:\n  shapelib info fish.tps\n  shapelib align fish.tps -o aligned.tps --size 20\n"
               "  shapelib distances aligned.tps --metric alpha --sigma2 0.5 -o alpha.csv\n"
               "run `shapelib COMMAND --help` for each command's options.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    def add(name, help_, epilog=None):
        sp = sub.add_parser(name, help=help_, description=help_, epilog=epilog,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
        sp.set_defaults(subparser=sp)  # a stray option is reported with this command's usage
        return sp

    for name in COMMAND_MODULES:
        importlib.import_module(f"{__name__}.{name}").register(add)
    return parser


def _warning_printer(args=None):
    """``warnings.showwarning`` for a command: one line ``shapelib: warning: …``, remedies in the
    command line's options (those of the command that runs)."""
    pose_remedy = (" Drop --no-align to align them (rotations and translations, sizes kept)."
                   if args is None or hasattr(args, "no_align") else
                   " Align them first: `shapelib align FILE -o aligned.tps`, or --size S here (generalized Procrustes, "
                   "then centroid size S).")

    def show(message, category, filename, lineno, file=None, line=None):
        from ..geometry.procrustes import PoseWarning
        from ..geometry.scale import ScaleWarning

        text = " ".join(str(message).split())
        if isinstance(message, ScaleWarning) and getattr(message, "facts", None):
            text = scale_warning_in_cli_words(message)
        if issubclass(category, PoseWarning):  # say it in command-line terms
            text = text.split(" Align them first")[0] + pose_remedy
        print(f"{PROG}: warning: {text}", file=sys.stderr)

    return show


#: the one-line form of every warning (``--no-align``'s remedy for a pose warning)
_one_line_warnings = _warning_printer()


def _interrupted(exc: BaseException) -> bool:
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def main(argv=None) -> int:
    """Entry point of the ``shapelib`` console script and ``python -m shapelib``."""
    argv = sys.argv[1:] if argv is None else list(argv)
    args = None
    if argv[:1] == ["study"]:  # run_all.py parses its own options
        run = lambda: cmd_study(argv[1:])  # noqa: E731
    else:
        args, extra = build_parser().parse_known_args(argv)
        if extra:
            args.subparser.error(f"unrecognized arguments: {' '.join(extra)}")
        run = lambda: args.func(args)  # noqa: E731
    with warnings.catch_warnings():  # a command's filters and the one-line form end with it
        warnings.showwarning = _warning_printer(args)
        return _run(run)


def _run(run) -> int:
    try:
        return int(run() or 0)
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `shapelib info F | head`: the reader has gone, nothing to say
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except (ValueError, OSError) as exc:
        if os.environ.get("SHAPELIB_DEBUG"):
            raise
        msg = " ".join(str(exc).split()) or type(exc).__name__
        if isinstance(exc, OSError) and not isinstance(exc, CLIError) and getattr(exc, "filename", None):
            msg = f"{exc.filename}: {exc.strerror or msg}"
        print(f"{PROG}: error: {msg}", file=sys.stderr)
        return 1
    except Exception as exc:  # a bug, not bad input: still one line, traceback on request
        if _interrupted(exc):  # Ctrl-C inside compiled code surfaces as a SystemError around it
            print(f"{PROG}: interrupted", file=sys.stderr)
            return 130
        if os.environ.get("SHAPELIB_DEBUG"):
            raise
        print(f"{PROG}: internal error: {type(exc).__name__}: {' '.join(str(exc).split())} "
              "(set SHAPELIB_DEBUG=1 for the traceback, and please report it)", file=sys.stderr)
        return 3


if __name__ == "__main__":
    sys.exit(main())