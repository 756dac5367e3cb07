"""The record of a run: its folder and files (:mod:`~workbench.record.record`), run folders and logs of a sweep
(:mod:`~workbench.record.tracking`) and the MLflow store (:mod:`~workbench.record.mlflow`; choosing and opening the store:
:mod:`~workbench.record.mlflow_store`)."""
