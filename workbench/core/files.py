"""Files, the one way the workbench writes and checks them: atomic writes (a reader sees the old content or the
whole new content, never a part), the one file hash (SHA-256), the one advisory lock, the checks that a name
stays inside its folder, and the output folders of reports, exports and collected tables (written whole into a
folder of their own, never into one holding someone's files).

Every module that writes a file (run records, cached frames, reports, exports) writes it here.
"""

from __future__ import annotations

import errno
import fcntl
import hashlib
import io
import json
import math
import os
import shutil
import struct
import tempfile
import zipfile
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Iterable, Iterator, Mapping

import numpy as np

from workbench.core.errors import WorkbenchError

TEMPORARY_SUFFIX = ".tmp"
"""A file being written is ``.<name>.<random>.tmp`` beside its final name; a kill can leave one behind, never a
part of a final file. Readers look only at final names; a rerun clears a killed run's folder."""


def _umask() -> int:
    """The process's umask (read by setting it and putting it back)."""
    umask = os.umask(0o022)
    os.umask(umask)
    return umask


FILE_MODE = 0o666 & ~_umask()
"""Permissions of a new file under the process's umask (the temporary file is created private)."""
FOLDER_MODE = 0o777 & ~_umask()
"""Permissions of a new folder under the process's umask (a temporary folder is created private)."""


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


def npz_bytes(arrays: Mapping[str, np.ndarray], compressed: bool = True) -> bytes:
    """The bytes of an ``.npz`` file of ``arrays``, deflated unless ``compressed`` is False."""
    buffer = io.BytesIO()
    (np.savez_compressed if compressed else np.savez)(buffer, **arrays)
    return buffer.getvalue()


def mapped_npz(path: Path) -> dict[str, np.ndarray]:
    """The arrays of an ``.npz`` file. Where the archive stores its arrays uncompressed (as run records store their
    inputs), each is mapped read-only from the file instead of copied: reading a record's inputs of 810 MB took
    2.2 s with ``numpy.load`` (most of it filling fresh memory), and mapping takes a millisecond, the pages then read
    from the page cache as they are used. A compressed archive is read whole with ``numpy.load``. Object arrays are
    refused either way (no pickles).

    Parameters
    ----------
    path : pathlib.Path

    Returns
    -------
    dict of str to ndarray
        Arrays by name (without ``.npy``), read-only where mapped.

    Raises
    ------
    OSError, ValueError, EOFError, zipfile.BadZipFile
        The file is not a readable NumPy archive.
    """
    with open(path, "rb") as stream, zipfile.ZipFile(stream) as archive:
        members = archive.infolist()
        if not all(member.compress_type == zipfile.ZIP_STORED for member in members):
            with np.load(stream, allow_pickle=False) as arrays:
                return {key: arrays[key] for key in arrays.files}
        arrays = {}
        for member in members:
            stream.seek(member.header_offset)
            header = stream.read(30)  # the member's local header: its name and extra field follow, then its data
            if len(header) < 30 or header[:4] != b"PK\x03\x04":
                raise ValueError(f"member {member.filename} has no local header")
            name_length, extra_length = struct.unpack("<HH", header[26:30])
            stream.seek(member.header_offset + 30 + name_length + extra_length)
            version = np.lib.format.read_magic(stream)
            read_header = (
                np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
            )
            shape, fortran, dtype = read_header(stream)
            if dtype.hasobject:
                raise ValueError(f"member {member.filename} holds Python objects, which are not read")
            name = member.filename.removesuffix(".npy")
            if math.prod(shape) == 0:
                arrays[name] = np.empty(shape, dtype)
            else:
                mapped = np.memmap(
                    path, dtype=dtype, mode="r", offset=stream.tell(), shape=shape, order="F" if fortran else "C"
                )
                arrays[name] = np.asarray(mapped)
        return arrays


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


def shown_names(names: Iterable[str]) -> str:
    """The first three of ``names`` and how many more, for a one-line message."""
    names = sorted(names)
    return ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")


def input_path(path, what: str, argument: str = "path", *, folder: bool = False) -> Path:
    """``path`` as a ``Path`` to read ``what`` from: refused in one line when it is not a path (naming
    ``argument``), is missing, or is a folder where a file is expected (or a file where a ``folder`` is), or a
    device, pipe or socket rather than a regular file.

    Raises
    ------
    WorkbenchError
    """
    if not isinstance(path, (str, os.PathLike)) or not str(path).strip():
        raise WorkbenchError(f"{argument} must be a path ({what}), got {path!r}")
    path = Path(path)
    if folder and path.is_dir() or not folder and path.is_file():
        return path
    if not path.exists():
        raise WorkbenchError(f"{path}: {what} not found")
    kind = "a folder" if path.is_dir() else "a file" if path.is_file() else "a device, pipe or socket"
    raise WorkbenchError(f"{path}: is {kind}, not a {'folder' if folder else 'file'} ({what} expected)")


def check_folder_setting(folder, setting: str, writer: str = "a run") -> Path:
    """A folder setting (``hydra.run.dir``, ``hydra.sweep.dir``, ``--out``) as a path, refused when it is empty or is
    the current directory or a folder above it (``writer`` writes into a folder of its own).

    Raises
    ------
    WorkbenchError
    """
    text = "" if folder is None else str(folder).strip()
    if not text or text == "None":
        raise WorkbenchError(
            f"{setting} is empty: {writer} writes into a folder of its own, never into the current "
            f"directory; name one ({setting}=outputs/<name>) or leave the default"
        )
    path = Path(text).expanduser()
    here = Path.cwd().resolve()
    if path.resolve() == here or path.resolve() in here.parents:
        raise WorkbenchError(
            f"{setting}={text} is the current directory or a folder above it; {writer} writes into a "
            f"folder of its own: name one ({setting}=outputs/<name>) or leave the default"
        )
    return path


OUTPUT_MARKER = ".workbench-output"
"""Written into a report, export or collected-tables folder with the rest of it: the names the workbench wrote
there (JSON). A later report, export or collect may replace a folder holding only those names and the marker."""


def written_names(folder: Path) -> set[str] | None:
    """The names an output folder's marker lists, or None when it has no readable marker (the workbench did not
    write the folder, or wrote it before folders were marked)."""
    try:
        names = json.loads((Path(folder) / OUTPUT_MARKER).read_text())["files"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return {name for name in names if isinstance(name, str)} if isinstance(names, list) else None


def check_output_folder(folder, setting: str, *, writer: str, known: Iterable[str] = ()) -> Path:
    """Refuse an output folder holding anything the workbench did not write there, before anything is written.

    The folder may be new, empty, or hold only what an earlier run of the command wrote (the names its
    :data:`OUTPUT_MARKER` lists). The current directory, by an empty name or any other, is never one.

    Parameters
    ----------
    folder : path or str
        The folder as given.
    setting : str
        The option that names it, for the message (``--out``, ``--name``).
    writer : str
        What writes it, for the message (``a report``).
    known : iterable of str
        Names the command writes, accepted without a marker where the workbench chose the folder itself (a
        default folder inside a record, or a reference report, written before folders were marked).

    Returns
    -------
    pathlib.Path

    Raises
    ------
    WorkbenchError
    """
    path = check_folder_setting(folder, setting, writer)
    with _folder_locked(path.parent):
        _refuse_foreign(path, setting, writer, known)
    return path


def _refuse_foreign(path: Path, setting: str, writer: str, known: Iterable[str]) -> None:
    """:func:`check_output_folder` of a checked path, with the lock of its parent held."""
    if path.is_symlink():
        raise WorkbenchError(
            f"{path} is a symbolic link; {writer} replaces its folder as a whole: name the folder itself ({setting}=...)"
        )
    if not os.path.lexists(path):
        return
    if not path.is_dir():
        raise WorkbenchError(f"{path} is a file, not a folder; name a new or empty folder ({setting}=...)")
    names = set(os.listdir(path))
    listed = written_names(path)
    foreign = names - ({OUTPUT_MARKER, *listed} if listed is not None else set(known))
    if foreign:
        raise WorkbenchError(
            f"{path} holds files the workbench did not write there ({shown_names(foreign)}); {writer} goes only into "
            f"a new or empty folder or one it wrote before, and touches nothing else: name another folder ({setting}=...)"
        )


@contextmanager
def output_folder(folder, setting: str, *, writer: str, known: Iterable[str] = ()) -> Iterator[Path]:
    """A report's, export's or collect's folder, written whole or not at all.

    The folder is checked (:func:`check_output_folder`); what the command writes goes into a new temporary folder
    beside it, which, once complete and marked (:data:`OUTPUT_MARKER`), takes the folder's place, and an earlier
    output there is removed. A failure or an interrupt removes the temporary folder and leaves the old one as it was.
    Two processes replacing one folder take turns (the lock of its parent folder).

    Parameters
    ----------
    folder, setting, writer, known
        As :func:`check_output_folder`.

    Yields
    ------
    pathlib.Path
        The temporary folder to write into (beside ``folder``, so relative links to its neighbours hold).
    """
    path = check_output_folder(folder, setting, writer=writer, known=known)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}.", suffix=TEMPORARY_SUFFIX))
    except OSError as error:
        raise naming(error, path) from None
    old = None
    try:
        os.chmod(staging, FOLDER_MODE)
        yield staging
        write_json(staging / OUTPUT_MARKER, {"written_by": writer, "files": sorted(os.listdir(staging))})
        with _folder_locked(path.parent):
            _refuse_foreign(path, setting, writer, known)  # nothing came in meanwhile
            if os.path.lexists(path):
                old = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}.", suffix=TEMPORARY_SUFFIX))
                os.replace(path, old)
            try:
                os.replace(staging, path)
            except BaseException:
                if old is not None:  # the earlier output back in place
                    os.replace(old, path)
                    old = None
                raise
    finally:
        for leftover in (staging, old):
            if leftover is not None and os.path.lexists(leftover):
                shutil.rmtree(leftover, ignore_errors=True)


@contextmanager
def _folder_locked(folder: Path) -> Iterator[None]:
    """The advisory lock (``fcntl.flock``) on a folder itself, which needs no lock file in it; nothing to lock when
    the folder does not exist yet, and no lock where the file system refuses one on a folder (some network file
    systems)."""
    try:
        handle = os.open(folder, os.O_RDONLY)
    except OSError:
        handle = None
    try:
        if handle is not None:
            with suppress(OSError):
                fcntl.flock(handle, fcntl.LOCK_EX)
        yield
    finally:
        if handle is not None:
            os.close(handle)
