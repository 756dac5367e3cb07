"""The randomised PCA path: subspace iteration on the covariance with the capture streamed a chunk of frames at a
time, its convergence test, the products with a capture it streams, and the cost model by which
``Eigenfaces(svd_solver="auto")`` chooses between it and the exact decomposition.

Frames are rows: a capture is an array of shape ``(n_frames, n_dims)``, in memory or on disk (``FramesOnDisk``).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from workbench.numerics.frames import frame_chunks, is_stored_frames


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


def centred_statistics(capture: np.ndarray, chunk_size: int = 8) -> tuple[np.ndarray, float]:
    """Mean frame, shape (n_dims,), and total variance ``sum |y - mean|^2 / n_frames`` of a capture in memory, in one
    pass over chunks small enough to stay in cache while both sums read them (as ``frames_statistics`` sums a
    stored capture: the squares less ``n |mean|^2``, which loses ``eps |mean|^2 / variance`` relative digits).

    The centred chunk is never formed: subtracting the mean is a pass of its own (it cost twice the sums)."""
    sums, squares, ones = np.zeros(capture.shape[1]), 0.0, np.ones(chunk_size)
    for _, chunk in frame_chunks(capture, chunk_size):
        sums += ones[: chunk.shape[0]] @ chunk
        squares += float(np.einsum("ij,ij->i", chunk, chunk).sum())
    mean = sums / capture.shape[0]
    return mean, max(squares / capture.shape[0] - float(mean @ mean), 0.0)


def solver_costs(n_frames: int, n_dims: int, n_eigen: int, n_power_iter: int = 6, oversample: int = 20):
    """Multiply-adds of the two PCA paths on a capture of this shape, the model ``svd_solver="auto"`` decides by.

    Exact: the covariance or frame Gram product, ``min^2 max``, and its symmetric eigen-decomposition,
    ``EIGH_COST * min^3`` (``min``, ``max`` of ``n_frames``, ``n_dims``). Randomised: ``2 + 2 n_power_iter``
    products of the capture with ``n_eigen + oversample`` columns (its most, when the iteration does not stop
    early), plus one pass for the mean and the total variance, weighed as one such product, each multiply-add
    weighed ``SKINNY_COST``.

    Returns
    -------
    exact, randomized : float
    """
    small, large = min(n_frames, n_dims), max(n_frames, n_dims)
    width = min(n_eigen + oversample, small)
    exact = float(small) ** 2 * large + EIGH_COST * float(small) ** 3
    randomized = SKINNY_COST * (3.0 + 2.0 * n_power_iter) * float(n_frames) * n_dims * width
    return exact, randomized


EIGH_COST = 4.0
"""Multiply-adds of a dense symmetric eigen-decomposition with eigenvectors, over ``n^3`` (LAPACK's divide and
conquer: reduction to tridiagonal form and back-transformation; calibrated by ``benchmarks/run.py pca_switch``)."""

SKINNY_COST = 1.25
"""Weight of a multiply-add of the randomised path against one of the exact path's Gram product: products with a few
dozen columns, their orthonormalisations and the mean corrections run at a lower rate than one square product
(``benchmarks/run.py pca_switch``: the two paths cross between 800 and 1,100 ICT mesh frames, where their times
vary by 30 % from run to run on a shared machine)."""


def auto_solver(n_frames: int, n_dims: int, n_components: int | None, floor: int) -> str:
    """``"exact"`` or ``"randomized"``: what ``svd_solver="auto"`` runs on a capture of this shape. Randomised when
    both dimensions exceed ``floor`` and :func:`solver_costs` puts it below the exact path; ``n_eigen`` as the
    randomised solver starts (``n_components``, else :data:`FIRST_EIGEN`)."""
    if min(n_frames, n_dims) <= floor:
        return "exact"
    exact, randomized = solver_costs(n_frames, n_dims, n_components or FIRST_EIGEN)
    return "randomized" if randomized < exact else "exact"


FIRST_EIGEN = 32
"""Eigenpairs the randomised solver first computes for the coverage rule (doubled until the coverage is reached)."""


RESIDUAL_RTOL = 1e-10
"""Convergence test of the randomised solver's subspace iteration: it stops once every eigenpair it must deliver has
a Ritz residual ``|C v - theta v|`` at most this times the largest Ritz value. The angle between a delivered
subspace and the exact one is at most that residual over the eigenvalue gap (Davis-Kahan), so 1e-10 keeps the
eigenfaces of well-separated axes to about 1e-9 of their norm and the eigenvalues (errors quadratic in the
residual) to round-off; a capture whose spectrum decays too slowly for it runs the full ``n_power_iter``."""


def randomized_covariance_eigen(
    capture: np.ndarray,
    mean: np.ndarray,
    n_eigen: int,
    rng: np.random.Generator,
    *,
    n_power_iter: int = 6,
    oversample: int = 20,
    iteration_dtype=np.float64,
    n_checked=None,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Leading eigenpairs of the covariance by randomised subspace iteration (Halko, Martinsson & Tropp 2011).

    The centred capture is never formed: products with ``D~ = D - 1 mu^T`` are corrected by the mean, so memory
    stays at the capture plus ``(n_frames + n_dims) x (n_eigen + oversample)``. Each subspace iteration multiplies
    by ``D~^T D~`` in one pass over the frames (:func:`frames_normal_times`), which also yields ``D~ B``; the
    eigenpairs come from that last pass, ``D~^T`` times an orthonormal basis of ``D~ B`` (a randomised SVD of
    ``D~`` with the range ``D~ B``), without a further pass. Float64 iterations stop early once the Ritz pairs of
    the current basis pass :data:`RESIDUAL_RTOL` (a test that costs no pass: it uses the same two products).

    Parameters
    ----------
    capture : ndarray of shape (n_frames, n_dims) or FramesOnDisk
        The capture, not centred; float32 and on-disk captures are read a chunk of frames at a time
        (:func:`frames_times`).
    mean : ndarray of shape (n_dims,)
    n_eigen : int
        Number of eigenpairs wanted.
    rng : numpy.random.Generator
        Draws the random test matrix.
    n_power_iter : int
        At most this many passes by ``D~^T D~``; each sharpens the decay by a power of the eigenvalue ratios.
    oversample : int
        Extra test vectors beyond ``n_eigen``.
    iteration_dtype : numpy dtype
        Arithmetic of every product but the last pass (which fixes the result's accuracy and is always float64):
        float32 for a float32 capture halves their cost (and runs every iteration: its residuals cannot pass the
        float64 test); an error there only perturbs the subspace the later iterations refine.
    n_checked : int or callable, optional
        How many leading pairs the convergence test checks (default ``n_eigen``); a callable is given the current
        Ritz eigenvalues of the covariance, descending, and returns it (the coverage rule's m on that estimate).
    Returns
    -------
    eigenvalues : ndarray of shape (n_eigen,)
        Descending.
    eigenvectors : ndarray of shape (n_eigen, n_dims)
        Unit eigenfaces as rows, with deterministic signs.
    n_passes : int
        Products with the whole capture it made (a ``D~^T D~`` pass counts two).
    """
    n_frames, n_dims = capture.shape
    width = min(n_eigen + oversample, n_frames, n_dims)

    def times(matrix, dtype=np.float64):  # D~ @ matrix, (n_frames, width)
        return frames_times(capture, matrix, dtype) - (mean @ matrix)[None, :]

    def transposed_times(matrix, dtype=np.float64):  # D~^T @ matrix, (n_dims, width)
        return frames_transposed_times(capture, matrix, dtype) - np.outer(mean, matrix.sum(axis=0))

    sketch = times(rng.standard_normal((n_dims, width)), iteration_dtype)
    basis = _orthonormal(transposed_times(_orthonormal(sketch), iteration_dtype))
    n_passes = 2
    for iteration in range(max(1, n_power_iter)):
        last = iteration == max(1, n_power_iter) - 1
        dtype = np.float64 if last else iteration_dtype
        product, normal = frames_normal_times(capture, basis, mean, dtype, with_product=True)
        n_passes += 2
        if last or (dtype == np.float64 and _ritz_converged(basis, normal, n_checked or n_eigen, n_frames)):
            break
        basis = _orthonormal(normal)
    values, vectors = _eigen_from_range(product, normal, n_eigen)
    return values / n_frames, vectors, n_passes


def _ritz_converged(basis: np.ndarray, normal: np.ndarray, n_checked, n_frames: int) -> bool:
    """Whether the leading ``n_checked`` Ritz pairs of ``D~^T D~`` on the span of ``basis`` (orthonormal, shape
    (n_dims, width)), given ``normal = D~^T D~ basis``, have residuals within :data:`RESIDUAL_RTOL` of the largest
    Ritz value (``n_checked``: an int, or a function of the Ritz eigenvalues of the covariance)."""
    theta, rotation = np.linalg.eigh(basis.T @ normal)
    theta, rotation = theta[::-1], rotation[:, ::-1]
    if theta[0] <= 0:
        return True
    count = n_checked(np.maximum(theta, 0.0) / n_frames) if callable(n_checked) else n_checked
    count = max(1, min(int(count), theta.size))
    residual = normal @ rotation[:, :count] - (basis @ rotation[:, :count]) * theta[:count]
    return bool(np.linalg.norm(residual, axis=0).max() <= RESIDUAL_RTOL * theta[0])


def _eigen_from_range(product: np.ndarray, normal: np.ndarray, n_eigen: int) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs of ``D~^T P D~`` (``P`` the projection on the span of ``product = D~ B``), from ``product`` and
    ``normal = D~^T product``: with the SVD ``product = U s V^T``, ``D~^T U = normal V / s``, whose SVD gives the
    eigenvalues (squared singular values, times ``n_frames``) and eigenfaces. Directions of ``product`` below
    ``1e-6`` of its largest singular value (rank-deficient captures) are left out: their eigenvalues are under
    ``1e-12`` of the largest (``TOL.eigen_rel``'s zero), and dividing by their singular values would amplify the
    round-off of ``normal`` (about ``eps s_1^2``) past ``1e-10`` of the largest."""
    _, singular, right_t = np.linalg.svd(product, full_matrices=False)
    kept = singular > 1e-6 * singular[0] if singular[0] > 0 else np.zeros(singular.shape, bool)
    lifted = (normal @ right_t[kept].T) / singular[kept]
    _, values, vt = np.linalg.svd(lifted.T, full_matrices=False)
    values = np.concatenate([values, np.zeros(max(0, n_eigen - values.size))])[:n_eigen]
    vt = np.vstack([vt, np.zeros((max(0, n_eigen - vt.shape[0]), vt.shape[1]))])[:n_eigen]
    return values**2, flip_signs(vt)


def _orthonormal(matrix: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the columns' span (thin QR), shape of ``matrix``."""
    return scipy.linalg.qr(matrix, mode="economic", check_finite=False)[0]


def frames_times(capture, matrix: np.ndarray, dtype=np.float64) -> np.ndarray:
    """``capture @ matrix``, shape (n_frames, k): at once for a float64 array in float64, else one chunk of frames
    at a time in ``dtype`` (:func:`workbench.numerics.frames.frame_chunks`)."""
    if not is_stored_frames(capture) and dtype == np.float64:
        return capture @ matrix
    out = np.empty((capture.shape[0], matrix.shape[1]))
    factor = matrix.astype(dtype)
    for rows, chunk in frame_chunks(capture, dtype=dtype):
        out[rows] = chunk @ factor
    return out


def frames_transposed_times(capture, matrix: np.ndarray, dtype=np.float64) -> np.ndarray:
    """``capture.T @ matrix``, shape (n_dims, k), as :func:`frames_times` (a float64 sum over chunks)."""
    if not is_stored_frames(capture) and dtype == np.float64:
        return capture.T @ matrix
    out = np.zeros((capture.shape[1], matrix.shape[1]))
    factor = matrix.astype(dtype)
    for rows, chunk in frame_chunks(capture, dtype=dtype):
        out += chunk.T @ factor[rows]
    return out


def frames_normal_times(capture, matrix: np.ndarray, mean: np.ndarray, dtype=np.float64, *, with_product=False):
    """``D~^T (D~ matrix)`` with ``D~ = capture - 1 mean^T``, shape (n_dims, k), in one pass over the frames.

    ``D~^T A = D^T A - mean (1^T A)`` for ``A = D matrix - 1 (mean^T matrix)``, so each chunk of frames is read
    once for both products (in ``dtype``; sums over chunks in float64). With ``with_product``, also ``A``, shape
    (n_frames, k), first.
    """
    shift = mean @ matrix
    if not is_stored_frames(capture) and dtype == np.float64:
        product = capture @ matrix - shift
        normal = capture.T @ product - np.outer(mean, product.sum(axis=0))
        return (product, normal) if with_product else normal
    out, column_sums = np.zeros((capture.shape[1], matrix.shape[1])), np.zeros(matrix.shape[1])
    products = np.empty((capture.shape[0], matrix.shape[1])) if with_product else None
    factor, shift = matrix.astype(dtype), shift.astype(dtype)
    for rows, chunk in frame_chunks(capture, dtype=dtype):
        product = chunk @ factor - shift
        out += chunk.T @ product
        column_sums += product.sum(axis=0, dtype=np.float64)
        if with_product:
            products[rows] = product
    normal = out - np.outer(mean, column_sums)
    return (products, normal) if with_product else normal
