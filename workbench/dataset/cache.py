"""Captures cached by content hash, so a sweep builds each dataset once and a later process reads it back.

The key is a hash of the typed ``dataset`` settings in canonical form
(:func:`workbench.settings.typed.canonical_settings`: every setting, keys sorted), of the source of ``workbench/dataset``
(a code change invalidates it) and of the content of every file the config names, under the data root or the
workbench's ``conf/`` folder (editing the marker table invalidates it): :func:`key_inputs`. Captures are kept in
memory for the process (the last ``MEMORY_SLOTS`` datasets: a Hydra sweep runs its jobs in one process, a joblib
worker runs many) and, when a cache folder is given, on disk:

- the frames (training and evaluated) as uncompressed ``.npy`` files in ``<folder>/frames``, written by
  :class:`~workbench.dataset.storage.FrameStorage` (frames stored on disk, ``dataset.storage: disk``, are there
  already) and read back memory-mapped, so a hit reads a frame only when a run needs it;
- ``<key>.npz``: the other arrays, uncompressed (no pickle);
- ``<key>.json``: everything else, the key's inputs and the SHA-256 of the ``.npz``, of each frames file and of
  the json itself; written last, so a key with a json is complete.

Nothing read from disk is trusted as is: a hit recomputes every checksum and compares the entry's recorded inputs
with the config's. An entry that cannot be read or does not match is reported in one line on stderr and rebuilt;
a frames file that does not match its checksum is removed first, so that the rebuild does not pick it up again.
Cached arrays are read-only, so no run can change what the next one gets.
"""

from __future__ import annotations

import errno
import hashlib
import io
import json
import sys
import time
import zipfile
from collections import OrderedDict
from functools import lru_cache
from pathlib import Path
from typing import Callable, Mapping

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.core.files import sha256_of_file, write_atomic
from workbench.dataset.capture import Capture, Timeline
from workbench.dataset.storage import FRAMES_FOLDER, FrameStorage
from workbench.numerics.frames import DTYPES, FramesOnDisk

MEMORY_SLOTS = 2
SETTLED_SECONDS = 2.0
"""A file's content hash is remembered in the process only when the file last changed at least this long before it
was hashed: an edit within the file system's timestamp granularity of the hashing could keep every time stamp."""
_ARRAYS = (
    "neutral",
    "train",
    "eval",
    "hand",
    "faces",
    "eval_visible",
    "train_source",
    "train_operator",
    "point_support",
)
_FRAMES = ("train", "eval")
_memory: "OrderedDict[str, dict[str, Capture]]" = OrderedDict()
_digests: dict[str, tuple[tuple, str]] = {}


def kept_in_memory(slots: int, always: int, max_bytes: int) -> Callable:
    """Decorator: keep the results of a deterministic function of hashable arguments for its next calls in this
    process, as ``functools.lru_cache`` does: the last ``slots`` results, but beyond the last ``always`` only
    while their arrays take at most ``max_bytes`` together (the least recently used go first). ``cache_clear()``
    forgets them."""

    def decorate(function: Callable) -> Callable:
        kept: OrderedDict = OrderedDict()

        def cached(*args):
            if args in kept:
                kept.move_to_end(args)
                return kept[args][0]
            result = function(*args)
            kept[args] = (result, array_bytes(result))
            while len(kept) > slots or (len(kept) > always and sum(size for _, size in kept.values()) > max_bytes):
                kept.popitem(last=False)
            return result

        cached.cache_clear = kept.clear
        cached.__doc__, cached.__name__, cached.__wrapped__ = function.__doc__, function.__name__, function
        return cached

    return decorate


def array_bytes(value, depth: int = 2) -> int:
    """Bytes of the NumPy arrays ``value`` holds as attributes (and their attributes, ``depth`` levels down)."""
    if isinstance(value, np.ndarray):
        return value.nbytes
    if depth == 0 or not hasattr(value, "__dict__"):
        return 0
    return sum(array_bytes(item, depth - 1) for item in vars(value).values())


class EntryMismatch(Exception):
    """A cache entry that reads but does not hold what its key says (the message says why)."""


@lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """Hash of every Python source file of the dataset stage and of the file formats it reads."""
    digest = hashlib.sha256()
    package = Path(__file__).resolve().parents[1]
    for path in sorted([*(package / "dataset").rglob("*.py"), *(package / "formats").rglob("*.py")]):
        digest.update(str(path.relative_to(package)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def key_inputs(cfg: Mapping) -> dict:
    """What a dataset's key is made of: the config, the content hash of each source file it names
    (:func:`source_digests`) and the hash of the dataset code."""
    return {"config": json.loads(_canonical(cfg)), "sources": source_digests(cfg), "code": code_fingerprint()}


def dataset_key(cfg: Mapping) -> str:
    """Content hash of a dataset config (order of keys does not matter), of the dataset code and of the content of
    every source file the config names (:func:`key_inputs`)."""
    return _sha256(_canonical(key_inputs(cfg)).encode())[:24]


def source_files(cfg: Mapping) -> list[Path]:
    """Each file, or file in a folder, that a string value of ``cfg`` names under ``cfg["data_root"]``, under the
    workbench's ``conf/`` folder (as ``dataset.marker_table`` does) or as an absolute path; empty for generated
    datasets without such files."""
    from workbench.settings.config import CONF_DIR

    roots = [Path(root) for root in (cfg.get("data_root"), CONF_DIR) if root]
    files = []
    for value in _strings(cfg):
        if not value:
            continue
        for root in roots:
            path = root / value  # an absolute value stays itself
            if path.is_file():
                files.append(path)
            elif path.is_dir() and path.resolve() != root.resolve():
                files += sorted(item for item in path.iterdir() if item.is_file())
    return files


def source_digests(cfg: Mapping) -> list[tuple[str, str]]:
    """(path, SHA-256 of the content) of every file of :func:`source_files`: a file edited in place gives another
    key even when its size and modification time are kept."""
    return [(str(path), file_digest(path)) for path in source_files(cfg)]


def file_digest(path: str | Path) -> str:
    """SHA-256 of a file's content, remembered in the process by the file's device, inode, size, modification and
    change times.

    Any write changes the change time (ctime), which no program can set back (``os.utime`` sets it to now), so a
    file edited in place with its size and modification time restored is hashed afresh; a file that changed less
    than :data:`SETTLED_SECONDS` before it was hashed is not remembered.
    """
    path = Path(path)
    status = path.stat()
    stamp = (status.st_dev, status.st_ino, status.st_size, status.st_mtime_ns, status.st_ctime_ns)
    known = _digests.get(str(path))
    if known is not None and known[0] == stamp:
        return known[1]
    started = time.time_ns()
    digest = sha256_of_file(path)
    if started - max(status.st_mtime_ns, status.st_ctime_ns) > SETTLED_SECONDS * 1e9:
        _digests[str(path)] = (stamp, digest)
    return digest


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _canonical(value) -> str:
    return json.dumps(value, sort_keys=True, default=str)


def _strings(value):
    if isinstance(value, str):
        yield value
    elif isinstance(value, Mapping):
        for item in value.values():
            yield from _strings(item)
    elif isinstance(value, (list, tuple)):
        for item in value:
            yield from _strings(item)


def cached_captures(
    cfg: Mapping, build: Callable[[Mapping], dict], cache_dir: str | Path | None = None
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
    inputs = key_inputs(cfg)
    key = _sha256(_canonical(inputs).encode())[:24]
    if key in _memory:
        _memory.move_to_end(key)
        return _memory[key]
    folder = cache_folder(cache_dir)
    captures = _load_or_report(folder, key, inputs) if folder else None
    if captures is None:
        try:
            captures = {name: _read_only(capture) for name, capture in build(cfg).items()}
            if folder:
                _save(folder, key, inputs, captures)
        except OSError as error:
            if folder and error.errno in (errno.ENOSPC, errno.EDQUOT):
                raise WorkbenchError(
                    f"paths.cache_dir {folder}: no space left on its disk writing {error.filename or 'a file'}; "
                    "free space there or set paths.cache_dir to a folder on another disk"
                ) from None
            raise
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
        raise WorkbenchError(f"paths.cache_dir {folder} is not a folder (a file is in the way); give a folder or null")
    return folder


def _load_or_report(folder: Path, key: str, inputs: dict) -> dict[str, Capture] | None:
    """The cached captures of ``key``, or None when there are none, they cannot be read or they do not match
    their checksums or ``inputs`` (reported on stderr in one line; the caller rebuilds the entry and writes it
    anew)."""
    try:
        return _load(folder, key, inputs)
    except EntryMismatch as mismatch:
        reason = str(mismatch)
    except (
        OSError,
        ValueError,
        KeyError,
        TypeError,
        AttributeError,
        EOFError,
        zipfile.BadZipFile,
        WorkbenchError,
    ) as error:
        reason = f"cannot be read ({type(error).__name__}: {error})"
    print(f"workbench: cache entry {folder / key}: {reason}; rebuilding it", file=sys.stderr)
    return None


_FORGET: list[Callable[[], None]] = []


def on_forget(forget: Callable[[], None]) -> None:
    """Have :func:`forget_kept_frames` call ``forget``: a builder that keeps frames in memory between runs (the
    synthetic actor's) registers how to drop them."""
    _FORGET.append(forget)


def forget_kept_frames() -> None:
    """Drop the frames the builders keep in memory (a stored file they may map has changed or is gone)."""
    for forget in _FORGET:
        forget()


def clear_memory() -> None:
    """Forget the captures, the source files' hashes and the frames the builders keep in memory, as a new process
    would (the disk cache stays)."""
    _memory.clear()
    _digests.clear()
    forget_kept_frames()


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


def _save(folder: Path, key: str, inputs: dict, captures: dict[str, Capture]) -> None:
    """Write the entry of ``key``: frames files, then ``<key>.npz``, then ``<key>.json`` with the checksums."""
    arrays, meta, frame_paths = {}, {}, {}
    for index, (name, capture) in enumerate(captures.items()):
        same_frames = capture.eval is capture.train
        frames = {}
        for field in _ARRAYS:
            array = getattr(capture, field)
            if array is None or (field == "eval" and same_frames):
                continue
            if field in _FRAMES and (isinstance(array, FramesOnDisk) or array.dtype.name in DTYPES):
                frames[field] = _frames_file(folder, (key, index), field, array)
                frame_paths[frames[field]["path"]] = None  # once each (the two parts of a split share a file)
            else:
                arrays[f"{index}_{field}"] = array
        if capture.eval_timeline is not None:
            arrays.update(capture.eval_timeline.as_arrays(f"{index}_timeline_"))
        meta[name] = {
            "index": index,
            "same_frames": same_frames,
            "name": capture.name,
            "frames": frames,
            "hand_names": list(capture.hand_names),
            "point_labels": list(capture.point_labels),
            "units": capture.units,
            "origin": capture.origin,
            "frame_rate": capture.frame_rate,
            "provenance": _plain(capture.provenance),
            "notes": list(capture.notes),
        }
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)  # uncompressed: compressing float frames saves little and costs most of a build
    payload = buffer.getvalue()
    write_atomic(folder / f"{key}.npz", payload)
    files = {f"{key}.npz": _sha256(payload), **{path: sha256_of_file(folder / path) for path in frame_paths}}
    document = {"key": key, "inputs": inputs, "captures": meta, "files": files}
    write_atomic(
        folder / f"{key}.json", json.dumps(dict(document, sha256=_sha256(_canonical(document).encode())), indent=1)
    )


def _frames_file(folder: Path, key: tuple, field: str, frames) -> dict:
    """Where frames are kept for the entry: ``{"path" (relative to ``folder`` when inside it), "first" row,
    "rows", "mapped"}``. Frames stored on disk stay in their file (``mapped`` false: read back as
    :class:`FramesOnDisk`); frames in memory are written to a ``.npy`` of their dtype by :class:`FrameStorage`
    (``mapped`` true: read back memory-mapped as an array)."""
    if isinstance(frames, FramesOnDisk):
        path, first, mapped = frames.path, frames.first, False
    else:
        storage = FrameStorage(dtype=frames.dtype.name, folder=str(folder / FRAMES_FOLDER))
        storage.path(f"cached_{field}", key).unlink(missing_ok=True)  # never vouch for a file left from before
        path, first, mapped = storage.keep(f"cached_{field}", key, frames).path, 0, True
    try:
        path = path.resolve().relative_to(folder.resolve())
    except ValueError:
        path = path.resolve()
    return {"path": str(path), "first": int(first), "rows": len(frames), "mapped": mapped}


def _load(folder: Path, key: str, inputs: dict) -> dict[str, Capture] | None:
    meta_path = folder / f"{key}.json"
    if not meta_path.is_file():
        return None
    try:
        document = json.loads(meta_path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise EntryMismatch(f"{meta_path.name} cannot be read ({type(error).__name__}: {error})") from None
    if not isinstance(document, dict):
        raise EntryMismatch(f"{meta_path.name} is not a cache entry")
    recorded = document.pop("sha256", None)
    if recorded != _sha256(_canonical(document).encode()):
        raise EntryMismatch(f"{meta_path.name} does not match its checksum (edited after it was written)")
    if _canonical(document["inputs"]) != _canonical(inputs):
        raise EntryMismatch(f"{meta_path.name} was made from other inputs ({_differences(document['inputs'], inputs)})")
    payload = io.BytesIO(_verified_files(folder, key, document["files"]))
    with np.load(payload, allow_pickle=False) as stored:
        arrays = {name: stored[name] for name in stored.files}
    captures = {}
    for name, info in document["captures"].items():
        index = info["index"]
        arrays.update({f"{index}_{field}": _open_frames(folder, spec) for field, spec in info["frames"].items()})
        train = arrays[f"{index}_train"]
        capture = Capture(
            name=info["name"],
            neutral=arrays[f"{index}_neutral"],
            train=train,
            eval=train if info["same_frames"] else arrays[f"{index}_eval"],
            hand=arrays[f"{index}_hand"],
            hand_names=tuple(info["hand_names"]),
            point_labels=tuple(info["point_labels"]),
            units=info["units"],
            origin=info["origin"],
            frame_rate=info["frame_rate"],
            provenance=info["provenance"],
            notes=tuple(info["notes"]),
            faces=arrays.get(f"{index}_faces"),
            eval_visible=arrays.get(f"{index}_eval_visible"),
            train_source=arrays.get(f"{index}_train_source"),
            train_operator=arrays.get(f"{index}_train_operator"),
            point_support=arrays.get(f"{index}_point_support"),
            eval_timeline=Timeline.from_arrays(arrays, f"{index}_timeline_"),
        )
        captures[name] = _read_only(capture)
    return captures


def _differences(recorded: dict, inputs: dict) -> str:
    """Which of an entry's recorded inputs differ from ``inputs``, in a few words."""
    parts = []
    if _canonical(recorded.get("config")) != _canonical(inputs["config"]):
        parts.append("another dataset config")
    old, new = dict(map(tuple, recorded.get("sources") or [])), dict(inputs["sources"])
    changed = sorted(path for path in old.keys() | new.keys() if old.get(path) != new.get(path))
    if changed:
        parts.append(
            f"source file {changed[0]} differs" + (f" and {len(changed) - 1} more" if len(changed) > 1 else "")
        )
    if recorded.get("code") != inputs["code"]:
        parts.append("other dataset code")
    return ", ".join(parts) or "inputs differ"


def _verified_files(folder: Path, key: str, files: Mapping[str, str]) -> bytes:
    """The bytes of ``<key>.npz`` after checking it and every frames file against their recorded SHA-256; a frames
    file that does not match is removed (it is the cache's own), so the rebuild writes it anew."""
    npz = f"{key}.npz"
    payload = (folder / npz).read_bytes()
    if files.get(npz) != _sha256(payload):
        raise EntryMismatch(f"{npz} does not match its checksum (changed after it was written)")
    for relative, digest in files.items():
        path = folder / relative
        if relative == npz:
            continue
        if not path.is_file():
            raise EntryMismatch(f"frames file {path} is missing")
        if sha256_of_file(path) != digest:
            if path.resolve().is_relative_to((folder / FRAMES_FOLDER).resolve()):
                path.unlink()
                forget_kept_frames()  # a builder's frames kept in memory may be this file
            raise EntryMismatch(f"frames file {path} does not match its checksum (changed after it was written)")
    return payload


def _open_frames(folder: Path, spec: Mapping):
    """Frames of an entry: a read-only array memory-mapped from the file, or :class:`FramesOnDisk`."""
    path, first, rows = folder / spec["path"], int(spec["first"]), int(spec["rows"])
    if spec["mapped"]:
        return np.asarray(np.load(path, mmap_mode="r", allow_pickle=False))[first : first + rows]
    return FramesOnDisk(path).rows(first, first + rows)
