"""Fitting the bases of a run: eigenfaces (eq. 2) with their coverage rule, quasi-eigen faces (eq. 3-4) and the
alternative bases (``basis.alternatives``)."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from workbench.dataset.capture import Capture
from workbench.dataset.transfer import PointTransfer
from workbench.numerics.bases import Eigenfaces, build_quasi_eigen_basis
from workbench.numerics.reduced import Subspace
from workbench.settings.bases import ALTERNATIVE_BASES
from workbench.settings.schema import BasisSchema
from workbench.study.results import Timings


def fit_bases(
    capture: Capture, basis: BasisSchema, timings: Timings, previous: Eigenfaces | None = None
) -> tuple[Eigenfaces, dict]:
    """Eigenfaces (eq. 2) of the training frames and the quasi-eigen faces (eq. 3-4) of each projection.

    Parameters
    ----------
    capture : Capture
    basis : BasisSchema
    timings : Timings
    previous : Eigenfaces, optional
        A fit of the very same training frames, whose decomposition a fixed m reuses (:func:`fit_eigenfaces`).

    Returns
    -------
    eigenfaces : Eigenfaces
    quasi_eigen : dict
        Projection name -> :class:`workbench.numerics.bases.QuasiEigenBasis`.
    """
    # the paper's m = n variant (basis.paper_regime) takes its eigenfaces from this fit: keep n of them converged
    reusable = len(capture.hand_names) if basis.paper_regime is True and basis.n_components is None else None
    with timings.stage("pca"):
        eigenfaces = fit_eigenfaces(capture, basis.coverage, basis.n_components, n_reusable=reusable, previous=previous)
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
    capture: Capture,
    coverage: float,
    n_components: int | None = None,
    *,
    n_reusable: int | None = None,
    previous: Eigenfaces | None = None,
) -> Eigenfaces:
    """Eigenfaces (eq. 2) of a capture's training frames, m by the coverage rule or fixed (``n_reusable``: see
    :class:`Eigenfaces`).

    A fixed m given ``previous``, a fit of the very same training frames (the coverage rule's fit beside the paper's
    m = n, ``basis.paper_regime``), reuses that fit's decomposition (:meth:`Eigenfaces.with_n_components`) instead
    of decomposing them again, when it found that many eigenpairs. The frames are not compared: the caller hands
    on only a fit of these frames.
    """
    if n_components is not None and previous is not None and previous._eigenvectors.shape[0] >= n_components:
        return previous.with_n_components(n_components)
    eigenfaces = Eigenfaces(coverage=coverage, n_components=n_components, n_reusable=n_reusable)
    if capture.train_source is not None:  # frames interpolated from markers: PCA in marker space, lifted
        eigenfaces.fit_mapped(capture.train_source, capture.train_operator)
    else:
        eigenfaces.fit(capture.train)
    return eigenfaces


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
