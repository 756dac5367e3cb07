"""Dataset mesh_sequence: NPZ, NPY and HDF5 sequences written here, bad input, and the ICT face's Live Link
performance saved as a VOCASET-style sequence gives the ict_livelink mesh table."""

import h5py
import numpy as np
import pandas as pd
import pytest

from workbench.api import run
from workbench.core.errors import WorkbenchError
from workbench.dataset import build_captures
from workbench.reporting.export.run import obj_text
from workbench.settings.config import compose

SHAPES = ["side", "up"]  # sorted, as a folder lists them


def write_basis(folder, neutral, deltas, triangles, unit=1.0):
    """A blendshape folder: neutral.obj and one OBJ per shape (positions / ``unit``)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "neutral.obj").write_text(obj_text(neutral / unit, triangles))
    for name, delta in zip(SHAPES, deltas):
        (folder / f"{name}.obj").write_text(obj_text((neutral + delta) / unit, triangles))
    return folder


@pytest.fixture
def scan(tmp_path):
    """A small 'scan' (metres) of a grid face moving as a blend of two shapes plus a little motion outside them."""
    rng = np.random.default_rng(3)
    x, y = np.meshgrid(np.linspace(-50, 50, 6), np.linspace(-60, 60, 7))
    neutral = np.column_stack([x.ravel(), y.ravel(), 80 - 0.01 * (x.ravel() ** 2 + y.ravel() ** 2)])
    cells = [(r * 6 + c, r * 6 + c + 1, (r + 1) * 6 + c) for r in range(6) for c in range(5)]
    triangles = np.array(cells)
    deltas = rng.normal(0, 2.0, (2, len(neutral), 3))
    weights = np.vstack([[0, 0], rng.uniform(0, 1, (39, 2))])
    frames = neutral + np.tensordot(weights, deltas, axes=1) + rng.normal(0, 0.01, (40, len(neutral), 3))
    frames[0] = neutral
    basis = write_basis(tmp_path / "basis", neutral, deltas, triangles)
    return tmp_path, frames / 1000.0, triangles, basis, deltas


def config(tmp_path, sequence, basis, *more):
    return compose(
        "paper",
        [
            "dataset=mesh_sequence",
            f"dataset.sequence={sequence}",
            f"dataset.blendshapes.path={basis}",
            f"paths.data_root={tmp_path}",
            *more,
        ],
    ).dataset


@pytest.mark.parametrize("suffix", [".npz", ".npy", ".h5"])
def test_sequence_files_give_displacements_from_the_neutral_frame(scan, suffix):
    tmp_path, frames, triangles, basis, deltas = scan
    path = tmp_path / f"seq{suffix}"
    if suffix == ".npz":
        np.savez(path, vertices=frames, faces=triangles)
    elif suffix == ".npy":
        np.save(path, frames)
    else:
        with h5py.File(path, "w") as handle:
            handle["vertices"], handle["faces"] = frames, triangles
    capture = build_captures(config(tmp_path, path, basis))["mesh"]
    np.testing.assert_allclose(capture.neutral, frames[0].reshape(-1) * 1000.0, rtol=1e-12)
    np.testing.assert_allclose(capture.eval, (frames - frames[0]).reshape(40, -1) * 1000.0, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(capture.hand, deltas.reshape(2, -1), atol=1e-6)
    np.testing.assert_array_equal(capture.faces, triangles)
    assert capture.hand_names == tuple(SHAPES) and capture.frame_rate == 60.0


def test_cli_runs_on_a_sequence_and_h_fits_the_blend(scan):
    tmp_path, frames, triangles, basis, _ = scan
    np.savez(tmp_path / "seq.npz", vertices=frames, faces=triangles)
    text = run(
        compose(
            "paper",
            [
                "dataset=mesh_sequence",
                "dataset.sequence=seq.npz",
                "dataset.blendshapes.path=basis",
                f"paths.data_root={tmp_path}",
                "solver=lstsq",
                "basis.coverage=0.99",
            ],
        ),
        tmp_path / "run",
    )
    table = pd.read_csv(tmp_path / "run" / "alpha_table.csv").set_index("basis")
    # the frames are the blend of the two shapes plus 0.01 mm noise: H reconstructs them almost exactly
    assert table.loc["H", "alpha_disp_mean"] < 1.0 and "mesh sequence seq.npz" in text


def test_bad_sequences_are_one_line_errors(scan):
    tmp_path, frames, triangles, basis, _ = scan

    def fails(pattern, *more, **arrays):
        np.savez(tmp_path / "bad.npz", **arrays)
        with pytest.raises(WorkbenchError, match=pattern) as error:
            build_captures(config(tmp_path, tmp_path / "bad.npz", basis, *more))
        assert "\n" not in str(error.value)

    fails(r"bad\.npz: no array 'vertices' \(dataset.vertices_key\); it has \['points'\]", points=frames)
    fails(
        r"bad\.npz: 'vertices' must have shape \(n_frames >= 2, n_vertices >= 3, 3\), got \(40, 42\)",
        vertices=frames[:, :, 0],
    )
    broken = frames.copy()
    broken[5, 3, 1] = np.nan
    fails(r"bad\.npz: 'vertices' frame 5 holds NaN or Inf", vertices=broken)
    fails(r"bad\.npz: 'faces' refers to vertex 42, outside the 42 vertices", vertices=frames, faces=triangles + 2)
    negative = triangles.copy()
    negative[0, 0] = -1
    fails(r"bad\.npz: 'faces' refers to vertex -1, outside the 42 vertices", vertices=frames, faces=negative)
    fails(r"bad\.npz: 'faces' must be integer triangles of shape \(n, 3\)", vertices=frames, faces=triangles * 1.0)
    fails(r"dataset.neutral_frame 40 is outside the sequence's 40 frames", "dataset.neutral_frame=40", vertices=frames)
    fails(
        r"dataset.blendshapes.path .*basis: 42 vertices, but the sequence bad\.npz has 41 points",
        vertices=frames[:, :41],
    )
    fails(r"its neutral lies up to .* other units \(unit_mm\)", "dataset.unit_mm=1.0", vertices=frames)
    fails(
        r"dataset.hand_shapes: needs distinct shape names of the file's \['side', 'up'\]; missing \['down'\]",
        "dataset.hand_shapes=[down]",
        vertices=frames,
    )
    (tmp_path / "seq.txt").write_text("1 2 3")
    with pytest.raises(WorkbenchError, match=r"seq\.txt: a mesh sequence must be one of \.npz, \.npy, \.h5, \.hdf5"):
        build_captures(config(tmp_path, tmp_path / "seq.txt", basis))
    (tmp_path / "seq.h5").write_text("not hdf5")
    with pytest.raises(WorkbenchError, match=r"seq\.h5: not a readable HDF5 file"):
        build_captures(config(tmp_path, tmp_path / "seq.h5", basis))
    with pytest.raises(WorkbenchError, match=r"dataset.blendshapes.path is not set"):
        build_captures(config(tmp_path, tmp_path / "bad.npz", "null"))


@pytest.mark.slow
def test_ict_performance_as_a_sequence_gives_the_ict_livelink_mesh_table(tmp_path, shared_data):
    """Known answer on real data: the ICT face driven by the Live Link take, saved as a VOCASET-style sequence
    (metres, triangles, separate neutral OBJ) with FaceXModel as the hand basis, gives ict_livelink's table."""
    common = ["solver=nnls", f"paths.data_root={shared_data}"]
    ict = ["dataset=ict_livelink", "dataset.max_frames=120", "dataset.train_on=mesh", *common]
    capture = build_captures(compose("paper", ict).dataset)["mesh"]
    neutral = capture.neutral.reshape(-1, 3)
    np.savez(tmp_path / "take.npz", vertices=(neutral + capture.eval.reshape(120, -1, 3)) / 1000.0, faces=capture.faces)
    (tmp_path / "neutral.obj").write_text(obj_text(neutral / 1000.0, capture.faces))
    hand = ",".join(capture.hand_names)
    sequence = [
        "dataset=mesh_sequence",
        f"dataset.sequence={tmp_path / 'take.npz'}",
        f"dataset.neutral={tmp_path / 'neutral.obj'}",
        "dataset.frame_rate=30",
        "dataset.blendshapes.path=ict-facekit/FaceXModel",
        "dataset.blendshapes.neutral=generic_neutral_mesh.obj",
        "dataset.blendshapes.unit_mm=10",
        "dataset.blendshapes.region_vertices=9409",
        f"dataset.hand_shapes=[{hand}]",
        *common,
    ]
    run(compose("paper", ict), tmp_path / "ict")
    run(compose("paper", sequence), tmp_path / "sequence")
    expected = pd.read_csv(tmp_path / "ict" / "alpha_table.csv")
    measured = pd.read_csv(tmp_path / "sequence" / "alpha_table.csv")
    columns = ["alpha_abs_mean", "alpha_abs_pooled", "alpha_disp_mean", "alpha_disp_pooled", "m", "n"]
    np.testing.assert_allclose(measured[columns].to_numpy(float), expected[columns].to_numpy(float), rtol=1e-6)


def test_sequence_plausibility_and_damaged_files_are_one_line_errors(scan):
    """Vertices far outside the face, jumps between frames and a static take are named (dataset.plausibility);
    positions that are not real numbers and truncated files are refused (never an unexpected error)."""
    tmp_path, frames, triangles, basis, _ = scan

    def fails(pattern, vertices, *more, name="bad.npz"):
        path = tmp_path / name
        if isinstance(vertices, bytes):
            path.write_bytes(vertices)
        else:
            np.savez(path, vertices=vertices, faces=triangles)
        with pytest.raises(WorkbenchError, match=pattern) as error:
            build_captures(config(tmp_path, path, basis, *more))
        assert "\n" not in str(error.value)

    far = frames.copy()
    far[17, 5] += 1000.0  # a vertex a million millimetres away (file units: metres)
    fails(
        r"bad\.npz: frame 17, vertex 5 lies 1e\+03 file units from the face's centre along an axis \(1 such "
        r"frame\(s\)\), more than 20 x the face's extent",
        far,
    )
    jump = frames.copy()
    jump[20:] += [0.5, 0.0, 0.0]  # the whole face half a metre away from frame 20 on
    fails(
        r"bad\.npz: vertex \d+ jumps 0\.5\d* file units from frame 19 to frame 20 \(1 such frame\(s\)\), more than "
        r"1 x the face's extent",
        jump,
    )
    fails(
        r"bad\.npz: the sequence is static: no vertex moves more than 0 file units from the first frame",
        np.repeat(frames[:1], 40, axis=0),
    )
    fails(r"bad\.npz: 'vertices' must hold real numbers \(vertex positions\), got <U3", np.full((40, 42, 3), "abc"))
    fails(r"bad\.npz: 'vertices' must hold real numbers \(vertex positions\), got complex128", frames + 0j)
    whole = (tmp_path / "bad.npz").read_bytes()
    fails(r"truncated\.npz: not a readable NumPy file", whole[: len(whole) // 2], name="truncated.npz")
    np.save(tmp_path / "whole.npy", frames)
    fails(
        r"truncated\.npy: not a readable NumPy file", (tmp_path / "whole.npy").read_bytes()[:3000], name="truncated.npy"
    )
    # kept, with a warning, when the researcher wants the data as it is
    np.savez(tmp_path / "jump.npz", vertices=jump, faces=triangles)
    capture = build_captures(config(tmp_path, tmp_path / "jump.npz", basis, "dataset.plausibility=warn"))["mesh"]
    assert any(note.startswith("WARNING: ") and "jumps" in note for note in capture.notes)
    assert len(capture.provenance["plausibility_warnings"]) == 1


def test_a_faces_key_the_file_lacks_is_refused_naming_its_arrays(scan):
    from workbench.formats.mesh_sequence import read_mesh_sequence

    tmp_path, frames, triangles, _, _ = scan
    np.savez(tmp_path / "seq.npz", vertices=frames, faces=triangles)
    with h5py.File(tmp_path / "seq.h5", "w") as handle:
        handle["vertices"], handle["faces"] = frames, triangles
    for name in ("seq.npz", "seq.h5"):
        path = tmp_path / name
        with pytest.raises(WorkbenchError) as refused:
            read_mesh_sequence(path, faces_key="nope")
        assert str(refused.value) == (
            f"{path}: no array 'nope' (faces_key, dataset.faces_key); it has ['faces', 'vertices']; give null to use "
            "the hand basis's triangles"
        )
        assert (read_mesh_sequence(path)[1] == triangles).all()
        assert read_mesh_sequence(path, faces_key=None)[1] is None
    np.savez(tmp_path / "positions.npz", vertices=frames)
    assert read_mesh_sequence(tmp_path / "positions.npz")[1] is None  # the default name may be absent


def test_a_neutral_in_other_units_than_the_sequence_leaves_positions_and_is_named(scan):
    """A sequence saved in centimetres beside a neutral OBJ in metres (dataset.unit_mm fits the OBJ): its frames
    minus the neutral are still positions, refused in one line naming dataset.neutral; kept with a warning."""
    tmp_path, frames, triangles, basis, _ = scan
    np.savez(tmp_path / "seq_cm.npz", vertices=frames * 100.0, faces=triangles)
    (tmp_path / "neutral_m.obj").write_text(obj_text(frames[0], triangles))
    given = [f"dataset.neutral={tmp_path / 'neutral_m.obj'}"]
    with pytest.raises(
        WorkbenchError, match=r"^dataset\.sequence seq_cm\.npz: its frames minus the neutral look like"
    ) as refused:
        build_captures(config(tmp_path, tmp_path / "seq_cm.npz", basis, *given))
    assert "dataset.neutral" in str(refused.value) and "\n" not in str(refused.value)
    warned = build_captures(config(tmp_path, tmp_path / "seq_cm.npz", basis, *given, "dataset.plausibility=warn"))
    assert any("look like positions" in note for note in warned["mesh"].notes)
    np.savez(tmp_path / "seq_m.npz", vertices=frames, faces=triangles)  # the same units: displacements, no warning
    fine = build_captures(config(tmp_path, tmp_path / "seq_m.npz", basis, *given))["mesh"]
    assert not any(note.startswith("WARNING") for note in fine.notes)
