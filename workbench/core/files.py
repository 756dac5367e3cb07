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
import re
import shutil
import struct
import sys
import tempfile
import zipfile
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Iterator, Mapping

import numpy as np

from workbench.core.errors import WorkbenchError

TEMPORARY_SUFFIX = ".tmp"
"""A file being written is ``.<name>.<random>.tmp`` beside its final name (the name cut short where the whole would
not fit: :func:`temporary_prefix`); a kill can leave one behind, never a part of a final file. Readers look only at
final names; a rerun clears a killed run's folder."""


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
        handle, temporary = tempfile.mkstemp(
            dir=path.parent, prefix=temporary_prefix(path.name), suffix=TEMPORARY_SUFFIX
        )
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


DISK_FULL_TEXTS = ("disk is full", "No space left on device", "Disk quota exceeded")
"""How a full disk reads in the errors of the C library, SQLite and the libraries above them."""


def disk_full(error: BaseException) -> bool:
    """Whether ``error``, or an error it was raised from (its cause, its context, a database driver's ``orig``),
    says the disk is full: ``ENOSPC`` or ``EDQUOT``, or SQLite's "database or disk is full", whatever line of a
    library's message holds it."""
    seen = set()
    while error is not None and id(error) not in seen:
        seen.add(id(error))
        if isinstance(error, OSError) and error.errno in (errno.ENOSPC, errno.EDQUOT):
            return True
        if any(text in str(error) for text in DISK_FULL_TEXTS):
            return True
        error = getattr(error, "orig", None) or error.__cause__ or error.__context__
    return False


def free_bytes(path: Path) -> int | None:
    """Bytes free for an unprivileged user on the file system holding ``path`` (its nearest existing folder), or
    None when it cannot be told."""
    path = Path(path).absolute()
    while not path.exists() and path != path.parent:
        path = path.parent
    try:
        status = os.statvfs(path)
    except OSError:
        return None
    return status.f_bavail * status.f_frsize


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
"""Written into a report, export or collected-tables folder with the rest of it (JSON): which command wrote the
folder (``written_by``) and the SHA-256 of every file it wrote there, at any depth (``files``: path relative to the
folder -> digest). A later run of the same command replaces a folder holding only those files, unchanged; a file
changed since is replaced only when forced, and another command's folder, or a folder holding a file the marker
does not list, never. An earlier version's marker lists the top-level names only (``files`` a list)."""
FORCE_FLAG = "--force"
"""The option of ``report``, ``export`` and ``collect`` that replaces files the user changed since they wrote them."""
NAME_MAX = 255
"""The longest file name, in bytes, the file systems the workbench runs on take (Linux's, macOS's)."""
_RANDOM = r"[A-Za-z0-9_]+"
"""The random part ``tempfile`` puts into a temporary name."""
_OLD_COPY = ".old"
"""Ends the random part of an earlier output moved aside while its replacement moves in."""


def temporary_prefix(name: str) -> str:
    """The start of a temporary name beside ``name`` (``tempfile`` adds 8 random characters and the suffix):
    ``.<name>.``, or, where that would not fit in :data:`NAME_MAX` bytes, ``.<the name cut short>~<its digest>.``,
    so that a temporary name fits wherever the final name fits and still tells whose it is."""
    room = NAME_MAX - len(".") - len(".") - 8 - len(_OLD_COPY) - len(TEMPORARY_SUFFIX)
    encoded = name.encode("utf-8", "surrogateescape")
    if len(encoded) <= room:
        return f".{name}."
    tag = "~" + hashlib.sha256(encoded).hexdigest()[:12]
    cut = encoded[: room - len(tag)].decode("utf-8", "ignore")  # never half a character
    return f".{cut}{tag}."


@dataclass(frozen=True)
class OutputMarker:
    """What :data:`OUTPUT_MARKER` says of an output folder.

    Attributes
    ----------
    writer : str or None
        The command that wrote the folder (``a report``, ``an export``, ``collect``); None when the marker does not
        say.
    files : dict of str to str
        Path relative to the folder (``/``-separated) -> SHA-256 of what the command wrote there; for an earlier
        version's marker, the top-level names, without digests (empty strings).
    recursive : bool
        Whether ``files`` lists every file at any depth with its digest (False for an earlier version's marker).
    """

    writer: str | None
    files: dict
    recursive: bool


def read_output_marker(folder: Path) -> OutputMarker | None:
    """The marker of an output folder, or None when it has none or it cannot be read (the workbench did not write
    the folder, or wrote it before folders were marked)."""
    try:
        marker = json.loads((Path(folder) / OUTPUT_MARKER).read_text())
        files = marker["files"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    writer = marker.get("written_by") if isinstance(marker.get("written_by"), str) else None
    if isinstance(files, dict):
        return OutputMarker(writer, {str(k): str(v) for k, v in files.items()}, recursive=True)
    if isinstance(files, list):
        return OutputMarker(writer, dict.fromkeys((name for name in files if isinstance(name, str)), ""), False)
    return None


_digests: dict[tuple, str] = {}
"""SHA-256 of files already read, by device, inode, size and modification time: an output folder is checked before
its command starts, before it writes and before it moves the new output in."""


def _entry_digest(path: Path) -> str:
    """SHA-256 of a file's content, or of where a symbolic link leads (``link:<target>``), or ``other`` for a device,
    pipe or socket."""
    status = os.lstat(path)
    if os.path.islink(path):
        return "link:" + hashlib.sha256(os.readlink(path).encode("utf-8", "surrogateescape")).hexdigest()
    if not os.path.isfile(path):
        return "other"
    key = (status.st_dev, status.st_ino, status.st_size, status.st_mtime_ns)
    if key not in _digests:
        _digests[key] = sha256_of_file(path)
    return _digests[key]


def folder_digests(folder: Path) -> dict[str, str]:
    """Every file under ``folder`` (symbolic links not followed; folders themselves not listed) -> its digest
    (:func:`_entry_digest`), by path relative to ``folder``, ``/``-separated; the marker itself left out.

    Parameters
    ----------
    folder : pathlib.Path

    Returns
    -------
    dict of str to str
    """
    found = {}
    for root, folders, names in os.walk(folder):
        for name in names + [name for name in folders if os.path.islink(os.path.join(root, name))]:
            relative = os.path.relpath(os.path.join(root, name), folder).replace(os.sep, "/")
            if relative != OUTPUT_MARKER:
                found[relative] = _entry_digest(Path(root) / name)
    return found


def check_output_folder(folder, setting: str, *, writer: str, known: Iterable[str] = (), force: bool = False) -> Path:
    """Refuse an output folder holding anything but an earlier output of the same command, before anything is
    written.

    The folder may be new, empty, or hold only what an earlier run of the same command wrote there, unchanged (the
    digests its :data:`OUTPUT_MARKER` lists); with ``force``, files of that output changed since are replaced too.
    The current directory, by an empty name or any other, is never one; nor is a mount point (it cannot be
    replaced as a whole), or a name with a control character (a newline in a folder name breaks every listing).
    Temporary copies of the folder that a killed command left are cleared first (:func:`clear_stale_copies`).

    Parameters
    ----------
    folder : path or str
        The folder as given.
    setting : str
        The option that names it, for the message (``--out``, ``--name``).
    writer : str
        What writes it, for the message and the marker (``a report``).
    known : iterable of str
        Names the command writes, accepted without a marker where the workbench chose the folder itself (a
        default folder inside a record, or a reference report, written before folders were marked).
    force : bool
        Replace files of an earlier output of the command that were changed since (:data:`FORCE_FLAG`).

    Returns
    -------
    pathlib.Path

    Raises
    ------
    WorkbenchError
    """
    path = check_folder_setting(folder, setting, writer)
    control = [character for character in str(folder) if ord(character) < 0x20 or ord(character) == 0x7F]
    if control:
        raise WorkbenchError(
            f"{setting}={str(folder)!r} holds a control character ({control[0]!r}); name the folder without one"
        )
    with _folder_locked(path.parent):
        clear_stale_copies(path)
        _refuse_foreign(path, setting, writer, known, force)
    return path


def _refuse_foreign(path: Path, setting: str, writer: str, known: Iterable[str], force: bool) -> None:
    """:func:`check_output_folder` of a checked path, with the lock of its parent held."""
    if path.is_symlink():
        raise WorkbenchError(
            f"{path} is a symbolic link; {writer} replaces its folder as a whole: name the folder itself ({setting}=...)"
        )
    if not os.path.lexists(path):
        return
    if not path.is_dir():
        raise WorkbenchError(f"{path} is a file, not a folder; name a new or empty folder ({setting}=...)")
    if os.path.ismount(path):
        raise WorkbenchError(
            f"{path} is a mount point, which {writer} cannot replace as a whole; name a folder inside it "
            f"({setting}={path / 'out'})"
        )
    marker = read_output_marker(path)
    if marker is not None and marker.writer not in (None, writer):
        raise WorkbenchError(
            f"{path} holds the output of {marker.writer} (its {OUTPUT_MARKER} says so); {writer} goes only into a new "
            f"or empty folder or one it wrote before, and replaces nothing else: name another folder ({setting}=...)"
        )
    if marker is None or not marker.recursive:  # no digests: the top-level names, as an earlier version wrote them
        listed = set(known) if marker is None else {OUTPUT_MARKER, *marker.files}
        foreign, changed = set(os.listdir(path)) - listed, set()
    else:
        found = folder_digests(path)
        foreign = {name for name in found if name not in marker.files}
        changed = {name for name in found if name in marker.files and found[name] != marker.files[name]}
    if foreign:
        raise WorkbenchError(
            f"{path} holds files the workbench did not write there ({shown_names(foreign)}); {writer} goes only into "
            f"a new or empty folder or one it wrote before, and touches nothing else: name another folder ({setting}=...)"
            " or move them away"
        )
    if changed and not force:
        raise WorkbenchError(
            f"{path}: {shown_names(changed)} changed since {writer} wrote {'it' if len(changed) == 1 else 'them'} "
            f"(SHA-256 no longer the one in {OUTPUT_MARKER}); rerun with {FORCE_FLAG} to overwrite, or move "
            f"{'it' if len(changed) == 1 else 'them'} away first"
        )


@contextmanager
def output_folder(
    folder, setting: str, *, writer: str, known: Iterable[str] = (), force: bool = False
) -> Iterator[Path]:
    """A report's, export's or collect's folder, written whole or not at all.

    The folder is checked (:func:`check_output_folder`); what the command writes goes into a new temporary folder
    beside it, which, once complete and marked (:data:`OUTPUT_MARKER`, every file's digest), takes the folder's
    place, and an earlier output there is removed. A failure or an interrupt removes the temporary folder and
    leaves the old one as it was; one a killed command left (``kill -9``) is removed by the next command writing
    that folder (:func:`clear_stale_copies`). Two processes replacing one folder take turns (the lock of its parent
    folder); of two commands writing one new folder at once, the second to finish is refused.

    Parameters
    ----------
    folder, setting, writer, known, force
        As :func:`check_output_folder`.

    Yields
    ------
    pathlib.Path
        The temporary folder to write into (beside ``folder``, so relative links to its neighbours hold).
    """
    path = check_output_folder(folder, setting, writer=writer, known=known, force=force)
    staging, held = None, None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with _folder_locked(path.parent):  # a copy is held from the moment it exists, so no other command clears it
            staging = Path(
                tempfile.mkdtemp(dir=path.parent, prefix=temporary_prefix(path.name), suffix=TEMPORARY_SUFFIX)
            )
            held = _hold(staging)
    except OSError as error:
        if staging is not None:
            _remove(staging)
        raise naming(error, path) from None
    try:
        os.chmod(staging, FOLDER_MODE)
        yield staging
        write_json(staging / OUTPUT_MARKER, {"written_by": writer, "files": folder_digests(staging)})
        with _folder_locked(path.parent):
            _refuse_foreign(path, setting, writer, known, force)  # nothing came in meanwhile
            _move_into_place(staging, path)
    finally:
        if held is not None:
            os.close(held)
        if os.path.lexists(staging):
            _remove(staging)


def _move_into_place(staging: Path, path: Path) -> None:
    """Replace ``path`` by ``staging`` (with the parent's lock held): the earlier output moves aside first and is
    removed once the new one is in place, or moves back when the new one cannot. Should even that fail, the earlier
    output is kept aside, and the next command on the folder moves it back (:func:`clear_stale_copies`)."""
    old, placed = None, False
    try:
        if os.path.lexists(path):
            old = Path(
                tempfile.mkdtemp(
                    dir=path.parent, prefix=temporary_prefix(path.name), suffix=_OLD_COPY + TEMPORARY_SUFFIX
                )
            )
            os.replace(path, old)
        try:
            os.replace(staging, path)
            placed = True
        except BaseException:
            if old is not None and not os.path.lexists(path):  # the earlier output back in place
                os.replace(old, path)
                old = None
            raise
    except OSError as error:
        if error.errno == errno.EBUSY:
            raise WorkbenchError(f"{path} cannot be replaced ({error.strerror}: a mount point, or in use)") from None
        raise naming(error, path) from None
    finally:
        if old is not None and (placed or not os.listdir(old)):  # never the earlier output while it is not replaced
            _remove(old)


def _hold(folder: Path) -> int | None:
    """Open ``folder`` and take its advisory lock, held while the command writes into it (the lock tells
    :func:`clear_stale_copies` it is not a killed command's); None where the file system refuses the lock."""
    handle = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(handle)
        return None
    return handle


def clear_stale_copies(path: Path) -> list[Path]:
    """Remove the temporary copies of output folder ``path`` that a killed command left beside it (``kill -9``, a
    power cut): every ``.<name>.<random>.tmp`` no running command holds (:func:`_hold`). An earlier output that was
    moved aside when the kill came is moved back where the folder is missing. Call it with the parent's lock held.

    Returns
    -------
    list of pathlib.Path
        The copies removed or moved back.
    """
    pattern = re.compile(
        re.escape(temporary_prefix(path.name)) + _RANDOM + f"({re.escape(_OLD_COPY)})?" + re.escape(TEMPORARY_SUFFIX)
    )
    cleared = []
    try:
        names = os.listdir(path.parent)
    except OSError:
        return cleared
    for name in sorted(names):
        match = pattern.fullmatch(name)
        copy = path.parent / name
        if match is None or copy.is_symlink() or not copy.is_dir():
            continue
        handle = _hold(copy)
        if handle is None:  # a running command's, or a file system without locks: left alone
            continue
        try:
            if match.group(1) and not os.path.lexists(path):
                os.replace(copy, path)
            else:
                _remove(copy)
        finally:
            os.close(handle)
        cleared.append(copy)
    return cleared


def _remove(folder: Path) -> None:
    """Remove a temporary folder of the workbench's, making the folders in it writable first where it cannot (an
    earlier output the user made read-only); a failure is one line on stderr, never the command's error in its
    place."""
    shutil.rmtree(folder, ignore_errors=True)
    if os.path.lexists(folder):
        _make_writable(folder)
        shutil.rmtree(folder, ignore_errors=True)
    if os.path.lexists(folder):
        print(f"workbench: could not remove the temporary folder {folder}; remove it by hand", file=sys.stderr)


def _make_writable(folder: Path) -> None:
    """Give the owner every permission on ``folder`` and the folders in it (symbolic links not followed)."""
    with suppress(OSError):
        os.chmod(folder, 0o700)
    with suppress(OSError), os.scandir(folder) as entries:
        for entry in entries:
            if entry.is_dir(follow_symlinks=False):
                _make_writable(Path(entry.path))


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
