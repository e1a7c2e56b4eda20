"""shapelib's Procrustes-regime answers beside R's (`shapes`, `vegan`) on the ADHD-200 outlines:
PCA variance shares, the Procrustes ANOVA of diagnosis, Goodall's F of two groups. R's numbers are
stored with their script and versions in data/reference/r_shapes/."""

import numpy as np
import pandas as pd
import pytest

import shapelib as sl
from tests.conftest import ROOT, requires_data

REF = ROOT / "data" / "reference" / "r_shapes"


@pytest.fixture(scope="module")
def adhd():
    from shapelib.datasets import load_adhd200

    x, labels = load_adhd200()
    return x, labels["phenotype"].to_numpy()


@requires_data
def test_pca_variance_shares_match_r_shapes(adhd):
    x, _ = adhd
    y = sl.procrustes_coordinates(x)
    s = np.linalg.svd(y - y.mean(axis=0), compute_uv=False) ** 2
    ours = 100 * s[:10] / s.sum()
    r = pd.read_csv(REF / "pca.csv")["percent"].to_numpy()
    np.testing.assert_allclose(ours, r, atol=0.2)  # percentage points


@requires_data
def test_procrustes_anova_matches_vegan_adonis2(adhd):
    x, phenotype = adhd
    fit = sl.shape_lm("~ diagnosis", pd.DataFrame({"diagnosis": phenotype.astype(str)}), x, n_permutations=199)
    r = pd.read_csv(REF / "anova.csv").set_index("term")
    assert fit.table.loc["diagnosis", "F"] == pytest.approx(r.loc["diagnosis", "F"], rel=2e-3)
    assert fit.table.loc["diagnosis", "r2"] == pytest.approx(r.loc["diagnosis", "r2"], rel=2e-3)
    assert fit.table.loc["diagnosis", "df"] == r.loc["diagnosis", "df"]
    # the sums of squares themselves (F and r² are ratios: coordinates at the wrong scale keep them);
    # R's are on the partial Procrustes tangent coordinates at unit size, ours on the aligned ones
    for term in ("diagnosis", "Residual", "Total"):
        assert fit.table.loc[term, "sum_of_squares"] == pytest.approx(r.loc[term, "sum_of_squares"], rel=2e-3)
    assert (fit.table.loc["diagnosis", "p_value"] <= 0.05) == (r.loc["diagnosis", "p_value"] <= 0.05)


@requires_data
def test_goodall_f_of_two_groups_matches_r_shapes(adhd):
    x, phenotype = adhd
    keep = np.isin(phenotype, [0, 1])
    fit = sl.shape_lm("~ g", pd.DataFrame({"g": phenotype[keep].astype(str)}), x[keep], n_permutations=99)
    r = pd.read_csv(REF / "goodall.csv").iloc[0]
    assert fit.table.loc["g", "F"] == pytest.approx(r["F"], rel=2e-3)
    assert fit.table.loc["g", "p_value"] <= 0.05 and r["p_value"] <= 0.05  # the same conclusion
