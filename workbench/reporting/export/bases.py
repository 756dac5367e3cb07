"""The bases a run exports: each basis's shapes with the weights of every evaluated frame under one solver
(:class:`ExportedBasis`; PCA as its mean and eigenfaces), and the glTF morph targets that play them back with every
weight in [0, 1] (:func:`playback_targets`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import pandas as pd

from workbench.core.errors import WorkbenchError

ALPHA_COLUMNS = ("alpha_abs_mean", "alpha_abs_pooled", "alpha_disp_mean", "alpha_disp_pooled")


AXES = "+Y up, the face looking along +Z (glTF's convention), coordinates as the data's"
TARGETS_TEXT = (
    "the glTF file's morph-target weights all stay in [0, 1] (the shape-key slider range Blender's "
    "importer sets, which Blender clamps to). A hand-made or quasi-eigen shape '<s>' keeps its own "
    "target '<s>' (weight clipped into [0, 1]); weights above 1 go to '<s>_over' (the shape times "
    "max weight - 1), weights below 0 to '<s>_neg' (the shape times the min weight); a PCA eigenface "
    "'<e>' becomes '<e>_pos' and '<e>_neg', scaled by the largest positive and negative coefficient. "
    "Raw weight of a shape = sum over its targets of scale x target weight (each target's 'scale'); the "
    "raw weights are also in the weights CSV files"
)
PCA_MEAN = "pca_mean"


WEIGHT_TOLERANCE = 1e-9
"""Weights this close outside [0, 1] are clipped into it instead of getting a target of their own (a solver's
rounding: the shape moves a vertex by this fraction of its size, far below float32's resolution)."""


OVER, NEGATIVE, POSITIVE = "_over", "_neg", "_pos"
"""Suffixes of the targets a shape is split into (:func:`playback_targets`)."""


@dataclass(frozen=True)
class ExportedBasis:
    """One basis as it is exported: shapes and the weights of every evaluated frame.

    Attributes
    ----------
    label : str
        ``H``, ``QE``, ``QE-linear``, ``PCA`` or an alternative basis's label.
    names : tuple of str
        One per shape.
    shapes : ndarray of shape (n_shapes, 3 * n_points)
        Displacements from neutral, mm.
    weights : ndarray of shape (n_eval_frames, n_shapes)
    solver : str
        The solver the weights come from (``projection`` for PCA).
    alpha : dict
        The run's alpha of this reconstruction (:data:`ALPHA_COLUMNS`).
    sculpted : tuple of bool
        Per shape: True where weight 1 means the shape as made (a hand shape, its quasi-eigen projection, PCA's
        mean), False for eigenfaces (unit length, no meaning at weight 1).
    """

    label: str
    names: tuple[str, ...]
    shapes: np.ndarray
    weights: np.ndarray
    solver: str
    alpha: dict
    sculpted: tuple[bool, ...] = ()


def pca_weights(result) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """PCA as a morph basis: ``pca_mean`` (weight 1 in every frame) then the eigenfaces with their coefficients.

    Returns
    -------
    names : tuple of str
    shapes : ndarray of shape (1 + m, n_dims)
    weights : ndarray of shape (n_eval_frames, 1 + m)
    """
    from workbench.numerics.solve import solve_weights

    eigenfaces, capture = result.eigenfaces, result.capture
    if capture.eval_visible is None:
        coefficients = (capture.eval - eigenfaces.mean_) @ eigenfaces.components_.T
    else:  # with gaps, the projection becomes least squares over the seen points (as the alpha table does)
        coefficients = solve_weights(
            eigenfaces.components_, capture.eval - eigenfaces.mean_, visible=capture.eval_visible
        ).weights
    names = (PCA_MEAN,) + tuple(f"pca_{j + 1:02d}" for j in range(eigenfaces.n_components_))
    weights = np.hstack([np.ones((len(coefficients), 1)), coefficients])
    return names, np.vstack([eigenfaces.mean_, eigenfaces.components_]), weights


def exported_bases(result, labels: Sequence[str] | None, solver: str, table: pd.DataFrame) -> list[ExportedBasis]:
    """The bases of one data variant's result to export, each with its weights under ``solver``.

    Parameters
    ----------
    result : workbench.study.results.StudyResult
    labels : sequence of str or None
        Basis labels; None: H, every quasi-eigen basis and PCA (PCA only where the bases were not carried onto
        other points; the alternative bases of ``basis.alternatives`` are not kept by the pipeline).
    solver : str
    table : pandas.DataFrame
        The recorded alpha table (for each basis's alpha).
    """
    from workbench.study.results import QE_LABELS

    n_hand = len(result.capture.hand_names)
    shapes = {"H": (result.capture.hand_names, result.capture.hand)}
    shapes.update({QE_LABELS[projection]: (qe.names, qe.shapes) for projection, qe in result.quasi_eigen.items()})
    pca_available = result.transfer == "identity"
    available = [label for label in shapes if (label, solver) in result.weights] + (["PCA"] if pca_available else [])
    chosen = available if labels is None else list(labels)
    unknown = [label for label in chosen if label not in available]
    if unknown or not chosen:
        raise WorkbenchError(
            f"export --bases {','.join(chosen)}: data '{result.data}' with solver '{solver}' has "
            f"bases {available}"
            + ("" if pca_available else " (PCA is not exported where the bases were carried onto other points)")
        )
    rows = table[table["data"] == result.data]
    exported = []
    for label in chosen:
        if label == "PCA":
            names, basis, weights = pca_weights(result)
            row = rows[rows["basis"] == "PCA"]
            used = "projection"
            sculpted = (True,) + (False,) * (len(names) - 1)
        else:
            names, basis = shapes[label]
            weights = result.weights[(label, solver)]
            row = rows[(rows["basis"] == label) & (rows["solver"] == solver)]
            used = solver
            sculpted = tuple(i < n_hand for i in range(len(names)))  # a QE basis's appended eigenfaces are not
        exported.append(
            ExportedBasis(
                label=label,
                names=tuple(names),
                shapes=np.asarray(basis),
                weights=weights,
                solver=used,
                alpha={c: float(row[c].iloc[0]) for c in ALPHA_COLUMNS},
                sculpted=sculpted,
            )
        )
    return exported


@dataclass(frozen=True)
class PlaybackTargets:
    """A basis as morph targets whose weights all lie in [0, 1].

    Attributes
    ----------
    names : tuple of str
        One per target.
    shapes : ndarray of shape (n_targets,) of int
        The basis shape each target is a multiple of.
    scales : ndarray of shape (n_targets,)
        Target = ``scales[k]`` x basis shape ``shapes[k]``.
    weights : ndarray of shape (n_frames, n_targets)
        In [0, 1]; the raw weight of shape ``i`` is the sum of ``scales[k] * weights[:, k]`` over its targets.
    """

    names: tuple[str, ...]
    shapes: np.ndarray
    scales: np.ndarray
    weights: np.ndarray

    def deltas(self, basis_shapes: np.ndarray) -> np.ndarray:
        """Each target's displacements, shape (n_targets, n_dims), from the basis's (n_shapes, n_dims)."""
        return self.scales[:, None] * basis_shapes[self.shapes]

    def raw_weights(self, n_shapes: int) -> np.ndarray:
        """The basis's weights, shape (n_frames, n_shapes), recovered from the targets'."""
        raw = np.zeros((len(self.weights), n_shapes))
        np.add.at(raw.T, self.shapes, (self.weights * self.scales).T)
        return raw


def playback_targets(names: Sequence[str], weights: np.ndarray, sculpted: Sequence[bool]) -> PlaybackTargets:
    """Split a basis into morph targets whose weights stay in [0, 1], reproducing every frame exactly.

    Blender's glTF importer gives each shape key the slider range [0, 1] (widened only to the first key's value)
    and Blender clamps a shape key's value to that range, so weights outside it do not play back. A sculpted
    shape ``s`` keeps its own target at scale 1 (weights clipped into [0, 1]: the slider an animator knows), plus
    ``s_over`` = (max weight - 1) x ``s`` carrying the part above 1 and ``s_neg`` = (min weight) x ``s`` carrying
    the part below 0, each only when the weights need it. An eigenface ``e`` (no meaning at weight 1) becomes
    ``e_pos`` and ``e_neg``, scaled by its largest positive and negative coefficient.

    Parameters
    ----------
    names : sequence of str
        One per shape.
    weights : ndarray of shape (n_frames, n_shapes)
    sculpted : sequence of bool
        Per shape (:attr:`ExportedBasis.sculpted`).

    Returns
    -------
    PlaybackTargets

    Raises
    ------
    WorkbenchError
        When a target's name would repeat another's (a shape named like another's ``_over`` target).
    """
    target_names, sources, scales, columns = [], [], [], []

    def add(name: str, source: int, scale: float, column: np.ndarray) -> None:
        target_names.append(name)
        sources.append(source)
        scales.append(scale)
        columns.append(np.clip(column, 0.0, 1.0) + 0.0)  # + 0.0: no -0.0 in the files

    for i, (name, is_sculpted) in enumerate(zip(names, sculpted)):
        w = weights[:, i]
        high, low = float(np.max(w)), float(np.min(w))
        if is_sculpted:
            add(name, i, 1.0, w)
            if high > 1.0 + WEIGHT_TOLERANCE:
                add(name + OVER, i, high - 1.0, (w - 1.0) / (high - 1.0))
        elif high > WEIGHT_TOLERANCE:
            add(name + POSITIVE, i, high, w / high)
        elif low >= -WEIGHT_TOLERANCE:  # an eigenface no frame uses still gets a target
            add(name + POSITIVE, i, 1.0, np.zeros_like(w))
        if low < -WEIGHT_TOLERANCE:
            add(name + NEGATIVE, i, low, w / low)
    repeated = sorted({name for name in target_names if target_names.count(name) > 1})
    if repeated:
        raise WorkbenchError(
            f"export: morph target name(s) {repeated} would repeat: a shape is named like another "
            f"shape's {OVER!r}/{NEGATIVE!r}/{POSITIVE!r} target; rename the shape"
        )
    return PlaybackTargets(
        names=tuple(target_names),
        shapes=np.asarray(sources, dtype=int),
        scales=np.asarray(scales, dtype=float),
        weights=np.column_stack(columns) if columns else np.zeros((len(weights), 0)),
    )
