"""Figures of the paper and plots of its studies, drawn from run records.

Modules:

- :mod:`workbench.reporting.figures.analogy`: figure 1, the analogical 3-D drawing, computed by the core on a small example.
- :mod:`workbench.reporting.figures.render`: off-screen mesh rendering with pyvista (headless, through EGL or OSMesa).
- :mod:`workbench.reporting.figures.faces`: figures 2-4 (hand versus quasi-eigen shapes, reconstructed frames, marker
  errors of one frame).
- :mod:`workbench.reporting.figures.studies`: coverage curve, alpha against a swept setting with confidence bands, marker
  versus mesh, alpha per frame over time.

Every figure is a :class:`matplotlib.figure.Figure` built without pyplot (no display, no global figure state)
and written by :func:`save_figure` as PNG and SVG.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Sequence

import matplotlib
from matplotlib.figure import Figure

from workbench.record import inside, write_atomic

FORMATS = ("png", "svg")
# Full-colour PNGs. Figures of rendered faces (raster images) at a resolution that survives zooming, and no
# vector copy (it would only wrap the same raster); line plots at screen resolution plus their vector copy
# (SVG, PDF), which is what survives zooming for them.
PNG_DPI = 200
RENDER_DPI = 140
PLOT_DPI = 100

# Basis colours shared by every plot, so a basis looks the same everywhere.
BASIS_COLOURS = {"H": "#1f5fbf", "QE": "#8e2bb0", "QE-linear": "#d17a00", "PCA": "#c0392b"}
BASIS_LABELS = {"H": "hand $E^H$", "QE": "quasi-eigen $E^{QE}$ (affine)",
                "QE-linear": "quasi-eigen (linear)", "PCA": "PCA $E^{PCA}$"}

# Text-as-text SVG with a fixed hash salt and no date: the same figure gives the same bytes on every rebuild.
SVG_RC = {"svg.fonttype": "none", "svg.hashsalt": "workbench"}


def new_figure(width: float, height: float) -> Figure:
    """A figure of ``width`` x ``height`` inches with constrained layout, not attached to any GUI."""
    return Figure(figsize=(width, height), layout="constrained")


def wrap_title(text: str, width_inches: float, fontsize: float = 11) -> str:
    """Wrap each line of a title to the width of a figure (about 0.55 of the font size per character)."""
    import textwrap

    chars = max(int(width_inches * 72 / (0.55 * fontsize)), 20)
    return "\n".join(textwrap.fill(line, chars) for line in text.split("\n"))


def basis_colour(basis: str) -> str:
    return BASIS_COLOURS.get(basis, "#555555")


def basis_label(basis: str) -> str:
    return BASIS_LABELS.get(basis, basis)


def save_figure(figure: Figure, folder: Path, stem: str, formats: Sequence[str] = FORMATS) -> list[Path]:
    """Write a figure as ``<folder>/<stem>.<format>`` for each format.

    Parameters
    ----------
    figure : matplotlib.figure.Figure
    folder : pathlib.Path
    stem : str
        File name without extension.
    formats : sequence of str
        Any of ``png``, ``svg``, ``pdf``. A figure of rendered images (faces) is written as PNG only.

    Returns
    -------
    list of pathlib.Path
        The files written, in the order of ``formats``.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    raster = is_raster(figure)
    written = []
    for fmt in (["png"] if raster else formats):
        path = inside(folder, f"{stem}.{fmt}")
        if fmt == "png":
            data = png_bytes(figure, dpi=RENDER_DPI if raster else PLOT_DPI)
        else:
            buffer = io.BytesIO()
            with matplotlib.rc_context(SVG_RC):
                figure.savefig(buffer, format=fmt, metadata={"Date": None} if fmt == "svg" else None)
            data = buffer.getvalue()
        write_atomic(path, data)  # a killed report leaves whole figures or none
        written.append(path)
    return written


def is_raster(figure: Figure) -> bool:
    """Whether a figure shows rendered images (faces), rather than lines and points only."""
    return any(ax.images for ax in figure.axes)


def png_bytes(figure: Figure, *, dpi: int = PNG_DPI) -> bytes:
    """Full-colour PNG of a figure, without metadata that changes between rebuilds."""
    from PIL import Image

    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi, metadata={"Software": None})
    # re-encoded losslessly at the highest compression (matplotlib writes level 6)
    image = Image.open(io.BytesIO(buffer.getvalue()))
    smaller = io.BytesIO()
    image.save(smaller, format="png", optimize=True, dpi=image.info.get("dpi", (dpi, dpi)))
    return min(buffer.getvalue(), smaller.getvalue(), key=len)
