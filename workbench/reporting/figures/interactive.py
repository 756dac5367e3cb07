"""Faces you can turn: a self-contained interactive 3-D view of captured and reconstructed frames for the HTML
report, and a short animation of captured | H | QE over a stretch of the take.

The view is a small WebGL viewer of the workbench's own (no library): the captured frame and its reconstruction side by side
under one camera (drag to turn both, scroll to zoom), a frame and a basis picked from menus, plain shaded or
coloured by displacement and error with colour bars. Everything it needs is in the report folder: the viewer's
script (``workbench/reporting/report/static/view3d.js``, with the markup of ``templates/view3d.html``) inline in
``index.html`` and the mesh data in ``figures/view3d.js``, a classic script, so the page works
from ``file://`` after the folder is copied anywhere, with no network. The data: vertex displacements quantised
to 0.05 mm (invisible at face scale), a reconstruction stored as its offset from the captured frame, their bytes
split into planes (low bytes, then high bytes: the high ones are mostly equal and compress well), zlib-compressed
and decoded in the browser by ``DecompressionStream``; colours are computed in the page from the displacements.
"""

from __future__ import annotations

import base64
import json
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from workbench.core.files import write_atomic

DATA_FILE = "view3d.js"
STEP_MM = 0.05  # quantisation of the displacements in the page
COLOUR_LEVELS = 64  # entries of each colour map sent to the page


@dataclass(frozen=True)
class ViewFrame:
    """One frame the view can show: captured, and reconstructed with each basis.

    Attributes
    ----------
    label : str
        Why it is shown, take, frame number and time.
    captured : ndarray of shape (3 * n_vertices,)
        Captured displacement.
    reconstructed : mapping
        Basis label -> ndarray of shape (3 * n_vertices,), the reconstructed displacement.
    notes : mapping
        Basis label -> text shown with the reconstruction (its alpha on this frame).
    """

    label: str
    captured: np.ndarray
    reconstructed: Mapping[str, np.ndarray]
    notes: Mapping[str, str]


def _packed(array: np.ndarray) -> str:
    return base64.b64encode(zlib.compress(np.ascontiguousarray(array).tobytes(), 9)).decode("ascii")


def byte_planes(values: np.ndarray) -> np.ndarray:
    """The bytes of little-endian int16 values as two planes, every low byte first, then every high byte."""
    return np.ascontiguousarray(values.view(np.uint8).reshape(-1, 2).T).ravel()


def _quantised(displacement: np.ndarray) -> str:
    return _packed(byte_planes(np.round(np.asarray(displacement) / STEP_MM).astype("<i2")))


def colour_table(cmap: str, levels: int = COLOUR_LEVELS) -> str:
    """A matplotlib colour map sampled at ``levels`` points, as hex RGB (6 characters each), for the page."""
    from matplotlib import colormaps

    rgb = np.round(255 * colormaps[cmap](np.linspace(0.0, 1.0, levels))[:, :3]).astype(int)
    return "".join(f"{r:02x}{g:02x}{b:02x}" for r, g, b in rgb)


def view_payload(
    neutral: np.ndarray,
    faces: np.ndarray,
    frames: Sequence[ViewFrame],
    *,
    bases: Mapping[str, str],
    displacement_range: tuple[float, float, bool],
    error_range: tuple[float, float, bool],
    cmaps: tuple[str, str],
    weight: np.ndarray | None = None,
    title: str = "",
    plain_colour: str = "#cfc6be",
) -> dict:
    """The data of the interactive view, ready for JSON.

    Parameters
    ----------
    neutral : ndarray of shape (3 * n_vertices,)
    faces : ndarray of shape (n_faces, 3) of int
    frames : sequence of ViewFrame
        In the order the menu lists them.
    bases : mapping
        Basis label -> its name in the page (e.g. ``QE`` -> ``quasi-eigen E^QE (affine)``), in the menu's order;
        every frame has a reconstruction for each.
    displacement_range, error_range : (float, float, bool)
        Colour range of the captured displacement length and of the reconstruction error, and whether the data go
        beyond it (the colour bar then shows an arrow).
    cmaps : (str, str)
        Matplotlib colour maps of the displacement and of the error.
    weight : ndarray of shape (n_vertices,) in [0, 1], optional
        Share of colour at each vertex: 0 where the capture has no data (shown plain, as geometry).
    title : str
    plain_colour : str
        The plain shade.

    Returns
    -------
    dict
        ``neutral`` (float32), ``faces`` (uint16 below 65,536 vertices, else uint32; see ``faces_bytes``),
        ``weight`` (uint8 or null), per frame ``captured`` and per basis its offset from the captured frame (int16
        in units of ``step``, as :func:`byte_planes`), each zlib-compressed and base64-encoded; ``loops``: the
        mesh's openings (eyes, mouth), closed by dark caps in the page.
    """
    from workbench.reporting.figures.render import hole_loops

    faces = np.asarray(faces)
    wide = faces.max() >= 2**16
    return {
        "title": title,
        "step": STEP_MM,
        "n_vertices": int(np.asarray(neutral).size // 3),
        "neutral": _packed(np.asarray(neutral, dtype="<f4")),
        "faces": _packed(faces.astype("<u4" if wide else "<u2")),
        "faces_bytes": 4 if wide else 2,
        "loops": [loop.tolist() for loop in hole_loops(faces)],
        "weight": None if weight is None else _packed(np.round(255 * np.clip(weight, 0, 1)).astype(np.uint8)),
        "bases": [{"key": key, "name": name} for key, name in bases.items()],
        "frames": [
            {
                "label": frame.label,
                "captured": _quantised(frame.captured),
                "shown": {key: _quantised(np.asarray(frame.reconstructed[key]) - frame.captured) for key in bases},
                "notes": {key: frame.notes.get(key, "") for key in bases},
            }
            for frame in frames
        ],
        "displacement": {
            "clim": list(displacement_range[:2]),
            "beyond": bool(displacement_range[2]),
            "colours": colour_table(cmaps[0]),
        },
        "error": {"clim": list(error_range[:2]), "beyond": bool(error_range[2]), "colours": colour_table(cmaps[1])},
        "plain": plain_colour,
    }


def write_view_data(path: Path, payload: dict) -> Path:
    """Write the view's data as a classic script (``window.WORKBENCH_VIEW = {...};``), loadable from file://."""
    write_atomic(path, "window.WORKBENCH_VIEW = " + json.dumps(payload, separators=(",", ":")) + ";\n")
    return path


ANIMATION_WIDTH = 960
"""Smallest width of the animation in pixels: its labels stay readable when a page shows it at full size."""


def colour_bar_strip(width: int, cmap: str, clim: tuple[float, float], extend: str, label: str) -> np.ndarray:
    """A horizontal colour bar with ticks and label as an RGB image ``width`` pixels wide."""
    import io

    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure
    from PIL import Image

    figure = Figure(figsize=(width / 100, 0.82), dpi=100)
    ax = figure.add_axes((0.06, 0.62, 0.86, 0.3))
    bar = figure.colorbar(ScalarMappable(Normalize(*clim), cmap), cax=ax, orientation="horizontal", extend=extend)
    bar.ax.tick_params(labelsize=12)
    bar.set_label(label, fontsize=13)
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=100)
    return np.asarray(Image.open(buffer).convert("RGB"))


def write_animation(
    path: Path,
    panels: Sequence[Sequence[np.ndarray]],
    titles: Sequence[str],
    captions: Sequence[str],
    *,
    fps: float,
    speed: str,
    colour: tuple[str, tuple[float, float], str, str] | None = None,
    quality: int = 45,
) -> Path:
    """A looping animated WebP of several panels side by side, one image per time step, with each panel's title, the
    frame shown, the playback speed and a colour bar under the coloured panels, at least
    :data:`ANIMATION_WIDTH` pixels wide in type a reader can read.

    Parameters
    ----------
    path : pathlib.Path
    panels : sequence of sequence of ndarray of shape (height, width, 3) of uint8
        ``panels[p][t]``: panel p at time step t; all the same size. Panels after the first are the coloured ones.
    titles : sequence of str
        One per panel, written above it.
    captions : sequence of str
        One per time step (take, frame and time), written under the first panel.
    fps : float
        Time steps per second of the animation.
    speed : str
        The playback speed in words (``real time: 15 frames per second``), written under the caption.
    colour : (cmap, (low, high), extend, label), optional
        The colour bar under the coloured panels.
    quality : int
        WebP quality (lossy: full colour, no palette).
    """
    import io

    from matplotlib import font_manager
    from PIL import Image, ImageDraw, ImageFont

    height, width = panels[0][0].shape[:2]
    gap = max(16, (ANIMATION_WIDTH - len(panels) * width) // (len(panels) + 1))
    canvas_width = max(ANIMATION_WIDTH, len(panels) * width + (len(panels) + 1) * gap)
    title_band, bottom_band = 40, 96
    font_file = font_manager.findfont("DejaVu Sans")
    title_font, text_font = ImageFont.truetype(font_file, 21), ImageFont.truetype(font_file, 16)
    base = Image.new("RGB", (canvas_width, title_band + height + bottom_band), "white")
    draw = ImageDraw.Draw(base)
    for p, title in enumerate(titles):
        centre = gap + p * (width + gap) + width // 2
        draw.text((centre, title_band // 2 + 4), title, fill="black", font=title_font, anchor="mm")
    if colour is not None and len(panels) > 1:
        cmap, clim, extend, label = colour
        left = 2 * gap + width
        strip = colour_bar_strip(canvas_width - left - gap // 2, cmap, clim, extend, label)
        base.paste(Image.fromarray(strip), (left, title_band + height + 4))
    frames = []
    for t, caption in enumerate(captions):
        frame = base.copy()
        for p, images in enumerate(panels):
            frame.paste(Image.fromarray(images[t]), (gap + p * (width + gap), title_band))
        draw = ImageDraw.Draw(frame)
        draw.text((gap, title_band + height + 14), caption, fill="black", font=text_font)
        draw.text((gap, title_band + height + 44), speed, fill="#333333", font=text_font)
        frames.append(frame)
    buffer = io.BytesIO()
    # every frame a key frame: a lossy frame that updates only part of the last one leaves block seams on the face
    frames[0].save(
        buffer,
        format="webp",
        save_all=True,
        append_images=frames[1:],
        duration=round(1000 / fps),
        loop=0,
        quality=quality,
        method=4,
        kmin=1,
        kmax=1,
    )
    write_atomic(path, buffer.getvalue())
    return path
