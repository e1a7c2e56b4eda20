"""shapelib.io: tpsDig, CSV, NumPy and geomorph layouts, read from files written the way tpsDig,
geomorph and R write them (by hand, below), checked against ktch as an independent reader/writer,
and every malformed input rejected with a message naming file, line/specimen and landmark."""

import warnings

import numpy as np
import pandas as pd
import pytest

from shapelib import io
from tests.conftest import import_or_missing

ktch_io = import_or_missing("ktch.io", "ktch (the dev extra: the independent reader) is not installed")


def _write(path, text, *, crlf=False):
    data = text.replace("\n", "\r\n") if crlf else text
    path.write_bytes(data.encode("utf-8"))
    return path


# tpsDig2 layout: LM= block, then IMAGE=, ID=, SCALE= (tpsUtil numbers IDs from 0); pixel coordinates
TPSDIG = """LM=4
412.00000 233.00000
398.50000 240.00000
1.2e2 2.5E+02
377.00000 219.00000
IMAGE=fish_01.jpg
ID=0
SCALE=0.012500

LM=4
402.00000 223.00000
388.00000 230.00000
130.00000 260.00000
367.00000 209.00000
IMAGE=fish_02.jpg
ID=1
SCALE=0.025000
"""
TPSDIG_ARRAY = np.array([
    [[412, 233], [398.5, 240], [120, 250], [377, 219]],
    [[402, 223], [388, 230], [130, 260], [367, 209]],
], dtype=float)


def test_tpsdig_layout_with_crlf_lowercase_key_blank_lines_and_comments(tmp_path):
    text = "# digitised by hand\n" + TPSDIG.replace("LM=4", "lm=4", 1).replace("ID=1", "ID=1\n\n\n")
    p = _write(tmp_path / "fish.tps", text, crlf=True)
    shapes, spec = io.read_tps(p)
    assert shapes.dtype == np.float64 and shapes.shape == (2, 4, 2)
    np.testing.assert_array_equal(shapes, TPSDIG_ARRAY)
    assert list(spec.columns[:1]) == ["id"] and spec["id"].tolist() == ["0", "1"]
    assert spec["image"].tolist() == ["fish_01.jpg", "fish_02.jpg"]
    np.testing.assert_array_equal(spec["scale"], [0.0125, 0.025])  # reported although not applied
    assert not spec["scaled"].any()
    assert spec["line"].tolist() == [2, 11]


def test_scale_applied_only_on_request_and_required_for_every_specimen(tmp_path):
    p = _write(tmp_path / "fish.tps", TPSDIG)
    scaled, spec = io.read_tps(p, scale=True)
    np.testing.assert_allclose(scaled, TPSDIG_ARRAY * np.array([0.0125, 0.025])[:, None, None], rtol=0, atol=0)
    assert spec["scaled"].all()
    p2 = _write(tmp_path / "noscale.tps", TPSDIG.replace("SCALE=0.025000\n", ""))
    np.testing.assert_array_equal(io.read_tps(p2)[0], TPSDIG_ARRAY)
    assert np.isnan(io.read_tps(p2)[1]["scale"].iloc[1])
    with pytest.raises(ValueError, match=r"noscale\.tps.*scale=True.*specimen #2 \(ID=1\).*no SCALE="):
        io.read_tps(p2, scale=True)


def test_ids_fall_back_to_image_then_position(tmp_path):
    text = TPSDIG.replace("ID=0\n", "").replace("ID=1\n", "").replace("IMAGE=fish_02.jpg\n", "")
    _, spec = io.read_tps(_write(tmp_path / "f.tps", text))
    assert spec["id"].tolist() == ["fish_01", "1"]


def test_missing_landmarks_negative_or_na_name_file_specimen_and_landmark(tmp_path):
    text = TPSDIG.replace("130.00000 260.00000", "-1 -1")
    p = _write(tmp_path / "miss.tps", text)
    with pytest.raises(ValueError, match=r"miss\.tps: line 13, specimen '1' \(#2\): landmark 3 is missing"):
        io.read_tps(p)
    shapes, spec = io.read_tps(p, missing="nan")
    assert np.isnan(shapes[1, 2]).all() and np.isfinite(np.delete(shapes.reshape(-1, 2), 6, axis=0)).all()
    assert spec["n_missing"].tolist() == [0, 1]
    # geomorph's writeland.tps writes missing values as NA
    p2 = _write(tmp_path / "na.tps", TPSDIG.replace("388.00000 230.00000", "NA NA"))
    with pytest.raises(ValueError, match=r"na\.tps: line 12, specimen '1' \(#2\): landmark 2 is missing"):
        io.read_tps(p2)
    # genuinely negative coordinates (aligned shapes) are read on request
    shapes, _ = io.read_tps(p, negative="coordinates")
    np.testing.assert_array_equal(shapes[1, 2], [-1, -1])


@pytest.mark.parametrize("mutate, pattern", [
    (lambda t: t.replace("398.50000 240.00000\n", "", 1),
     r"bad\.tps: line 5: specimen #1 \(LM= at line 1\): its LM=4 header declares 4 points but only 3"),
    (lambda t: t.replace("377.00000 219.00000\n", "377.00000 219.00000\n1 2\n", 1),
     r"bad\.tps: line 6: unexpected data '1 2' in specimen #1 \(LM= at line 1\)"),
    (lambda t: t.replace("398.50000 240.00000", "398.5O 240", 1),
     r"bad\.tps: line 3, specimen #1 \(LM= at line 1\), LM=4 point 2: non-numeric coordinate '398\.5O'"),
    (lambda t: t.replace("398.50000 240.00000", "398.5 240 7", 1),
     r"bad\.tps: line 3, specimen #1 \(LM= at line 1\), LM=4 point 2: expected 2 coordinates, got 3"),
    (lambda t: t.replace("LM=4", "LM=5", 1).replace("IMAGE=fish_01.jpg", "1 1\nIMAGE=fish_01.jpg"),
     r"bad\.tps: specimen #2 \(ID=1\) \(LM= at line 11\) has 4 landmarks but specimen #1 has 5"),
    (lambda t: "",
     r"bad\.tps: no landmarks"),
    (lambda t: "ID=3\n" + t,
     r"bad\.tps: line 1: ID= appears before the first LM= line"),
    (lambda t: t.replace("LM=4", "LM3=4", 1),
     r"bad\.tps: line 2, specimen #1 \(LM= at line 1\), LM3=4 point 1: expected 3 coordinates, got 2"),
    (lambda t: t.replace("SCALE=0.012500", "SCALE=abc"),
     r"bad\.tps: specimen #1 \(ID=0\) \(LM= at line 1\): SCALE='abc' is not a number"),
    (lambda t: t.replace("ID=1", "ID=1\nID=2"),
     r"bad\.tps: line 17: specimen #2 \(ID=1\) \(LM= at line 10\) has a second ID= line"),
    (lambda t: "1 1\n2 2\n" + t,
     r"bad\.tps: line 1: coordinate row '1 1' appears before the first LM= line"),
    (lambda t: t.replace("IMAGE=fish_01.jpg", "CURVES=1\nPOINTS=-2\n3 3\n4 4\nIMAGE=fish_01.jpg", 1),
     r"bad\.tps: line 7: specimen #1 \(LM= at line 1\): POINTS= needs a non-negative point count; got -2$"),
    (lambda t: t.replace("IMAGE=fish_01.jpg", "CURVES=-1\nIMAGE=fish_01.jpg", 1),
     r"bad\.tps: line 6: specimen #1 \(LM= at line 1\): CURVES= needs a non-negative count; got -1$"),
    (lambda t: t.replace("398.50000 240.00000", "398.5 inf", 1),
     r"bad\.tps: line 3, specimen #1 \(LM= at line 1\), LM=4 point 2: non-finite coordinate 'inf' \(coordinates must be finite numbers\)"),
    (lambda t: t.replace("398.50000 240.00000", "1e400 240", 1),
     r"bad\.tps: line 3, specimen #1 \(LM= at line 1\), LM=4 point 2: non-finite coordinate '1e400'"),
])
def test_malformed_tps_names_file_line_specimen_and_landmark(tmp_path, mutate, pattern):
    p = _write(tmp_path / "bad.tps", mutate(TPSDIG))
    with pytest.raises(ValueError, match=pattern):
        io.read_landmarks(p)


def test_curves_are_read_apart_from_fixed_landmarks(tmp_path):
    # tpsDig2: CURVES=c, then c POINTS= blocks, between the LM= block and IMAGE=/ID=
    text = """LM=2
10 20
30 40
CURVES=2
POINTS=3
11 21
12 22
13 23
POINTS=2
31 41
32 42
IMAGE=a.jpg
ID=a
LM=2
50 60
70 80
CURVES=2
POINTS=3
51 61
52 62
53 63
POINTS=2
71 81
72 82
IMAGE=b.jpg
ID=b
"""
    p = _write(tmp_path / "curves.tps", text)
    shapes, spec, curves = io.read_tps(p, return_curves=True)
    np.testing.assert_array_equal(shapes, [[[10, 20], [30, 40]], [[50, 60], [70, 80]]])
    assert [len(c) for c in curves] == [2, 2] and curves[1][0].shape == (3, 2)
    np.testing.assert_array_equal(curves[1][1], [[71, 81], [72, 82]])
    assert spec["n_curve_points"].tolist() == [5, 5]
    np.testing.assert_array_equal(io.read_landmarks(p)[0], shapes)  # semilandmarks never mixed in
    # round trip through our writer and through ktch
    io.write_tps(tmp_path / "out.tps", shapes, spec, curves=curves)
    s2, _, c2 = io.read_tps(tmp_path / "out.tps", return_curves=True)
    np.testing.assert_array_equal(s2, shapes)
    np.testing.assert_array_equal(c2[0][0], curves[0][0])
    k = ktch_io.read_tps(tmp_path / "out.tps")
    np.testing.assert_array_equal(k[0].curves[0], curves[0][0])
    with pytest.raises(ValueError, match=r"curves\.tps: line 11: specimen #1 \(LM= at line 1\): its curve 2 \(POINTS=2\) header declares 2 points but only 1"):
        io.read_tps(_write(tmp_path / "curves.tps", text.replace("32 42\n", "", 1)))


def test_3d_lm3_blocks(tmp_path):
    text = "LM3=3\n1 2 3\n4 5 6\n7 8 9.5e-1\nID=s1\n\nLM3=3\n0 0 1\n0 1 0\n1 0 0\nID=s2\n"
    shapes, spec = io.read_landmarks(_write(tmp_path / "x.tps", text))
    assert shapes.shape == (2, 3, 3) and shapes[0, 2, 2] == 0.95
    io.write_tps(tmp_path / "y.tps", shapes, spec)
    assert (tmp_path / "y.tps").read_text().startswith("LM3=3\n")
    np.testing.assert_array_equal(io.read_tps(tmp_path / "y.tps")[0], shapes)
    k = ktch_io.read_tps(tmp_path / "y.tps")
    np.testing.assert_array_equal(np.stack([s.landmarks for s in k]), shapes)


def test_geomorph_writeland_layout(tmp_path):
    # writeland.tps: LM=p, write.table rows, optional SCALE=, ID=, then an empty line
    text = "LM=3\n0.1 -0.2\n0.3 0.4\n-0.5 0.6\nSCALE=1\nID=sp1\n\nLM=3\n1 2\n3 4\n5 6\nSCALE=1\nID=sp2\n\n"
    p = _write(tmp_path / "gm.tps", text)
    with pytest.raises(ValueError, match=r"gm\.tps: line 2, specimen 'sp1' \(#1\): landmark 1 is missing"):
        io.read_tps(p)
    shapes, spec = io.read_tps(p, negative="coordinates", scale=True)
    np.testing.assert_array_equal(shapes[0], [[0.1, -0.2], [0.3, 0.4], [-0.5, 0.6]])
    assert spec["id"].tolist() == ["sp1", "sp2"]


def test_ktch_oracle_both_directions(tmp_path, rng):
    shapes = rng.uniform(0, 500, size=(5, 7, 2)).round(3)
    ids = [f"spec{i}" for i in range(5)]
    ktch_io.write_tps(tmp_path / "k.tps", shapes, idx=ids, image_path=[f"{i}.jpg" for i in ids], scale=0.5)
    ours, spec = io.read_tps(tmp_path / "k.tps")
    np.testing.assert_array_equal(ours, shapes)
    assert spec["id"].tolist() == ids and (spec["scale"] == 0.5).all()
    np.testing.assert_array_equal(io.read_tps(tmp_path / "k.tps", scale=True)[0], shapes * 0.5)
    # our writer -> ktch, with full float64 precision
    precise = rng.uniform(0, 500, size=(4, 6, 2))
    io.write_tps(tmp_path / "o.tps", precise, ids[:4])
    theirs = ktch_io.read_tps(tmp_path / "o.tps")
    np.testing.assert_array_equal(np.stack([t.landmarks for t in theirs]), precise)
    assert [t.specimen_name for t in theirs] == ids[:4]
    np.testing.assert_array_equal(io.read_tps(tmp_path / "o.tps")[0], precise)


def test_negative_coordinates_are_marked_by_the_writer_and_read_back_as_written(tmp_path, rng):
    x = rng.normal(size=(3, 4, 2))  # centred, like aligned shapes
    x[2, 1] = np.nan  # a missing landmark among negative coordinates is written NA
    spec = pd.DataFrame({"id": ["a", "b", "c"], "comment": ["left side", None, None]})
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing to warn about: the file says what it holds
        io.write_landmarks(tmp_path / "neg.tps", x, spec)
    text = (tmp_path / "neg.tps").read_text()
    assert text.count(f"COMMENT={io.NEGATIVE_COORDINATES_COMMENT}") == 3 and "NA NA" in text
    back, table = io.read_landmarks(tmp_path / "neg.tps", missing="nan")
    np.testing.assert_array_equal(back, x)
    assert table["comment"].tolist()[0] == "left side"  # the user's comment, not the marker
    # an independent reader (ktch, which knows no NA) reads a marked file without missing landmarks
    io.write_tps(tmp_path / "full.tps", x[:2])
    np.testing.assert_array_equal(np.stack([t.landmarks for t in ktch_io.read_tps(tmp_path / "full.tps")]), x[:2])
    # an explicit choice still decides: negative values as tpsDig's missing code
    assert np.isnan(io.read_tps(tmp_path / "neg.tps", negative="missing", missing="nan")[0][0]).any()
    # without negative coordinates: no marker, missing landmarks in tpsDig's code
    y = np.abs(x)
    io.write_tps(tmp_path / "m.tps", y)
    assert "-1 -1" in (tmp_path / "m.tps").read_text() and "COMMENT=" not in (tmp_path / "m.tps").read_text()
    back, spec = io.read_tps(tmp_path / "m.tps", missing="nan")
    np.testing.assert_array_equal(np.isnan(back), np.isnan(y))
    # another program's aligned file (no marker): negatives are missing unless told
    (tmp_path / "other.tps").write_text(text.replace(f"COMMENT={io.NEGATIVE_COORDINATES_COMMENT}\n", ""))
    with pytest.raises(ValueError, match="is missing"):
        io.read_tps(tmp_path / "other.tps")
    np.testing.assert_array_equal(io.read_tps(tmp_path / "other.tps", negative="coordinates", missing="nan")[0], x)


# ------------------------------------------------------------------------------------------ CSV


def test_csv_wide_numbered_named_and_geomorph_two_d_array(tmp_path):
    _write(tmp_path / "w.csv", "id,sex,x1,y1,x2,y2,x3,y3\nA,F,1,2,3,4,5,6\nB,M,1.5e1,2,3,4,5,-6\n", crlf=True)
    shapes, spec = io.read_landmarks(tmp_path / "w.csv")
    np.testing.assert_array_equal(shapes, [[[1, 2], [3, 4], [5, 6]], [[15, 2], [3, 4], [5, -6]]])
    assert spec.columns[0] == "id" and spec["id"].tolist() == ["A", "B"] and spec["sex"].tolist() == ["F", "M"]
    # named landmark columns
    _write(tmp_path / "n.csv", "specimen,snout_x,snout_y,tail_x,tail_y\nA,1,2,3,4\n\nB,5,6,7,8\n")
    shapes, spec = io.read_landmarks(tmp_path / "n.csv")
    assert shapes.shape == (2, 2, 2) and spec.attrs["landmarks"] == ["snout", "tail"]
    # R's write.csv(two.d.array(A)): quoted headers, an unnamed row-name column, NA for missing
    _write(tmp_path / "r.csv", '"","1.X","1.Y","2.X","2.Y"\n"sp1",1,2,3,4\n"sp2",5,NA,7,8\n')
    with pytest.raises(ValueError, match=r"r\.csv: line 3, specimen 'sp2' \(#2\): landmark 1 is missing"):
        io.read_landmarks(tmp_path / "r.csv")
    shapes, spec = io.read_landmarks(tmp_path / "r.csv", missing="nan")
    assert spec["id"].tolist() == ["sp1", "sp2"] and np.isnan(shapes[1, 0, 1])


def test_csv_long(tmp_path):
    _write(tmp_path / "l.csv", "specimen,landmark,x,y,z\nA,2,3,4,5\nA,1,0,1,2\nB,1,9,9,9\nB,2,8,8,8\n")
    shapes, spec = io.read_landmarks(tmp_path / "l.csv")
    np.testing.assert_array_equal(shapes, [[[0, 1, 2], [3, 4, 5]], [[9, 9, 9], [8, 8, 8]]])
    assert spec["id"].tolist() == ["A", "B"] and spec.attrs["layout"] == "long"


@pytest.mark.parametrize("text, pattern", [
    ("id,x1,y1,x2,y2\nA,1,2,3,4\nB,1,two,3,4\n",
     r"bad\.csv: line 3, specimen 'B', landmark 1 \('1'\): non-numeric value 'two' in column 'y1'"),
    ("id,x1,y1,x2,y2\nA,1,2,3,4\nB,1,2,3\n",
     r"bad\.csv: line 3, specimen 'B' \(#2\): landmark 2 is missing"),
    ("id,x1,y1,x2\nA,1,2,3\n",
     r"bad\.csv: landmark '2' has coordinate column\(s\) \['x2'\]"),
    ("", r"bad\.csv: empty file"),
    ("id,x1,y1\n", r"bad\.csv: no data rows"),
    ("id,weight\nA,3\n", r"bad\.csv: no coordinate columns"),
    ("specimen,landmark,x,y\nA,1,0,0\nA,2,1,1\nB,1,0,0\n",
     r"bad\.csv: specimen 'B' \(first at line 4\) has no row for landmark '2'"),
    ("specimen,landmark,x,y\nA,1,0,0\nA,1,1,1\n",
     r"bad\.csv: line 3: specimen 'A' has landmark '1' twice"),
    ("specimen,landmark,x,y\nA,1,0,0\nA,2,x,1\n",
     r"bad\.csv: line 3, specimen 'A', landmark 2: non-numeric value 'x' in column 'x'"),
    # a repeated header: pandas renames the second copy x2.1/y2.1, which must not become metadata
    ("id,x1,y1,x2,y2,x2,y2,x3,y3\nA,10,10,20,10,25,15,20,20\nB,11,10,21,11,26,16,20,21\n",
     r"bad\.csv: line 1: duplicate column names \['x2', 'y2'\]"),
    ("\nspecimen,snout_x,snout_y,tail_x,tail_y,snout_x,snout_y\nA,1,2,3,4,5,6\n",
     r"bad\.csv: line 2: duplicate column names \['snout_x', 'snout_y'\]"),
    ("specimen,landmark,x,y,y\nA,1,0,0,0\n",
     r"bad\.csv: line 1: duplicate column names \['y'\]"),
    ("id,x1,y1,x2,y2\nA,1,2,3,4\nB,1,2,inf,4\n",
     r"bad\.csv: line 3, specimen 'B', landmark 2 \('2'\): non-finite value 'inf' in column 'x2' \(coordinates must be finite numbers\)"),
    ("id,x1,y1,x2,y2\nA,1,2,3,4\nB,1,2,3,-1e400\n",
     r"bad\.csv: line 3, specimen 'B', landmark 2 \('2'\): non-finite value '-1e400' in column 'y2'"),
    ("specimen,landmark,x,y\nA,1,0,0\nA,2,-Infinity,1\n",
     r"bad\.csv: line 3, specimen 'A', landmark 2: non-finite value '-Infinity' in column 'x'"),
])
def test_malformed_csv(tmp_path, text, pattern):
    p = _write(tmp_path / "bad.csv", text)
    with pytest.raises(ValueError, match=pattern):
        io.read_landmarks(p)


def test_csv_column_named_like_a_pandas_renamed_duplicate_is_metadata(tmp_path):
    # no repeated header here: 'x2.1' is an ordinary metadata column, not a second copy of x2
    _write(tmp_path / "m.csv", "id,x2.1,x1,y1,x2,y2,y2.1\nA,left,1,2,3,4,7\nB,right,5,6,7,8,9\n")
    shapes, spec = io.read_landmarks(tmp_path / "m.csv")
    np.testing.assert_array_equal(shapes, [[[1, 2], [3, 4]], [[5, 6], [7, 8]]])
    assert spec["x2.1"].tolist() == ["left", "right"] and spec["y2.1"].tolist() == ["7", "9"]
    # blank header cells (trailing commas) are not duplicates: pandas names them Unnamed: n
    _write(tmp_path / "t.csv", "id,x1,y1,,\nA,1,2,,\n")
    assert io.read_landmarks(tmp_path / "t.csv")[0].shape == (1, 1, 2)


def test_utf8_bom_with_latin1_bytes_is_stripped(tmp_path):
    # a BOM, then ANSI (latin-1) text: not valid UTF-8, read as latin-1 without the BOM's bytes
    p = tmp_path / "bom.tps"
    p.write_bytes(b"\xef\xbb\xbfLM=3\r\n1 1\r\n2 1\r\n2 2\r\nID=caf\xe9\r\n")
    shapes, spec = io.read_tps(p)
    np.testing.assert_array_equal(shapes, [[[1, 1], [2, 1], [2, 2]]])
    assert spec["id"].tolist() == ["caf\u00e9"]
    q = tmp_path / "bom.csv"
    q.write_bytes(b"\xef\xbb\xbfid,x1,y1\r\ncaf\xe9,1,2\r\n")
    shapes, spec = io.read_landmarks(q)
    assert spec.columns.tolist()[0] == "id" and spec["id"].tolist() == ["caf\u00e9"]


# ------------------------------------------------------------------------------------ round trips


@pytest.mark.parametrize("name, kw", [("s.tps", {}), ("s.csv", {}), ("s.csv", {"layout": "long"}),
                                      ("s.npy", {}), ("s.npz", {})])
@pytest.mark.parametrize("d", [2, 3])
def test_round_trip_is_exact(tmp_path, rng, name, kw, d):
    x = rng.uniform(1, 1000, size=(4, 5, d)) * 10.0 ** rng.integers(-8, 8, size=(4, 5, d))
    ids = ["a", "b b", "c", "d"]
    io.write_landmarks(tmp_path / name, x, ids, **kw)
    back, spec = io.read_landmarks(tmp_path / name)
    np.testing.assert_array_equal(back, x)
    assert spec["id"].tolist() == (ids if name != "s.npy" else ["0", "1", "2", "3"])


def test_pkn_layout(rng, tmp_path):
    x = rng.normal(size=(20, 10, 2))
    pkn = io.to_pkn(x)
    assert pkn.shape == (10, 2, 20)
    np.testing.assert_array_equal(pkn[:, :, 3], x[3])  # geomorph: A[, , i] is specimen i
    np.testing.assert_array_equal(io.from_pkn(pkn), x)
    with pytest.raises(ValueError, match=r"k = shape\[1\] must be 2 or 3.*looks like shapelib's \(N, K, d\)"):
        io.from_pkn(x)
    np.save(tmp_path / "pkn.npy", pkn)
    with pytest.raises(ValueError, match=r"pkn\.npy: landmarks must have d = 2 or 3.*p x k x n.*from_pkn"):
        io.read_landmarks(tmp_path / "pkn.npy")
    np.testing.assert_array_equal(io.read_landmarks(tmp_path / "pkn.npy", layout="pkn")[0], x)


def test_dispatch_errors(tmp_path):
    with pytest.raises(ValueError, match=r"unknown landmark file extension '\.txt'"):
        io.read_landmarks(tmp_path / "a.txt")
    with pytest.raises(ValueError, match=r"a\.tps: no such file"):
        io.read_landmarks(tmp_path / "a.tps")
    (tmp_path / "bad.npy").write_bytes(b"not numpy")
    with pytest.raises(ValueError, match=r"bad\.npy: not a readable NumPy file"):
        io.read_landmarks(tmp_path / "bad.npy")
    with pytest.raises(ValueError, match="missing must be 'error' or 'nan'"):
        io.read_landmarks(tmp_path / "bad.npy", missing="drop")


def test_duplicate_ids_warn(tmp_path):
    p = _write(tmp_path / "dup.tps", TPSDIG.replace("ID=1", "ID=0"))
    with pytest.warns(UserWarning, match=r"dup\.tps: specimen id '0' occurs more than once"):
        io.read_tps(p)
