"""OBJ meshes and blendshape folders: small files written here, and ICT FaceKit's FaceXModel folder."""

import json

import numpy as np
import pytest

from workbench.core.errors import WorkbenchError
from workbench.formats.obj import load_blendshapes, polygons_within, read_obj, triangulate

# Two quads and a triangle over 7 vertices; the triangle refers to its vertices relative to the end.
NEUTRAL = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0], [3, 0, 0]], dtype=float)
FACES = "f 1/1/1 2/2/1 3/3/1 4/4/1\nf 2 5 6 3\nf -3 -1 -2\n"


def write_obj(path, vertices, faces=FACES, vertex_suffix=""):
    lines = ["# test mesh", "mtllib none.mtl", "o face"]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}{vertex_suffix}" for x, y, z in vertices]
    lines += ["vt 0 0", "vn 0 0 1", "usemtl skin"]
    path.write_text("\n".join(lines) + "\n" + faces)
    return path


@pytest.fixture
def folder(tmp_path):
    write_obj(tmp_path / "neutral.obj", NEUTRAL)
    moved = NEUTRAL.copy()
    moved[0] += [0.0, 0.0, 0.5]
    write_obj(tmp_path / "lift_L.obj", moved)
    moved = NEUTRAL.copy()
    moved[6] += [0.1, 0.0, 0.0]
    write_obj(tmp_path / "pull_R.obj", moved, vertex_suffix=" 0.5 0.5 0.5")  # a vertex colour after x y z
    return tmp_path


def test_read_obj_vertices_polygons_and_relative_indices(folder):
    mesh = read_obj(folder / "neutral.obj")
    np.testing.assert_array_equal(mesh.vertices, NEUTRAL)
    np.testing.assert_array_equal(mesh.polygon_sizes, [4, 4, 3])
    np.testing.assert_array_equal(mesh.polygon_vertices, [0, 1, 2, 3, 1, 4, 5, 2, 4, 6, 5])


def test_triangulate_fans_quads_and_keeps_triangles():
    triangles = triangulate(np.array([4, 3]), np.array([0, 1, 2, 3, 4, 5, 6]))
    np.testing.assert_array_equal(triangles, [[0, 1, 2], [0, 2, 3], [4, 5, 6]])


def test_polygons_within_keeps_polygons_entirely_inside_the_region():
    sizes, corners = polygons_within(np.array([4, 4, 3]), np.array([0, 1, 2, 3, 1, 4, 5, 2, 4, 6, 5]), 4)
    np.testing.assert_array_equal(sizes, [4])
    np.testing.assert_array_equal(corners, [0, 1, 2, 3])


def test_blendshape_folder_names_displacements_units_and_region(folder):
    shapes = load_blendshapes(folder, neutral_file="neutral.obj", unit_mm=10.0)
    assert shapes.names == ("lift_L", "pull_R")
    np.testing.assert_allclose(shapes.neutral, NEUTRAL * 10)
    np.testing.assert_allclose(shapes.deltas[0, 0], [0, 0, 5])
    np.testing.assert_allclose(shapes.deltas[1, 6], [1, 0, 0])
    assert np.count_nonzero(shapes.deltas) == 2
    assert shapes.n_polygons == 3 and shapes.triangles.shape == (5, 3)

    region = load_blendshapes(folder, neutral_file="neutral.obj", names=["pull_R"], region_vertices=4)
    assert region.names == ("pull_R",) and region.neutral.shape == (4, 3) and region.deltas.shape == (1, 4, 3)
    assert region.n_polygons == 1 and region.n_vertices_in_file == 7
    np.testing.assert_allclose(region.shapes(["pull_R"]), 0.0)
    with pytest.raises(WorkbenchError, match=r"blendshape\(s\) \['nope'\] not found"):
        region.shapes(["nope"])


def test_expression_with_a_different_vertex_count_is_named(folder):
    write_obj(folder / "broken.obj", NEUTRAL[:6], faces="f 1 2 3\n")
    with pytest.raises(WorkbenchError) as error:
        load_blendshapes(folder, neutral_file="neutral.obj")
    message = str(error.value)
    assert "broken.obj" in message and "6 vertices" in message and "neutral.obj has 7" in message


def test_expression_with_other_polygons_is_named(folder):
    write_obj(folder / "rewired.obj", NEUTRAL, faces="f 1 2 3 4\nf 2 5 6 3\nf 5 6 7\n")
    with pytest.raises(WorkbenchError, match=r"rewired\.obj: its polygons \(3\) differ"):
        load_blendshapes(folder, neutral_file="neutral.obj")


def test_expression_holding_only_vertices_takes_the_neutral_polygons(folder):
    write_obj(folder / "bare.obj", NEUTRAL + 1.0, faces="")
    shapes = load_blendshapes(folder, neutral_file="neutral.obj", names=["bare"])
    np.testing.assert_allclose(shapes.deltas, 1.0)


def test_expression_names_given_as_one_string_are_refused(folder):
    with pytest.raises(WorkbenchError, match=r"^names must be a list of expression names, got the string 'lift_L'"):
        load_blendshapes(folder, neutral_file="neutral.obj", names="lift_L")
    assert load_blendshapes(folder, neutral_file="neutral.obj", names=["lift_L"]).names == ("lift_L",)


def test_malformed_and_missing_files(folder, tmp_path):
    (folder / "junk.obj").write_text("v 1 2 x\nf 1 2 3\n")
    with pytest.raises(WorkbenchError, match=r"junk\.obj: a 'v' line holds something that is not a number"):
        read_obj(folder / "junk.obj")
    (folder / "short.obj").write_text("v 1 2 3\nv 1 2\nv 0 0 0\n")
    with pytest.raises(WorkbenchError, match=r"short\.obj: vertex 2 has fewer than 3 coordinates"):
        read_obj(folder / "short.obj")
    (folder / "outside.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    with pytest.raises(WorkbenchError, match=r"outside\.obj: a face refers to vertex 9, outside the file's 3"):
        read_obj(folder / "outside.obj")
    with pytest.raises(WorkbenchError, match=r"no OBJ for expression\(s\) \['smile'\]"):
        load_blendshapes(folder, neutral_file="neutral.obj", names=["smile"])
    with pytest.raises(WorkbenchError, match="OBJ file not found"):
        load_blendshapes(folder, neutral_file="missing.obj")
    with pytest.raises(WorkbenchError, match="nowhere: blendshape folder not found"):
        load_blendshapes(tmp_path / "nowhere", neutral_file="neutral.obj")


@pytest.fixture(scope="module")
def ict(shared_data):
    folder = shared_data / "ict-facekit" / "FaceXModel"
    return folder, load_blendshapes(folder, neutral_file="generic_neutral_mesh.obj", region_vertices=9409, unit_mm=10.0)


def test_ict_facexmodel_topology_names_and_units(ict):
    folder, shapes = ict
    neutral = read_obj(folder / "generic_neutral_mesh.obj")
    assert neutral.n_vertices == 26719 and neutral.polygon_sizes.size == 26384
    assert set(np.unique(neutral.polygon_sizes)) == {3, 4}  # quads and triangles
    assert shapes.n_vertices_in_file == 26719 and shapes.neutral.shape == (9409, 3) and shapes.n_polygons == 9230
    assert shapes.triangles.max() == 9408
    listed = json.loads((folder / "vertex_indices.json").read_text())["expressions"]
    assert len(shapes.names) == 57 and set(listed) <= set(shapes.names)
    assert {"PupilDilate_L", "PupilDilate_R", "cheekRaiser_L", "cheekRaiser_R"} == set(shapes.names) - set(listed)
    # About centimetres in the files: the face region is about 18 cm wide, so about 180 mm here.
    width = np.ptp(shapes.neutral[:, 0])
    assert 150 < width < 220


def test_ict_quirks_sides_and_pupils(ict):
    _, shapes = ict
    smile_left = shapes.shapes(["mouthSmile_L"])[0]
    moved = np.linalg.norm(smile_left, axis=1) > 1.0
    assert shapes.neutral[moved, 0].mean() > 10  # "_L" is the face's own left: +x
    # PupilDilate moves the eyes (beyond vertex 9409), not the face region: a nearly singular basis shape.
    assert np.abs(shapes.shapes(["PupilDilate_L", "PupilDilate_R"])).max() < 0.1  # mm, file rounding
    assert np.linalg.norm(shapes.shapes(["jawOpen"])[0], axis=1).max() > 30


def test_an_obj_edited_in_place_with_its_size_and_time_kept_is_read_afresh(tmp_path):
    """The parsed file is remembered in the process by its change time too, which no program can set back."""
    import os

    path = tmp_path / "face.obj"
    path.write_text("v 1 2 3\nv 4 5 6\nv 7 8 9\nf 1 2 3\n")
    first = read_obj(path).vertices.copy()
    status = path.stat()
    path.write_text("v 1 2 3\nv 4 5 6\nv 7 8 8\nf 1 2 3\n")  # same size
    os.utime(path, ns=(status.st_atime_ns, status.st_mtime_ns))
    assert path.stat().st_size == status.st_size and path.stat().st_mtime_ns == status.st_mtime_ns
    assert read_obj(path).vertices[2, 2] == 8.0 and first[2, 2] == 9.0


# --- a capture as one OBJ file per frame ------------------------------------------------------------------------


def frames_of(n_frames, seed=0):
    """Frames of the test mesh: the neutral with each vertex moved by up to 0.1 (positions)."""
    rng = np.random.default_rng(seed)
    return NEUTRAL + rng.uniform(-0.1, 0.1, (n_frames, *NEUTRAL.shape))


def test_an_obj_folder_is_read_as_one_sequence_in_natural_order(tmp_path):
    from workbench.formats.obj_sequence import read_obj_sequence

    frames = frames_of(12)
    for index, frame in enumerate(frames):  # frame_2 must come before frame_10, unlike a plain sort
        write_obj(tmp_path / f"frame_{index}.OBJ" if index == 3 else tmp_path / f"frame_{index}.obj", frame)
    (tmp_path / "notes.txt").write_text("not a frame")
    (tmp_path / "sub.obj").mkdir()  # a folder named like a frame is no frame
    sequence = read_obj_sequence(tmp_path)
    assert [path.name for path in sequence.paths][:4] == ["frame_0.obj", "frame_1.obj", "frame_2.obj", "frame_3.OBJ"]
    assert sequence.paths[-1].name == "frame_11.obj" and sequence.n_frames == 12
    np.testing.assert_allclose(sequence.vertices, frames, rtol=0, atol=5e-7)  # the files hold 6 decimals
    np.testing.assert_array_equal(
        sequence.faces, triangulate(np.array([4, 4, 3]), read_obj(sequence.paths[0]).polygon_vertices)
    )
    listed = read_obj_sequence([sequence.paths[5], str(sequence.paths[0])])  # a list keeps its order
    np.testing.assert_array_equal(listed.vertices, sequence.vertices[[5, 0]])


def test_an_obj_sequence_names_the_first_file_whose_topology_differs(tmp_path):
    from workbench.formats.obj_sequence import read_obj_sequence

    frames = frames_of(4)
    write_obj(tmp_path / "f1.obj", frames[0])
    write_obj(tmp_path / "f2.obj", frames[1], faces="f 1 2 3 4\nf 2 5 6 3\nf 5 7 6\n")  # the same polygons, as written
    write_obj(tmp_path / "f3.obj", frames[2][:-1], faces="f 1 2 3 4\nf 2 5 6 3\n")
    write_obj(tmp_path / "f10.obj", frames[3], faces="f 1 2 3 4\nf 2 5 6 3\nf 5 6 7\n")
    with pytest.raises(WorkbenchError, match=r"f3\.obj: 6 vertices, but the first file f1\.obj has 7; every frame of"):
        read_obj_sequence(tmp_path)
    (tmp_path / "f3.obj").unlink()
    with pytest.raises(WorkbenchError, match=r"f10\.obj: its polygons \(3\) differ from those of the first file f1"):
        read_obj_sequence(tmp_path)
    assert read_obj_sequence([tmp_path / "f1.obj", tmp_path / "f2.obj"]).n_frames == 2
    far = frames[1].copy()
    far[2] = 1e6
    write_obj(tmp_path / "f10.obj", far)
    with pytest.raises(WorkbenchError, match=r"f10\.obj"):
        read_obj_sequence(tmp_path)


def test_an_obj_sequence_refuses_too_few_frames_or_other_files_naming_them(tmp_path):
    from workbench.formats.obj_sequence import read_obj_sequence

    write_obj(tmp_path / "only.obj", NEUTRAL)
    with pytest.raises(WorkbenchError, match=r": holds 1 OBJ file; an OBJ sequence needs at least 2 frames$"):
        read_obj_sequence(tmp_path)
    with pytest.raises(WorkbenchError, match=r"notes\.txt: not an OBJ file; every file of an OBJ sequence"):
        (tmp_path / "notes.txt").write_text("x")
        read_obj_sequence([tmp_path / "only.obj", tmp_path / "notes.txt"])
    with pytest.raises(WorkbenchError, match=r"^source must be a folder of OBJ files, a list of OBJ paths or a mesh"):
        read_obj_sequence(3)
    with pytest.raises(WorkbenchError, match=r"only\.obj: is a file, not a folder \(folder of OBJ files or mesh seq"):
        read_obj_sequence(tmp_path / "only.obj")
    with pytest.raises(WorkbenchError, match=r"missing\.obj: OBJ file not found"):
        read_obj_sequence([tmp_path / "only.obj", tmp_path / "missing.obj"])


def test_an_obj_sequence_reader_takes_the_mesh_sequence_files_too(tmp_path):
    import workbench

    frames = frames_of(5)
    np.save(tmp_path / "take.npy", frames)
    sequence = workbench.read_obj_sequence(tmp_path / "take.npy")
    np.testing.assert_array_equal(sequence.vertices, frames)
    assert sequence.faces is None and sequence.paths == (tmp_path / "take.npy",)
