"""The disk cache: a key that covers the conf/ files a dataset reads, damaged entries rebuilt, a cache path that
is a file refused in one line."""

import shutil

import numpy as np
import pytest
from omegaconf import OmegaConf

import workbench.config
from workbench.config import CONF_DIR, compose
from workbench.dataset import build_captures, build_synthetic
from workbench.dataset.cache import cached_captures, clear_memory, dataset_key
from workbench.errors import WorkbenchError

SYNTHETIC = {"kind": "synthetic", "n_frames": 200, "frame_rate": 120.0, "n_face_markers": 66, "n_head_markers": 7,
             "head_rotation_deg": 3.0, "head_translation_mm": 5.0, "marker_noise_mm": 0.05, "seed": 0,
             "mesh_rows": 20, "mesh_cols": 20, "train_on": ["markers"], "stabilise": True, "split": "same"}


@pytest.fixture(autouse=True)
def empty_memory():
    clear_memory()
    yield
    clear_memory()


class CountingBuilder:
    def __init__(self):
        self.calls = 0

    def __call__(self, cfg):
        self.calls += 1
        return build_synthetic(cfg)


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
    first = cached_captures(SYNTHETIC, build, tmp_path)
    key = dataset_key(SYNTHETIC)
    npz, meta = tmp_path / f"{key}.npz", tmp_path / f"{key}.json"
    if damage == "truncated npz":
        npz.write_bytes(npz.read_bytes()[:100])
    elif damage == "bad json":
        meta.write_text("{")
    else:
        meta.write_text('{"markers": {"index": 0}}')
    clear_memory()
    again = cached_captures(SYNTHETIC, build, tmp_path)
    assert build.calls == 2
    assert f"cache entry {tmp_path / key}.npz/.json cannot be read" in capsys.readouterr().err
    np.testing.assert_array_equal(again["markers"].train, first["markers"].train)
    clear_memory()
    cached_captures(SYNTHETIC, build, tmp_path)  # the rebuilt entry is whole again
    assert build.calls == 2


def test_a_cache_path_that_is_a_file_is_refused(tmp_path):
    blocker = tmp_path / "cache"
    blocker.write_text("")
    with pytest.raises(WorkbenchError, match=r"paths.cache_dir .*cache is not a folder"):
        cached_captures(SYNTHETIC, CountingBuilder(), blocker)
