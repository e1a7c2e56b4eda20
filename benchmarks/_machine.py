"""What the benchmarks record about the machine they ran on."""

from __future__ import annotations

import os


def loadavg() -> str:
    """The 1, 5 and 15-minute load averages (``os.getloadavg``), or "n/a" where the OS has none.

    Printed beside every timing: the development machine's 2 cores are sometimes shared, and a
    number measured under load is provisional."""
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "n/a"
