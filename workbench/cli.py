"""Command line: ``workbench [--config-name STUDY] [overrides...]`` (also ``python -m workbench``).

The Hydra entry point is thin: it hands the composed config to :func:`run`.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import hydra
import numpy as np
import pandas as pd
from omegaconf import DictConfig, OmegaConf

from workbench.config import DEFAULT_STUDY, REPO_ROOT, STUDIES_DIR, check_config_dirs, searchpath_override
from workbench.errors import WorkbenchError
from workbench.pipeline import intuitiveness_table, run_study
from workbench.record import (config_hash, git_state, versions, write_atomic, write_json, write_npz)
from workbench.report import alpha_table, headline, markdown_table, study_header


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


def run(cfg: DictConfig, output_dir: Path) -> str:
    """Run the study a config describes, write its record into ``output_dir`` and return the printed text.

    Parameters
    ----------
    cfg : omegaconf.DictConfig
        A composed study config (without or with its ``hydra`` node).
    output_dir : pathlib.Path

    Returns
    -------
    str
        The header and the Markdown alpha table.
    """
    started = time.time()
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
    rows = [result_row for result in results for result_row in result.rows]
    metrics = {
        "study": plain["study"],
        "config_hash": config_hash(resolved_yaml),
        "dataset": {"name": capture.name, "units": capture.units, "origin": capture.origin,
                    "frame_rate": capture.frame_rate, "hand_names": list(capture.hand_names),
                    "provenance": capture.provenance},
        "data": {result.data: data_metrics(result) for result in results},
        "rows": [dict(table.iloc[i].to_dict(), solver_iterations=row.n_iterations,
                      solver_fallback_frames=row.n_fallback_frames,
                      solver_max_kkt_violation=row.max_kkt_violation,
                      undefined_displacement_frames=row.alpha.n_undefined_displacement_frames)
                 for i, row in enumerate(rows)],
        "versions": versions(),
        "git": git_state(REPO_ROOT),
    }
    write_json(output_dir / "metrics.json", metrics)
    write_json(output_dir / "timings.json", dict(results[0].timings.seconds, total=time.time() - started))
    if plain.get("save_inputs", False):
        for result in results:
            name = "inputs.npz" if len(results) == 1 else f"inputs_{result.data}.npz"
            write_npz(output_dir / name, {
                "train": result.capture.train, "eval": result.capture.eval, "neutral": result.capture.neutral,
                "hand": result.capture.hand, "hand_names": np.array(result.capture.hand_names),
                "mean": result.eigenfaces.mean_, "components": result.eigenfaces.components_,
                **({"faces": result.capture.faces} if result.capture.faces is not None else {})})
    write_atomic(output_dir / "done", "")
    return text


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
    }


@hydra.main(version_base="1.3", config_path=str(STUDIES_DIR), config_name=DEFAULT_STUDY)
def _hydra_main(cfg: DictConfig) -> None:
    output_dir = Path(hydra.core.hydra_config.HydraConfig.get().runtime.output_dir)
    try:
        text = run(cfg, output_dir)
    except WorkbenchError as error:
        print(f"workbench: error: {error}", file=sys.stderr)
        sys.exit(2)
    print(text + f"\nrecord: {output_dir}")


# Subcommands other than running a study: name -> "module:function", the function taking the remaining
# arguments (a list of str) and returning an exit code. Imported only when used.
COMMANDS: dict[str, str] = {}


def main() -> None:
    """Entry point of the ``workbench`` command.

    ``workbench [--config-name STUDY] [overrides...]`` runs a study through Hydra; ``workbench <command> ...``
    runs one of :data:`COMMANDS`.
    """
    if len(sys.argv) > 1 and sys.argv[1] in COMMANDS:
        import importlib

        module, function = COMMANDS[sys.argv[1]].split(":")
        try:
            sys.exit(getattr(importlib.import_module(module), function)(sys.argv[2:]))
        except WorkbenchError as error:
            print(f"workbench {sys.argv[1]}: error: {error}", file=sys.stderr)
            sys.exit(2)
    try:
        check_config_dirs()
    except WorkbenchError as error:
        print(f"workbench: error: {error}", file=sys.stderr)
        sys.exit(2)
    sys.argv.append(searchpath_override())
    _hydra_main()
