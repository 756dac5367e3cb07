"""Figures of the paper and plots of its studies, drawn from run records.

Modules:

- :mod:`workbench.reporting.figures.analogy`: figure 1, the analogical 3-D drawing, computed by the core on a small example.
- :mod:`workbench.reporting.figures.render`: off-screen mesh rendering with pyvista (headless, through EGL or OSMesa).
- :mod:`workbench.reporting.figures.faces`: figures 2-4 (hand versus quasi-eigen shapes, reconstructed frames, marker
  errors of one frame).
- :mod:`workbench.reporting.figures.headline`: the figure under a run report's summary, the paper's comparison (H, QE
  and PCA at m = n and with the coverage rule) with its intervals.
- :mod:`workbench.reporting.figures.studies`: coverage curve, alpha against a swept setting with confidence bands, marker
  versus mesh, alpha per frame over time, alpha per solver.
- :mod:`workbench.reporting.figures.shapes`: a run's weight curves and how far each hand shape moves when projected.
- :mod:`workbench.reporting.figures.bases`: the other bases, alpha against each intuitiveness measure.

Every figure is a :class:`matplotlib.figure.Figure` built without pyplot (no display, no global figure state)
and written by :func:`save_figure`: a figure of rendered faces as a lossless WebP, a line plot as SVG (vector,
sharp at any zoom), plus any copies asked for (PNG, PDF).
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Sequence

import matplotlib
from matplotlib.figure import Figure

from workbench.core.files import inside, write_atomic

FORMATS = ("png", "svg", "pdf")
"""Copies a report can ask for besides each figure's own file (:func:`shown_format`)."""
# Figures of rendered faces (raster images) as lossless WebP at a resolution that survives zooming, with no vector
# copy (it would only wrap the same raster); line plots as SVG, and PNG copies of them at print resolution.
PNG_DPI = 200
RENDER_DPI = 110

# One colour-blind-safe palette for every plot (Okabe & Ito's eight colours, distinct in the common forms of colour
# blindness and in grey): a basis, and a data variant, look the same everywhere.
OKABE_ITO = {
    "blue": "#0072B2",
    "vermillion": "#D55E00",
    "bluish green": "#009E73",
    "reddish purple": "#CC79A7",
    "orange": "#E69F00",
    "sky blue": "#56B4E9",
    "yellow": "#F0E442",
    "black": "#000000",
}
BASIS_COLOURS = {
    "H": OKABE_ITO["blue"],
    "QE": OKABE_ITO["vermillion"],
    "QE-linear": OKABE_ITO["bluish green"],
    "PCA": OKABE_ITO["reddish purple"],
}
DATA_COLOURS = {"markers": OKABE_ITO["sky blue"], "mesh": OKABE_ITO["orange"]}
BASIS_LABELS = {
    "H": "hand $E^H$",
    "QE": "quasi-eigen $E^{QE}$ (affine)",
    "QE-linear": "quasi-eigen (linear)",
    "PCA": "PCA $E^{PCA}$",
}

# Text-as-text SVG with a fixed hash salt and no date: the same figure gives the same bytes on every rebuild.
# Text as text; the font named once, with two fallbacks, instead of matplotlib's list of eleven on every label (the
# labels are drawn in DejaVu Sans either way: the list only changes what a browser without it falls back to).
SVG_RC = {"svg.fonttype": "none", "svg.hashsalt": "workbench", "font.sans-serif": ["DejaVu Sans", "Arial", "Helvetica"]}


def new_figure(width: float, height: float) -> Figure:
    """A figure of ``width`` x ``height`` inches with constrained layout, not attached to any GUI."""
    return Figure(figsize=(width, height), layout="constrained")


def wrap_title(text: str, width_inches: float, fontsize: float = 11) -> str:
    """Wrap each line of a title to the width of a figure (about 0.55 of the font size per character)."""
    import textwrap

    chars = max(int(width_inches * 72 / (0.55 * fontsize)), 20)
    return "\n".join(textwrap.fill(line, chars) for line in text.split("\n"))


def replicates_legend(figure, handles, labels, not_replicates: str, width_inches: float, **options):
    """The figure's legend below its panels; where the runs behind its bands or bars are not replicates (they differ
    only in an optimiser's seed: ``not_replicates`` says so, :func:`workbench.stats.replicates.pseudo_replicate_reason`)
    the legend's title says it, and that no ordering is drawn from them."""
    title = (
        wrap_title(f"not replicates: {not_replicates}; the spread is that seed's, no ordering", width_inches, 8)
        if not_replicates
        else None
    )
    return figure.legend(
        handles, labels, loc="outside lower center", frameon=False, title=title, title_fontsize=8, **options
    )


def text_width(text: str, fontsize: float) -> float:
    """The width in inches of one line of text drawn in the figures' font (DejaVu Sans) at ``fontsize`` points."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import TextPath

    if not text.strip():
        return 0.0
    return TextPath((0, 0), text, size=fontsize, prop=FontProperties(family="DejaVu Sans")).get_extents().x1 / 72


MEASURE_SLACK_EM = 2.0
"""How far (in ems of the font size) a line's quick width estimate (:func:`estimated_width`) must stay below a width
for :func:`wider_than` to take it as narrower without measuring it. The estimate, the FreeType layout's box, came
within 0.55 em of the measured ink width on every string of the reports' words tried, above or below."""


def estimated_width(text: str, fontsize: float) -> float:
    """The width in inches of one line of text in the figures' font by FreeType's layout box: tens of times faster
    than :func:`text_width`'s outlines, and not the ink's extent."""
    from matplotlib.font_manager import FontProperties, findfont, get_font

    font = get_font(findfont(FontProperties(family="DejaVu Sans")))
    font.set_size(fontsize, 72)
    font.set_text(text, 0.0)
    return font.get_width_height()[0] / 64 / 72


def wider_than(text: str, width_inches: float, fontsize: float) -> bool:
    """``text_width(text, fontsize) > width_inches``, measured only where the quick estimate comes within
    :data:`MEASURE_SLACK_EM` of that width (a line well inside it needs no measuring)."""
    if estimated_width(text, fontsize) < width_inches - MEASURE_SLACK_EM * fontsize / 72:
        return False
    return text_width(text, fontsize) > width_inches


def wrap_to_width(text: str, width_inches: float, fontsize: float) -> str:
    """Wrap each line of ``text`` at word boundaries so that no line is wider than ``width_inches`` when drawn at
    ``fontsize`` (measured in the figures' font, not estimated); a single word wider than that stays whole."""
    lines = []
    for paragraph in text.split("\n"):
        line = ""
        for word in paragraph.split(" "):
            candidate = f"{line} {word}" if line else word
            if line and wider_than(candidate, width_inches, fontsize):
                lines.append(line)
                line = word
            else:
                line = candidate
        lines.append(line)
    return "\n".join(lines)


def fixed_decimals(values: Sequence[float], significant: int = 2, most: int = 4) -> int:
    """Decimals of one number format for every number of a figure: enough for ``significant`` digits of the
    smallest non-zero value, at most ``most``.

    Parameters
    ----------
    values : sequence of float
    significant : int
    most : int

    Returns
    -------
    int
    """
    import math

    sizes = [abs(float(v)) for v in values if v and math.isfinite(v)]
    if not sizes:
        return 0
    return int(min(most, max(0, significant - 1 - math.floor(math.log10(min(sizes))))))


def basis_colour(basis: str) -> str:
    return BASIS_COLOURS.get(basis, "#555555")


def basis_label(basis: str) -> str:
    return BASIS_LABELS.get(basis, basis)


def shown_format(figure: Figure) -> str:
    """The format a report shows a figure in: ``webp`` (lossless) for rendered faces, ``svg`` for line plots."""
    return "webp" if is_raster(figure) else "svg"


def save_figure(figure: Figure, folder: Path, stem: str, formats: Sequence[str] = ()) -> list[Path]:
    """Write a figure as ``<folder>/<stem>.<format>``: its own format (:func:`shown_format`) first, then each of
    ``formats``.

    Parameters
    ----------
    figure : matplotlib.figure.Figure
    folder : pathlib.Path
    stem : str
        File name without extension.
    formats : sequence of str
        Copies besides the shown file: any of ``png``, ``svg``, ``pdf``. A figure of rendered faces gets no vector
        copy (it would only wrap the raster).

    Returns
    -------
    list of pathlib.Path
        The files written, the shown one first.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    raster = is_raster(figure)
    wanted = [shown_format(figure), *(fmt for fmt in formats if not (raster and fmt in ("svg", "pdf")))]
    written, rendered = [], None
    for fmt in dict.fromkeys(wanted):
        path = inside(folder, f"{stem}.{fmt}")
        if fmt in ("png", "webp"):
            dpi = RENDER_DPI if raster else PNG_DPI
            rendered = rendered or drawn_png(figure, dpi)  # drawn once: copies have the same pixels
            data = lossless_bytes(rendered, fmt)
        else:
            buffer = io.BytesIO()
            with matplotlib.rc_context(SVG_RC):
                figure.savefig(buffer, format=fmt, dpi=PNG_DPI, metadata={"Date": None} if fmt == "svg" else None)
            data = compact_svg(buffer.getvalue()) if fmt == "svg" else buffer.getvalue()
        write_atomic(path, data)  # a killed report leaves whole figures or none
        written.append(path)
    return written


def shorter_numbers(svg: bytes, decimals: int = 2, path_decimals: int = 1) -> bytes:
    """An SVG with the numbers of its attributes (coordinates, transforms) cut to ``decimals`` decimals, those of
    path data (``d``, the lines' points) to ``path_decimals``, its text left as it is: matplotlib writes six, a
    millionth of a point; a hundredth (3.5 micrometres on paper) is as sharp at any zoom and the file a third
    smaller, and a tenth of a point moves a line's corner by an eighth of a screen pixel. Widths and opacities keep
    two decimals."""
    import re

    number = re.compile(rb"(\d\.\d{%d})\d+" % decimals)
    path_number = re.compile(rb"(\d\.\d{%d})\d+" % path_decimals)
    svg = re.sub(rb' d="[^"]*"', lambda value: path_number.sub(rb"\1", value.group(0)), svg)
    return re.sub(rb'="[^"]*"', lambda value: number.sub(rb"\1", value.group(0)), svg)


def compact_svg(svg: bytes) -> bytes:
    """An SVG as matplotlib writes it, without what a browser does not need: numbers cut (:func:`shorter_numbers`),
    the indentation between elements and inside path data, comments, and the ids nothing refers to (every group has
    one). What it draws is unchanged."""
    import re

    svg = re.sub(rb"<!--.*?-->", b"", shorter_numbers(svg), flags=re.S)
    svg = re.sub(rb">\n\s*<", b"><", svg)  # indentation only: whitespace within a line of text stays
    svg = re.sub(rb' d="[^"]*"', lambda path: re.sub(rb"\s*\n\s*", b" ", path.group(0)), svg)
    referred = set(re.findall(rb"#([\w.-]+)", svg))
    svg = re.sub(rb' id="([^"]+)"', lambda found: found.group(0) if found.group(1) in referred else b"", svg)
    return shared_styles(svg)


def shared_styles(svg: bytes) -> bytes:
    """An SVG whose inline styles that recur (every marker, tick and bar repeats its own) are classes of one style
    sheet instead: the same rules on the same elements, a class selector outranking matplotlib's ``*`` rule as the
    inline style did. Elements that already have a class keep their inline style."""
    import re
    from collections import Counter

    found = Counter(re.findall(rb'<[^>]* style="([^"]*)"', svg))
    recurring = sorted(style for style, count in found.items() if count > 1)
    if not recurring or b" class=" in svg:
        return svg
    names = {style: b"s%d" % number for number, style in enumerate(recurring)}
    svg = re.sub(
        rb' style="([^"]*)"',
        lambda match: b' class="%s"' % names[match.group(1)] if match.group(1) in names else match.group(0),
        svg,
    )
    sheet = b"<style>" + b"".join(b".%s{%s}" % (names[style], style) for style in recurring) + b"</style>"
    opening = re.search(rb"<svg[^>]*>", svg)
    return svg[: opening.end()] + sheet + svg[opening.end() :]


def is_raster(figure: Figure) -> bool:
    """Whether a figure is shown as pixels: it shows rendered images (faces), or it was marked so
    (:func:`shown_as_pixels`), rather than lines and points only."""
    return getattr(figure, "shown_as_pixels", False) or any(ax.images for ax in figure.axes)


def shown_as_pixels(figure: Figure) -> Figure:
    """Mark a chart that is no line plot (bars with a label each, hundreds of them) to be shown as a lossless
    WebP: as SVG, every label and bar is an element of its own and the file is several times larger."""
    figure.shown_as_pixels = True
    return figure


def raster_bytes(figure: Figure, fmt: str = "png", *, dpi: int = PNG_DPI) -> bytes:
    """A full-colour, lossless PNG or WebP of a figure, without metadata that changes between rebuilds."""
    return lossless_bytes(drawn_png(figure, dpi), fmt)


def drawn_png(figure: Figure, dpi: int) -> bytes:
    """The figure drawn as matplotlib writes a PNG (a WebP is made from it: :func:`lossless_bytes`), without
    metadata that changes between rebuilds."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi, metadata={"Software": None})
    return buffer.getvalue()


def lossless_bytes(png: bytes, fmt: str) -> bytes:
    """A PNG as matplotlib writes it (:func:`drawn_png`), or the same pixels as a lossless WebP (a few times smaller
    for renders). The PNG is not compressed again: PIL's ``optimize`` made a report's PNG copies 2-5 % smaller in
    five times the time (4.9 s against 0.95 s for the 13 figures of a synthetic run's report)."""
    if fmt != "webp":
        return png
    from PIL import Image

    smaller = io.BytesIO()
    # lossless; quality is the effort here (the last few percent cost ten times the time)
    Image.open(io.BytesIO(png)).convert("RGB").save(smaller, format="webp", lossless=True, quality=50, method=4)
    return smaller.getvalue()
