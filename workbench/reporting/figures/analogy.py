"""Figure 1: the analogical drawing, a point cloud near a plane in 3-D, computed by the core.

Kim & Ko draw the capture as points near a hyperplane, the PCA axes, hand-made vectors off the plane and their
quasi-eigen projections, in the colours of the plots' palette (:func:`analogy_colours`). Here the same picture is computed, not drawn: a seeded cloud
near a plane, :class:`workbench.numerics.bases.Eigenfaces` for the axes and :func:`workbench.numerics.bases.quasi_eigen_faces`
(eq. 3-4, affine, through the mean) for the projections.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from workbench.numerics.bases import Eigenfaces, pca_to_qe_weights, quasi_eigen_faces
from workbench.reporting.figures import BASIS_COLOURS, OKABE_ITO, new_figure

COVERAGE = 0.95
PCA_COLOUR, HAND_COLOUR, QE_COLOUR = BASIS_COLOURS["PCA"], BASIS_COLOURS["H"], BASIS_COLOURS["QE"]  # the plots' palette
POINT_GREY, PROJECTION_GREY = "0.45", "0.2"


def analogy_colours() -> str:
    """The colours figure 1 draws, named for its caption (the names of the palette, :data:`OKABE_ITO`)."""
    names = {colour.lower(): name for name, colour in OKABE_ITO.items()}
    return (
        f"Colours: PCA axes and their plane {names[PCA_COLOUR.lower()]}, hand vectors {names[HAND_COLOUR.lower()]}, "
        f"quasi-eigen projections {names[QE_COLOUR.lower()]}; the points grey, the projection lines dark grey "
        "dotted, the mean and the origin black."
    )


@dataclass(frozen=True)
class AnalogyExample:
    """The small 3-D example behind figure 1.

    Attributes
    ----------
    points : ndarray of shape (n_points, 3)
        The "capture": displacements near a plane through ``mean``.
    eigenfaces : Eigenfaces
        Fitted on ``points`` at coverage ``COVERAGE`` (two axes: the plane).
    hand : ndarray of shape (n_hand, 3)
        Hand vectors from the origin (the neutral face), off the plane.
    quasi_eigen : ndarray of shape (n_hand, 3)
        Their affine quasi-eigen projections onto the plane (eq. 3-4).
    """

    points: np.ndarray
    eigenfaces: Eigenfaces
    hand: np.ndarray
    quasi_eigen: np.ndarray


def make_analogy_example(
    rng: np.random.Generator, *, n_points: int = 300, off_plane_std: float = 0.04
) -> AnalogyExample:
    """A seeded cloud near a tilted plane and three hand vectors off it, projected by the core.

    Parameters
    ----------
    rng : numpy.random.Generator
    n_points : int
        Points of the cloud.
    off_plane_std : float
        Standard deviation of the scatter off the plane (the in-plane spread is about 1 and 0.6).

    Returns
    -------
    AnalogyExample
    """
    centre = np.array([2.2, 2.0, 1.6])
    first = np.array([1.0, 0.25, 0.15]) / np.linalg.norm([1.0, 0.25, 0.15])
    second = np.array([-0.25, 1.0, 0.2])
    second = (second - first * (first @ second)) / np.linalg.norm(second - first * (first @ second))
    axes = np.vstack([first, second])
    normal = np.cross(first, second)
    spread = rng.standard_normal((n_points, 2)) * np.array([1.0, 0.6])
    points = centre + spread @ axes + off_plane_std * rng.standard_normal((n_points, 1)) * normal
    eigenfaces = Eigenfaces(coverage=COVERAGE).fit(points)
    in_plane_offsets = np.array([[1.7, 0.9], [-1.5, 0.8], [0.4, -1.4]])
    heights = np.array([1.2, 1.0, -0.9])
    hand = centre + in_plane_offsets @ axes + heights[:, None] * normal
    weights = pca_to_qe_weights(hand, eigenfaces.components_, eigenfaces.mean_, "affine")
    quasi_eigen = quasi_eigen_faces(weights, eigenfaces.components_, eigenfaces.mean_, "affine")
    return AnalogyExample(points=points, eigenfaces=eigenfaces, hand=hand, quasi_eigen=quasi_eigen)


def figure_analogy(example: AnalogyExample) -> Figure:
    """Draw figure 1 from a computed example.

    Parameters
    ----------
    example : AnalogyExample

    Returns
    -------
    matplotlib.figure.Figure
    """
    eigen = example.eigenfaces
    mean, axes = eigen.mean_, eigen.components_
    half_lengths = 2.0 * np.sqrt(eigen.explained_variance_[: eigen.n_components_])

    figure = new_figure(7.6, 6.4)
    ax = figure.add_subplot(projection="3d")
    ax.scatter(*example.points.T, s=5, color=POINT_GREY, alpha=0.4, depthshade=False)
    _draw_plane(ax, mean, axes[:2], 1.3 * half_lengths[:2])
    for j, (axis, length) in enumerate(zip(axes, half_lengths), start=1):
        ax.quiver(*mean, *(axis * length), color=PCA_COLOUR, linewidth=2.4, arrow_length_ratio=0.12)
        ax.text(*(mean + axis * length * 1.1 - [0, 0, 0.45]), f"$e_{j}^{{PCA}}$", color=PCA_COLOUR, fontsize=13)
    ax.scatter(*mean, s=40, color="black", depthshade=False)
    ax.text(*(mean + [-0.35, -0.3, 0.25]), r"$\mu$", fontsize=15)
    origin = np.zeros(3)
    ax.scatter(*origin, s=40, color="black", depthshade=False)
    ax.text(*(origin + [-0.6, 0.0, 0.3]), "$v_0$ (neutral)", fontsize=11)
    for i, (hand, projected) in enumerate(zip(example.hand, example.quasi_eigen), start=1):
        ax.quiver(*origin, *hand, color=HAND_COLOUR, linewidth=1.8, arrow_length_ratio=0.05)
        ax.quiver(*origin, *projected, color=QE_COLOUR, linewidth=1.8, arrow_length_ratio=0.05)
        ax.plot(*np.c_[hand, projected], color=PROJECTION_GREY, linestyle=":", linewidth=1.4)
        # Labels beyond each tip, pushed away from the mean so they do not sit on the cloud.
        away = np.r_[(hand - mean)[:2], 0.0]
        away = 0.3 * away / np.linalg.norm(away)
        ax.text(*(hand + away + [0, 0, 0.15]), f"$e_{i}^H$", color=HAND_COLOUR, fontsize=13)
        ax.text(*(projected + away + [0, 0, 0.1]), f"$e_{i}^{{QE}}$", color=QE_COLOUR, fontsize=13)
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")
    ax.view_init(elev=24, azim=-58)
    ax.set_box_aspect(np.ptp(np.vstack([example.points, example.hand, origin[None]]), axis=0))
    figure.legend(
        handles=[
            Line2D([], [], color=POINT_GREY, marker="o", linestyle="", markersize=4, label="captured frames (points)"),
            Line2D(
                [],
                [],
                color=PCA_COLOUR,
                linewidth=2.4,
                label=f"PCA axes $e_j^{{PCA}}$ (2 std; m = {eigen.n_components_}, coverage {eigen.coverage_:.3f})",
            ),
            Line2D([], [], color=HAND_COLOUR, linewidth=1.8, label="hand vectors $e_i^H$ (off the plane)"),
            Line2D(
                [],
                [],
                color=QE_COLOUR,
                linewidth=1.8,
                label=r"quasi-eigen $e_i^{QE} = \mu + \Sigma_j\, w_{ij}\, e_j^{PCA}$ (eq. 3-4)",
            ),
            Line2D(
                [],
                [],
                color=PROJECTION_GREY,
                linestyle=":",
                linewidth=1.4,
                label="projection: least distance to the plane",
            ),
        ],
        loc="outside lower center",
        ncols=2,
        fontsize=9,
        frameon=False,
    )
    figure.suptitle(
        "Figure 1 (reproduced): quasi-eigen projection onto the PCA plane\n"
        f"computed by the workbench core on a seeded 3-D example ({len(example.points)} points)",
        fontsize=11,
    )
    return figure


def _draw_plane(ax, centre: np.ndarray, axes: np.ndarray, half_lengths: np.ndarray) -> None:
    """A translucent rectangle through ``centre`` spanned by two unit ``axes`` (shape (2, 3))."""
    s, t = np.meshgrid(np.linspace(-1, 1, 2), np.linspace(-1, 1, 2))
    corners = (
        centre[None, None, :] + s[..., None] * half_lengths[0] * axes[0] + t[..., None] * half_lengths[1] * axes[1]
    )
    ax.plot_surface(
        corners[..., 0],
        corners[..., 1],
        corners[..., 2],
        color=PCA_COLOUR,
        alpha=0.08,
        edgecolor=PCA_COLOUR,
        linewidth=0.4,
    )
