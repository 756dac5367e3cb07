"""The dataset cache: same config, same captures, built once; a changed config builds anew."""

import numpy as np
import pytest

from workbench.dataset import build_synthetic
from workbench.dataset.cache import cached_captures, clear_memory, dataset_key

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
