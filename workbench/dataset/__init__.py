"""The dataset stage: build a :class:`Capture` (displacements, neutral, hand basis) from a dataset config."""

from __future__ import annotations

from functools import lru_cache
from typing import Mapping, Sequence

import numpy as np

from workbench.dataset.animface import build_animface
from workbench.dataset.cache import cached_captures
from workbench.dataset.capture import Capture
from workbench.dataset.decimate import Decimation, decimate
from workbench.dataset.gaps import fill_gaps, make_gap_mask
from workbench.dataset.ict_livelink import build_ict_livelink
from workbench.dataset.rbf import mesh_rbf_operator
from workbench.dataset.rigid import stabilise
from workbench.dataset.transfer import apply_point_operator
from workbench.errors import WorkbenchError
from workbench.progress import progress

SPLITS = ("same", "tail")
TRAIN_ON = ("markers", "mesh", "mesh_rbf")


def split_frames(frames: np.ndarray, split: str, eval_fraction: float) -> tuple[np.ndarray, np.ndarray]:
    """Choose training and evaluation frames.

    Parameters
    ----------
    frames : ndarray of shape (n_frames, n_dims)
    split : {"same", "tail"}
        ``same`` trains and evaluates on every frame, as the paper does; ``tail`` holds out the last
        ``eval_fraction`` of the take for evaluation.
    eval_fraction : float
        In (0, 1), used by ``tail``.

    Returns
    -------
    train, eval : ndarray
    """
    if split not in SPLITS:
        raise WorkbenchError(f"dataset.split must be one of {SPLITS}, got {split!r}")
    if split == "same":
        return frames, frames
    if not 0.0 < eval_fraction < 1.0:
        raise WorkbenchError(f"dataset.eval_fraction must be in (0, 1) for split 'tail', got {eval_fraction}")
    n_eval = int(round(eval_fraction * len(frames)))
    if n_eval < 1 or n_eval > len(frames) - 2:
        raise WorkbenchError(f"dataset.eval_fraction {eval_fraction} leaves {n_eval} of {len(frames)} frames "
                             "for evaluation; need at least 1 and at least 2 for training")
    return frames[:-n_eval], frames[-n_eval:]


def train_on_list(cfg: Mapping, allowed: Sequence[str]) -> list[str]:
    """``dataset.train_on`` as a list of distinct names (one name or a list of them), each in ``allowed``."""
    value = cfg.get("train_on", allowed[0])
    names = [value] if isinstance(value, str) else list(value)
    if not names or any(name not in allowed for name in names) or len(set(names)) != len(names):
        raise WorkbenchError(f"dataset.train_on must be one of {tuple(allowed)} or a list of distinct ones, "
                             f"got {value!r}")
    return names


def build_synthetic(cfg: Mapping) -> dict[str, Capture]:
    """The synthetic actor's capture: stabilised markers, the dense mesh and/or the markers interpolated onto it.

    Parameters
    ----------
    cfg : mapping
        The ``dataset`` config group (see ``conf/dataset/synthetic.yaml``).

    Returns
    -------
    dict
        ``train_on`` name (``markers``, ``mesh`` or ``mesh_rbf``) -> :class:`Capture`, all from the same take
        (with ``split: other_take``, the evaluated frames come from a second take of the same actor).
    """
    names = train_on_list(cfg, TRAIN_ON)
    split = cfg.get("split", "same")
    if split not in SPLITS + ("other_take",):
        raise WorkbenchError(f"dataset.split must be one of {SPLITS + ('other_take',)}, got {split!r}")
    seeds = [int(cfg["seed"])] + ([_eval_seed(cfg)] if split == "other_take" else [])
    takes = [_synthetic_take(_take_key(cfg, seed)) for seed in seeds]
    decimation = _mesh_decimation(int(cfg["mesh_rows"]), int(cfg["mesh_cols"]), cfg.get("mesh_fraction", 1.0))
    hand_mesh = takes[0].hand_shapes_mesh()
    markers = ([_face_marker_frames(take, cfg) for take in takes]
               if {"markers", "mesh_rbf"} & set(names) else None)
    return {name: _synthetic_capture(takes, hand_mesh, decimation, markers, name, cfg) for name in names}


def _take_key(cfg: Mapping, seed: int) -> tuple:
    """The generation parameters of a take, hashable (the cache key of :func:`_synthetic_take`)."""
    return (("n_frames", cfg["n_frames"]), ("frame_rate", cfg["frame_rate"]),
            ("n_face_markers", cfg["n_face_markers"]), ("n_head_markers", cfg["n_head_markers"]),
            ("head_rotation_deg", cfg["head_rotation_deg"]), ("head_translation_mm", cfg["head_translation_mm"]),
            ("marker_noise_mm", cfg["marker_noise_mm"]), ("seed", seed), ("mesh_rows", cfg["mesh_rows"]),
            ("mesh_cols", cfg["mesh_cols"]))


@lru_cache(maxsize=2)
def _synthetic_take(key: tuple):
    """The take of these parameters; kept for the next run of a sweep in the same process (its arrays are
    read-only, and the take is a deterministic function of its parameters)."""
    from workbench.dataset.synthetic import make_synthetic_take

    return make_synthetic_take(**dict(key))


@lru_cache(maxsize=4)
def _mesh_decimation(mesh_rows: int, mesh_cols: int, fraction: float) -> Decimation:
    from workbench.dataset.synthetic import make_face_mesh

    mesh = make_face_mesh(mesh_rows, mesh_cols)
    return decimate(mesh.vertices, mesh.faces, fraction)


@lru_cache(maxsize=2)
def _mesh_frames(key: tuple, mesh_fraction: float) -> np.ndarray:
    """Dense ground-truth displacements at the kept vertices, shape (n_frames, 3 * n_kept), read-only.

    The muscles act on each point alone, so deforming only the kept vertices gives exactly their rows of the
    full mesh sequence, at a cost that falls with the mesh density.
    """
    from workbench.dataset.synthetic import deform

    take = _synthetic_take(key)
    kept = _mesh_decimation(take.mesh.grid_shape[0], take.mesh.grid_shape[1], mesh_fraction).kept
    rest = take.mesh.vertices[kept]
    chunk = max(1, -(-take.n_frames // 20))  # frames per progress step
    frames = np.empty((take.n_frames, len(rest), 3))
    for start in progress(range(0, take.n_frames, chunk), desc="mesh frames"):
        frames[start:start + chunk] = deform(rest, take.activations[start:start + chunk]) - rest
    frames = frames.reshape(take.n_frames, -1)
    frames.setflags(write=False)
    return frames


def _eval_seed(cfg: Mapping) -> int:
    seed = cfg.get("eval_seed")
    return int(cfg["seed"]) + 1 if seed is None else int(seed)


def _face_marker_frames(take, cfg: Mapping) -> tuple[np.ndarray, tuple[str, ...], dict]:
    """Stabilised face markers of one take as displacements from rest, after the gap policy.

    Returns
    -------
    frames : ndarray of shape (n_frames, n_face_markers, 3)
    notes : tuple of str
    gaps : dict
        The gap policy's report (empty without dropout).
    """
    positions, notes, gaps = take.markers, [], {}
    rate = float(cfg.get("gap_rate", 0.0))
    if rate > 0:
        # the take draws from the first three children of its seed; gaps use the fourth
        rng = np.random.default_rng(np.random.SeedSequence(take.provenance["seed"], spawn_key=(3,)))
        mask = make_gap_mask(positions.shape[0], positions.shape[1], rate,
                             float(cfg.get("gap_mean_frames", 12)), rng)
        positions, report = fill_gaps(np.where(mask[:, :, None], np.nan, positions),
                                      cfg.get("gap_policy", "linear"))
        gaps = dict(report.as_dict(), rate=rate, mean_frames=float(cfg.get("gap_mean_frames", 12)))
        notes.append(f"marker dropout (seed {take.provenance['seed']}): {report.n_missing_samples} missing samples "
                     f"({100 * report.missing_fraction:.2f} %, longest gap {report.longest_gap_frames} frames), "
                     f"filled by policy '{report.policy}' before head-motion removal")
    head = np.asarray(take.head_marker_index)
    if cfg.get("stabilise", True):
        stable = stabilise(positions, head, take.head_marker_rest)
        positions = stable.markers
        notes.append(f"head motion removed with {head.size} head markers; rigid residual RMS "
                     f"{np.mean(stable.residual_rms):.3f} mm (mean over frames)")
    else:
        notes.append("head motion NOT removed (dataset.stabilise=false)")
    face_index = np.setdiff1d(np.arange(take.markers.shape[1]), head)
    neutral = take.mesh.vertices[take.face_marker_vertices]
    return positions[:, face_index] - neutral, tuple(notes), gaps


def _synthetic_capture(takes: Sequence, hand_mesh: np.ndarray, decimation: Decimation, markers, train_on: str,
                       cfg: Mapping) -> Capture:
    """One data variant of the synthetic take(s).

    Parameters
    ----------
    takes : sequence of SyntheticTake
        The take, and with ``split: other_take`` the take the evaluated frames come from.
    hand_mesh : ndarray of shape (18, n_vertices, 3)
    decimation : Decimation
        The kept mesh vertices (all of them at ``mesh_fraction`` 1).
    markers : list of the results of :func:`_face_marker_frames`, one per take, or None
    train_on : {"markers", "mesh", "mesh_rbf"}
    cfg : mapping
    """
    take, notes, faces = takes[0], [], None
    vertices = take.mesh.vertices
    provenance = dict(take.provenance, train_on=train_on)
    if train_on == "markers":
        points = take.face_marker_vertices
        per_take = [frames.reshape(len(frames), -1) for frames, _, _ in markers]
        notes += markers[0][1]
        labels = tuple(take.marker_labels[i] for i in take.face_marker_index)
    else:
        points = decimation.kept
        faces = decimation.faces
        labels = tuple(f"v{i}" for i in points)
        if decimation.fraction < 1.0:
            notes.append(f"mesh decimated to {points.size} of {len(vertices)} vertices (mesh_fraction "
                         f"{decimation.fraction}, quadric edge collapse); data and shapes taken at the kept vertices")
        provenance.update(mesh_fraction=decimation.fraction, n_mesh_points=int(points.size))
        if train_on == "mesh":
            per_take = [_mesh_frames(_take_key(cfg, t.provenance["seed"]), cfg.get("mesh_fraction", 1.0))
                        for t in takes]
            notes.append("the dense ground-truth mesh (no head motion, no marker noise)")
        else:
            operator = mesh_rbf_operator(vertices, take.mesh.faces, take.face_marker_vertices, points,
                                         metric="euclidean")
            per_take = [apply_point_operator(operator, frames).reshape(len(frames), -1) for frames, _, _ in markers]
            notes += markers[0][1]
            notes.append(f"stabilised markers interpolated onto {points.size} mesh vertices by a thin-plate-spline "
                         "RBF (Euclidean, linear polynomial)")
    if markers is not None and markers[0][2] and train_on != "mesh":
        provenance["gaps"] = markers[0][2]
    split = cfg.get("split", "same")
    if split == "other_take":
        train, evaluate = per_take
        notes.append(f"split 'other_take': {len(train)} training frames of take seed {takes[0].provenance['seed']}, "
                     f"{len(evaluate)} evaluated of take seed {takes[1].provenance['seed']}")
        provenance["eval_seed"] = takes[1].provenance["seed"]
    else:
        train, evaluate = split_frames(per_take[0], split, cfg.get("eval_fraction", 0.2))
        notes.append(f"split '{split}': {len(train)} training frames, {len(evaluate)} evaluated")
    hand = hand_mesh[:, points]
    return Capture(
        name="synthetic actor (generated by the workbench; not real capture)",
        neutral=vertices[points].reshape(-1), train=train, eval=evaluate,
        hand=hand.reshape(hand.shape[0], -1), hand_names=tuple(take.muscle_names), point_labels=labels,
        units="mm", origin="centre of the synthetic head (face points lie 60-110 mm from it)",
        frame_rate=float(cfg["frame_rate"]), provenance=provenance, notes=tuple(notes), faces=faces)


BUILDERS = {"synthetic": build_synthetic, "ict_livelink": build_ict_livelink, "animface": build_animface}
"""``dataset.kind`` -> builder taking the ``dataset`` config group and returning ``{train_on name: Capture}``."""


def build_captures(cfg: Mapping, cache_dir: str | None = None) -> dict[str, Capture]:
    """Build the captures a dataset config describes, one per ``dataset.train_on`` name.

    The same config (and dataset code and source files) gives the captures built before: from memory within a
    process, from ``cache_dir`` across processes when it is set (:mod:`workbench.dataset.cache`).

    Parameters
    ----------
    cfg : mapping
        The ``dataset`` config group; ``kind`` selects the builder.
    cache_dir : str, optional
        Folder of the disk cache (``paths.cache_dir``); memory only when None.

    Returns
    -------
    dict
        ``train_on`` name -> :class:`Capture`, in the configured order.
    """
    kind = cfg.get("kind")
    if kind not in BUILDERS:
        raise WorkbenchError(f"dataset.kind must be one of {sorted(BUILDERS)}, got {kind!r}")
    return cached_captures(cfg, BUILDERS[kind], cache_dir)
