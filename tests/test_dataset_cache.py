"""The dataset cache: same config, same captures, built once; a changed config (or a conf/ file it reads) builds
anew; damaged entries are rebuilt; a cache path that is a file is refused."""

import shutil

import numpy as np
import pytest
from omegaconf import OmegaConf

import workbench.config
from workbench.config import CONF_DIR, compose
from workbench.dataset import build_captures, build_synthetic
from workbench.dataset.cache import cached_captures, clear_memory, dataset_key
from workbench.errors import WorkbenchError

CONFIG = {"kind": "synthetic", "n_frames": 300, "frame_rate": 120.0, "n_face_markers": 66, "n_head_markers": 7,
          "head_rotation_deg": 3.0, "head_translation_mm": 5.0, "marker_noise_mm": 0.05, "seed": 0,
          "mesh_rows": 30, "mesh_cols": 26, "train_on": ["markers", "mesh"], "stabilise": True, "split": "same"}


class CountingBuilder:
    def __init__(self):
        self.calls = 0

    def __call__(self, cfg):
        self.calls += 1
        return build_synthetic(cfg)


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
        assert (a.name, a.hand_names, a.point_labels, a.units, a.origin, a.frame_rate, a.notes) == \
               (b.name, b.hand_names, b.point_labels, b.units, b.origin, b.frame_rate, b.notes)
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
    from workbench import pipeline
    from workbench.cli import resolved_without_hydra
    from workbench.config import compose

    cfg = resolved_without_hydra(compose("paper", ["dataset.n_frames=300", "dataset.mesh_rows=30",
                                                   "dataset.mesh_cols=26", "solver=lstsq",
                                                   f"paths.cache_dir={tmp_path}"]))
    first = pipeline.run_study(cfg)
    clear_memory()

    def no_build(_cfg):
        raise AssertionError("the dataset was rebuilt although it is in the disk cache")

    monkeypatch.setitem(pipeline.build_captures.__globals__["BUILDERS"], "synthetic", no_build)
    second = pipeline.run_study(cfg)
    assert [row.alpha.absolute_mean for row in first[0].rows] == [row.alpha.absolute_mean for row in second[0].rows]


def test_editing_the_marker_table_under_conf_rebuilds_the_dataset(shared_data, tmp_path, monkeypatch):
    conf = tmp_path / "conf"
    shutil.copytree(CONF_DIR, conf)
    monkeypatch.setattr(workbench.config, "CONF_DIR", conf)
    cfg = OmegaConf.to_container(compose("paper", ["dataset=ict_livelink", "dataset.max_frames=40",
                                                   "dataset.train_on=markers", f"paths.data_root={shared_data}"]
                                         ).dataset, resolve=True)
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
    assert f"cache entry {tmp_path / key}.npz/.json cannot be read" in capsys.readouterr().err
    np.testing.assert_array_equal(again["markers"].train, first["markers"].train)
    clear_memory()
    cached_captures(CONFIG, build, tmp_path)  # the rebuilt entry is whole again
    assert build.calls == 2


def test_a_cache_path_that_is_a_file_is_refused(tmp_path):
    blocker = tmp_path / "cache"
    blocker.write_text("")
    with pytest.raises(WorkbenchError, match=r"paths.cache_dir .*cache is not a folder"):
        cached_captures(CONFIG, CountingBuilder(), blocker)
