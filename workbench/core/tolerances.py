"""Numeric tolerances in one place, instead of literals scattered through the code."""

from dataclasses import dataclass


@dataclass(frozen=True)
class Tolerances:
    """Tolerances used by the numerical core.

    Attributes
    ----------
    eigen_rel : float
        Eigenvalues below ``eigen_rel * largest`` are treated as zero (rank determination of the capture).
    kkt : float
        Relative tolerance of the KKT checks of the constrained solvers (scaled by the size of the problem).
    active_set_max_iter : int
        Iterations of the batched active-set solver before a frame falls back to SciPy's per-frame solver.
    zero_displacement : float
        Frames whose displacement norm is below this (in data units) have no per-frame displacement alpha.
    gram_ridge : float
        The constrained weight solvers add ``gram_ridge * largest eigenvalue`` to the diagonal of the gram
        matrix when its smallest eigenvalue is at or below that (duplicate or nearly collinear shapes).
    weight_bound : float
        A weight counts as outside [0, 1] when it passes a bound by more than this (solvers stop at rounding).
    tie_rel : float
        Two values (alphas, errors) whose difference is within ``tie_rel`` times the larger of them are equal:
        never ``<`` in an ordering, and a frame whose non-negative solution is that close to its least-squares one
        does not need negative weights (the difference is rounding, not a finding).
    """

    eigen_rel: float = 1e-12
    kkt: float = 1e-9
    active_set_max_iter: int = 60
    zero_displacement: float = 1e-9
    gram_ridge: float = 1e-12
    weight_bound: float = 1e-6
    tie_rel: float = 1e-9


TOL = Tolerances()
