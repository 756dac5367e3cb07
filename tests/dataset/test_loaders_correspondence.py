"""Marker-to-mesh correspondence: the editable table, placement by similarity alignment and nearest vertex."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from workbench.core.errors import WorkbenchError
from workbench.dataset.correspondence import place_markers, placement_table_text, read_marker_table
from workbench.settings.config import CONF_DIR

TABLE = CONF_DIR / "correspondence" / "animface_ict.csv"


def grid_mesh(n=12, spacing=10.0):
    """A curved sheet of n x n vertices (mm), like a patch of face."""
    x, y = np.meshgrid(np.arange(n) * spacing, np.arange(n) * spacing)
    z = 0.004 * ((x - 55) ** 2 + (y - 55) ** 2)
    return np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)


def write_table(path, rows, header="marker,landmark,vertex,note"):
    path.write_text("# a comment line\n" + "\n".join([header] + rows) + "\n")
    return path


def test_table_rows_landmarks_overrides_and_empty_vertices(tmp_path):
    table = read_marker_table(
        write_table(tmp_path / "t.csv", ["A,0,,landmark", "B,11,,", "C,143,143,fixed", "D,,60,override", "E,,,found"]),
        n_vertices=144,
    )
    assert table.labels == ("A", "B", "C", "D", "E")
    np.testing.assert_array_equal(table.landmarks, [0, 11, 143, -1, -1])
    np.testing.assert_array_equal(table.vertices, [-1, -1, 143, 60, -1])
    assert table.notes[3] == "override"
    with pytest.raises(WorkbenchError, match=r"needs a vertex for every marker; row\(s\) \['A', 'B', 'E'\]"):
        table.require_vertices("a test")


@pytest.mark.parametrize(
    "rows,message",
    [
        (["A,0,,", "B,1,,", "A,2,,"], r"row 4: marker 'A' appears twice"),
        (["A,0,,", "B,1,,", "C,2,x,"], r"row 4: vertex 'x' is not a vertex index"),
        (["A,0,,", "B,1,,", "C,200,,"], r"row 4: landmark 200 is outside the mesh's vertices \[0, 144\)"),
        (["A,0,,", "B,1,,", "C,,,"], r"2 row\(s\) with a landmark vertex; the similarity alignment needs at least 3"),
    ],
)
def test_malformed_tables_name_file_and_row(tmp_path, rows, message):
    path = write_table(tmp_path / "bad.csv", rows)
    with pytest.raises(WorkbenchError, match=message) as error:
        read_marker_table(path, n_vertices=144)
    assert str(error.value).startswith(str(path))


def test_table_without_the_columns(tmp_path):
    with pytest.raises(WorkbenchError, match=r"missing column\(s\) \['landmark'\]"):
        read_marker_table(write_table(tmp_path / "old.csv", ["A,1,x"], header="marker,vertex,note"))


def test_placement_recovers_a_known_similarity_and_the_nearest_vertices(tmp_path):
    mesh = grid_mesh()
    rotation = Rotation.from_rotvec([0.05, 0.2, -0.1]).as_matrix()
    scale, shift = 1.2, np.array([300.0, 800.0, 20.0])
    chosen = np.array([0, 11, 132, 143, 50, 77, 95, 30])
    rng = np.random.default_rng(0)
    # Markers 1.5 mm off their vertices, then moved into a "capture" frame.
    markers = scale * (mesh[chosen] + rng.normal(0, 0.5, (8, 3))) @ rotation.T + shift
    # Four landmark pairs, the first also fixed by hand; the other seven vertices are found.
    rows = [f"m{i},{vertex if i < 4 else ''},{vertex if i == 0 else ''}," for i, vertex in enumerate(chosen)]
    table = read_marker_table(write_table(tmp_path / "t.csv", rows), n_vertices=len(mesh))
    placement = place_markers(table, markers, mesh, refine_iterations=10)
    np.testing.assert_array_equal(placement.vertices, chosen)
    assert placement.found.tolist() == [False] + [True] * 7
    assert placement.mesh_to_capture.scale == pytest.approx(scale, rel=0.02)
    np.testing.assert_allclose(placement.mesh_to_capture.rotation, rotation, atol=0.02)
    assert placement.distances.max() < 3.0 and "7 vertices by nearest vertex" in placement.describe()
    text = placement_table_text(placement, table)
    assert text.splitlines()[0] == "marker,landmark,vertex,note" and text.splitlines()[5].startswith("m4,,50,")


def test_placement_rejects_markers_without_a_neutral_position(tmp_path):
    mesh = grid_mesh()
    table = read_marker_table(write_table(tmp_path / "t.csv", ["a,0,,", "b,11,,", "c,132,,"]))
    markers = mesh[[0, 11, 132]].copy()
    markers[1] = np.nan
    with pytest.raises(WorkbenchError, match=r"markers \['b'\] have no position in the neutral frame"):
        place_markers(table, markers, mesh)


def test_shipped_table_is_the_automatic_placement_on_the_jaw_take(shared_data):
    """Emptying every vertex of conf/correspondence/animface_ict.csv and placing again gives the same vertices."""
    from dataclasses import replace

    from workbench.formats.c3d import read_c3d_markers
    from workbench.formats.obj import load_blendshapes

    face = load_blendshapes(
        shared_data / "ict-facekit" / "FaceXModel",
        neutral_file="generic_neutral_mesh.obj",
        names=[],
        region_vertices=9409,
        unit_mm=10.0,
    )
    shipped = read_marker_table(TABLE, n_vertices=9409)
    assert len(shipped.labels) == 41 and len(set(shipped.vertices)) == 41 and shipped.vertices.min() >= 0
    take = read_c3d_markers(shared_data / "animface" / "animface_jaw.c3d")
    neutral = take.positions[0, take.index_of(shipped.labels, named_in=str(TABLE))]
    placement = place_markers(replace(shipped, vertices=np.full(41, -1)), neutral, face.neutral, refine_iterations=50)
    np.testing.assert_array_equal(placement.vertices, shipped.vertices)
    assert 0.9 < placement.mesh_to_capture.scale < 1.1  # the performer's face is about the ICT face's size
    assert placement.distances.mean() < 4.0 and placement.distances.max() < 8.0
