"""One run of the paper study: dataset -> bases -> solve -> metrics, returned as plain results.

``run_study`` takes a plain mapping (a resolved config) and returns one :class:`StudyResult` per data variant
(``dataset.train_on``: markers, mesh, ...); writing files is ``workbench.record``'s job and printing is
``workbench.run_text``'s.
"""

from __future__ import annotations

import re
import time
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import Mapping, Sequence

import numpy as np

from workbench.bases import Eigenfaces, build_quasi_eigen_basis
from workbench.dataset import build_captures, variant_names
from workbench.dataset.capture import Capture
from workbench.dataset.transfer import PointTransfer, point_transfer
from workbench.errors import WorkbenchError
from workbench.frames import frame_chunks
from workbench.metrics import (AlphaSummary, Conditioning, ErrorDistribution, WeightStatistics, basis_conditioning,
                               error_distribution, frame_rms_error, intuitiveness, needs_negative_share,
                               reference_squares, summarise_alpha, summarise_squares, weight_statistics)
from workbench.reduced import FrameProjections, Subspace, project_frames
from workbench.solve import in_span_error_sq, reconstruct, reduce_basis, solve_projected, solve_weights

QE_LABELS = {"affine": "QE", "linear": "QE-linear"}


@dataclass
class Timings:
    """Wall-clock seconds of each stage, in the order they ran."""

    seconds: dict = field(default_factory=dict)

    @contextmanager
    def stage(self, name: str):
        start = time.perf_counter()
        yield
        self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - start


@dataclass(frozen=True)
class Row:
    """One line of the alpha table: a basis reconstructed with one solver.

    ``weight_statistics`` (None for PCA, whose coefficients are no animator's weights), ``frame_error_mm`` (RMS
    point error of each evaluated frame over the face region, :func:`face_region`) and its ``error_mm``
    distribution are set by :func:`frame_measures`; ``offset_error_share`` is the share of the squared error
    along the capture mean's part outside the eigenfaces' span (:func:`outside_offset`), NaN where not taken;
    ``clean_alpha`` is the same reconstruction scored against the clean frames (``metric.score_clean``).
    """

    basis: str
    projection: str
    solver: str
    n_shapes: int
    alpha: AlphaSummary
    n_iterations: int = 0
    n_fallback_frames: int = 0
    max_kkt_violation: float = 0.0
    max_abs_weight: float = float("nan")
    conditioning: Conditioning | None = None
    weight_statistics: WeightStatistics | None = None
    frame_error_mm: np.ndarray | None = None
    error_mm: ErrorDistribution | None = None
    offset_error_share: float = float("nan")
    clean_alpha: AlphaSummary | None = None


@dataclass(frozen=True)
class StudyResult:
    """Everything a run computed.

    Attributes
    ----------
    data : str
        The data variant trained and evaluated on (``dataset.train_on``: ``markers``, ``mesh``, ...).
    capture : Capture
    eigenfaces : Eigenfaces
    quasi_eigen : dict
        Projection name -> :class:`workbench.bases.QuasiEigenBasis`.
    rows : list of Row
    weights : dict
        ``(basis, solver)`` -> ndarray of shape (n_eval_frames, n_shapes).
    timings : Timings
    train_on : str
        The data variant the bases were fitted on (``data`` unless ``dataset.eval_on`` is set).
    eval_on : str
        The data variant scored (``capture`` is its capture).
    transfer : str
        How the fitted bases were carried from ``train_on``'s points to ``eval_on``'s (``identity`` when the
        same; see :mod:`workbench.dataset.transfer`).
    basis_intuitiveness : dict
        Closeness, locality and usage of every basis (:func:`basis_intuitiveness`) when ``basis.alternatives``
        is set; empty otherwise.
    face_region : str
        Which points the per-frame error in millimetres is taken over (:func:`face_region`).
    offset : dict
        The capture mean's part outside the eigenfaces' span, ``(I - P) mu`` (:func:`outside_offset`): its
        ``norm`` and its ``ratio`` to the median evaluated frame's displacement norm; empty when not taken.
    protocol : str
        Which frames were scored: ``training frames`` (those the bases were fitted on, or as ``dataset.split``
        says) or a held-out protocol of ``dataset.held_out`` (:data:`HELD_OUT`).
    """

    data: str
    capture: Capture
    eigenfaces: Eigenfaces
    quasi_eigen: dict
    rows: list
    weights: dict
    timings: Timings
    train_on: str = ""
    eval_on: str = ""
    transfer: str = "identity"
    basis_intuitiveness: dict = field(default_factory=dict)
    face_region: str = ""
    offset: dict = field(default_factory=dict)
    protocol: str = "training frames"


def check_solver_config(name: str, solver: Mapping) -> dict:
    """Validate one entry of the ``solver`` config group and return it as keyword arguments."""
    kind = solver.get("kind")
    if kind not in ("lstsq", "nnls", "box"):
        raise WorkbenchError(f"solver.{name}.kind must be one of lstsq, nnls, box; got {kind!r}")
    lower, upper = solver.get("lower"), solver.get("upper")
    if kind == "box" and lower is None and upper is None:
        raise WorkbenchError(f"solver.{name} is a box solver without bounds: set lower and/or upper")
    if kind == "lstsq":
        lower = upper = None
    if kind == "box" and lower is not None and upper is not None and np.any(np.asarray(lower) > np.asarray(upper)):
        raise WorkbenchError(f"solver.{name}.lower ({lower}) must not exceed solver.{name}.upper ({upper})")
    return {"kind": kind, "lower": lower, "upper": upper}


def run_study(cfg: Mapping) -> list[StudyResult]:
    """Build the data, then for each data variant fit eigenfaces and quasi-eigen faces on the training frames
    and score every basis on the evaluated ones (of the same variant, or of each ``dataset.eval_on`` variant).

    Parameters
    ----------
    cfg : mapping
        A resolved study config with ``dataset``, ``basis`` and ``solver`` groups.

    Returns
    -------
    list of StudyResult
        One per ``dataset.train_on`` variant, in the configured order (times each ``dataset.eval_on`` variant
        when that is set); they share one :class:`Timings`.
    """
    timings = Timings()
    solvers = {name: check_solver_config(name, spec) for name, spec in cfg["solver"].items()}
    if not solvers:
        raise WorkbenchError("the solver group is empty: choose one of solver=lstsq|nnls|box|all")
    dataset_cfg, basis_cfg = cfg["dataset"], cfg["basis"]
    train_names, eval_names = data_variants(dataset_cfg)
    held_out = held_out_protocols(dataset_cfg)
    if held_out and eval_names:
        raise WorkbenchError("dataset.held_out scores each data variant on its own held-out frames; with "
                             "dataset.eval_on (bases carried onto other points) it is not supported: leave one unset")
    build_names = train_names + [name for name in eval_names or () if name not in train_names]
    coverage_on = coverage_on_setting(basis_cfg)
    score_clean = bool((cfg.get("metric") or {}).get("score_clean", False))
    build_cfg = {key: value for key, value in dataset_cfg.items() if key != "held_out"}  # the same built data
    built_cfg = dict(build_cfg, train_on=build_names) if eval_names else build_cfg
    with timings.stage("dataset"):
        captures = build_captures(built_cfg, cache_dir=cfg.get("paths", {}).get("cache_dir"))
        clean = (build_captures(clean_dataset_config(built_cfg), cache_dir=cfg.get("paths", {}).get("cache_dir"))
                 if coverage_on == "clean" or score_clean else None)
    if eval_names and basis_cfg.get("alternatives"):
        raise WorkbenchError("basis.alternatives are fitted and scored on each data variant's own points; "
                             "carrying them onto others (dataset.eval_on) is not supported: leave one of them unset")
    if not eval_names:
        results = []
        for data, capture in captures.items():
            capture, fitted_cfg = with_clean_m(subset_hand_shapes(capture, basis_cfg), basis_cfg,
                                               clean[data] if coverage_on == "clean" else None)
            truth = clean_frames(capture, clean[data]) if score_clean else None
            results.append(run_on_capture(data, capture, fitted_cfg, solvers, timings, truth=truth))
            for protocol in held_out:
                part = held_out_capture(capture, protocol, dataset_cfg.get("eval_fraction", 0.2))
                truth = clean_frames(part, clean[data]) if score_clean else None
                results.append(replace(run_on_capture(f"{data} held-out {protocol}", part, fitted_cfg, solvers,
                                                      timings, truth=truth), train_on=data, eval_on=data,
                                       protocol=HELD_OUT[protocol]))
        return results
    masked = [name for name in eval_names if captures[name].eval_visible is not None]
    if masked:
        raise WorkbenchError(f"dataset.gap_policy 'masked' leaves gaps in the evaluated frames of {masked}; "
                             "carrying bases onto them (dataset.eval_on) is not supported: use gap_policy linear "
                             "or drop, or leave dataset.eval_on unset")
    results = []
    for train_on in train_names:
        source, fitted_cfg = with_clean_m(subset_hand_shapes(captures[train_on], basis_cfg), basis_cfg,
                                          clean[train_on] if coverage_on == "clean" else None)
        eigenfaces, quasi_eigen = fit_bases(source, fitted_cfg, timings)
        for eval_on in eval_names:
            target = select_shapes(captures[eval_on], source.hand_names)
            with timings.stage("transfer"):
                transfer = point_transfer(source.neutral.reshape(-1, 3), target.neutral.reshape(-1, 3))
            note = (f"bases fitted on '{train_on}' ({source.n_points} points) and carried onto '{eval_on}' "
                    f"({target.n_points} points): {transfer.describe()}")
            m_notes = tuple(note for note in source.notes if note.startswith(CLEAN_M_NOTE))
            target = replace(target, notes=target.notes + m_notes + (note,))
            carried = {projection: replace(qe, shapes=transfer.apply(qe.shapes))
                       for projection, qe in quasi_eigen.items()}
            carried_pca = pca_subspace(eigenfaces, transfer)
            rows, weights = score_bases(target, eigenfaces, carried, carried_pca, solvers, timings,
                                        truth=clean_frames(target, clean[eval_on]) if score_clean else None)
            results.append(StudyResult(data=f"{train_on}->{eval_on}", capture=target, eigenfaces=eigenfaces,
                                       quasi_eigen=carried, rows=rows, weights=weights, timings=timings,
                                       train_on=train_on, eval_on=eval_on, transfer=transfer.method,
                                       face_region=face_region(target).description,
                                       offset=offset_facts(carried_pca, rows)))
    return results


HELD_OUT = {"tail": "held-out tail of each take", "take": "held-out last take"}
"""``dataset.held_out`` protocol -> how its frames are described."""


def held_out_protocols(dataset_cfg: Mapping) -> list[str]:
    """``dataset.held_out`` as a list of distinct protocols of :data:`HELD_OUT` (empty when null)."""
    value = dataset_cfg.get("held_out")
    if value is None:
        names = []
    elif isinstance(value, (str, Mapping)) or not hasattr(value, "__iter__"):
        names = [value]
    else:
        names = list(value)
    if any(not isinstance(name, str) or name not in HELD_OUT for name in names) or len(set(names)) != len(names):
        raise WorkbenchError(f"dataset.held_out must be null, one of {list(HELD_OUT)} or a list of distinct ones, "
                             f"got {value!r}")
    if names and dataset_cfg.get("split", "same") != "same":
        raise WorkbenchError(f"dataset.held_out adds held-out frames beside the paper's protocol (split 'same'); "
                             f"with dataset.split {dataset_cfg.get('split')!r} the run is already held out: leave "
                             "one of them unset")
    return names


def held_out_capture(capture: Capture, protocol: str, eval_fraction: float) -> Capture:
    """The capture cut into training frames and held-out evaluated frames, from its frames of split 'same'.

    Parameters
    ----------
    capture : Capture
        Trained and evaluated on the same frames.
    protocol : {"tail", "take"}
        ``tail``: the last ``eval_fraction`` of every take is held out (of the one take, as ``split: tail``);
        ``take``: the last take is held out whole, the bases fitted on the others.
    eval_fraction : float

    Returns
    -------
    Capture
    """
    from workbench.dataset.real import number_setting

    if len(capture.train) != len(capture.eval) or (capture.train_source is not None
                                                   and len(capture.train_source) != len(capture.train)):
        raise WorkbenchError("dataset.held_out needs the training and evaluated frames to be the same frames "
                             "(split 'same'; with gap_policy masked, gap_fit_on filled)")
    timeline = capture.timeline()
    spans = timeline.take_spans()
    if protocol == "take":
        if len(spans) < 2:
            raise WorkbenchError("dataset.held_out 'take' holds out the last take, and this capture has one take; "
                                 "use 'tail'")
        held = np.arange(spans[-1][0], spans[-1][1])
        described = (f"held out: the last take, {timeline.take[held[0]]}, scored with bases fitted on the other "
                     f"{len(spans) - 1} takes")
    else:
        fraction = number_setting(eval_fraction, "dataset.eval_fraction", "in (0, 1) for dataset.held_out 'tail'",
                                  lambda value: 0.0 < value < 1.0)
        counts = [int(round(fraction * (stop - start))) for start, stop in spans]
        if any(count < 1 or count > stop - start - 2 for count, (start, stop) in zip(counts, spans)):
            raise WorkbenchError(f"dataset.eval_fraction {fraction} holds out {counts} frames of takes of "
                                 f"{[stop - start for start, stop in spans]}; each take needs at least 1 held out "
                                 "and 2 for training")
        held = np.concatenate([np.arange(stop - count, stop) for count, (_, stop) in zip(counts, spans)])
        described = (f"held out: the last {100 * fraction:g} % of {'every' if len(spans) > 1 else 'the'} take, "
                     "scored with bases fitted on the rest")
    kept = np.setdiff1d(np.arange(len(capture.eval)), held)
    notes = tuple(note for note in capture.notes if not note.startswith("split '")) + (
        f"{described}: {len(kept)} training frames, {len(held)} evaluated",)
    return replace(capture, train=select_frames(capture.train, kept), eval=select_frames(capture.eval, held),
                   eval_visible=None if capture.eval_visible is None else capture.eval_visible[held],
                   train_source=None if capture.train_source is None else capture.train_source[kept],
                   eval_timeline=timeline[held], notes=notes)


def select_frames(frames, index: np.ndarray):
    """Some frames of a capture: a slice when ``index`` is a run of consecutive frames (frames on disk stay on
    disk), else a copy in memory."""
    from workbench.frames import FramesOnDisk

    if index.size and np.all(np.diff(index) == 1):
        start, stop = int(index[0]), int(index[-1]) + 1
        return frames.rows(start, stop) if isinstance(frames, FramesOnDisk) else frames[start:stop]
    if isinstance(frames, FramesOnDisk):
        raise WorkbenchError("dataset.held_out 'tail' of several takes picks frames from each, which frames on disk "
                             "(dataset.storage disk) cannot give; use dataset.storage memory or held_out 'take'")
    return frames[index]


COVERAGE_ON = ("training", "clean")
CLEAN_M_NOTE = "m chosen on the clean capture"


def coverage_on_setting(basis_cfg: Mapping) -> str:
    """``basis.coverage_on``, checked: ``training`` (the coverage rule on the training frames) or ``clean`` (on
    the clean capture of the same take, then held fixed); ``clean`` chooses m itself, so ``n_components`` must be
    unset."""
    value = basis_cfg.get("coverage_on", "training")
    if value not in COVERAGE_ON:
        raise WorkbenchError(f"basis.coverage_on must be one of {COVERAGE_ON}, got {value!r}")
    if value == "clean" and basis_cfg.get("n_components") is not None:
        raise WorkbenchError(f"basis.coverage_on 'clean' chooses m from the clean capture; basis.n_components "
                             f"({basis_cfg['n_components']}) would fix it too: leave n_components null")
    return value


def clean_dataset_config(dataset_cfg: Mapping) -> dict:
    """The dataset config of the clean capture of the same take: the synthetic actor without marker noise and
    without marker dropout (same seed, so the same performance and head motion).

    Raises
    ------
    WorkbenchError
        For a dataset whose clean version is unknown (a real capture's noise cannot be switched off).
    """
    kind = dataset_cfg.get("kind")
    if kind != "synthetic":
        raise WorkbenchError(f"basis.coverage_on 'clean' and metric.score_clean need the clean version of the "
                             f"capture, which only the synthetic actor has (dataset.kind synthetic), got {kind!r}")
    return dict(dataset_cfg, marker_noise_mm=0.0, gap_rate=0.0)


def with_clean_m(capture: Capture, basis_cfg: Mapping, clean: Capture | None) -> tuple[Capture, dict]:
    """The capture and basis settings to fit with: unchanged without a clean capture; with one, ``n_components``
    fixed to the m the coverage threshold keeps on the clean capture's training frames, said in a note.

    Parameters
    ----------
    capture : Capture
    basis_cfg : mapping
    clean : Capture or None
        The same data variant of the clean capture (:func:`clean_dataset_config`).

    Returns
    -------
    capture : Capture
    basis_cfg : dict
    """
    if clean is None:
        return capture, dict(basis_cfg)
    clean_pca = fit_eigenfaces(clean, basis_cfg["coverage"])
    m = int(clean_pca.n_components_)
    note = (f"{CLEAN_M_NOTE}: m = {m} eigenfaces reach coverage {clean_pca.coverage_:.4f} >= {basis_cfg['coverage']} "
            "on the clean capture of the same take (no marker noise, no dropout); the eigenfaces are fitted on this "
            "capture with that m (basis.coverage_on clean)")
    return replace(capture, notes=capture.notes + (note,)), dict(basis_cfg, n_components=m)


def clean_frames(capture: Capture, clean: Capture) -> np.ndarray:
    """The clean capture's frames at the evaluated frames of ``capture``, matched by take and frame number.

    Parameters
    ----------
    capture : Capture
        The evaluated capture (noise, dropout; its frames may be a subset of the take's).
    clean : Capture
        The same data variant of the clean capture (:func:`clean_dataset_config`), same points.

    Returns
    -------
    ndarray of shape (n_eval_frames, 3 * n_points)
    """
    ours, theirs = capture.timeline(), clean.timeline()
    if clean.neutral.shape != capture.neutral.shape:
        raise WorkbenchError("metric.score_clean: the clean capture has other points than the evaluated one")
    index = np.full(len(ours), -1)
    for take in np.unique(ours.take):
        mine, pool = np.flatnonzero(ours.take == take), np.flatnonzero(theirs.take == take)
        if pool.size == 0:
            continue
        order = np.argsort(theirs.frame[pool], kind="stable")
        frames = theirs.frame[pool][order]
        at = np.minimum(np.searchsorted(frames, ours.frame[mine]), len(frames) - 1)
        found = frames[at] == ours.frame[mine]
        index[mine[found]] = pool[order[at[found]]]
    if np.any(index < 0):
        raise WorkbenchError(f"metric.score_clean: {int((index < 0).sum())} evaluated frames are not among the clean "
                             "capture's evaluated frames (frames a gap policy dropped before a tail split); use "
                             "dataset.split same or gap_policy linear")
    return np.asarray(clean.eval)[index]


def clean_scores(capture: Capture, truth: np.ndarray, rows: Sequence[Row], shapes: Mapping[str, np.ndarray],
                 weights: Mapping, pca_reconstruction=None) -> list[Row]:
    """The rows with ``clean_alpha`` set: each basis's reconstruction of the evaluated (noisy) frames scored
    against the clean frames, so that a basis that reproduces the noise (over-fitting) is told from one that
    removes it (denoising).

    Parameters
    ----------
    capture : Capture
        The evaluated capture (its neutral positions).
    truth : ndarray of shape (n_eval_frames, 3 * n_points)
        The clean frames (:func:`clean_frames`).
    rows : sequence of Row
    shapes : mapping
        Basis label -> shapes of shape (n, 3 * n_points) at the evaluated points.
    weights : mapping
        ``(basis, solver)`` -> weights of shape (n_eval_frames, n).
    pca_reconstruction : callable, optional
        A ``slice`` of frames -> PCA's reconstruction of them, for the ``PCA`` row.

    Returns
    -------
    list of Row
    """
    squares = reference_squares(capture.neutral, truth)
    scored = []
    for row in rows:
        if row.basis == "PCA":
            estimate = pca_reconstruction
        else:
            estimate = (lambda frames, b=shapes[row.basis], w=weights[(row.basis, row.solver)]:
                        reconstruct(b, w[frames]))
        summary = None if estimate is None else summarise_alpha(capture.neutral, truth, estimate, squares=squares)
        scored.append(replace(row, clean_alpha=summary))
    return scored


def data_variants(dataset_cfg: Mapping) -> tuple[list[str], list[str] | None]:
    """``dataset.train_on`` and ``dataset.eval_on`` as lists of names (``eval_on`` None when not set)."""
    train_names, eval_names = variant_names(dataset_cfg, "train_on"), variant_names(dataset_cfg, "eval_on")
    if eval_names is not None and train_names is None:
        raise WorkbenchError("dataset.eval_on needs dataset.train_on to name the variants the bases are fitted on")
    return train_names or [], eval_names


def hand_subset_indices(names: Sequence[str], spec, seed: int) -> np.ndarray:
    """Which hand shapes a ``basis.hand_subset`` setting keeps.

    Parameters
    ----------
    names : sequence of str
        The capture's hand-shape names.
    spec : str or sequence of str
        ``all``; ``upper`` or ``lower`` (the synthetic actor's 6 upper-face and 12 lower-face muscles, as in
        the paper's section 5.3); ``random<k>`` (``k`` shapes drawn without replacement); or a list of names.
    seed : int
        Seed of the draw for ``random<k>`` (``basis.subset_seed``).

    Returns
    -------
    ndarray of int
        Indices into ``names``, ascending.
    """
    from workbench.dataset.synthetic.muscles import LOWER_FACE, UPPER_FACE

    names = list(names)
    if isinstance(spec, str) and spec == "all":
        return np.arange(len(names))
    if isinstance(spec, str) and spec in ("upper", "lower"):
        region = UPPER_FACE if spec == "upper" else LOWER_FACE
        index = np.array([i for i, name in enumerate(names) if name in region], dtype=int)
        if index.size == 0:
            raise WorkbenchError(f"basis.hand_subset={spec} names the synthetic actor's {spec}-face muscles, and "
                                 "this dataset's hand shapes include none of them; list the shapes by name instead")
        return index
    if isinstance(spec, str):
        match = re.fullmatch(r"random(\d+)", spec)
        if match is None:
            raise WorkbenchError(f"basis.hand_subset must be all, upper, lower, random<k> or a list of hand-shape "
                                 f"names, got {spec!r}")
        k = int(match.group(1))
        if not 1 <= k <= len(names):
            raise WorkbenchError(f"basis.hand_subset=random{k} needs 1 <= k <= {len(names)} (the hand shapes)")
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise WorkbenchError(f"basis.subset_seed must be a non-negative integer, got {seed!r}")
        return np.sort(np.random.default_rng(int(seed)).choice(len(names), size=k, replace=False))
    unknown = [name for name in spec if name not in names]
    if unknown or not spec or len(set(spec)) != len(spec):
        raise WorkbenchError(f"basis.hand_subset as a list must name distinct hand shapes of {names}; "
                             f"got {list(spec)}")
    return np.array(sorted(names.index(name) for name in spec), dtype=int)


def subset_hand_shapes(capture: Capture, basis_cfg: Mapping) -> Capture:
    """The capture with only the hand shapes ``basis.hand_subset`` keeps."""
    spec = basis_cfg.get("hand_subset", "all")
    index = hand_subset_indices(capture.hand_names, spec, basis_cfg.get("subset_seed", 0))
    if index.size == len(capture.hand_names):
        return capture
    return select_shapes(capture, [capture.hand_names[i] for i in index])


def select_shapes(capture: Capture, names: Sequence[str]) -> Capture:
    """The capture with the hand shapes of these names, in this order."""
    if tuple(names) == tuple(capture.hand_names):
        return capture
    missing = [name for name in names if name not in capture.hand_names]
    if missing:
        raise WorkbenchError(f"hand shapes {missing} are missing from the evaluated data's hand basis")
    index = [capture.hand_names.index(name) for name in names]
    return replace(capture, hand=capture.hand[index], hand_names=tuple(names))


def fit_bases(capture: Capture, basis_cfg: Mapping, timings: Timings) -> tuple[Eigenfaces, dict]:
    """Eigenfaces (eq. 2) of the training frames and the quasi-eigen faces (eq. 3-4) of each projection.

    Returns
    -------
    eigenfaces : Eigenfaces
    quasi_eigen : dict
        Projection name -> :class:`workbench.bases.QuasiEigenBasis`.
    """
    with timings.stage("pca"):
        eigenfaces = fit_eigenfaces(capture, basis_cfg["coverage"], basis_cfg["n_components"])
    with timings.stage("quasi_eigen"):
        quasi_eigen = {
            projection: build_quasi_eigen_basis(
                capture.hand, capture.hand_names, eigenfaces, projection=projection,
                empty_axis_eps=basis_cfg["empty_axis_eps"], empty_axis_scale=basis_cfg["empty_axis_scale"],
                append_empty_axes=basis_cfg["append_empty_axes"])
            for projection in basis_cfg["projections"]}
    return eigenfaces, quasi_eigen


def fit_eigenfaces(capture: Capture, coverage: float, n_components: int | None = None) -> Eigenfaces:
    """Eigenfaces (eq. 2) of a capture's training frames, m by the coverage rule or fixed."""
    eigenfaces = Eigenfaces(coverage=coverage, n_components=n_components)
    if capture.train_source is not None:  # frames interpolated from markers: PCA in marker space, lifted
        return eigenfaces.fit_mapped(capture.train_source, capture.train_operator)
    return eigenfaces.fit(capture.train)


def pca_subspace(eigenfaces: Eigenfaces, transfer: PointTransfer | None = None) -> Subspace:
    """PCA's reconstruction at the evaluated points as an affine subspace: the (carried) mean plus the span of the
    (carried) eigenfaces, whose orthogonal projection is the reconstruction.

    Returns
    -------
    Subspace
        Orthonormal columns of shape (n_dims, m) and the mean as offset.
    """
    if transfer is None or transfer.operator is None:
        return Subspace(eigenfaces.components_.T, eigenfaces.mean_)
    # carried eigenfaces are no longer orthonormal: an orthonormal basis of their span
    orthonormal, _ = np.linalg.qr(transfer.apply(eigenfaces.components_).T)
    return Subspace(orthonormal, transfer.apply_one(eigenfaces.mean_))


def run_on_capture(data: str, capture: Capture, basis_cfg: Mapping, solvers: Mapping[str, Mapping],
                   timings: Timings, truth: np.ndarray | None = None) -> StudyResult:
    """The paper's method on one capture: eigenfaces, quasi-eigen faces, weights of every basis and solver, alpha.

    Parameters
    ----------
    data : str
        Name of the data variant, kept in the result.
    capture : Capture
    basis_cfg : mapping
        The ``basis`` config group.
    solvers : mapping
        Solver name -> keyword arguments of :func:`workbench.solve.solve_weights` (see :func:`check_solver_config`).
    timings : Timings
        Stage times are added to it.
    truth : ndarray of shape (n_eval_frames, 3 * n_points), optional
        The clean frames; every row is also scored against them (``metric.score_clean``).

    Returns
    -------
    StudyResult
    """
    eigenfaces, quasi_eigen = fit_bases(capture, basis_cfg, timings)
    rows, weights = score_bases(capture, eigenfaces, quasi_eigen, pca_subspace(eigenfaces), solvers, timings,
                                truth=truth)
    alternatives = fit_alternative_bases(capture, basis_cfg, timings)
    measured = {}
    if alternatives:
        more_rows, more_weights = score_alternative_bases(capture, alternatives, solvers, timings, truth=truth)
        rows, weights = rows + more_rows, {**weights, **more_weights}
        with timings.stage("intuitiveness"):
            measured = basis_intuitiveness(capture, eigenfaces, quasi_eigen, alternatives, weights,
                                           basis_cfg.get("intuitiveness") or {})
    return StudyResult(data=data, capture=capture, eigenfaces=eigenfaces, quasi_eigen=quasi_eigen, rows=rows,
                       weights=weights, timings=timings, train_on=data, eval_on=data, basis_intuitiveness=measured,
                       face_region=face_region(capture).description,
                       offset=offset_facts(pca_subspace(eigenfaces), rows))


def score_bases(capture: Capture, eigenfaces: Eigenfaces, quasi_eigen: Mapping, pca: Subspace,
                solvers: Mapping[str, Mapping], timings: Timings,
                truth: np.ndarray | None = None) -> tuple[list, dict]:
    """Weights (eq. 5) and alpha (eq. 6) of H and every quasi-eigen basis with every solver, then PCA.

    Parameters
    ----------
    capture : Capture
        The evaluated data; its ``hand`` is the H basis.
    eigenfaces : Eigenfaces
        For ``m`` of the PCA row (and its reconstruction under capture gaps).
    quasi_eigen : mapping
        Projection name -> :class:`workbench.bases.QuasiEigenBasis` at the capture's points.
    pca : Subspace
        PCA's reconstruction at the capture's points (:func:`pca_subspace`).
    solvers : mapping
    timings : Timings
    truth : ndarray of shape (n_eval_frames, 3 * n_points), optional
        The clean frames: every row is also scored against them (:func:`clean_scores`).

    Returns
    -------
    rows : list of Row
    weights : dict
        ``(basis, solver)`` -> ndarray of shape (n_eval_frames, n_shapes).
    """
    bases = [("H", "-", capture.hand)] + [
        (QE_LABELS[projection], projection, qe.shapes) for projection, qe in quasi_eigen.items()]
    with timings.stage("metrics"):
        conditioning = {label: basis_conditioning(shapes) for label, _, shapes in bases}
    if capture.eval_visible is None:
        offset, _ = outside_offset(pca)
        extra = {"PCA": pca, **({OFFSET: Subspace(offset[:, None])} if offset is not None else {})}
        rows, weights, projections = projected_rows(capture, bases, solvers, timings, conditioning, extra)
        with timings.stage("pca_reconstruction"):
            summary = summarise_squares(projections.distance_sq["PCA"], projections.displacement_sq,
                                        projections.position_sq, len(capture.eval) * capture.n_points)
        pca_fit = (pca.columns.T, projections.coordinates["PCA"], pca.offset)
        if offset is not None:
            rows = offset_error_shares(rows, weights, {label: shapes for label, _, shapes in bases}, offset,
                                       projections.coordinates[OFFSET][:, 0])
    else:
        rows, weights = masked_rows(capture, bases, solvers, timings, conditioning)
        with timings.stage("pca_reconstruction"):
            # with gaps the orthogonal projection becomes least squares on the eigenfaces over the seen points
            visible = capture.eval_visible
            offsets = solve_weights(eigenfaces.components_, capture.eval - eigenfaces.mean_, visible=visible).weights
            summary = summarise_alpha(
                capture.neutral, capture.eval,
                lambda rows: eigenfaces.mean_ + reconstruct(eigenfaces.components_, offsets[rows]),
                squares=reference_squares(capture.neutral, capture.eval, visible=visible), visible=visible)
        pca_fit = (eigenfaces.components_, offsets, eigenfaces.mean_)
    rows.append(Row(basis="PCA", projection="-", solver="projection", n_shapes=eigenfaces.n_components_,
                    alpha=summary))
    basis_shapes = {label: shapes for label, _, shapes in bases}
    with timings.stage("frame_measures"):
        rows = frame_measures(capture, rows, weights, basis_shapes, pca_fit)
    if truth is not None:
        directions, coefficients, mean = pca_fit
        with timings.stage("metrics"):
            rows = clean_scores(capture, truth, rows, basis_shapes, weights,
                                lambda frames: mean + reconstruct(directions, coefficients[frames]))
    return rows, weights


OFFSET = "(I-P) mu"
"""Label of the capture mean's part outside the eigenfaces' span among the subspaces of the projection pass."""


def outside_offset(pca: Subspace) -> tuple[np.ndarray | None, float]:
    """The capture mean's part outside the eigenfaces' span, ``(I - P) mu``: every affine quasi-eigen face is
    ``P e_i^H + (I - P) mu`` (eq. 3-4), so each carries this same offset, while PCA adds it once as its mean.

    Parameters
    ----------
    pca : Subspace
        The eigenfaces (orthonormal columns) and the mean ``mu`` as offset, at the evaluated points.

    Returns
    -------
    unit : ndarray of shape (n_dims,) or None
        Its direction; None when it is zero (to rounding).
    norm : float
    """
    if pca.offset is None:
        return None, 0.0
    mean = np.asarray(pca.offset, dtype=float)
    outside = mean - pca.columns @ (pca.columns.T @ mean)
    norm = float(np.linalg.norm(outside))
    if not norm > 1e-9 * max(float(np.linalg.norm(mean)), 1e-300):
        return None, norm
    return outside / norm, norm


def offset_facts(pca: Subspace, rows: Sequence[Row]) -> dict:
    """``norm`` of :func:`outside_offset` and its ``ratio`` to the median evaluated frame's displacement norm (NaN
    when that median is 0: most evaluated frames at rest, as the face region's ground truth of a short take)."""
    _, norm = outside_offset(pca)
    squares = rows[0].alpha.displacement_sq if rows else None
    if squares is None or not len(squares):
        return {}
    median = float(np.median(np.sqrt(squares)))
    return {"norm": norm, "ratio": norm / median if median > 0 else float("nan")}


def offset_error_shares(rows: Sequence[Row], weights: Mapping, shapes: Mapping[str, np.ndarray], unit: np.ndarray,
                        frames_along: np.ndarray) -> list[Row]:
    """The rows with the share of their squared error that lies along ``unit`` (``offset_error_share``).

    Parameters
    ----------
    rows : sequence of Row
    weights : mapping
        ``(basis, solver)`` -> weights of shape (n_frames, n).
    shapes : mapping
        Basis label -> shapes of shape (n, n_dims).
    unit : ndarray of shape (n_dims,)
    frames_along : ndarray of shape (n_frames,)
        Each evaluated frame's coordinate along ``unit``.
    """
    along = {label: basis @ unit for label, basis in shapes.items()}
    shared = []
    for row in rows:
        key = (row.basis, row.solver)
        if key in weights and row.basis in along and row.alpha.error_sq is not None:
            residual = frames_along - weights[key] @ along[row.basis]
            total = float(row.alpha.error_sq.sum())
            row = replace(row, offset_error_share=float(residual @ residual) / total if total > 0 else float("nan"))
        shared.append(row)
    return shared


@dataclass(frozen=True)
class FaceRegion:
    """The points the per-frame error in millimetres is taken over.

    Attributes
    ----------
    points : ndarray of shape (n_points,) of bool, or None
        None: every point of the capture.
    description : str
    """

    points: np.ndarray | None
    description: str


def face_region(capture: Capture) -> FaceRegion:
    """The face region of a capture's points, per dataset.

    - markers (no triangles): every marker of the capture (head markers used only to remove head motion are not
      among its points);
    - the synthetic mesh: the vertices some hand shape moves (the muscles' reach); the rest is the static head
      around the face;
    - the AnimFace mesh: the vertices within reach of the markers (``point_support``); the rest is extrapolated;
    - the ICT FaceKit mesh: its face region, vertices [0, 9409) of the model (the capture holds no others);
    - another mesh: every vertex.
    """
    kind, n = capture.provenance.get("kind"), capture.n_points
    if capture.provenance.get("train_on", "markers" if capture.faces is None else "mesh") == "markers":
        return FaceRegion(None, f"the face region: every one of the {n} markers")
    if kind == "synthetic":
        moved = np.linalg.norm(capture.hand.reshape(len(capture.hand), n, 3), axis=2).max(axis=0) > 0.0
        return FaceRegion(None if moved.all() else moved,
                          f"the face region: the {int(moved.sum())} of {n} mesh vertices some hand shape moves (the "
                          "muscles' reach; the rest of the head patch never moves)")
    if capture.point_support is not None and not capture.point_support.all():
        return FaceRegion(np.asarray(capture.point_support, dtype=bool),
                          f"the face region: the {int(capture.point_support.sum())} of {n} vertices within reach of "
                          "the markers (the others' motion is extrapolated)")
    if kind == "ict_livelink":
        region = capture.provenance.get("region_vertices")
        return FaceRegion(None, f"the ICT face region (the {n} vertices of [0, {region}) of the model)")
    return FaceRegion(None, f"the face region: every one of the {n} vertices")


def frame_measures(capture: Capture, rows: Sequence[Row], weights: Mapping, shapes: Mapping[str, np.ndarray],
                   pca_fit: tuple | None = None) -> list[Row]:
    """The rows with their per-frame error in millimetres over the face region (and its distribution) and the
    statistics of their weights.

    Parameters
    ----------
    capture : Capture
    rows : sequence of Row
    weights : mapping
        ``(basis, solver)`` -> weights of shape (n_eval_frames, n).
    shapes : mapping
        Basis label -> shapes of shape (n, n_dims) (for the error over a part of the points).
    pca_fit : tuple, optional
        PCA's reconstruction ``offset + coefficients @ directions`` as ``(directions (k, n_dims), coefficients
        (n_eval_frames, k), offset (n_dims,))``, for its row.

    Returns
    -------
    list of Row
    """
    region, timeline = face_region(capture), capture.timeline()
    takes = np.unique(timeline.take, return_inverse=True)[1]  # compared once, as integers
    points = np.ones(capture.n_points, dtype=bool) if region.points is None else region.points
    visible = capture.eval_visible
    counts = (visible[:, points].sum(axis=1) if visible is not None else int(points.sum()))
    fits = {}
    for row in rows:
        key = (row.basis, row.solver)
        if key in weights:
            fits[key] = (shapes[row.basis], weights[key], None)
        elif row.basis == "PCA" and pca_fit is not None:
            fits[key] = pca_fit
    explicit = region_error_sq(capture.eval, points, fits, visible) if region.points is not None else {}
    measured = []
    for row in rows:
        key = (row.basis, row.solver)
        error_sq = explicit.get(key, row.alpha.error_sq if region.points is None else None)
        per_frame = frame_rms_error(error_sq, counts) if error_sq is not None else None
        statistics = weight_statistics(weights[key], timeline.seconds, takes) if key in weights else None
        measured.append(replace(row, weight_statistics=statistics, frame_error_mm=per_frame,
                                error_mm=error_distribution(per_frame) if per_frame is not None else None))
    nnls = {row.basis: row.alpha.error_sq for row in measured if row.solver == "nnls"}
    return [replace(row, weight_statistics=replace(row.weight_statistics, needs_negative_share=needs_negative_share(
                row.alpha.error_sq, nnls[row.basis], row.alpha.displacement_sq))) if row.solver == "lstsq" and row.basis in nnls
            and row.weight_statistics is not None else row for row in measured]


def region_error_sq(frames, points: np.ndarray, fits: Mapping, visible: np.ndarray | None = None) -> dict:
    """Squared reconstruction error of each frame over some points only, one pass over the frames for every fit.

    Each fit's error is ``|x - o|^2 - 2 w.(S (x - o)) + w^T S S^T w`` over the points' coordinates, from one
    product of the frames with every fit's shapes and offset (no reconstruction is formed); frames where those
    terms cancel to below ``EXPLICIT_BELOW`` of their size get the explicit residual, as
    :func:`workbench.reduced.project_frames` does.

    Parameters
    ----------
    frames : ndarray of shape (n_frames, 3 * n_points) or FramesOnDisk
    points : ndarray of shape (n_points,) of bool
    fits : mapping
        Key -> ``(shapes (k, n_dims), weights (n_frames, k), offset (n_dims,) or None)``: the reconstruction
        ``offset + weights @ shapes``.
    visible : ndarray of shape (n_frames, n_points) of bool, optional
        Points each frame saw; only those count (then every residual is formed explicitly).

    Returns
    -------
    dict
        Key -> ndarray of shape (n_frames,).
    """
    from workbench.reduced import EXPLICIT_BELOW

    dims = np.repeat(points, 3)
    # one block of columns per distinct basis and offset (a basis solved by several solvers is taken once)
    blocks, parts, where, quadratic = {}, {}, {}, {}
    for key, (shapes, weights, offset) in fits.items():
        basis = (id(shapes), id(offset))
        if basis not in blocks:
            restricted = np.zeros(int(dims.sum())) if offset is None else np.asarray(offset, dtype=float)[dims]
            blocks[basis] = (shapes[:, dims], restricted)
            where[basis] = sum(len(block) + 1 for block, _ in list(blocks.values())[:-1])
            quadratic[basis] = (blocks[basis][0] @ blocks[basis][0].T, blocks[basis][0] @ restricted,
                                float(restricted @ restricted))
        parts[key] = (*blocks[basis], weights, basis)
    together = np.vstack([np.vstack([shapes, offset]) for shapes, offset in blocks.values()]).T
    errors = {key: np.empty(frames.shape[0]) for key in fits}
    for rows, chunk in frame_chunks(frames):
        chunk = chunk[:, dims]
        if visible is not None:
            seen = np.repeat(visible[rows][:, points], 3, axis=1)
            for key, (shapes, offset, weights, _) in parts.items():
                difference = np.where(seen, chunk - weights[rows] @ shapes - offset, 0.0)
                errors[key][rows] = np.einsum("ij,ij->i", difference, difference)
            continue
        products, squares = chunk @ together, np.einsum("ij,ij->i", chunk, chunk)
        for key, (shapes, offset, weights, basis) in parts.items():
            gram, shapes_offset, offset_sq = quadratic[basis]
            k, w, first = shapes.shape[0], weights[rows], where[basis]
            along = products[:, first:first + k] - shapes_offset  # S (x - o)
            frame_offset = products[:, first + k]
            error = (squares - 2.0 * frame_offset + offset_sq - 2.0 * np.einsum("ij,ij->i", w, along)
                     + np.einsum("ij,ij->i", w @ gram, w))
            close = np.flatnonzero(error <= EXPLICIT_BELOW * (squares + offset_sq))
            if close.size:
                residual = chunk[close] - w[close] @ shapes - offset
                error[close] = np.einsum("ij,ij->i", residual, residual)
            errors[key][rows] = np.maximum(error, 0.0)
    return errors


def projected_rows(capture: Capture, bases: Sequence[tuple], solvers: Mapping[str, Mapping], timings: Timings,
                   conditioning: Mapping | None = None, subspaces: Mapping[str, Subspace] | None = None
                   ) -> tuple[list, dict, FrameProjections]:
    """Weights (eq. 5) and alpha (eq. 6) of each basis with every solver, from one pass over the evaluated frames.

    The pass (:func:`workbench.reduced.project_frames`) takes the frames' coordinates in every basis's span and
    in ``subspaces``; each solver then works on the ``n``-dimensional coordinates and alpha comes from them, so
    the frames are read once whatever the number of bases and solvers.

    Parameters
    ----------
    capture : Capture
        Without capture gaps (``eval_visible`` None).
    bases : sequence of (label, projection, shapes)
        ``shapes`` of shape (n, n_dims).
    solvers : mapping
    timings : Timings
    conditioning : mapping, optional
        Label -> :class:`Conditioning`, kept in the rows with each basis's largest weight; None: neither.
    subspaces : mapping, optional
        More affine subspaces to take in the same pass (label -> :class:`Subspace`), e.g. PCA's.

    Returns
    -------
    rows : list of Row
        Solver by solver, bases in the given order.
    weights : dict
        ``(basis, solver)`` -> ndarray of shape (n_eval_frames, n).
    projections : FrameProjections
    """
    with timings.stage("projection"):
        reductions = {label: reduce_basis(shapes) for label, _, shapes in bases}
        projections = project_frames(
            capture.eval, {**{label: Subspace(r.u) for label, r in reductions.items()}, **(subspaces or {})},
            capture.neutral)
    n_compared = len(capture.eval) * capture.n_points
    rows, weights = [], {}
    for solver_name, solver in solvers.items():
        for label, projection, shapes in bases:
            reduction, coordinates = reductions[label], projections.coordinates[label]
            with timings.stage(f"solve_{solver_name}"):
                solution = solve_projected(reduction, coordinates, **solver)
            with timings.stage("metrics"):
                error_sq = projections.distance_sq[label] + in_span_error_sq(reduction, coordinates, solution.weights)
                summary = summarise_squares(error_sq, projections.displacement_sq, projections.position_sq,
                                            n_compared)
            weights[(label, solver_name)] = solution.weights
            rows.append(solved_row(label, projection, solver_name, shapes, summary, solution, conditioning))
    return rows, weights, projections


def masked_rows(capture: Capture, bases: Sequence[tuple], solvers: Mapping[str, Mapping], timings: Timings,
                conditioning: Mapping | None = None) -> tuple[list, dict]:
    """:func:`projected_rows` under capture gaps: each frame solved and scored on the points it saw."""
    visible = capture.eval_visible
    with timings.stage("metrics"):
        squares = reference_squares(capture.neutral, capture.eval, visible=visible)
    rows, weights = [], {}
    for solver_name, solver in solvers.items():
        for label, projection, shapes in bases:
            with timings.stage(f"solve_{solver_name}"):
                solution = solve_weights(shapes, capture.eval, visible=visible, **solver)
            with timings.stage("metrics"):
                summary = summarise_alpha(capture.neutral, capture.eval,
                                          lambda rows: reconstruct(shapes, solution.weights[rows]), squares=squares,
                                          visible=visible)
            weights[(label, solver_name)] = solution.weights
            rows.append(solved_row(label, projection, solver_name, shapes, summary, solution, conditioning))
    return rows, weights


def solved_row(label: str, projection: str, solver_name: str, shapes: np.ndarray, summary: AlphaSummary,
               solution, conditioning: Mapping | None) -> Row:
    """The table row of one basis solved with one solver (its largest weight and conditioning with
    ``conditioning``)."""
    extra = {} if conditioning is None else {"max_abs_weight": float(np.abs(solution.weights).max()),
                                             "conditioning": conditioning[label]}
    return Row(basis=label, projection=projection, solver=solver_name, n_shapes=shapes.shape[0], alpha=summary,
               n_iterations=solution.n_iterations, n_fallback_frames=solution.n_fallback_frames,
               max_kkt_violation=solution.max_kkt_violation, **extra)


def intuitiveness_table(result: StudyResult) -> list[dict]:
    """Per hand shape and projection: relative distance and cosine between ``e_i^H`` and ``e_i^QE``."""
    records = []
    n_hand = result.capture.hand.shape[0]
    for projection, qe in result.quasi_eigen.items():
        distance, cosine = intuitiveness(result.capture.hand, qe.shapes[:n_hand])
        for name, d, c, norm in zip(result.capture.hand_names, distance, cosine,
                                    np.linalg.norm(result.capture.hand, axis=1)):
            records.append({"projection": projection, "shape": name, "relative_distance": float(d),
                            "cosine": float(c), "hand_norm": float(norm)})
    return records


# ---------------------------------------------------------------------------------------------------------------
# Other bases beside the paper's (basis.alternatives) and the intuitiveness of every basis
# ---------------------------------------------------------------------------------------------------------------

ALTERNATIVE_OPTIONS = {"SPCA": "spca", "ICA": "ica", "NMF": "nmf", "SPLOCS": "splocs", "H-fit": "hand_fit"}
"""Basis label -> the ``basis`` config key holding its options."""


def fit_alternative_bases(capture: Capture, basis_cfg: Mapping, timings: Timings) -> dict:
    """Fit the bases ``basis.alternatives`` names on the training frames (:mod:`workbench.alternatives`).

    Returns
    -------
    dict
        Label (``SPCA``, ``ICA``, ``NMF``, ``SPLOCS``, ``H-fit``) -> ndarray of shape (n, n_dims), in the
        configured order; ``n`` is ``basis.alternatives_n`` or the hand basis size (H-fit: always the latter).
    """
    from workbench import alternatives as alt

    names = basis_cfg.get("alternatives") or []
    names = [names] if isinstance(names, str) else list(names)
    if any(name not in ALTERNATIVE_OPTIONS for name in names) or len(set(names)) != len(names):
        raise WorkbenchError(f"basis.alternatives must list distinct names of {list(ALTERNATIVE_OPTIONS)}, "
                             f"got {names}")
    n = basis_cfg.get("alternatives_n") or capture.hand.shape[0]
    seed = int(basis_cfg.get("alternatives_seed") or 0)
    bases = {}
    for name in names:
        key = ALTERNATIVE_OPTIONS[name]
        options = dict(basis_cfg.get(key) or {})
        with timings.stage(f"fit_{key}"):
            if name == "SPCA":
                bases[name] = alt.sparse_pca_basis(capture.train, n_components=n, **options)
            elif name == "ICA":
                bases[name] = alt.ica_basis(capture.train, n_components=n, seed=seed, **options)
            elif name == "NMF":
                bases[name] = alt.nmf_basis(capture.train, n_components=n, seed=seed, **options)
            elif name == "SPLOCS":
                distance = alt.SurfaceDistance(capture.neutral, capture.faces)
                bases[name] = alt.splocs_basis(capture.train, distance, n_components=n, **options)
            else:
                bases[name] = alt.fitted_hand_basis(capture.train, capture.hand, **options)
    return bases


def score_alternative_bases(capture: Capture, bases: Mapping[str, np.ndarray], solvers: Mapping[str, Mapping],
                            timings: Timings, truth: np.ndarray | None = None) -> tuple[list, dict]:
    """Weights (eq. 5) and alpha (eq. 6) of each alternative basis with every solver, exactly as H and QE (and
    against the clean frames ``truth`` when given).

    Returns
    -------
    rows : list of Row
        Projection ``-``; solver by solver, bases in the configured order.
    weights : dict
        ``(basis, solver)`` -> ndarray of shape (n_eval_frames, n).
    """
    listed = [(label, "-", shapes) for label, shapes in bases.items()]
    if getattr(capture, "eval_visible", None) is not None:  # frames with capture gaps: visible points only
        rows, weights = masked_rows(capture, listed, solvers, timings)
    else:
        rows, weights, _ = projected_rows(capture, listed, solvers, timings)
    with timings.stage("frame_measures"):
        rows = frame_measures(capture, rows, weights, bases)
    if truth is not None:
        rows = clean_scores(capture, truth, rows, dict(bases), weights)
    return rows, weights


def basis_intuitiveness(capture: Capture, eigenfaces: Eigenfaces, quasi_eigen: Mapping,
                        alternatives: Mapping[str, np.ndarray], weights: Mapping, settings: Mapping) -> dict:
    """Closeness to the hand shapes, locality and usage of H, each quasi-eigen basis, PCA and the alternatives
    (:mod:`workbench.intuitiveness`), as plain values for the run record.

    Parameters
    ----------
    capture : Capture
    eigenfaces : Eigenfaces
    quasi_eigen : mapping
        Projection -> :class:`workbench.bases.QuasiEigenBasis`.
    alternatives : mapping
        Label -> shapes of shape (n, n_dims).
    weights : mapping
        ``(basis, solver)`` -> weights of the evaluated frames, shape (n_eval_frames, n).
    settings : mapping
        ``locality_energy`` and ``usage_threshold`` (``basis.intuitiveness``).

    Returns
    -------
    dict
        ``locality_energy``, ``usage_threshold``, ``point_weights`` and ``bases``: one entry per basis with
        ``basis``, ``n``, ``matched_abs_cosine`` (mean over matched pairs), ``locality`` (mean over elements),
        ``usage`` (solver -> mean elements used per evaluated frame) and ``elements`` (per element: the matched
        hand shape, its ``|cosine|`` and the element's locality).
    """
    from workbench.intuitiveness import (LOCALITY_ENERGY, USAGE_THRESHOLD, locality, matched_closeness,
                                         point_areas, usage)

    energy = float(settings.get("locality_energy", LOCALITY_ENERGY))
    threshold = float(settings.get("usage_threshold", USAGE_THRESHOLD))
    areas = point_areas(capture.neutral, capture.faces)
    bases = {"H": capture.hand, **{QE_LABELS[p]: qe.shapes for p, qe in quasi_eigen.items()},
             "PCA": eigenfaces.components_, **alternatives}
    per_basis = {label: {solver: w for (b, solver), w in weights.items() if b == label} for label in bases}
    if getattr(capture, "eval_visible", None) is None:  # PCA's weights: the projection coefficients
        per_basis["PCA"] = {"projection": (capture.eval - eigenfaces.mean_) @ eigenfaces.components_.T}
    entries = []
    for label, shapes in bases.items():
        element, hand_index, cosine = matched_closeness(shapes, capture.hand)
        local = locality(shapes, areas, energy)
        entries.append({
            "basis": label, "n": int(shapes.shape[0]), "matched_abs_cosine": float(cosine.mean()),
            "locality": float(np.nanmean(local)),
            "usage": {solver: float(usage(w, shapes, threshold).mean()) for solver, w in per_basis[label].items()},
            "elements": [{"element": int(e), "hand_shape": capture.hand_names[h], "abs_cosine": float(c),
                          "locality": float(local[e])} for e, h, c in zip(element, hand_index, cosine)],
        })
    return {"locality_energy": energy, "usage_threshold": threshold,
            "point_weights": "mesh triangle areas" if capture.faces is not None else "equal per point",
            "bases": entries}
