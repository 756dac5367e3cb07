"""Helpers shared by the real-data builders: paths, the blendshape basis, frame selection, wording."""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.core.files import sha256_of_file
from workbench.formats.obj import Blendshapes, load_blendshapes

ICT_CREDIT = "ICT FaceKit generic face (USC Institute for Creative Technologies, ICT-VGL/ICT-FaceKit), MIT licence"
LIVELINK_CREDIT = (
    "Live Link Face take by Alexandre Donciu-Julin (alexdjulin/LiveLinkFace-CSV-Retarget-For-"
    "Motionbuilder), MIT licence"
)
ANIMFACE_CREDIT = (
    "AnimFace by Miguel Ramos Carretero, CC BY-SA 4.0 (bigoMay/AnimFace; thesis 'Efficient Facial "
    "Animation Integrating Euclidean and Geodesic Distance-Based Algorithms into Radial Basis Function "
    "Interpolation', Bournemouth University, 2019)"
)


def data_root(root: str | None) -> Path:
    """The configured data root (``dataset.data_root``, usually ``paths.data_root``), which must exist."""
    if not root:
        raise WorkbenchError("dataset.data_root is not set (it defaults to ${paths.data_root})")
    path = Path(root).expanduser()
    if not path.is_dir():
        raise WorkbenchError(
            f"dataset.data_root {path} (resolved {path.resolve()}) is not a folder: set "
            "WORKBENCH_DATA_ROOT or paths.data_root=... to where the shared face data lives"
        )
    return path


def data_path(root: str | None, relative: str, key: str) -> Path:
    """A file or folder named by ``dataset.<key>``, relative to the data root ``root`` (``dataset.data_root``)
    unless absolute."""
    if not relative:
        raise WorkbenchError(f"dataset.{key} is not set")
    path = Path(relative).expanduser()
    return path if path.is_absolute() else data_root(root) / path


def conf_path(relative: str, key: str) -> Path:
    """A file named by ``dataset.<key>``, relative to the workbench's ``conf/`` folder unless absolute."""
    from workbench.settings.config import CONF_DIR

    if not relative:
        raise WorkbenchError(f"dataset.{key} is not set")
    path = Path(relative).expanduser()
    return path if path.is_absolute() else CONF_DIR / path


def data_file_checksums(cfg: Mapping) -> dict:
    """The checksum of every data file or folder a dataset config names, for the run's provenance.

    A setting names a file or folder when its text is a path under the data root or the workbench's ``conf/``
    folder (``kind`` is a name, not a path). A folder's checksum is the SHA-256 of the lines ``<sha256>  <name>``
    of its files sorted by name, which is what ``LC_ALL=C sha256sum * | sha256sum`` prints in it.

    Parameters
    ----------
    cfg : mapping
        The ``dataset`` config group.

    Returns
    -------
    dict
        Path relative to its root (``conf/...`` for the workbench's own) -> ``sha256`` and ``bytes`` (a folder: of
        all its files) and, for a folder, ``files``; empty for generated datasets.
    """
    import hashlib

    from workbench.settings.config import CONF_DIR

    roots = [(Path(cfg["data_root"]), "") if cfg.get("data_root") else None, (CONF_DIR, "conf/")]
    found = {}

    def visit(value, key=""):
        if isinstance(value, Mapping):
            for name, item in value.items():
                if name not in ("kind", "data_root"):
                    visit(item, name)
        elif isinstance(value, (list, tuple)):
            for item in value:
                visit(item, key)
        elif isinstance(value, str) and value and not Path(value).is_absolute():
            for root, prefix in filter(None, roots):
                path = root / value
                if path.is_file():
                    found[prefix + value] = {"sha256": sha256_of_file(path), "bytes": path.stat().st_size}
                elif path.is_dir() and path.resolve() != root.resolve():
                    files = sorted((item for item in path.iterdir() if item.is_file()), key=lambda item: item.name)
                    lines = "".join(f"{sha256_of_file(item)}  {item.name}\n" for item in files)
                    found[prefix + value] = {
                        "sha256": hashlib.sha256(lines.encode()).hexdigest(),
                        "bytes": sum(item.stat().st_size for item in files),
                        "files": len(files),
                    }

    visit(cfg)
    return found


def load_basis(cfg: Mapping, names: Sequence[str] | None = None) -> Blendshapes:
    """The blendshape basis a dataset config names (``dataset.blendshapes``), in millimetres.

    Parameters
    ----------
    cfg : mapping
        The ``dataset`` config group.
    names : sequence of str, optional
        Expressions to read; all in the folder when None.

    Returns
    -------
    Blendshapes
    """
    spec = cfg.blendshapes
    for key in ("folder", "neutral", "unit_mm"):
        if spec is None or getattr(spec, key) is None:
            raise WorkbenchError(f"dataset.blendshapes.{key} is not set")
    region = spec.region_vertices
    region = None if region is None else int(region)
    return load_blendshapes(
        data_path(cfg.data_root, spec.folder, "blendshapes.folder"),
        neutral_file=spec.neutral,
        names=names,
        region_vertices=region,
        unit_mm=float(spec.unit_mm),
    )


def hand_shape_names(hand_shapes: Sequence[str] | None, available: Sequence[str]) -> list[str]:
    """``dataset.hand_shapes`` (distinct plain names, checked with the settings), each a shape the basis folder
    has; a dataset group given alone may leave it out."""
    names = list(hand_shapes or [])
    if not names:
        raise WorkbenchError("dataset.hand_shapes is empty: list the blendshape names that form the hand basis")
    unknown = [name for name in names if name not in available]
    if unknown:
        raise WorkbenchError(
            f"dataset.hand_shapes names {unknown}, which the blendshape folder does not have; it has {list(available)}"
        )
    return names


def frame_selection(n_frames: int, frame_step: int, max_frames: int | None, what: str) -> np.ndarray:
    """Indices of every ``frame_step``-th frame, at most ``max_frames`` of them (from the start).

    Returns
    -------
    ndarray of shape (n_selected,) of int
    """
    frame_step = int(frame_step)
    index = np.arange(0, n_frames, frame_step)
    if max_frames is not None:
        index = index[: int(max_frames)]
    if index.size < 2:
        raise WorkbenchError(f"{n_frames} frames with frame_step {frame_step} leave {index.size}; need at least 2")
    return index


def mesh_point_indices(n_vertices: int, vertex_step: int, hand: np.ndarray | None = None, names=()) -> np.ndarray:
    """Vertices used as mesh points: every ``vertex_step``-th one (1 keeps the whole mesh, for full runs).

    With ``hand`` (the hand shapes on the whole mesh, shape (n_shapes, n_vertices, 3), named ``names``), a step
    that keeps too few vertices for the hand shapes (one that no longer moves any kept vertex, or shapes no longer
    independent there, while the whole mesh has them all) is refused naming the largest step that keeps them.
    """
    step = int(vertex_step)
    points = np.arange(0, n_vertices, step)
    if hand is None or step == 1 or _hand_basis_holds(hand, names, points):
        return points
    if not _hand_basis_holds(hand, names, np.arange(n_vertices)):
        return points  # the whole mesh breaks the rule too: not the step's fault, the fit names it
    largest = next(
        s
        for s in range(min(step, n_vertices + 1) - 1, 0, -1)
        if _hand_basis_holds(hand, names, np.arange(0, n_vertices, s))
    )
    raise WorkbenchError(
        f"dataset.mesh_vertex_step={step} keeps {len(points)} of the {n_vertices} mesh vertices, too few for the "
        f"hand shapes (every hand shape must move a kept vertex and add a direction of its own there); use "
        f"dataset.mesh_vertex_step={largest} or less"
    )


def _hand_basis_holds(hand: np.ndarray, names, points: np.ndarray) -> bool:
    from workbench.numerics.bases import check_hand_basis

    try:
        check_hand_basis(hand[:, points].reshape(len(hand), -1), names)
    except WorkbenchError:
        return False
    return True


def origin_text(description: str, neutral_points: np.ndarray) -> str:
    """``Capture.origin``: where the origin is, and how far the capture's points lie from it (it scales alpha)."""
    distance = np.linalg.norm(neutral_points.reshape(-1, 3), axis=1)
    return f"{description} (the points lie {distance.min():.0f}-{distance.max():.0f} mm from it)"
