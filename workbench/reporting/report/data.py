"""What a run's report draws from besides its tables: the run's saved inputs, and the few arrays recomputed from
them with the core's own functions (the quasi-eigen basis of eq. 3-4, reconstructions with the run's solver), with
the record's labels, timelines and frame choices the figures share.

Figures 2-4 show a few frames and shapes; recomputing them from the saved inputs keeps records small. Nothing else
is recomputed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from workbench.dataset.capture import Timeline
from workbench.record.record import RunRecord

QE_PROJECTIONS = {"QE": "affine", "QE-linear": "linear"}


def quasi_eigen_shapes(
    inputs: Mapping[str, np.ndarray], projection: str, appended_axes: Sequence[int] = ()
) -> np.ndarray:
    """The run's quasi-eigen basis from its saved inputs (eq. 3-4), with any appended eigenfaces.

    Parameters
    ----------
    inputs : mapping
        ``hand`` (n_shapes, n_dims), ``mean`` (n_dims,), ``components`` (m, n_dims).
    projection : {"affine", "linear"}
    appended_axes : sequence of int
        1-based eigenface axes the post-treatment appended (``metrics.json``).

    Returns
    -------
    ndarray of shape (n_shapes + n_appended, n_dims)
    """
    from workbench.numerics.bases import pca_to_qe_weights, quasi_eigen_faces

    components, mean = inputs["components"], inputs["mean"]
    weights = pca_to_qe_weights(inputs["hand"], components, mean, projection)
    shapes = quasi_eigen_faces(weights, components, mean, projection)
    appended = [components[j - 1] for j in appended_axes]
    return np.vstack([shapes, *appended]) if appended else shapes


def figure_solver(config: Mapping) -> tuple[str, dict]:
    """The solver figures 2-4 use: ``lstsq`` when the run had it, else the first configured one."""
    from workbench.settings.schema import SolverSchema
    from workbench.settings.typed import solver_options, typed

    solvers = config["solver"]
    name = "lstsq" if "lstsq" in solvers else next(iter(solvers))
    return name, solver_options(typed(SolverSchema, solvers[name]))


def reconstruct_frames(shapes: np.ndarray, frames: np.ndarray, solver: Mapping) -> np.ndarray:
    """Reconstructions of some frames in a basis with the run's solver (eq. 5).

    Parameters
    ----------
    shapes : ndarray of shape (n_shapes, n_dims)
    frames : ndarray of shape (n_frames, n_dims)
        Captured displacements.
    solver : mapping
        Keyword arguments of :func:`workbench.numerics.solve.solve_weights`.

    Returns
    -------
    ndarray of shape (n_frames, n_dims)
    """
    from workbench.numerics.solve import reconstruct, solve_weights

    return reconstruct(shapes, solve_weights(shapes, frames, **solver).weights)


def frame_alpha(neutral: np.ndarray, captured: np.ndarray, reconstructed: np.ndarray) -> dict:
    """Per-frame absolute and displacement alpha (eq. 6) and RMS error of some frames.

    Parameters
    ----------
    neutral : ndarray of shape (n_dims,)
    captured, reconstructed : ndarray of shape (n_frames, n_dims)

    Returns
    -------
    dict
        ``absolute``, ``displacement``, ``rms`` : ndarray of shape (n_frames,).
    """
    from workbench.numerics.metrics import alpha_per_frame, rms_error

    squared = (captured - reconstructed) ** 2
    return {
        "absolute": alpha_per_frame(neutral + captured, neutral + reconstructed),
        "displacement": alpha_per_frame(captured, reconstructed),
        "rms": rms_error(squared.reshape(len(squared), -1, 3).sum(axis=2).sum(axis=1), squared.shape[1] // 3),
    }


def dataset_label(record: RunRecord) -> str:
    provenance = record.metrics["dataset"]["provenance"]
    if provenance.get("kind") == "synthetic":
        return "synthetic actor (generated, not real capture)"
    return record.metrics["dataset"]["name"]


SHORT_DATASET_LABELS = {
    "synthetic": "synthetic actor (generated)",
    "ict_livelink": "ICT FaceKit face, real Live Link Face take",
    "animface": "AnimFace capture, ICT FaceKit hand shapes (another face)",
}


def short_label(record: RunRecord) -> str:
    """The dataset in a few words, for figure titles."""
    kind = record.metrics["dataset"]["provenance"].get("kind")
    return SHORT_DATASET_LABELS.get(kind, record.metrics["dataset"]["name"])


def record_inputs(record: RunRecord, data: str, cache: dict) -> dict | None:
    """The arrays of a data variant's ``inputs.npz``: saved by the run (``save_inputs=true``), or, when the run
    saved none, rebuilt from its config (:func:`rebuilt_arrays`); None for a variant that has none (bases carried
    onto other points, held-out frames) or when the data cannot be had (:func:`missing_reason` says why)."""
    key = ("inputs", data)
    if key not in cache:
        saved = record.load_inputs(data)
        cache[key] = (
            saved if saved is not None or saved_inputs(record) else (rebuilt_arrays(record, cache)["inputs"].get(data))
        )
    return cache[key]


def record_alpha_per_frame(record: RunRecord, cache: dict) -> dict | None:
    """The arrays of ``alpha_per_frame.npz``: saved by the run, or rebuilt with its inputs when it saved none."""
    saved = record.load_alpha_per_frame()
    return saved if saved is not None or saved_inputs(record) else rebuilt_arrays(record, cache)["alpha_per_frame"]


def saved_inputs(record: RunRecord) -> bool:
    """Whether the run saved its inputs (``save_inputs=true``): then a variant without them truly has none."""
    return any(record.folder.glob("inputs*.npz"))


def missing_reason(cache: dict) -> str:
    """Why the inputs of a run that saved none could not be rebuilt (``""`` when they were, or were saved)."""
    return cache.get(("rebuilt",), {}).get("missing", "")


def rebuilt_arrays(record: RunRecord, cache: dict) -> dict:
    """A run's ``inputs.npz`` and ``alpha_per_frame.npz`` arrays, rebuilt by running its study again from the
    record's resolved config (the dataset cache makes the data cheap), checked against the record: the data files'
    checksums it names and every number of its alpha table.

    Returns
    -------
    dict
        ``inputs``: data variant -> arrays (those a run with ``save_inputs=true`` writes); ``alpha_per_frame``:
        arrays or None; ``missing``: why not, when the data cannot be had.

    Raises
    ------
    WorkbenchError
        When the rebuilt data differ from the data the run read.
    """
    from workbench.core.errors import WorkbenchError
    from workbench.record.replay import check_replayed
    from workbench.settings.typed import study_settings
    from workbench.study.run import run_study
    from workbench.study.summary import alpha_per_frame_arrays, input_arrays

    key = ("rebuilt",)
    if key not in cache:
        try:
            results = run_study(study_settings(record.config))
        except (WorkbenchError, OSError) as error:
            cache[key] = {
                "inputs": {},
                "alpha_per_frame": None,
                "missing": f"the run saved no inputs and its data could not be read again: {error}",
            }
            return cache[key]
        check_replayed(record, results, "the report cannot rebuild the run's inputs")
        cache[key] = {
            "inputs": {
                result.data: input_arrays(result)
                for result in results
                if result.transfer == "identity" and result.protocol == "training frames"
            },
            "alpha_per_frame": alpha_per_frame_arrays(results),
            "missing": "",
        }
    return cache[key]


def figure_order(variants: Sequence[str], preferred: str) -> list[str]:
    """Data variants in the order a figure looks for its own: ``preferred`` (e.g. ``mesh``) first, and each
    variant's paper regime (``mesh m=n``, m = n, the variant the summary's verdict is about) before its coverage
    rule's."""
    from workbench.study.regime import coverage_rule_name, is_paper_regime

    return sorted(variants, key=lambda d: (coverage_rule_name(d) != preferred, not is_paper_regime(d)))


def figure_m(record: RunRecord, data: str) -> str:
    """Which m a figure drawn from data variant ``data`` shows, for its title: ``m = 18 (m = n, the paper's
    regime)`` or ``m = 13 (the coverage rule)``."""
    from workbench.study.regime import is_paper_regime

    regime = "m = n, the paper's regime" if is_paper_regime(data) else "the coverage rule"
    return f"m = {record.metrics['data'][data]['pca']['m']} ({regime})"


def mesh_variant(record: RunRecord, cache: dict) -> tuple[str, dict] | None:
    """The data variant whose points are mesh vertices (saved with triangles), preferring ``mesh m=n`` (the
    paper's regime), then ``mesh`` (:func:`figure_order`)."""
    for data in figure_order(record.data_variants, "mesh"):
        inputs = record_inputs(record, data, cache)
        if inputs is not None and "faces" in inputs:
            return data, inputs
    return None


NEEDS_FACE = (
    "needs the frames of a mesh data variant (a run with dataset.train_on=[markers,mesh]), or those of a "
    "marker variant and the dataset's face mesh to carry them onto"
)
"""Why a face figure is not drawn when neither a mesh variant's nor a marker variant's frames can be had."""
CARRIED_NOTE = "markers carried onto the mesh by RBF (as in the paper); the run has no mesh data variant"
"""Said by every face figure of a run without a mesh data variant."""


@dataclass(frozen=True)
class FaceData:
    """What the face figures show: a mesh variant's own frames, or, for a run without one, a marker variant's
    displacement fields carried onto the dataset's face mesh by the RBF map of
    :func:`workbench.dataset.transfer.point_transfer` (as the paper showed faces of a run on markers).

    Weights, alpha and every other number are those of ``data``, computed on its own points; only what is drawn
    is carried (:meth:`carry`), so a reconstruction shown is ``T @`` the reconstruction on the markers.

    Attributes
    ----------
    data : str
        The data variant whose numbers are shown.
    inputs : mapping
        Its arrays (``inputs.npz``), on its own points.
    neutral : ndarray of shape (3 * n_vertices,)
        The mesh at rest.
    faces : ndarray of shape (n_triangles, 3) of int
    support : ndarray of shape (n_vertices,) of bool, or None
        Vertices with data (the rest fade into the plain shade in colour maps).
    transfer : PointTransfer or None
        The map from ``data``'s points to the mesh's vertices; None when ``data`` is the mesh.
    mesh_text : str
        What the mesh carried onto is (``""`` for a mesh variant).
    """

    data: str
    inputs: Mapping
    neutral: np.ndarray
    faces: np.ndarray
    support: np.ndarray | None
    transfer: object = None
    mesh_text: str = ""

    @property
    def carried(self) -> bool:
        return self.transfer is not None

    @property
    def note(self) -> str:
        """:data:`CARRIED_NOTE` for carried faces, else ``""``."""
        if not self.carried:
            return ""
        return (
            CARRIED_NOTE
            if self.transfer.method == "rbf"
            else CARRIED_NOTE.replace("by RBF", f"by the map '{self.transfer.describe()}'")
        )

    def caption(self, numbers: str) -> str:
        """What a figure's caption adds for carried faces (``""`` otherwise); ``numbers`` says whose the numbers
        it shows are (a clause)."""
        if not self.carried:
            return ""
        return (
            f"{self.note[0].upper()}{self.note[1:]}: the faces drawn are the displacement fields of the "
            f"'{self.data}' variant carried onto {self.mesh_text} by one linear map and added to its rest pose; "
            f"the weights are solved on the markers, as the run solved them; {numbers}."
        )

    @property
    def operator(self) -> np.ndarray | None:
        """The linear map :meth:`carry` applies to each coordinate, shape (n_vertices, n_points); None when the
        faces are not carried or the map leaves them as they are."""
        return None if self.transfer is None else self.transfer.operator

    def carry(self, fields: np.ndarray) -> np.ndarray:
        """Displacement fields on ``data``'s points, shape (n_fields, 3 * n_points), onto the mesh, shape
        (n_fields, 3 * n_vertices) (unchanged for a mesh variant)."""
        return fields if self.transfer is None else self.transfer.apply(np.asarray(fields, dtype=np.float64))


def face_data(record: RunRecord, cache: dict) -> FaceData | str:
    """The faces a run's report draws (:class:`FaceData`): its mesh variant, or else its marker variant carried
    onto the dataset's face mesh (rest geometry only: no mesh frame is built); or what is missing."""
    key = ("face",)
    if key not in cache:
        cache[key] = _face_data(record, cache)
    return cache[key]


def _face_data(record: RunRecord, cache: dict) -> FaceData | str:
    from workbench.core.errors import WorkbenchError
    from workbench.dataset.rest_mesh import rest_mesh
    from workbench.dataset.transfer import point_transfer

    found = mesh_variant(record, cache)
    if found is not None:
        data, inputs = found
        return FaceData(data, inputs, inputs["neutral"], inputs["faces"], inputs.get("point_support"))
    found = marker_variant(record, cache)
    if found is None:
        return NEEDS_FACE
    data, inputs = found
    try:
        mesh = rest_mesh(record.settings.dataset, record.metrics["dataset"]["provenance"])
    except (WorkbenchError, OSError) as error:
        return f"{NEEDS_FACE}: the run has no mesh data variant and the dataset's face mesh cannot be read ({error})"
    transfer = point_transfer(inputs["neutral"].reshape(-1, 3), mesh.vertices)
    return FaceData(data, inputs, mesh.vertices.reshape(-1), mesh.triangles, mesh.support, transfer, mesh.description)


def marker_variant(record: RunRecord, cache: dict) -> tuple[str, dict] | None:
    """The data variant of markers (no triangles), preferring ``markers m=n`` (the paper's regime), then
    ``markers`` (:func:`figure_order`)."""
    for data in figure_order(record.data_variants, "markers"):
        inputs = record_inputs(record, data, cache)
        if inputs is not None and "faces" not in inputs:
            return data, inputs
    return None


def qe_label(record: RunRecord) -> str:
    projections = record.settings.basis.projections
    return "QE" if "affine" in projections else "QE-linear"


def appended_axes(record: RunRecord, data: str, label: str) -> list[int]:
    return record.metrics["data"][data]["quasi_eigen"][QE_PROJECTIONS[label]]["appended_axes"]


def record_timeline(record: RunRecord, inputs: Mapping) -> Timeline:
    """The evaluated frames' take, frame number in the file and time (saved inputs), or frames of one take at the
    record's frame rate for records written before runs saved them."""
    found = Timeline.from_arrays(inputs, "eval_")
    return (
        found
        if found is not None
        else Timeline.uniform("take", np.arange(len(inputs["eval"])), record.metrics["dataset"]["frame_rate"])
    )


def training_variants(record: RunRecord) -> list[str]:
    """The data variants scored on their training frames (the paper's protocol), not on held-out frames."""
    return [data for data, values in record.metrics["data"].items() if values["protocol"] == "training frames"]


def figure_bases(record: RunRecord, data: str, inputs: Mapping, cache: dict, *, every: bool = False) -> dict:
    """Basis label -> shapes: H and the run's quasi-eigen basis (with ``every``: both projections the run had)."""
    key = ("bases", data, every)
    if key not in cache:
        labels = [
            label for label, projection in QE_PROJECTIONS.items() if projection in record.settings.basis.projections
        ]
        labels = labels if every else [qe_label(record)]
        cache[key] = {
            "H": inputs["hand"],
            **{
                label: quasi_eigen_shapes(inputs, QE_PROJECTIONS[label], appended_axes(record, data, label))
                for label in labels
            },
        }
    return cache[key]


def frame_weights(record: RunRecord, data: str, label: str, cache: dict) -> tuple[np.ndarray, np.ndarray]:
    """Weights of every evaluated frame that saw every point, in a basis, with the figures' solver.

    Returns
    -------
    weights : ndarray of shape (n_complete, n_shapes)
    complete : ndarray of shape (n_eval_frames,) of bool
    """
    from workbench.numerics.solve import solve_weights

    key = ("weights", data, label)
    if key not in cache:
        inputs = record_inputs(record, data, cache)
        _, solver = figure_solver(record.config)
        complete = np.isfinite(inputs["eval"]).all(axis=1)
        shapes = figure_bases(record, data, inputs, cache, every=True)[label]
        cache[key] = solve_weights(shapes, inputs["eval"][complete], **solver).weights, complete
    return cache[key]


def negative_weight_share(record: RunRecord) -> dict:
    """Data variant -> (basis -> share of evaluated frames whose least-squares weights include a negative one), as
    the run recorded it (rows' ``weights``); empty for records without weight statistics."""
    shares = {}
    for row in record.rows():
        if row.get("solver") == "lstsq" and row.get("weights"):
            shares.setdefault(row["data"], {})[row["basis"]] = float(row["weights"]["negative_share"])
    return shares


def figure3_frames(record: RunRecord, inputs: Mapping) -> list[tuple[str, int]]:
    """The frames of figure 3: the most displaced frame of each region of the face its hand shapes act on (brows,
    eyes, mouth, jaw), at least a second apart, or the most displaced frame when no region is found.

    Returns
    -------
    list of (str, int)
        (region, index among the evaluated frames), top of the face first.
    """
    from workbench.reporting.figures.faces import face_regions, point_norms, region_frames

    names = [str(name) for name in inputs["hand_names"]]
    timeline = record_timeline(record, inputs)
    regions = face_regions(inputs["hand"], names, inputs.get("point_support"))
    frames = seen_frames(inputs["eval"])
    chosen = region_frames(frames, regions, timeline.seconds, timeline.take)
    if not chosen:
        lengths = np.nan_to_num(point_norms(frames))
        chosen = [("face", int(np.argmax((lengths**2).sum(axis=1))))]
    return chosen


def seen_frames(frames: np.ndarray) -> np.ndarray:
    """Evaluated frames with those that miss a point (a marker's gap, ``gap_policy=masked``) set to rest, so that
    the frames a figure picks by their displacement saw every point (and can be reconstructed and drawn whole);
    unchanged when every frame, or none, saw every point.

    Parameters
    ----------
    frames : ndarray of shape (n_frames, 3 * n_points)

    Returns
    -------
    ndarray of shape (n_frames, 3 * n_points)
    """
    incomplete = ~np.isfinite(frames).all(axis=1)
    if not incomplete.any() or incomplete.all():
        return frames
    return np.where(incomplete[:, None], 0.0, frames)


def most_displaced(inputs: Mapping, frames: Sequence[int]) -> int:
    """The frame of ``frames`` with the largest captured displacement (over every point)."""
    captured = np.nan_to_num(inputs["eval"][list(frames)])
    return int(list(frames)[int(np.argmax(np.linalg.norm(captured, axis=1)))])


def frame_caption(region: str, timeline: Timeline, frame: int) -> str:
    """How a frame of figure 3 is named: the region it is the most displaced frame of, take, file frame, time."""
    return f"most displaced {region}: {timeline.label(frame)}"


def vertex_rms(
    frames: np.ndarray,
    reconstruct: Callable[[slice], np.ndarray],
    chunk: int = 256,
    operator: np.ndarray | None = None,
) -> np.ndarray:
    """RMS over frames of the 3-D error at every point, in chunks of frames.

    Carried onto other points by a linear ``operator`` (:class:`workbench.dataset.transfer.PointTransfer`), the
    error at target ``v`` of frame ``f``, coordinate ``c`` is ``sum_s T[v, s] e[f, s, c]``, so its sum of squares
    over frames and coordinates is ``(T C T^T)[v, v]`` with ``C = sum_f,c e[f, :, c] e[f, :, c]^T`` over the source
    points: no frame is carried.

    Parameters
    ----------
    frames : ndarray of shape (n_frames, 3 * n_points)
    reconstruct : callable
        Rows (a slice) -> their reconstructions, ndarray of shape (n_rows, 3 * n_points).
    chunk : int
    operator : ndarray of shape (n_targets, n_points), optional
        Values at the points -> values at other points (:meth:`FaceData.carry`'s map); the RMS is then at those.

    Returns
    -------
    ndarray of shape (n_points,), or (n_targets,) with ``operator``
    """
    n_points = frames.shape[1] // 3
    total = np.zeros(n_points if operator is None else (n_points, n_points))
    for start in range(0, len(frames), chunk):
        rows = slice(start, start + chunk)
        error = (reconstruct(rows) - frames[rows]).reshape(-1, n_points, 3)
        if operator is None:
            total += (error**2).sum(axis=(0, 2))
        else:
            by_point = np.transpose(error, (1, 0, 2)).reshape(n_points, -1)
            total += by_point @ by_point.T
    if operator is not None:
        total = np.maximum(np.einsum("vs,vs->v", operator @ total, operator), 0.0)
    return np.sqrt(total / len(frames)) if len(frames) else np.zeros(len(total))


def moving_stretch(inputs: Mapping, timeline: Timeline, n_frames: int) -> np.ndarray:
    """The ``n_frames`` consecutive evaluated frames of one take in which the face moves most (the summed RMS
    change of the displacement between consecutive frames), or the longest take when every take is shorter.

    Returns
    -------
    ndarray of int
        Consecutive frame indices.
    """
    frames = np.nan_to_num(inputs["eval"])
    change = np.zeros(len(frames))
    change[1:] = np.sqrt(((frames[1:] - frames[:-1]) ** 2).mean(axis=1))
    incomplete = ~np.isfinite(inputs["eval"]).all(axis=1)
    change[incomplete] = 0.0  # a frame missing a marker neither moves nor is moved to
    change[1:][incomplete[:-1]] = 0.0
    best, best_key = None, None
    for start, stop in timeline.take_spans():
        change[start] = 0.0  # no motion across a take boundary
        length = min(n_frames, stop - start)
        # motion of the window [first, first + length): the changes into its frames after the first
        summed = np.concatenate([[0.0], np.cumsum(change[start:stop])])
        motion = summed[length:] - summed[1 : len(summed) - length + 1]
        first = int(np.argmax(motion))
        key = (length, float(motion[first]))  # a full-length window first, then the most motion
        if best_key is None or key > best_key:
            best, best_key = np.arange(start + first, start + first + length), key
    return best
