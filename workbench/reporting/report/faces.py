"""Faces you can turn in a run's report: the interactive 3-D view's data (``figures/view3d.js``) and the animation
(``figures/animation.webp``) of the run's mesh variant."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from workbench.record.record import RunRecord
from workbench.reporting.report.data import (
    FaceData,
    face_data,
    figure3_frames,
    figure_bases,
    figure_solver,
    frame_alpha,
    frame_caption,
    moving_stretch,
    qe_label,
    reconstruct_frames,
    record_timeline,
    short_label,
)
from workbench.reporting.report.run_figures import needs

VIEW_CAPTION = (
    "Figure 3's frames you can turn (drag; scroll to zoom): the captured frame (left) beside its "
    "reconstruction with the basis you pick (right), both under one camera; coloured by the captured "
    "displacement and by the per-vertex error (one error scale for every basis and frame), or plain "
    "shaded. Regions without data are shown as plain geometry. Everything the view needs is in this "
    "report's folder: it works from the file, with no network, wherever the folder is copied."
)
VIEW_VERTICES = 4000
"""The interactive view's mesh is decimated to about this many vertices (kept at their places, so every value
shown is the run's own at that vertex): enough for a face at screen size, and half the data of the ICT face."""
BASIS_NAMES = {
    "H": "H, the hand shapes",
    "QE": "QE, quasi-eigen faces (affine projection)",
    "QE-linear": "QE-linear, quasi-eigen faces (linear projection)",
    "PCA": "PCA, the m eigenfaces",
}


@dataclass
class FacesBlock:
    """The interactive 3-D view (its data script ``view``, HTML only) and the animation (both documents), or why
    they are missing."""

    view: str = ""
    animation: str = ""
    caption: str = ""
    missing: str = ""
    view_caption: str = VIEW_CAPTION


def build_faces(record: RunRecord, out: Path, cache: dict, seconds: float = 2.0, most_fps: float = 10.0) -> FacesBlock:
    """Write the interactive view's data (``figures/view3d.js``) and the animation (``figures/animation.webp``) of a
    run's mesh variant.

    Parameters
    ----------
    record : RunRecord
    out : pathlib.Path
        The report folder.
    cache : dict
        Arrays shared with the figures.
    seconds : float
        Length of the animation: the stretch of a take where the face moves most, played in real time.
    most_fps : float
        Frames of a faster capture are skipped down to about this rate (fewer frames: a smaller file).
    """
    from workbench.reporting.figures.interactive import DATA_FILE

    face = face_data(record, cache)
    if isinstance(face, str):
        return FacesBlock(missing=needs(face, cache))
    write_view(record, face, out / "figures" / DATA_FILE, cache)
    caption = write_moving_faces(record, face, out / "figures" / "animation.webp", cache, seconds, most_fps)
    more = face.caption("the alphas of the bases are the markers' own")
    return FacesBlock(
        view=f"figures/{DATA_FILE}",
        animation="animation.webp",
        caption=f"{caption} {more}" if more else caption,
        view_caption=f"{VIEW_CAPTION} {more}" if more else VIEW_CAPTION,
    )


def write_view(record: RunRecord, face: FaceData, path: Path, cache: dict) -> None:
    """The interactive view's data: figure 3's frames, captured and reconstructed with every basis, on the mesh
    decimated to about :data:`VIEW_VERTICES` vertices (weights and alpha on the variant's own points; what is
    drawn carried onto the mesh when the variant is markers)."""
    from workbench.dataset.decimate import decimate
    from workbench.reporting.figures import fixed_decimals
    from workbench.reporting.figures.faces import DISPLACEMENT_CMAP, ERROR_CMAP, colour_range, masked, point_norms
    from workbench.reporting.figures.interactive import ViewFrame, view_payload, write_view_data
    from workbench.reporting.figures.render import PLAIN_COLOUR, support_weight

    data, inputs, support = face.data, face.inputs, face.support
    solver_name, solver = figure_solver(record.config)
    weight = support_weight(face.neutral, support)
    timeline = record_timeline(record, inputs)
    chosen = figure3_frames(record, inputs)
    captured = inputs["eval"][[frame for _, frame in chosen]]
    shown = {
        name: reconstruct_frames(shapes, captured, solver)
        for name, shapes in figure_bases(record, data, inputs, cache, every=True).items()
    }
    mean, components = inputs["mean"], inputs["components"]
    shown["PCA"] = mean + ((captured - mean) @ components.T) @ components
    alphas = {name: frame_alpha(inputs["neutral"], captured, frames_out) for name, frames_out in shown.items()}
    captured, shown = face.carry(captured), {name: face.carry(frames_out) for name, frames_out in shown.items()}
    decimals = fixed_decimals([a for alpha in alphas.values() for a in alpha["absolute"]], significant=3)
    lengths = colour_range([masked(values, support) for values in point_norms(captured)], percentile=99.5)
    errors = colour_range(
        [masked(values, support) for frames_out in shown.values() for values in point_norms(frames_out - captured)],
        percentile=99.5,
    )
    # the view's mesh: about VIEW_VERTICES of the vertices, kept where they are (a decimation selects rows)
    points = face.neutral.reshape(-1, 3)
    mesh = decimate(points, face.faces, min(1.0, VIEW_VERTICES / len(points)))
    rows = (3 * mesh.kept[:, None] + np.arange(3)).ravel()
    view_frames = [
        ViewFrame(
            frame_caption(region, timeline, frame),
            captured[i][rows],
            {name: frames_out[i][rows] for name, frames_out in shown.items()},
            {
                name: f"alpha {alpha['absolute'][i]:.{decimals}f} % (abs.), solver "
                f"{'projection' if name == 'PCA' else solver_name}"
                for name, alpha in alphas.items()
            },
        )
        for i, (region, frame) in enumerate(chosen)
    ]
    write_view_data(
        path,
        view_payload(
            face.neutral[rows],
            mesh.faces,
            view_frames,
            bases={name: BASIS_NAMES.get(name, name) for name in shown},
            displacement_range=(lengths.low, lengths.high, lengths.extend != "neither"),
            error_range=(errors.low, errors.high, errors.extend != "neither"),
            cmaps=(DISPLACEMENT_CMAP, ERROR_CMAP),
            weight=None if weight is None else weight[mesh.kept],
            title=f"{short_label(record)}; data {data}" + (f"; {face.note}" if face.carried else ""),
            plain_colour=PLAIN_COLOUR,
        ),
    )


def write_moving_faces(
    record: RunRecord, face: FaceData, path: Path, cache: dict, seconds: float, most_fps: float
) -> str:
    """The animation: captured | H | QE over the stretch of the take where the face moves most, in real time.

    Returns
    -------
    str
        Its caption.
    """
    from workbench.reporting.figures.faces import ERROR_CMAP, colour_range, masked, point_norms
    from workbench.reporting.figures.interactive import write_animation
    from workbench.reporting.figures.render import MeshView, crop_background, render_meshes, support_weight

    data, inputs, support = face.data, face.inputs, face.support
    solver_name, solver = figure_solver(record.config)
    weight = support_weight(face.neutral, support)
    timeline = record_timeline(record, inputs)
    rate = float(record.metrics["dataset"]["frame_rate"])
    stretch = moving_stretch(inputs, timeline, int(round(seconds * rate)))
    step = max(1, int(round(rate / most_fps)))
    steps = stretch[::step]
    seen = np.isfinite(inputs["eval"][steps]).all(axis=1)
    skipped = int((~seen).sum()) if seen.any() else 0  # frames missing a marker (gap_policy=masked) left out
    steps = steps[seen] if seen.any() else steps
    moving = inputs["eval"][steps]
    qe = qe_label(record)
    bases = figure_bases(record, data, inputs, cache)
    moved = {name: face.carry(reconstruct_frames(bases[name], moving, solver)) for name in ("H", qe)}
    moving = face.carry(moving)
    errors_moving = {
        name: [masked(values, support) for values in point_norms(frames_out - moving)]
        for name, frames_out in moved.items()
    }
    span = colour_range([values for per_frame in errors_moving.values() for values in per_frame], percentile=99.5)
    size = (420, 490)
    panels = [render_meshes(face.neutral + moving, face.faces, None, MeshView(window_size=size))]
    for name, frames_out in moved.items():
        panels.append(
            render_meshes(
                face.neutral + frames_out,
                face.faces,
                errors_moving[name],
                MeshView(cmap=ERROR_CMAP, clim=(span.low, span.high), window_size=size),
                weight,
            )
        )
    cropped = crop_background([image for panel in panels for image in panel])
    panels = [cropped[k * len(steps) : (k + 1) * len(steps)] for k in range(len(panels))]
    fps = rate / step
    speed = f"real time: {fps:.3g} frames per second"
    write_animation(
        path,
        panels,
        ["captured", "H (error)", f"{qe} (error)"],
        [timeline.label(int(frame)) for frame in steps],
        fps=fps,
        speed=speed,
        colour=(ERROR_CMAP, (span.low, span.high), span.extend, "reconstruction error per vertex (mm)"),
    )
    first, last = int(steps[0]), int(steps[-1])
    return (
        f"The {len(steps) / fps:.1f} s of the take where the face moves most "
        f"({timeline.take[first]}, t = {timeline.seconds[first]:.2f} to {timeline.seconds[last]:.2f} s), "
        f"played in {speed}: captured (plain shaded), and reconstructed with H and {qe} (solver "
        f"{solver_name}), coloured by the per-vertex error."
        + (f" {skipped} of its frames missed a marker and are left out." if skipped else "")
    )
