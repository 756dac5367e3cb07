"""Orderings that hold by construction: stated with their reason, never tested.

Some orderings of a run's rows follow from how the bases and solvers are made, whatever the data:

- **the solvers' nesting**: per frame, least squares minimises the error over every weight vector, non-negative
  weights over a subset of them and box [0, 1] weights over a subset of that, so for any basis
  ``lstsq <= nnls <= box`` frame by frame, hence in every alpha;
- **QE spans PCA**: PCA reconstructs a frame as ``mu + E^T E (x - mu)``, a point of ``mu + span(E^PCA)``; the
  affine QE shapes ``P e_i^H + (I - P) mu`` lie in ``span(mu, E^PCA)``, of dimension ``m + 1`` (``m`` when the
  mean's displacement lies in the eigenfaces' span), and when their rank reaches it (generically when
  ``m + 1 <= n``) they span all of it, so QE with least squares is never worse than PCA, frame by frame;
- **Eckart-Young**: on the frames PCA was fitted to (exactly, not by a randomised decomposition), the best affine
  subspace of dimension ``m`` in pooled squared error is PCA's, and a basis of ``n <= m`` shapes through the
  neutral face is one such subspace or a part of one, so PCA's pooled alpha is at most that basis's under any
  solver.

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
    """Whether a data variant was scored on the very frames its bases were fitted on (split 'same')."""
    return facts.get("protocol", "training frames") == "training frames" and not any(
        str(note).startswith(("split 'tail'", "split 'other_take'")) for note in facts.get("notes", [])
    )


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
    found = []
    keys = {(row["basis"], row["solver"]) for row in rows}
    for basis in dict.fromkeys(row["basis"] for row in rows if row["solver"] in SOLVER_ORDER):
        nested = [solver for solver in SOLVER_ORDER if (basis, solver) in keys]
        found += [
            Identity((basis, a), (basis, b), f"{a} minimises the error over a superset of {b}'s weights")
            for a, b in zip(nested, nested[1:])
        ]
    pca = facts.get("pca") or {}
    m = pca.get("m")
    same_points = all(row.get("train_on", row.get("data")) == row.get("eval_on", row.get("data")) for row in rows)
    qe = next((row for row in rows if row["basis"] == "QE" and row["solver"] == "lstsq"), None)
    rank = ((qe or {}).get("basis_conditioning") or {}).get("rank")
    if (
        qe is not None
        and qe.get("n") is not None
        and ("PCA", "projection") in keys
        and m is not None
        and same_points
        and rank is not None
        and rank >= m + 1
    ):
        found.append(
            Identity(
                ("QE", "lstsq"),
                ("PCA", "projection"),
                f"the {qe['n']:g} affine QE shapes have rank {rank} = m + 1: they span mu + "
                "span(eigenfaces), where PCA's reconstruction lies",
            )
        )
    if (
        ("PCA", "projection") in keys
        and m is not None
        and same_points
        and scored_on_training_frames(facts)
        and pca.get("method") in EXACT_PCA
    ):
        for row in rows:
            if row["basis"] != "PCA" and row.get("n") is not None and row["n"] <= m:
                found.append(
                    Identity(
                        ("PCA", "projection"),
                        (row["basis"], row["solver"]),
                        f"Eckart-Young: on its training frames PCA's m = {m} is the best pooled fit "
                        f"of any {row['n']:g} <= m shapes",
                        pooled_only=True,
                    )
                )
    return found


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
