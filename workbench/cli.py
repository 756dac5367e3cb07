"""Command line: ``workbench [--config-name STUDY] [overrides...]`` (also ``python -m workbench``).

The Hydra entry point is thin: it hands the composed config to :func:`run`.
"""

from __future__ import annotations

import logging
import os
import re
import sys
import time
import traceback
from contextlib import contextmanager
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

# Only what every command needs is imported here: `--help`, `--version` and tab completion must start fast, so
# Hydra, pandas and the numerical code are imported by the functions that use them.
from workbench.config import CHECKOUT, CONF_DIR, DEFAULT_STUDY, STUDIES_DIR, check_config_dirs
from workbench.errors import WorkbenchError, single_line
from workbench.extras import missing_extra
from workbench.interrupt import INTERRUPTED, MESSAGE as INTERRUPTED_MESSAGE, caused_by_interrupt, raise_from_now_on

if TYPE_CHECKING:
    from omegaconf import DictConfig

log = logging.getLogger("workbench")


def resolved_without_hydra(cfg: DictConfig) -> dict:
    """The config as plain, resolved containers, leaving out Hydra's own node (its sweep keys exist only
    inside a running multirun, so resolving them outside one would fail)."""
    from omegaconf import OmegaConf

    plain = {}
    for key in cfg:
        if key == "hydra":
            continue
        node = cfg[key]
        plain[key] = OmegaConf.to_container(node, resolve=True) if OmegaConf.is_config(node) else node
    return plain


def resolved_yaml_text(cfg: DictConfig) -> str:
    """The resolved config (without Hydra's node) as YAML: what ``config.yaml`` holds and the config hash hashes."""
    from omegaconf import OmegaConf

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
    import pandas as pd
    from omegaconf import OmegaConf

    from workbench.dataset.real import bool_setting
    from workbench.pipeline import run_study
    from workbench.record import DONE, frame_comparisons, record_state, run_metrics, write_record
    from workbench.run_text import alpha_table, headline, printed_tables, result_identities, study_header

    started = time.time()
    started_at = datetime.now(timezone.utc).isoformat(timespec="seconds")
    if record_state(output_dir) == "complete":
        raise WorkbenchError(f"{output_dir} already holds a complete record ('{DONE}' exists); records are never "
                             "overwritten: write the run elsewhere")
    from workbench.schema import check_study_config

    check_study_config(cfg)
    plain = resolved_without_hydra(cfg)
    save_inputs = bool_setting(plain.get("save_inputs", False), "save_inputs")  # checked before the run, not after
    resolved_yaml = OmegaConf.to_yaml(OmegaConf.create(plain))
    results = run_study(plain)
    paper_alpha = plain["paper"]["alpha"]
    table = pd.concat([alpha_table(result.rows, data=result.data, m=result.eigenfaces.n_components_,
                                   coverage=result.eigenfaces.coverage_, paper_alpha=paper_alpha)
                       for result in results], ignore_index=True)
    with results[0].timings.stage("comparisons"):
        comparisons = {result.data: frame_comparisons(result, plain["metric"]) for result in results}
    text = (study_header(results, plain) + "\n" + printed_tables(table) + "\n"
            + headline(table, plain["metric"], paper_alpha, comparisons, result_identities(results)))

    metrics = run_metrics(results, table, study=plain["study"], resolved_yaml=resolved_yaml, overrides=overrides,
                          job_num=job_num, started_at=started_at, repository=CHECKOUT, comparisons=comparisons)
    write_record(Path(output_dir), resolved_yaml=resolved_yaml, table=table, text=text, metrics=metrics,
                 timings=dict(results[0].timings.seconds, total=time.time() - started), results=results,
                 save_inputs=save_inputs)
    return text


def hydra_app() -> None:
    """The Hydra application: compose the study from the command line and run :func:`_hydra_main` on it (or print
    the help, the config or completions). Hydra is imported here, not with the module, to keep start-up fast."""
    import hydra

    register_cli_resolvers()
    hydra.main(version_base="1.3", config_path=str(STUDIES_DIR), config_name=DEFAULT_STUDY)(_hydra_main)()


def print_help(argv: Sequence[str]) -> bool:
    """``workbench [--config-name STUDY] [overrides] --help``: Hydra's application help, rendered from the study's
    ``hydra.help`` template as Hydra renders it, but with the config groups read from ``conf/`` in one pass (Hydra
    copies its whole config store for each of the 70-odd lookups it makes, most of the help's time). Returns False,
    leaving the help to Hydra, when the command line adds config folders of its own."""
    import string

    from hydra import compose, initialize_config_dir
    from hydra._internal.utils import get_args_parser
    from omegaconf import OmegaConf, open_dict

    args = get_args_parser().parse_args(argv)
    if args.config_dir or args.config_path:
        return False
    register_cli_resolvers()
    with initialize_config_dir(config_dir=str(STUDIES_DIR), version_base="1.3"):
        cfg = compose(config_name=args.config_name or DEFAULT_STUDY, overrides=args.overrides,
                      return_hydra_config=True)
    template = cfg.hydra.help.template
    with open_dict(cfg):
        del cfg["hydra"]
    print(string.Template(template).safe_substitute(APP_CONFIG_GROUPS=config_groups_text(),
                                                    CONFIG=OmegaConf.to_yaml(cfg, resolve=args.resolve)))
    return True


def config_groups_text() -> str:
    """The config groups of ``conf/`` (Hydra's own, under ``hydra/``, left out) with their options, one group a line
    as Hydra's help lists them: ``solver: all, box, lstsq, nnls``. A folder without configs is not a group."""
    lines = []
    for folder in sorted(path for path in CONF_DIR.rglob("*") if path.is_dir()):
        group = folder.relative_to(CONF_DIR).as_posix()
        options = sorted(path.stem for path in folder.glob("*.yaml"))
        if options and group.split("/")[0] != "hydra":
            lines.append(f"{group}: {', '.join(options)}\n")
    return "".join(lines)


def _hydra_main(cfg: DictConfig) -> None:
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    from workbench.record import config_hash
    from workbench.tracking import FolderBusy, as_typed

    hydra_cfg = HydraConfig.get()
    output_dir = Path(hydra_cfg.runtime.output_dir)
    multirun = hydra_cfg.mode == RunMode.MULTIRUN
    try:
        if multirun:  # a plain run's config was checked before Hydra made its folder (tracking.RunFolders)
            from workbench.schema import check_study_config

            for warning in check_study_config(cfg, as_typed(hydra_cfg.overrides.task), refuse_ineffective=False):
                print(f"workbench: warning: {warning}", file=sys.stderr)
        text = run_owned(cfg, output_dir, overrides=as_typed(hydra_cfg.overrides.task),
                         job_num=int(hydra_cfg.job.num) if multirun else None, plain=not multirun)
    except FolderBusy as error:
        if not multirun:
            exit_on_error("workbench", error)
        # to the console only: the folder belongs to another process
        logging.getLogger("workbench.skip").info(f"skip {output_dir}: in use by another workbench process")
        return
    except BaseException as error:  # noqa: BLE001 - one line for any failure; --verbose shows the traceback
        exit_on_error("workbench", error)
    if text is None:
        # to the console only: a resumed sweep never touches a complete record's log
        logging.getLogger("workbench.skip").info(
            f"skip {output_dir}: complete record (config hash {config_hash(resolved_yaml_text(cfg))})")
    elif multirun:
        log.info(f"done {output_dir}: {first_headline(text)}")
    else:
        log.info(text + f"\nrecord: {output_dir}")


def run_owned(cfg: DictConfig, output_dir: Path, *, overrides: Sequence[str], job_num: int | None,
              plain: bool) -> str | None:
    """:func:`run` while holding the run folder's lock: the text it printed, or None when the folder already
    holds a complete record of the same config. A folder that is not the workbench's is refused before anything
    is written into it (:func:`workbench.tracking.check_run_dir`). A plain run (``plain``) that fails or is
    interrupted removes what it wrote, and its folder if it made it (a sweep's run keeps its partial record: its
    rerun clears and redoes the run)."""
    from workbench.record import config_hash
    from workbench.tracking import (check_run_dir, created_by_this_run, discard_failed_run, lock_run_dir,
                                    prepare_run_dir, unlock_run_dir)

    found = check_run_dir(output_dir, "hydra.sweep.dir" if not plain else "hydra.run.dir")
    lock = lock_run_dir(output_dir)
    try:
        if not prepare_run_dir(output_dir, config_hash(resolved_yaml_text(cfg))):
            return None
        return run(cfg, output_dir, overrides=overrides, job_num=job_num)
    except BaseException:
        if plain:
            discard_failed_run(output_dir, found, created_by_this_run(output_dir))
        raise
    finally:
        unlock_run_dir(lock)


def first_headline(text: str) -> str:
    """The first line after the alpha table of a run's printed text (its headline), for a sweep's one-line log."""
    lines = text.splitlines()
    last_table_line = max((i for i, line in enumerate(lines) if line.startswith("|")), default=-1)
    return next((line for line in lines[last_table_line + 1:] if line.strip()), "")


# Subcommands other than running a study: name -> "module:function", the function taking the remaining
# arguments (a list of str) and returning an exit code. Imported only when used.
COMMANDS: dict[str, str] = {
    "report": "workbench.reporting.pages:main",
    "collect": "workbench.reporting.collect:main",
    "mlflow": "workbench.reporting.mlflow_store:main",
    "export": "workbench.export:main",
}


def study_names() -> list[str]:
    """The studies: the configs in ``studies/`` (``--config-name`` takes one)."""
    return sorted(path.stem for path in STUDIES_DIR.glob("*.yaml"))


def help_section(name: str) -> str:
    """Text for the ``${workbench_help:...}`` resolver of ``conf/hydra/help/workbench.yaml``: ``version``, or the
    ``studies`` or ``commands`` listed one a line with their first line of documentation."""
    from workbench import __version__

    if name == "version":
        return __version__
    if name == "studies":
        entries = {study: first_comment(STUDIES_DIR / f"{study}.yaml") for study in study_names()}
    elif name == "commands":
        entries = {command: command_summary(target) for command, target in COMMANDS.items()}
    else:
        raise ValueError(f"workbench_help: unknown section {name!r}")
    width = max(map(len, entries))
    return "\n".join(f"{key.ljust(width)}  {text}".rstrip() for key, text in entries.items())


def command_summary(target: str) -> str:
    """The first sentence of the docstring of a command's module (read, not imported), without a leading
    ```workbench <command> ...``:`` so that ``--help`` stays fast."""
    import ast
    import importlib.util

    origin = importlib.util.find_spec(target.split(":")[0]).origin
    text = " ".join((ast.get_docstring(ast.parse(Path(origin).read_text())) or "").split())
    text = re.sub(r"^``workbench [^`]*``:\s*", "", text)
    return text.split(". ")[0].rstrip(".")


def first_comment(path: Path) -> str:
    """The first comment line of a YAML file up to its first colon or full stop: what the file is."""
    for line in path.read_text().splitlines():
        if line.startswith("#"):
            return line.lstrip("# ").split(": ")[0].split(". ")[0].strip()
    return ""


def register_cli_resolvers() -> None:
    """What the studies' configs use: their schemas, the resolvers of run folder names and of the help text."""
    from omegaconf import OmegaConf

    from workbench.schema import register_schemas

    register_schemas()
    if not OmegaConf.has_resolver("run_id"):  # workbench.tracking's, imported when a run folder is named
        OmegaConf.register_new_resolver("run_id", run_dir_name)
    if not OmegaConf.has_resolver("workbench_help"):
        OmegaConf.register_new_resolver("workbench_help", help_section)


def run_dir_name(overrides: str) -> str:
    """``${run_id:...}``: :func:`workbench.tracking.run_dir_name`, imported on first use."""
    from workbench.tracking import run_dir_name as tracking_run_dir_name

    return tracking_run_dir_name(overrides)


def complete_without_hydra() -> bool:
    """Tab completion beside Hydra's (which completes groups and keys): the studies after ``--config-name=``, the
    commands as the first word, and nothing after a command (the shell then offers file names, which the commands
    take). Prints its candidates; returns True when the line is complete, False when Hydra adds its own.
    """
    words = os.environ.get("COMP_LINE", "").split(" ")
    for flag in ("--config-name=", "-cn="):
        if words[-1].startswith(flag):
            prefix = words[-1][len(flag):]
            print(" ".join(flag + study for study in study_names() if study.startswith(prefix)))
            return True
    if len(words) > 2 and words[1] in COMMANDS:
        return True
    if len(words) == 2:
        print(" ".join(command for command in COMMANDS if command.startswith(words[1])))
    return False


VERBOSE_FLAG = "--verbose"
HELP_FLAGS = {"--help", "-h"}
_verbose = False


def exit_on_error(program: str, error: BaseException) -> None:
    """Print one line for ``error`` (the traceback too with ``--verbose``) and exit non-zero.

    A :class:`WorkbenchError` is bad input or configuration, and a fault of the environment (a file that cannot
    be read or written, a full disk, too little memory) is named with its path: both exit 2. Ctrl-C exits 130.
    Anything else is unexpected (exit 3) and names its type, since its message alone may not say where it came
    from.
    """
    if isinstance(error, SystemExit):
        raise error
    if _verbose:
        traceback.print_exception(error, file=sys.stderr)
    if caused_by_interrupt(error):
        print(INTERRUPTED_MESSAGE.replace("workbench", program, 1), file=sys.stderr)
        sys.exit(INTERRUPTED)
    fault = environment_fault(error)
    if fault is not None:
        print(f"{program}: error: {single_line(fault)}", file=sys.stderr)
        sys.exit(2)
    hint = "" if _verbose else f" (run with {VERBOSE_FLAG} for the traceback)"
    print(f"{program}: error: unexpected {type(error).__name__}: {single_line(error)}{hint}", file=sys.stderr)
    sys.exit(3)


@contextmanager
def one_line_usage_errors():
    """A command's wrong arguments are one line (argparse prints its usage block first): within this block an
    argument parser's error raises a :class:`WorkbenchError` naming the problem and ``--help``."""
    import argparse

    def error(parser, message):
        raise WorkbenchError(f"{message} (see {parser.prog} --help)")

    original = argparse.ArgumentParser.error
    argparse.ArgumentParser.error = error
    try:
        yield
    finally:
        argparse.ArgumentParser.error = original


def environment_fault(error: BaseException) -> str | None:
    """The one-line message of bad input (:class:`WorkbenchError`) or of a fault of the environment (an
    optional dependency not installed, naming its extra; an ``OSError`` such as a denied permission or a full
    disk, naming its path; running out of memory), or None for anything else."""
    if isinstance(error, WorkbenchError):
        return str(error)
    missing = missing_extra(error)
    if missing is not None:
        return missing
    if isinstance(error, MemoryError):
        return ("out of memory (MemoryError); use a smaller dataset (dataset.n_frames, dataset.max_frames, "
                "dataset.frame_step, dataset.mesh_vertex_step)")
    if isinstance(error, OSError) and error.strerror:
        paths = " -> ".join(str(path) for path in (error.filename, error.filename2) if path is not None)
        return f"{paths or 'a file of the run'}: {error.strerror}"
    return None


def main() -> None:
    """Entry point of the ``workbench`` command.

    ``workbench [--config-name STUDY] [overrides...]`` runs a study through Hydra; ``workbench <command> ...``
    runs one of :data:`COMMANDS`. ``--verbose`` anywhere adds the traceback to an error's one line (Hydra's own
    errors: set ``HYDRA_FULL_ERROR=1``).
    """
    global _verbose
    if "--version" in sys.argv[1:]:
        from workbench import __version__

        print(f"workbench {__version__}")
        sys.exit(0)
    if "query=bash" in sys.argv[1:] and complete_without_hydra():
        sys.exit(0)
    if VERBOSE_FLAG in sys.argv[1:]:
        _verbose = True
        sys.argv = [arg for arg in sys.argv if arg != VERBOSE_FLAG]
    if len(sys.argv) > 1 and sys.argv[1] in COMMANDS:
        import importlib

        module, function = COMMANDS[sys.argv[1]].split(":")
        raise_from_now_on()  # a command writing files removes its partial file when interrupted
        try:
            with one_line_usage_errors():
                code = getattr(importlib.import_module(module), function)(sys.argv[2:])
        except BaseException as error:  # noqa: BLE001 - SystemExit passes through, Ctrl-C is one line
            exit_on_error(f"workbench {sys.argv[1]}", error)
        sys.exit(code)
    try:
        check_config_dirs()
    except Exception as error:  # noqa: BLE001
        exit_on_error("workbench", error)
    # Hydra reports a bad override or config choice in several lines of its own; let it raise instead, and print
    # one line (unless the user asked for Hydra's full error or --verbose).
    full_error = os.environ.get("HYDRA_FULL_ERROR") == "1"
    os.environ["HYDRA_FULL_ERROR"] = "1"
    raise_from_now_on()  # an interrupted run removes what it wrote
    try:
        if not (HELP_FLAGS & set(sys.argv[1:]) and print_help(sys.argv[1:])):
            hydra_app()
    except KeyboardInterrupt as error:  # while Hydra composes the config, before the job's own handler
        exit_on_error("workbench", error)
    except Exception as error:  # noqa: BLE001 - errors of the job itself never get here (run_job catches them)
        if caused_by_interrupt(error):
            exit_on_error("workbench", error)
        if full_error or _verbose:
            raise
        print(f"workbench: error: {missing_extra(error) or one_line(error)}", file=sys.stderr)
        sys.exit(2)


def one_line(error: BaseException) -> str:
    """Hydra's multi-line message of a config error (and its cause's) as one line: lists such as the available
    options of a config group are joined, the config search path is left out."""
    text = str(error)
    if error.__cause__ is not None and str(error.__cause__) not in text:
        text += "\n" + str(error.__cause__)
    parts = []
    for line in text.split("Config search path:")[0].splitlines():
        if not line.strip() or line.strip().startswith(("full_key:", "object_type=", "reference_type=",
                                                        "Set the environment variable")):
            continue
        if line.startswith(("\t", "    ")) and parts and parts[-1].endswith((":", ",")):
            parts[-1] += (" " if parts[-1].endswith(":") else " ") + line.strip() + ","
        else:
            parts.append(line.strip())
    return "; ".join(part.rstrip(",.") for part in parts)
