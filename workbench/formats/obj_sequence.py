"""A capture as a sequence of OBJ files, one frame each, sharing one topology (a folder of exported frames, or a
list of files), read as one array of positions like the mesh sequence files (:mod:`workbench.formats.mesh_sequence`),
which the same reader takes too.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.core.files import input_path
from workbench.formats.mesh_sequence import SEQUENCE_SUFFIXES, read_mesh_sequence
from workbench.formats.obj import _file_key, _vertices_cached, check_vertices, read_obj, triangulate


@dataclass(frozen=True)
class ObjSequence:
    """Frames of a mesh sequence with the files they came from.

    Attributes
    ----------
    vertices : ndarray of shape (n_frames, n_vertices, 3)
        Positions in the files' units, float64, frame ``i`` from ``paths[i]`` (for a sequence file, its frames).
    faces : ndarray of shape (n_faces, 3) of int, or None
        The first OBJ's polygons as triangles (fans from each polygon's first corner), 0-based; a sequence file's
        triangles, or None when it has none.
    paths : tuple of pathlib.Path
        The OBJ file of each frame, in frame order; for a sequence file, that one file.
    """

    vertices: np.ndarray
    faces: np.ndarray | None
    paths: tuple

    @property
    def n_frames(self) -> int:
        return int(self.vertices.shape[0])


def natural_key(name: str) -> list:
    """Sort key of a file name that orders its runs of digits by value: ``frame_2`` before ``frame_10``."""
    return [(0, int(part), "") if part.isdigit() else (1, 0, part.lower()) for part in re.split(r"(\d+)", name)]


def obj_files(source) -> list[Path]:
    """The OBJ files of ``source``: a folder's ``*.obj`` files (suffix in any case, not its subfolders) in natural
    order of their names, or a list of paths in the order given; at least 2.

    Raises
    ------
    WorkbenchError
        Naming ``source`` when it is neither, the folder holds fewer than 2 OBJ files, or a listed file is not one.
    """
    if isinstance(source, (str, os.PathLike)):
        folder = input_path(source, "folder of OBJ files or mesh sequence file", "source", folder=True)
        files = sorted(
            (path for path in folder.iterdir() if path.suffix.lower() == ".obj" and path.is_file()),
            key=lambda path: natural_key(path.name),
        )
        where = f"{folder}: holds {len(files)} OBJ file{'s' if len(files) != 1 else ''}"
    elif isinstance(source, Sequence) and all(isinstance(item, (str, os.PathLike)) for item in source):
        files = [input_path(item, "OBJ file", "source") for item in source]
        others = [path for path in files if path.suffix.lower() != ".obj"]
        if others:
            raise WorkbenchError(f"{others[0]}: not an OBJ file; every file of an OBJ sequence must end in .obj")
        where = f"source lists {len(files)} OBJ file{'s' if len(files) != 1 else ''}"
    else:
        raise WorkbenchError(
            f"source must be a folder of OBJ files, a list of OBJ paths or a mesh sequence file, got {source!r:.80}"
        )
    if len(files) < 2:
        raise WorkbenchError(f"{where}; an OBJ sequence needs at least 2 frames")
    return files


def read_obj_sequence(source: str | os.PathLike | Sequence[str | os.PathLike]) -> ObjSequence:
    """A capture given as one OBJ file per frame (a folder, or a list of files), all with the first file's
    topology, or a mesh sequence file (``.npz``, ``.npy``, ``.h5``/``.hdf5``; :func:`read_mesh_sequence`).

    Parameters
    ----------
    source : path-like or sequence of path-like
        A folder (its ``*.obj`` files in natural order of their names: ``frame_2.obj`` before ``frame_10.obj``),
        a list of OBJ files (in the order given) or a sequence file.

    Returns
    -------
    ObjSequence
        ``vertices`` of shape (n_frames, n_vertices, 3) in the files' units, ``faces`` (triangles) and the
        ``paths`` of the frames. Frames are positions: ``vertices - neutral`` are the displacements the estimator
        fits (e.g. ``neutral = vertices[0]``, or a neutral OBJ's vertices), reshaped to (n_frames, 3 * n_vertices).

    Raises
    ------
    WorkbenchError
        Naming the first file whose vertex count or polygons differ from the first file's, or whose vertices are
        not finite or lie far outside the first file's face, or the source when it holds fewer than 2 frames.
    """
    if isinstance(source, (str, os.PathLike)) and Path(source).suffix.lower() in SEQUENCE_SUFFIXES:
        vertices, faces = read_mesh_sequence(source)
        return ObjSequence(vertices=vertices, faces=faces, paths=(Path(source),))
    files = obj_files(source)
    first = read_obj(files[0])
    _check_frame(first.vertices, first.vertices, files[0])
    face_digest = _vertices_cached(*_file_key(files[0]))[1]
    vertices = np.empty((len(files), first.n_vertices, 3), dtype=np.float64)
    vertices[0] = first.vertices
    for index, path in enumerate(files[1:], start=1):
        frame, digest, _ = _vertices_cached(*_file_key(path))
        if frame.shape[0] != first.n_vertices:
            raise WorkbenchError(
                f"{path}: {frame.shape[0]} vertices, but the first file {files[0].name} has {first.n_vertices}; "
                "every frame of an OBJ sequence must have the first file's topology"
            )
        if digest != face_digest:  # the same polygons may be written otherwise (with texture indices, ...)
            _check_same_polygons(read_obj(path), first)
        _check_frame(frame, first.vertices, path)
        vertices[index] = frame
    faces = triangulate(first.polygon_sizes, first.polygon_vertices) if first.polygon_sizes.size else None
    return ObjSequence(vertices=vertices, faces=faces, paths=tuple(files))


def _check_same_polygons(mesh, first) -> None:
    """A :class:`WorkbenchError` naming ``mesh``'s file unless its polygons are the first file's."""
    if not (
        np.array_equal(mesh.polygon_sizes, first.polygon_sizes)
        and np.array_equal(mesh.polygon_vertices, first.polygon_vertices)
    ):
        raise WorkbenchError(
            f"{mesh.path}: its polygons ({mesh.polygon_sizes.size}) differ from those of the first file "
            f"{first.path.name} ({first.polygon_sizes.size}); every frame of an OBJ sequence must have the first "
            "file's topology"
        )


def _check_frame(vertices: np.ndarray, first: np.ndarray, path: Path) -> None:
    """A :class:`WorkbenchError` naming ``path`` when a frame's vertices are not finite or lie far outside the
    first frame's face (:func:`workbench.formats.obj.check_vertices`)."""
    if not np.all(np.isfinite(vertices)):
        raise WorkbenchError(f"{path}: {int(np.sum(~np.isfinite(vertices)))} vertex coordinates are NaN or Inf")
    check_vertices(vertices, first, path)
