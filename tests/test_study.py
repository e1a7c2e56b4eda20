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
