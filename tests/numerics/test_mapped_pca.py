"""PCA of frames that are a linear map of smaller data (mesh frames interpolated from markers), computed in the
small space and lifted: it must equal the PCA of the materialised frames."""

import numpy as np
import pytest

from workbench.api import run_study
from workbench.core.errors import WorkbenchError
from workbench.dataset import build_captures
from workbench.numerics.bases import Eigenfaces
from workbench.settings.config import compose, resolved_without_hydra


@pytest.mark.parametrize("n_frames,k,n_dims", [(500, 30, 900), (40, 60, 300)])
def test_mapped_pca_equals_pca_of_the_mapped_frames(n_frames, k, n_dims):
    rng = np.random.default_rng(n_frames)
    small = rng.standard_normal((n_frames, k)) @ np.diag(np.linspace(3.0, 0.1, k)) + rng.standard_normal(k)
    operator = rng.standard_normal((n_dims, k))
    direct = Eigenfaces(coverage=0.99).fit(small @ operator.T)
    lifted = Eigenfaces(coverage=0.99).fit_mapped(small, operator)
    assert lifted.method_ == "mapped" and lifted.n_components_ == direct.n_components_
    rank = direct.explained_variance_.size
    np.testing.assert_allclose(lifted.explained_variance_[:rank], direct.explained_variance_, rtol=1e-9)
    np.testing.assert_allclose(lifted.components_, direct.components_, atol=1e-9)  # same deterministic signs
    np.testing.assert_allclose(lifted.mean_, direct.mean_, atol=1e-10)
    assert lifted.coverage_ == pytest.approx(direct.coverage_, abs=1e-12)
    fixed = Eigenfaces(n_components=3).fit_mapped(small, operator)
    np.testing.assert_allclose(
        fixed.components_, Eigenfaces(n_components=3).fit(small @ operator.T).components_, atol=1e-9
    )


def test_mapped_pca_rejects_mismatched_operator():
    with pytest.raises(WorkbenchError, match="operator must have shape"):
        Eigenfaces().fit_mapped(np.ones((10, 4)) + np.arange(4), np.ones((12, 5)))


def test_rbf_mesh_capture_carries_its_marker_source_and_the_study_uses_it():
    cfg = resolved_without_hydra(
        compose(
            "paper",
            [
                "dataset.n_frames=400",
                "dataset.train_on=[markers,mesh_rbf]",
                "dataset.mesh_rows=30",
                "dataset.mesh_cols=26",
                "solver=lstsq",
            ],
        )
    )
    captures = build_captures(cfg["dataset"])
    mesh = captures["mesh_rbf"]
    assert captures["markers"].train_source is None
    np.testing.assert_allclose(mesh.train_source @ mesh.train_operator.T, mesh.train, atol=1e-9)
    results = {result.data: result for result in run_study(cfg)}
    lifted = results["mesh_rbf"].eigenfaces
    direct = Eigenfaces(coverage=cfg["basis"]["coverage"]).fit(mesh.train)
    assert lifted.method_ == "mapped" and lifted.n_components_ == direct.n_components_
    np.testing.assert_allclose(lifted.components_, direct.components_, atol=1e-8)
