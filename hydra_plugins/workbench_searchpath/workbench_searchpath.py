"""Puts the workbench's config groups (``conf/``) on Hydra's search path of every study.

Hydra finds plugins in the ``hydra_plugins`` namespace package, so the groups are found the same way by a run,
by tab completion, by ``--help`` and by :func:`workbench.config.compose`, with nothing added to the command line.
"""

from hydra.core.config_search_path import ConfigSearchPath
from hydra.plugins.search_path_plugin import SearchPathPlugin


class WorkbenchSearchPathPlugin(SearchPathPlugin):
    def manipulate_search_path(self, search_path: ConfigSearchPath) -> None:
        from workbench.config import CONF_DIR, STUDIES_DIR

        # Only for the workbench's own apps (its studies are the primary config folder): other Hydra apps in the
        # same environment are left alone.
        if any(element.path == f"file://{STUDIES_DIR}" or element.path == str(STUDIES_DIR)
               for element in search_path.get_path()):
            search_path.append(provider="workbench", path=f"file://{CONF_DIR}")
