"""A record run again and checked against itself: the study rerun from the record's resolved config, refused when
the data files it reads or the alpha table it gives are not the record's. The export and the report share it."""

from __future__ import annotations

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.record.record import RunRecord
from workbench.study.table import ALPHA_COLUMNS, alpha_table

TABLE_CHECK_RTOL = 1e-6
"""A replayed alpha must equal the recorded one to this relative tolerance (the pipeline is deterministic; what
is left is BLAS's order of summation)."""
TABLE_CHECK_ATOL = 1e-12
"""...and to this absolute one, for an alpha of (nearly) zero."""
ROW_KEYS = ("basis", "projection", "solver")


def replay(record: RunRecord, consequence: str) -> list:
    """Run the record's study again from its resolved config, and check the results against the record.

    Parameters
    ----------
    record : RunRecord
        A complete run record (:func:`workbench.record.record.load_record`).
    consequence : str
        What the caller cannot do when the check fails, ending the refusal (``"rerun the study and export the new
        record"``).

    Returns
    -------
    list of StudyResult
        As :func:`workbench.study.run.run_study` returns them.

    Raises
    ------
    WorkbenchError
        One line naming the record, from :func:`check_replayed`; or the study's own refusal (data not found).
    """
    from workbench.study.run import run_study

    results = run_study(record.settings)
    check_replayed(record, results, consequence)
    return results


def check_replayed(record: RunRecord, results, consequence: str) -> None:
    """Refuse results rerun from a record that are not the record's: a data file whose SHA-256 is not the one the
    record names, a data variant whose rows (basis, projection, solver) differ, or an alpha column
    (:data:`~workbench.study.table.ALPHA_COLUMNS`) that differs by more than :data:`TABLE_CHECK_RTOL`."""
    recorded_files = record.metrics["dataset"]["provenance"].get("data_files") or {}
    found_files = (results[0].capture.provenance.get("data_files") or {}) if results else {}
    for path, entry in recorded_files.items():
        if (found_files.get(path) or {}).get("sha256") != entry.get("sha256"):
            raise WorkbenchError(
                f"run record {record.folder}: its data file {path} is not the one the run read (its SHA-256 "
                f"differs from the record's); {consequence}"
            )
    for result in results:
        fresh = alpha_table(
            result.rows,
            data=result.data,
            m=result.eigenfaces.n_components_,
            coverage=result.eigenfaces.coverage_,
            paper_alpha={},
        )
        own = record.table[record.table["data"] == result.data].reset_index(drop=True)
        keys = list(ROW_KEYS)
        if len(own) != len(fresh) or not (own[keys].astype(str) == fresh[keys].astype(str)).all().all():
            raise WorkbenchError(
                f"run record {record.folder}: the rerun's alpha table of data '{result.data}' has other rows than "
                f"the recorded one; {consequence}"
            )
        columns = [column for column in ALPHA_COLUMNS if column in own.columns]
        a, b = own[columns].to_numpy(float), fresh[columns].to_numpy(float)
        if not np.allclose(a, b, rtol=TABLE_CHECK_RTOL, atol=TABLE_CHECK_ATOL, equal_nan=True):
            worst = np.nanmax(np.abs(a - b) / np.maximum(np.abs(a), 1e-300))
            raise WorkbenchError(
                f"run record {record.folder}: recomputing the run gives alpha {worst:.2e} (relative) away from the "
                f"recorded table for data '{result.data}' (allowed {TABLE_CHECK_RTOL:g}): the data or the code "
                f"changed since the run; {consequence}"
            )
