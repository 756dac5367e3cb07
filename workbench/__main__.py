import os
import sys
from pathlib import Path

# `python -m workbench` puts the current folder first on sys.path (the `workbench` command does not). The folders a
# run makes there would then shadow modules imported later: a sweep folder named `coverage` hides the coverage
# package that numba imports when it loads. The workbench itself is imported by now; the current folder stays only
# when it is the checkout holding the package (where hydra_plugins is found through it).
try:
    here = os.getcwd()
except FileNotFoundError:  # the current folder was removed: main() says so in one line
    here = None
if (
    sys.path
    and sys.path[0] in ("", here)
    and (here is None or Path(here).resolve() != Path(__file__).resolve().parents[1])
):
    del sys.path[0]

from workbench.cli.main import main  # noqa: E402

main()
