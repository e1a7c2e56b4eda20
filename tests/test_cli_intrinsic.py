"""``shapelib mean`` and ``shapelib pca`` run as users run them, on real .tps/.csv files: results
equal the library's, figures written, bad input one line on stderr."""

import numpy as np
import pandas as pd

from shapelib import io
from shapelib.geometry.scale import to_centroid_size
from shapelib.statistics.frechet import frechet_mean
from shapelib.statistics.tangent_pca import tangent_pca
from tests.test_cli import files, one_line_error, run  # noqa: F401  (files: the fixture)


def test_mean_writes_the_library_mean_and_a_figure(files):  # noqa: F811
    out, fig = files["dir"] / "mean.tps", files["dir"] / "mean.png"
    proc = run("mean", files["tps"], "--size", 20, "--metric", "alpha", "--sigma2", 9, "--jobs", 1, "-o", out,
               "--plot", fig, check=0)
    assert "Fréchet mean (alpha" in proc.stdout and "converged True" in proc.stdout
    mean, spec = io.read_landmarks(out, negative="coordinates")
    assert list(spec["id"]) == ["frechet_mean"]
    ref = frechet_mean(to_centroid_size(files["x"], 20), sigma2=9.0, n_jobs=1)
    assert np.allclose(mean[0], ref.mean, atol=1e-4)  # the file keeps ~6 significant digits
    assert fig.stat().st_size > 1000


def test_pca_scores_table_and_modes_figure(files):  # noqa: F811
    out, fig = files["dir"] / "scores.csv", files["dir"] / "modes.png"
    proc = run("pca", files["csv"], "--size", 20, "--metric", "alpha", "--sigma2", 9, "--n-components", 2, "-o", out,
               "--plot", fig, check=0)
    assert "PC1" in proc.stdout and "cumulative" in proc.stdout
    scores = pd.read_csv(out, index_col="id")
    assert list(scores.index) == files["ids"] and list(scores.columns) == ["PC1", "PC2"]
    ref = tangent_pca(to_centroid_size(files["x"], 20), sigma2=9.0, n_components=2, modes=(), n_jobs=1)
    assert np.allclose(scores.to_numpy(), ref.scores, atol=1e-9)
    assert fig.stat().st_size > 1000


def test_bad_input_is_one_line(files):  # noqa: F811
    out = files["dir"] / "m.tps"
    one_line_error(run("mean", files["tps"], "--metric", "procrustes", "--sigma2", 1, "-o", out),
                   "--metric procrustes", "alpha, fisher_rao")
    one_line_error(run("mean", files["tps"], "--metric", "alpha", "--sigma2", -1, "-o", out), "--sigma2")
    one_line_error(run("pca", files["tps"], "--metric", "alpha", "--sigma2", 9, "-o", files["dir"] / "s.txt"),
                   "-o", ".csv")
    one_line_error(run("pca", files["tps"], "--metric", "alpha", "--sigma2", 9, "--n-components", 0, "-o",
                       files["dir"] / "s.csv"), "--n-components")
    broken = files["dir"] / "broken.tps"
    broken.write_text(files["tps"].read_text().replace("LM=9", "LM=10", 1))
    one_line_error(run("mean", broken, "--metric", "alpha", "--sigma2", 9, "-o", out), "broken.tps", "LM=10")
    assert not out.exists()
    assert run("mean", files["tps"]).returncode == 2  # usage: --metric, --sigma2, -o missing


def test_mean_and_pca_of_three_dimensional_landmarks(tmp_path):
    """A 3-D landmark CSV (x, y, z columns): the commands give the library's mean and scores, and
    draw the 3-D shapes."""
    from shapelib.geometry.procrustes import pose_align
    from tests.conftest import ellipse_population

    x = ellipse_population(np.random.default_rng(5), 6, 8, 3, noise=0.1) * 2.5
    src = tmp_path / "saddles.csv"
    io.write_landmarks(src, x, pd.DataFrame({"id": [f"s{i}" for i in range(len(x))]}))
    mean_out, scores_out, fig = tmp_path / "mean.csv", tmp_path / "scores.csv", tmp_path / "mean.png"
    run("mean", src, "--size", 20, "--metric", "alpha", "--sigma2", 4, "--jobs", 1, "-o", mean_out, "--plot", fig,
        check=0)
    mean, _ = io.read_landmarks(mean_out)
    shapes = pose_align(to_centroid_size(x, 20))[0]
    ref = frechet_mean(shapes, sigma2=4.0, n_jobs=1)
    assert mean.shape == (1, 8, 3) and np.allclose(mean[0], ref.mean, atol=1e-4)
    assert fig.stat().st_size > 1000
    modes_fig = tmp_path / "modes.png"
    run("pca", src, "--size", 20, "--metric", "alpha", "--sigma2", 4, "--n-components", 2, "-o", scores_out,
        "--plot", modes_fig, check=0)
    assert modes_fig.stat().st_size > 1000
    scores = pd.read_csv(scores_out, index_col="id")
    ref = tangent_pca(shapes, sigma2=4.0, n_components=2, modes=(), n_jobs=1)
    assert np.allclose(np.abs(scores.to_numpy()), np.abs(ref.scores), atol=1e-6)
