"""Mesh sequences (4-D scans, VOCASET-style registered meshes): one array of vertex positions
``(frames, vertices, 3)`` with the triangles beside it, in a NumPy ``.npz`` (arrays named by ``vertices_key`` and
``faces_key``), a ``.npy`` (positions only) or an HDF5 file (``.h5``/``.hdf5``, datasets at those paths).

A ``.npy`` is memory-mapped and an HDF5 dataset read by slices, a chunk of frames at a time; a ``.npz`` (possibly
compressed, so not mappable) is read whole. Every frame is checked when the file is opened.
"""

from __future__ import annotations

import hashlib
import os
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.core.files import input_path
from workbench.formats.plausibility import SequenceMotion
from workbench.numerics.frames import chunk_frames

SEQUENCE_SUFFIXES = (".npz", ".npy", ".h5", ".hdf5")
DEFAULT_FACES_KEY = "faces"
"""The triangles' array when none is named: a file without it has none (the hand basis's are used). An array
named otherwise must exist."""


def _missing_faces(path: Path, faces_key: str | None, found: bool, names) -> None:
    """Refuse a ``faces_key`` other than the default that names no array of the file (``found`` False; ``names``
    are the file's arrays)."""
    if faces_key is not None and faces_key != DEFAULT_FACES_KEY and not found:
        raise WorkbenchError(
            f"{path}: no array '{faces_key}' (faces_key, dataset.faces_key); it has {sorted(names)}; "
            "give null to use the hand basis's triangles"
        )


@contextmanager
def open_mesh_sequence(path: Path, vertices_key: str, faces_key: str | None) -> Iterator[MeshSequence]:
    """A sequence file opened for reading its frames on demand, checked (a pass over every frame, a chunk at a
    time). A ``.npy`` is memory-mapped and HDF5 read by slices; a ``.npz`` is read whole (a compressed archive
    cannot be mapped).

    Raises
    ------
    WorkbenchError
        If the file is missing or of another kind, lacks the named arrays, or they have the wrong shape or values.
    """
    path = input_path(path, "mesh sequence file")
    suffix = path.suffix.lower()
    if suffix not in SEQUENCE_SUFFIXES:
        raise WorkbenchError(f"{path}: a mesh sequence must be one of {', '.join(SEQUENCE_SUFFIXES)}")
    opened = (
        _hdf5_arrays(path, vertices_key, faces_key)
        if suffix in (".h5", ".hdf5")
        else _numpy_arrays(path, vertices_key, faces_key)
    )
    with opened as (vertices, faces):
        if len(vertices.shape) != 3 or vertices.shape[2] != 3 or vertices.shape[0] < 2 or vertices.shape[1] < 3:
            raise WorkbenchError(
                f"{path}: '{vertices_key}' must have shape (n_frames >= 2, n_vertices >= 3, 3), got {vertices.shape}"
            )
        digest, problems = _check_values(path, vertices_key, vertices)
        if faces is not None:
            if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
                raise WorkbenchError(
                    f"{path}: '{faces_key}' must be integer triangles of shape (n, 3), got {faces.dtype} {faces.shape}"
                )
            if faces.size and (faces.min() < 0 or faces.max() >= vertices.shape[1]):
                raise WorkbenchError(
                    f"{path}: '{faces_key}' refers to vertex "
                    f"{int(faces.min() if faces.min() < 0 else faces.max())}, outside the "
                    f"{vertices.shape[1]} vertices (0-based)"
                )
        yield MeshSequence(vertices, faces, digest, tuple(problems))


@dataclass(frozen=True)
class MeshSequence:
    """An open sequence file.

    Attributes
    ----------
    vertices : array-like of shape (n_frames, n_vertices, 3)
        Positions in file units, read on demand by slicing (a memory map, an HDF5 dataset or an array).
    faces : ndarray of shape (n, 3) of int, or None
    digest : str
        Content hash of the positions.
    problems : tuple of str
        What the plausibility checks found (vertices far outside the face, jumps between frames, a static
        sequence), for ``dataset.plausibility`` to settle.
    """

    vertices: object
    faces: np.ndarray | None
    digest: str
    problems: tuple = ()

    @property
    def n_frames(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[1])

    def frames(self, start: int, stop: int, step: int = 1) -> np.ndarray:
        """Positions of frames ``start:stop:step``, float64, shape (n, n_vertices, 3)."""
        return np.asarray(self.vertices[start:stop:step], dtype=np.float64)


def _check_values(path: Path, vertices_key: str, vertices) -> tuple[str, list[str]]:
    """Content hash of the positions and the plausibility problems of the sequence, read a chunk of frames at a
    time; an error names a type that is not real numbers, and the first frame holding NaN or Inf."""
    dtype = np.dtype(vertices.dtype)
    if not (np.issubdtype(dtype, np.floating) or np.issubdtype(dtype, np.integer)) or dtype == np.bool_:
        raise WorkbenchError(f"{path}: '{vertices_key}' must hold real numbers (vertex positions), got {dtype}")
    n_frames, per_frame = vertices.shape[0], vertices.shape[1] * 3
    size = chunk_frames(per_frame)
    digest = hashlib.sha256(f"{dtype.str} {tuple(vertices.shape)}".encode())
    motion = SequenceMotion(str(path))
    first, count = None, 0
    for start in range(0, n_frames, size):
        chunk = np.ascontiguousarray(_read_chunk(path, vertices, start, start + size))
        digest.update(chunk)
        finite = np.all(np.isfinite(chunk), axis=(1, 2))
        bad = np.flatnonzero(~finite)
        if bad.size and first is None:
            first = start + int(bad[0])
        count += bad.size
        if count == 0:
            motion.add(start, chunk)
    if count:
        raise WorkbenchError(f"{path}: '{vertices_key}' frame {first} holds NaN or Inf ({count} such frames)")
    return digest.hexdigest(), motion.problems()


def _read_chunk(path: Path, vertices, start: int, stop: int) -> np.ndarray:
    """Frames ``start:stop`` of the file, or a one-line error when its data end early (a truncated file)."""
    try:
        return vertices[start:stop]
    except (OSError, ValueError, EOFError) as error:
        raise WorkbenchError(
            f"{path}: frames {start}-{stop - 1} cannot be read ({error}); the file is damaged or truncated"
        ) from None


@contextmanager
def _numpy_arrays(path: Path, vertices_key: str, faces_key: str | None):
    import zipfile
    import zlib

    damaged = (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error)
    try:
        loaded = np.load(path, mmap_mode="r", allow_pickle=False)  # memory-maps a .npy; a .npz ignores it
    except damaged as error:
        raise WorkbenchError(f"{path}: not a readable NumPy file ({error})") from None
    if isinstance(loaded, np.ndarray):  # .npy: positions only
        _missing_faces(path, faces_key, False, [])
        yield loaded, None
        return
    with loaded:
        if vertices_key not in loaded.files:
            raise WorkbenchError(f"{path}: no array '{vertices_key}' (dataset.vertices_key); it has {loaded.files}")
        _missing_faces(path, faces_key, faces_key in loaded.files, loaded.files)
        try:  # a .npz's arrays are read here: a truncated or damaged archive fails now
            faces = loaded[faces_key] if faces_key and faces_key in loaded.files else None
            vertices = loaded[vertices_key]
        except damaged as error:
            raise WorkbenchError(
                f"{path}: an array of the archive cannot be read ({type(error).__name__}: "
                f"{error}); the file is damaged or truncated"
            ) from None
    yield vertices, faces


@contextmanager
def _hdf5_arrays(path: Path, vertices_key: str, faces_key: str | None):
    import h5py

    try:
        handle = h5py.File(path, "r")
    except OSError as error:
        raise WorkbenchError(f"{path}: not a readable HDF5 file ({error})") from None
    with handle:
        if vertices_key not in handle or not isinstance(handle[vertices_key], h5py.Dataset):
            raise WorkbenchError(
                f"{path}: no dataset '{vertices_key}' (dataset.vertices_key); it has {sorted(handle.keys())}"
            )
        _missing_faces(path, faces_key, bool(faces_key) and faces_key in handle, list(handle.keys()))
        faces = handle[faces_key][()] if faces_key and faces_key in handle else None
        yield handle[vertices_key], faces


def read_mesh_sequence(
    path: str | os.PathLike, *, vertices_key: str = "vertices", faces_key: str | None = "faces"
) -> tuple[np.ndarray, np.ndarray | None]:
    """A registered mesh sequence (``.npz``, ``.npy`` or HDF5), read whole and checked (:func:`open_mesh_sequence`).

    Parameters
    ----------
    path : path-like
    vertices_key, faces_key : str
        The arrays' names in an ``.npz`` or their paths in an HDF5 file (``faces_key`` None: no triangles). A
        file without ``faces`` has none; a ``faces_key`` named otherwise that the file lacks is refused.

    Returns
    -------
    vertices : ndarray of shape (n_frames, n_vertices, 3)
        Positions in the file's units, float64.
    faces : ndarray of shape (n_faces, 3) of int, or None
    """
    with open_mesh_sequence(path, vertices_key, faces_key) as sequence:
        return sequence.frames(0, sequence.n_frames), sequence.faces
