"""The face mesh of a dataset at rest: its vertices, triangles and the vertices within the markers' reach, read
from the dataset's config alone (no frames are built).

A run that trained on markers only has no mesh frames; its report shows faces by carrying the markers'
displacement fields onto this mesh, as the paper did ("markers interpolated onto the mesh with radial basis
functions"), with the map :func:`workbench.dataset.transfer.point_transfer` gives.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from workbench.core.errors import WorkbenchError


@dataclass(frozen=True)
class RestMesh:
    """A dataset's face mesh at rest, in the coordinates of its markers.

    Attributes
    ----------
    vertices : ndarray of shape (n_vertices, 3)
        Rest positions, in the units and frame of the dataset's marker variant.
    triangles : ndarray of shape (n_triangles, 3) of int
    support : ndarray of shape (n_vertices,) of bool, or None
        The vertices within the markers' reach (the rest get their motion by extrapolation); None: all.
    description : str
        What the mesh is, for captions.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    support: np.ndarray | None
    description: str


def rest_mesh(cfg, provenance: Mapping | None = None) -> RestMesh:
    """The face mesh of a dataset config at rest (rest geometry only: no frame is deformed or interpolated).

    Parameters
    ----------
    cfg : typed dataset settings
        The ``dataset`` group, checked and typed (a record's: :attr:`workbench.record.record.RunRecord.settings`).
    provenance : mapping, optional
        The dataset's provenance as a run recorded it; AnimFace needs its placement (the scale of the ICT face in
        the performer's frame and the markers' vertices).

    Returns
    -------
    RestMesh

    Raises
    ------
    WorkbenchError
        When the dataset has no face mesh or its files cannot be read.
    """
    kind = cfg.kind
    if kind == "synthetic":
        return _synthetic_rest_mesh(cfg)
    if kind in ("ict_livelink", "animface"):
        from workbench.dataset.animface import within_marker_reach
        from workbench.dataset.real import load_basis

        basis = load_basis(cfg, [])  # the neutral only
        provenance = provenance or {}
        if kind == "ict_livelink":
            vertices, markers = basis.neutral, provenance.get("virtual_marker_vertices") or {}
            text = f"the ICT FaceKit face region ({len(vertices)} vertices)"
        else:
            placement = provenance.get("placement") or {}
            if "scale" not in placement or not placement.get("vertices"):
                raise WorkbenchError(
                    "dataset animface: the record's provenance has no marker placement (scale and "
                    "vertices), so the ICT face cannot be put in the performer's frame"
                )
            vertices, markers = float(placement["scale"]) * basis.neutral, placement["vertices"]
            text = f"the ICT FaceKit face region ({len(vertices)} vertices) scaled into the performer's frame"
        markers = np.asarray(list(markers.values()), dtype=np.int64)
        support = within_marker_reach(vertices, markers, np.arange(len(vertices))) if markers.size else None
        return RestMesh(vertices, basis.triangles, support, text)
    raise WorkbenchError(f"dataset.kind {kind!r} has no face mesh to carry the markers onto")


def _synthetic_rest_mesh(cfg) -> RestMesh:
    """The synthetic actor's head mesh at rest; the face region (the vertices inside the face markers' convex
    hull in the face plane) is the markers' reach."""
    from workbench.dataset.synthetic import make_face_mesh
    from workbench.dataset.synthetic_builder import face_region

    rows, cols, n_markers = cfg.mesh_rows, cfg.mesh_cols, cfg.n_face_markers  # checked integers
    mesh = make_face_mesh(rows, cols)
    support = np.zeros(mesh.n_vertices, dtype=bool)
    support[face_region(rows, cols, n_markers)[0]] = True
    return RestMesh(mesh.vertices, mesh.faces, support, f"the synthetic actor's head mesh ({mesh.n_vertices} vertices)")
