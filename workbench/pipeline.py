"""One run of the paper study: dataset -> bases -> solve -> metrics, returned as plain results.

``run_study`` takes a plain mapping (a resolved config) and returns one :class:`StudyResult` per data variant
(``dataset.train_on``: markers, mesh, ...); writing files is ``workbench.record``'s job and printing is
``workbench.report``'s.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from workbench.bases import Eigenfaces, build_quasi_eigen_basis
from workbench.dataset import build_captures
from workbench.dataset.capture import Capture
from workbench.errors import WorkbenchError
from workbench.metrics import AlphaSummary, intuitiveness, summarise_alpha
from workbench.solve import reconstruct, solve_weights

QE_LABELS = {"affine": "QE", "linear": "QE-linear"}


@dataclass
class Timings:
    """Wall-clock seconds of each stage, in the order they ran."""

    seconds: dict = field(default_factory=dict)

    @contextmanager
    def stage(self, name: str):
        start = time.perf_counter()
        yield
        self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - start


@dataclass(frozen=True)
class Row:
    """One line of the alpha table: a basis reconstructed with one solver."""

    basis: str
    projection: str
    solver: str
    n_shapes: int
    alpha: AlphaSummary
    n_iterations: int = 0
    n_fallback_frames: int = 0
    max_kkt_violation: float = 0.0


@dataclass(frozen=True)
class StudyResult:
    """Everything a run computed.

    Attributes
    ----------
    data : str
        The data variant trained and evaluated on (``dataset.train_on``: ``markers``, ``mesh``, ...).
    capture : Capture
    eigenfaces : Eigenfaces
    quasi_eigen : dict
        Projection name -> :class:`workbench.bases.QuasiEigenBasis`.
    rows : list of Row
    weights : dict
        ``(basis, solver)`` -> ndarray of shape (n_eval_frames, n_shapes).
    timings : Timings
    """

    data: str
    capture: Capture
    eigenfaces: Eigenfaces
    quasi_eigen: dict
    rows: list
    weights: dict
    timings: Timings


def check_solver_config(name: str, solver: Mapping) -> dict:
    """Validate one entry of the ``solver`` config group and return it as keyword arguments."""
    kind = solver.get("kind")
    if kind not in ("lstsq", "nnls", "box"):
        raise WorkbenchError(f"solver.{name}.kind must be one of lstsq, nnls, box; got {kind!r}")
    lower, upper = solver.get("lower"), solver.get("upper")
    if kind == "box" and lower is None and upper is None:
        raise WorkbenchError(f"solver.{name} is a box solver without bounds: set lower and/or upper")
    if kind == "lstsq":
        lower = upper = None
    return {"kind": kind, "lower": lower, "upper": upper}


def run_study(cfg: Mapping) -> list[StudyResult]:
    """Build the data, then for each data variant fit eigenfaces and quasi-eigen faces on the training frames
    and score every basis on the evaluated ones.

    Parameters
    ----------
    cfg : mapping
        A resolved study config with ``dataset``, ``basis`` and ``solver`` groups.

    Returns
    -------
    list of StudyResult
        One per ``dataset.train_on`` variant, in the configured order; they share one :class:`Timings`.
    """
    timings = Timings()
    solvers = {name: check_solver_config(name, spec) for name, spec in cfg["solver"].items()}
    if not solvers:
        raise WorkbenchError("the solver group is empty: choose one of solver=lstsq|nnls|box|all")
    with timings.stage("dataset"):
        captures = build_captures(cfg["dataset"])
    return [run_on_capture(data, capture, cfg["basis"], solvers, timings) for data, capture in captures.items()]


def run_on_capture(data: str, capture: Capture, basis_cfg: Mapping, solvers: Mapping[str, Mapping],
                   timings: Timings) -> StudyResult:
    """The paper's method on one capture: eigenfaces, quasi-eigen faces, weights of every basis and solver, alpha.

    Parameters
    ----------
    data : str
        Name of the data variant, kept in the result.
    capture : Capture
    basis_cfg : mapping
        The ``basis`` config group.
    solvers : mapping
        Solver name -> keyword arguments of :func:`workbench.solve.solve_weights` (see :func:`check_solver_config`).
    timings : Timings
        Stage times are added to it.

    Returns
    -------
    StudyResult
    """
    with timings.stage("pca"):
        eigenfaces = Eigenfaces(coverage=basis_cfg["coverage"], n_components=basis_cfg["n_components"])
        eigenfaces.fit(capture.train)
    with timings.stage("quasi_eigen"):
        quasi_eigen = {
            projection: build_quasi_eigen_basis(
                capture.hand, capture.hand_names, eigenfaces, projection=projection,
                empty_axis_eps=basis_cfg["empty_axis_eps"], empty_axis_scale=basis_cfg["empty_axis_scale"],
                append_empty_axes=basis_cfg["append_empty_axes"])
            for projection in basis_cfg["projections"]}
    bases = [("H", "-", capture.hand)] + [
        (QE_LABELS[projection], projection, qe.shapes) for projection, qe in quasi_eigen.items()]

    rows, weights = [], {}
    for solver_name, solver in solvers.items():
        for label, projection, shapes in bases:
            with timings.stage(f"solve_{solver_name}"):
                solution = solve_weights(shapes, capture.eval, **solver)
            with timings.stage("metrics"):
                summary = summarise_alpha(capture.neutral, capture.eval, reconstruct(shapes, solution.weights))
            weights[(label, solver_name)] = solution.weights
            rows.append(Row(basis=label, projection=projection, solver=solver_name, n_shapes=shapes.shape[0],
                            alpha=summary, n_iterations=solution.n_iterations,
                            n_fallback_frames=solution.n_fallback_frames,
                            max_kkt_violation=solution.max_kkt_violation))
    with timings.stage("pca_reconstruction"):
        summary = summarise_alpha(capture.neutral, capture.eval, eigenfaces.reconstruct(capture.eval))
    rows.append(Row(basis="PCA", projection="-", solver="projection", n_shapes=eigenfaces.n_components_,
                    alpha=summary))
    return StudyResult(data=data, capture=capture, eigenfaces=eigenfaces, quasi_eigen=quasi_eigen, rows=rows,
                       weights=weights, timings=timings)


def intuitiveness_table(result: StudyResult) -> list[dict]:
    """Per hand shape and projection: relative distance and cosine between ``e_i^H`` and ``e_i^QE``."""
    records = []
    n_hand = result.capture.hand.shape[0]
    for projection, qe in result.quasi_eigen.items():
        distance, cosine = intuitiveness(result.capture.hand, qe.shapes[:n_hand])
        for name, d, c, norm in zip(result.capture.hand_names, distance, cosine,
                                    np.linalg.norm(result.capture.hand, axis=1)):
            records.append({"projection": projection, "shape": name, "relative_distance": float(d),
                            "cosine": float(c), "hand_norm": float(norm)})
    return records
