import os
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared"

# Offline default for a checkout that sits beside the shared data mirror (as in CI).
if not os.environ.get("SHAPELIB_DATA_DIR") and (SHARED / "data").is_dir():
    os.environ["SHAPELIB_DATA_DIR"] = str(SHARED / "data")

sys.path.insert(0, str(ROOT))


def _data_available() -> bool:
    d = os.environ.get("SHAPELIB_DATA_DIR")
    return bool(d) and (Path(d) / "cdfhc" / "cdfhc_data2D_CC.mat").is_file()


requires_data = pytest.mark.skipif(not _data_available(), reason="SHAPELIB_DATA_DIR with the raw data is not set")


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)
