"""What one study run returns: the table rows, the result of one data variant, the stages' times."""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from workbench.dataset.capture import Capture
from workbench.numerics.bases import Eigenfaces
from workbench.numerics.metrics import AlphaSummary, Conditioning, ErrorDistribution, WeightStatistics
from workbench.numerics.reduced import SpanPass

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
    """One line of the alpha table: a basis reconstructed with one solver.

    ``weight_statistics`` (None for PCA, whose coefficients are no animator's weights), ``frame_error_mm`` (RMS
    point error of each evaluated frame over the face region, :func:`face_region`) and its ``error_mm``
    distribution are set by :func:`frame_measures`; ``offset_error_share`` is the share of the squared error
    along the capture mean's part outside the eigenfaces' span (:func:`outside_offset`), NaN where not taken;
    ``clean_alpha`` is the same reconstruction scored against the clean frames (``metric.score_clean``).
    """

    basis: str
    projection: str
    solver: str
    n_shapes: int
    alpha: AlphaSummary
    n_iterations: int = 0
    n_fallback_frames: int = 0
    max_kkt_violation: float = 0.0
    max_abs_weight: float = float("nan")
    conditioning: Conditioning | None = None
    weight_statistics: WeightStatistics | None = None
    frame_error_mm: np.ndarray | None = None
    error_mm: ErrorDistribution | None = None
    offset_error_share: float = float("nan")
    clean_alpha: AlphaSummary | None = None


@dataclass(frozen=True, repr=False)
class StudyResult:
    """Everything a run computed on one data variant; :attr:`name` tells the results of one run apart.

    Attributes
    ----------
    data : str
        The data variant: ``dataset.train_on``'s (``markers``, ``mesh``, ...), ``<variant> m=n`` for the paper's
        regime (``basis.paper_regime``), ``<variant> held-out <protocol>`` for a held-out protocol, and
        ``<train_on>-><eval_on>`` for bases carried onto other points (``dataset.eval_on``); the alpha table's
        ``data`` column. Distinct within a run.
    capture : Capture
        The frames scored; the variants of one dataset share its ``name``.
    eigenfaces : Eigenfaces
    quasi_eigen : dict
        Projection name -> :class:`workbench.numerics.bases.QuasiEigenBasis`.
    rows : list of Row
    weights : dict
        ``(basis, solver)`` -> ndarray of shape (n_eval_frames, n_shapes).
    timings : Timings
    train_on : str
        The data variant the bases were fitted on (``data`` unless ``dataset.eval_on`` is set).
    eval_on : str
        The data variant scored (``capture`` is its capture).
    transfer : str
        How the fitted bases were carried from ``train_on``'s points to ``eval_on``'s (``identity`` when the
        same; see :mod:`workbench.dataset.transfer`).
    basis_intuitiveness : dict
        Closeness, locality and usage of every basis (:func:`basis_intuitiveness`) when ``basis.alternatives``
        is set; empty otherwise.
    face_region : str
        Which points the per-frame error in millimetres is taken over (:func:`face_region`).
    offset : dict
        The capture mean's part outside the eigenfaces' span, ``(I - P) mu`` (:func:`outside_offset`): its
        ``norm`` and its ``ratio`` to the median evaluated frame's displacement norm; empty when not taken.
    protocol : str
        Which frames were scored: ``training frames`` (those the bases were fitted on, or as ``dataset.split``
        says) or a held-out protocol of ``dataset.held_out`` (:data:`HELD_OUT`).
    folds : dict
        Cross-validated held-out frames (``dataset.held_out`` kfold or take_out): each fold's m, frames and alphas
        (``workbench.study.crossval.fold_values``); empty otherwise.
    span_pass : SpanPass or None
        The scoring pass over the evaluated frames through the bases' joint span (large frames only), handed on to
        this variant's m = n refit (:func:`workbench.study.run.with_paper_regime`), which drops it; None otherwise.
    """

    data: str
    capture: Capture
    eigenfaces: Eigenfaces
    quasi_eigen: dict
    rows: list
    weights: dict
    timings: Timings
    train_on: str = ""
    eval_on: str = ""
    transfer: str = "identity"
    basis_intuitiveness: dict = field(default_factory=dict)
    face_region: str = ""
    offset: dict = field(default_factory=dict)
    protocol: str = "training frames"
    folds: dict = field(default_factory=dict)
    span_pass: SpanPass | None = field(default=None, compare=False)

    @property
    def name(self) -> str:
        """The capture's name and the data variant, e.g. ``ICT Live Link ... [markers m=n]``: distinct within a run."""
        return f"{self.capture.name} [{self.data}]"

    @property
    def m(self) -> int:
        """The number of eigenfaces the bases were fitted with (``eigenfaces.n_components_``)."""
        return int(self.eigenfaces.n_components_)

    @property
    def n_frames(self) -> int:
        """The number of frames scored (``capture.eval``'s rows)."""
        return int(self.capture.eval.shape[0])

    @property
    def n_rows(self) -> int:
        """The number of rows of the alpha table (``len(rows)``)."""
        return len(self.rows)

    def __repr__(self) -> str:
        return f"StudyResult(name={self.name!r}, m={self.m}, n_frames={self.n_frames}, n_rows={self.n_rows})"
