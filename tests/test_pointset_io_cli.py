"""Point sets from files (CSV, NumPy, tpsDig with CURVES and varying counts) and `shapelib register`
on real files: outputs, figure, correspondences, one-line errors."""

import numpy as np
import pytest

import shapelib as sl
from shapelib.cli import main
from shapelib.io import read_point_sets, write_point_set


def outline(n=40, angle=0.0):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    x = np.column_stack([np.cos(t) + 0.45 * np.cos(2 * t), 0.55 * np.sin(t) + 0.12 * np.sin(2 * t)])
    c, s = np.cos(angle), np.sin(angle)
    return x @ np.array([[c, -s], [s, c]]).T


def test_csv_with_ids_npz_and_tps_with_curves_of_varying_counts(tmp_path):
    f = tmp_path / "sets.csv"
    f.write_text("id,x,y\na,0,0\na,1,0\na,0,1\nb,0,0\nb,2,1\n")
    sets, ids = read_point_sets(f)
    assert ids == ["a", "b"] and [s.shape for s in sets] == [(3, 2), (2, 2)]
    np.savez(tmp_path / "sets.npz", left=outline(10), right=outline(13))
    sets, ids = read_point_sets(tmp_path / "sets.npz")
    assert ids == ["left", "right"] and np.allclose(sets[1], outline(13))
    tps = tmp_path / "fish.tps"
    tps.write_text("LM=2\n0 0\n1 0\nCURVES=1\nPOINTS=3\n0 1\n1 1\n2 1\nID=one\n"
                   "LM=3\n0 0\n1 0\n5 5\nID=two\n")
    sets, ids = read_point_sets(tps)
    assert ids == ["one", "two"] and [len(s) for s in sets] == [5, 3]
    assert np.allclose(sets[0], [[0, 0], [1, 0], [0, 1], [1, 1], [2, 1]])


def test_bad_files_get_one_error_naming_file_and_line_or_point(tmp_path):
    bad = tmp_path / "bad.tps"
    bad.write_text("LM=2\n0 0\n1 x\n")
    with pytest.raises(sl.InputError, match=r"bad.tps: line 3: not a number"):
        read_point_sets(bad)
    dup = tmp_path / "dup.csv"
    dup.write_text("x,y\n0,0\n1,1\n0,0\n")
    with pytest.raises(sl.InputError, match=r"dup.csv: point 2 repeats point 0"):
        read_point_sets(dup)
    noxy = tmp_path / "cols.csv"
    noxy.write_text("a,b\n0,0\n1,1\n")
    with pytest.raises(sl.InputError, match="needs columns x and y"):
        read_point_sets(noxy)
    with pytest.raises(sl.InputError, match="point sets are read from"):
        read_point_sets(tmp_path / "x.txt")


def test_shapelib_register_writes_the_moved_points_correspondences_and_figure(tmp_path, capsys):
    src, tgt = tmp_path / "src.csv", tmp_path / "tgt.npy"
    write_point_set(src, outline())
    truth = outline(angle=2.2) + [1.0, 2.0]
    perm = np.random.default_rng(0).permutation(40)
    np.save(tgt, truth[perm])
    out, fig, corr = tmp_path / "moved.csv", tmp_path / "fig.png", tmp_path / "corr.csv"
    assert main(["register", str(src), str(tgt), "-o", str(out), "--plot", str(fig), "--correspondence", str(corr),
                 "--transform", "rigid"]) == 0
    moved = read_point_sets(out)[0][0]
    assert np.abs(moved - truth).max() < 1e-6
    c = np.loadtxt(corr, delimiter=",", skiprows=1, dtype=int)
    assert np.array_equal(perm[c[:, 1]], np.arange(40))
    assert fig.stat().st_size > 1000
    assert "rigid registration (alpha) of 40 points onto 40" in capsys.readouterr().out


def test_shapelib_register_errors_are_one_line_with_a_non_zero_exit(tmp_path, capsys):
    src = write_point_set(tmp_path / "src.csv", outline())
    np.savez(tmp_path / "many.npz", a=outline(10), b=outline(12))
    assert main(["register", str(src), str(tmp_path / "many.npz"), "-o", str(tmp_path / "m.csv")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "holds 2 point sets (a, b); choose one with --target-id ID" in err
    assert main(["register", str(src), str(src), "-o", str(tmp_path / "m.txt")]) == 1
    assert "-o " in (err := capsys.readouterr().err) and "expected a file ending in .csv or .npy" in err
    assert main(["register", str(src), str(src), "-o", str(tmp_path / "m.csv"), "--w", "often"]) == 1
    assert "--w must be a number in [0, 1) or 'auto'" in capsys.readouterr().err


def test_distances_of_point_sets_modulo_similarity_equal_the_library(tmp_path, capsys):
    """`shapelib distances FILE --modulo similarity`: sets of different sizes, one a rotated, scaled,
    moved and mirrored copy of another, give the library's matrix, with that pair at ~0."""
    a = outline(40)
    b = 2.5 * outline(40, angle=1.1)[::-1] * [1, -1] + [3.0, -1.0]  # similar to a (mirrored), points reordered
    c = np.column_stack([np.cos(np.linspace(0, 2 * np.pi, 31, endpoint=False)),
                         0.3 * np.sin(np.linspace(0, 2 * np.pi, 31, endpoint=False))])
    f = tmp_path / "sets.npz"
    np.savez(f, a=a, b=b, c=c)
    out = tmp_path / "D.csv"
    assert main(["distances", str(f), "--metric", "alpha_bound", "--modulo", "similarity", "--sigma2", "0.01",
                 "-o", str(out), "--no-progress"]) == 0
    import pandas as pd

    d = pd.read_csv(out, index_col=0)
    assert list(d.index) == ["a", "b", "c"]
    want = sl.pairwise_distances([a, b, c], metric="alpha_bound", modulo="similarity", sigma2=0.01, progress=False)
    np.testing.assert_allclose(d.to_numpy(), want, rtol=1e-12, atol=1e-15)
    assert d.loc["a", "b"] < 1e-3 * d.loc["a", "c"]
    capsys.readouterr()
    assert main(["distances", str(f), "--metric", "alpha", "--modulo", "similarity", "--sigma2", "0.01", "-o",
                 str(tmp_path / "x.csv")]) != 0
    err = capsys.readouterr().err
    assert "alpha_bound or fisher_rao_bound" in err and len(err.strip().splitlines()) == 1


def test_shapelib_register_takes_known_correspondences_from_a_csv(tmp_path, capsys):
    """`--landmarks`: the rows of --correspondence's format reach the registration and come back in its
    correspondences; a bad file is a one-line error naming the line."""
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    x = np.column_stack([np.cos(t), 0.5 * np.sin(t)])  # symmetric under a half turn: ambiguous alone
    c, s = np.cos(2.0), np.sin(2.0)
    truth = (x + np.column_stack([0.1 * x[:, 1] ** 2, 0.05 * np.sin(3 * t)])) @ np.array([[c, -s], [s, c]]).T
    perm = np.random.default_rng(0).permutation(60)
    src, tgt = write_point_set(tmp_path / "src.csv", x), write_point_set(tmp_path / "tgt.csv", truth[perm])
    where = np.argsort(perm)
    lm = tmp_path / "lm.csv"
    lm.write_text(f"source,target\n# two points known\n0,{where[0]}\n15,{where[15]}\n")
    out, corr = tmp_path / "moved.csv", tmp_path / "corr.csv"
    assert main(["register", str(src), str(tgt), "-o", str(out), "--correspondence", str(corr), "--landmarks",
                 str(lm), "--no-progress"]) == 0
    assert np.abs(read_point_sets(out)[0][0] - truth).max() < 1e-3
    assert np.array_equal(np.loadtxt(corr, delimiter=",", skiprows=1, dtype=int)[:, 1], where)
    capsys.readouterr()
    lm.write_text("source,target\n0,1\n2;3\n")
    assert main(["register", str(src), str(tgt), "-o", str(out), "--landmarks", str(lm)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "lm.csv, line 3: expected two integers" in err
    lm.write_text("0,70\n")
    assert main(["register", str(src), str(tgt), "-o", str(out), "--landmarks", str(lm)]) == 1
    assert "target point 70, outside 0..59" in capsys.readouterr().err
    assert main(["register", str(src), str(tgt), "-o", str(out), "--landmarks", str(tmp_path / "no.csv")]) == 1
    assert "--landmarks: no such file" in capsys.readouterr().err
