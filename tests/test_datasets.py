import shutil

import numpy as np
import pytest

from shapelib import datasets
from tests.conftest import requires_data

pytestmark = requires_data


def test_registry_lists_every_file_with_pinned_url_and_sha256():
    reg = datasets.registry()
    assert len(reg) > 1400
    for path, (url, sha) in reg.items():
        assert url.startswith("https://raw.githubusercontent.com/") and len(sha) == 64
        # pinned to a commit: a 40-hex segment in the URL
        assert any(len(seg) == 40 and all(c in "0123456789abcdef" for c in seg) for seg in url.split("/")), url


def test_corpus_callosum_loader():
    shapes, ids = datasets.load_corpus_callosum()
    assert shapes.shape == (7, 63, 2) and shapes.dtype == np.float64
    assert ids.tolist() == [1, 3, 8, 2, 6, 7, 9]
    assert np.all(np.isfinite(shapes))


def test_other_loaders_shapes():
    assert datasets.load_fish2d().shape == (7, 150, 2)
    assert datasets.load_beijing().shape == (7, 113, 2)
    x, y = datasets.load_tps_rpm("fish_def_3")
    assert x.shape == (98, 2) and y.ndim == 2 and y.shape[1] == 2
    src, tgt = datasets.load_cpd_fish()
    assert src.shape == tgt.shape == (91, 2)
    assert datasets.load_gmmreg_fish("fish_X_nohead").shape == (78, 2)


def test_unknown_names_are_errors():
    with pytest.raises(ValueError, match="unknown TPS-RPM"):
        datasets.load_tps_rpm("fish_bogus_1")
    with pytest.raises(ValueError, match="unknown gmmreg"):
        datasets.load_gmmreg_fish("shark")
    with pytest.raises(ValueError, match="unknown MPEG-7"):
        datasets.load_mpeg7_image("unicorn-1")


def test_mpeg7_boundary_and_landmarks():
    img = datasets.load_mpeg7_image("fish-3")
    b = datasets.mpeg7_boundary("fish-3")
    assert b.shape[1] == 2 and len(b) > 100
    # every boundary pixel is a foreground pixel
    rows = img.shape[0] - 1 - b[:, 1].astype(int)
    assert img[rows, b[:, 0].astype(int)].all()
    lm = datasets.mpeg7_landmarks("fish-3", 233)
    assert lm.shape == (233, 2)
    steps = np.linalg.norm(np.diff(np.vstack([lm, lm[:1]]), axis=0), axis=1)
    assert steps.max() / np.median(steps) < 1.5  # evenly spaced along the outline
    # landmarks lie on the outline: within a pixel of a boundary pixel
    d = np.min(np.linalg.norm(lm[:, None, :] - b[None, :, :], axis=2), axis=1)
    assert d.max() < 1.5
    with pytest.raises(ValueError, match="n must be"):
        datasets.mpeg7_landmarks("fish-3", 2)


def test_mpeg7_boundary_includes_holes():
    # 'cattle' silhouettes have holes: more boundary pixels than the outer contour alone
    b = datasets.mpeg7_boundary("cattle-1")
    assert len(b) > 0


def test_adhd200_loader():
    contours, labels = datasets.load_adhd200()
    assert contours.shape == (647, 50, 2) and contours.dtype == np.float64
    assert list(labels.columns) == ["patient.id", "gender", "age", "phenotype"]
    assert len(labels) == len(contours)


def test_checksum_mismatch_is_reported(tmp_path, monkeypatch):
    src = datasets.fetch("cpd/fish_source.txt")
    (tmp_path / "cpd").mkdir()
    bad = tmp_path / "cpd" / "fish_source.txt"
    shutil.copy(src, bad)
    with open(bad, "ab") as fh:
        fh.write(b"0 0\n")
    monkeypatch.setenv(datasets.DATA_DIR_ENV, str(tmp_path))
    with pytest.raises(datasets.DataError, match="checksum mismatch.*fish_source"):
        datasets.fetch("cpd/fish_source.txt")


def test_missing_file_names_file_url_and_variable(tmp_path, monkeypatch):
    monkeypatch.setenv(datasets.DATA_DIR_ENV, str(tmp_path))
    with pytest.raises(datasets.DataError) as err:
        datasets.load_cpd_fish()
    msg = str(err.value)
    assert "cpd/fish_source.txt" in msg and "https://raw.githubusercontent.com/" in msg
    assert datasets.DATA_DIR_ENV in msg


def test_unregistered_file_is_an_error():
    with pytest.raises(datasets.DataError, match="not in the dataset registry"):
        datasets.fetch("nowhere/file.txt")


def test_every_tps_rpm_case_has_its_ground_truth_point_for_point():
    assert len(datasets.TPS_RPM_LEVELS) == 56
    for name in ("fish_def_1", "chinese_outlier_5", "fish_occlusion_6"):
        for sample in (1, 10):
            case = datasets.load_tps_rpm_case(name, sample=sample)
            n = len(case["y2"])
            assert n <= len(case["x1"]) and case["y2"].shape[1] == case["y2a"].shape[1] == 2
    # clean deformation levels: the target is the warped template, point for point
    case = datasets.load_tps_rpm_case("fish_def_2", sample=3)
    assert np.allclose(case["y2a"], case["y2"])
    with pytest.raises(ValueError, match="samples 1 to 10; got sample=11"):
        datasets.load_tps_rpm_case("fish_def_2", sample=11)
