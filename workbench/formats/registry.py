"""Every file format the workbench reads or writes, by name and file suffix: one line each.

A new format is its module in ``formats/`` and one line in :data:`FORMATS`; the datasets find a reader by what
the file holds and its suffix (:func:`format_for`), and the Python API re-exports each reader under its public
name with the reader's own docstring (``workbench.read_c3d`` is :func:`workbench.formats.c3d.read_c3d_markers`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from workbench.core.errors import WorkbenchError
from workbench.formats import c3d, gltf, livelink, mesh_sequence, obj, obj_sequence, weight_curves


@dataclass(frozen=True)
class FileFormat:
    """One file format.

    Attributes
    ----------
    name : str
        What the format is called (``c3d``, ``gltf``, ...).
    holds : str
        What its files hold: ``marker take``, ``weight curves``, ``mesh``, ``blendshapes``, ``morph mesh`` or
        ``mesh sequence``; a dataset asks for a reader of what it needs.
    suffixes : tuple of str
        The file suffixes it reads (lower case; empty for a folder, or a folder or list of files).
    read : callable
        The reader: a path first, then keyword options.
    public_name : str
        The reader's name in the Python API (``import workbench``).
    write : callable, optional
        The writer, for a format the workbench also writes.
    """

    name: str
    holds: str
    suffixes: tuple[str, ...]
    read: Callable
    public_name: str
    write: Callable | None = None


FORMATS: dict[str, FileFormat] = {
    entry.name: entry
    for entry in (
        FileFormat("c3d", "marker take", (".c3d",), c3d.read_c3d_markers, "read_c3d"),
        FileFormat("livelink", "weight curves", (".csv",), livelink.read_livelink_csv, "read_livelink"),
        FileFormat(
            "weight_curves", "weight curves", (".csv", ".json"), weight_curves.read_weight_curves, "read_weight_curves"
        ),
        FileFormat("obj", "mesh", (".obj",), obj.read_obj, "read_obj"),
        FileFormat("blendshapes", "blendshapes", (), obj.read_blendshapes, "read_blendshapes"),
        FileFormat("gltf", "morph mesh", (".glb",), gltf.read_morph_mesh, "read_gltf", write=gltf.glb_bytes),
        FileFormat(
            "mesh_sequence",
            "mesh sequence",
            mesh_sequence.SEQUENCE_SUFFIXES,
            mesh_sequence.read_mesh_sequence,
            "read_mesh_sequence",
        ),
        FileFormat("obj_sequence", "mesh sequence", (), obj_sequence.read_obj_sequence, "read_obj_sequence"),
    )
}
"""Format name -> :class:`FileFormat`."""


def format_for(path: str | os.PathLike, holds: str, setting: str) -> FileFormat:
    """The format that reads ``path`` for what it ``holds``, by the file's suffix (the last format listed for a
    suffix is the most general: ``weight_curves`` reads Live Link Face's CSV files too).

    Raises
    ------
    WorkbenchError
        Naming ``setting`` and the file when no format of that kind reads its suffix.
    """
    suffix = Path(path).suffix.lower()
    found = [entry for entry in FORMATS.values() if entry.holds == holds and suffix in entry.suffixes]
    if not found:
        known = sorted({s for entry in FORMATS.values() if entry.holds == holds for s in entry.suffixes})
        raise WorkbenchError(
            f"{setting} {path}: no reader of a {holds} reads '{suffix or '(no suffix)'}' files; known: {', '.join(known)}"
        )
    return found[-1]
