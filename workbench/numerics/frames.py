"""Capture frames in memory (float64 or float32) or on disk (a ``.npy`` file), read a chunk of frames at a time.

Every pass of the numerical core over a capture goes through :func:`frame_chunks`, which yields float64 chunks
whatever the storage, so arithmetic accumulates in float64 while a float32 capture takes half the memory and a
capture on disk takes none beyond one chunk. A capture on disk is read with plain file reads (through the page
cache, not a memory map), so the process's resident memory stays bounded by the chunk size.
"""

from __future__ import annotations

import hashlib
import io
import os
import tempfile
from pathlib import Path
from typing import Iterator

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.core.files import FILE_MODE, TEMPORARY_SUFFIX, naming, sha256_of_file, temporary_prefix, write_atomic
from workbench.core.frames import FRAME_DTYPES

CHUNK_ENTRIES = 1 << 24
"""Matrix entries per chunk of frames (128 MB as float64): a chunk holds ``CHUNK_ENTRIES // n_dims`` frames."""

LARGE_FRAMES = 1 << 28
"""Values (frames x coordinates) from which frames count as large, 2 GiB as float64: from here on a pass over them
takes seconds, and the passes take the faster routes whose sums run in another order (the randomised PCA's larger
chunks, the scoring through the bases' joint span). Below it a pass takes a second or less, and the routes stay as
they were: the weights of a rank-deficient basis are not unique and move by round-off with the order of the sums
(up to 3e-7 in the paper's reference run, ``w_max_abs``), so the smaller runs, and the reference reports, keep the
numbers they had."""

DTYPES = {name: getattr(np, name) for name in FRAME_DTYPES}


def chunk_frames(n_dims: int) -> int:
    """Frames per chunk for frames of ``n_dims`` values: at least 1, at most ``CHUNK_ENTRIES`` entries."""
    return max(1, CHUNK_ENTRIES // max(1, n_dims))


class FramesOnDisk:
    """Frames stored in a ``.npy`` file of shape (n_frames, n_dims), read on demand as float64.

    Parameters
    ----------
    path : str or Path
        A C-ordered ``.npy`` file of float32 or float64.

    Attributes
    ----------
    path : Path
    shape : tuple of int
    dtype : numpy.dtype
        The stored type; every read returns float64.
    """

    ndim = 2

    def __init__(self, path):
        self.path = Path(path)
        try:
            with open(self.path, "rb") as stream:
                version = np.lib.format.read_magic(stream)
                reader = (
                    np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
                )
                shape, fortran, dtype = reader(stream)
                self._offset = stream.tell()
        except (OSError, ValueError) as error:
            raise WorkbenchError(f"{self.path}: not a readable .npy file of frames ({error})") from None
        if len(shape) != 2 or fortran or dtype not in (np.dtype(np.float32), np.dtype(np.float64)):
            raise WorkbenchError(
                f"{self.path}: frames must be a C-ordered float32/float64 array of shape "
                f"(n_frames, n_dims), got shape {shape}, dtype {dtype}, fortran {fortran}"
            )
        self.shape, self.dtype = tuple(int(n) for n in shape), dtype
        self._first = 0

    def rows(self, start: int, stop: int) -> "FramesOnDisk":
        """Frames ``start`` to ``stop - 1`` as frames on disk (the same file, nothing read)."""
        start, stop, _ = slice(start, stop).indices(self.shape[0])
        part = object.__new__(FramesOnDisk)
        part.__dict__.update(self.__dict__)
        part.shape, part._first = (max(0, stop - start), self.shape[1]), self._first + start
        return part

    @property
    def first(self) -> int:
        """Row of the file where these frames start (0 unless taken with :meth:`rows`)."""
        return self._first

    def __len__(self) -> int:
        return self.shape[0]

    @property
    def nbytes(self) -> int:
        return self.shape[0] * self.shape[1] * self.dtype.itemsize

    def read(self, start: int, stop: int, dtype=np.float64) -> np.ndarray:
        """Frames ``start`` to ``stop - 1`` as a new array of shape (stop - start, n_dims), float64 or ``dtype``."""
        start, stop = max(0, start), min(stop, self.shape[0])
        count = max(0, stop - start) * self.shape[1]
        with open(self.path, "rb") as stream:
            stream.seek(self._offset + (self._first + start) * self.shape[1] * self.dtype.itemsize)
            values = np.fromfile(stream, dtype=self.dtype, count=count)
        if values.size != count:
            raise WorkbenchError(f"{self.path}: file is shorter than its header says ({self.shape})")
        return values.reshape(-1, self.shape[1]).astype(dtype, copy=False)

    def __getitem__(self, index) -> np.ndarray:
        """Frames by a slice of step 1 (read from the file) or by any other NumPy row index, as float64."""
        if isinstance(index, slice) and index.step in (None, 1):
            start, stop, _ = index.indices(self.shape[0])
            return self.read(start, stop)
        rows = np.arange(self.shape[0])[index]
        if np.ndim(rows) == 0:
            return self.read(int(rows), int(rows) + 1)[0]
        return (
            np.concatenate([self.read(int(row), int(row) + 1) for row in rows])
            if len(rows)
            else np.empty((0, self.shape[1]))
        )

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        whole = self.read(0, self.shape[0])
        return whole if dtype is None else whole.astype(dtype, copy=False)

    def __repr__(self) -> str:
        return f"FramesOnDisk({str(self.path)!r}, shape={self.shape}, dtype={self.dtype})"


def is_stored_frames(frames) -> bool:
    """True for frames that are not a float64 array in memory (a float32 array or :class:`FramesOnDisk`), which
    the numerical core reads chunk by chunk instead of converting whole."""
    return isinstance(frames, FramesOnDisk) or (isinstance(frames, np.ndarray) and frames.dtype == np.float32)


def frame_chunks(
    frames, size: int | None = None, dtype=np.float64, wanted: np.ndarray | None = None
) -> Iterator[tuple[slice, np.ndarray]]:
    """Consecutive chunks of frames as float64 arrays (or ``dtype``).

    Parameters
    ----------
    frames : ndarray of shape (n_frames, n_dims) or FramesOnDisk
    size : int, optional
        Frames per chunk; :func:`chunk_frames` of ``n_dims`` when None.
    dtype : numpy dtype
        Type of the chunks (float32 only where the caller's arithmetic is meant to be float32).
    wanted : ndarray of shape (n_frames,) of bool, optional
        Only the chunks holding a wanted frame are read and yielded (all when None).

    Yields
    ------
    rows : slice
        The frames of the chunk.
    chunk : ndarray of shape (rows.stop - rows.start, n_dims)
        A view of an array in memory of that type, a converted copy otherwise.
    """
    n_frames, n_dims = frames.shape
    size = size or chunk_frames(n_dims)
    for start in range(0, n_frames, size):
        rows = slice(start, min(start + size, n_frames))
        if wanted is not None and not wanted[rows].any():
            continue
        chunk = frames.read(rows.start, rows.stop, dtype) if isinstance(frames, FramesOnDisk) else frames[rows]
        yield rows, np.asarray(chunk, dtype=dtype)


def check_finite_chunk(name: str, rows: slice, chunk: np.ndarray) -> None:
    """A :class:`WorkbenchError` naming ``name`` and the chunk's frames when ``chunk`` (of :func:`frame_chunks`)
    holds NaN or Inf."""
    if not np.isfinite(chunk).all():
        raise WorkbenchError(f"{name} holds NaN or Inf values (in frames {rows.start}-{rows.stop - 1})")


def checksum_path(path: Path) -> Path:
    """The file beside a frames file written by :class:`FrameWriter` that holds its SHA-256 (hex)."""
    return path.with_name(path.name + ".sha256")


def written_intact(path: Path) -> str | None:
    """None when the frames file ``path`` has the SHA-256 its writer recorded beside it, else why not (no
    checksum beside it, or another content)."""
    try:
        recorded = checksum_path(path).read_text().strip()
    except OSError:
        return "no checksum beside it"
    if sha256_of_file(path) != recorded:
        return "its SHA-256 no longer matches the one recorded when it was written"
    return None


class FrameWriter:
    """Write frames of shape (n_frames, n_dims) to a ``.npy`` file chunk by chunk, atomically.

    The file appears under its final name only when every frame was written (:meth:`close`); until then it is a
    temporary file beside it, removed if writing fails.

    Parameters
    ----------
    path : str or Path
    n_frames, n_dims : int
    dtype : {"float64", "float32"}
    """

    def __init__(self, path, n_frames: int, n_dims: int, dtype: str = "float32"):
        if dtype not in DTYPES:
            raise WorkbenchError(f"frame dtype must be one of {sorted(DTYPES)}, got {dtype!r}")
        self.path, self.shape, self.dtype = Path(path), (int(n_frames), int(n_dims)), np.dtype(DTYPES[dtype])
        self.path.parent.mkdir(parents=True, exist_ok=True)
        handle, self._temporary = tempfile.mkstemp(
            dir=self.path.parent, prefix=temporary_prefix(self.path.name), suffix=TEMPORARY_SUFFIX
        )
        os.fchmod(handle, FILE_MODE)
        self._stream = os.fdopen(handle, "wb")
        header = io.BytesIO()
        np.lib.format.write_array_header_1_0(
            header, {"descr": np.lib.format.dtype_to_descr(self.dtype), "fortran_order": False, "shape": self.shape}
        )
        self._digest = hashlib.sha256(header.getvalue())
        self._stream.write(header.getvalue())
        self._written = 0

    def write(self, chunk: np.ndarray) -> None:
        """Append frames, shape (k, n_dims), converted to the file's dtype."""
        chunk = np.asarray(chunk).reshape(-1, self.shape[1])
        if self._written + len(chunk) > self.shape[0]:
            self.abort()
            raise WorkbenchError(f"{self.path}: more frames written than the {self.shape[0]} announced")
        data = np.ascontiguousarray(chunk, dtype=self.dtype).data  # no copy of the chunk
        try:
            self._stream.write(data)
        except OSError as error:  # a full disk fails a write on an open file, which names none
            self.abort()
            raise naming(error, self.path) from None
        self._digest.update(data)
        self._written += len(chunk)

    def close(self) -> FramesOnDisk:
        """Finish the file (all frames must have been written) and open it for reading."""
        try:
            if self._written != self.shape[0]:
                raise WorkbenchError(f"{self.path}: {self._written} of {self.shape[0]} frames written")
            self._stream.flush()
            os.fsync(self._stream.fileno())
            self._stream.close()
            checksum_path(self.path).unlink(missing_ok=True)  # the file that is replaced loses its checksum first
            os.replace(self._temporary, self.path)
            write_atomic(checksum_path(self.path), self._digest.hexdigest() + "\n")
        except BaseException as error:
            self.abort()
            if isinstance(error, OSError) and error.filename is None:
                raise naming(error, self.path) from None
            raise
        return FramesOnDisk(self.path)

    def abort(self) -> None:
        """Drop the temporary file."""
        try:
            self._stream.close()  # flushes what is buffered, which fails again on a full disk
        except OSError:
            pass
        Path(self._temporary).unlink(missing_ok=True)
