"""Wavefront OBJ meshes and blendshape folders (ICT FaceKit's ``FaceXModel`` layout).

A blendshape folder holds one neutral OBJ and one OBJ per named expression, all with the neutral's vertex count
and polygons (quads and triangles). The expression's name is its file name without ``.obj``; its shape is the
displacement of every vertex from the neutral.
"""

from __future__ import annotations

import functools
import hashlib
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.core.files import input_path


@dataclass(frozen=True)
class ObjMesh:
    """The geometry of one OBJ file (texture coordinates, normals and materials are not kept).

    Attributes
    ----------
    vertices : ndarray of shape (n_vertices, 3)
        ``v`` lines in file order, in the file's units.
    polygon_sizes : ndarray of shape (n_polygons,) of int
        Corners of each ``f`` line (3 for a triangle, 4 for a quad, ...).
    polygon_vertices : ndarray of shape (polygon_sizes.sum(),) of int
        0-based vertex index of every corner, polygon after polygon.
    path : pathlib.Path
    """

    vertices: np.ndarray
    polygon_sizes: np.ndarray
    polygon_vertices: np.ndarray
    path: Path

    @property
    def n_vertices(self) -> int:
        return self.vertices.shape[0]


def _parse_vertices(lines: list[bytes], path: Path) -> np.ndarray:
    tokens = b" ".join(line[2:] for line in lines).split()
    try:
        if len(tokens) == 3 * len(lines):
            vertices = np.array(tokens, dtype=np.float64).reshape(-1, 3)
        else:
            # Some writers add a w or a colour after x y z: keep the first three numbers of each line.
            rows = [line.split()[1:4] for line in lines]
            short = next((i for i, row in enumerate(rows) if len(row) < 3), None)
            if short is not None:
                raise WorkbenchError(f"{path}: vertex {short + 1} has fewer than 3 coordinates: {lines[short]!r}")
            vertices = np.array(rows, dtype=np.float64)
    except ValueError as error:
        if isinstance(error, WorkbenchError):
            raise
        raise WorkbenchError(f"{path}: a 'v' line holds something that is not a number ({error})") from None
    bad = np.flatnonzero(~np.all(np.isfinite(vertices), axis=1))
    if bad.size:
        raise WorkbenchError(
            f"{path}: vertex {int(bad[0]) + 1} is not finite ({lines[bad[0]]!r}; {bad.size} such "
            "vertices); coordinates must be finite numbers"
        )
    return vertices


def _parse_polygons(lines: list[bytes], vertices_before, n_vertices: int, path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Corner vertex indices of ``f`` lines (``i``, ``i/t``, ``i//n`` or ``i/t/n``; negative = relative, with
    ``vertices_before()`` giving how many vertices precede each line)."""
    corners = [line.split()[1:] for line in lines]
    sizes = np.fromiter((len(corner) for corner in corners), dtype=np.int64, count=len(corners))
    if sizes.size and sizes.min() < 3:
        bad = int(np.argmin(sizes))
        raise WorkbenchError(f"{path}: face {bad + 1} has {sizes[bad]} corners, a polygon needs at least 3")
    try:
        index = np.array([token.split(b"/", 1)[0] for corner in corners for token in corner], dtype=np.int64)
    except ValueError:
        raise WorkbenchError(f"{path}: an 'f' line holds a vertex reference that is not an integer") from None
    relative = index < 0
    if relative.any():
        index[relative] += np.repeat(vertices_before(), sizes)[relative] + 1
    index -= 1
    outside = (index < 0) | (index >= n_vertices)
    if outside.any():
        raise WorkbenchError(
            f"{path}: a face refers to vertex {int(index[outside][0]) + 1}, outside the file's {n_vertices} vertices"
        )
    return sizes, index


VERTEX_START = (b"v ", b"v\t")
FACE_START = (b"f ", b"f\t")


def _lines_of(data: bytes, start: tuple[bytes, ...]) -> list[bytes]:
    """The lines of an OBJ file's text that begin with one of ``start`` (a keyword and its blank), line ends
    (``\\n``, ``\\r\\n`` or ``\\r``) left out. A C-level split and prefix test: about half the time of a multiline
    regex on the ICT meshes."""
    return [line for line in data.splitlines() if line.startswith(start)]


@dataclass(frozen=True)
class _ObjLines:
    """An OBJ file's vertex and face lines (cached per file version)."""

    vertex_lines: list
    face_lines: list
    face_digest: bytes


@functools.lru_cache(maxsize=8)
def _split_obj(path_text: str, stamp: tuple[int, ...], size: int) -> _ObjLines:
    path = Path(path_text)
    data = path.read_bytes()
    vertex_lines, face_lines = _lines_of(data, VERTEX_START), _lines_of(data, FACE_START)
    if not vertex_lines:
        raise WorkbenchError(f"{path}: no vertices ('v' lines); is this a Wavefront OBJ file?")
    # A digest of the face lines recognises a target with the neutral's exact polygons without parsing them.
    return _ObjLines(
        vertex_lines=vertex_lines, face_lines=face_lines, face_digest=hashlib.sha256(b"\n".join(face_lines)).digest()
    )


def _vertices_before_faces(path: Path) -> np.ndarray:
    """How many vertices each face line follows (for relative, negative vertex references)."""
    lines = path.read_bytes().splitlines()
    vertex = np.fromiter((line.startswith(VERTEX_START) for line in lines), dtype=bool, count=len(lines))
    face = np.fromiter((line.startswith(FACE_START) for line in lines), dtype=bool, count=len(lines))
    return np.cumsum(vertex)[face]


def _file_key(path: Path) -> tuple[str, tuple[int, ...], int]:
    """What the parsed file is remembered by in the process: its path, its stamp and its size. The stamp holds the
    change time, which any write sets to now and no program can set back, so a file edited in place with its size
    and modification time restored is read afresh. The path is kept as named (not resolved), so that a message
    about a file reached through a symbolic link names the link the user gave."""
    path = input_path(path, "OBJ file")
    stat = path.stat()
    return os.path.abspath(path), (stat.st_dev, stat.st_ino, stat.st_mtime_ns, stat.st_ctime_ns), stat.st_size


@functools.lru_cache(maxsize=128)
def _vertices_cached(path_text: str, stamp: tuple[int, ...], size: int) -> tuple[np.ndarray, bytes, int]:
    split = _split_obj(path_text, stamp, size)
    vertices = _parse_vertices(split.vertex_lines, Path(path_text))
    vertices.flags.writeable = False
    return vertices, split.face_digest, len(split.face_lines)


@functools.lru_cache(maxsize=16)
def _polygons_cached(path_text: str, stamp: tuple[int, ...], size: int) -> tuple[np.ndarray, np.ndarray]:
    split = _split_obj(path_text, stamp, size)
    sizes, corners = _parse_polygons(
        split.face_lines, lambda: _vertices_before_faces(Path(path_text)), len(split.vertex_lines), Path(path_text)
    )
    sizes.flags.writeable = corners.flags.writeable = False
    return sizes, corners


def read_obj(path: str | os.PathLike) -> ObjMesh:
    """Read the vertices and polygons of a Wavefront OBJ file.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    ObjMesh
        ``vertices`` of shape (n_vertices, 3) in the file's units and its polygons; arrays are read-only (results
        are cached per file version).

    Raises
    ------
    WorkbenchError
        If the file is missing or a ``v`` / ``f`` line cannot be read.
    """
    path = input_path(path, "OBJ file")
    key = _file_key(path)
    vertices = _vertices_cached(*key)[0]
    sizes, corners = _polygons_cached(*key)
    return ObjMesh(vertices=vertices, polygon_sizes=sizes, polygon_vertices=corners, path=path)


def triangulate(polygon_sizes: np.ndarray, polygon_vertices: np.ndarray) -> np.ndarray:
    """Split polygons into triangles as fans from their first corner.

    Parameters
    ----------
    polygon_sizes : ndarray of shape (n_polygons,) of int
    polygon_vertices : ndarray of shape (polygon_sizes.sum(),) of int

    Returns
    -------
    ndarray of shape (sum(polygon_sizes - 2), 3) of int
    """
    starts = np.concatenate([[0], np.cumsum(polygon_sizes)[:-1]]).astype(np.int64)
    n_triangles = polygon_sizes - 2
    first = np.repeat(starts, n_triangles)
    # Corner k of the fan's j-th triangle: first, first + j + 1, first + j + 2.
    j = np.arange(n_triangles.sum()) - np.repeat(np.cumsum(n_triangles) - n_triangles, n_triangles)
    return np.stack([polygon_vertices[first], polygon_vertices[first + j + 1], polygon_vertices[first + j + 2]], axis=1)


def polygons_within(
    polygon_sizes: np.ndarray, polygon_vertices: np.ndarray, n_kept: int
) -> tuple[np.ndarray, np.ndarray]:
    """The polygons whose every corner is one of the first ``n_kept`` vertices.

    Returns
    -------
    sizes, corners : ndarray
        In the layout of :class:`ObjMesh`.
    """
    polygon_of_corner = np.repeat(np.arange(polygon_sizes.size), polygon_sizes)
    outside = np.zeros(polygon_sizes.size, dtype=bool)
    np.logical_or.at(outside, polygon_of_corner, polygon_vertices >= n_kept)
    keep_corner = ~outside[polygon_of_corner]
    return polygon_sizes[~outside], polygon_vertices[keep_corner]


@dataclass(frozen=True)
class Blendshapes:
    """A neutral mesh and named expression shapes as displacements from it, in millimetres.

    Attributes
    ----------
    neutral : ndarray of shape (n_vertices, 3)
        Neutral positions of the kept vertices, in mm.
    names : tuple of str
        Expression names (file names without ``.obj``), in the order of ``deltas``.
    deltas : ndarray of shape (n_shapes, n_vertices, 3)
        Displacement of each kept vertex from neutral for each expression, in mm.
    triangles : ndarray of shape (n_triangles, 3) of int
        The kept polygons (those whose every corner is kept), split into triangles.
    n_polygons : int
        Kept polygons before triangulation.
    n_vertices_in_file : int
        Vertices of the neutral OBJ before the region was cut.
    unit_mm : float
        Millimetres per OBJ unit (the files carry no units).
    files : dict
        ``"neutral"`` and every expression name -> file path.
    """

    neutral: np.ndarray
    names: tuple[str, ...]
    deltas: np.ndarray
    triangles: np.ndarray
    n_polygons: int
    n_vertices_in_file: int
    unit_mm: float
    files: dict = field(default_factory=dict)

    def shapes(self, names: Sequence[str]) -> np.ndarray:
        """Displacements of the named expressions, shape (len(names), n_vertices, 3); clear error for unknowns."""
        missing = [name for name in names if name not in self.names]
        if missing:
            raise WorkbenchError(f"blendshape(s) {missing} not found; the folder has {list(self.names)}")
        position = {name: i for i, name in enumerate(self.names)}
        return self.deltas[[position[name] for name in names]]


def expression_names(folder: Path, neutral_file: str) -> list[str]:
    """Names of the expression OBJs in a blendshape folder: every ``*.obj`` but the neutral, sorted."""
    folder = input_path(folder, "blendshape folder", "folder", folder=True)
    return sorted(path.stem for path in folder.glob("*.obj") if path.name != neutral_file)


def load_blendshapes(
    folder: str | os.PathLike,
    *,
    neutral_file: str,
    names: Sequence[str] | None = None,
    region_vertices: int | None = None,
    unit_mm: float = 1.0,
) -> Blendshapes:
    """Read a blendshape folder: a neutral OBJ and one OBJ per named expression, all of the same topology.

    Parameters
    ----------
    folder : path-like
        The folder (ICT FaceKit's ``FaceXModel`` layout).
    neutral_file : str
        File name of the neutral mesh inside ``folder``.
    names : sequence of str, optional
        Expressions to read; every ``*.obj`` except the neutral when None.
    region_vertices : int, optional
        Keep only vertices ``[0, region_vertices)`` and the polygons among them (ICT's face region is the first
        9,409 vertices); all vertices when None.
    unit_mm : float
        Millimetres per OBJ unit (ICT FaceKit is in about centimetres: 10).

    Returns
    -------
    Blendshapes

    Raises
    ------
    WorkbenchError
        If the folder or a named file is missing, or an expression's vertex count or polygons differ from the
        neutral's.
    """
    folder = input_path(folder, "blendshape folder", "folder", folder=True)
    if not unit_mm > 0:
        raise WorkbenchError(f"blendshape unit_mm must be positive, got {unit_mm}")
    if isinstance(names, str):
        raise WorkbenchError(f"names must be a list of expression names, got the string {names!r}; give [{names!r}]")
    neutral_path = folder / neutral_file
    neutral = read_obj(neutral_path)
    available = expression_names(folder, neutral_file)
    if names is None:
        names = available
    missing = [name for name in names if name not in available]
    if missing:
        raise WorkbenchError(f"{folder}: no OBJ for expression(s) {missing}; the folder has {available}")
    if len(set(names)) != len(names):
        raise WorkbenchError(f"expression names must be distinct, got {list(names)}")
    n_kept = neutral.n_vertices if region_vertices is None else int(region_vertices)
    if not 3 <= n_kept <= neutral.n_vertices:
        raise WorkbenchError(
            f"region_vertices must be in [3, {neutral.n_vertices}] for {neutral_path} "
            f"({neutral.n_vertices} vertices), got {region_vertices}"
        )

    deltas = np.empty((len(names), n_kept, 3))
    neutral_digest = _vertices_cached(*_file_key(neutral_path))[1]
    check_vertices(neutral.vertices, neutral.vertices, neutral_path)
    for i, name in enumerate(names):
        target_path = folder / f"{name}.obj"
        vertices, digest, n_faces = _vertices_cached(*_file_key(target_path))
        if len(vertices) != neutral.n_vertices:
            raise WorkbenchError(
                f"{target_path}: {len(vertices)} vertices, but the neutral {neutral_path.name} "
                f"has {neutral.n_vertices}; every expression must have the neutral's topology"
            )
        check_vertices(vertices, neutral.vertices, target_path)
        # A target holding only vertices takes its polygons from the neutral.
        if n_faces and digest != neutral_digest:
            check_same_topology(read_obj(target_path), neutral)
        deltas[i] = (vertices[:n_kept] - neutral.vertices[:n_kept]) * unit_mm
    sizes, corners = polygons_within(neutral.polygon_sizes, neutral.polygon_vertices, n_kept)
    return Blendshapes(
        neutral=neutral.vertices[:n_kept] * unit_mm,
        names=tuple(names),
        deltas=deltas,
        triangles=triangulate(sizes, corners),
        n_polygons=int(sizes.size),
        n_vertices_in_file=neutral.n_vertices,
        unit_mm=float(unit_mm),
        files={"neutral": str(neutral_path), **{name: str(folder / f"{name}.obj") for name in names}},
    )


def check_vertices(vertices: np.ndarray, neutral: np.ndarray, path: Path) -> None:
    """Refuse a mesh with a vertex far outside the neutral face (a coordinate at 1e6 or 1e300): no researcher
    wants that shape (:func:`workbench.formats.plausibility.mesh_outlier_problems`).

    Parameters
    ----------
    vertices, neutral : ndarray of shape (n_vertices, 3)
        In the file's units.
    path : pathlib.Path
    """
    from workbench.formats.plausibility import mesh_outlier_problems

    problems = mesh_outlier_problems(vertices, neutral, str(path), unit="file units")
    if problems:
        raise WorkbenchError(problems[0])


def check_same_topology(target: ObjMesh, neutral: ObjMesh) -> None:
    """Raise a :class:`WorkbenchError` naming ``target`` unless it has the neutral's vertices and polygons."""
    if target.n_vertices != neutral.n_vertices:
        raise WorkbenchError(
            f"{target.path}: {target.n_vertices} vertices, but the neutral {neutral.path.name} "
            f"has {neutral.n_vertices}; every expression must have the neutral's topology"
        )
    if (
        target.polygon_sizes.shape != neutral.polygon_sizes.shape
        or not np.array_equal(target.polygon_sizes, neutral.polygon_sizes)
        or not np.array_equal(target.polygon_vertices, neutral.polygon_vertices)
    ):
        raise WorkbenchError(
            f"{target.path}: its polygons ({target.polygon_sizes.size}) differ from those of the "
            f"neutral {neutral.path.name} ({neutral.polygon_sizes.size}); every expression must "
            "have the neutral's topology"
        )


def read_blendshapes(
    folder: str | os.PathLike,
    *,
    neutral: str,
    names: Sequence[str] | None = None,
    region_vertices: int | None = None,
    unit_mm: float = 1.0,
) -> Blendshapes:
    """A blendshape folder: a neutral OBJ and one OBJ per named expression (ICT FaceKit's ``FaceXModel`` layout), as
    displacements in millimetres (:func:`load_blendshapes`).

    Parameters
    ----------
    folder : path-like
    neutral : str
        File name of the neutral OBJ inside ``folder``.
    names : sequence of str, optional
        Expressions to read (every other ``*.obj`` when None); a single string is refused, not read as its
        letters.
    region_vertices : int, optional
        Keep vertices ``[0, region_vertices)`` only (ICT's face region: 9,409).
    unit_mm : float, default 1.0
        Millimetres per OBJ unit (ICT FaceKit: 10).

    Returns
    -------
    Blendshapes
        ``neutral`` of shape (n_vertices, 3), ``names``, ``deltas`` of shape (n_shapes, n_vertices, 3),
        ``triangles``. ``deltas.reshape(len(deltas), -1)`` are hand shapes for ``QuasiEigenFaces``.
    """
    return load_blendshapes(folder, neutral_file=neutral, names=names, region_vertices=region_vertices, unit_mm=unit_mm)
