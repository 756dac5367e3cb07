"""The settings: where the configs live and how a study is composed (:mod:`~workbench.settings.config`), the typed
schema of every setting (:mod:`~workbench.settings.schema`) and the rules its fields share
(:mod:`~workbench.settings.rules`)."""
