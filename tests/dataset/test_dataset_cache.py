"""The dataset cache: same config, same captures, built once; a changed config (or a conf/ file it reads, or a source
file edited in place with its size and time kept) builds anew; an entry that is damaged, foreign or edited (its
arrays, its json, a frames file) is reported in one line and rebuilt; a cache path that is a file is refused; a hit
gives byte-identical tables to a build. Every case works on real files."""

import json
import os
import shutil
import subprocess
import sys
import time

import numpy as np
import pytest
from omegaconf import OmegaConf

import workbench.dataset.cache as cache
import workbench.settings.config
from workbench.core.errors import WorkbenchError
from workbench.dataset import build_captures
from workbench.dataset.cache import cached_captures, clear_memory, dataset_key, kept_in_memory
from workbench.dataset.synthetic_builder import build_synthetic
from workbench.numerics.frames import FramesOnDisk
from workbench.settings.config import CONF_DIR, REPO_ROOT, compose
from workbench.settings.typed import built_settings, dataset_settings

CONFIG = {
    "kind": "synthetic",
    "n_frames": 300,
    "frame_rate": 120.0,
    "n_face_markers": 66,
    "n_head_markers": 7,
    "head_rotation_deg": 3.0,
    "head_translation_mm": 5.0,
    "marker_noise_mm": 0.05,
    "seed": 0,
    "mesh_rows": 30,
    "mesh_cols": 26,
    "train_on": ["markers", "mesh"],
    "stabilise": True,
    "split": "same",
}


class CountingBuilder:
    def __init__(self):
        self.calls = 0

    def __call__(self, cfg):
        self.calls += 1
        # the synthetic builder takes its own settings: the source files some tests name are for the key alone
        return build_synthetic(dataset_settings({key: value for key, value in cfg.items() if key in CONFIG}))


def assert_one_note(capsys, start: str, end: str) -> str:
    """The one line the cache printed on stderr, checked to start and end as given."""
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith(start) and lines[0].endswith(end), lines
    return lines[0]


def entry_files(folder, key):
    """The json and npz of an entry, and its frames files (path -> spec from the json)."""
    meta, npz = folder / f"{key}.json", folder / f"{key}.npz"
    frames = {
        folder / spec["path"]: spec
        for capture in json.loads(meta.read_text())["captures"].values()
        for spec in capture["frames"].values()
    }
    return meta, npz, frames


@pytest.fixture(autouse=True)
def empty_memory():
    clear_memory()
    yield
    clear_memory()


def test_key_ignores_key_order_and_follows_values():
    reordered = dict(reversed(list(CONFIG.items())))
    assert dataset_key(reordered) == dataset_key(CONFIG)
    assert dataset_key(dict(CONFIG, seed=1)) != dataset_key(CONFIG)


def test_memory_cache_builds_once_and_freezes_arrays():
    build = CountingBuilder()
    first = cached_captures(CONFIG, build)
    second = cached_captures(dict(CONFIG), build)
    assert build.calls == 1 and second is first
    with pytest.raises(ValueError):
        first["markers"].train[0, 0] = 1.0
    cached_captures(dict(CONFIG, seed=1), build)
    assert build.calls == 2


def test_disk_cache_round_trips_every_field(tmp_path):
    build = CountingBuilder()
    built = cached_captures(CONFIG, build, tmp_path)
    clear_memory()
    loaded = cached_captures(CONFIG, build, tmp_path)
    assert build.calls == 1 and loaded is not built
    for name in ("markers", "mesh"):
        a, b = built[name], loaded[name]
        for field in ("neutral", "train", "eval", "hand"):
            assert np.array_equal(getattr(a, field), getattr(b, field)), (name, field)
        assert (a.faces is None and b.faces is None) or np.array_equal(a.faces, b.faces)
        assert (a.name, a.hand_names, a.point_labels, a.units, a.origin, a.frame_rate, a.notes) == (
            b.name,
            b.hand_names,
            b.point_labels,
            b.units,
            b.origin,
            b.frame_rate,
            b.notes,
        )
        assert b.eval is b.train  # split 'same' stays one array
    assert len(list(tmp_path.glob("*.npz"))) == 1 and len(list(tmp_path.glob("*.json"))) == 1


def test_incomplete_disk_entry_is_rebuilt(tmp_path):
    build = CountingBuilder()
    cached_captures(CONFIG, build, tmp_path)
    next(tmp_path.glob("*.json")).unlink()  # as if killed before the last file
    clear_memory()
    cached_captures(CONFIG, build, tmp_path)
    assert build.calls == 2


def test_key_follows_the_source_files_a_config_names(tmp_path):
    take = tmp_path / "takes" / "a.csv"
    take.parent.mkdir()
    take.write_text("1,2,3\n")
    cfg = {"kind": "real", "data_root": str(tmp_path), "livelink_csv": "takes/a.csv", "unit": "mm"}
    before = dataset_key(cfg)
    assert dataset_key(dict(cfg)) == before
    take.write_text("1,2,3,4\n")  # edited: another size
    assert dataset_key(cfg) != before


def test_study_reads_a_cached_dataset_from_disk(tmp_path, monkeypatch):
    from workbench.settings.config import compose, resolved_without_hydra
    from workbench.settings.typed import study_settings
    from workbench.study import run as pipeline

    cfg = resolved_without_hydra(
        compose(
            "paper",
            [
                "dataset.n_frames=300",
                "dataset.mesh_rows=30",
                "dataset.mesh_cols=26",
                "solver=lstsq",
                f"paths.cache_dir={tmp_path}",
            ],
        )
    )
    first = pipeline.run_study(study_settings(cfg))
    clear_memory()

    def no_build(_cfg):
        raise AssertionError("the dataset was rebuilt although it is in the disk cache")

    monkeypatch.setitem(pipeline.build_from_settings.__globals__["BUILDERS"], "synthetic", no_build)
    second = pipeline.run_study(study_settings(cfg))
    assert [row.alpha.absolute_mean for row in first[0].rows] == [row.alpha.absolute_mean for row in second[0].rows]


def test_editing_the_marker_table_under_conf_rebuilds_the_dataset(shared_data, tmp_path, monkeypatch):
    conf = tmp_path / "conf"
    shutil.copytree(CONF_DIR, conf)
    monkeypatch.setattr(workbench.settings.config, "CONF_DIR", conf)
    cfg = OmegaConf.to_container(
        compose(
            "paper",
            [
                "dataset=ict_livelink",
                "dataset.max_frames=40",
                "dataset.train_on=markers",
                f"paths.data_root={shared_data}",
            ],
        ).dataset,
        resolve=True,
    )
    cache = tmp_path / "cache"
    before = build_captures(cfg, cache)["markers"]
    key = dataset_key(cfg)
    table = conf / "correspondence" / "animface_ict.csv"
    table.write_text(table.read_text().replace("\nForeHead_M,,8488,", "\nForeHead_M,,8400,"))
    clear_memory()
    assert dataset_key(cfg) != key
    after = build_captures(cfg, cache)["markers"]
    assert before.provenance["virtual_marker_vertices"]["ForeHead_M"] == 8488
    assert after.provenance["virtual_marker_vertices"]["ForeHead_M"] == 8400
    assert not np.array_equal(before.neutral, after.neutral)


@pytest.mark.parametrize("damage", ["truncated npz", "bad json", "json of another shape"])
def test_a_damaged_cache_entry_is_reported_and_rebuilt(tmp_path, capsys, damage):
    build = CountingBuilder()
    first = cached_captures(CONFIG, build, tmp_path)
    key = dataset_key(CONFIG)
    npz, meta = tmp_path / f"{key}.npz", tmp_path / f"{key}.json"
    if damage == "truncated npz":
        npz.write_bytes(npz.read_bytes()[:100])
    elif damage == "bad json":
        meta.write_text("{")
    else:
        meta.write_text('{"markers": {"index": 0}}')
    clear_memory()
    again = cached_captures(CONFIG, build, tmp_path)
    assert build.calls == 2
    assert_one_note(
        capsys,
        f"workbench: cache entry {tmp_path / key}: "
        + {
            "truncated npz": f"{key}.npz does not match its checksum",
            "bad json": f"{key}.json cannot be read",
            "json of another shape": f"{key}.json does not match its checksum",
        }[damage],
        "; rebuilding it",
    )
    np.testing.assert_array_equal(again["markers"].train, first["markers"].train)
    clear_memory()
    cached_captures(CONFIG, build, tmp_path)  # the rebuilt entry is whole again
    assert build.calls == 2


def test_a_cache_path_that_is_a_file_is_refused(tmp_path):
    blocker = tmp_path / "cache"
    blocker.write_text("")
    with pytest.raises(WorkbenchError, match=r"paths.cache_dir .*cache is not a folder"):
        cached_captures(CONFIG, CountingBuilder(), blocker)


def test_a_hit_maps_uncompressed_frames_read_only(tmp_path):
    build = CountingBuilder()
    built = cached_captures(CONFIG, build, tmp_path)
    clear_memory()
    loaded = cached_captures(CONFIG, build, tmp_path)
    assert build.calls == 1
    meta, npz, frames = entry_files(tmp_path, dataset_key(CONFIG))
    with np.load(npz) as stored:
        assert "0_train" not in stored.files  # frames are not in the npz ...
    assert {path.parent for path in frames} == {tmp_path / "frames"}  # ... but in .npy files beside it
    import zipfile

    assert {info.compress_type for info in zipfile.ZipFile(npz).infolist()} == {zipfile.ZIP_STORED}
    for name in ("markers", "mesh"):
        train = loaded[name].train
        assert type(train) is np.ndarray and not train.flags.writeable and not train.flags.owndata
        np.testing.assert_array_equal(train, built[name].train)
        with pytest.raises(ValueError):
            train[0, 0] = 1.0


@pytest.mark.parametrize("memoised", [False, True])
def test_a_source_file_edited_in_place_with_size_and_time_kept_is_not_served_stale(
    tmp_path, monkeypatch, capsys, memoised
):
    take = tmp_path / "data" / "take.csv"
    take.parent.mkdir()
    take.write_text("1,2,3\n")
    cfg = dict(CONFIG, data_root=str(tmp_path / "data"), notes_file="take.csv")
    if memoised:  # the file's hash is remembered in the process: the edit must still be seen
        monkeypatch.setattr(cache, "SETTLED_SECONDS", 0.05)
        time.sleep(0.1)
    build = CountingBuilder()
    cached_captures(cfg, build, tmp_path / "cache")
    key = dataset_key(cfg)
    assert (str(take) in cache._digests) == memoised
    before = take.stat()
    take.write_text("4,5,6\n")  # same size
    os.utime(take, ns=(before.st_atime_ns, before.st_mtime_ns))  # modification time put back
    after = take.stat()
    assert (after.st_size, after.st_mtime_ns) == (before.st_size, before.st_mtime_ns)
    assert dataset_key(cfg) != key
    cached_captures(cfg, build, tmp_path / "cache")
    assert build.calls == 2
    assert capsys.readouterr().err == ""  # another key: a plain miss, no entry was damaged


def test_an_entry_of_another_dataset_is_detected_and_rebuilt(tmp_path, capsys):
    build = CountingBuilder()
    original = cached_captures(CONFIG, build, tmp_path)
    other = dict(CONFIG, seed=1)
    cached_captures(other, build, tmp_path)
    key, other_key = dataset_key(CONFIG), dataset_key(other)
    for suffix in (".json", ".npz"):  # the other dataset's entry under this dataset's key
        shutil.copyfile(tmp_path / f"{other_key}{suffix}", tmp_path / f"{key}{suffix}")
    clear_memory()
    again = cached_captures(CONFIG, build, tmp_path)
    assert build.calls == 3
    assert_one_note(
        capsys,
        f"workbench: cache entry {tmp_path / key}: {key}.json was made from other inputs (another dataset config)",
        "rebuilding it",
    )
    np.testing.assert_array_equal(again["markers"].train, original["markers"].train)


@pytest.mark.parametrize(
    "damage",
    [
        "the other dataset's npz",
        "hand shapes reversed",
        "hand shapes and names reversed",
        "frames scaled by 1.5",
        "frames of another dataset",
        "frames file missing",
    ],
)
def test_changed_arrays_are_detected_and_rebuilt(tmp_path, capsys, damage):
    build = CountingBuilder()
    original = cached_captures(CONFIG, build, tmp_path)
    other = dict(CONFIG, seed=1)
    cached_captures(other, build, tmp_path)
    key = dataset_key(CONFIG)
    meta, npz, frames = entry_files(tmp_path, key)
    train_file = tmp_path / json.loads(meta.read_text())["captures"]["markers"]["frames"]["train"]["path"]
    if damage == "the other dataset's npz":
        shutil.copyfile(tmp_path / f"{dataset_key(other)}.npz", npz)
        expected = f"{key}.npz does not match its checksum"
    elif damage.startswith("hand shapes"):
        with np.load(npz) as stored:
            arrays = {name: stored[name] for name in stored.files}
        arrays["0_hand"] = arrays["0_hand"][::-1]
        np.savez(npz, **arrays)
        expected = f"{key}.npz does not match its checksum"
        if damage.endswith("names reversed"):
            document = json.loads(meta.read_text())
            document["captures"]["markers"]["hand_names"].reverse()
            meta.write_text(json.dumps(document))
            expected = f"{key}.json does not match its checksum"
    elif damage == "frames scaled by 1.5":
        np.save(train_file, np.load(train_file) * 1.5)
        expected = f"frames file {train_file} does not match its checksum"
    elif damage == "frames of another dataset":
        other_meta = json.loads((tmp_path / f"{dataset_key(other)}.json").read_text())
        shutil.copyfile(tmp_path / other_meta["captures"]["markers"]["frames"]["train"]["path"], train_file)
        expected = f"frames file {train_file} does not match its checksum"
    else:
        train_file.unlink()
        expected = f"frames file {train_file} is missing"
    clear_memory()
    again = cached_captures(CONFIG, build, tmp_path)
    assert build.calls == 3
    assert_one_note(capsys, f"workbench: cache entry {tmp_path / key}: {expected}", "; rebuilding it")
    for name in ("markers", "mesh"):
        for field in ("train", "hand", "neutral"):
            np.testing.assert_array_equal(getattr(again[name], field), getattr(original[name], field))
        assert again[name].hand_names == original[name].hand_names
    clear_memory()
    cached_captures(CONFIG, build, tmp_path)  # the rebuilt entry is whole again: no note, no build
    assert build.calls == 3 and capsys.readouterr().err == ""


@pytest.mark.slow
def test_an_edited_frames_file_stored_on_disk_is_detected_and_rebuilt(tmp_path, capsys):
    cfg = dict(CONFIG, train_on="mesh", storage="disk", dtype="float32")
    built = build_captures(cfg, tmp_path)["mesh"]
    assert isinstance(built.train, FramesOnDisk)
    original = np.asarray(built.train)
    path = built.train.path
    before = path.stat()
    with open(path, "r+b") as stream:  # one value changed in place: same size, time put back
        stream.seek(-4, os.SEEK_END)
        stream.write(np.float32(123.0).tobytes())
    os.utime(path, ns=(before.st_atime_ns, before.st_mtime_ns))
    clear_memory()
    again = build_captures(cfg, tmp_path)["mesh"]
    assert_one_note(
        capsys,
        f"workbench: cache entry {tmp_path / dataset_key(built_settings(dataset_settings(cfg))[1])}: "
        f"frames file {path} does not match its checksum",
        "rebuilding it",
    )
    np.testing.assert_array_equal(np.asarray(again.train), original)  # the file was written anew, not reused
    clear_memory()
    build_captures(cfg, tmp_path)
    assert capsys.readouterr().err == ""


@pytest.mark.slow
def test_a_hit_gives_the_tables_of_a_build_on_real_data(shared_data, tmp_path):
    from workbench.settings.config import resolved_without_hydra
    from workbench.settings.typed import study_settings
    from workbench.study import run as pipeline
    from workbench.study.table import alpha_table

    def tables(cache_dir):
        cfg = resolved_without_hydra(
            compose(
                "paper",
                ["dataset=ict_livelink", "dataset.max_frames=300", "solver=all", f"paths.data_root={shared_data}"]
                + ([f"paths.cache_dir={cache_dir}"] if cache_dir else []),
            )
        )
        clear_memory()
        return [
            alpha_table(
                result.rows,
                data=result.data,
                m=result.eigenfaces.n_components_,
                coverage=result.eigenfaces.coverage_,
                paper_alpha={},
            ).to_csv(float_format="%.17g")
            for result in pipeline.run_study(study_settings(cfg))
        ]

    built = tables(None)
    assert tables(tmp_path) == built  # a miss: built, then written
    assert tables(tmp_path) == built  # a hit: read back memory-mapped


@pytest.mark.process
@pytest.mark.slow
def test_a_hit_in_another_process_writes_the_same_alpha_table(tmp_path):
    small = [
        "dataset.n_frames=300",
        "dataset.mesh_rows=20",
        "dataset.mesh_cols=20",
        "dataset.train_on=[markers,mesh]",
        "solver=all",
    ]
    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT), OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")

    def table(run, *extra):
        subprocess.run(
            [sys.executable, "-m", "workbench", *small, *extra, f"hydra.run.dir={tmp_path / run}"],
            cwd=tmp_path,
            env=env,
            check=True,
            capture_output=True,
            timeout=300,
        )
        return (tmp_path / run / "alpha_table.csv").read_bytes()

    built = table("no_cache")
    assert table("miss", f"paths.cache_dir={tmp_path / 'cache'}") == built
    assert table("hit", f"paths.cache_dir={tmp_path / 'cache'}") == built
    assert len(list((tmp_path / "cache").glob("*.json"))) == 1


def test_results_kept_in_memory_are_the_last_slots_and_beyond_the_last_always_only_within_the_bytes():
    calls = []

    @kept_in_memory(slots=3, always=1, max_bytes=2000)
    def make(n_values):
        calls.append(n_values)
        return np.zeros(n_values)  # 8 bytes a value

    first = make(100)
    assert make(100) is first and calls == [100]
    make(50), make(10)  # 800 + 400 + 80 bytes: three kept
    make(100), make(50), make(10)
    assert calls == [100, 50, 10]
    make(20)  # a fourth: the least recently used (100) goes
    make(10), make(50), make(20)
    assert calls == [100, 50, 10, 20]
    make(300)  # 2,400 bytes: over the budget, so only the last one (always=1) stays
    make(300)
    make(20)
    assert calls == [100, 50, 10, 20, 300, 20]
    make.cache_clear()
    make(20)
    assert calls[-1] == 20 and len(calls) == 7
