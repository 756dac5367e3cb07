"""Command line: ``workbench [--config-name STUDY] [overrides...]`` (also ``python -m workbench``).

The Hydra entry point is thin: it hands the composed config to :func:`run`.
"""

from __future__ import annotations

import logging
import os
import sys
import traceback
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

from workbench.core.errors import (
    VERBOSE_FLAG,
    WorkbenchError,
    check_utf8,
    environment_fault,
    exit_on_error,
    show_tracebacks,
    single_line,
    tracebacks_shown,
)
from workbench.core.extras import missing_extra
from workbench.core.interrupt import caused_by_interrupt, ignore_further_interrupts, raise_from_now_on

# Only what every command needs is imported here: `--help`, `--version` and tab completion must start fast, so
# Hydra, pandas and the numerical code are imported by the functions that use them.
from workbench.settings.config import (
    CONF_DIR,
    DEFAULT_STUDY,
    STUDIES_DIR,
    check_config_dirs,
    config_error_line,
    register_resolvers,
    resolved_yaml_text,
    study_names,
)

if TYPE_CHECKING:
    from omegaconf import DictConfig

log = logging.getLogger("workbench")
WIDE_FLAG = "--wide"
"""Print a run's full text (every table column, long lines whole) instead of the 120 columns it fits by default."""
_wide = False

# Subcommands other than running a study: name -> "module:function", the function taking the remaining
# arguments (a list of str) and returning an exit code. Imported only when used.
COMMANDS: dict[str, str] = {
    "report": "workbench.reporting.report.command:main",
    "collect": "workbench.reporting.collect.command:main",
    "mlflow": "workbench.record.mlflow:main",
    "export": "workbench.reporting.export.command:main",
}


def hydra_app() -> None:
    """The Hydra application: compose the study from the command line and run :func:`_hydra_main` on it (or print
    the help, the config or completions). Hydra is imported here, not with the module, to keep start-up fast."""
    import hydra

    register_resolvers(COMMANDS)
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
    register_resolvers(COMMANDS)
    with initialize_config_dir(config_dir=str(STUDIES_DIR), version_base="1.3"):
        cfg = compose(config_name=args.config_name or DEFAULT_STUDY, overrides=args.overrides, return_hydra_config=True)
    template = cfg.hydra.help.template
    with open_dict(cfg):
        del cfg["hydra"]
    print(
        string.Template(template).safe_substitute(
            APP_CONFIG_GROUPS=config_groups_text(), CONFIG=OmegaConf.to_yaml(cfg, resolve=args.resolve)
        )
    )
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

    from workbench.record.record import config_hash  # loaded already, with the folder callback (tracking)
    from workbench.record.tracking import FolderBusy, as_typed

    hydra_cfg = HydraConfig.get()
    output_dir = Path(hydra_cfg.runtime.output_dir)
    multirun = hydra_cfg.mode == RunMode.MULTIRUN
    try:
        # inside: a Ctrl-C while the study's modules load (a second or so) ends below, without the folder Hydra made
        from workbench.api import run_owned

        if multirun:  # a plain run's config was checked before Hydra made its folder (tracking.RunFolders)
            from workbench.settings.schema import check_study_config

            for warning in check_study_config(cfg, as_typed(hydra_cfg.overrides.task), refuse_ineffective=False):
                print(f"workbench: warning: {warning}", file=sys.stderr)
        text = run_owned(
            cfg,
            output_dir,
            overrides=as_typed(hydra_cfg.overrides.task),
            job_num=int(hydra_cfg.job.num) if multirun else None,
            plain=not multirun,
            wide=_wide or multirun,  # a sweep logs one headline line per run
        )
    except FolderBusy as error:
        if not multirun:
            exit_on_error("workbench", error)
        # to the console only: the folder belongs to another process
        from workbench.reporting.tables.width import printed

        skipped = f"skip {shown_folder(output_dir)}: in use by another workbench process"
        logging.getLogger("workbench.skip").info(printed(skipped))
        return
    except BaseException as error:  # noqa: BLE001 - one line for any failure; --verbose shows the traceback
        if multirun and isinstance(error, Exception) and not caused_by_interrupt(error):
            return sweep_run_error(error, output_dir)  # the sweep goes on with its other values
        if not multirun:  # failed before its run claimed the folder Hydra made: no empty outputs/paper/<date>
            from workbench.record.tracking import remove_made_folders

            remove_made_folders(output_dir)
        exit_on_error("workbench", error)
    if text is None:
        # to the console only: a resumed sweep never touches a complete record's log
        from workbench.reporting.tables.width import printed

        skipped = (
            f"skip {shown_folder(output_dir)}: complete record (config hash {config_hash(resolved_yaml_text(cfg))})"
        )
        logging.getLogger("workbench.skip").info(printed(skipped))
    elif multirun:
        from workbench.reporting.tables.width import printed

        log.info(printed(f"done {shown_folder(output_dir)}: {first_headline(text)}"))
    else:
        log.info(text + f"\nrecord: {output_dir}")


def shown_folder(folder: Path) -> str:
    """A sweep's run folder as its lines name it: relative to the working folder when inside it (a line within
    120 columns), else whole."""
    try:
        return Path(folder).resolve().relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        return str(folder)


def sweep_run_error(error: Exception, output_dir: Path) -> None:
    """A sweep's failed run, kept for the sweep's closing line (:mod:`workbench.cli.sweep_failures`)."""
    from workbench.cli.sweep_failures import sweep_run_failed

    if tracebacks_shown():
        traceback.print_exception(error, file=sys.stderr)
    fault = environment_fault(error)
    message = single_line(fault) if fault is not None else f"unexpected {type(error).__name__}: {single_line(error)}"
    sweep_run_failed(output_dir.name, message, 2 if fault is not None else 3)


def first_headline(text: str) -> str:
    """The first line after the alpha table of a run's printed text (its headline), for a sweep's one-line log."""
    lines = text.splitlines()
    last_table_line = max((i for i, line in enumerate(lines) if line.startswith("|")), default=-1)
    return next((line for line in lines[last_table_line + 1 :] if line.strip()), "")


def complete_without_hydra() -> bool:
    """Tab completion beside Hydra's (which completes groups and keys): the studies after ``--config-name=``, the
    commands as the first word, and nothing after a command (the shell then offers file names, which the commands
    take). Prints its candidates; returns True when the line is complete, False when Hydra adds its own.
    """
    words = os.environ.get("COMP_LINE", "").split(" ")
    for flag in ("--config-name=", "-cn="):
        if words[-1].startswith(flag):
            prefix = words[-1][len(flag) :]
            print(" ".join(flag + study for study in study_names() if study.startswith(prefix)))
            return True
    if len(words) > 2 and words[1] in COMMANDS:
        return True
    if len(words) == 2:
        print(" ".join(command for command in COMMANDS if command.startswith(words[1])))
    return False


HELP_FLAGS = {"--help", "-h"}


@contextmanager
def one_line_usage_errors(program: str | None = None):
    """A command's wrong arguments are one line (argparse prints its usage block first): within this block an
    argument parser's error raises a :class:`WorkbenchError` naming the problem and ``--help`` (of ``program``,
    else of the parser's own program name)."""
    import argparse

    def error(parser, message):
        raise WorkbenchError(f"{message} (see {program or parser.prog} --help)")

    original = argparse.ArgumentParser.error
    argparse.ArgumentParser.error = error
    try:
        yield
    finally:
        argparse.ArgumentParser.error = original


def main() -> None:
    """Entry point of the ``workbench`` command.

    ``workbench [--config-name STUDY] [overrides...]`` runs a study through Hydra; ``workbench <command> ...``
    runs one of :data:`workbench.cli.main.COMMANDS`. ``--verbose`` anywhere adds the traceback to an error's one line (Hydra's own
    errors: set ``HYDRA_FULL_ERROR=1``).
    """
    try:
        os.getcwd()
    except FileNotFoundError:  # every relative path would fail with a bare "[Errno 2]"
        exit_on_error(
            "workbench",
            WorkbenchError(
                "the current folder was removed (deleted or moved away while this shell was in it); cd into an "
                "existing folder and run the command again"
            ),
        )
    for argument in sys.argv[1:]:  # before anything runs: a record cannot hold a name that is not UTF-8
        try:
            check_utf8(argument, "argument")
        except WorkbenchError as error:
            exit_on_error("workbench", error)
    if "--version" in sys.argv[1:]:
        from workbench.version import __version__

        print(f"workbench {__version__}")
        sys.exit(0)
    if "query=bash" in sys.argv[1:] and complete_without_hydra():
        sys.exit(0)
    global _wide
    _wide = WIDE_FLAG in sys.argv[1:] and not (len(sys.argv) > 1 and sys.argv[1] in COMMANDS)
    from workbench.reporting.tables.width import print_whole

    print_whole(_wide)  # a sweep's summary too (printed when it ends, by the collect callback)
    if _wide:
        sys.argv = [arg for arg in sys.argv if arg != WIDE_FLAG]
    if VERBOSE_FLAG in sys.argv[1:]:
        show_tracebacks()
        os.environ.setdefault("MLFLOW_LOGGING_LEVEL", "INFO")  # MLflow's own lines too (quiet otherwise)
        logging.basicConfig(format="%(message)s")  # and the workbench's notes (a Hydra run sets its own logging)
        logging.getLogger("workbench").setLevel(logging.DEBUG)
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
        ignore_further_interrupts()  # done and reported: Ctrl-C would only cut the libraries' exit
        sys.exit(code)
    try:
        check_config_dirs()
    except Exception as error:  # noqa: BLE001
        exit_on_error("workbench", error)
    # Hydra reports a bad override or config choice in several lines of its own; let it raise instead, and print
    # one line (unless the user asked for Hydra's full error or --verbose).
    full_error = os.environ.get("HYDRA_FULL_ERROR") == "1"
    os.environ["HYDRA_FULL_ERROR"] = "1"
    from workbench.cli import sweep_failures

    sweep_failures.MAIN_PROCESS = os.getpid()
    sweep_failures.FAILED.clear()  # this command's sweep only (main may be called again in one process)
    raise_from_now_on()  # an interrupted run removes what it wrote; from here a Ctrl-C is caught below
    try:
        with one_line_usage_errors("workbench"):  # Hydra's argument parser: one line, not its usage block
            if not (HELP_FLAGS & set(sys.argv[1:]) and print_help(sys.argv[1:])):
                hydra_app()
        sweep_failures.exit_if_runs_failed()  # a sweep's runs have all ended: name the ones that failed
    except KeyboardInterrupt as error:  # while Hydra composes the config, before the job's own handler
        exit_on_error("workbench", error)
    except Exception as error:  # noqa: BLE001 - errors of the job itself never get here (run_job catches them)
        if caused_by_interrupt(error):
            exit_on_error("workbench", error)
        if type(error).__name__ == "SweepRunFailed":  # a sweep ran every run; name the ones that failed
            from workbench.cli.sweep_failures import exit_if_runs_failed

            exit_if_runs_failed(error)
        if full_error or tracebacks_shown():
            raise
        print(f"workbench: error: {missing_extra(error) or config_error_line(error)}", file=sys.stderr)
        sys.exit(2)
