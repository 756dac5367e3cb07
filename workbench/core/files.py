"""Files, the one way the workbench writes and checks them: atomic writes (a reader sees the old content or the
whole new content, never a part), the one file hash (SHA-256), the one advisory lock, and the checks that a name
stays inside its folder.

Every module that writes a file (run records, cached frames, reports, exports) writes it here.
"""

from __future__ import annotations

import errno
import fcntl
import hashlib
import io
import json
import os
import tempfile
from pathlib import Path
from typing import Mapping

import numpy as np

from workbench.core.errors import WorkbenchError

TEMPORARY_SUFFIX = ".tmp"
"""A file being written is ``.<name>.<random>.tmp`` beside its final name; a kill can leave one behind, never a
part of a final file. Readers look only at final names; a rerun clears a killed run's folder."""


def _file_mode() -> int:
    """Permissions of a new file under the process's umask (the temporary file is created private)."""
    umask = os.umask(0o022)
    os.umask(umask)
    return 0o666 & ~umask


FILE_MODE = _file_mode()


def write_atomic(path: Path, data: bytes | str) -> None:
    """Write a file so that a reader sees either the old content or the whole new content, never a part."""
    path = Path(path)
    payload = data.encode() if isinstance(data, str) else data
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=TEMPORARY_SUFFIX)
    except OSError as error:
        raise naming(error, path) from None
    try:
        os.fchmod(handle, FILE_MODE)
        with os.fdopen(handle, "wb") as stream:
            stream.write(payload)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temporary, path)
    except BaseException as error:
        Path(temporary).unlink(missing_ok=True)
        if isinstance(error, OSError):
            raise naming(error, path) from None
        raise


def naming(error: OSError, path: Path) -> OSError:
    """``error`` naming the file being written (a full disk fails a write on an open file, which names none)."""
    return type(error)(error.errno, f"cannot write ({error.strerror})", str(path))


def json_text(value) -> str:
    return json.dumps(value, indent=2, sort_keys=False, allow_nan=True) + "\n"


def npz_bytes(arrays: Mapping[str, np.ndarray]) -> bytes:
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    return buffer.getvalue()


def write_json(path: Path, value) -> None:
    write_atomic(path, json_text(value))


def write_npz(path: Path, arrays: Mapping[str, np.ndarray]) -> None:
    write_atomic(path, npz_bytes(arrays))


def sha256_of_file(path: Path) -> str:
    """SHA-256 (hex) of a file's content, read into one buffer of 1 MB (``hashlib.file_digest`` needs Python
    3.11)."""
    digest, buffer = hashlib.sha256(), bytearray(1 << 20)
    view = memoryview(buffer)
    with open(path, "rb", buffering=0) as stream:
        while size := stream.readinto(buffer):
            digest.update(view[:size])
    return digest.hexdigest()


def lock_file(path: Path, *, wait: bool = True) -> int | None:
    """Take the exclusive advisory lock (``fcntl.flock``) on ``path``, creating the file if needed.

    The operating system releases the lock when the process ends, however it ends.

    Parameters
    ----------
    path : pathlib.Path
    wait : bool
        Wait for another process to release the lock; when False, return None at once if it holds it.

    Returns
    -------
    int or None
        The open file's descriptor, for :func:`unlock_file`; None when ``wait`` is False and the lock is held.
    """
    handle = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
    except OSError as error:
        os.close(handle)
        if not wait and error.errno in (errno.EWOULDBLOCK, errno.EACCES):
            return None
        raise
    return handle


def unlock_file(handle: int) -> None:
    """Release a lock taken by :func:`lock_file`."""
    fcntl.flock(handle, fcntl.LOCK_UN)
    os.close(handle)


def plain_name(name: str) -> bool:
    """Whether ``name`` can name a file or folder without leaving its parent (no separator, not '.' or '..')."""
    return bool(name) and name not in (".", "..") and "/" not in name and "\\" not in name and "\0" not in name


def inside(root: Path, *parts: str) -> Path:
    """``root / parts``, refused when it would leave ``root``, by its name or through a symbolic link (a report or
    collect writes only into its output folder, whatever names a record holds and whatever links it contains).

    Raises
    ------
    WorkbenchError
    """
    root = Path(root)
    path = root.joinpath(*parts)
    for resolved, base, target in (
        (False, os.path.abspath(root), os.path.abspath(path)),
        (True, os.path.realpath(root), os.path.realpath(path)),
    ):
        if os.path.commonpath([base, target]) != base:
            link = f" (a symbolic link leads to {target})" if resolved else ""
            raise WorkbenchError(f"refusing to write {path}: it is not inside the output folder {root}{link}")
    return path
