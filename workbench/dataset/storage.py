"""Where and how a built capture's frames are kept: ``dataset.storage`` (memory or disk) and ``dataset.dtype``
(float64 or float32).

Builders of dense captures (the synthetic mesh, interpolated meshes, mesh sequences, the ICT face driven by weight
curves) write their frames chunk by chunk into a :class:`FrameSink` (:meth:`FrameStorage.generate`), so the whole
float64 array is never held: in memory the sink is an array of the chosen dtype, on disk a ``.npy`` file in
``paths.cache_dir`` named by a content hash of what the frames are made from (the same inputs and dataset code
find the file again). Frames built whole (markers) are converted (or written out) when built.
"""

from __future__ import annotations

import hashlib
import sys
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Callable

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.core.progress import progress
from workbench.numerics.frames import DTYPES, FramesOnDisk, FrameWriter, chunk_frames, written_intact

FRAMES_FOLDER = "frames"
"""Sub-folder of ``paths.cache_dir`` holding captures stored on disk."""


@dataclass(frozen=True)
class FrameStorage:
    """How frames are kept.

    Attributes
    ----------
    dtype : {"float64", "float32"}
    folder : str or None
        Folder of the ``.npy`` files (on disk); None: in memory.
    """

    dtype: str = "float64"
    folder: str | None = None

    def path(self, name: str, key) -> Path:
        """The file of frames called ``name`` made from ``key`` (anything with a stable ``repr``)."""
        digest = hashlib.sha256(repr(key).encode()).hexdigest()[:24]
        return Path(self.folder) / f"{name}_{digest}_{self.dtype}.npy"

    def existing(self, name: str, key) -> FramesOnDisk | None:
        """The frames stored before under ``name`` and ``key``, or None (always None in memory).

        A file is used again only when it still has the SHA-256 its writer recorded beside it; any other is
        reported in one line on stderr and None returned, so that it is built (and replaced) anew."""
        if self.folder is None or not self.path(name, key).is_file():
            return None
        path = self.path(name, key)
        fault = written_intact(path)
        if fault is not None:
            print(f"workbench: frames file {path}: {fault}; building it again", file=sys.stderr)
            return None
        return FramesOnDisk(path)

    def sink(self, name: str, key, n_frames: int, n_dims: int) -> "FrameSink":
        """A sink for ``n_frames`` frames of ``n_dims`` values, written in order."""
        if self.folder is None:
            return FrameSink(array=np.empty((n_frames, n_dims), dtype=DTYPES[self.dtype]))
        return FrameSink(writer=FrameWriter(self.path(name, key), n_frames, n_dims, self.dtype))

    def keep(self, name: str, key, frames):
        """Frames built whole (shape (n_frames, n_dims)) kept as this storage says; frames already kept so (an array
        of its dtype in memory, or frames on disk, as builders write them) unchanged."""
        if isinstance(frames, FramesOnDisk) or (self.folder is None and frames.dtype == DTYPES[self.dtype]):
            return frames
        if self.folder is None:
            kept = frames.astype(DTYPES[self.dtype])
            kept.setflags(write=False)
            return kept
        return self.build(name, key, *frames.shape, lambda rows: frames[rows])

    def build(self, name: str, key, n_frames: int, n_dims: int, chunk_of: Callable[[slice], np.ndarray]):
        """Frames made a chunk at a time by ``chunk_of(rows)``, which gives frames ``rows`` (a slice of step 1),
        shape (rows.stop - rows.start, n_dims); see :meth:`generate`."""
        return self.generate(name, key, n_frames, n_dims, lambda rows, out: np.copyto(out, chunk_of(rows)))

    def generate(
        self, name: str, key, n_frames: int, n_dims: int, fill: Callable[[slice, np.ndarray], object], *, desc: str = ""
    ):
        """Frames computed a chunk at a time straight into this storage's dtype, or the file made before from
        ``key`` (on disk). A build that fails or is interrupted leaves no partial file behind.

        Parameters
        ----------
        name : str
        key
            Everything the frames are made of (anything with a stable ``repr``).
        n_frames, n_dims : int
        fill : callable
            ``fill(rows, out)`` writes frames ``rows`` (a slice of step 1) into ``out``, a writeable C-contiguous
            array of shape (rows.stop - rows.start, n_dims) and this storage's dtype.
        desc : str
            Label of a progress bar over the chunks (shown on a terminal only).

        Returns
        -------
        ndarray of shape (n_frames, n_dims) of this storage's dtype, read-only, or FramesOnDisk
        """
        found = self.existing(name, key)
        if found is not None and found.shape == (n_frames, n_dims):
            return found
        sink = self.sink(name, key, n_frames, n_dims)
        size = max(1, min(-(-n_frames // 20), sink.chunk_size))  # at least 20 chunks: a progress bar that moves
        try:
            for start in progress(range(0, n_frames, size), desc=desc):
                rows = slice(start, min(start + size, n_frames))
                sink.fill(rows, partial(fill, rows))
        except BaseException:
            sink.abort()
            raise
        return sink.finish()


class FrameSink:
    """Frames written chunk by chunk, in order, into an array in memory or a file (:class:`FrameStorage`)."""

    def __init__(self, *, array: np.ndarray | None = None, writer: FrameWriter | None = None):
        self.array, self.writer = array, writer
        self.shape = array.shape if array is not None else writer.shape

    @property
    def chunk_size(self) -> int:
        """Frames per chunk that keep a float64 chunk within :data:`workbench.numerics.frames.CHUNK_ENTRIES`."""
        return chunk_frames(self.shape[1])

    def abort(self) -> None:
        """Give up: drop the file being written (nothing to do in memory)."""
        if self.writer is not None:
            self.writer.abort()

    def fill(self, rows: slice, compute) -> None:
        """Frames ``rows`` (the next ones) computed straight into the sink's dtype: ``compute(out)`` fills ``out``,
        a C-contiguous array of shape (rows.stop - rows.start, n_dims) and the sink's dtype (the sink's own rows
        in memory, a buffer of one chunk written out after it for a file)."""
        if self.array is not None:
            compute(self.array[rows])
        else:
            out = np.empty((rows.stop - rows.start, self.shape[1]), dtype=self.writer.dtype)
            compute(out)
            self.writer.write(out)

    def finish(self):
        """The frames: a read-only array in memory, or :class:`FramesOnDisk`."""
        if self.array is not None:
            self.array.setflags(write=False)
            return self.array
        return self.writer.close()


def frame_storage(storage: str, dtype: str, cache_dir: str | None) -> FrameStorage:
    """Where the frames of ``dataset.storage`` (``memory`` or ``disk``) and ``dataset.dtype`` (checked with the
    settings) are kept: disk storage lives in ``cache_dir``."""
    if storage == "disk" and not cache_dir:
        raise WorkbenchError(
            "dataset.storage=disk keeps the frames in paths.cache_dir, which is not set: add paths.cache_dir=<folder>"
        )
    return FrameStorage(dtype=dtype, folder=str(Path(cache_dir) / FRAMES_FOLDER) if storage == "disk" else None)
