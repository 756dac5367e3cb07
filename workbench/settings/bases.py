"""The bases a study can fit beside H, QE and PCA (``basis.alternatives``): one table, one entry each.

An entry says what the settings, the study and the report need of a basis: its label, the ``basis`` key holding
its options and their schema, whether it takes ``basis.alternatives_n`` and ``basis.alternatives_seed``, and how
the report draws it. Its fit is registered under the same label beside the fitting code
(:data:`workbench.numerics.alternatives.FITS`). A new basis is its fit, one entry here and its options' defaults
in ``conf/basis/default.yaml``.
"""

from __future__ import annotations

from dataclasses import dataclass

from workbench.settings.rules import integer, interval, meta


@dataclass
class SparsePCASchema:
    alpha: float = meta(0.01, interval(0, low_open=True))
    max_iter: int = meta(100, integer(1))


@dataclass
class IterativeFitSchema:
    max_iter: int = meta(200, integer(1))
    tol: float = meta(1.0e-4, interval(0))


@dataclass
class SplocsSchema:
    sparsity_lambda: float = meta(2.0, interval(0))
    d_min: float = meta(0.1, interval(0))
    d_max: float = meta(0.7, interval(0, low_open=True))
    n_iterations: int = meta(10, integer(1))
    n_admm_iterations: int = meta(10, integer(1))
    rho: float = meta(10.0, interval(0, low_open=True))


@dataclass
class HandFitSchema:
    n_iterations: int = meta(5, integer(1))


@dataclass(frozen=True)
class AlternativeBasis:
    """One basis of ``basis.alternatives``.

    Attributes
    ----------
    options_key : str
        The ``basis`` setting holding its options (``basis.<options_key>.<option>``).
    options : type
        The options' schema (a dataclass of fields with their rules), also the keyword arguments of its fit.
    sized : bool
        It fits ``basis.alternatives_n`` shapes (False: as many as the hand basis has).
    draws : bool
        It draws at random, seeded by ``basis.alternatives_seed``.
    colour, marker : str
        How the report's plots draw it (a Matplotlib colour and marker); ``hollow`` draws the marker unfilled.
    """

    options_key: str
    options: type
    sized: bool
    draws: bool
    colour: str
    marker: str
    hollow: bool = False


ALTERNATIVE_BASES: dict[str, AlternativeBasis] = {
    "SPCA": AlternativeBasis("spca", SparsePCASchema, sized=True, draws=False, colour="#56B4E9", marker="^"),
    "ICA": AlternativeBasis("ica", IterativeFitSchema, sized=True, draws=True, colour="#882255", marker="v"),
    "NMF": AlternativeBasis("nmf", IterativeFitSchema, sized=True, draws=True, colour="#8c564b", marker="P"),
    "SPLOCS": AlternativeBasis("splocs", SplocsSchema, sized=True, draws=False, colour="#999933", marker="X"),
    "H-fit": AlternativeBasis(
        "hand_fit", HandFitSchema, sized=False, draws=False, colour="#4a4a4a", marker="s", hollow=True
    ),
}
"""Label -> :class:`AlternativeBasis`, in the order the settings, the run's table and the report list them."""
