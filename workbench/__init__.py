"""Research workbench for Kim & Ko's intuitive quasi-eigen faces.

Data flows one way: ``dataset`` -> ``bases`` -> ``solve`` -> ``metrics`` -> ``record`` -> ``report``.
The numerical core (``bases``, ``solve``, ``metrics``) is pure: arrays in, arrays and frozen dataclasses out.
"""

import os

from workbench.interrupt import exit_at_once_while_starting, started_as_command

if started_as_command():  # first, before the seconds of imports: Ctrl-C then is one line, not a traceback
    exit_at_once_while_starting()

# OpenBLAS's worker threads spin for about 2**28 cycles (~0.1 s) after every threaded call before they sleep.
# The compiled per-frame solvers run their own threads right after such a call (the projection of the frames),
# and the spinning workers halved their speed on a 2-core machine. 2**16 cycles keeps a short spin for
# back-to-back BLAS calls. It only takes effect when set before NumPy loads OpenBLAS; a value the user set wins.
os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "16")

from workbench.version import __version__  # noqa: E402 - after the environment is set
