"""The paper study end to end: records, the table, independent recomputation, determinism, the CLI."""

import json

import numpy as np
import pandas as pd
import pytest
from scipy.optimize import lsq_linear

from workbench.api import run
from workbench.record.record import DONE
from workbench.settings.config import compose

SMALL = ["dataset.n_frames=4000", "save_inputs=true", "basis.paper_regime=false"]  # 33 s of performance: enough
# motion above the noise; the coverage rule's run alone (the m = n variant: tests/study/test_regime.py)


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    output = tmp_path_factory.mktemp("paper")
    text = run(compose("paper", SMALL), output)
    return output, text


def test_run_writes_a_complete_record(small_run):
    output, text = small_run
    for name in (
        "config.yaml",
        "alpha_table.csv",
        "alpha_table.md",
        "metrics.json",
        "timings.json",
        "inputs.npz",
        DONE,
    ):
        assert (output / name).is_file(), name
    assert not list(output.glob(".*.tmp"))
    metrics = json.loads((output / "metrics.json").read_text())
    assert list(metrics["data"]) == ["markers"] and metrics["data"]["markers"]["n_points"] == 66
    assert "synthetic" in metrics["dataset"]["name"]
    assert len(metrics["data"]["markers"]["intuitiveness"]) == 2 * 18
    assert (output / "alpha_table.md").read_text() == text
    assert "paper: m = 18 at 0.995" in text


def test_table_has_every_basis_and_solver(small_run):
    table = pd.read_csv(small_run[0] / "alpha_table.csv")
    assert list(table["basis"]) == ["H", "QE", "QE-linear"] * 3 + ["PCA"]
    assert set(table["data"]) == {"markers"}
    assert list(table["solver"]) == ["lstsq"] * 3 + ["nnls"] * 3 + ["box"] * 3 + ["projection"]
    assert table.loc[table["basis"] == "QE", "paper_alpha"].iloc[0] == 0.72
    assert (table["alpha_abs_mean"] >= 0).all()


def test_quasi_eigen_beats_hand_basis_under_least_squares(small_run):
    table = pd.read_csv(small_run[0] / "alpha_table.csv").set_index(["basis", "solver"])
    for column in ("alpha_abs_mean", "alpha_disp_pooled"):
        assert table.loc[("QE", "lstsq"), column] < 0.6 * table.loc[("H", "lstsq"), column]


@pytest.mark.slow
def test_table_recomputed_independently_from_inputs(small_run):
    """Recompute H, QE and PCA rows from inputs.npz with plain NumPy/SciPy (SVD, per-frame lsq_linear)."""
    output, _ = small_run
    data = np.load(output / "inputs.npz", allow_pickle=False)
    table = pd.read_csv(output / "alpha_table.csv").set_index(["basis", "solver"])
    train, evaluate, neutral, hand = data["train"], data["eval"], data["neutral"], data["hand"]
    mean = train.mean(axis=0)
    _, singular, vt = np.linalg.svd(train - mean, full_matrices=False)
    variance = singular**2
    m = int(np.searchsorted(np.cumsum(variance) / variance.sum(), 0.995) + 1)
    assert m == table["m"].iloc[0]
    axes = vt[:m]
    np.testing.assert_allclose(np.abs(axes @ data["components"].T), np.eye(m), atol=1e-6)
    quasi_eigen = mean + ((hand - mean) @ axes.T) @ axes

    def alpha_abs_mean(reconstruction):
        target = neutral + evaluate
        return np.mean(
            100 * np.linalg.norm(target - (neutral + reconstruction), axis=1) / np.linalg.norm(target, axis=1)
        )

    pca = mean + ((evaluate - mean) @ axes.T) @ axes
    assert alpha_abs_mean(pca) == pytest.approx(table.loc[("PCA", "projection"), "alpha_abs_mean"], rel=1e-6)
    for label, basis in (("H", hand), ("QE", quasi_eigen)):
        weights = np.linalg.lstsq(basis.T, evaluate.T, rcond=None)[0].T
        assert alpha_abs_mean(weights @ basis) == pytest.approx(table.loc[(label, "lstsq"), "alpha_abs_mean"], rel=1e-6)
        boxed = np.array([lsq_linear(basis.T, frame, bounds=(0, 1), method="bvls", tol=1e-12).x for frame in evaluate])
        assert alpha_abs_mean(boxed @ basis) == pytest.approx(table.loc[(label, "box"), "alpha_abs_mean"], rel=1e-5)


def test_same_config_gives_identical_tables(small_run, tmp_path):
    run(compose("paper", SMALL), tmp_path)
    assert (tmp_path / "alpha_table.csv").read_bytes() == (small_run[0] / "alpha_table.csv").read_bytes()


def test_cli_runs_and_prints_the_table(tmp_path, cli, tiny_study):
    result = cli(*tiny_study, "solver=box", f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    basis_cells = [line.split("|")[2].strip() for line in result.stdout.splitlines() if line.startswith("|")]
    assert basis_cells[0] == "basis" and {"H", "QE", "QE-linear", "PCA"} <= set(basis_cells)
    assert (tmp_path / "run" / DONE).is_file()


def test_cli_bad_parameter_is_one_line(tmp_path, cli, tiny_study):
    result = cli(*tiny_study, "basis.coverage=1.5", f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
    assert result.returncode == 2
    assert result.stderr.strip() == "workbench: error: basis.coverage must be in (0, 1], got 1.5"
    assert not (tmp_path / "run" / DONE).exists()


def test_cli_multirun_sweeps(tmp_path, cli):
    result = cli(
        "-m",
        "dataset.n_frames=300",
        "solver=box",
        "basis.coverage=0.99,0.995",
        f"hydra.sweep.dir={tmp_path / 'sweep'}",
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stderr
    # each run in a folder named by its overrides, so that the same sweep run again resumes
    coverages = sorted(
        float(
            pd.read_csv(
                tmp_path / "sweep" / f"basis.coverage={coverage},dataset.n_frames=300,solver=box" / "alpha_table.csv"
            )["coverage"][0]
        )
        for coverage in ("0.99", "0.995")
    )
    assert coverages[0] <= coverages[1]


@pytest.mark.slow
def test_paper_scale_default_study(tmp_path, cli):
    """The README's run command at paper scale (35,000 frames, 66 markers)."""
    result = cli(f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    table = pd.read_csv(tmp_path / "run" / "alpha_table.csv")
    table = table[table["data"] == "markers"].set_index(["basis", "solver"])  # the coverage rule's variant
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert len(metrics["dataset"]["hand_names"]) == 18 and metrics["data"]["markers"]["n_eval_frames"] == 35000
    assert metrics["data"]["markers m=n"]["n_eval_frames"] == 35000  # and the paper's regime m = n beside it
    assert table.loc[("QE", "lstsq"), "alpha_abs_mean"] < 0.6 * table.loc[("H", "lstsq"), "alpha_abs_mean"]


def test_markers_and_mesh_in_one_run(tmp_path):
    """dataset.train_on as a list runs the method on each data variant of the same take, one table."""
    text = run(
        compose(
            "paper",
            [
                "dataset.n_frames=600",
                "dataset.train_on=[markers,mesh]",
                "solver=lstsq",
                "basis.paper_regime=false",
                "save_inputs=true",
            ],
        ),
        tmp_path,
    )
    table = pd.read_csv(tmp_path / "alpha_table.csv")
    assert list(table["data"]) == ["markers"] * 4 + ["mesh"] * 4
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["data"]["markers"]["n_points"] == 66 and metrics["data"]["mesh"]["n_points"] == 4200
    assert (tmp_path / "inputs_markers.npz").is_file()
    with np.load(tmp_path / "inputs_mesh.npz", allow_pickle=False) as mesh_inputs:
        assert mesh_inputs["faces"].shape[1] == 3 and mesh_inputs["faces"].max() == 4199
    assert "data 'mesh': 600 training frames" in text and "mesh: alpha_abs_mean with lstsq" in text
