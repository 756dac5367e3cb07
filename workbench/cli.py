"""Command line: ``workbench [--config-name STUDY] [overrides...]`` (also ``python -m workbench``).

The Hydra entry point is thin: it hands the composed config to :func:`run`.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import hydra
import numpy as np
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
    result = run_study(plain)
    eigenfaces = result.eigenfaces
    table = alpha_table(result.rows, m=eigenfaces.n_components_, coverage=eigenfaces.coverage_,
                        paper_alpha=plain["paper"]["alpha"])
    text = (study_header(result, plain) + "\n" + markdown_table(table) + "\n"
            + headline(table, plain["metric"], plain["paper"]["alpha"]))

    output_dir = Path(output_dir)
    write_atomic(output_dir / "config.yaml", resolved_yaml)
    write_atomic(output_dir / "alpha_table.csv", table.to_csv(index=False))
    write_atomic(output_dir / "alpha_table.md", text)
    capture = result.capture
    metrics = {
        "study": plain["study"],
        "config_hash": config_hash(resolved_yaml),
        "dataset": {"name": capture.name, "units": capture.units, "origin": capture.origin,
                    "n_points": capture.n_points, "n_train_frames": len(capture.train),
                    "n_eval_frames": len(capture.eval), "frame_rate": capture.frame_rate,
                    "hand_names": list(capture.hand_names), "notes": list(capture.notes),
                    "provenance": capture.provenance},
        "pca": {"m": eigenfaces.n_components_, "coverage_reached": eigenfaces.coverage_,
                "method": eigenfaces.method_, "rank": int(eigenfaces.explained_variance_.size),
                "explained_variance_ratio": eigenfaces.explained_variance_ratio_[:60].tolist()},
        "quasi_eigen": {projection: {"empty_axes": [j + 1 for j in qe.empty_axes],
                                     "appended_axes": [j + 1 for j in qe.appended_axes],
                                     "axis_sums": qe.axis_sums.tolist(), "thresholds": qe.thresholds.tolist()}
                        for projection, qe in result.quasi_eigen.items()},
        "intuitiveness": intuitiveness_table(result),
        "rows": [dict(table.iloc[i].to_dict(), solver_iterations=row.n_iterations,
                      solver_fallback_frames=row.n_fallback_frames,
                      solver_max_kkt_violation=row.max_kkt_violation,
                      undefined_displacement_frames=row.alpha.n_undefined_displacement_frames)
                 for i, row in enumerate(result.rows)],
        "versions": versions(),
        "git": git_state(REPO_ROOT),
    }
    write_json(output_dir / "metrics.json", metrics)
    write_json(output_dir / "timings.json", dict(result.timings.seconds, total=time.time() - started))
    if plain.get("save_inputs", False):
        write_npz(output_dir / "inputs.npz", {
            "train": capture.train, "eval": capture.eval, "neutral": capture.neutral, "hand": capture.hand,
            "hand_names": np.array(capture.hand_names), "mean": eigenfaces.mean_,
            "components": eigenfaces.components_})
    write_atomic(output_dir / "done", "")
    return text


@hydra.main(version_base="1.3", config_path=str(STUDIES_DIR), config_name=DEFAULT_STUDY)
def _hydra_main(cfg: DictConfig) -> None:
    output_dir = Path(hydra.core.hydra_config.HydraConfig.get().runtime.output_dir)
    try:
        text = run(cfg, output_dir)
    except WorkbenchError as error:
        print(f"workbench: error: {error}", file=sys.stderr)
        sys.exit(2)
    print(text + f"\nrecord: {output_dir}")


def main() -> None:
    """Entry point of the ``workbench`` command."""
    try:
        check_config_dirs()
    except WorkbenchError as error:
        print(f"workbench: error: {error}", file=sys.stderr)
        sys.exit(2)
    sys.argv.append(searchpath_override())
    _hydra_main()
