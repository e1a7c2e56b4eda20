"""The stored reference values are a faithful transcription of the paper."""
import re

import pandas as pd
import pytest

from tests.conftest import ROOT, SHARED, needs

PAPER = SHARED / "paper" / "peter-rangarajan-information-geometry-landmark-shapes.txt"


def load():
    return pd.read_csv(ROOT / "data" / "reference" / "table1.csv", comment="#", dtype={"printed": str})


def test_table1_reference_is_complete_and_consistent():
    ref = load()
    assert len(ref) == 36 * 11 and ref["key"].is_unique
    assert set(ref["column"]) == {
        "fisher_rao_s2_0.1", "fisher_rao_s2_0.5", "fisher_rao_s2_1.5", "alpha_s2_0.1", "alpha_s2_0.5",
        "alpha_s2_1.5", "diffeomorphism", "procrustes", "hausdorff", "wendland", "tps",
    }
    assert (ref["value"] - ref["printed"].astype(float) * ref["scale"]).abs().max() < 1e-12
    alpha = ref["column"].str.startswith("alpha")
    assert (ref.loc[alpha, "scale"] == 1e-3).all() and (ref.loc[~alpha, "scale"] == 1e-2).all()


@needs(PAPER.exists(), f"the paper text is not at {PAPER} (the shared/ folder beside the checkout)")
def test_table1_reference_matches_paper_text_cell_by_cell():
    text = PAPER.read_text()
    rows = re.findall(r"(\d) vs\. (\d)((?: \d+\.\d\d){11})", text)
    assert len(rows) == 36
    columns = ["fisher_rao_s2_0.1", "fisher_rao_s2_0.5", "fisher_rao_s2_1.5", "alpha_s2_0.1", "alpha_s2_0.5",
               "alpha_s2_1.5", "diffeomorphism", "procrustes", "hausdorff", "wendland", "tps"]
    ref = load().set_index("key")
    for i, j, cells in rows:
        for col, printed in zip(columns, cells.split()):
            assert ref.loc[f"table1/{col}/{i}-{j}", "printed"] == printed
