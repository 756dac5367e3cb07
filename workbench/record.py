"""Run records: every file written atomically (temporary file, then rename), the ``done`` marker last."""

from __future__ import annotations

import hashlib
import io
import json
import os
import platform
import subprocess
import sys
import tempfile
from importlib import metadata
from pathlib import Path
from typing import Mapping

import numpy as np

RECORD_PACKAGES = ("numpy", "scipy", "pandas", "matplotlib", "hydra-core", "omegaconf", "fast-simplification",
                   "scikit-learn")
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
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = data.encode() if isinstance(data, str) else data
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=TEMPORARY_SUFFIX)
    try:
        os.fchmod(handle, FILE_MODE)
        with os.fdopen(handle, "wb") as stream:
            stream.write(payload)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def write_json(path: Path, value) -> None:
    write_atomic(path, json.dumps(value, indent=2, sort_keys=False, allow_nan=True) + "\n")


def write_npz(path: Path, arrays: Mapping[str, np.ndarray]) -> None:
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)
    write_atomic(path, buffer.getvalue())


def config_hash(resolved_yaml: str) -> str:
    """Short content hash of a resolved config: the same settings give the same hash."""
    return hashlib.sha256(resolved_yaml.encode()).hexdigest()[:16]


def git_state(repository: Path) -> dict:
    """Commit of the workbench's checkout and whether its tree had uncommitted changes."""
    def git(*args):
        return subprocess.run(["git", "-C", str(repository), *args], capture_output=True, text=True, timeout=10)
    try:
        commit = git("rev-parse", "HEAD")
        status = git("status", "--porcelain", "--untracked-files=no")
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "dirty": None}
    if commit.returncode != 0:
        return {"commit": None, "dirty": None}
    return {"commit": commit.stdout.strip(), "dirty": bool(status.stdout.strip())}


def versions() -> dict:
    """Python, platform and the versions of the packages that decide the numbers."""
    found = {"python": sys.version.split()[0], "platform": platform.platform()}
    for package in RECORD_PACKAGES:
        try:
            found[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            found[package] = None
    return found
