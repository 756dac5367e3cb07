"""Orderings that hold by construction: stated with their reason, never tested.

Some orderings of a run's rows follow from how the bases and solvers are made, whatever the data:

- **the solvers' nesting**: per frame, least squares minimises the error over every weight vector, non-negative
  weights over a subset of them and box [0, 1] weights over a subset of that, so for any basis
  ``lstsq <= nnls <= box`` frame by frame, hence in every alpha;
- **QE spans PCA**: PCA reconstructs a frame as ``mu + E^T E (x - mu)``, a point of ``mu + span(E^PCA)``; the
  affine QE shapes ``P e_i^H + (I - P) mu`` lie in ``span(mu, E^PCA)``, of dimension ``m + 1`` (``m`` when the
  mean's displacement lies in the eigenfaces' span), and when their rank reaches it (generically when
  ``m + 1 <= n``) they span all of it, so QE with least squares is never worse than PCA, frame by frame;
- **QE spans QE-linear**: the linear QE shapes ``P e_i^H`` lie in ``span(eigenfaces)``, inside ``span(mu,
  eigenfaces)``, which the affine QE shapes span when their rank is ``m + 1``: QE with least squares is never worse
  than QE-linear under any solver, frame by frame;
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

from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

SOLVER_ORDER = ("lstsq", "nnls", "box")
EXACT_PCA = ("covariance", "gram")
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


def _solver_nesting(rows: Sequence[Mapping]) -> list[Identity]:
    keys = {(row["basis"], row["solver"]) for row in rows}
    found = []
    for basis in dict.fromkeys(row["basis"] for row in rows if row["solver"] in SOLVER_ORDER):
        nested = [solver for solver in SOLVER_ORDER if (basis, solver) in keys]
        found += [
            Identity((basis, a), (basis, b), f"{a} minimises the error over a superset of {b}'s weights")
            for a, b in zip(nested, nested[1:])
        ]
    return found


def _qe_spans(rows: Sequence[Mapping], m: int | None) -> list[Identity]:
    """QE with least squares against PCA and QE-linear, when the affine QE shapes have rank m + 1 (on the same
    points or carried onto others: a linear transfer keeps both inclusions)."""
    qe = next((row for row in rows if row["basis"] == "QE" and row["solver"] == "lstsq"), None)
    rank = ((qe or {}).get("basis_conditioning") or {}).get("rank")
    if qe is None or qe.get("n") is None or m is None or rank is None or rank < m + 1:
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


def run_identities(rows: Sequence[Mapping], facts: Mapping) -> list[Identity]:
    """The orderings one data variant of a run holds by construction.

    Parameters
    ----------
    rows : sequence of mapping
        The variant's rows (``metrics.json`` ``rows``): ``basis``, ``solver``, ``n`` and, where recorded,
        ``basis_conditioning`` (``rank``, ``n_shapes``), ``train_on`` and ``eval_on``.
    facts : mapping
        The variant's part of ``metrics.json`` ``data``: ``pca`` (``m``, ``method``), ``protocol``, ``notes``.

    Returns
    -------
    list of Identity
    """
    m = (facts.get("pca") or {}).get("m")
    return _solver_nesting(rows) + _qe_spans(rows, m) + _pooled_optima(rows, facts, m)


def identity_lookup(identities: Sequence[Identity], column: str) -> Callable[[tuple, tuple], Identity | None]:
    """``lookup(a, b)``: the identity saying ``a <= b`` for ``column``, or None.

    Chains of the solvers' nesting are followed (``lstsq <= box`` through ``nnls``).
    """
    direct = {(tuple(item.smaller), tuple(item.larger)): item for item in identities if item.applies(column)}
    nested = {item.smaller[0] for item in identities if item.smaller[0] == item.larger[0]}

    def lookup(a, b) -> Identity | None:
        a, b = tuple(a), tuple(b)
        if (a, b) in direct:
            return direct[a, b]
        if (
            a[0] == b[0]
            and a[0] in nested
            and a[1] in SOLVER_ORDER
            and b[1] in SOLVER_ORDER
            and SOLVER_ORDER.index(a[1]) < SOLVER_ORDER.index(b[1])
        ):
            return Identity(a, b, f"{a[1]} minimises the error over a superset of {b[1]}'s weights")
        return None

    return lookup


def identity_text(identity: Identity) -> str:
    """``QE lstsq <= PCA by construction (reason)``."""
    return (
        f"{' '.join(identity.smaller).replace(' projection', '')} <= "
        f"{' '.join(identity.larger).replace(' projection', '')} by construction ({identity.reason})"
    )
