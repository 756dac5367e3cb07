"""Where the workbench's configs live, what they resolve (run folder names, the help text's studies and commands)
and composing a study without running it (for tests and notebooks).

In the checkout (``pip install -e .``) the config groups and the studies are the top-level folders ``conf/`` and
``studies/`` beside the package. A built package (``pip install .``, a wheel, an sdist, ``pip install git+URL``)
carries copies of them inside the package, as ``workbench/conf`` and ``workbench/studies`` (the ``package-dir``
mapping in ``pyproject.toml``); those are used when they exist.
"""

from __future__ import annotations

import functools
import hashlib
import re
from pathlib import Path
from typing import TYPE_CHECKING, Mapping, Sequence

from workbench.core.errors import WorkbenchError

if TYPE_CHECKING:
    from omegaconf import DictConfig

PACKAGE_DIR = Path(__file__).resolve().parents[1]
"""The ``workbench`` package folder (this module is in its ``settings/``)."""
INSTALLED = (PACKAGE_DIR / "conf").is_dir() and (PACKAGE_DIR / "studies").is_dir()
"""True for a built package (the configs inside it), False for the checkout (the configs beside it)."""
REPO_ROOT = PACKAGE_DIR.parent
"""The checkout holding the package (for a built package: the folder it is installed in, ``site-packages``)."""
CHECKOUT = None if INSTALLED else REPO_ROOT
"""The checkout the workbench runs from, or None for a built package (no git state, no reference reports)."""
CONF_DIR = (PACKAGE_DIR if INSTALLED else REPO_ROOT) / "conf"
STUDIES_DIR = (PACKAGE_DIR if INSTALLED else REPO_ROOT) / "studies"
DEFAULT_STUDY = "paper"


def check_config_dirs() -> None:
    """The config folders exist: beside the package in the checkout, or inside a built package."""
    for folder in (CONF_DIR, STUDIES_DIR):
        if not folder.is_dir():
            raise WorkbenchError(
                f"config folder {folder} is missing: reinstall the workbench (pip install "
                "quasi-eigen-workbench, or 'pip install -e .' in its checkout)"
            )


def compose(study: str = DEFAULT_STUDY, overrides: Sequence[str] = ()):
    """Compose a study's config as the command line would, without running it.

    Parameters
    ----------
    study : str
        Name of a file in ``studies/`` without ``.yaml``.
    overrides : sequence of str
        Hydra overrides such as ``"dataset.n_frames=2000"``.

    Returns
    -------
    omegaconf.DictConfig

    Raises
    ------
    WorkbenchError
        One line, in the command line's words: a study that is not one of ``studies/``, an override that is not a
        string, cannot be parsed, names a retired setting (:func:`workbench.settings.schema.refuse_retired`), an
        unknown key or option, or a value of the wrong type.
    """
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    from workbench.settings.schema import refuse_retired

    if not isinstance(study, str) or study not in study_names():
        raise WorkbenchError(f"study must be one of {', '.join(study_names())} (studies/), got {study!r}")
    overrides = override_list(overrides, "overrides")
    check_override_keys(overrides, "overrides")
    refuse_retired(overrides)
    register_resolvers()
    check_config_dirs()
    try:
        with initialize_config_dir(config_dir=str(STUDIES_DIR), version_base="1.3"):
            return hydra_compose(config_name=study, overrides=overrides, return_hydra_config=True)
    except (HydraException, OmegaConfBaseException) as error:
        raise WorkbenchError(config_error_line(error)) from None


def override_list(overrides, argument: str) -> list[str]:
    """``overrides`` as a list of ``key=value`` strings; a single string (which would be read as its letters), or
    anything else that is not a sequence of strings, is refused in one line naming ``argument``."""
    if isinstance(overrides, str):
        raise WorkbenchError(
            f"{argument} must be a list of 'key=value' strings, got the string {overrides!r}; give [{overrides!r}]"
        )
    if not isinstance(overrides, Sequence) or not all(isinstance(item, str) for item in overrides):
        raise WorkbenchError(f"{argument} must be a list of 'key=value' strings, got {overrides!r}")
    return list(overrides)


def check_override_keys(overrides: Sequence[str], argument: str) -> None:
    """A one-line :class:`WorkbenchError` naming ``argument`` and the override when one names no setting (``=1``,
    ``+=x``, ``~``), which Hydra would take as a config group called '' and fail on deep inside; an override it
    cannot parse is left to composing, which names it in the command line's words."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import HydraException

    parser = OverridesParser.create()
    for override in overrides:
        try:
            parsed = parser.parse_override(override)
        except HydraException:
            continue
        if not parsed.key_or_group:
            raise WorkbenchError(
                f"{argument}: the override {override!r} names no setting before its '=': write key=value, e.g. "
                "'dataset.n_frames=2000'"
            )


def config_error_line(error: BaseException) -> str:
    """Hydra's or OmegaConf's error composing a config as one line, as the command line prints it: a retired
    setting says why it went, an override that cannot be parsed is named, a study that is not found lists the
    studies, and Hydra's multi-line text (and its cause's) is joined, leaving out the config search path."""
    from workbench.settings.schema import RETIRED_SETTINGS, retired_message

    text = str(error)
    found = re.match(r"Could not override '([^']+)'", text)
    if found and found.group(1) in RETIRED_SETTINGS:
        return retired_message(found.group(1))
    if error.__cause__ is not None and str(error.__cause__) not in text:
        text += "\n" + str(error.__cause__)
    parts = []
    for line in text.split("Config search path:")[0].splitlines():
        if not line.strip() or line.strip().startswith(
            ("full_key:", "object_type=", "reference_type=", "Set the environment variable")
        ):
            continue
        if line.startswith(("\t", "    ")) and parts and parts[-1].endswith((":", ",")):
            parts[-1] += " " + line.strip() + ","
        else:
            parts.append(line.strip())
    line = "; ".join(part.rstrip(",.") for part in parts)
    if type(error).__name__ == "OverrideParseException":
        line = f"override {getattr(error, 'override', '')!r} cannot be parsed: {line}"
    elif line.startswith("Cannot find primary config"):
        line = f"{line.split('. ')[0]}; the studies are {', '.join(study_names())}"
    return line


RUN_ID_MAX = 120
"""Longest run folder name made from the overrides alone; longer ones are cut and get a hash."""


def run_dir_name(override_dirname: str) -> str:
    """The folder name of a run, from Hydra's ``hydra.job.override_dirname`` (its sorted overrides).

    Readable when it can be (``basis.coverage=0.99,dataset.seed=1``); characters unsafe in a file name are
    replaced, and a name that had to be changed or cut gets a hash of the full text so that two runs never
    share a folder.

    Parameters
    ----------
    override_dirname : str

    Returns
    -------
    str
    """
    text = str(override_dirname)
    if not text:
        return "default"
    safe = re.sub(r"[^A-Za-z0-9._=,+\-]", "_", text)
    if safe == text and len(text) <= RUN_ID_MAX:
        return text
    return f"{safe[: RUN_ID_MAX - 9]}-{hashlib.sha256(text.encode()).hexdigest()[:8]}"


def study_names() -> list[str]:
    """The studies: the configs in ``studies/`` (``--config-name`` takes one)."""
    return sorted(path.stem for path in STUDIES_DIR.glob("*.yaml"))


def help_section(name: str, commands: Mapping[str, str] | None = None) -> str:
    """Text for the ``${workbench_help:...}`` resolver of ``conf/hydra/help/workbench.yaml``: ``version``, or the
    ``studies`` or ``commands`` (``name -> "module:function"``, the command line's table) listed one a line with
    their first line of documentation."""
    from workbench.version import __version__

    if name == "version":
        return __version__
    if name == "studies":
        entries = {study: first_comment(STUDIES_DIR / f"{study}.yaml") for study in study_names()}
    elif name == "commands":
        entries = {command: command_summary(target) for command, target in (commands or {}).items()}
    else:
        raise ValueError(f"workbench_help: unknown section {name!r}")
    width = max(map(len, entries))
    return "\n".join(f"{key.ljust(width)}  {text}".rstrip() for key, text in entries.items())


@functools.cache
def command_summary(target: str) -> str:
    """The first sentence of the docstring of a command's module (read, not imported), without a leading
    ```workbench <command> ...``:`` so that ``--help`` stays fast. Kept once read: Hydra resolves the help text at
    every composition (several per run of a sweep), and parsing the modules each time cost a twentieth of a sweep."""
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


def register_resolvers(commands: Mapping[str, str] | None = None) -> None:
    """What the studies' configs use: their schemas, the resolvers of run folder names and of the help text (whose
    list of subcommands is ``commands``, given by the command line)."""
    from functools import partial

    from omegaconf import OmegaConf

    from workbench.settings.schema import register_schemas

    register_schemas()
    if not OmegaConf.has_resolver("run_id"):
        OmegaConf.register_new_resolver("run_id", run_dir_name)
    if commands is not None or not OmegaConf.has_resolver("workbench_help"):
        OmegaConf.register_new_resolver("workbench_help", partial(help_section, commands=commands), replace=True)


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
