"""The public Python API beside the estimator: the file readers, the captures of a dataset config, a study run from
Python and the run records it writes. ``import workbench`` re-exports these names (lazily: nothing here is
imported until a name is used).

Every function hands over to the module that does the work, imported when it is called, so that the names keep
working wherever that module lives; each says where in its docstring.
"""

from __future__ import annotations

import os
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Mapping, Sequence

from workbench.core.errors import WorkbenchError
from workbench.settings.config import CHECKOUT, resolved_without_hydra, resolved_yaml_text

if TYPE_CHECKING:
    from omegaconf import DictConfig

    from workbench.dataset.capture import Capture
    from workbench.record.record import RunRecord
    from workbench.study.results import StudyResult


# ---------------------------------------------------------------------------------------------------------------
# Readers
# ---------------------------------------------------------------------------------------------------------------


def __getattr__(name: str):
    """The readers of :data:`workbench.formats.registry.FORMATS` under their public names (``read_c3d``, ...),
    each the reader itself with its own docstring; the formats are imported when one is first asked for."""
    from workbench.formats.registry import FORMATS

    for entry in FORMATS.values():
        if entry.public_name == name:
            globals()[name] = entry.read  # later uses skip this function
            return entry.read
    raise AttributeError(f"module 'workbench.api' has no attribute {name!r}")


# ---------------------------------------------------------------------------------------------------------------
# Configs, captures, runs and records
# ---------------------------------------------------------------------------------------------------------------


def compose_config(study: str = "paper", overrides: Sequence[str] = ()) -> "DictConfig":
    """A study's config composed as the command line composes it, without running it (:func:`workbench.settings.config.compose`).

    Parameters
    ----------
    study : str, default "paper"
        A study of ``studies/`` (``workbench --config-name STUDY``).
    overrides : sequence of str
        The command line's overrides, e.g. ``["dataset=ict_livelink", "dataset.frame_step=20"]`` (a single string
        is refused, not read as its letters).

    Returns
    -------
    omegaconf.DictConfig

    Raises
    ------
    WorkbenchError
        In one line, with the command line's words: an unknown study, an override that is not a string, cannot be
        parsed, names an unknown key or option, a retired setting or a value of the wrong type.
    """
    from workbench.settings.config import compose

    return compose(study, overrides)


def _study_config(config) -> "DictConfig":
    """``config`` as a DictConfig: a composed one as it is, a mapping (a record's resolved ``config``) wrapped."""
    from omegaconf import DictConfig, OmegaConf

    if isinstance(config, DictConfig):
        return config
    if isinstance(config, Mapping):
        return OmegaConf.create(dict(config))
    raise WorkbenchError(
        f"config must be a composed study config (compose_config) or a mapping of one, got {type(config).__name__}"
    )


def build_captures(config, *, cache_dir: str | None = None) -> dict[str, "Capture"]:
    """The captures a dataset config describes, one per ``dataset.train_on`` variant
    (:func:`workbench.dataset.build_captures`).

    Parameters
    ----------
    config : DictConfig or mapping
        A composed study config (its ``dataset`` group is used, and its ``paths.cache_dir`` unless ``cache_dir``
        is given) or the ``dataset`` group itself.
    cache_dir : str, optional
        Folder of the disk cache of built datasets; memory only when None.

    Returns
    -------
    dict
        Variant name (``markers``, ``mesh``, ...) -> ``Capture``: ``neutral`` of shape (3 * n_points,), ``train``
        and ``eval`` frames of shape (n_frames, 3 * n_points) as displacements from neutral, ``hand`` of shape
        (n_shapes, 3 * n_points) and ``hand_names``: the arrays :class:`QuasiEigenFaces` fits on.
    """
    from omegaconf import OmegaConf

    from workbench.dataset import build_captures as build

    if not isinstance(config, Mapping) and not OmegaConf.is_config(config):
        raise WorkbenchError(f"config must be a study config or its dataset group, got {type(config).__name__}")
    if "dataset" in config:
        paths = config.get("paths") or {}
        cache_dir = paths.get("cache_dir") if cache_dir is None else cache_dir
        config = config["dataset"]
    from workbench.settings.typed import dataset_settings

    plain = OmegaConf.to_container(config, resolve=True) if OmegaConf.is_config(config) else dict(config)
    return build(dataset_settings(plain, check=True), cache_dir=cache_dir)


def run_study(config) -> list["StudyResult"]:
    """Run a study in memory, as the command line runs it, and return its results (nothing is written).

    Parameters
    ----------
    config : DictConfig or mapping
        A composed study config (:func:`compose_config`), or the resolved config of a record
        (``read_record(folder).config``). Checked as the command line checks it.

    Returns
    -------
    list of workbench.study.results.StudyResult
        One per data variant: its ``capture``, ``eigenfaces``, ``quasi_eigen`` bases, ``rows`` (the alpha table's
        rows: basis, solver and every alpha variant in ``row.alpha``) and ``weights``.
    """
    from workbench.settings.typed import study_settings
    from workbench.study.run import run_study as run

    return run(study_settings(_study_config(config)))


def record_study(config, output_dir: str | os.PathLike, *, overrides: Sequence[str] = ()) -> "RunRecord":
    """Run a study as the command line runs it and write its run record into ``output_dir`` (the command's
    ``hydra.run.dir``); returns the record read back.

    A folder holding a complete record of the same config is not run again (its record is returned), one holding
    anything else that is not a record of the workbench's is refused, and a run that fails removes what it wrote and the folders it made.

    Parameters
    ----------
    config : DictConfig or mapping
        As :func:`run_study`.
    output_dir : path-like
        Not empty, nor the current folder or one above it.
    overrides : sequence of str
        The overrides that made ``config``, kept in the record (``metrics.json``'s ``overrides``); a single string
        is refused, not read as its letters.

    Returns
    -------
    workbench.record.record.RunRecord
    """
    from workbench.core.files import check_folder_setting
    from workbench.record.tracking import note_new_run_dir
    from workbench.settings.config import override_list

    config = _study_config(config)
    output_dir = check_folder_setting(output_dir, "output_dir")
    overrides = override_list(overrides, "overrides")
    note_new_run_dir(Path(output_dir))  # a failed run removes the folder (and parents) it made
    run_owned(config, Path(output_dir), overrides=overrides, job_num=None, plain=True)
    return read_record(output_dir)


def read_record(folder: str | os.PathLike, *, check_archives: bool = False) -> "RunRecord":
    """A complete run record, every file checked against the checksums the run wrote
    (:func:`workbench.record.record.load_record`).

    Parameters
    ----------
    folder : path-like
        A run folder (holding ``done``).
    check_archives : bool, default False
        Check the ``.npz`` archives now too (otherwise each is checked when read).

    Returns
    -------
    workbench.record.record.RunRecord
        ``config`` (the resolved config), ``table`` (the alpha table, a DataFrame), ``metrics``
        (``metrics.json``: its ``rows`` hold every alpha variant of every basis and solver) and ``timings``.
    """
    from workbench.record.record import load_record

    if not isinstance(folder, (str, os.PathLike)) or not str(folder).strip():
        raise WorkbenchError(f"folder must be the path of a run record, got {folder!r}")
    return load_record(Path(folder), check_archives=check_archives)


def run(
    cfg: DictConfig,
    output_dir: Path,
    overrides: Sequence[str] = (),
    job_num: int | None = None,
    *,
    wide: bool = True,
) -> str:
    """Run the study a config describes, write its record into ``output_dir`` and return the printed text.

    Parameters
    ----------
    cfg : omegaconf.DictConfig
        A composed study config (without or with its ``hydra`` node).
    output_dir : pathlib.Path
        Must not hold a complete record (one with ``done``): records are never overwritten.
    overrides : sequence of str
        The command-line and sweep overrides that made ``cfg``, kept in the record.
    job_num : int, optional
        The run's position in its sweep (Hydra's job number), kept so that tables list runs in sweep order.
    wide : bool, default True
        Return the full text, as the record's ``alpha_table.md`` holds it (``workbench --wide``); False: the text
        the command prints by default, within 120 columns
        (:data:`workbench.reporting.run_text.PRINT_WIDTH`).

    Returns
    -------
    str
        One sentence on what was reproduced, the header, the Markdown alpha table and the headline.
    """
    import pandas as pd
    from omegaconf import OmegaConf

    from workbench.record.record import DONE, record_state, run_metrics, write_record
    from workbench.reporting.run_text import (
        compact_tables,
        fit_width,
        headline,
        printed_tables,
        reproduced_sentence,
        result_identities,
        study_header,
    )
    from workbench.study.run import run_study
    from workbench.study.summary import (
        alpha_per_frame_arrays,
        frame_comparisons,
        results_metrics,
        saved_inputs,
    )
    from workbench.study.table import alpha_table

    started = time.time()
    started_at = datetime.now(timezone.utc).isoformat(timespec="seconds")
    if record_state(output_dir) == "complete":
        raise WorkbenchError(
            f"{output_dir} already holds a complete record ('{DONE}' exists); records are never "
            "overwritten: write the run elsewhere"
        )
    from workbench.settings.typed import study_settings

    settings = study_settings(cfg)  # checked once, before the run
    plain = resolved_without_hydra(cfg)
    resolved_yaml = OmegaConf.to_yaml(OmegaConf.create(plain))
    results = run_study(settings)
    paper_alpha = plain["paper"]["alpha"]
    table = pd.concat(
        [
            alpha_table(
                result.rows,
                data=result.data,
                m=result.eigenfaces.n_components_,
                coverage=result.eigenfaces.coverage_,
                paper_alpha=paper_alpha,
            )
            for result in results
        ],
        ignore_index=True,
    )
    with results[0].timings.stage("comparisons"):
        comparisons = {result.data: frame_comparisons(result, plain["metric"]) for result in results}
    sentence = reproduced_sentence(results, plain, comparisons)
    opening = fit_width(sentence) + "\n" if sentence else ""
    header = study_header(results, plain)
    closing = headline(table, plain["metric"], paper_alpha, comparisons, result_identities(results))
    text = opening + header + "\n" + printed_tables(table) + "\n" + closing

    metrics = run_metrics(
        results_metrics(results, table, comparisons),
        study=plain["study"],
        resolved_yaml=resolved_yaml,
        overrides=overrides,
        job_num=job_num,
        started_at=started_at,
        repository=CHECKOUT,
    )
    write_record(
        Path(output_dir),
        resolved_yaml=resolved_yaml,
        table=table,
        text=text,
        metrics=metrics,
        timings=dict(results[0].timings.seconds, total=time.time() - started),
        inputs=saved_inputs(results) if settings.save_inputs else None,
        alpha_per_frame=alpha_per_frame_arrays(results) if settings.save_inputs else None,
    )
    return text if wide else fit_width(opening + header + "\n" + compact_tables(table) + "\n" + closing)


def run_owned(
    cfg: DictConfig,
    output_dir: Path,
    *,
    overrides: Sequence[str],
    job_num: int | None,
    plain: bool,
    wide: bool = True,
) -> str | None:
    """:func:`run` while holding the run folder's lock: the text it printed, or None when the folder already
    holds a complete record of the same config. A folder that is not the workbench's is refused before anything
    is written into it (:func:`workbench.record.tracking.check_run_dir`). A plain run (``plain``) that fails or is
    interrupted removes what it wrote, and its folder and the parents it made for it if it made them (a sweep's run
    keeps its partial record: its rerun clears and redoes the run). A complete record keeps no lock file;
    ``wide`` as :func:`run`."""
    from workbench.record.record import config_hash
    from workbench.record.tracking import (
        check_run_dir,
        created_by_this_run,
        discard_failed_run,
        lock_run_dir,
        prepare_run_dir,
        release_run_dir,
        remove_made_folders,
    )

    found = check_run_dir(output_dir, "hydra.sweep.dir" if not plain else "hydra.run.dir")
    lock = lock_run_dir(output_dir)
    try:
        if not prepare_run_dir(output_dir, config_hash(resolved_yaml_text(cfg))):
            return None
        return run(cfg, output_dir, overrides=overrides, job_num=job_num, wide=wide)
    except BaseException:
        if plain and discard_failed_run(output_dir, found, created_by_this_run(output_dir)):
            remove_made_folders(output_dir)
        raise
    finally:
        release_run_dir(output_dir, lock)
