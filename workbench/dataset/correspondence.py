"""Marker-to-mesh correspondence: which vertex of the basis mesh each capture marker sits on.

The correspondence is an editable CSV table (``conf/correspondence/*.csv``), one row per marker::

    marker,landmark,vertex,note
    NoseHead,4857,5052,ICT landmark 30 (nose tip)
    Chin,,969,
    Chin_L1,,,

- ``landmark``: a mesh vertex paired with the marker for the similarity alignment (scale, rotation,
  translation) that brings the mesh onto the capture; at least 3 rows need one.
- ``vertex``: the marker's vertex on the mesh when fixed by hand (a per-marker override, or an earlier
  placement pasted in for review). Left empty, it is found: the nearest vertex to the marker's neutral position
  once the mesh is aligned onto the capture.
- ``note``: free text. Lines starting with ``#`` are comments.

Placement: the similarity is fitted to the landmark pairs, then optionally refined by iterating "nearest
vertex for the free markers, refit the similarity to every marker-vertex pair" (iterative closest points with
scale), because markers sit beside features (on the skin around an eye corner, outside a mouth corner) rather
than on the mesh's landmark vertices.
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.dataset.rigid import Similarity, similarity_transform

TABLE_COLUMNS = ("marker", "landmark", "vertex", "note")


@dataclass(frozen=True)
class MarkerTable:
    """The rows of a correspondence table.

    Attributes
    ----------
    labels : tuple of str
        Marker labels, in table order.
    landmarks : ndarray of shape (n_markers,) of int
        Mesh vertex paired with each marker for the similarity alignment, -1 for markers not used in it.
    vertices : ndarray of shape (n_markers,) of int
        Mesh vertex of each marker, -1 where the table leaves it to the nearest-vertex search.
    notes : tuple of str
    path : pathlib.Path
    """

    labels: tuple[str, ...]
    landmarks: np.ndarray
    vertices: np.ndarray
    notes: tuple[str, ...]
    path: Path

    def require_vertices(self, purpose: str) -> np.ndarray:
        """Every marker's vertex, with a clear error when the table leaves some to the nearest-vertex search."""
        empty = [label for label, vertex in zip(self.labels, self.vertices) if vertex < 0]
        if empty:
            raise WorkbenchError(
                f"{self.path}: {purpose} needs a vertex for every marker; row(s) {empty} have none "
                "(fill them in, e.g. from an animface run's provenance)"
            )
        return self.vertices


def read_marker_table(path: str | os.PathLike, *, n_vertices: int | None = None) -> MarkerTable:
    """Read a correspondence table (see the module docstring for its columns).

    Parameters
    ----------
    path : path-like
    n_vertices : int, optional
        Vertices of the mesh; filled vertices must be below it.

    Returns
    -------
    MarkerTable

    Raises
    ------
    WorkbenchError
        Naming the file and row, for a missing column, a duplicate marker, a vertex or landmark that is not an
        index of the mesh, or fewer than 3 landmark rows.
    """
    path = Path(path)
    if not path.is_file():
        raise WorkbenchError(f"{path}: correspondence table not found")
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            lines = [line for line in handle if line.strip() and not line.lstrip().startswith("#")]
    except UnicodeDecodeError as error:
        raise WorkbenchError(f"{path}: not a text CSV file ({error})") from None
    reader = csv.DictReader(lines, skipinitialspace=True)
    header = [name.strip() for name in (reader.fieldnames or [])]
    missing = [column for column in TABLE_COLUMNS[:3] if column not in header]
    if missing:
        raise WorkbenchError(
            f"{path}: missing column(s) {missing}; a correspondence table has columns {', '.join(TABLE_COLUMNS)}"
        )
    labels, landmarks, vertices, notes = [], [], [], []
    for number, row in enumerate(reader, start=2):
        row = {key.strip(): (value or "").strip() for key, value in row.items() if key is not None}
        label = row["marker"]
        if not label:
            raise WorkbenchError(f"{path}: row {number}: empty marker label")
        if label in labels:
            raise WorkbenchError(f"{path}: row {number}: marker {label!r} appears twice")
        labels.append(label)
        landmarks.append(_parse_vertex(row["landmark"], "landmark", path, number, n_vertices))
        vertices.append(_parse_vertex(row["vertex"], "vertex", path, number, n_vertices))
        notes.append(row.get("note", ""))
    n_landmarks = sum(landmark >= 0 for landmark in landmarks)
    if n_landmarks < 3:
        raise WorkbenchError(
            f"{path}: {n_landmarks} row(s) with a landmark vertex; the similarity alignment needs "
            "at least 3 landmark pairs"
        )
    return MarkerTable(
        labels=tuple(labels),
        landmarks=np.array(landmarks, dtype=np.int64),
        vertices=np.array(vertices, dtype=np.int64),
        notes=tuple(notes),
        path=path,
    )


def _parse_vertex(text: str, column: str, path: Path, number: int, n_vertices: int | None) -> int:
    if text == "":
        return -1
    try:
        vertex = int(text)
    except ValueError:
        raise WorkbenchError(f"{path}: row {number}: {column} {text!r} is not a vertex index") from None
    if vertex < 0 or (n_vertices is not None and vertex >= n_vertices):
        raise WorkbenchError(
            f"{path}: row {number}: {column} {vertex} is outside the mesh's vertices [0, {n_vertices})"
        )
    return vertex


@dataclass(frozen=True)
class MarkerPlacement:
    """Markers placed on a mesh.

    Attributes
    ----------
    labels : tuple of str
        Table order.
    vertices : ndarray of shape (n_markers,) of int
        The mesh vertex of each marker.
    found : ndarray of shape (n_markers,) of bool
        Markers whose vertex was found by the nearest-vertex search (not given in the table).
    mesh_to_capture : Similarity
        Takes mesh coordinates onto the capture's: fitted to the landmark pairs, then to every marker-vertex
        pair when refined.
    distances : ndarray of shape (n_markers,)
        Distance from each marker's neutral position to its vertex after alignment, in capture units.
    landmark_rms : float
        RMS distance of the landmark pairs after the landmark alignment, in capture units.
    n_landmarks : int
        Landmark pairs of the first alignment.
    refine_iterations : int
        Refinement iterations run (0: the landmark alignment is final).
    """

    labels: tuple[str, ...]
    vertices: np.ndarray
    found: np.ndarray
    mesh_to_capture: Similarity
    distances: np.ndarray
    landmark_rms: float
    n_landmarks: int
    refine_iterations: int

    def in_mesh_frame(self, points: np.ndarray) -> np.ndarray:
        """Capture points in the mesh's head frame (its axes and origin) at the capture's size: the rigid part of
        the inverse of ``mesh_to_capture``, ``(points - translation) @ rotation``.

        Parameters
        ----------
        points : ndarray of shape (..., 3)
            In capture coordinates (mm).

        Returns
        -------
        ndarray of shape (..., 3)
            In mm; the mesh there sits at ``mesh_to_capture.scale`` times its own coordinates.
        """
        return (points - self.mesh_to_capture.translation) @ self.mesh_to_capture.rotation

    def describe(self) -> str:
        """One line: alignment, scale and marker-to-vertex distances."""
        worst = int(np.argmax(self.distances))
        refined = (
            f", then refitted to all {len(self.labels)} marker-vertex pairs "
            f"({self.refine_iterations} round{'s' if self.refine_iterations > 1 else ''})"
            if self.refine_iterations
            else ""
        )
        return (
            f"markers placed on the mesh: similarity alignment on {self.n_landmarks} landmark pairs "
            f"(RMS {self.landmark_rms:.1f} mm){refined}, scale {self.mesh_to_capture.scale:.3f}; "
            f"{int(self.found.sum())} vertices by nearest vertex, {int((~self.found).sum())} from the table; "
            f"marker-to-vertex distance mean {self.distances.mean():.1f} mm, max "
            f"{self.distances[worst]:.1f} mm ({self.labels[worst]})"
        )


def place_markers(
    table: MarkerTable,
    marker_neutral: np.ndarray,
    mesh_vertices: np.ndarray,
    *,
    candidate_vertices: Sequence[int] | None = None,
    refine_iterations: int = 0,
) -> MarkerPlacement:
    """Place capture markers on a mesh: similarity alignment on the landmark pairs, then the nearest vertex.

    Parameters
    ----------
    table : MarkerTable
    marker_neutral : ndarray of shape (n_markers, 3)
        Neutral positions of the table's markers, in table order, in capture coordinates.
    mesh_vertices : ndarray of shape (n_vertices, 3)
        The mesh's neutral vertices, in mesh coordinates.
    candidate_vertices : sequence of int, optional
        Vertices the nearest-vertex search may choose (e.g. the face region); all when None.
    refine_iterations : int
        At most this many rounds of "nearest vertex for the free markers, refit the similarity to every
        marker-vertex pair", stopping early when no vertex changes; 0 keeps the landmark alignment.

    Returns
    -------
    MarkerPlacement
    """
    from scipy.spatial import cKDTree

    marker_neutral = np.asarray(marker_neutral, dtype=np.float64)
    if marker_neutral.shape != (len(table.labels), 3):
        raise WorkbenchError(
            f"{table.path}: {len(table.labels)} markers in the table but neutral positions of shape "
            f"{marker_neutral.shape}"
        )
    if not np.all(np.isfinite(marker_neutral)):
        gaps = [label for label, point in zip(table.labels, marker_neutral) if not np.all(np.isfinite(point))]
        raise WorkbenchError(
            f"markers {gaps} have no position in the neutral frame; choose a neutral frame where "
            "every marker of the correspondence table is seen"
        )
    for column, values in (("landmark", table.landmarks), ("vertex", table.vertices)):
        if values.max() >= len(mesh_vertices):
            raise WorkbenchError(
                f"{table.path}: {column} {int(values.max())} is outside the mesh's {len(mesh_vertices)} vertices"
            )
    if not 0 <= int(refine_iterations):
        raise WorkbenchError(f"correspondence refine_iterations must be >= 0, got {refine_iterations}")
    candidates = (
        np.arange(len(mesh_vertices)) if candidate_vertices is None else np.asarray(candidate_vertices, dtype=np.int64)
    )
    tree = cKDTree(mesh_vertices[candidates])
    found = table.vertices < 0

    def assign(similarity: Similarity) -> np.ndarray:
        vertices = table.vertices.copy()
        if found.any():
            # Nearest vertex to the marker, searched in mesh coordinates (the inverse similarity).
            in_mesh = (marker_neutral[found] - similarity.translation) @ similarity.rotation / similarity.scale
            vertices[found] = candidates[tree.query(in_mesh)[1]]
        return vertices

    with_landmark = table.landmarks >= 0
    similarity = similarity_transform(mesh_vertices[table.landmarks[with_landmark]], marker_neutral[with_landmark])
    landmark_rms = float(
        np.sqrt(
            np.mean(
                np.sum(
                    (similarity.apply(mesh_vertices[table.landmarks[with_landmark]]) - marker_neutral[with_landmark])
                    ** 2,
                    axis=1,
                )
            )
        )
    )
    vertices = assign(similarity)
    iterations = 0
    for iterations in range(1, int(refine_iterations) + 1):
        similarity = similarity_transform(mesh_vertices[vertices], marker_neutral)
        previous, vertices = vertices, assign(similarity)
        if np.array_equal(previous, vertices):
            break
    distances = np.linalg.norm(similarity.apply(mesh_vertices[vertices]) - marker_neutral, axis=1)
    return MarkerPlacement(
        labels=table.labels,
        vertices=vertices,
        found=found,
        mesh_to_capture=similarity,
        distances=distances,
        landmark_rms=landmark_rms,
        n_landmarks=int(with_landmark.sum()),
        refine_iterations=iterations,
    )


def placement_table_text(placement: MarkerPlacement, table: MarkerTable) -> str:
    """The correspondence table with every vertex filled in by a placement (to review and save as overrides).

    Returns
    -------
    str
        CSV text with the columns of :data:`TABLE_COLUMNS`.
    """
    lines = [",".join(TABLE_COLUMNS)]
    for label, landmark, vertex, note, found, distance in zip(
        placement.labels, table.landmarks, placement.vertices, table.notes, placement.found, placement.distances
    ):
        if found:
            note = "; ".join(part for part in (note, f"nearest vertex {distance:.1f} mm") if part)
        landmark_text = "" if landmark < 0 else str(landmark)
        lines.append(f"{label},{landmark_text},{vertex},{note.replace(',', ';')}")
    return "\n".join(lines) + "\n"
