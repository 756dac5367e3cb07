"""Fitting the bases of a run: eigenfaces (eq. 2) with their coverage rule, quasi-eigen faces (eq. 3-4) and the
alternative bases (``basis.alternatives``)."""

from __future__ import annotations

import weakref
from dataclasses import asdict

import numpy as np

from workbench.dataset.capture import Capture
from workbench.dataset.transfer import PointTransfer
from workbench.numerics.bases import Eigenfaces, build_quasi_eigen_basis
from workbench.numerics.reduced import Subspace
from workbench.settings.bases import ALTERNATIVE_BASES
from workbench.settings.schema import BasisSchema
from workbench.study.results import Timings


def fit_bases(capture: Capture, basis: BasisSchema, timings: Timings) -> tuple[Eigenfaces, dict]:
    """Eigenfaces (eq. 2) of the training frames and the quasi-eigen faces (eq. 3-4) of each projection.

    Returns
    -------
    eigenfaces : Eigenfaces
    quasi_eigen : dict
        Projection name -> :class:`workbench.numerics.bases.QuasiEigenBasis`.
    """
    # the paper's m = n variant (basis.paper_regime) takes its eigenfaces from this fit: keep n of them converged
    reusable = len(capture.hand_names) if basis.paper_regime is True and basis.n_components is None else None
    with timings.stage("pca"):
        eigenfaces = fit_eigenfaces(capture, basis.coverage, basis.n_components, n_reusable=reusable)
    with timings.stage("quasi_eigen"):
        quasi_eigen = {
            projection: build_quasi_eigen_basis(
                capture.hand,
                capture.hand_names,
                eigenfaces,
                projection=projection,
                empty_axis_eps=basis.empty_axis_eps,
                empty_axis_scale=basis.empty_axis_scale,
                append_empty_axes=basis.append_empty_axes,
            )
            for projection in basis.projections
        }
    return eigenfaces, quasi_eigen


def fit_eigenfaces(
    capture: Capture, coverage: float, n_components: int | None = None, *, n_reusable: int | None = None
) -> Eigenfaces:
    """Eigenfaces (eq. 2) of a capture's training frames, m by the coverage rule or fixed (``n_reusable``: see
    :class:`Eigenfaces`).

    A fixed m on the very training frames of the previous fit (the paper's m = n beside the coverage rule's m,
    ``basis.paper_regime``) reuses that fit's decomposition (:meth:`Eigenfaces.with_n_components`) instead of
    decomposing them again, when it found that many eigenpairs.
    """
    frames = _training_frames(capture)
    if n_components is not None and _LAST_FIT and all(ref() is array for ref, array in zip(_LAST_FIT[0], frames)):
        previous = _LAST_FIT[1]
        if previous._eigenvectors.shape[0] >= n_components:
            return previous.with_n_components(n_components)
    eigenfaces = Eigenfaces(coverage=coverage, n_components=n_components, n_reusable=n_reusable)
    if capture.train_source is not None:  # frames interpolated from markers: PCA in marker space, lifted
        eigenfaces.fit_mapped(capture.train_source, capture.train_operator)
    else:
        eigenfaces.fit(capture.train)
    _LAST_FIT[:] = [tuple(weakref.ref(array) for array in frames), eigenfaces]
    return eigenfaces


_LAST_FIT: list = []
"""Weak references to the training frames of the last :func:`fit_eigenfaces` and its fit, as ``[refs, fit]``: a
reference only says the same array object is still alive, so the study must not change training frames in place
(it never does: a capture is frozen and its arrays are shared, never written, once built)."""


def _training_frames(capture: Capture) -> tuple:
    """The arrays the eigenfaces of a capture are fitted on: the marker frames and their map, or the frames."""
    if capture.train_source is not None:
        return (capture.train_source, capture.train_operator)
    return (capture.train,)


def pca_subspace(eigenfaces: Eigenfaces, transfer: PointTransfer | None = None) -> Subspace:
    """PCA's reconstruction at the evaluated points as an affine subspace: the (carried) mean plus the span of the
    (carried) eigenfaces, whose orthogonal projection is the reconstruction.

    Returns
    -------
    Subspace
        Orthonormal columns of shape (n_dims, m) and the mean as offset.
    """
    if transfer is None or transfer.operator is None:
        return Subspace(eigenfaces.components_.T, eigenfaces.mean_)
    # carried eigenfaces are no longer orthonormal: an orthonormal basis of their span
    orthonormal, _ = np.linalg.qr(transfer.apply(eigenfaces.components_).T)
    return Subspace(orthonormal, transfer.apply_one(eigenfaces.mean_))


def fit_alternative_bases(capture: Capture, basis: BasisSchema, timings: Timings) -> dict:
    """Fit the bases ``basis.alternatives`` names on the training frames (their table:
    :data:`workbench.settings.bases.ALTERNATIVE_BASES`; their fits: :data:`workbench.numerics.alternatives.FITS`).

    Returns
    -------
    dict
        Label (``SPCA``, ``ICA``, ``NMF``, ``SPLOCS``, ``H-fit``) -> ndarray of shape (n, n_dims), in the
        configured order; ``n`` is ``basis.alternatives_n`` or the hand basis size (always the latter for a basis
        that is not sized, H-fit).
    """
    from workbench.numerics.alternatives import FITS

    names = [basis.alternatives] if isinstance(basis.alternatives, str) else list(basis.alternatives or ())
    n = basis.alternatives_n or capture.hand.shape[0]
    bases = {}
    for name in names:
        key = ALTERNATIVE_BASES[name].options_key
        with timings.stage(f"fit_{key}"):
            bases[name] = FITS[name](capture, n, basis.alternatives_seed, asdict(getattr(basis, key)))
    return bases
