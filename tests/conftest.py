"""Shared fixtures: where the shared face data lives (``../shared/data`` or ``WORKBENCH_DATA_ROOT``)."""

import os
from pathlib import Path

import pytest

from workbench.config import REPO_ROOT


def shared_data_root() -> Path:
    """The data root the loader tests read: ``WORKBENCH_DATA_ROOT`` or ``<repo>/../shared/data``."""
    configured = os.environ.get("WORKBENCH_DATA_ROOT")
    return Path(configured).expanduser().resolve() if configured else (REPO_ROOT.parent / "shared" / "data").resolve()


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The shared face data folder; skipped when absent, failed when ``WORKBENCH_REQUIRE_DATA=1`` (as CI sets)."""
    root = shared_data_root()
    expected = ("ict-facekit/FaceXModel/generic_neutral_mesh.obj", "livelinkface/alex_rom_3.csv",
                "animface/animface_jaw.c3d")
    missing = [name for name in expected if not (root / name).is_file()]
    if missing:
        reason = (f"shared face data not found at {root} (missing {', '.join(missing)}); set WORKBENCH_DATA_ROOT "
                  "to the folder holding ict-facekit/, livelinkface/ and animface/")
        if os.environ.get("WORKBENCH_REQUIRE_DATA") == "1":
            pytest.fail(reason + " -- required because WORKBENCH_REQUIRE_DATA=1", pytrace=False)
        pytest.skip(reason)
    return root


@pytest.fixture(scope="session")
def chromium() -> str:
    """Path of a headless Chromium; skipped when absent, failed when ``WORKBENCH_REQUIRE_BROWSER=1`` (as CI sets,
    after installing Debian's ``chromium``)."""
    import shutil

    found = next((shutil.which(name) for name in ("chromium", "chromium-browser", "google-chrome")
                  if shutil.which(name)), None)
    if found is None:
        reason = "headless Chromium not found (install Debian's 'chromium' to check the report pages in a browser)"
        if os.environ.get("WORKBENCH_REQUIRE_BROWSER") == "1":
            pytest.fail(reason + " -- required because WORKBENCH_REQUIRE_BROWSER=1", pytrace=False)
        pytest.skip(reason)
    return found
