"""The command line: the entry (:mod:`~workbench.cli.main`), the cluster launcher's glue
(:mod:`~workbench.cli.cluster`) and a sweep's failed runs (:mod:`~workbench.cli.sweep_failures`). Nothing is
imported here, so that ``workbench --help`` starts fast."""
