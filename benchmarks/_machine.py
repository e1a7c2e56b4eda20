"""What the benchmarks record about the machine they ran on, and where they record it."""

from __future__ import annotations

import datetime
import json
import os
import platform
import shlex
import sys
from pathlib import Path

#: where ``--record`` writes each benchmark's results; the documentation's performance page
#: renders its tables from these files (docs/_ext/shapelib_docs.py)
RECORD_DIR = Path(__file__).resolve().parents[1] / "docs" / "_data" / "benchmarks"


def loadavg() -> str:
    """The 1, 5 and 15-minute load averages (``os.getloadavg``), or "n/a" where the OS has none.

    Printed beside every timing: the development machine's 2 cores are sometimes shared, and a
    number measured under load is provisional."""
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "n/a"


def _processor() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine() -> dict:
    """The machine, the software and the moment of a measurement (UTC)."""
    import numpy as np

    import shapelib

    return {
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "cpus": os.cpu_count(),
        "processor": _processor(),
        "machine": platform.machine(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "shapelib": shapelib.__version__,
        "loadavg": loadavg(),
    }


def record(name: str, results: dict, *, argv=None, path: Path | None = None) -> Path:
    """Write ``results`` with the machine and the command line to ``docs/_data/benchmarks/<name>.json``."""
    argv = sys.argv[1:] if argv is None else list(argv)
    path = RECORD_DIR / f"{name}.json" if path is None else Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    command = " ".join(["python", f"benchmarks/{name}.py", *map(shlex.quote, (a for a in argv if a != "--record"))])
    data = {"benchmark": name, "command": command, "machine": machine(), "results": results}
    path.write_text(json.dumps(data, indent=1, ensure_ascii=False, default=str) + "\n")
    return path
