"""Sliding semilandmarks from files: geomorph's sliders table (:func:`shapelib.read_sliders`) and
``shapelib align --slide SLIDERS.csv | curves``, checked against the library and against what
sliding must do (semilandmarks move along their curves, fixed landmarks only with the pose)."""

import numpy as np
import pytest

import shapelib as sl
from shapelib import io
from shapelib.geometry.procrustes import generalized_procrustes
from tests.test_cli import run

N = 8


def _quads(rng):
    return np.array([[0, 0], [2, 0], [2.2, 1], [-0.1, 1.1]]) + rng.normal(scale=0.05, size=(N, 4, 2))


def _edge_specimens(seed=0):
    """4 fixed landmarks of a quadrilateral, then 4 semilandmarks spaced at random on its (straight)
    bottom edge from landmark 0 to landmark 1: geomorph's define.sliders(c(1, 5, 6, 7, 8, 2))."""
    rng = np.random.default_rng(seed)
    quads = _quads(rng)
    s = np.sort(rng.uniform(0.05, 0.95, (N, 4)), axis=1)[..., None]
    shapes = np.concatenate([quads, quads[:, :1] + s * (quads[:, 1:2] - quads[:, :1])], axis=1)
    chain = [0, 4, 5, 6, 7, 1]
    sliders = np.array([chain[i:i + 3] for i in range(len(chain) - 2)])
    return 3 + shapes, sliders  # positive coordinates, as digitised


def _curve_specimens(seed=1):
    """4 fixed landmarks and two tpsDig curves per specimen: 6 points along the bottom edge, 5
    along a bulging top edge, their end points near (not on) the landmarks."""
    rng = np.random.default_rng(seed)
    quads = _quads(rng)
    curves = []
    for q in quads:
        s = np.r_[0.02, np.sort(rng.uniform(0.1, 0.9, 4)), 0.98][:, None]
        t = np.r_[0.03, np.sort(rng.uniform(0.1, 0.9, 3)), 0.97][:, None]
        bottom = q[0] + s * (q[1] - q[0])
        top = q[2] + t * (q[3] - q[2]) + np.c_[np.zeros(5), 0.2 * np.sin(np.pi * t[:, 0])]
        curves.append([3 + bottom, 3 + top])
    return 3 + quads, curves


def _write_geomorph(path, sliders, *, header='"before","slide","after"', sep=","):
    """A sliders table as R's ``write.table(..., sep=",", row.names=FALSE)`` writes it: numbers from 1."""
    lines = ([header] if header else []) + [sep.join(str(v + 1) for v in row) for row in sliders]
    path.write_text("\n".join(lines) + "\n")
    return path


# ---------------------------------------------------------------------------------------------
# read_sliders
# ---------------------------------------------------------------------------------------------

def _r_write_csv(path, sliders):  # write.csv(sliders): quoted row names in a first column
    rows = [",".join([f'"{i}"', *(str(v + 1) for v in r)]) for i, r in enumerate(sliders, start=1)]
    path.write_text('"","before","slide","after"\n' + "\n".join(rows) + "\n")


def _savetxt(path, sliders):  # numpy.savetxt's default: whole numbers as 1.000000000000000000e+00
    np.savetxt(path, sliders + 1)


WRITERS = {
    "geomorph": lambda p, s: _write_geomorph(p, s),
    "no_header": lambda p, s: _write_geomorph(p, s, header=None),
    "whitespace": lambda p, s: _write_geomorph(p, s, header="before slide after", sep="\t"),
    "semicolon": lambda p, s: _write_geomorph(p, s, header="before;slide;after", sep=";"),
    "r_row_names": _r_write_csv,
    "savetxt": _savetxt,
}


@pytest.mark.parametrize("layout", sorted(WRITERS))
def test_a_sliders_table_round_trips_from_geomorph_s_numbering(tmp_path, layout):
    sliders = np.vstack([sl.curve_sliders(4, 6), sl.curve_sliders(10, 5), sl.curve_sliders(15, 4, closed=True)])
    path = tmp_path / "curveslide.csv"
    WRITERS[layout](path, sliders)
    got = sl.read_sliders(path, n_landmarks=19)
    assert got.dtype.kind == "i" and got.shape == sliders.shape
    np.testing.assert_array_equal(got, sliders)
    if layout == "geomorph":
        assert path.read_text().splitlines()[1] == "5,6,7"  # the file counts from 1
        assert got.min() == 4  # the array from 0


BAD = {  # content -> what the one-line error names: (row, value)
    "zero": ("before,slide,after\n1,2,3\n0,3,4\n", "row 2 (line 3)", "before 0"),
    "out_of_range": ("1,2,3\n2,3,9\n", "row 2 (line 2)", "after 9"),
    "own_anchor": ("1,2,3\n3,3,4\n", "row 2 (line 2)", "slide 3"),
    "same_anchors": ("1,2,1\n", "row 1 (line 1)", "both 1"),
    "duplicate": ("1,2,3\n2,3,4\n1,2,4\n", "row 3 (line 3)", "slide 2 already slides in row 1"),
    "fraction": ("before,slide,after\n1,2.5,3\n", "row 1 (line 2)", "'2.5'"),
    "word": ("1,2,3\n2,x,4\n", "row 2 (line 2)", "'x'"),
    "na": ("1,2,3\nNA,3,4\n", "row 2 (line 2)", "'NA'"),
    "two_columns": ("1,2,3\n2,3\n", "row 2 (line 2)", "3 columns"),
    "empty": ('"before","slide","after"\n', "no sliders", ""),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_bad_sliders_table_is_one_error_naming_file_row_and_value(tmp_path, case):
    text, row, value = BAD[case]
    path = tmp_path / f"{case}.csv"
    path.write_text(text)
    with pytest.raises(ValueError) as err:
        sl.read_sliders(path, n_landmarks=8)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(str(path)) and row in msg and value in msg, msg


def test_read_sliders_without_n_landmarks_checks_only_the_lower_end(tmp_path):
    path = _write_geomorph(tmp_path / "s.csv", np.array([[97, 98, 99]]))
    np.testing.assert_array_equal(sl.read_sliders(path), [[97, 98, 99]])
    with pytest.raises(ValueError, match="landmarks 1 to 50"):
        sl.read_sliders(path, n_landmarks=50)
    with pytest.raises(ValueError, match="no such file"):
        sl.read_sliders(tmp_path / "missing.csv")


# ---------------------------------------------------------------------------------------------
# shapelib align --slide
# ---------------------------------------------------------------------------------------------

def _python_align(shapes, sliders, criterion, size):
    """What ``align --slide`` must write: the library's sliding, then the alignment align does."""
    res = sl.slide_semilandmarks(shapes, sliders, criterion=criterion)
    aligned, _ = generalized_procrustes(res.shapes, scaling=False)
    return aligned * size, res


@pytest.mark.parametrize("criterion", ["bending_energy", "procrustes"])
def test_align_slide_agrees_with_the_library_and_slides_along_the_curve(tmp_path, criterion):
    shapes, sliders = _edge_specimens()
    data = io.write_landmarks(tmp_path / "quads.csv", shapes)
    table = _write_geomorph(tmp_path / "curveslide.csv", sliders)
    out = tmp_path / "aligned.csv"
    proc = run("align", data, "-o", out, "--slide", table, "--slide-criterion", criterion, "--size", 20, check=0)
    expected, res = _python_align(shapes, sliders, criterion, 20.0)
    assert res.converged
    assert f"slid 4 semilandmarks by minimum {criterion.replace('_', ' ')}: converged in {res.n_iter} iteration" \
        in proc.stdout
    got, _ = io.read_landmarks(out)
    np.testing.assert_allclose(got, expected, atol=1e-12)

    # each specimen brought back onto its input by the similarity that fits its fixed landmarks:
    # the fixed landmarks land on themselves, the semilandmarks stay on the straight edge between
    # landmarks 1 and 2 and have moved along it
    plain, _ = generalized_procrustes(shapes, scaling=False)
    moved = 0.0
    for before, after in zip(shapes, got):
        a, b = after[:4], before[:4]
        design = np.block([[a, np.ones((4, 1)), np.zeros((4, 1))],
                           [np.c_[a[:, 1], -a[:, 0]], np.zeros((4, 1)), np.ones((4, 1))]])
        coef = np.linalg.lstsq(design, np.r_[b[:, 0], b[:, 1]], rcond=None)[0]
        m = np.array([[coef[0], coef[1]], [-coef[1], coef[0]]])
        back = after @ m.T + coef[2:]
        np.testing.assert_allclose(back[:4], before[:4], atol=1e-9)
        tangent = (before[1] - before[0]) / np.linalg.norm(before[1] - before[0])
        offset = back[4:] - before[0]
        normal = offset - np.outer(offset @ tangent, tangent)
        np.testing.assert_allclose(normal, 0, atol=1e-9)
        moved = max(moved, float(np.max(np.abs((back[4:] - before[4:]) @ tangent))))
    assert moved > 0.05  # edge length about 2: the semilandmarks slid, visibly
    # and sliding changed the aligned shapes: without it align writes something else
    assert np.max(np.abs(got - 20 * plain)) > 0.05


def test_align_slide_curves_equals_the_sliders_table_and_writes_curves_back(tmp_path):
    landmarks, curves = _curve_specimens()
    ids = [f"s{i}" for i in range(N)]
    with_curves = io.write_tps(tmp_path / "curves.tps", landmarks, ids, curves=curves)
    combined = np.stack([np.vstack([lm, *cs]) for lm, cs in zip(landmarks, curves)])
    flat = io.write_tps(tmp_path / "flat.tps", combined, ids)
    sliders = np.vstack([sl.curve_sliders(4, 6), sl.curve_sliders(10, 5)])
    table = _write_geomorph(tmp_path / "curveslide.csv", sliders)

    proc = run("align", with_curves, "-o", tmp_path / "a.tps", "--slide", "curves", check=0)
    assert "slid 7 semilandmarks by minimum bending energy: converged" in proc.stdout
    run("align", flat, "-o", tmp_path / "b.tps", "--slide", table, check=0)
    lm, _, got_curves = io.read_tps(tmp_path / "a.tps", return_curves=True)
    assert lm.shape == (N, 4, 2) and [[len(c) for c in cs] for cs in got_curves] == [[6, 5]] * N
    from_curves = np.stack([np.vstack([a, *cs]) for a, cs in zip(lm, got_curves)])
    from_table, _ = io.read_landmarks(tmp_path / "b.tps")
    np.testing.assert_allclose(from_curves, from_table, atol=1e-12)
    expected, _ = _python_align(combined, sliders, "bending_energy", 1.0)
    np.testing.assert_allclose(from_curves, expected, atol=1e-12)


def test_align_slide_that_does_not_converge_warns_and_exits_4(tmp_path):
    shapes, sliders = _edge_specimens(seed=3)
    data = io.write_landmarks(tmp_path / "quads.csv", shapes)
    table = _write_geomorph(tmp_path / "curveslide.csv", sliders)
    proc = run("align", data, "-o", tmp_path / "a.csv", "--slide", table, "--slide-max-iter", 1, check=4)
    assert "did not converge in 1 iteration" in proc.stdout
    assert "warning: sliding did not converge" in proc.stderr and "exit status 4" in proc.stderr
    assert (tmp_path / "a.csv").is_file()  # written all the same


def test_align_slide_errors_are_one_line_naming_option_file_and_row(tmp_path):
    shapes, sliders = _edge_specimens()
    data = io.write_landmarks(tmp_path / "quads.csv", shapes)
    out = tmp_path / "a.csv"

    def error(*args):
        proc = run("align", data, "-o", out, *args, check=1)
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("shapelib: error: "), proc.stderr
        return lines[0]

    bad = _write_geomorph(tmp_path / "bad.csv", np.array([[0, 4, 5], [4, 5, 8]]))  # landmark 9 of 8
    assert all(s in error("--slide", bad) for s in ("--slide", "bad.csv", "row 2", "after 9", "1 to 8"))
    assert "no such file" in error("--slide", tmp_path / "nope.csv")
    assert "--slide curves" in error("--slide", "curves") and "CURVES=" in error("--slide", "curves")
    assert "needs --slide" in error("--slide-criterion", "procrustes")
    assert "needs --slide" in error("--slide-max-iter", 5)
    assert not out.exists()

    landmarks, curves = _curve_specimens()
    no_curves = io.write_tps(tmp_path / "plain.tps", landmarks)
    proc = run("align", no_curves, "-o", tmp_path / "a.tps", "--slide", "curves", check=1)
    assert "has no CURVES= blocks" in proc.stderr and "plain.tps" in proc.stderr
    curves[3] = [curves[3][0], curves[3][1][:4]]
    uneven = io.write_tps(tmp_path / "uneven.tps", landmarks, curves=curves)
    proc = run("align", uneven, "-o", tmp_path / "a.tps", "--slide", "curves", check=1)
    assert "#4" in proc.stderr and "[6, 4]" in proc.stderr and "[6, 5]" in proc.stderr
