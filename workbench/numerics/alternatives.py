"""Other interpretable bases of the same size as the hand basis, to set beside the quasi-eigen faces.

Each is fitted on the training displacements (frames as rows, displacements from the neutral face) and returns
``n_components`` shapes as rows, so it is scored exactly like ``H`` and ``QE`` (eq. 5 weights, eq. 6 alpha):

- ``SPCA``: sparse PCA (the objective of scikit-learn's :class:`~sklearn.decomposition.SparsePCA`, solved for
  every coordinate at once), :func:`sparse_pca_basis`;
- ``ICA``: independent components (scikit-learn's :class:`~sklearn.decomposition.FastICA`), :func:`ica_basis`;
- ``NMF``: non-negative matrix factorisation of the positive and negative parts (scikit-learn's
  :class:`~sklearn.decomposition.NMF`), :func:`nmf_basis`;
- ``SPLOCS``: sparse localised deformation components (Neumann et al. 2013), :func:`splocs_basis`;
- ``H-fit``: the hand basis refitted to the capture by alternating least squares, :func:`fitted_hand_basis`.

Every method works about the neutral face, not the capture mean: a blendshape frame is ``v0 + sum_i w_i e_i``
with no mean term, and these bases are scored that way, so a basis fitted to centred data would spend one of its
``n`` shapes on the mean. Pure numerical code: arrays in, arrays out. ICA's start and NMF's (a randomised SVD) are
drawn from the ``seed`` passed in; the others are deterministic.
"""

from __future__ import annotations

import warnings
from contextlib import contextmanager

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from workbench.core.errors import WorkbenchError


@contextmanager
def _quiet():
    """Silence scikit-learn's convergence warnings: the iteration limits are settings of the run, recorded in
    its config."""
    from sklearn.exceptions import ConvergenceWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        yield


def _check_train(train, n_components: int) -> np.ndarray:
    train = np.asarray(train, dtype=np.float64)
    if train.ndim != 2 or train.size == 0 or not np.all(np.isfinite(train)):
        raise WorkbenchError(f"training frames must be a finite, non-empty 2-D array, got shape {train.shape}")
    if isinstance(n_components, bool) or not 1 <= int(n_components) <= min(train.shape):
        raise WorkbenchError(
            f"basis.alternatives_n: n_components must be between 1 and min(n_frames, n_dims) = "
            f"{min(train.shape)}, got {n_components} (null: the hand basis's size)"
        )
    return train


def leading_svd(frames: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ``n`` leading singular triplets of a matrix from the eigen-decomposition of its smaller Gram matrix
    (a mesh capture is far wider than tall: 1,008 frames of 28,227 coordinates take tens of seconds by a full SVD,
    a second this way; the leading triplets lose no accuracy that matters here).

    Parameters
    ----------
    frames : ndarray of shape (n_frames, n_dims)
    n : int

    Returns
    -------
    u : ndarray of shape (n_frames, n)
    singular : ndarray of shape (n,)
        Descending.
    vt : ndarray of shape (n, n_dims)
    """
    if frames.shape[0] <= frames.shape[1]:
        values, vectors = np.linalg.eigh(frames @ frames.T)
        u = vectors[:, ::-1][:, :n]
        singular = np.sqrt(np.maximum(values[::-1][:n], 0.0))
        vt = (u.T @ frames) / np.where(singular > 0, singular, 1.0)[:, None]
    else:
        values, vectors = np.linalg.eigh(frames.T @ frames)
        vt = vectors[:, ::-1][:, :n].T
        singular = np.sqrt(np.maximum(values[::-1][:n], 0.0))
        u = (frames @ vt.T) / np.where(singular > 0, singular, 1.0)
    return u, singular, vt


def unit_activation(shapes: np.ndarray, train: np.ndarray) -> np.ndarray:
    """Orient and scale each shape as an animator's: its least-squares weights over the training frames have a
    non-negative mean and a largest value of 1 (a shape is "fully on" at weight 1, as the hand shapes are).

    Sign and scale leave the span, and so unconstrained alpha, unchanged; they matter for the non-negative and
    box ``[0, 1]`` solvers, which would otherwise see PCA-like shapes of arbitrary sign and unit norm.

    Parameters
    ----------
    shapes : ndarray of shape (n_components, n_dims)
    train : ndarray of shape (n_frames, n_dims)

    Returns
    -------
    ndarray of shape (n_components, n_dims)
    """
    weights = np.linalg.lstsq(shapes.T, train.T, rcond=None)[0].T  # (n_frames, n_components)
    signs = np.where(weights.mean(axis=0) < 0, -1.0, 1.0)
    peaks = (weights * signs).max(axis=0)
    scale = np.where(peaks > 0, peaks, 1.0) * signs
    return shapes * scale[:, None]


def sparse_pca_basis(
    train, *, n_components: int, alpha: float = 0.01, max_iter: int = 100, tol: float = 1e-6
) -> np.ndarray:
    """Sparse PCA about the neutral face: shapes with few non-zero coordinates that span most of the capture.

    The objective is scikit-learn's ``SparsePCA`` (sparse dictionary learning on the transposed data),
    ``min 1/2 |R - U V|_F^2 + alpha |V|_1`` over unit-norm columns of ``U`` (frame loadings) and sparse
    rows of ``V`` (the shapes), here without centring. ``R`` is the ``R`` factor of a QR decomposition of the
    training frames, or the frames themselves when they are fewer than their dimensions: it has the same Gram
    matrix ``X^T X``, so the optimal ``V`` is the same and the problem has at most ``n_dims`` rows. The data are
    scaled to a root-mean-square column norm of 1, which makes ``alpha`` a fraction of a typical coordinate's
    norm. It is solved the way scikit-learn does (alternating a Lasso for ``V`` with block-coordinate updates of
    ``U``, started from the leading singular vectors), but with the Lasso of every coordinate solved at once by
    vectorised coordinate descent: scikit-learn's ``SparsePCA`` solves one Lasso per coordinate in a Python loop,
    which had not finished one fit on the ICT mesh (28,227 coordinates) after five minutes.

    Parameters
    ----------
    train : ndarray of shape (n_frames, n_dims)
        Training displacements from neutral.
    n_components : int
    alpha : float
        Sparsity, relative to the RMS column norm of the data.
    max_iter : int
        Alternations of ``V`` and ``U``.
    tol : float
        Stop when the objective decreases by less than this fraction.

    Returns
    -------
    ndarray of shape (n_components, n_dims)
        Scaled by :func:`unit_activation`.
    """
    train = _check_train(train, n_components)
    if not alpha >= 0:
        raise WorkbenchError(f"SPCA alpha must be >= 0, got {alpha}")
    n = int(n_components)
    reduced = np.linalg.qr(train, mode="r") if train.shape[0] > train.shape[1] else train
    reduced = reduced / (np.linalg.norm(reduced) / np.sqrt(reduced.shape[1]))
    total = float(np.sum(reduced**2))
    loadings, _, _ = leading_svd(reduced, n)  # U, (k, n)
    shapes = loadings.T @ reduced  # V, (n, n_dims)
    previous = np.inf
    for _ in range(int(max_iter)):
        shapes = _lasso_rows(loadings.T @ loadings, loadings.T @ reduced, alpha, shapes)
        data_codes, code_gram = reduced @ shapes.T, shapes @ shapes.T
        loadings = _update_loadings(loadings, data_codes, code_gram)
        # |R - U V|^2 from the small products, without forming R - U V
        misfit = total - 2.0 * np.sum(loadings * data_codes) + np.sum((loadings.T @ loadings) * code_gram)
        cost = 0.5 * misfit + alpha * np.abs(shapes).sum()
        if previous - cost <= tol * cost:
            break
        previous = cost
    empty = ~np.any(shapes != 0, axis=1)
    if empty.any():
        raise WorkbenchError(f"SPCA alpha={alpha} leaves {int(empty.sum())} of {n} components empty; lower it")
    return unit_activation(shapes, train)


def _lasso_rows(
    gram: np.ndarray, correlation: np.ndarray, alpha: float, start: np.ndarray, sweeps: int = 20, tol: float = 1e-6
) -> np.ndarray:
    """``min_v 1/2 |r - U v|^2 + alpha |v|_1`` for every column ``r`` of the data at once, by coordinate descent:
    at most ``sweeps`` sweeps from the warm start (each lowers the objective, and the alternation calls again),
    fewer once no coefficient moves by more than ``tol`` times the largest correlation.

    Parameters
    ----------
    gram : ndarray of shape (n, n)
        ``U^T U``.
    correlation : ndarray of shape (n, n_columns)
        ``U^T R``.
    alpha : float
    start : ndarray of shape (n, n_columns)
        Warm start.

    Returns
    -------
    ndarray of shape (n, n_columns)
    """
    codes = start.copy()
    scale = max(float(np.abs(correlation).max()), 1e-300)
    for _ in range(sweeps):
        largest_change = 0.0
        for k in range(len(gram)):
            if gram[k, k] <= 0:
                codes[k] = 0.0
                continue
            target = correlation[k] - gram[k] @ codes + gram[k, k] * codes[k]
            new = np.sign(target) * np.maximum(np.abs(target) - alpha, 0.0) / gram[k, k]
            largest_change = max(largest_change, float(np.abs(new - codes[k]).max()))
            codes[k] = new
        if largest_change <= tol * scale:
            break
    return codes


def _update_loadings(loadings: np.ndarray, data_codes: np.ndarray, code_gram: np.ndarray) -> np.ndarray:
    """One block-coordinate pass over the columns of ``U`` in ``min |R - U V|^2`` with ``|u_k| <= 1``.

    Parameters
    ----------
    loadings : ndarray of shape (k, n)
        ``U``.
    data_codes : ndarray of shape (k, n)
        ``R V^T``.
    code_gram : ndarray of shape (n, n)
        ``V V^T``.
    """
    loadings = loadings.copy()
    for k in range(loadings.shape[1]):
        if code_gram[k, k] <= 0:  # an unused component keeps its loading
            continue
        direction = data_codes[:, k] - loadings @ code_gram[:, k] + code_gram[k, k] * loadings[:, k]
        loadings[:, k] = direction / max(code_gram[k, k], float(np.linalg.norm(direction)))
    return loadings


def ica_basis(train, *, n_components: int, max_iter: int = 200, tol: float = 1e-4, seed: int = 0) -> np.ndarray:
    """Independent components: the best ``n``-dimensional span about the neutral face, rotated so that the
    frames' coordinates in it are as independent (non-Gaussian) as FastICA can make them.

    The frames are whitened about the neutral face, not their mean (``Z = sqrt(L) U_n`` from the leading
    singular triplets of ``X = U S V^T``, so ``Z^T Z / L = I``), and scikit-learn's ``FastICA(whiten=False)``
    (which then neither centres nor whitens) finds the orthogonal rotation ``W`` with sources ``Z W^T``. Then
    ``X_n = (Z W^T) W diag(s_n) V_n^T / sqrt(L)``, so the shapes are the rows
    of ``W diag(s_n) V_n^T / sqrt(L)``: they span the same space as the first ``n`` singular vectors.

    Parameters
    ----------
    train : ndarray of shape (n_frames, n_dims)
    n_components : int
    max_iter, tol : int, float
        scikit-learn's iteration limit and stopping tolerance (its defaults).
    seed : int
        scikit-learn's ``random_state`` (the initial rotation).

    Returns
    -------
    ndarray of shape (n_components, n_dims)
        Scaled by :func:`unit_activation`.
    """
    from sklearn.decomposition import FastICA

    train = _check_train(train, n_components)
    n = int(n_components)
    n_frames = train.shape[0]
    u, singular, vt = leading_svd(train, n)
    if singular[-1] <= 1e-12 * singular[0]:
        raise WorkbenchError(f"ICA needs {n} independent directions, but the training frames have rank < {n}")
    whitened = np.sqrt(n_frames) * u
    model = FastICA(whiten=False, max_iter=max_iter, tol=tol, random_state=seed)
    with _quiet():
        model.fit(whitened)
    rotation = model.components_  # (n, n), orthogonal: sources = whitened @ rotation.T
    shapes = rotation @ (singular[:, None] * vt) / np.sqrt(n_frames)
    return unit_activation(shapes, train)


def nmf_basis(train, *, n_components: int, max_iter: int = 200, tol: float = 1e-4, seed: int = 0) -> np.ndarray:
    """Non-negative matrix factorisation of signed displacements, on their positive and negative parts.

    Displacements are signed, so NMF is applied to ``[max(X, 0), max(-X, 0)]`` (each coordinate split into two
    non-negative ones, shape ``(n_frames, 2 n_dims)``) and a factor ``h = [h+, h-]`` becomes the signed shape
    ``h+ - h-``. Each shape is then a part of the face that moves in its own directions, switched on by a
    non-negative weight, as a muscle is, and the fit cannot explain a motion by shapes that cancel (one moving a
    point up, another down), since the two directions are separate non-negative columns. (NMF of the displacements
    shifted to be non-negative would instead make the shift part of every shape.)

    Parameters
    ----------
    train : ndarray of shape (n_frames, n_dims)
    n_components : int
    max_iter, tol : int, float
        scikit-learn's iteration limit and stopping tolerance.
    seed : int
        scikit-learn's ``random_state``: the randomised SVD behind the ``nndsvda`` start.

    Returns
    -------
    ndarray of shape (n_components, n_dims)
        Scaled by :func:`unit_activation`.
    """
    from sklearn.decomposition import NMF

    train = _check_train(train, n_components)
    n_dims = train.shape[1]
    split = np.hstack([np.maximum(train, 0.0), np.maximum(-train, 0.0)])
    with _quiet():
        model = NMF(
            n_components=int(n_components), init="nndsvda", solver="cd", max_iter=max_iter, tol=tol, random_state=seed
        ).fit(split)
    parts = model.components_
    shapes = parts[:, :n_dims] - parts[:, n_dims:]
    empty = ~np.any(shapes != 0, axis=1)
    if empty.any():
        raise WorkbenchError(
            f"NMF left {int(empty.sum())} of {n_components} components empty (the capture has "
            "fewer parts than components)"
        )
    return unit_activation(shapes, train)


class SurfaceDistance:
    """Distances over the face from one point to every point, in units of the face's size.

    On a mesh (``faces`` given) they are shortest paths along the edges (Dijkstra), an approximation of the
    geodesic distance that does not cut across the mouth; for markers they are Euclidean between neutral
    positions. Both are divided by the largest side of the neutral points' bounding box, as Neumann et al. scale
    their meshes into a unit box, so that their ``d_min``, ``d_max`` carry over.

    Parameters
    ----------
    neutral : ndarray of shape (3 * n_points,)
    faces : ndarray of shape (n_faces, 3) of int, or None
    """

    def __init__(self, neutral, faces=None):
        self.points = np.asarray(neutral, dtype=np.float64).reshape(-1, 3)
        self.faces = None if faces is None else np.asarray(faces)
        self.size = float(np.ptp(self.points, axis=0).max()) or 1.0
        self._graph = None
        if self.faces is not None:
            from workbench.numerics.mesh_graph import mesh_edge_graph

            self._graph = mesh_edge_graph(self.points, self.faces)

    def from_point(self, index: int) -> np.ndarray:
        """Distances from point ``index`` to every point, shape (n_points,); ``inf`` where not connected."""
        if self._graph is None:
            distance = np.linalg.norm(self.points - self.points[index], axis=1)
        else:
            from scipy.sparse.csgraph import dijkstra

            distance = dijkstra(self._graph, directed=False, indices=int(index))
        return distance / self.size


def support_map(distance: np.ndarray, d_min: float, d_max: float) -> np.ndarray:
    """Neumann et al.'s support map: 0 within ``d_min`` of the centre, 1 beyond ``d_max``, linear between.

    Parameters
    ----------
    distance : ndarray of shape (n_points,)
    d_min, d_max : float

    Returns
    -------
    ndarray of shape (n_points,)
    """
    return (np.clip(distance, d_min, d_max) - d_min) / (d_max - d_min)


def _project_weights(weights: np.ndarray) -> np.ndarray:
    """Neumann et al.'s constraint on a component's weights: non-negative with a largest value of 1."""
    weights = np.maximum(weights, 0.0)
    peak = weights.max()
    return weights / peak if peak > 0 else weights


def _prox_group_l1(values: np.ndarray, strength: np.ndarray) -> np.ndarray:
    """Proximal map of ``sum_j strength_j |v_j|`` over the 3-vectors ``v_j`` (group soft-thresholding).

    Parameters
    ----------
    values : ndarray of shape (n_components, n_points, 3)
    strength : ndarray of shape (n_components, n_points)
    """
    length = np.linalg.norm(values, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        shrink = np.where(length > 0, np.maximum(0.0, 1.0 - strength / length), 0.0)
    return values * shrink[..., None]


def _splocs_greedy_start(
    residual: np.ndarray, distance: SurfaceDistance, k_count: int, d_min: float, d_max: float
) -> tuple[np.ndarray, np.ndarray]:
    """SPLOCS's greedy start: each component grown from the point with the largest residual motion, inside its
    support. ``residual`` (shape (n_frames, n_points, 3), the scaled displacements) is used up in place.

    Returns
    -------
    components : ndarray of shape (k_count, n_points, 3)
    weights : ndarray of shape (n_frames, k_count)
    """
    components = np.zeros((k_count, residual.shape[1], 3))
    weights = np.zeros((residual.shape[0], k_count))
    for k in range(k_count):
        centre = int(np.argmax(np.einsum("fpc,fpc->p", residual, residual)))
        _, singular, vt = np.linalg.svd(residual[:, centre, :].T, full_matrices=False)
        w = singular[0] * vt[0]
        positive, negative = _project_weights(w), _project_weights(-w)
        w = positive if np.linalg.norm(positive) >= np.linalg.norm(negative) else negative
        if not w.any():
            continue
        inside = 1.0 - support_map(distance.from_point(centre), d_min, d_max)
        components[k] = np.tensordot(w, residual, (0, 0)) * inside[:, None] / (w @ w)
        weights[:, k] = w
        residual -= np.multiply.outer(w, components[k])
    return components, weights


def _splocs_update_weights(flat: np.ndarray, weights: np.ndarray, components: np.ndarray) -> None:
    """SPLOCS's block-coordinate update of ``weights`` (shape (n_frames, K), in place) against the frames
    ``flat`` (shape (n_frames, n_dims)) and the components (shape (K, n_points, 3))."""
    k_count = components.shape[0]
    rest = flat - weights @ components.reshape(k_count, -1)
    for k in range(k_count):
        ck = components[k].ravel()
        norm_sq = ck @ ck
        if norm_sq <= 1e-16:
            weights[:, k] = 0.0
            continue
        rest += np.outer(weights[:, k], ck)
        weights[:, k] = _project_weights(rest @ ck / norm_sq)
        rest -= np.outer(weights[:, k], ck)


def splocs_basis(
    train,
    distance: SurfaceDistance,
    *,
    n_components: int,
    sparsity_lambda: float = 2.0,
    d_min: float = 0.1,
    d_max: float = 0.7,
    n_iterations: int = 10,
    n_admm_iterations: int = 10,
    rho: float = 10.0,
) -> np.ndarray:
    """Sparse localised deformation components (Neumann, Varanasi, Wenger, Wacker, Magnor, Theobalt 2013).

    Minimises ``|X - W C|_F^2 + sum_k sum_j Lambda_kj |c_kj|`` (``c_kj`` the 3-vector of component ``k`` at
    point ``j``, an l1/l2 group norm) with each column of ``W`` non-negative and at most 1, alternating as the
    paper does: a greedy start (each component grown from the point with the largest residual motion, inside
    its support), then per iteration a block-coordinate update of the weights, the support maps
    ``Lambda_k = lambda * support_map(distance from the largest point of c_k)``, and ``n_admm_iterations`` of
    ADMM on the components (a Cholesky-prefactored least-squares step, the group soft-threshold, the dual
    step; the components are set to the thresholded variable). The displacements are taken from the neutral
    face (the paper's "first frame" rest shape) and divided by their standard deviation while fitting, as in
    the authors' code.

    Parameters
    ----------
    train : ndarray of shape (n_frames, n_dims)
    distance : SurfaceDistance
        Distances over the face (edge paths on a mesh, Euclidean for markers), in units of the face's size.
    n_components : int
        ``K`` in the paper.
    sparsity_lambda : float
        ``lambda`` in the paper (their default 2).
    d_min, d_max : float
        ``d_min``, ``d_max`` of the support maps in the paper (their defaults 0.1 and 0.7 of the face's size).
    n_iterations : int
        Outer iterations (the authors' code runs 10).
    n_admm_iterations : int
        ADMM iterations per outer iteration (10 in the authors' code).
    rho : float
        ADMM penalty (10 in the authors' code).

    Returns
    -------
    ndarray of shape (n_components, n_dims)
        In data units, each component's weights peaking at 1 over the training frames (the paper's
        constraint), so no rescaling is applied.
    """
    train = _check_train(train, n_components)
    if not 0 <= d_min < d_max:
        raise WorkbenchError(f"SPLOCS needs 0 <= d_min < d_max, got d_min={d_min}, d_max={d_max}")
    if not sparsity_lambda >= 0 or not rho > 0:
        raise WorkbenchError(f"SPLOCS needs sparsity_lambda >= 0 and rho > 0, got {sparsity_lambda}, {rho}")
    n_frames, n_dims = train.shape
    n_points = n_dims // 3
    if distance.points.shape[0] != n_points:
        raise WorkbenchError(f"SPLOCS distances are over {distance.points.shape[0]} points, the frames have {n_points}")
    k_count = int(n_components)
    scale = float(np.std(train)) or 1.0
    data = train / scale
    components, weights = _splocs_greedy_start(
        data.reshape(n_frames, n_points, 3).copy(), distance, k_count, d_min, d_max
    )
    flat = data
    dual = np.zeros_like(components)
    strength = np.zeros((k_count, n_points))
    for _ in range(int(n_iterations)):
        _splocs_update_weights(flat, weights, components)
        for k in range(k_count):  # support maps around each component's largest point
            centre = int(np.argmax(np.einsum("pc,pc->p", components[k], components[k])))
            strength[k] = sparsity_lambda * support_map(distance.from_point(centre), d_min, d_max)
        gram = weights.T @ weights
        rhs = weights.T @ flat
        # the ADMM's least-squares step, prefactored (a K x K inverse, K the number of components)
        inverse = cho_solve(cho_factor(gram + rho * np.eye(k_count)), np.eye(k_count))
        split = components.copy()
        for _ in range(int(n_admm_iterations)):
            components = (inverse @ (rhs + rho * (split - dual).reshape(k_count, -1))).reshape(split.shape)
            split = _prox_group_l1(components + dual, strength / rho)
            dual += components - split
        components = split
    return components.reshape(k_count, -1) * scale


def fitted_hand_basis(train, hand, *, n_iterations: int = 5) -> np.ndarray:
    """The hand basis refitted to the capture by alternating least squares, starting from the hand shapes.

    Each iteration solves the weights of every training frame in the current shapes (unconstrained least
    squares, eq. 5), then the shapes that best reproduce the frames with those weights,
    ``E = argmin |X - W E|^2 = (W^T W)^+ W^T X``. Shapes keep their order, names and units (weight 1 is still
    "fully on"), and a hand basis that already generates the frames (``X = W E^H``) is returned unchanged.
    Few iterations on purpose: each one fits the capture better and moves the shapes further from the
    animator's; the intuitiveness measures report how far.

    Parameters
    ----------
    train : ndarray of shape (n_frames, n_dims)
    hand : ndarray of shape (n_shapes, n_dims)
    n_iterations : int
        At least 1.

    Returns
    -------
    ndarray of shape (n_shapes, n_dims)
    """
    hand = np.asarray(hand, dtype=np.float64)
    train = _check_train(train, 1)
    if hand.ndim != 2 or hand.shape[1] != train.shape[1]:
        raise WorkbenchError(f"hand basis must have shape (n_shapes, {train.shape[1]}), got {hand.shape}")
    if int(n_iterations) < 1:
        raise WorkbenchError(f"H-fit needs n_iterations >= 1, got {n_iterations}")
    shapes = hand.copy()
    for _ in range(int(n_iterations)):
        weights = np.linalg.lstsq(shapes.T, train.T, rcond=None)[0].T
        shapes = np.linalg.lstsq(weights, train, rcond=None)[0]
    return shapes


FITS = {
    "SPCA": lambda face, n, seed, options: sparse_pca_basis(face.train, n_components=n, **options),
    "ICA": lambda face, n, seed, options: ica_basis(face.train, n_components=n, seed=seed, **options),
    "NMF": lambda face, n, seed, options: nmf_basis(face.train, n_components=n, seed=seed, **options),
    "SPLOCS": lambda face, n, seed, options: splocs_basis(
        face.train, SurfaceDistance(face.neutral, face.faces), n_components=n, **options
    ),
    "H-fit": lambda face, n, seed, options: fitted_hand_basis(face.train, face.hand, **options),
}
"""Label -> fit ``(face, n, seed, options) -> ndarray of shape (n, n_dims)`` of each basis of
``workbench.settings.bases.ALTERNATIVE_BASES``: ``face`` has the training frames ``train`` (n_frames, n_dims),
the ``neutral`` (n_dims,), its triangles ``faces`` (or None) and the ``hand`` shapes (n_shapes, n_dims); ``n`` is
the number of shapes (those that are not sized ignore it), ``seed`` the seed of those that draw, and ``options``
the keyword arguments of the basis's options."""
