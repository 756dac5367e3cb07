"""Dataset ``ict_livelink``: a FACS-based blendshape face (ICT FaceKit) driven by real ARKit weight curves.

The performance is the linear blendshape face of eq. 1 driven, frame by frame, with the weights a Live Link
Face take recorded from a real person: real human motion on a real FACS-based face. ``mesh`` trains on the
face-region vertices, ``markers`` on virtual markers at the vertices of a marker table.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import numpy as np

from workbench.dataset.cache import code_fingerprint
from workbench.dataset.capture import Capture, Timeline
from workbench.dataset.common import array_digest, name_list, split_frames
from workbench.dataset.correspondence import read_marker_table
from workbench.dataset.hand_basis import check_hand_shapes
from workbench.dataset.real import (
    ICT_CREDIT,
    LIVELINK_CREDIT,
    conf_path,
    data_path,
    frame_selection,
    hand_shape_names,
    load_basis,
    mesh_point_indices,
    origin_text,
)
from workbench.dataset.storage import FrameStorage
from workbench.formats.livelink import drive_blendshapes, map_arkit_channels, read_livelink_csv
from workbench.formats.obj import Blendshapes, expression_names
from workbench.formats.plausibility import (
    face_size_problems,
    frame_rate_problems,
    settle,
    static_weights_problems,
    unused_channel_problems,
    with_warnings,
)
from workbench.formats.weight_curves import read_weight_curves


def build_ict_livelink(cfg, storage: FrameStorage = FrameStorage()) -> dict[str, Capture]:
    """The ICT face driven by a Live Link Face take, on the mesh and/or at virtual markers.

    Parameters
    ----------
    cfg : typed dataset settings or mapping
        The ``dataset`` config group (see ``conf/dataset/ict_livelink.yaml``).
    storage : FrameStorage
        Where the frames are written, a chunk of frames at a time (``dataset.storage``, ``dataset.dtype``), so the
        dense mesh never exists whole in float64.

    Returns
    -------
    dict
        ``train_on`` name (``mesh`` or ``markers``) -> :class:`Capture`, from the same performance.
    """
    names = name_list(cfg.train_on)
    driven_take = _driven_take(cfg)
    curves_key, curves_path, take_name, take = (
        driven_take.curves_key,
        driven_take.curves_path,
        driven_take.take_name,
        driven_take.take,
    )
    frames, warnings, basis, mapping = driven_take.frames, driven_take.warnings, driven_take.basis, driven_take.mapping
    hand_names = driven_take.hand_names
    frame_rate = take.frame_rate / int(cfg.frame_step)
    weights = take.weights[frames]
    timeline = Timeline(
        take=np.full(len(frames), take_name), frame=frames, seconds=take.seconds[frames] - take.seconds[0]
    )

    marker_table = read_marker_table(conf_path(cfg.marker_table, "marker_table"), n_vertices=len(basis.neutral))
    marker_vertices = marker_table.require_vertices("dataset ict_livelink's virtual markers")
    hand_index = [basis.names.index(name) for name in hand_names]
    check_hand_shapes(
        basis.deltas[hand_index].reshape(len(hand_names), -1),
        hand_names,
        f"dataset.blendshapes.folder {data_path(cfg.data_root, cfg.blendshapes.folder, 'blendshapes.folder')}",
    )
    mesh_points = mesh_point_indices(len(basis.neutral), cfg.mesh_vertex_step, basis.deltas[hand_index], hand_names)
    points = {"mesh": mesh_points, "markers": marker_vertices}
    labels = {"mesh": tuple(f"v{i}" for i in mesh_points), "markers": marker_table.labels}

    notes_common, provenance = _shared_facts(cfg, driven_take, marker_table, marker_vertices, frame_rate)
    captures = {}
    for name in names:
        index = points[name]
        neutral = basis.neutral[index]
        deltas = basis.deltas[:, index].reshape(len(basis.names), -1)
        key = (array_digest(weights), array_digest(mapping.matrix), array_digest(deltas), code_fingerprint())
        displacements = storage.build(
            f"ict_livelink_{name}",
            key,
            len(weights),
            deltas.shape[1],
            lambda rows, deltas=deltas: drive_blendshapes(weights[rows], mapping, deltas),
        )
        train, evaluate = split_frames(displacements, cfg.split, cfg.eval_fraction)
        notes = list(notes_common)
        if name == "markers":
            notes.append(
                f"virtual markers: {len(index)} ICT vertices of {marker_table.path.name} (the AnimFace "
                "marker layout placed on the ICT face), exact (no noise)"
            )
        else:
            notes.append(f"mesh: {len(index)} face-region vertices (every {int(cfg.mesh_vertex_step)})")
        notes.append(f"split '{cfg.split}': {len(train)} training frames, {len(evaluate)} evaluated")
        faces = basis.triangles if name == "mesh" and len(index) == len(basis.neutral) else None
        captures[name] = Capture(
            name=(
                "ICT FaceKit face driven by a Live Link Face take (real ARKit weights)"
                if curves_key == "livelink_csv"
                else f"ICT FaceKit face driven by the weight curves of {curves_path.name}"
            ),
            neutral=neutral.reshape(-1),
            train=train,
            eval=evaluate,
            hand=deltas[hand_index],
            hand_names=tuple(hand_names),
            point_labels=labels[name],
            units="mm",
            origin=origin_text(
                "ICT FaceKit model origin: midline, about nose-tip height, near the centre of the head", neutral
            ),
            frame_rate=float(frame_rate),
            **with_warnings(notes, dict(provenance, train_on=name), warnings),
            faces=faces,
            eval_timeline=timeline[len(timeline) - len(evaluate) :],
        )
    return captures


@dataclass(frozen=True)
class _DrivenTake:
    """The weight curves of a take read and checked, and the ICT shapes they drive (:func:`_driven_take`)."""

    curves_key: str
    curves_path: Path
    take_name: str
    take: object
    frames: np.ndarray
    warnings: list
    driven: list
    basis: Blendshapes
    mapping: object
    hand_names: list
    folder_mapping: object


def _driven_take(cfg: Mapping) -> _DrivenTake:
    """Read the take's weight curves (Live Link CSV or ``dataset.weight_curves``), check them, and load the ICT
    shapes they drive and the hand shapes."""
    timecode_rate = float(cfg.timecode_rate)
    curves_key = "weight_curves" if cfg.weight_curves else "livelink_csv"
    curves_path = data_path(cfg.data_root, getattr(cfg, curves_key), curves_key)
    take_name = curves_path.stem
    if curves_key == "weight_curves":  # MediaPipe or generic named weights (workbench.formats.weight_curves)
        take = read_weight_curves(curves_path, frame_rate=cfg.weight_frame_rate, timecode_rate=timecode_rate)
    else:
        take = read_livelink_csv(curves_path, timecode_rate=timecode_rate)
    folder = data_path(cfg.data_root, cfg.blendshapes.folder, "blendshapes.folder")
    available = expression_names(folder, cfg.blendshapes.neutral)
    hand_names = hand_shape_names(cfg.hand_shapes, available)
    folder_mapping = map_arkit_channels(take.names, available, cfg.arkit_overrides or {})
    frames = frame_selection(take.n_frames, cfg.frame_step, cfg.max_frames, "dataset.max_frames")
    dropped = [channel for channel, shapes in (cfg.arkit_overrides or {}).items() if not shapes]
    problems = (
        static_weights_problems(take.weights[frames], str(take.path))
        + frame_rate_problems(take.frame_rate, str(take.path), "frame rate (from its time stamps)")
        + unused_channel_problems(
            [channel for channel in folder_mapping.unmapped if channel not in dropped],
            list(take.names),
            take.weights[frames],
            f"{take.path} with {folder}",
        )
    )
    warnings = settle(problems, cfg.plausibility)
    driven = [name for name in folder_mapping.shapes if name not in folder_mapping.undriven]
    basis = load_basis(cfg, sorted(set(driven) | set(hand_names)))
    warnings += settle(
        face_size_problems(basis.neutral, str(folder), "dataset.blendshapes.unit_mm", basis.unit_mm),
        cfg.plausibility,
    )
    mapping = map_arkit_channels(take.names, basis.names, cfg.arkit_overrides or {})  # rows of basis.deltas
    return _DrivenTake(
        curves_key=curves_key,
        curves_path=curves_path,
        take_name=take_name,
        take=take,
        frames=frames,
        warnings=warnings,
        driven=driven,
        basis=basis,
        mapping=mapping,
        hand_names=hand_names,
        folder_mapping=folder_mapping,
    )


def _shared_facts(
    cfg: Mapping, driven_take: _DrivenTake, marker_table, marker_vertices: np.ndarray, frame_rate: float
) -> tuple[list[str], dict]:
    """The notes and provenance every data variant of the capture carries."""
    curves_key, curves_path, take, frames = (
        driven_take.curves_key,
        driven_take.curves_path,
        driven_take.take,
        driven_take.frames,
    )
    driven, basis, mapping = driven_take.driven, driven_take.basis, driven_take.mapping
    folder_mapping = driven_take.folder_mapping
    notes_common = [
        (
            "ICT FaceKit generic face driven by the ARKit weights of a real person's Live Link Face take"
            if curves_key == "livelink_csv"
            else f"ICT FaceKit generic face driven by the weight curves of {curves_path.name}"
        )
        + ": the motion "
        f"is a linear blend of the {len(driven)} driven ICT shapes (eq. 1), with no capture noise",
        f"ICT OBJ units (about cm) x {basis.unit_mm:g} -> mm; face region = the first {len(basis.neutral)} of "
        f"{basis.n_vertices_in_file} vertices",
        *folder_mapping.describe(),
        f"frames: {len(frames)} of {take.n_frames} (every {int(cfg.frame_step)}), "
        f"{frame_rate:.2f} Hz from the timecodes",
    ]
    provenance = {
        "kind": "ict_livelink",
        "data_root": str(cfg.data_root),
        "files": {
            "blendshapes": cfg.blendshapes.folder,
            curves_key: getattr(cfg, curves_key),
            "marker_table": str(marker_table.path),
        },
        "credits": [ICT_CREDIT] + ([LIVELINK_CREDIT] if curves_key == "livelink_csv" else []),
        "unit_mm": basis.unit_mm,
        "region_vertices": len(basis.neutral),
        "arkit_mapping": {channel: list(targets) for channel, targets in mapping.targets.items()},
        "n_frames_in_file": take.n_frames,
        "frames_used": len(frames),
        "frame_step": int(cfg.frame_step),
        "virtual_marker_vertices": dict(zip(marker_table.labels, marker_vertices.tolist())),
    }
    return notes_common, provenance
