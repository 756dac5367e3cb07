"""The real-data builders (mesh_sequence, ict_livelink, animface) write their dense frames chunk by chunk into the
configured storage: float32 or on disk they hold the float64 in-memory frames (to float32 rounding, or exactly),
and a sequence larger than a chunk is built on disk without its whole float64 array in memory."""

import tracemalloc

import numpy as np
import pytest

import workbench.numerics.frames
from workbench.dataset import build_captures
from workbench.dataset.cache import clear_memory
from workbench.dataset.mesh_sequence import build_mesh_sequence
from workbench.numerics.frames import FramesOnDisk
from workbench.reporting.export.run import obj_text
from workbench.settings.config import compose
from workbench.settings.typed import dataset_settings

STORAGES = {
    "memory": [],
    "float32": ["dataset.dtype=float32", "dataset.storage=disk"],
    "disk": ["dataset.storage=disk"],
}


def built(overrides, storage, cache_dir):
    """The captures of ``paper`` with ``overrides`` in the storage named (``STORAGES``), disk files in cache_dir."""
    clear_memory()
    cfg = compose("paper", [*overrides, *STORAGES[storage], f"paths.cache_dir={cache_dir}"])
    return build_captures(cfg.dataset, cache_dir=str(cache_dir) if storage != "memory" else None)


def check_storages(overrides, names, tmp_path):
    """Each capture in float32 on disk is the float64 in-memory one to float32 rounding, in float64 on disk
    exactly, in the file its builder wrote (``names``: capture name -> file name prefix; frames converted after
    building would be in a ``train`` file); training and evaluated frames stay one object with ``split: same``."""
    reference = built(overrides, "memory", tmp_path / "memory")
    float32 = built(overrides, "float32", tmp_path / "float32")
    disk = built(overrides, "disk", tmp_path / "disk")
    for name in names:
        expected = reference[name]
        assert isinstance(expected.train, np.ndarray) and expected.train.dtype == np.float64
        for capture, dtype in ((float32[name], np.float32), (disk[name], np.float64)):
            assert isinstance(capture.train, FramesOnDisk) and capture.train.dtype == dtype
            assert capture.train.path.parent == tmp_path / ("float32" if dtype == np.float32 else "disk") / "frames"
            assert capture.eval is capture.train and capture.train.path.name.startswith(names[name] + "_")
        np.testing.assert_array_equal(np.asarray(float32[name].train), expected.train.astype(np.float32))
        np.testing.assert_array_equal(np.asarray(disk[name].train), expected.train)
    return reference, float32, disk


@pytest.fixture
def sequence(tmp_path):
    """A 50-frame sequence (metres) of a 42-vertex grid face in a .npy, with a two-shape hand basis beside it."""
    rng = np.random.default_rng(5)
    x, y = np.meshgrid(np.linspace(-50, 50, 6), np.linspace(-60, 60, 7))
    neutral = np.column_stack([x.ravel(), y.ravel(), 80 - 0.01 * (x.ravel() ** 2 + y.ravel() ** 2)])
    triangles = np.array([(r * 6 + c, r * 6 + c + 1, (r + 1) * 6 + c) for r in range(6) for c in range(5)])
    deltas = rng.normal(0, 2.0, (2, len(neutral), 3))
    frames = neutral + np.tensordot(rng.uniform(0, 1, (50, 2)), deltas, axes=1) + rng.normal(0, 0.01, (50, 42, 3))
    frames[0] = neutral
    folder = tmp_path / "basis"
    folder.mkdir()
    (folder / "neutral.obj").write_text(obj_text(neutral, triangles))
    for name, delta in zip(["side", "up"], deltas):
        (folder / f"{name}.obj").write_text(obj_text(neutral + delta, triangles))
    np.save(tmp_path / "seq.npy", frames / 1000.0)
    return tmp_path, frames


def sequence_overrides(tmp_path, *more):
    return [
        "dataset=mesh_sequence",
        "dataset.sequence=seq.npy",
        "dataset.blendshapes.path=basis",
        f"paths.data_root={tmp_path}",
        *more,
    ]


def test_mesh_sequence_in_float32_and_on_disk_matches_float64_in_memory(sequence, monkeypatch):
    tmp_path, frames = sequence
    monkeypatch.setattr(
        workbench.numerics.frames, "CHUNK_ENTRIES", 7 * 42 * 3
    )  # 7 frames a chunk: 8 chunks of 50 frames
    reference, _, disk = check_storages(
        sequence_overrides(tmp_path, "dataset.frame_step=3"), {"mesh": "mesh_sequence"}, tmp_path / "out"
    )
    expected = (frames[::3] / 1000.0 * 1000.0 - frames[0] / 1000.0 * 1000.0).reshape(17, -1)
    np.testing.assert_array_equal(reference["mesh"].train, expected)
    # the same sequence again finds its file; a changed sequence file does not
    assert (
        built(sequence_overrides(tmp_path, "dataset.frame_step=3"), "disk", tmp_path / "out" / "disk")[
            "mesh"
        ].train.path
        == disk["mesh"].train.path
    )
    changed = frames / 1000.0
    changed[3] += 0.0005
    np.save(tmp_path / "seq.npy", changed)
    again = built(sequence_overrides(tmp_path, "dataset.frame_step=3"), "disk", tmp_path / "out" / "disk")["mesh"]
    assert again.train.path != disk["mesh"].train.path
    np.testing.assert_array_equal(np.asarray(again.train)[1], (changed[3] * 1000.0 - changed[0] * 1000.0).ravel())


@pytest.mark.parametrize("suffix", [".npz", ".h5"])
def test_mesh_sequence_tail_split_every_other_frame_from_npz_and_hdf5(sequence, suffix):
    import h5py

    tmp_path, frames = sequence
    if suffix == ".npz":
        np.savez_compressed(tmp_path / "seq.npz", vertices=frames / 1000.0)
    else:
        with h5py.File(tmp_path / "seq.h5", "w") as handle:
            handle["vertices"] = frames / 1000.0
    overrides = sequence_overrides(
        tmp_path,
        f"dataset.sequence=seq{suffix}",
        "dataset.split=tail",
        "dataset.eval_fraction=0.2",
        "dataset.frame_step=2",
    )
    reference = built(overrides, "memory", tmp_path / "memory")["mesh"]
    on_disk = built(overrides, "float32", tmp_path / "float32")["mesh"]
    assert len(reference.train) == 20 and len(reference.eval) == 5
    metres = frames / 1000.0
    np.testing.assert_array_equal(reference.eval[-1], (metres[48] * 1000.0 - metres[0] * 1000.0).ravel())
    assert isinstance(on_disk.eval, FramesOnDisk) and on_disk.eval.path == on_disk.train.path
    for field in ("train", "eval"):
        np.testing.assert_array_equal(np.asarray(getattr(on_disk, field)), getattr(reference, field).astype(np.float32))


def test_a_mesh_sequence_larger_than_a_chunk_is_built_on_disk_without_its_whole_array(tmp_path, monkeypatch):
    """500 frames of 2,000 vertices: 24 MB as float64, written 20 frames (0.96 MB) at a time."""
    n_frames, n_vertices = 500, 2000
    rng = np.random.default_rng(0)
    neutral = rng.normal(0, 50, (n_vertices, 3))
    folder = tmp_path / "basis"
    folder.mkdir()
    (folder / "neutral.obj").write_text(obj_text(neutral, np.array([[0, 1, 2]])))
    (folder / "shape.obj").write_text(obj_text(neutral + 1.0, np.array([[0, 1, 2]])))
    positions = np.lib.format.open_memmap(
        tmp_path / "seq.npy", mode="w+", dtype=np.float64, shape=(n_frames, n_vertices, 3)
    )
    for start in range(0, n_frames, 50):
        positions[start : start + 50] = neutral + rng.normal(0, 1, (50, n_vertices, 3))
    positions[0] = neutral
    positions.flush()
    del positions
    monkeypatch.setattr(workbench.numerics.frames, "CHUNK_ENTRIES", 20 * n_vertices * 3)
    cfg = {
        "kind": "mesh_sequence",
        "data_root": str(tmp_path),
        "sequence": "seq.npy",
        "unit_mm": 1.0,  # the file is in mm (the schema's default is metres)
        "frame_rate": 60,
        "blendshapes": {"path": "basis", "neutral": "neutral.obj"},
        "storage": "disk",
        "dtype": "float64",
    }
    whole = n_frames * n_vertices * 3 * 8
    tracemalloc.start()
    try:
        capture = build_captures(cfg, cache_dir=str(tmp_path / "cache"))["mesh"]
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert isinstance(capture.train, FramesOnDisk) and capture.train.shape == (n_frames, 3 * n_vertices)
    print(f"peak traced memory {peak / 1e6:.2f} MB for a {whole / 1e6:.1f} MB float64 capture")
    assert peak < whole / 6
    reference = build_mesh_sequence(dataset_settings(dict(cfg, storage="memory")))["mesh"].train
    np.testing.assert_array_equal(capture.train[n_frames - 3 :], reference[n_frames - 3 :])


@pytest.mark.slow
def test_ict_livelink_in_float32_and_on_disk_matches_float64_in_memory(shared_data, tmp_path, monkeypatch):
    monkeypatch.setattr(workbench.numerics.frames, "CHUNK_ENTRIES", 1 << 20)  # 37 frames of the mesh a chunk
    check_storages(
        [
            "dataset=ict_livelink",
            "dataset.max_frames=300",
            "dataset.train_on=[mesh,markers]",
            f"paths.data_root={shared_data}",
        ],
        {"mesh": "ict_livelink_mesh", "markers": "ict_livelink_markers"},
        tmp_path,
    )


def test_ict_livelink_tail_split_on_disk_is_two_parts_of_one_file(shared_data, tmp_path):
    overrides = [
        "dataset=ict_livelink",
        "dataset.max_frames=100",
        "dataset.train_on=mesh",
        "dataset.split=tail",
        f"paths.data_root={shared_data}",
    ]
    reference = built(overrides, "memory", tmp_path / "memory")["mesh"]
    on_disk = built(overrides, "disk", tmp_path / "disk")["mesh"]
    assert on_disk.eval.path == on_disk.train.path and len(on_disk.eval) == len(reference.eval) == 20
    np.testing.assert_array_equal(np.asarray(on_disk.train), reference.train)
    np.testing.assert_array_equal(np.asarray(on_disk.eval), reference.eval)


@pytest.mark.slow
def test_animface_mesh_in_float32_and_on_disk_matches_float64_in_memory(shared_data, tmp_path, monkeypatch):
    monkeypatch.setattr(workbench.numerics.frames, "CHUNK_ENTRIES", 1 << 20)  # 37 frames of the mesh a chunk
    overrides = [
        "dataset=animface",
        "dataset.max_frames_per_take=150",
        "dataset.train_on=[mesh,markers]",
        f"paths.data_root={shared_data}",
    ]
    reference, float32, disk = check_storages(overrides, {"mesh": "interpolated"}, tmp_path)
    # the note's largest displacement is computed a chunk at a time from the frames stored
    largest = np.linalg.norm(reference["mesh"].train.reshape(len(reference["mesh"].train), -1, 3), axis=2).max()
    assert any(f"largest displacement {largest:.1f} mm on the mesh" in note for note in disk["mesh"].notes)
    assert isinstance(float32["markers"].train, FramesOnDisk)
    np.testing.assert_array_equal(np.asarray(disk["markers"].train), reference["markers"].train)


def test_frames_on_disk_are_used_again_only_while_they_hold_what_was_written(tmp_path, capsys):
    """A frames file found again is used as it is only with the SHA-256 its writer recorded: an edit that keeps its
    size (one value changed) or a missing checksum gets it built anew, in one line on stderr."""
    from workbench.dataset.storage import FrameStorage
    from workbench.numerics.frames import checksum_path

    storage, calls = FrameStorage(folder=str(tmp_path / "frames")), []
    expected = np.arange(60.0).reshape(10, 6)

    def fill(rows, out):
        calls.append(rows)
        out[:] = expected[rows]

    first = storage.generate("test", ("key",), 10, 6, fill)
    assert calls and checksum_path(first.path).is_file()
    calls.clear()
    assert storage.generate("test", ("key",), 10, 6, fill).path == first.path and not calls  # intact: used again
    raw = bytearray(first.path.read_bytes())
    raw[-8:] = np.float64(1e6).tobytes()  # the last value edited, same size
    first.path.write_bytes(bytes(raw))
    again = storage.generate("test", ("key",), 10, 6, fill)
    assert calls, "an edited frames file was used as it is"
    np.testing.assert_array_equal(np.asarray(again), expected)
    assert "its SHA-256 no longer matches" in capsys.readouterr().err
    calls.clear()
    checksum_path(first.path).unlink()
    np.testing.assert_array_equal(np.asarray(storage.generate("test", ("key",), 10, 6, fill)), expected)
    assert calls and "no checksum beside it" in capsys.readouterr().err
