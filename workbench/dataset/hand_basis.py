"""A hand basis read from a file instead of the dataset's own: an OBJ blendshape folder or a glTF file's morph
targets (``dataset.hand_basis``), e.g. a basis exported by ``workbench export`` or a rig made in another tool.

The file's mesh must hold the capture's points in the capture's order (the vertices of the mesh data variant, as
an export of that variant writes them): its shapes then replace the capture's hand shapes point for point.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.dataset.capture import Capture
from workbench.formats.obj import Blendshapes, expression_names, load_blendshapes

NEUTRAL_MISMATCH = 0.1
"""A hand basis whose neutral lies further than this fraction of the capture's extent from the capture's neutral is
refused (a wrong file, or wrong units)."""


def read_shape_file(
    path: Path,
    key: str,
    *,
    neutral: str | None = None,
    unit_mm: float | None = None,
    mesh: str | None = None,
    region_vertices: int | None = None,
) -> Blendshapes:
    """Shapes of an OBJ blendshape folder or of a ``.glb`` file's morph targets, in millimetres.

    Parameters
    ----------
    path : pathlib.Path
        A folder or a ``.glb`` file.
    key : str
        Config key of the settings for messages, e.g. ``"dataset.hand_basis"``.
    neutral : str, optional
        Folder: the neutral OBJ's name (default ``neutral.obj``).
    unit_mm : float, optional
        Folder: mm per OBJ unit (default the folder's ``manifest.json`` ``unit_mm`` where it has one, as an export
        writes, else 1).
    mesh : str, optional
        glb: the mesh's name when the file has several.
    region_vertices : int, optional
        Keep the first vertices only.

    The settings come checked (:class:`~workbench.settings.schema.HandBasisSchema`, ``dataset.blendshapes``).

    Returns
    -------
    Blendshapes
        Every shape of the file.
    """
    from workbench.formats.gltf import read_morph_mesh

    region = None if region_vertices is None else int(region_vertices)
    if path.is_dir():
        neutral = neutral or "neutral.obj"
        unit_mm = float(unit_mm) if unit_mm is not None else folder_unit_mm(path)
        return load_blendshapes(
            path, neutral_file=neutral, names=expression_names(path, neutral), region_vertices=region, unit_mm=unit_mm
        )
    if path.suffix.lower() != ".glb":
        raise WorkbenchError(
            f"{key}.path {path}: must be a blendshape folder (neutral OBJ plus one OBJ per shape) or a .glb file"
        )
    morph = read_morph_mesh(path, mesh_name=mesh)
    n_kept = len(morph.neutral) if region is None else region
    if n_kept > len(morph.neutral):
        raise WorkbenchError(f"{key}.region_vertices {region} exceeds the {len(morph.neutral)} vertices of {path}")
    kept_triangles = morph.triangles[np.all(morph.triangles < n_kept, axis=1)]
    return Blendshapes(
        neutral=morph.neutral[:n_kept],
        names=morph.names,
        deltas=morph.deltas[:, :n_kept],
        triangles=kept_triangles,
        n_polygons=len(kept_triangles),
        n_vertices_in_file=len(morph.neutral),
        unit_mm=1000.0,
        files={"glb": str(path)},
    )


def folder_unit_mm(folder: Path) -> float:
    """Millimetres per OBJ unit that a blendshape folder's ``manifest.json`` states (``workbench export`` writes
    one beside its OBJ files); 1 for a folder without one."""
    from workbench.settings.rules import positive_setting

    manifest = folder / "manifest.json"
    if not manifest.is_file():
        return 1.0
    try:
        stated = json.loads(manifest.read_text())
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise WorkbenchError(
            f"{manifest}: not a readable JSON file ({error}); set dataset.hand_basis.unit_mm to "
            "read the folder without it"
        ) from None
    if not isinstance(stated, dict) or "unit_mm" not in stated:
        raise WorkbenchError(
            f"{manifest}: needs a field 'unit_mm' (millimetres per OBJ unit); set "
            "dataset.hand_basis.unit_mm to read the folder without it"
        )
    return positive_setting(stated["unit_mm"], f"{manifest}: field 'unit_mm'")


def check_hand_shapes(hand: np.ndarray, names, where: str) -> None:
    """:func:`workbench.numerics.bases.check_hand_basis` on shapes read from a file, its refusal naming ``where``
    (the setting and the file) before anything is fitted."""
    from workbench.numerics.bases import check_hand_basis

    try:
        check_hand_basis(hand, names)
    except WorkbenchError as error:
        raise WorkbenchError(f"{where}: {error}") from None


def shape_subset(basis: Blendshapes, names, key: str) -> tuple[tuple[str, ...], np.ndarray]:
    """The named shapes of ``basis`` (all when ``names`` is None), shape (n, n_vertices, 3)."""
    names = list(basis.names) if names is None else list(names)
    missing = [name for name in names if name not in basis.names]
    if missing or not names or len(set(names)) != len(names):
        raise WorkbenchError(
            f"{key}: needs distinct shape names of the file's {list(basis.names)}; "
            f"{'missing ' + str(missing) if missing else 'got ' + str(names)}"
        )
    return tuple(names), basis.shapes(names)


def check_same_points(points: np.ndarray, neutral: np.ndarray, key: str, path: Path, what: str) -> float:
    """Raise unless the file's neutral (n, 3) holds ``points`` (n, 3), the neutral of ``what``; returns the RMS
    distance (mm)."""
    if len(neutral) != len(points):
        raise WorkbenchError(
            f"{key}.path {path}: {len(neutral)} vertices, but {what} has {len(points)} points; the "
            "shapes must hold its points in order (for an export: export that data variant, or set "
            "dataset.train_on to the variant it was exported from)"
        )
    extent = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    distance = np.linalg.norm(neutral - points, axis=1)
    if distance.max() > NEUTRAL_MISMATCH * extent:
        raise WorkbenchError(
            f"{key}.path {path}: its neutral lies up to {distance.max():.3g} mm from the data's "
            f"(more than {NEUTRAL_MISMATCH:g} of the data's {extent:.3g} mm extent): another face, "
            "another vertex order or other units (unit_mm)"
        )
    return float(np.sqrt(np.mean(distance**2)))


def apply_hand_basis(
    captures: Mapping[str, Capture],
    path: str | None,
    shapes: Sequence[str] | None = None,
    *,
    data_root: str | None = None,
    neutral: str | None = None,
    unit_mm: float | None = None,
    mesh: str | None = None,
    region_vertices: int | None = None,
) -> dict[str, Capture]:
    """The captures with their hand basis read from ``dataset.hand_basis`` (unchanged when it is not set).

    Parameters
    ----------
    captures : mapping
        Data variant -> :class:`Capture`.
    path : str or None
        ``dataset.hand_basis.path``, relative to ``data_root`` unless absolute; None: no hand basis of a file.
    shapes : sequence of str, optional
        ``dataset.hand_basis.shapes`` (default: the capture's hand shape names).
    data_root : str, optional
        ``dataset.data_root`` (the synthetic actor has none).
    neutral, unit_mm, mesh, region_vertices
        Those of ``dataset.hand_basis``, as :func:`read_shape_file` takes them (checked with the study:
        :class:`~workbench.settings.schema.HandBasisSchema`).

    Returns
    -------
    dict
    """
    from workbench.dataset.real import data_path

    if path is None:  # the schema asks for a path in every group that is set
        return dict(captures)
    key = "dataset.hand_basis"
    path = data_path(data_root, path, "hand_basis.path")
    if not path.exists():
        raise WorkbenchError(f"{key}.path {path}: not found")
    basis = read_shape_file(path, key, neutral=neutral, unit_mm=unit_mm, mesh=mesh, region_vertices=region_vertices)
    replaced = {}
    for name, capture in captures.items():
        names, chosen = shape_subset(basis, shapes or capture.hand_names, key)
        check_hand_shapes(chosen.reshape(len(names), -1), names, f"{key}.path {path}")
        rms = check_same_points(capture.neutral.reshape(-1, 3), basis.neutral, key, path, f"data variant '{name}'")
        note = f"hand basis: {len(names)} shapes read from {path} (its neutral {rms:.3g} mm RMS from the data's)"
        replaced[name] = replace(
            capture,
            hand=chosen.reshape(len(names), -1),
            hand_names=names,
            notes=capture.notes + (note,),
            provenance=dict(capture.provenance, hand_basis=str(path)),
        )
    return replaced
