"""Plots of a run's hand shapes and their weights: the weight curves w_i(t) around chosen frames, with left/right
partners sharing a colour, and how far each hand shape moves when projected (cosine and relative distance)."""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure

from workbench.reporting.figures import basis_colour, new_figure, wrap_title

WEIGHT_POINTS = 150
"""Most points of a weight curve in one window (a few seconds): more would not show at a panel's width."""


PAIR_STYLES = {"_L": "-", "_R": "--"}
"""Line style of a left and a right shape; the two shapes of a pair share a colour."""


def shape_styles(names: Sequence[str]) -> dict[str, tuple[str, str]]:
    """Colour and line style of each shape: one colour per left/right pair (or unpaired shape), solid for ``_L``
    and unpaired shapes, dashed for ``_R``."""
    stems = list(dict.fromkeys(name[:-2] if name[-2:] in PAIR_STYLES else name for name in names))
    colours = {stem: f"C{k % 10}" for k, stem in enumerate(stems)}
    return {
        name: (colours[name[:-2] if name[-2:] in PAIR_STYLES else name], PAIR_STYLES.get(name[-2:], "-"))
        for name in names
    }


def plot_weight_curves(windows: Sequence[Mapping], names: Sequence[str], shown: Sequence[int], *, title: str) -> Figure:
    """Weight curves w_i(t) of several bases around marked frames: one column per frame, one row per basis; the
    two shapes of a left/right pair share a colour (``_L`` solid, ``_R`` dashed).

    Parameters
    ----------
    windows : sequence of mapping
        One per marked frame: ``label`` (its name), ``take``, ``seconds`` (ndarray of shape (n_frames,), time in
        the take), ``marked`` (the frame's time) and ``weights`` (basis label -> ndarray of shape
        (n_frames, n_shapes)).
    names : sequence of str
        One per shape.
    shown : sequence of int
        The shapes drawn.
    title : str

    Returns
    -------
    matplotlib.figure.Figure
    """
    labels = list(windows[0]["weights"])
    styles = shape_styles([names[k] for k in shown])
    width = max(9.0, 3.6 * len(windows) + 0.8)
    figure = new_figure(width, 2.4 * len(labels) + 2.4)
    axes = figure.subplots(len(labels), len(windows), squeeze=False, sharey="row")
    for column, window in enumerate(windows):
        for row, label in enumerate(labels):
            ax = axes[row, column]
            values = np.asarray(window["weights"][label])
            step = max(1, -(-len(values) // WEIGHT_POINTS))  # a 120 Hz capture: every 5th frame still draws smooth
            for index in shown:
                colour, style = styles[names[index]]
                ax.plot(
                    window["seconds"][::step],
                    values[::step, index],
                    color=colour,
                    linestyle=style,
                    linewidth=1.2,
                    label=names[index],
                )
            ax.axvline(window["marked"], color="0.15", linewidth=1.0, linestyle=":")
            ax.axhline(0.0, color="0.3", linewidth=0.8)
            ax.axhline(1.0, color="0.6", linewidth=0.8, linestyle=":")
            ax.grid(alpha=0.3)
            if column == 0:
                ax.set_ylabel(f"w_i, {label}", fontsize=9, color=basis_colour(label))
        axes[0, column].set_title(wrap_title(window["label"], width / len(windows), 9), fontsize=9)
        axes[-1, column].set_xlabel(f"time in {window['take']} (s)", fontsize=9)
    handles, legend = axes[0, 0].get_legend_handles_labels()
    figure.legend(
        handles,
        legend,
        loc="outside lower center",
        ncols=max(1, -(-len(legend) // 2)),
        fontsize=8.5,
        frameon=False,
        title="hand shape (pairs: _L solid, _R dashed); dotted vertical: the frame of figure 3",
        title_fontsize=8.5,
    )
    figure.suptitle(wrap_title(title, width), fontsize=11)
    return figure


def plot_intuitiveness_bars(
    names: Sequence[str],
    cosine: Mapping[str, Sequence[float]],
    relative_distance: Mapping[str, Sequence[float]],
    *,
    title: str,
) -> Figure:
    """How far each hand shape moved when projected: cosine and relative distance to its quasi-eigen face, bars
    per shape, one bar per projection.

    Parameters
    ----------
    names : sequence of str
        Hand shapes.
    cosine, relative_distance : mapping
        Projection (``affine``, ``linear``) -> one value per shape.
    title : str

    Returns
    -------
    matplotlib.figure.Figure
    """
    projections = list(cosine)
    height = 0.26 * len(names) + 1.8
    figure = new_figure(9.0, height)
    left, right = figure.subplots(1, 2, sharey=True)
    step = 0.8 / len(projections)
    colours = {"affine": basis_colour("QE"), "linear": basis_colour("QE-linear")}
    rows = np.arange(len(names))
    for k, projection in enumerate(projections):
        offset = (k - (len(projections) - 1) / 2) * step
        left.barh(
            rows + offset,
            cosine[projection],
            height=step * 0.9,
            color=colours.get(projection, f"C{k}"),
            label=projection,
        )
        right.barh(
            rows + offset,
            relative_distance[projection],
            height=step * 0.9,
            color=colours.get(projection, f"C{k}"),
            label=projection,
        )
    left.set_yticks(rows, names, fontsize=8)
    left.invert_yaxis()
    left.set_xlim(min(0.0, float(np.min([np.min(v) for v in cosine.values()]))), 1.0)
    left.set_xlabel("cosine to its quasi-eigen face\n(1: same direction)")
    right.set_xlabel("relative distance |e^QE - e^H| / |e^H|\n(0: unchanged)")
    for ax in (left, right):
        ax.grid(axis="x", alpha=0.3)
    left.legend(fontsize=8, title="projection", title_fontsize=8)
    figure.suptitle(wrap_title(title, 9.0), fontsize=11)
    return figure
