import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pytest

from shapelib.study import load_values, pair_key, record_values, save_figure


def test_record_values_merges_and_round_trips(tmp_path):
    record_values(tmp_path, {"a/x/1-2": 1.5}, notes={"a": "n"})
    record_values(tmp_path, {"a/x/1-3": np.float64(2.5)}, meta={"t": np.arange(3)})
    data = load_values(tmp_path)
    assert data["values"] == {"a/x/1-2": 1.5, "a/x/1-3": 2.5}
    assert data["notes"] == {"a": "n"} and data["meta"] == {"t": [0, 1, 2]}


@pytest.mark.parametrize("bad", [np.nan, np.inf, "1.0", None, True])
def test_record_values_rejects_non_numbers(tmp_path, bad):
    with pytest.raises(ValueError):
        record_values(tmp_path, {"k": bad})
    assert not (tmp_path / "values.json").exists()


def test_pair_key_sorts_ids():
    assert pair_key("table1", "tps", 8, 3) == "table1/tps/3-8"


def test_save_figure_is_byte_deterministic(tmp_path):
    def draw(name):
        fig, ax = plt.subplots()
        ax.plot([0, 1, 2], [1, 0, 1], "k.-")
        path = save_figure(fig, tmp_path, name)
        plt.close(fig)
        return path.read_bytes()

    assert draw("a") == draw("b")


def test_stratified_sample_is_balanced_reproducible_and_within_the_indices():
    from shapelib.study import stratified_sample

    group = np.repeat([0, 1, 2], [50, 30, 5])  # a small third cell: it gives all it has
    cells = [group == g for g in range(3)]
    idx = np.arange(10, 85)  # a subset of the whole range: the masks index the whole range
    picked = stratified_sample(idx, 31, cells, np.random.default_rng(4))
    assert np.all(np.diff(picked) > 0) and np.isin(picked, idx).all()
    counts = np.bincount(group[picked], minlength=3)
    assert counts.tolist() == [11, 10, 5]  # 31 // 3 + (k < 31 % 3), the last capped at the 5 it has
    again = stratified_sample(idx, 31, cells, np.random.default_rng(4))
    np.testing.assert_array_equal(picked, again)
    np.testing.assert_array_equal(stratified_sample(idx[::-1], 200, cells, None), idx)
