"""The report side: the tidy runs table (runs), ``workbench collect``, ``workbench report`` (pages) and figures."""
