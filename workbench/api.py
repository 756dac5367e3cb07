"""The public Python API beside the estimator: the file readers, the real datasets' steps on plain arrays (ARKit
mapping, head stabilisation, marker placement, RBF carry), the captures of a dataset config, a study run from
Python and the run records it writes. ``import workbench`` re-exports these names (lazily: nothing here is
imported until a name is used).

Every function hands over to the module that does the work, imported when it is called, so that the names keep
working wherever that module lives; each says where in its docstring.
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Mapping, Sequence

from workbench.core.errors import WorkbenchError
from workbench.settings.config import CHECKOUT, resolved_yaml_text

if TYPE_CHECKING:
    from omegaconf import DictConfig

    from workbench.dataset.capture import Capture
    from workbench.dataset.correspondence import MarkerPlacement, MarkerTable
    from workbench.dataset.rigid import Stabilised
    from workbench.formats.livelink import ArkitMapping
    from workbench.record.record import RunRecord
    from workbench.study.results import StudyResult


# ---------------------------------------------------------------------------------------------------------------
# Readers
# ---------------------------------------------------------------------------------------------------------------


def __getattr__(name: str):
    """The readers of :data:`workbench.formats.registry.FORMATS` under their public names (``read_c3d``, ...),
    each the reader itself with its own docstring; the formats are imported when one is first asked for."""
    from workbench.formats.registry import FORMATS

    for entry in FORMATS.values():
        if entry.public_name == name:
            globals()[name] = entry.read  # later uses skip this function
            return entry.read
    raise AttributeError(f"module 'workbench.api' has no attribute {name!r}")


# ---------------------------------------------------------------------------------------------------------------
# Real data: the steps the dataset builders take, on plain arrays
# ---------------------------------------------------------------------------------------------------------------


def _names(value, argument: str) -> list[str]:
    """A list of strings, or a one-line error naming ``argument`` (a single string is refused)."""
    if isinstance(value, str) or not isinstance(value, Sequence) or not all(isinstance(v, str) for v in value):
        raise WorkbenchError(f"{argument} must be a list of names (strings), got {value!r:.80}")
    return list(value)


def _points(value, argument: str, shape: str, ndim: int):
    """A float64 array of ``ndim`` dimensions, the last of length 3, or a one-line error naming ``argument``."""
    import numpy as np

    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise WorkbenchError(f"{argument} must be an array of shape {shape} of numbers") from None
    if array.ndim != ndim or array.shape[-1] != 3:
        raise WorkbenchError(f"{argument} must have shape {shape}, got {array.shape}")
    return array


def _indices(value, argument: str, size: int):
    """An array of integer indices into ``size`` points, or a one-line error naming ``argument``."""
    import numpy as np

    array = np.asarray(value)
    if array.ndim != 1 or array.size == 0 or not np.issubdtype(array.dtype, np.integer):
        raise WorkbenchError(f"{argument} must be a non-empty list of integer indices, got {value!r:.80}")
    if array.min() < 0 or array.max() >= size:
        raise WorkbenchError(f"{argument} must be indices in [0, {size}), got {array.min()} .. {array.max()}")
    return array


def arkit_mapping(
    channel_names: Sequence[str], basis_names: Sequence[str], overrides: Mapping[str, Sequence[str]] | None = None
) -> "ArkitMapping":
    """Which basis shapes each ARKit channel drives: the mapping dataset ``ict_livelink`` builds
    (:func:`workbench.formats.livelink.map_arkit_channels`).

    The rule, per channel: its name with a lower-case first letter if the basis has it (``JawOpen -> jawOpen``,
    ``JawLeft -> jawLeft``, ``MouthLeft -> mouthLeft``); else ``...Left``/``...Right`` as ``..._L``/``..._R``
    (``MouthSmileLeft -> mouthSmile_L``); else, for a channel without a side, the basis's pair
    (``BrowInnerUp -> browInnerUp_L`` and ``browInnerUp_R``); else nothing. ``overrides`` replaces the rule.

    Parameters
    ----------
    channel_names : sequence of str
        ARKit channels, e.g. ``read_livelink(path).names`` (52).
    basis_names : sequence of str
        The basis's shape names, e.g. ``read_blendshapes(...).names``, in the order of its ``deltas``.
    overrides : mapping, optional
        Channel -> list of shape names, replacing the rule for that channel (``[]`` leaves it unmapped), as
        ``dataset.arkit_overrides`` (``conf/dataset/ict_livelink.yaml``: ``TongueOut: []``).

    Returns
    -------
    workbench.formats.livelink.ArkitMapping
        ``matrix`` of shape (n_channels, n_shapes), 1 where a channel drives a shape; ``targets`` (channel ->
        shapes), ``unmapped`` channels and ``undriven`` shapes. Displacements in the basis's units (mm for
        ``read_blendshapes(..., unit_mm=10)``) are ``(weights @ matrix) @ deltas.reshape(n_shapes, -1)``, with
        ``weights`` of shape (n_frames, n_channels): shape (n_frames, 3 * n_vertices).
    """
    from workbench.formats.livelink import map_arkit_channels

    channels = _names(channel_names, "channel_names")
    shapes = _names(basis_names, "basis_names")
    if overrides is not None and not isinstance(overrides, Mapping):
        raise WorkbenchError(f"overrides must be a mapping of channel -> list of shape names, got {overrides!r:.80}")
    return map_arkit_channels(channels, shapes, dict(overrides or {}))


def rest_frame(markers, rigid_markers: Sequence[int]) -> int:
    """The take's rest face: its frame nearest the median pose of its frames (RMS over the markers), head motion
    removed; dataset ``animface`` takes it as the neutral when ``dataset.neutral_frame`` is null
    (:func:`workbench.dataset.animface.rest_frame`).

    Parameters
    ----------
    markers : array-like of shape (n_frames, n_markers, 3)
        Every frame of the take, in mm, NaN at gaps: the builder measures the markers of its correspondence
        table, ``read_c3d(path).positions[:, table_index]``.
    rigid_markers : sequence of int
        Indices of the markers that move only with the head (at least 3).

    Returns
    -------
    int
        A frame of ``markers``.
    """
    from workbench.dataset.animface import rest_frame_of

    markers = _points(markers, "markers", "(n_frames, n_markers, 3)", 3)
    rigid = _indices(rigid_markers, "rigid_markers", markers.shape[1])
    return rest_frame_of(markers, rigid, slice(None), [f"marker {i}" for i in range(markers.shape[1])])


def stabilise_markers(markers, rigid_markers: Sequence[int], reference) -> "Stabilised":
    """Remove rigid head motion: each frame is moved so its rigid markers best fit their reference positions
    (Kabsch, least squares), as dataset ``animface`` does (:func:`workbench.dataset.rigid.stabilise`).

    A frame with gaps is aligned on the rigid markers it has; with fewer than 3 it comes back NaN.

    Parameters
    ----------
    markers : array-like of shape (n_frames, n_markers, 3)
        Marker positions in mm (e.g. ``read_c3d(path).positions``), NaN at gaps.
    rigid_markers : sequence of int
        Indices of the markers that move only with the head (at least 3; AnimFace's: forehead, nose bridge,
        inner eye corners).
    reference : array-like of shape (n_rigid, 3)
        Their positions in the head frame, in mm: the builder's are the neutral frame's,
        ``markers[neutral_frame, rigid_markers]`` (see :func:`rest_frame`).

    Returns
    -------
    workbench.dataset.rigid.Stabilised
        ``markers`` of shape (n_frames, n_markers, 3) in mm, in the reference's head frame, and ``residual_rms`` of
        shape (n_frames,): the rigid markers' RMS distance from the reference after alignment, in mm.
    """
    from workbench.dataset.rigid import stabilise

    markers = _points(markers, "markers", "(n_frames, n_markers, 3)", 3)
    rigid = _indices(rigid_markers, "rigid_markers", markers.shape[1])
    reference = _points(reference, "reference", f"({rigid.size}, 3)", 2)
    if len(reference) != rigid.size:
        raise WorkbenchError(
            f"reference must have shape ({rigid.size}, 3), one row per rigid marker, got {reference.shape}"
        )
    return stabilise(markers, rigid, reference)


def read_marker_table(path: str | os.PathLike, *, n_vertices: int | None = None) -> "MarkerTable":
    """A marker-to-vertex correspondence table (``marker,landmark,vertex,note``; the shipped one is
    ``conf/correspondence/animface_ict.csv``), as both real datasets read it
    (:func:`workbench.dataset.correspondence.read_marker_table`).

    Parameters
    ----------
    path : path-like
    n_vertices : int, optional
        Vertices of the mesh (ICT's face region: 9,409); indices must be below it.

    Returns
    -------
    workbench.dataset.correspondence.MarkerTable
        ``labels`` (n_markers,), ``landmarks`` and ``vertices`` of shape (n_markers,) of int (-1 where empty):
        ``vertices`` are the mesh vertices of dataset ``ict_livelink``'s virtual markers.
    """
    from workbench.dataset.correspondence import read_marker_table as read

    if not isinstance(path, (str, os.PathLike)) or not str(path).strip():
        raise WorkbenchError(f"path must be the path of a correspondence table, got {path!r:.80}")
    return read(path, n_vertices=n_vertices)


def place_markers(
    table: "MarkerTable", marker_neutral, mesh_vertices, *, refine_iterations: int = 0
) -> "MarkerPlacement":
    """Place capture markers on a mesh, as dataset ``animface`` does: a similarity alignment (with scale) on the
    table's landmark pairs, refined on every marker-vertex pair, then the nearest vertex for each marker the table
    leaves empty (:func:`workbench.dataset.correspondence.place_markers`).

    Parameters
    ----------
    table : MarkerTable
        From :func:`read_marker_table`.
    marker_neutral : array-like of shape (n_markers, 3)
        The table's markers in the neutral frame, in table order, in mm.
    mesh_vertices : array-like of shape (n_vertices, 3)
        The mesh's neutral (``read_blendshapes(...).neutral``), in mm.
    refine_iterations : int, default 0
        Rounds of refinement (``dataset.refine_iterations``: 50).

    Returns
    -------
    workbench.dataset.correspondence.MarkerPlacement
        ``vertices`` of shape (n_markers,) of int, ``mesh_to_capture`` (the similarity; its ``scale`` is the
        performer's size over the mesh's) and ``in_mesh_frame(points)``, which expresses capture points of shape
        (..., 3) in the mesh's head frame at the performer's size, in mm (the frame of the builder's arrays).
    """
    from workbench.dataset.correspondence import MarkerTable
    from workbench.dataset.correspondence import place_markers as place

    if not isinstance(table, MarkerTable):
        raise WorkbenchError(f"table must be a MarkerTable (read_marker_table), got {type(table).__name__}")
    marker_neutral = _points(marker_neutral, "marker_neutral", "(n_markers, 3)", 2)
    mesh_vertices = _points(mesh_vertices, "mesh_vertices", "(n_vertices, 3)", 2)
    if isinstance(refine_iterations, bool) or not isinstance(refine_iterations, int) or refine_iterations < 0:
        raise WorkbenchError(f"refine_iterations must be an integer >= 0, got {refine_iterations!r}")
    return place(table, marker_neutral, mesh_vertices, refine_iterations=refine_iterations)


def rbf_carry(
    marker_displacements,
    vertices,
    triangles,
    marker_vertices: Sequence[int],
    target_vertices: Sequence[int] | None = None,
    *,
    metric: str = "euclidean",
    kernel: str = "thin_plate_spline",
    epsilon: float | None = None,
    smoothing: float = 0.0,
    degree: int = 1,
):
    """Carry marker displacements onto a mesh by radial-basis interpolation, as dataset ``animface`` builds its
    ``mesh`` (:func:`workbench.dataset.rbf.mesh_rbf_operator`: one linear map applied to every frame).

    Parameters
    ----------
    marker_displacements : array-like of shape (n_frames, n_markers, 3)
        Each marker's displacement from the neutral, in mm.
    vertices : array-like of shape (n_vertices, 3)
        The mesh's neutral, in mm (the builder's: ``placement.mesh_to_capture.scale * neutral``).
    triangles : array-like of shape (n_triangles, 3) of int, or None
        Needed for ``metric="geodesic"``.
    marker_vertices : sequence of int
        The vertex each marker sits on (distinct), shape (n_markers,).
    target_vertices : sequence of int, optional
        The vertices wanted; all when None.
    metric, kernel, epsilon, smoothing, degree
        ``dataset.rbf``: the defaults are SciPy's ``RBFInterpolator``'s (a linear tail; the builder's without the
        setting are the schema's, a constant tail); ``conf/dataset/animface.yaml`` sets
        ``metric="geodesic"``, ``kernel="inverse_multiquadric"``, ``epsilon=0.05`` (1/mm), ``degree=0``.

    Returns
    -------
    ndarray of shape (n_frames, n_targets, 3)
        Displacements at the target vertices, in mm.
    """
    import numpy as np

    from workbench.dataset.rbf import interpolate_frames, mesh_rbf_operator

    marker_displacements = _points(marker_displacements, "marker_displacements", "(n_frames, n_markers, 3)", 3)
    vertices = _points(vertices, "vertices", "(n_vertices, 3)", 2)
    centres = _indices(marker_vertices, "marker_vertices", len(vertices))
    if len(centres) != marker_displacements.shape[1]:
        raise WorkbenchError(
            f"marker_vertices must give one vertex per marker ({marker_displacements.shape[1]}), got {len(centres)}"
        )
    targets = (
        np.arange(len(vertices))
        if target_vertices is None
        else _indices(target_vertices, "target_vertices", len(vertices))
    )
    if triangles is not None:
        triangles = np.asarray(triangles)
    operator = mesh_rbf_operator(
        vertices,
        triangles,
        centres,
        targets,
        metric=metric,
        kernel=kernel,
        smoothing=smoothing,
        epsilon=epsilon,
        degree=degree,
    )
    return interpolate_frames(operator, marker_displacements)


# ---------------------------------------------------------------------------------------------------------------
# Configs, captures, runs and records
# ---------------------------------------------------------------------------------------------------------------


def compose_config(study: str = "paper", overrides: Sequence[str] = ()) -> "DictConfig":
    """A study's config composed as the command line composes it, without running it (:func:`workbench.settings.config.compose`).

    Parameters
    ----------
    study : str, default "paper"
        A study of ``studies/`` (``workbench --config-name STUDY``).
    overrides : sequence of str
        The command line's overrides, e.g. ``["dataset=ict_livelink", "dataset.frame_step=20"]`` (a single string
        is refused, not read as its letters).

    Returns
    -------
    omegaconf.DictConfig

    Raises
    ------
    WorkbenchError
        In one line, with the command line's words: an unknown study, an override that is not a string, cannot be
        parsed, names an unknown key or option, a retired setting or a value of the wrong type.
    """
    from workbench.settings.config import compose

    return compose(study, overrides)


def _study_config(config) -> "DictConfig":
    """``config`` as a DictConfig: a composed one as it is, a mapping (a record's resolved ``config``) wrapped."""
    from omegaconf import DictConfig, OmegaConf

    if isinstance(config, DictConfig):
        return config
    if isinstance(config, Mapping):
        return OmegaConf.create(dict(config))
    raise WorkbenchError(
        f"config must be a composed study config (compose_config) or a mapping of one, got {type(config).__name__}"
    )


def build_captures(config, *, cache_dir: str | None = None) -> dict[str, "Capture"]:
    """The captures a dataset config describes, one per ``dataset.train_on`` variant
    (:func:`workbench.dataset.build_captures`).

    Parameters
    ----------
    config : DictConfig or mapping
        A composed study config (its ``dataset`` group is used, and its ``paths.cache_dir`` unless ``cache_dir``
        is given) or the ``dataset`` group itself.
    cache_dir : str, optional
        Folder of the disk cache of built datasets; memory only when None.

    Returns
    -------
    dict
        Variant name (``markers``, ``mesh``, ...) -> ``Capture``: ``neutral`` of shape (3 * n_points,), ``train``
        and ``eval`` frames of shape (n_frames, 3 * n_points) as displacements from neutral, ``hand`` of shape
        (n_shapes, 3 * n_points) and ``hand_names``: the arrays :class:`QuasiEigenFaces` fits on.
    """
    from omegaconf import OmegaConf

    from workbench.dataset import build_captures as build

    if not isinstance(config, Mapping) and not OmegaConf.is_config(config):
        raise WorkbenchError(f"config must be a study config or its dataset group, got {type(config).__name__}")
    if "dataset" in config:
        paths = config.get("paths") or {}
        cache_dir = paths.get("cache_dir") if cache_dir is None else cache_dir
        config = config["dataset"]
    from workbench.settings.typed import dataset_settings

    plain = OmegaConf.to_container(config, resolve=True) if OmegaConf.is_config(config) else dict(config)
    return build(dataset_settings(plain), cache_dir=cache_dir)


def run_study(config) -> list["StudyResult"]:
    """Run a study in memory, as the command line runs it, and return its results (nothing is written).

    Parameters
    ----------
    config : DictConfig or mapping
        A composed study config (:func:`compose_config`), or the resolved config of a record
        (``read_record(folder).config``). Checked as the command line checks it.

    Returns
    -------
    list of workbench.study.results.StudyResult
        One per data variant: its ``capture``, ``eigenfaces``, ``quasi_eigen`` bases, ``rows`` (the alpha table's
        rows: basis, solver and every alpha variant in ``row.alpha``) and ``weights``.
    """
    from workbench.settings.typed import study_settings
    from workbench.study.run import run_study as run

    return run(study_settings(_study_config(config)))


def record_study(config, output_dir: str | os.PathLike, *, overrides: Sequence[str] = ()) -> "RunRecord":
    """Run a study as the command line runs it and write its run record into ``output_dir`` (the command's
    ``hydra.run.dir``); returns the record read back.

    A folder holding a complete record of the same config is not run again (its record is returned), one holding
    anything else that is not a record of the workbench's is refused, and a run that fails removes what it wrote and the folders it made.

    Parameters
    ----------
    config : DictConfig or mapping
        As :func:`run_study`.
    output_dir : path-like
        Not empty, nor the current folder or one above it.
    overrides : sequence of str
        The overrides that made ``config``, kept in the record (``metrics.json``'s ``overrides``); a single string
        is refused, not read as its letters.

    Returns
    -------
    workbench.record.record.RunRecord
    """
    from workbench.core.files import check_folder_setting
    from workbench.record.tracking import note_new_run_dir
    from workbench.settings.config import override_list

    config = _study_config(config)
    output_dir = check_folder_setting(output_dir, "output_dir")
    overrides = override_list(overrides, "overrides")
    note_new_run_dir(Path(output_dir))  # a failed run removes the folder (and parents) it made
    run_owned(config, Path(output_dir), overrides=overrides, job_num=None, plain=True)
    return read_record(output_dir)


def read_record(folder: str | os.PathLike, *, check_archives: bool = False) -> "RunRecord":
    """A complete run record, every file checked against the checksums the run wrote
    (:func:`workbench.record.record.load_record`).

    Parameters
    ----------
    folder : path-like
        A run folder (holding ``done``).
    check_archives : bool, default False
        Check the ``.npz`` archives now too (otherwise each is checked when read).

    Returns
    -------
    workbench.record.record.RunRecord
        ``config`` (the resolved config), ``table`` (the alpha table, a DataFrame), ``metrics``
        (``metrics.json``: its ``rows`` hold every alpha variant of every basis and solver) and ``timings``.
    """
    from workbench.record.record import load_record

    if not isinstance(folder, (str, os.PathLike)) or not str(folder).strip():
        raise WorkbenchError(f"folder must be the path of a run record, got {folder!r}")
    return load_record(Path(folder), check_archives=check_archives)


def run(
    cfg: DictConfig,
    output_dir: Path,
    overrides: Sequence[str] = (),
    job_num: int | None = None,
    *,
    wide: bool = True,
) -> str:
    """Run the study a config describes, write its record into ``output_dir`` and return the printed text.

    Parameters
    ----------
    cfg : omegaconf.DictConfig
        A composed study config (without or with its ``hydra`` node).
    output_dir : pathlib.Path
        Must not hold a complete record (one with ``done``): records are never overwritten.
    overrides : sequence of str
        The command-line and sweep overrides that made ``cfg``, kept in the record.
    job_num : int, optional
        The run's position in its sweep (Hydra's job number), kept so that tables list runs in sweep order.
    wide : bool, default True
        Return the full text, as the record's ``alpha_table.md`` holds it (``workbench --wide``); False: the text
        the command prints by default, within 120 columns
        (:data:`workbench.reporting.text.run.PRINT_WIDTH`).

    Returns
    -------
    str
        One sentence on what was reproduced, the header, the Markdown alpha table and the headline.
    """
    import pandas as pd
    from omegaconf import OmegaConf

    from workbench.record.record import DONE, record_state, run_metrics, write_record
    from workbench.reporting.text.run import (
        compact_tables,
        fit_width,
        headline,
        printed_tables,
        reproduced_sentence,
        study_header,
    )
    from workbench.study.claims import claims_at_m_equals_n, result_identities
    from workbench.study.run import run_study
    from workbench.study.summary import (
        alpha_per_frame_arrays,
        claim_ratios,
        frame_comparisons,
        results_metrics,
        saved_inputs,
    )
    from workbench.study.table import alpha_table

    started = time.time()
    started_at = datetime.now(timezone.utc).isoformat(timespec="seconds")
    if record_state(output_dir) == "complete":
        raise WorkbenchError(
            f"{output_dir} already holds a complete record ('{DONE}' exists); records are never "
            "overwritten: write the run elsewhere"
        )
    from workbench.settings.schema import resolved_settings
    from workbench.settings.typed import study_settings

    resolved = resolved_settings(cfg)  # resolved once: checked and typed before the run, written as YAML after it
    settings = study_settings(resolved)
    resolved_yaml = OmegaConf.to_yaml(OmegaConf.create(resolved))
    results = run_study(settings)
    metric, paper_alpha = asdict(settings.metric), asdict(settings.paper.alpha)
    table = pd.concat(
        [
            alpha_table(
                result.rows,
                data=result.data,
                m=result.eigenfaces.n_components_,
                coverage=result.eigenfaces.coverage_,
                paper_alpha=paper_alpha,
            )
            for result in results
        ],
        ignore_index=True,
    )
    with results[0].timings.stage("comparisons"):
        comparisons = {result.data: frame_comparisons(result, metric) for result in results}
        ratios = {result.data: claim_ratios(result, metric) for result in results}
        claims = claims_at_m_equals_n(results, metric, settings.metric.claim_margin, resolved["solver"])
    sentence = reproduced_sentence(claims)
    opening = fit_width(sentence) + "\n" if sentence else ""
    header = study_header(results, settings)
    closing = headline(table, metric, paper_alpha, comparisons, result_identities(results, resolved["solver"]), claims)
    text = opening + header + "\n" + printed_tables(table) + "\n" + closing

    metrics = run_metrics(
        results_metrics(results, table, comparisons, ratios, claims),
        study=settings.study,
        resolved_yaml=resolved_yaml,
        overrides=overrides,
        job_num=job_num,
        started_at=started_at,
        repository=CHECKOUT,
    )
    write_record(
        Path(output_dir),
        resolved_yaml=resolved_yaml,
        table=table,
        text=text,
        metrics=metrics,
        timings=dict(results[0].timings.seconds, total=time.time() - started),
        inputs=saved_inputs(results) if settings.save_inputs else None,
        alpha_per_frame=alpha_per_frame_arrays(results) if settings.save_inputs else None,
    )
    return text if wide else fit_width(opening + header + "\n" + compact_tables(table) + "\n" + closing)


def run_owned(
    cfg: DictConfig,
    output_dir: Path,
    *,
    overrides: Sequence[str],
    job_num: int | None,
    plain: bool,
    wide: bool = True,
) -> str | None:
    """:func:`run` while holding the run folder's lock: the text it printed, or None when the folder already
    holds a complete record of the same config. A folder that is not the workbench's is refused before anything
    is written into it (:func:`workbench.record.tracking.check_run_dir`). A plain run (``plain``) that fails or is
    interrupted removes what it wrote, and its folder and the parents it made for it if it made them (a sweep's run
    keeps its partial record: its rerun clears and redoes the run). A complete record keeps no lock file;
    ``wide`` as :func:`run`."""
    from workbench.record.record import config_hash
    from workbench.record.tracking import (
        check_run_dir,
        created_by_this_run,
        discard_failed_run,
        lock_run_dir,
        prepare_run_dir,
        release_run_dir,
        remove_made_folders,
    )

    found = check_run_dir(output_dir, "hydra.sweep.dir" if not plain else "hydra.run.dir")
    lock = lock_run_dir(output_dir)
    try:
        if not prepare_run_dir(output_dir, config_hash(resolved_yaml_text(cfg))):
            return None
        return run(cfg, output_dir, overrides=overrides, job_num=job_num, wide=wide)
    except BaseException:
        if plain and discard_failed_run(output_dir, found, created_by_this_run(output_dir)):
            remove_made_folders(output_dir)
        raise
    finally:
        release_run_dir(output_dir, lock)


# ---------------------------------------------------------------------------------------------------------------
# Rigs
# ---------------------------------------------------------------------------------------------------------------


def write_rig(
    path: str | os.PathLike,
    estimator,
    *,
    triangles,
    basis: str = "QE",
    frames=None,
    seconds=None,
    frame_rate: float = 60.0,
    solver: str | None = None,
    take: str = "take",
) -> dict:
    """Write a fitted :class:`~workbench.numerics.estimator.QuasiEigenFaces` basis as a glTF 2.0 rig (``.glb``), the
    file ``workbench export`` writes for a run's basis (:func:`workbench.reporting.export.rig.rig_mesh`): the neutral mesh,
    morph targets whose weights stay in [0, 1] and, given frames, one morph-weight animation of their weights.

    Blender, three.js and game engines import it; read it back with ``workbench.read_gltf``. Lengths are written in
    metres from the estimator's millimetres (the workbench's unit), +Y up as the data lie.

    Parameters
    ----------
    path : path-like
        A new ``.glb`` file, or one this function or the export wrote before (replaced); any other existing file is
        refused and left alone.
    estimator : QuasiEigenFaces
        Fitted, with ``neutral`` (the rig's rest mesh, ``n_dims = 3 * n_vertices``, mm).
    triangles : array-like of shape (n_triangles, 3) of int
        The mesh's triangles, 0-based vertex indices.
    basis : {"QE", "H", "PCA"}, default "QE"
        The quasi-eigen faces (``shape_names_``), the hand shapes, or ``pca_mean`` then the eigenfaces.
    frames : array-like of shape (n_frames, n_dims), optional
        Displacements from neutral whose weights (:meth:`QuasiEigenFaces.transform`) the animation plays; without
        them the rig has no animation.
    seconds : array-like of shape (n_frames,), optional
        Key times, increasing (default ``arange(n_frames) / frame_rate``); the animation starts at 0.
    frame_rate : float, default 60.0
        Frames per second of ``frames`` (for the default times; recorded in the file).
    solver : {"lstsq", "nnls", "box"}, optional
        The weights' solver (default the estimator's); None for ``PCA``.
    take : str, default "take"
        The animation is named ``<basis>_<solver>_<take>``.

    Returns
    -------
    dict
        ``path``, ``basis``, ``solver``, ``shapes`` (names), ``targets`` (each morph target's name, the shape it is
        a multiple of and the multiple: raw weight = sum of scale x target weight), ``animations`` (names) and
        ``weights`` (ndarray of shape (n_frames, n_shapes), the raw weights animated, or None).

    Raises
    ------
    WorkbenchError
        The estimator is not fitted or has no neutral, the path is not a ``.glb`` file it may write, triangles or
        times do not fit the mesh and frames.
    """
    from workbench.reporting.export.rig import write_estimator_rig

    return write_estimator_rig(
        path,
        estimator,
        triangles=triangles,
        basis=basis,
        frames=frames,
        seconds=seconds,
        frame_rate=frame_rate,
        solver=solver,
        take=take,
    )
