"""Faults of the environment end in one line naming the path and the fault, exit 2: a full disk, a denied
permission, a dataset too large for memory, a cache path that is a file."""

import errno
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from workbench.core import errors
from workbench.core.files import write_atomic
from workbench.settings.config import REPO_ROOT

SMALL = ["dataset.n_frames=300", "dataset.mesh_rows=20", "dataset.mesh_cols=20", "solver=lstsq"]


def one_line(result) -> str:
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert result.returncode == 2 and len(lines) == 1, (result.returncode, result.stderr)
    return lines[0]


@pytest.fixture
def small_tmpfs(tmp_path):
    """A 24 KiB tmpfs (too small for a run record), where the test may mount one."""
    folder = tmp_path / "small-disk"
    folder.mkdir()
    if (
        shutil.which("mount") is None
        or subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=24k", "tmpfs", str(folder)], capture_output=True
        ).returncode
        != 0
    ):
        pytest.skip("cannot mount a tmpfs here (the simulated ENOSPC test covers the message)")
    yield folder
    subprocess.run(["umount", str(folder)], check=True)


@pytest.mark.process
def test_a_full_disk_names_the_file_and_leaves_no_partial_record(small_tmpfs, tmp_path, cli):
    folder = small_tmpfs / "run"
    line = one_line(cli(*SMALL, f"hydra.run.dir={folder}"))
    assert line.startswith(f"workbench: error: {folder}/") and line.endswith(
        ": cannot write (No space left on device)"
    ), line
    assert not folder.exists()


@pytest.mark.process
def test_a_full_disk_for_the_job_log_is_one_warning_line(tmp_path):
    """The log is written after the record: the record stays complete, and the full disk is named once."""
    import logging

    from workbench.record.tracking import RunLog

    handler = RunLog(tmp_path / "full" / "workbench.log", delay=True)  # its folder missing: the open fails
    result = subprocess.run(
        [
            sys.executable,
            "-c",
            "import logging, sys; from workbench.record.tracking import RunLog; "
            f"h = RunLog({str(tmp_path / 'full' / 'workbench.log')!r}, delay=True); "
            "log = logging.getLogger('x'); log.addHandler(h); log.warning('a'); log.warning('b')",
        ],
        capture_output=True,
        text=True,
        env=dict(os.environ, PYTHONPATH=str(REPO_ROOT)),
    )
    assert result.returncode == 0 and result.stderr == (
        f"workbench: warning: cannot write {tmp_path / 'full' / 'workbench.log'} (No such file or directory); the "
        "record is complete, only the copy of what the run printed is missing\n"
    )
    assert isinstance(handler, logging.FileHandler)


def test_a_simulated_full_disk_names_the_file(tmp_path, monkeypatch, capsys):
    def full(_):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr("workbench.core.files.os.fsync", full)
    with pytest.raises(OSError) as raised:
        write_atomic(tmp_path / "metrics.json", "{}")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(SystemExit) as stopped:
        errors.exit_on_error("workbench", raised.value)
    assert stopped.value.code == 2
    assert capsys.readouterr().err == (
        f"workbench: error: {tmp_path / 'metrics.json'}: cannot write (No space left on device)\n"
    )


@pytest.mark.parametrize("storage", ["memory", "disk"])
def test_a_full_disk_under_the_cache_names_the_setting_and_the_folder(tmp_path, monkeypatch, storage):
    from workbench.api import build_captures
    from workbench.dataset import cache
    from workbench.settings.config import compose

    def full(_):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    cfg = compose("paper", [*SMALL, f"dataset.storage={storage}"])
    monkeypatch.setattr(cache, "_memory", type(cache._memory)())  # built here, not found in this process's memory
    monkeypatch.setattr("workbench.numerics.frames.os.fsync", full)
    folder = tmp_path / "cache"
    with pytest.raises(errors.WorkbenchError) as raised:
        build_captures(cfg, cache_dir=str(folder))
    assert str(raised.value).startswith(
        f"paths.cache_dir {folder}: no space left on its disk writing {folder / 'frames'}/"
    ), raised.value
    assert str(raised.value).endswith("; free space there or set paths.cache_dir to a folder on another disk")
    assert [path for path in folder.rglob("*") if path.is_file()] == []  # no partial file left


@pytest.mark.parametrize(
    "error, expected",
    [
        (
            PermissionError(errno.EACCES, "Permission denied", "/data/animface_jaw.c3d"),
            "/data/animface_jaw.c3d: Permission denied",
        ),
        (IsADirectoryError(errno.EISDIR, "Is a directory", "/data/take.csv"), "/data/take.csv: Is a directory"),
        (MemoryError(), "out of memory (MemoryError)"),
    ],
)
def test_environment_faults_are_one_line_exit_2(error, expected, capsys):
    with pytest.raises(SystemExit) as stopped:
        errors.exit_on_error("workbench", error)
    assert stopped.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(f"workbench: error: {expected}") and err.count("\n") == 1


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads any file regardless of its permissions")
def test_an_unreadable_data_file_is_named(shared_data, tmp_path, cli):
    root = tmp_path / "data"
    shutil.copytree(shared_data / "livelinkface", root / "livelinkface")
    (root / "ict-facekit").symlink_to(shared_data / "ict-facekit")
    (root / "livelinkface" / "alex_rom_3.csv").chmod(0)
    line = one_line(
        cli(
            "dataset=ict_livelink",
            f"paths.data_root={root}",
            "dataset.max_frames=40",
            f"hydra.run.dir={tmp_path / 'run'}",
        )
    )
    assert "alex_rom_3.csv" in line and "Permission denied" in line


def test_a_dataset_too_large_for_memory_is_refused_before_allocating(tmp_path, cli):
    line = one_line(cli("dataset.n_frames=100000000", f"hydra.run.dir={tmp_path / 'run'}"))
    assert "the synthetic dataset would need about 163.2 GiB of memory but" in line
    assert "reduce dataset.n_frames" in line
    assert not (tmp_path / "run").exists()


def test_the_memory_estimate_counts_the_mesh_frames_where_they_are_kept():
    """Float32 mesh frames take half the memory and frames on disk none (the full-head run of docs/performance.md
    on a machine with less free memory than its float64 size)."""
    from workbench.dataset.synthetic_builder import synthetic_values

    markers, mesh = 1000 * 73 * 3, 1000 * 400 * 3
    assert synthetic_values(1000, 73, 0, "memory", "float64") == markers
    assert synthetic_values(1000, 73, 400, "memory", "float64") == markers + mesh
    assert synthetic_values(1000, 73, 400, "memory", "float32") == markers + mesh // 2
    assert synthetic_values(1000, 73, 400, "disk", "float32") == markers


def test_a_cache_path_that_is_a_file_is_one_line(tmp_path, cli):
    (tmp_path / "cache").write_text("")
    line = one_line(cli(*SMALL, f"paths.cache_dir={tmp_path / 'cache'}", f"hydra.run.dir={tmp_path / 'run'}"))
    assert (
        line == f"workbench: error: paths.cache_dir {tmp_path / 'cache'} is not a folder (a file is in the way); "
        "give a folder or null"
    )


@pytest.mark.process
@pytest.mark.parametrize("preset, expected", [(None, "16"), ("28", "28")])
def test_openblas_workers_stop_spinning_unless_the_user_set_it(preset, expected):
    # OpenBLAS reads the variable once, when NumPy loads it: the workbench must set it on import, before NumPy
    env = {key: value for key, value in os.environ.items() if key != "OPENBLAS_THREAD_TIMEOUT"}
    if preset is not None:
        env["OPENBLAS_THREAD_TIMEOUT"] = preset
    script = "import workbench, numpy, os; print(os.environ['OPENBLAS_THREAD_TIMEOUT'])"
    shown = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True)
    assert shown.stdout.strip() == expected


KERNELS = """
from workbench.numerics.compiled import njit


@njit(cache=True)
def add_one(x):
    return x + 1.0


@njit(cache=True)
def times_two(x):
    return x * 2.0
"""


def damage(cache: Path, how: str) -> None:
    """Damage the cache files of ``add_one`` as the probes did."""
    index = next(cache.glob("*add_one-*.nbi"))
    data = next(cache.glob("*add_one-*.nbc"))
    if how == "truncated index":
        index.write_bytes(index.read_bytes()[:20])
    elif how == "empty data":
        data.write_bytes(b"")
    elif how == "garbage index":
        index.write_bytes(bytes(np.random.default_rng(0).integers(0, 256, 64, dtype=np.uint8)))
    elif how == "garbage data":
        data.write_bytes(b"x" * 100)
    elif how == "swapped data":  # add_one's machine code and times_two's, each under the other's name
        other = next(cache.glob("*times_two-*.nbc"))
        first, second = data.read_bytes(), other.read_bytes()
        data.write_bytes(second)
        other.write_bytes(first)


@pytest.mark.parametrize("how", ["truncated index", "empty data", "garbage index", "garbage data", "swapped data"])
def test_a_damaged_numba_cache_file_is_removed_and_compiled_again_in_one_line(tmp_path, monkeypatch, capsys, how):
    """A damaged ``*.nbi`` / ``*.nbc`` made every run using the compiled kernels exit 3 with ``unexpected
    UnpicklingError``, on every rerun; two swapped data files made each function run the other's code."""
    import importlib

    from workbench.numerics import compiled

    (tmp_path / "robust_kernels.py").write_text(KERNELS)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(compiled, "_reported", set())
    kernels = importlib.import_module("robust_kernels")
    monkeypatch.delitem(sys.modules, "robust_kernels")

    def fresh():
        """New dispatchers of the same functions: they read numba's cache files as a new process would."""
        return [compiled.njit(cache=True)(function.py_func) for function in (kernels.add_one, kernels.times_two)]

    assert [function(3.0) for function in fresh()] == [4.0, 6.0]
    cache = Path(kernels.add_one._cache.cache_path)
    capsys.readouterr()
    damage(cache, how)
    assert [function(3.0) for function in fresh()] == [4.0, 6.0]
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"workbench: numba's compiled cache {cache}: "), lines
    assert "add_one" in lines[0] and "compiling again" in lines[0], lines
    again = fresh()  # the cache written anew, read back without a word
    assert [function(3.0) for function in again] == [4.0, 6.0]
    assert [sum(function.stats.cache_hits.values()) for function in again] == [1, 1]
    assert capsys.readouterr().err == ""
