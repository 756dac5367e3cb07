"""The randomised PCA path: a block Krylov space of the covariance grown a pass over the frames at a time (the
capture streamed a chunk of frames at a time), its convergence test, the products with a capture it streams, and the
cost model by which ``Eigenfaces(svd_solver="auto")`` chooses between it and the exact decomposition.

Frames are rows: a capture is an array of shape ``(n_frames, n_dims)``, in memory or on disk (``FramesOnDisk``).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from workbench.numerics.frames import LARGE_FRAMES, check_finite_chunk, frame_chunks


def flip_signs(components: np.ndarray) -> np.ndarray:
    """Make eigenvector signs deterministic: the largest-magnitude entry of each row is positive.

    Parameters
    ----------
    components : ndarray of shape (m, n_dims)

    Returns
    -------
    ndarray of shape (m, n_dims)
        The same rows, some multiplied by -1 (scikit-learn's ``svd_flip`` convention).
    """
    pivots = np.argmax(np.abs(components), axis=1)
    signs = np.sign(components[np.arange(components.shape[0]), pivots])
    signs[signs == 0] = 1.0
    return components * signs[:, None]


def solver_costs(n_frames: int, n_dims: int, n_eigen: int, n_blocks: int = 4, oversample: int = 8):
    """Multiply-adds of the two PCA paths on a capture of this shape, the model ``svd_solver="auto"`` decides by.

    Exact: the covariance or frame Gram product, ``min^2 max``, and its symmetric eigen-decomposition,
    ``EIGH_COST * min^3`` (``min``, ``max`` of ``n_frames``, ``n_dims``). Randomised: ``2 n_blocks`` products of
    the capture with ``n_eigen + oversample`` columns (the passes a capture with a fast-decaying spectrum takes,
    the mean and total variance among them), each multiply-add weighed ``SKINNY_COST``.

    Returns
    -------
    exact, randomized : float
    """
    small, large = min(n_frames, n_dims), max(n_frames, n_dims)
    width = min(n_eigen + oversample, small)
    exact = float(small) ** 2 * large + EIGH_COST * float(small) ** 3
    randomized = SKINNY_COST * 2.0 * n_blocks * float(n_frames) * n_dims * width
    return exact, randomized


EIGH_COST = 4.0
"""Multiply-adds of a dense symmetric eigen-decomposition with eigenvectors, over ``n^3`` (LAPACK's divide and
conquer: reduction to tridiagonal form and back-transformation; calibrated by ``benchmarks/run.py pca_switch``)."""

SKINNY_COST = 4.3
"""Weight of a multiply-add of the randomised path against one of the exact path's Gram product: products with a few
dozen columns on chunks of frames, the orthonormalisations and the Rayleigh-Ritz steps run at a far lower rate than
one square product. Calibrated by ``benchmarks/run.py pca_switch`` on the ICT mesh (28,227 columns): the model switches
at 969 frames; from 700 to 1,250 frames the path it took was at most 16 % slower than the other (one run; each path's
time moves by about that from run to run, and the randomised one with the frames' spectrum). 4.8 switched at 1,068
frames, and at 1,000-1,050 frames the exact path it took was 1.3-1.9 times the randomised one's time."""


def auto_solver(n_frames: int, n_dims: int, n_components: int | None, floor: int) -> str:
    """``"exact"`` or ``"randomized"``: what ``svd_solver="auto"`` runs on a capture of this shape. Randomised when
    both dimensions exceed ``floor`` and :func:`solver_costs` puts it below the exact path; ``n_eigen`` as the
    randomised solver starts (``n_components``, else :data:`FIRST_EIGEN`)."""
    if min(n_frames, n_dims) <= floor:
        return "exact"
    exact, randomized = solver_costs(n_frames, n_dims, n_components or FIRST_EIGEN)
    return "randomized" if randomized < exact else "exact"


FIRST_EIGEN = 24
"""Eigenpairs the randomised solver first computes for the coverage rule (doubled until the coverage is reached)."""


RESIDUAL_RTOL = 1e-10
"""Convergence test of the randomised solver: it stops once every eigenpair it must deliver has a Ritz residual
``|C v - theta v|`` at most this times the largest Ritz value. The angle between a delivered subspace and the exact
one is at most that residual over the eigenvalue gap (Davis-Kahan), so 1e-10 keeps the eigenfaces of well-separated
axes to about 1e-9 of their norm and the eigenvalues (errors quadratic in the residual) to round-off; a capture whose
spectrum decays too slowly for it runs all :data:`MAX_BLOCKS`."""

MAX_BLOCKS = 8
"""At most this many blocks of the Krylov space, each one product ``D~^T D~ Q`` (one pass over the frames)."""

OVERSAMPLE = 8
"""Columns of a block beyond the eigenpairs wanted."""

CANCELLATION = 1e4
"""The first pass multiplies by the uncentred ``D^T D`` and subtracts ``n mu mu^T``; its product enters the Krylov
space only while ``|mu|^2`` is at most this times the total variance (a relative error of about ``eps |mu|^2 /
lambda``); a capture further from the origin starts the space from that product instead, one pass later."""

CHUNK_BYTES = 1 << 24
"""Bytes of float64 frames per chunk of a product pass (16 MB) on a capture below
:data:`~workbench.numerics.frames.LARGE_FRAMES` values."""

LARGE_CHUNK_BYTES = 1 << 26
"""Bytes of float64 frames per chunk of a product pass on a capture of at least
:data:`~workbench.numerics.frames.LARGE_FRAMES` values (64 MB, about 300 frames of a 9,409-vertex mesh). The second
product of a chunk, ``A^T D`` with ``A = D Q``, adds into a block as wide as a frame, read and written once per
chunk: at mesh scale (35,000 frames x 28,227) a pass with 16 MB chunks took 12-18 % longer; 128 MB was no faster,
256 MB slower."""


def randomized_covariance_eigen(
    capture: np.ndarray,
    n_eigen: int,
    rng: np.random.Generator,
    *,
    max_blocks: int = MAX_BLOCKS,
    oversample: int = OVERSAMPLE,
    n_checked=None,
    name: str = "capture",
) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, int]:
    """Mean, total variance and leading eigenpairs of the covariance by randomised block Krylov iteration (block
    Lanczos with full reorthogonalisation: Musco & Musco 2015; Halko, Martinsson & Tropp 2011).

    The Krylov space ``[Q, C Q, C^2 Q, ...]`` of ``C = D~^T D~`` (``D~`` the centred capture, never formed) grows a
    block per pass over the frames: each pass multiplies one orthonormal block by ``C`` (both products on a chunk
    of frames while it is in cache). The Ritz pairs of ``C`` on the space come from the products already made
    (``V^T C V`` with ``C V`` kept), so the test of convergence and the eigenpairs cost no further pass; the space
    converges far faster than subspace iteration for the same passes (it keeps every block, not the last). The
    first pass also sums the frames and their squares: the mean, the total variance and the check for NaN or Inf
    cost no pass of their own.

    Parameters
    ----------
    capture : ndarray of shape (n_frames, n_dims) or FramesOnDisk
        The capture, not centred; float32 and on-disk captures are read a chunk of frames at a time as float64.
    n_eigen : int
        Number of eigenpairs wanted.
    rng : numpy.random.Generator
        Draws the random first block.
    max_blocks : int
        At most this many passes that grow the space.
    oversample : int
        Columns of a block beyond ``n_eigen``.
    n_checked : int or callable, optional
        How many leading pairs the convergence test checks (default ``n_eigen``); a callable is given the current
        Ritz eigenvalues as shares of the total variance, descending, and returns it (the coverage rule's m on that
        estimate).
    name : str
        The capture as a refusal names it.

    Returns
    -------
    mean : ndarray of shape (n_dims,)
    total : float
        ``sum |y - mean|^2 / n_frames``.
    eigenvalues : ndarray of shape (n_eigen,)
        Descending (zeros past the capture's rank).
    eigenvectors : ndarray of shape (n_eigen, n_dims)
        Unit eigenfaces as rows, with deterministic signs.
    n_passes : int
        Products with the whole capture it made (each pass by ``D~^T D~`` counts two).

    Raises
    ------
    WorkbenchError
        NaN or Inf in the capture, naming ``name`` and the frames.
    """
    n_frames, n_dims = capture.shape
    width = min(n_eigen + oversample, n_frames, n_dims)
    start = _orthonormal(rng.standard_normal((n_dims, width)))
    mean, total, uncentred = statistics_and_normal_times(capture, start, name)
    normal = uncentred - n_frames * np.outer(mean, mean @ start)
    basis, normals = ([start], [normal]) if mean @ mean <= CANCELLATION * total else ([], [])
    n_passes, grow, checked = 2, normal, n_checked or n_eigen
    while True:
        if basis:
            theta, rotation = _rayleigh_ritz(basis, normals)
            if len(basis) >= max_blocks or _ritz_converged(theta, rotation, basis, normals, checked, n_frames * total):
                break
        block = _orthonormal_against(grow, basis)
        if block.shape[1] == 0:  # the space already holds every direction the capture varies in
            break
        grow = frames_normal_times(capture, block, mean)
        basis.append(block)
        normals.append(grow)
        n_passes += 2
    if not basis:
        return mean, total, np.zeros(n_eigen), np.zeros((n_eigen, n_dims)), n_passes
    count = min(n_eigen, theta.size)
    vectors = (np.hstack(basis) @ rotation[:, :count]).T
    values = np.maximum(theta[:count], 0.0) / n_frames
    values = np.concatenate([values, np.zeros(n_eigen - count)])
    vectors = np.vstack([flip_signs(vectors), np.zeros((n_eigen - count, n_dims))])
    return mean, total, values, vectors, n_passes


def _rayleigh_ritz(basis: list, normals: list) -> tuple[np.ndarray, np.ndarray]:
    """Ritz values (descending) and their coordinates on the orthonormal ``basis`` (blocks of shape (n_dims, k)),
    given ``normals``, the blocks times ``D~^T D~``."""
    projected = np.hstack(basis).T @ np.hstack(normals)
    theta, rotation = np.linalg.eigh((projected + projected.T) / 2.0)
    return theta[::-1], rotation[:, ::-1]


def _ritz_converged(theta, rotation, basis: list, normals: list, n_checked, trace: float) -> bool:
    """Whether the leading ``n_checked`` Ritz pairs (``theta``, ``rotation``: :func:`_rayleigh_ritz` of ``basis``,
    orthonormal blocks of shape (n_dims, k), with ``normals`` = ``C`` times each) have residuals
    ``|C V y - theta V y|`` within :data:`RESIDUAL_RTOL` of the largest Ritz value (``n_checked``: an int, or a
    function of the Ritz values as shares of ``trace``, the trace of ``C``)."""
    if theta[0] <= 0 or trace <= 0:
        return True
    count = n_checked(np.maximum(theta, 0.0) / trace) if callable(n_checked) else n_checked
    count = max(1, min(int(count), theta.size))
    leading = rotation[:, :count]
    residual = np.hstack(normals) @ leading - (np.hstack(basis) @ leading) * theta[:count]
    return bool(np.linalg.norm(residual, axis=0).max() <= RESIDUAL_RTOL * theta[0])


def _orthonormal_against(block: np.ndarray, basis: list) -> np.ndarray:
    """An orthonormal basis, shape (n_dims, j) with ``j <= k``, of what ``block`` (shape (n_dims, k)) adds to the
    span of ``basis``: its part in that span removed twice, the directions left below :data:`NEW_DIRECTION` of the
    block's largest column dropped (the space is exhausted there), and the span removed once more from the rest,
    whose normalisation magnifies what round-off left of it."""
    scale = float(np.linalg.norm(block, axis=0).max()) if block.size else 0.0
    spanned = np.hstack(basis) if basis else None
    for _ in range(2 if basis else 0):
        block = block - spanned @ (spanned.T @ block)
    orthonormal, triangle = scipy.linalg.qr(block, mode="economic", check_finite=False)
    rotation, sizes, _ = np.linalg.svd(triangle)  # the SVD of the block, from that of its small triangle
    directions = orthonormal @ rotation[:, sizes > NEW_DIRECTION * scale] if scale > 0 else block[:, :0]
    if basis and directions.shape[1]:
        directions = _orthonormal(directions - spanned @ (spanned.T @ directions))
    return directions


NEW_DIRECTION = 1e-9
"""A block's direction is new to the Krylov space when its part outside the space is at least this share of the
block's largest column (below it the part is round-off of the space's own directions)."""


def _orthonormal(matrix: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the columns' span (thin QR), shape of ``matrix``."""
    return scipy.linalg.qr(matrix, mode="economic", check_finite=False)[0]


def product_chunks(capture):
    """The frames in chunks of :data:`CHUNK_BYTES` (:data:`LARGE_CHUNK_BYTES` on a capture of at least
    :data:`~workbench.numerics.frames.LARGE_FRAMES` values) as float64, for a pass that multiplies each chunk
    twice."""
    n_frames, n_dims = capture.shape
    size = LARGE_CHUNK_BYTES if n_frames * n_dims >= LARGE_FRAMES else CHUNK_BYTES
    return frame_chunks(capture, max(1, size // (8 * n_dims)))


def statistics_and_normal_times(capture, matrix: np.ndarray, name: str = "capture"):
    """Mean frame, total variance and ``D^T (D matrix)`` of the uncentred capture ``D``, in one pass.

    Returns
    -------
    mean : ndarray of shape (n_dims,)
    total : float
        ``sum |y - mean|^2 / n_frames`` (the squares less ``n |mean|^2``).
    normal : ndarray of shape (n_dims, k)

    Raises
    ------
    WorkbenchError
        NaN or Inf in the capture (found by the sums, then located), naming ``name``.
    """
    sums, squares = np.zeros(capture.shape[1]), 0.0
    normal_t = np.zeros((matrix.shape[1], capture.shape[1]))
    for _, chunk in product_chunks(capture):
        sums += np.ones(chunk.shape[0]) @ chunk
        squares += float(np.vdot(chunk, chunk))
        normal_t += (chunk @ matrix).T @ chunk  # as (A^T D)^T: the faster product for a wide, short chunk
    if not (np.isfinite(squares) and np.isfinite(sums).all()):  # located, unless finite frames overflowed the sums
        for rows, chunk in frame_chunks(capture):
            check_finite_chunk(name, rows, chunk)
    mean = sums / capture.shape[0]
    return mean, max(squares / capture.shape[0] - float(mean @ mean), 0.0), np.ascontiguousarray(normal_t.T)


def frames_normal_times(capture, matrix: np.ndarray, mean: np.ndarray) -> np.ndarray:
    """``D~^T (D~ matrix)`` with ``D~ = capture - 1 mean^T``, shape (n_dims, k), in one pass over the frames.

    ``D~^T A = D^T A - mean (1^T A)`` for ``A = D matrix - 1 (mean^T matrix)``, so each chunk of frames is read
    once for both products (float64 arithmetic; a float32 or stored chunk is converted in cache).
    """
    shift = mean @ matrix
    out_t, column_sums = np.zeros((matrix.shape[1], capture.shape[1])), np.zeros(matrix.shape[1])
    for _, chunk in product_chunks(capture):
        product = chunk @ matrix - shift
        out_t += product.T @ chunk  # as (A^T D)^T: the faster product for a wide, short chunk
        column_sums += product.sum(axis=0)
    return np.ascontiguousarray(out_t.T) - np.outer(mean, column_sums)
