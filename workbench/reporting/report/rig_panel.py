"""Pose the rigs: a report panel where the H rig and the QE rigs (at the coverage rule's m and at m = n) are posed
with the same sliders, one per hand shape, and the capture is played through them.

Each rig is the ``.glb`` :func:`workbench.api.write_rig` and ``workbench export`` write (one writer,
:func:`workbench.reporting.export.rig.rig_mesh`), without animations: one morph target per shape, on the mesh decimated
to about :data:`PANEL_VERTICES` vertices; the weights the run's solver found for at most :data:`PANEL_KEYS` of the
evaluated frames travel beside it (the export's ``_over``/``_neg`` targets, which keep Blender's sliders in [0, 1],
would double or triple a QE rig's bytes, and three.js does not clamp a morph target's weight). Each ``.glb`` is
zlib-compressed and base64-encoded in a classic script (``figures/rigs.js``), since a page opened from ``file://``
may not fetch files; three.js (vendored as ``static/three.min.js`` with its licence, built by
``static/three-build.sh``) parses it with its ``GLTFLoader`` and draws its morph targets.
"""

from __future__ import annotations

import base64
import json
import os
import zlib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from workbench.core.files import write_atomic
from workbench.record.record import RunRecord

PANEL_VERTICES = 1000
"""The panel's mesh is decimated to about this many vertices (kept where they are: each is the run's own vertex)."""
PANEL_KEYS = 120
"""At most this many evaluated frames, spread evenly, on the panel's timeline."""
STEP_MM = 0.05
"""Quantisation of the captured frames' displacements in the page (invisible at face scale)."""
DATA_FILE, LIBRARY_FILE, LICENCE_FILE = "rigs.js", "three.min.js", "three-LICENSE.txt"
CAPTION = (
    "The H rig and the QE rig posed with the same sliders, one per hand shape, under one camera (drag to turn, "
    "scroll to zoom). Solo sets one shape to 1 and the rest to 0: the paper's figure 2, live. Both faces are "
    "coloured by how far the QE face lies from the H face at each vertex. The timeline plays the run's frames "
    "through the rigs with the weights each rig's solver found, beside the captured frame, with each face's error "
    "on that frame and the weight curves of the shape last touched. The rigs are glTF files as the export writes "
    "them (one morph target per shape) on a decimated mesh; everything is in this folder and works from the file."
)


@dataclass
class RigPanel:
    """The panel's files (HTML only), or why it is missing."""

    data: str = ""
    library: str = ""
    caption: str = CAPTION
    missing: str = ""

    def page_block(self, markdown: bool) -> dict:
        """The block the report's templates read (:func:`workbench.reporting.report.page.page_sections`)."""
        return {
            "kind": "rigs",
            "data": self.data,
            "library": self.library,
            "caption": self.caption,
            "missing": self.missing,
        }


def with_rig_panel(sections: list, record: RunRecord, out: Path, cache: dict, shared: Path | None = None) -> list:
    """``sections`` with "Pose the rigs" after "Faces you can turn" (or at the end), for runs with faces to draw;
    ``shared`` as :func:`build_rig_panel`."""
    from workbench.reporting.report.sections import Section

    panel = build_rig_panel(record, out, cache, shared)
    if panel is None:
        return sections
    headings = [section.heading for section in sections]
    at = headings.index("Faces you can turn") + 1 if "Faces you can turn" in headings else len(sections)
    return [*sections[:at], Section("Pose the rigs", [panel]), *sections[at:]]


def build_rig_panel(record: RunRecord, out: Path, cache: dict, shared: Path | None = None) -> RigPanel | None:
    """Write ``figures/rigs.js`` and ``figures/three.min.js`` for a run with faces to draw: a mesh data variant, or
    a marker variant carried onto the dataset's face mesh (:func:`workbench.reporting.report.data.face_data`, as the
    other face figures draw a run on markers); None when it has neither.

    Parameters
    ----------
    record : RunRecord
    out : pathlib.Path
        The report folder.
    cache : dict
        Arrays shared with the figures.
    shared : pathlib.Path, optional
        The folder the reference reports share (``reports/shared``, ``--reference``): three.js goes there once, as
        figure 1 does, instead of into each report's ``figures/``.
    """
    from workbench.reporting.report.data import face_data

    face = face_data(record, cache)
    if isinstance(face, str):
        return None
    payload = rig_payload(record, face, cache)
    figures = out / "figures"
    write_atomic(figures / DATA_FILE, "window.WORKBENCH_RIGS = " + json.dumps(payload, separators=(",", ":")) + ";\n")
    library = figures if shared is None else Path(shared)
    library.mkdir(parents=True, exist_ok=True)
    for name in (LIBRARY_FILE, LICENCE_FILE):  # three.js and its licence, beside the page that loads it
        with resources.as_file(resources.files("workbench.reporting.report") / "static" / name) as source:
            write_atomic(library / name, source.read_bytes())
    more = face.caption("the weights, alpha and errors are the markers' own")
    return RigPanel(
        data=f"figures/{DATA_FILE}",
        library=Path(os.path.relpath(library / LIBRARY_FILE, out)).as_posix(),
        caption=f"{CAPTION} {more}" if more else CAPTION,
    )


def panel_keys(complete: np.ndarray, n_keys: int = PANEL_KEYS) -> np.ndarray:
    """Rows of the evaluated frames on the timeline: at most ``n_keys`` of the complete ones, spread evenly."""
    rows = np.flatnonzero(complete)
    return rows[np.unique(np.linspace(0, len(rows) - 1, min(n_keys, len(rows))).round().astype(int))]


def panel_rigs(record: RunRecord, data: str, inputs, cache: dict) -> list[tuple[str, str, np.ndarray]]:
    """``(key, label, shapes)`` of the rigs shown: H, the run's QE and, in the paper's regime, QE at m = n."""
    from workbench.reporting.report.data import figure_bases, qe_label, record_inputs
    from workbench.study.regime import coverage_rule_name, paper_regime_name

    qe = qe_label(record)
    coverage, regime = coverage_rule_name(data), paper_regime_name(coverage_rule_name(data))
    found = {data: inputs}
    for variant in (coverage, regime):
        if variant not in found and variant in record.data_variants:
            found[variant] = record_inputs(record, variant, cache)
    same_frames = {v: i for v, i in found.items() if i is not None and len(i["eval"]) == len(inputs["eval"])}
    rigs = []
    if coverage in same_frames:
        bases = figure_bases(record, coverage, same_frames[coverage], cache)
        m = len(same_frames[coverage]["components"])  # the eigenfaces the coverage rule kept
        rigs += [("H", "H, the hand shapes", bases["H"]), (qe, f"{qe} at the coverage rule (m = {m})", bases[qe])]
    if regime in same_frames:
        bases = figure_bases(record, regime, same_frames[regime], cache)
        if not rigs:
            rigs.append(("H", "H, the hand shapes", bases["H"]))
        rigs.append((f"{qe} m=n", f"{qe} at m = n (m = {len(inputs['hand'])})", bases[qe]))
    return rigs


def run_solvers(config) -> dict:
    """Solver name -> keyword arguments of :func:`workbench.numerics.solve.solve_weights`, every solver the run
    had, the figures' solver first (lstsq when the run had it)."""
    from workbench.reporting.report.data import figure_solver
    from workbench.settings.schema import SolverSchema
    from workbench.settings.typed import solver_options, typed

    first, options = figure_solver(config)
    rest = {name: solver_options(typed(SolverSchema, config["solver"][name])) for name in config["solver"]}
    return {first: options, **{name: value for name, value in rest.items() if name != first}}


def rig_payload(record: RunRecord, face, cache: dict) -> dict:
    """The data of the panel, ready for JSON: each rig's ``.glb`` (compressed), the shapes' names and slider
    ranges, the timeline's frames with each rig's error and the captured frames (quantised)."""
    from workbench.dataset.decimate import decimate
    from workbench.numerics.solve import solve_weights
    from workbench.reporting.export.bases import ExportedBasis
    from workbench.reporting.export.rig import rig_bytes
    from workbench.reporting.figures.faces import ERROR_CMAP
    from workbench.reporting.figures.interactive import byte_planes, colour_table
    from workbench.reporting.figures.render import PLAIN_COLOUR
    from workbench.reporting.report.data import frame_alpha, record_timeline, short_label

    data, inputs = face.data, face.inputs
    solvers = run_solvers(record.config)
    names = [str(name) for name in inputs["hand_names"]]
    timeline = record_timeline(record, inputs)
    keys = panel_keys(np.isfinite(inputs["eval"]).all(axis=1))
    captured = inputs["eval"][keys]
    points = face.neutral.reshape(-1, 3)
    mesh = decimate(points, face.faces, min(1.0, PANEL_VERTICES / len(points)))
    rows = (3 * mesh.kept[:, None] + np.arange(3)).ravel()
    rigs, ranges, difference = [], [], []
    for key, label, shapes in panel_rigs(record, data, inputs, cache):
        shape_names = tuple(names) + tuple(f"pca_{i}" for i in range(len(names) + 1, len(shapes) + 1))
        basis = ExportedBasis(
            label=key.replace(" ", "_").replace("=", ""),
            names=shape_names,
            shapes=face.carry(shapes)[:, rows],  # a marker variant's shapes carried onto the mesh
            weights=np.zeros((1, len(shapes))),  # a rig without animations: one target per shape
            solver="none",
            alpha={},
            sculpted=tuple(i < len(names) for i in range(len(shapes))),
        )
        glb = rig_bytes(basis, points[mesh.kept], mesh.faces, (), {"units": "metres", "run": record.folder.name})
        weights, errors = {}, {}
        for solver, options in solvers.items():
            found = solve_weights(shapes, captured, **options).weights
            alpha = frame_alpha(inputs["neutral"], captured, found @ shapes)
            weights[solver] = [[float(f"{w:.9g}") for w in row] for row in found]
            errors[solver] = {
                "alpha": np.round(alpha["absolute"], 4).tolist(),
                "rms": np.round(alpha["rms"], 4).tolist(),
            }
            ranges.append(np.stack([found[:, : len(names)].min(axis=0), found[:, : len(names)].max(axis=0)]))
        difference.append(face.carry(shapes[: len(names)])[:, rows])
        rigs.append(
            {
                "key": key,
                "label": label,
                "targets": list(shape_names),
                "weights": weights,
                "errors": errors,
                "glb": base64.b64encode(zlib.compress(glb, 9)).decode("ascii"),
            }
        )
    low = np.minimum(0.0, np.min([r[0] for r in ranges], axis=0))
    high = np.maximum(1.0, np.max([r[1] for r in ranges], axis=0))
    solo = np.linalg.norm((difference[1] - difference[0]).reshape(len(names), -1, 3), axis=2)
    quantised = np.round(face.carry(captured)[:, rows] / STEP_MM).astype("<i2")
    return {
        "title": f"{short_label(record)}; data {data}",
        "solvers": list(solvers),
        "shapes": list(names),
        "ranges": [[float(a), float(b)] for a, b in zip(low, high)],
        "rigs": rigs,
        "n_vertices": int(len(mesh.kept)),
        "kept": mesh.kept.tolist(),
        "step": STEP_MM,
        "captured": base64.b64encode(zlib.compress(byte_planes(quantised.ravel()).tobytes(), 9)).decode("ascii"),
        "timeline": {
            "rows": keys.tolist(),
            "take": [str(timeline.take[k]) for k in keys],
            "frame": [int(timeline.frame[k]) for k in keys],
            "seconds": [round(float(timeline.seconds[k]), 6) for k in keys],
        },
        "difference": {"clim": [0.0, float(np.percentile(solo, 99.5)) or 1.0], "colours": colour_table(ERROR_CMAP)},
        "plain": PLAIN_COLOUR,
    }
