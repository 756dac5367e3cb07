"""Command line: ``workbench [--config-name STUDY] [overrides...]`` (also ``python -m workbench``).

The Hydra entry point is thin: it hands the composed config to :func:`run`.
"""

from __future__ import annotations

import os
import sys
import time
import traceback
from datetime import datetime, timezone
from pathlib import Path
from typing import Sequence

import hydra
import numpy as np
import pandas as pd
from omegaconf import DictConfig, OmegaConf

from workbench.config import DEFAULT_STUDY, REPO_ROOT, STUDIES_DIR, check_config_dirs, searchpath_override
from workbench.errors import WorkbenchError
from workbench.pipeline import intuitiveness_table, run_study
from workbench.record import (config_hash, git_state, versions, write_atomic, write_json, write_npz)
from workbench.report import alpha_table, headline, markdown_table, study_header
from workbench.tracking import DONE, prepare_run_dir, record_state, register_resolvers

register_resolvers()


def resolved_without_hydra(cfg: DictConfig) -> dict:
    """The config as plain, resolved containers, leaving out Hydra's own node (its sweep keys exist only
    inside a running multirun, so resolving them outside one would fail)."""
    plain = {}
    for key in cfg:
        if key == "hydra":
            continue
        node = cfg[key]
        plain[key] = OmegaConf.to_container(node, resolve=True) if OmegaConf.is_config(node) else node
    return plain


def resolved_yaml_text(cfg: DictConfig) -> str:
    """The resolved config (without Hydra's node) as YAML: what ``config.yaml`` holds and the config hash hashes."""
    return OmegaConf.to_yaml(OmegaConf.create(resolved_without_hydra(cfg)))


def run(cfg: DictConfig, output_dir: Path, overrides: Sequence[str] = (), job_num: int | None = None) -> str:
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

    Returns
    -------
    str
        The header and the Markdown alpha table.
    """
    started = time.time()
    started_at = datetime.now(timezone.utc).isoformat(timespec="seconds")
    if record_state(output_dir) == "complete":
        raise WorkbenchError(f"{output_dir} already holds a complete record ('{DONE}' exists); records are never "
                             "overwritten: write the run elsewhere")
    plain = resolved_without_hydra(cfg)
    resolved_yaml = OmegaConf.to_yaml(OmegaConf.create(plain))
    results = run_study(plain)
    paper_alpha = plain["paper"]["alpha"]
    table = pd.concat([alpha_table(result.rows, data=result.data, m=result.eigenfaces.n_components_,
                                   coverage=result.eigenfaces.coverage_, paper_alpha=paper_alpha)
                       for result in results], ignore_index=True)
    text = (study_header(results, plain) + "\n" + markdown_table(table) + "\n"
            + headline(table, plain["metric"], paper_alpha))

    output_dir = Path(output_dir)
    write_atomic(output_dir / "config.yaml", resolved_yaml)
    write_atomic(output_dir / "alpha_table.csv", table.to_csv(index=False))
    write_atomic(output_dir / "alpha_table.md", text)
    capture = results[0].capture
    rows = [(result, result_row) for result in results for result_row in result.rows]
    metrics = {
        "study": plain["study"],
        "config_hash": config_hash(resolved_yaml),
        "overrides": list(overrides),
        "job_num": job_num,
        "dataset": {"name": capture.name, "units": capture.units, "origin": capture.origin,
                    "frame_rate": capture.frame_rate, "hand_names": list(capture.hand_names),
                    "provenance": capture.provenance},
        "data": {result.data: data_metrics(result) for result in results},
        "rows": [dict(table.iloc[i].to_dict(), train_on=result.train_on or result.data,
                      eval_on=result.eval_on or result.data, solver_iterations=row.n_iterations,
                      solver_fallback_frames=row.n_fallback_frames,
                      solver_max_kkt_violation=row.max_kkt_violation,
                      max_abs_weight=row.max_abs_weight,
                      basis_conditioning=row.conditioning.as_dict() if row.conditioning else None,
                      undefined_displacement_frames=row.alpha.n_undefined_displacement_frames)
                 for i, (result, row) in enumerate(rows)],
        "versions": versions(),
        "git": git_state(REPO_ROOT),
        "started_at": started_at,
        "finished_at": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
    write_json(output_dir / "metrics.json", metrics)
    write_json(output_dir / "timings.json", dict(results[0].timings.seconds, total=time.time() - started))
    if plain.get("save_inputs", False):
        # bases carried onto other points (dataset.eval_on) live in two point sets: no single inputs file
        for result in [result for result in results if result.transfer == "identity"]:
            name = "inputs.npz" if len(results) == 1 else f"inputs_{result.data.replace('->', '_to_')}.npz"
            write_npz(output_dir / name, {
                "train": result.capture.train, "eval": result.capture.eval, "neutral": result.capture.neutral,
                "hand": result.capture.hand, "hand_names": np.array(result.capture.hand_names),
                "mean": result.eigenfaces.mean_, "components": result.eigenfaces.components_,
                **({"faces": result.capture.faces} if result.capture.faces is not None else {}),
                **({"eval_visible": result.capture.eval_visible} if result.capture.eval_visible is not None
                   else {})})
        write_npz(output_dir / "alpha_per_frame.npz", alpha_per_frame_arrays(results))
    write_atomic(output_dir / "done", "")
    return text


def alpha_per_frame_arrays(results) -> dict:
    """Per-frame alpha of every table row, for plots over time: ``<data>.absolute`` and ``<data>.displacement``
    of shape (n_rows, n_eval_frames), and ``<data>.basis`` / ``<data>.solver`` naming the rows in table order."""
    arrays = {}
    for result in results:
        arrays[f"{result.data}.basis"] = np.array([row.basis for row in result.rows])
        arrays[f"{result.data}.solver"] = np.array([row.solver for row in result.rows])
        arrays[f"{result.data}.absolute"] = np.array([row.alpha.absolute_per_frame for row in result.rows])
        arrays[f"{result.data}.displacement"] = np.array([row.alpha.displacement_per_frame for row in result.rows])
    return arrays


def data_metrics(result) -> dict:
    """The part of ``metrics.json`` about one data variant: frames, points, spectrum, empty axes, intuitiveness."""
    capture, eigenfaces = result.capture, result.eigenfaces
    return {
        "n_points": capture.n_points, "n_train_frames": len(capture.train), "n_eval_frames": len(capture.eval),
        "notes": list(capture.notes),
        "pca": {"m": eigenfaces.n_components_, "coverage_reached": eigenfaces.coverage_,
                "method": eigenfaces.method_, "rank": int(eigenfaces.explained_variance_.size),
                "explained_variance_ratio": eigenfaces.explained_variance_ratio_[:60].tolist()},
        "quasi_eigen": {projection: {"empty_axes": [j + 1 for j in qe.empty_axes],
                                     "appended_axes": [j + 1 for j in qe.appended_axes],
                                     "axis_sums": qe.axis_sums.tolist(), "thresholds": qe.thresholds.tolist()}
                        for projection, qe in result.quasi_eigen.items()},
        "intuitiveness": intuitiveness_table(result),
        **({"basis_intuitiveness": result.basis_intuitiveness} if result.basis_intuitiveness else {}),
    }


@hydra.main(version_base="1.3", config_path=str(STUDIES_DIR), config_name=DEFAULT_STUDY)
def _hydra_main(cfg: DictConfig) -> None:
    from hydra.types import RunMode

    hydra_cfg = hydra.core.hydra_config.HydraConfig.get()
    output_dir = Path(hydra_cfg.runtime.output_dir)
    try:
        hash_of_config = config_hash(resolved_yaml_text(cfg))
        if not prepare_run_dir(output_dir, hash_of_config):
            print(f"skip {output_dir}: complete record (config hash {hash_of_config})")
            return
        multirun = hydra_cfg.mode == RunMode.MULTIRUN
        text = run(cfg, output_dir, overrides=list(hydra_cfg.overrides.task),
                   job_num=int(hydra_cfg.job.num) if multirun else None)
    except Exception as error:  # noqa: BLE001 - one line for any failure; --verbose shows the traceback
        exit_on_error("workbench", error)
    if multirun:
        print(f"done {output_dir}: {first_headline(text)}")
    else:
        print(text + f"\nrecord: {output_dir}")


def first_headline(text: str) -> str:
    """The first line after the alpha table of a run's printed text (its headline), for a sweep's one-line log."""
    lines = text.splitlines()
    last_table_line = max((i for i, line in enumerate(lines) if line.startswith("|")), default=-1)
    return next((line for line in lines[last_table_line + 1:] if line.strip()), "")


# Subcommands other than running a study: name -> "module:function", the function taking the remaining
# arguments (a list of str) and returning an exit code. Imported only when used.
COMMANDS: dict[str, str] = {
    "report": "workbench.reporting:main",
    "collect": "workbench.collect:main",
}


VERBOSE_FLAG = "--verbose"
_verbose = False


def exit_on_error(program: str, error: BaseException) -> None:
    """Print one line for ``error`` (the traceback too with ``--verbose``) and exit non-zero.

    A :class:`WorkbenchError` is bad input or configuration (exit 2); anything else is unexpected (exit 3) and
    names its type, since its message alone may not say where it came from.
    """
    if isinstance(error, SystemExit):
        raise error
    if _verbose:
        traceback.print_exception(error, file=sys.stderr)
    if isinstance(error, WorkbenchError):
        print(f"{program}: error: {error}", file=sys.stderr)
        sys.exit(2)
    hint = "" if _verbose else f" (run with {VERBOSE_FLAG} for the traceback)"
    print(f"{program}: error: unexpected {type(error).__name__}: {error}{hint}", file=sys.stderr)
    sys.exit(3)


def main() -> None:
    """Entry point of the ``workbench`` command.

    ``workbench [--config-name STUDY] [overrides...]`` runs a study through Hydra; ``workbench <command> ...``
    runs one of :data:`COMMANDS`. ``--verbose`` anywhere adds the traceback to an error's one line (Hydra's own
    errors: set ``HYDRA_FULL_ERROR=1``).
    """
    global _verbose
    if VERBOSE_FLAG in sys.argv[1:]:
        _verbose = True
        sys.argv = [arg for arg in sys.argv if arg != VERBOSE_FLAG]
    if len(sys.argv) > 1 and sys.argv[1] in COMMANDS:
        import importlib

        module, function = COMMANDS[sys.argv[1]].split(":")
        try:
            code = getattr(importlib.import_module(module), function)(sys.argv[2:])
        except Exception as error:  # noqa: BLE001
            exit_on_error(f"workbench {sys.argv[1]}", error)
        sys.exit(code)
    try:
        check_config_dirs()
    except Exception as error:  # noqa: BLE001
        exit_on_error("workbench", error)
    sys.argv.append(searchpath_override())
    # Hydra reports a bad override or config choice in several lines of its own; let it raise instead, and print
    # one line (unless the user asked for Hydra's full error or --verbose).
    full_error = os.environ.get("HYDRA_FULL_ERROR") == "1"
    os.environ["HYDRA_FULL_ERROR"] = "1"
    try:
        _hydra_main()
    except Exception as error:  # noqa: BLE001 - errors of the job itself never get here (run_job catches them)
        if full_error or _verbose:
            raise
        print(f"workbench: error: {one_line(error)}", file=sys.stderr)
        sys.exit(2)


def one_line(error: BaseException) -> str:
    """Hydra's multi-line message of a config error (and its cause's) as one line: lists such as the available
    options of a config group are joined, the config search path is left out."""
    text = str(error)
    if error.__cause__ is not None and str(error.__cause__) not in text:
        text += "\n" + str(error.__cause__)
    parts = []
    for line in text.split("Config search path:")[0].splitlines():
        if not line.strip() or line.strip().startswith(("full_key:", "object_type=", "Set the environment variable")):
            continue
        if line.startswith(("\t", "    ")) and parts and parts[-1].endswith((":", ",")):
            parts[-1] += (" " if parts[-1].endswith(":") else " ") + line.strip() + ","
        else:
            parts.append(line.strip())
    return "; ".join(part.rstrip(",.") for part in parts)
