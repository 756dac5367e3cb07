"""Captures cached by content hash, so a sweep builds each dataset once.

The key is a hash of the ``dataset`` config group, of the source of ``workbench/dataset`` (a code change
invalidates it) and of the size and modification time of every file the config names, under the data root or the
workbench's ``conf/`` folder (editing the marker table invalidates it). An entry that cannot be read is reported
on stderr and rebuilt. Captures are kept in memory for the process (the last ``MEMORY_SLOTS`` datasets: a Hydra sweep
runs its jobs in one process, a joblib worker runs many) and, when a cache folder is given, on disk as
``<key>.npz`` (arrays, no pickle) plus ``<key>.json`` (everything else, written last: a key with both files is
complete). Cached arrays are read-only, so no run can change what the next one gets.
"""

from __future__ import annotations

import hashlib
import json
import sys
import zipfile
from collections import OrderedDict
from functools import lru_cache
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from workbench.dataset.capture import Capture, Timeline
from workbench.errors import WorkbenchError
from workbench.frames import FramesOnDisk
from workbench.record import write_atomic, write_npz

MEMORY_SLOTS = 2
_ARRAYS = ("neutral", "train", "eval", "hand", "faces", "eval_visible", "train_source", "train_operator",
           "point_support")
_memory: "OrderedDict[str, dict[str, Capture]]" = OrderedDict()


@lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """Hash of every Python source file of the dataset stage."""
    digest = hashlib.sha256()
    root = Path(__file__).resolve().parent
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def dataset_key(cfg: Mapping) -> str:
    """Content hash of a dataset config (order of keys does not matter), of the dataset code and of the size and
    modification time of every source file the config names (:func:`source_file_stats`)."""
    text = json.dumps(cfg, sort_keys=True, default=str)
    sources = json.dumps(source_file_stats(cfg))
    return hashlib.sha256((text + sources + code_fingerprint()).encode()).hexdigest()[:24]


def source_file_stats(cfg: Mapping) -> list[tuple[str, int, int]]:
    """(path, size, mtime_ns) of each file, or file in a folder, that a string value of ``cfg`` names under
    ``cfg["data_root"]``, under the workbench's ``conf/`` folder (as ``dataset.marker_table`` does) or as an absolute
    path; empty for generated datasets without such files. Editing a source file changes the cache key."""
    from workbench.config import CONF_DIR

    roots = [Path(root) for root in (cfg.get("data_root"), CONF_DIR) if root]
    stats = []
    for value in _strings(cfg):
        if not value:
            continue
        for root in roots:
            path = root / value  # an absolute value stays itself
            if path.is_file():
                files = [path]
            elif path.is_dir() and path.resolve() != root.resolve():
                files = sorted(item for item in path.iterdir() if item.is_file())
            else:
                continue
            stats += [(str(item), item.stat().st_size, item.stat().st_mtime_ns) for item in files]
    return stats


def _strings(value):
    if isinstance(value, str):
        yield value
    elif isinstance(value, Mapping):
        for item in value.values():
            yield from _strings(item)
    elif isinstance(value, (list, tuple)):
        for item in value:
            yield from _strings(item)


def cached_captures(cfg: Mapping, build: Callable[[Mapping], dict], cache_dir: str | Path | None = None
                    ) -> dict[str, Capture]:
    """``build(cfg)``, or the captures it returned before for the same config.

    Parameters
    ----------
    cfg : mapping
        The ``dataset`` config group.
    build : callable
        Builds ``{name: Capture}`` from ``cfg`` on a miss.
    cache_dir : str or Path, optional
        Folder of the disk cache; memory only when None.

    Returns
    -------
    dict
        ``name -> Capture`` with read-only arrays.
    """
    key = dataset_key(cfg)
    if key in _memory:
        _memory.move_to_end(key)
        return _memory[key]
    folder = cache_folder(cache_dir)
    captures = _load_or_report(folder, key) if folder else None
    if captures is None:
        captures = {name: _read_only(capture) for name, capture in build(cfg).items()}
        if folder:
            _save(folder, key, captures)
    _memory[key] = captures
    while len(_memory) > MEMORY_SLOTS:
        _memory.popitem(last=False)
    return captures


def cache_folder(cache_dir: str | Path | None) -> Path | None:
    """``paths.cache_dir`` as a folder (created if absent), or None without one.

    Raises
    ------
    WorkbenchError
        When the path exists and is not a folder.
    """
    if not cache_dir:
        return None
    folder = Path(cache_dir)
    if folder.exists() and not folder.is_dir():
        raise WorkbenchError(f"paths.cache_dir {folder} is not a folder (a file is in the way); give a folder or "
                             "null")
    return folder


def _load_or_report(folder: Path, key: str) -> dict[str, Capture] | None:
    """The cached captures of ``key``, or None when there are none or they cannot be read (a truncated or
    otherwise damaged entry is reported on stderr; the caller rebuilds it and writes it anew)."""
    try:
        return _load(folder, key)
    except (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile) as error:
        print(f"workbench: cache entry {folder / key}.npz/.json cannot be read ({type(error).__name__}: {error}); "
              "rebuilding it", file=sys.stderr)
        return None


def clear_memory() -> None:
    """Forget the captures held in memory (the disk cache stays)."""
    _memory.clear()


def _read_only(capture: Capture) -> Capture:
    for name in _ARRAYS:
        array = getattr(capture, name)
        if isinstance(array, np.ndarray):
            array.flags.writeable = False
    return capture


def _plain(value):
    """JSON-ready copy of provenance values (NumPy scalars and arrays become numbers and lists)."""
    if isinstance(value, Mapping):
        return {str(key): _plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def _save(folder: Path, key: str, captures: dict[str, Capture]) -> None:
    arrays, meta = {}, {}
    for index, (name, capture) in enumerate(captures.items()):
        same_frames = capture.eval is capture.train
        for field in _ARRAYS:
            array = getattr(capture, field)
            if array is not None and not (field == "eval" and same_frames) and not isinstance(array, FramesOnDisk):
                arrays[f"{index}_{field}"] = array
        if capture.eval_timeline is not None:
            arrays.update(capture.eval_timeline.as_arrays(f"{index}_timeline_"))
        meta[name] = {"index": index, "same_frames": same_frames, "name": capture.name,
                      "frame_files": frame_files(capture),
                      "hand_names": list(capture.hand_names), "point_labels": list(capture.point_labels),
                      "units": capture.units, "origin": capture.origin, "frame_rate": capture.frame_rate,
                      "provenance": _plain(capture.provenance), "notes": list(capture.notes)}
    write_npz(folder / f"{key}.npz", arrays)
    write_atomic(folder / f"{key}.json", json.dumps(meta, indent=1))


def frame_files(capture: Capture) -> dict:
    """Field -> ``[path, first row, rows]`` of the capture's frames stored on disk (``dataset.storage: disk``),
    kept in the cache's json instead of its npz."""
    stored = {field: getattr(capture, field) for field in ("train", "eval")}
    return {field: [str(frames.path), frames.first, len(frames)] for field, frames in stored.items()
            if isinstance(frames, FramesOnDisk)}


def _load(folder: Path, key: str) -> dict[str, Capture] | None:
    meta_path, array_path = folder / f"{key}.json", folder / f"{key}.npz"
    if not (meta_path.is_file() and array_path.is_file()):
        return None
    meta = json.loads(meta_path.read_text())
    with np.load(array_path, allow_pickle=False) as stored:
        arrays = {name: stored[name] for name in stored.files}
    captures = {}
    for name, info in meta.items():
        index = info["index"]
        files = info.get("frame_files") or {}
        if not all(Path(path).is_file() for path, _, _ in files.values()):
            return None  # frames stored on disk were deleted: build again
        arrays.update({f"{index}_{field}": FramesOnDisk(path).rows(first, first + count)
                       for field, (path, first, count) in files.items()})
        train = arrays[f"{index}_train"]
        capture = Capture(
            name=info["name"], neutral=arrays[f"{index}_neutral"], train=train,
            eval=train if info["same_frames"] else arrays[f"{index}_eval"], hand=arrays[f"{index}_hand"],
            hand_names=tuple(info["hand_names"]), point_labels=tuple(info["point_labels"]), units=info["units"],
            origin=info["origin"], frame_rate=info["frame_rate"], provenance=info["provenance"],
            notes=tuple(info["notes"]), faces=arrays.get(f"{index}_faces"),
            eval_visible=arrays.get(f"{index}_eval_visible"), train_source=arrays.get(f"{index}_train_source"),
            train_operator=arrays.get(f"{index}_train_operator"), point_support=arrays.get(f"{index}_point_support"),
            eval_timeline=Timeline.from_arrays(arrays, f"{index}_timeline_"))
        captures[name] = _read_only(capture)
    return captures
