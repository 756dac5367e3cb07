"""Orderings that hold by construction: stated with their reason, never tested.

Some orderings of a run's rows follow from how the bases and solvers are made, whatever the data:

- **the solvers' nesting**: per frame, a solver minimises the error over the weights its bounds allow, so of two
  solvers whose allowed weights nest (the bounds of one contain the other's: least squares none, non-negative
  weights ``[0, inf)``, a box ``[lower, upper]`` as its settings give it, :data:`workbench.core.solvers.SOLVER_KINDS`)
  the one allowing more is never worse, for any basis, frame by frame, hence in every alpha: ``lstsq <= nnls <= box``
  for a box with ``lower >= 0``, but only ``lstsq <= box`` for a box reaching below 0;
- **QE spans PCA**: PCA reconstructs a frame as ``mu + E^T E (x - mu)``, a point of ``mu + span(E^PCA)``; the
  affine QE shapes ``P e_i^H + (I - P) mu`` lie in ``span(mu, E^PCA)``, of dimension ``m + 1`` (``m`` when the
  mean's displacement lies in the eigenfaces' span), and when their rank reaches it (generically when
  ``m + 1 <= n``) they span all of it, so QE with least squares is never worse than PCA, frame by frame;
- **QE spans QE-linear**: the linear QE shapes ``P e_i^H`` lie in ``span(eigenfaces)``, inside ``span(mu,
  eigenfaces)``, which the affine QE shapes span when their rank is ``m + 1``: QE with least squares is never worse
  than QE-linear under any solver, frame by frame;
- **QE is H**: when every hand shape lies in the eigenface hyperplane (``mu + span(eigenfaces)``, to within
  :data:`QE_IS_H` of its norm: m large enough to hold them), projecting it there leaves it where it is, so QE's
  shapes are H's and QE = H under every solver (QE-linear likewise, with ``span(eigenfaces)``), as long as no
  eigenface was appended; a difference between them is the hand shapes' residual, not a finding;
- **carried bases**: bases carried onto other points (``dataset.eval_on``) by a linear transfer ``T`` keep both
  inclusions, ``T`` of a span being the span of the images: the carried PCA reconstruction lies in
  ``T mu + span(T eigenfaces)`` and the carried QE shapes span ``span(T mu, T eigenfaces)``;
- **Eckart-Young**: on the frames PCA was fitted to (exactly, not by a randomised decomposition), the best affine
  subspace of dimension ``m`` in pooled squared error is PCA's, and a basis of ``n <= m`` shapes through the
  neutral face is one such subspace or a part of one, so PCA's pooled alpha is at most that basis's under any
  solver. Likewise ICA's ``k`` shapes span the leading ``k`` singular vectors of the (uncentred) training
  displacements, the best linear subspace of dimension ``k``: with least squares, ICA's pooled alpha on those
  frames is at most that of any basis whose reconstructions lie in a linear subspace of dimension ``<= k`` (``n``
  shapes; PCA's ``mu + span(eigenfaces)`` lies in one of dimension ``m + 1``);
- **H-fit's descent**: H-fit starts from the hand shapes and alternates exact least-squares steps for the weights
  and the shapes on the training frames, neither of which raises the pooled squared error, so with least squares
  its pooled alpha on those frames is at most H's under any solver.

Each holds whatever the data, so it is stated with its reason and never tested; what the data decide is its size.
Identities that hold on pooled errors only need the very frames the bases were fitted on, at every point
(no masked solve).

:func:`run_identities` decides which of these a record's data variant holds from what ``metrics.json`` keeps (the
rows' bases, solvers, sizes and ranks, m, the PCA method, which frames were scored); findings and tables print them
as "A <= B by construction (reason)" and spend no interval on them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

from workbench.core.solvers import solver_kind

EXACT_PCA = ("covariance", "gram")
QE_IS_H = 1e-3
"""QE is H when every hand shape lies in the eigenface hyperplane to within this fraction of its norm
(:attr:`workbench.numerics.bases.QuasiEigenBasis.hand_residual`)."""
QE_LABELS = {"affine": "QE", "linear": "QE-linear"}
POOLED_COLUMNS = ("alpha_abs_pooled", "alpha_disp_pooled")


@dataclass(frozen=True)
class Identity:
    """An ordering of two rows that holds by construction.

    Attributes
    ----------
    smaller, larger : tuple of (str, str)
        ``(basis, solver)`` of the row that can never be worse and of the other.
    reason : str
        Why, in a few words (printed beside it).
    pooled_only : bool
        Holds for pooled alphas only (Eckart-Young), not frame by frame.
    """

    smaller: tuple
    larger: tuple
    reason: str
    pooled_only: bool = False

    def applies(self, column: str) -> bool:
        """Whether it holds for an alpha column (every column, or the pooled ones for Eckart-Young)."""
        return not self.pooled_only or column in POOLED_COLUMNS


def scored_on_training_frames(facts: Mapping) -> bool:
    """Whether a data variant was scored on the very frames its bases were fitted on (split 'same'), at every
    point (no masked solve, which scores the visible points only)."""
    notes = [str(note) for note in facts.get("notes", [])]
    return facts.get("protocol", "training frames") == "training frames" and not any(
        note.startswith(("split 'tail'", "split 'other_take'", "masked solve")) for note in notes
    )


def solver_bounds(name: str, settings: Mapping | None = None) -> tuple[float, float] | None:
    """The weights the solver ``name`` allows, ``(lower, upper)`` (open sides infinite), from its kind's entry of
    :data:`workbench.core.solvers.SOLVER_KINDS` and the run's solver settings (``solver``: a box's bounds); None
    for a solver of no known kind (PCA's projection).

    Parameters
    ----------
    name : str
    settings : mapping, optional
        The run's ``solver`` settings (``solver.<name>.kind``, ``.lower``, ``.upper``); without them, the kind's
        defaults (a box ``[0, 1]``).
    """
    _, entry = solver_kind(name, settings)
    if entry is None:
        return None
    given = (settings or {}).get(name) or {}
    low, high = entry.bounds(given.get("lower", entry.lower), given.get("upper", entry.upper))
    return (-math.inf if low is None else float(low)), (math.inf if high is None else float(high))


def solver_contains(first: str, second: str, settings: Mapping | None = None) -> bool:
    """Whether the solver ``first`` allows every weight vector ``second`` allows (its bounds contain the other's),
    so that it is never worse on any basis; False for two solvers of which one has no known kind."""
    a, b = solver_bounds(first, settings), solver_bounds(second, settings)
    return a is not None and b is not None and first != second and a[0] <= b[0] and a[1] >= b[1]


def _nesting_reason(first: str, second: str, settings: Mapping | None) -> str:
    low, high = solver_bounds(second, settings)
    return f"{first} minimises the error over a superset of {second}'s weights [{low:g}, {high:g}]"


def _solver_nesting(rows: Sequence[Mapping], settings: Mapping | None = None) -> list[Identity]:
    """Every pair of one basis's rows whose solvers' allowed weights nest (:func:`solver_contains`)."""
    found = []
    for basis in dict.fromkeys(row["basis"] for row in rows):
        solvers = [row["solver"] for row in rows if row["basis"] == basis]
        found += [
            Identity((basis, a), (basis, b), _nesting_reason(a, b, settings))
            for a in solvers
            for b in solvers
            if solver_contains(a, b, settings) and not solver_contains(b, a, settings)
        ]
    return found


def _fold_spans(folds: Mapping) -> str | None:
    """Why QE with least squares spans mu + span(eigenfaces) in every fold of a cross-validated variant (its
    affine shapes' rank is m + 1 for each fold's m, :func:`workbench.study.crossval.fold_values`), or None."""
    keys = [tuple(row) for row in folds.get("rows") or []]
    ranks, ms = folds.get("rank"), folds.get("m")
    if ("QE", "affine", "lstsq") not in keys or not ranks or not ms:
        return None
    index = keys.index(("QE", "affine", "lstsq"))
    per_fold = ranks[index]
    if len(per_fold) != len(ms) or any(rank is None or rank < m + 1 for rank, m in zip(per_fold, ms)):
        return None
    n = (folds.get("n_shapes") or [None] * len(keys))[index]
    shapes = f"the {n:g} affine QE shapes" if n is not None else "the affine QE shapes"
    return (
        f"in each of the {len(ms)} folds {shapes} have rank m + 1 (m = {list(ms)}, rank = {list(per_fold)}): "
        "they span mu + span(eigenfaces)"
    )


def _qe_spans(rows: Sequence[Mapping], m: int | None, folds: Mapping | None = None) -> list[Identity]:
    """QE with least squares against PCA and QE-linear, when the affine QE shapes have rank m + 1 (on the same
    points or carried onto others: a linear transfer keeps both inclusions); for a cross-validated variant, when
    they have it in every fold (the pooled rows keep no rank of their own)."""
    qe = next((row for row in rows if row["basis"] == "QE" and row["solver"] == "lstsq"), None)
    if qe is None:
        return []
    rank = (qe.get("basis_conditioning") or {}).get("rank")
    if folds:
        spans = _fold_spans(folds)
        if spans is None:
            return []
    else:
        if qe.get("n") is None or m is None or rank is None or rank < m + 1:
            return []
        spans = f"the {qe['n']:g} affine QE shapes have rank {rank} = m + 1: they span mu + span(eigenfaces)"
    carried = " (carried by a linear transfer, which keeps it)" if _carried(rows) else ""
    found = []
    for row in rows:
        if (row["basis"], row["solver"]) == ("PCA", "projection"):
            found.append(
                Identity(("QE", "lstsq"), ("PCA", "projection"), f"{spans}, where PCA's reconstruction lies{carried}")
            )
        elif row["basis"] == "QE-linear":
            found.append(
                Identity(
                    ("QE", "lstsq"), ("QE-linear", row["solver"]), f"{spans}, which holds QE-linear's span{carried}"
                )
            )
    return found


def _qe_is_h(rows: Sequence[Mapping], facts: Mapping) -> list[Identity]:
    """QE = H (both ways) under every solver both have, when every hand shape lies in the eigenface hyperplane to
    within :data:`QE_IS_H` (in every fold of a cross-validated variant) and no eigenface was appended."""
    m = (facts.get("pca") or {}).get("m")
    folds = facts.get("folds") or {}
    found = []
    for projection, label in QE_LABELS.items():
        facts_qe = (facts.get("quasi_eigen") or {}).get(projection) or {}
        residuals = (folds.get("hand_residual") or {}).get(projection) if folds else [facts_qe.get("hand_residual")]
        if not residuals or any(value is None or not value <= QE_IS_H for value in residuals):
            continue
        if facts_qe.get("appended_axes"):
            continue
        where = f"in each of the {len(residuals)} folds" if folds else f"at m = {m}"
        reason = (
            f"every hand shape lies in the eigenface hyperplane {where} (to {max(residuals):.1g} of its norm): "
            f"{label}'s shapes are H's, {label} = H"
        )
        solvers = {row["solver"] for row in rows if row["basis"] == label} & {
            row["solver"] for row in rows if row["basis"] == "H"
        }
        for solver in sorted(solvers):
            found += [
                Identity((label, solver), ("H", solver), reason),
                Identity(("H", solver), (label, solver), reason),
            ]
    return found


def _carried(rows: Sequence[Mapping]) -> bool:
    return any(row.get("train_on", row.get("data")) != row.get("eval_on", row.get("data")) for row in rows)


def _span_dimension(row: Mapping, m: int) -> float:
    """The dimension of a linear subspace that holds every reconstruction of a row: PCA's ``mu +
    span(eigenfaces)`` lies in one of ``m + 1``; a basis of ``n`` shapes spans at most ``n``."""
    return m + 1 if row["basis"] == "PCA" else float(row.get("n") or "nan")


def _pooled_optima(rows: Sequence[Mapping], facts: Mapping, m: int | None) -> list[Identity]:
    """Eckart-Young for PCA and for ICA, and H-fit's descent: pooled, on the training frames only."""
    if m is None or _carried(rows) or not scored_on_training_frames(facts):
        return []
    keys = {(row["basis"], row["solver"]) for row in rows}
    found = []
    if ("PCA", "projection") in keys and (facts.get("pca") or {}).get("method") in EXACT_PCA:
        found += [
            Identity(
                ("PCA", "projection"),
                (row["basis"], row["solver"]),
                f"Eckart-Young: on its training frames PCA's m = {m} is the best pooled fit of any {row['n']:g} <= m "
                "shapes",
                pooled_only=True,
            )
            for row in rows
            if row["basis"] != "PCA" and row.get("n") is not None and row["n"] <= m
        ]
    ica = next((row for row in rows if (row["basis"], row["solver"]) == ("ICA", "lstsq")), None)
    if ica is not None and ica.get("n") is not None:
        found += [
            Identity(
                ("ICA", "lstsq"),
                (row["basis"], row["solver"]),
                f"Eckart-Young: ICA's {ica['n']:g} shapes span the best linear fit of that dimension to its training "
                f"frames; {row['basis']}'s reconstructions lie in one of dimension {_span_dimension(row, m):g}",
                pooled_only=True,
            )
            for row in rows
            if row["basis"] != "ICA" and _span_dimension(row, m) <= ica["n"]
        ]
    if ("H-fit", "lstsq") in keys:
        found += [
            Identity(
                ("H-fit", "lstsq"),
                ("H", row["solver"]),
                "H-fit starts from H, and each of its alternating least-squares steps lowers the pooled error "
                "on the training frames",
                pooled_only=True,
            )
            for row in rows
            if row["basis"] == "H"
        ]
    return found


def run_identities(rows: Sequence[Mapping], facts: Mapping, solvers: Mapping | None = None) -> list[Identity]:
    """The orderings one data variant of a run holds by construction.

    Parameters
    ----------
    rows : sequence of mapping
        The variant's rows (``metrics.json`` ``rows``): ``basis``, ``solver``, ``n`` and, where recorded,
        ``basis_conditioning`` (``rank``, ``n_shapes``), ``train_on`` and ``eval_on``.
    facts : mapping
        The variant's part of ``metrics.json`` ``data``: ``pca`` (``m``, ``method``), ``protocol``, ``notes``,
        ``quasi_eigen`` (per projection its ``hand_residual`` and ``appended_axes``), and
        for a cross-validated variant ``folds`` (each fold's ``m`` and every row's ``rank``,
        :func:`workbench.study.crossval.fold_values`): its identities are those that hold in every fold.
    solvers : mapping, optional
        The run's ``solver`` settings (each solver's kind and bounds): the solvers' nesting is decided by their
        bounds (:func:`solver_contains`). Without them, ``facts["solvers"]`` where a record keeps them, else each
        kind's defaults (a box ``[0, 1]``).

    Returns
    -------
    list of Identity
    """
    m = (facts.get("pca") or {}).get("m")
    settings = solvers if solvers is not None else facts.get("solvers")
    return (
        _solver_nesting(rows, settings)
        + _qe_spans(rows, m, facts.get("folds"))
        + _qe_is_h(rows, facts)
        + _pooled_optima(rows, facts, m)
    )


def identity_lookup(identities: Sequence[Identity], column: str) -> Callable[[tuple, tuple], Identity | None]:
    """``lookup(a, b)``: the identity saying ``a <= b`` for ``column``, or None.

    The solvers' nesting is listed pair by pair (:func:`run_identities`, by the solvers' bounds), so no chain is
    followed here.
    """
    direct = {(tuple(item.smaller), tuple(item.larger)): item for item in identities if item.applies(column)}

    def lookup(a, b) -> Identity | None:
        return direct.get((tuple(a), tuple(b)))

    return lookup


def identity_text(identity: Identity) -> str:
    """``QE lstsq <= PCA by construction (reason)``."""
    return (
        f"{' '.join(identity.smaller).replace(' projection', '')} <= "
        f"{' '.join(identity.larger).replace(' projection', '')} by construction ({identity.reason})"
    )
