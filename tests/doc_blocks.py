"""The shell commands of the README and of ``docs/``: read, run in a scratch copy of the checkout, and timed.

``tests/project/test_docs.py`` runs every command of every shell block (``bash``, ``sh``, ``shell``) as a reader would:
in a copy of the checkout with ``../shared`` beside it and the test's virtual environment as ``.venv``, in the
order of its document, after the commands of other documents that write the output folders it reads (its
prerequisites). Placeholders are filled (``<date-time>`` is the newest run of ``outputs/paper``, ``workbench
x<TAB>  # a b`` checks that bash completes ``x`` to ``a b``), ``/tmp/`` becomes a scratch folder, installing
commands check that what they install is there, and a few commands are not run (:data:`NOT_RUN`). Commands that
take a minute or more (measured, in ``docs/commands.md``) are not run either, unless a later command reads what
they write: then a study's small preset (``<study>_small``) writes the same folder instead, and any other command
runs as written; a later run of that study in the same document (more seeds into another folder, to be collected
with the first) runs as its small preset too. A command that ran before in the same test run (in another document's test, or earlier in the same
one) has what it wrote copied instead, where that is safe (:class:`Reuse`).

``python tests/doc_blocks.py measure [DOC ...]`` runs the commands of the documents (default: all) for real,
long ones included, and rewrites their rows in ``docs/commands.md`` with the wall time and peak memory measured.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
LONG_SECONDS = 60.0
"""A command that takes this many CPU seconds or more (measured, in docs/commands.md) is not run by the doc test:
CPU time rather than wall time, which grows with whatever else the machine runs."""
TIMES_DOC = "docs/commands.md"
FENCE = re.compile(r"^```(?:bash|sh|shell)\s*$")
HEREDOC = re.compile(r"<<-?\s*['\"]?(\w+)['\"]?")
OUTPUT_PATH = re.compile(r"(?:\$PWD/)?(outputs/[^\s'\"`;|&)]*[^\s'\"`;|&).,])")

NOT_RUN = {
    r"\.venv/bin/pytest": "the test suite itself: CI runs the README's test command verbatim (.ci/run)",
    r"\bmlflow (?:ui|server)\b": "a server that runs until it is stopped",
    r"<partition>": "needs a SLURM cluster's partition",
    r"slurm-cluster|hydra/launcher=slurm": "needs the one-machine SLURM cluster (started as root): "
    "tests/cli/test_cluster.py runs these steps in CI (.ci/run)",
    r"mylab|~/quasi-eigen-workbench": "a lab's own cluster, configs and MLflow server",
    r"(?<!-)\bpip install (?!-e)": "installs into an environment: CI builds, installs and runs the wheel and the "
    "sdist (.ci/run)",
}
"""Commands (matched by a pattern) the doc test does not run, with the reason it says."""


def apt_get(match: re.Match) -> str:
    packages = [word for word in match.group(1).split() if not word.startswith("-")]
    return f"doc_has_tool {packages[0]} "


REWRITES = [
    # the virtual environment and its packages are the ones running the test: check, never install
    (re.compile(r"python3 -m venv \.venv"), lambda match: "true"),
    (
        re.compile(r"(?:\.venv/bin/)?pip install -e (?:'\.\[([\w,]+)\]'|\.(?=\s|$))"),
        lambda match: f"doc_has_extras '{match.group(1) or ''}'",
    ),
    (re.compile(r"npm install [^#\n]*gltf-validator"), lambda match: "doc_has_tool gltf-validator"),
    (re.compile(r"apt-get install ([^#\n]*)"), apt_get),
    # tools outside Python: run where installed (required where WORKBENCH_REQUIRE_TOOLS=1), else the block is skipped
    (
        re.compile(r"^(chromium|blender) ", re.MULTILINE),
        lambda match: (
            f"doc_has_tool {match.group(1)} && "
            + ("doc_short_tmp " if match.group(1) == "chromium" else "")
            + match.group(0)
        ),
    ),
    # a placeholder: the newest run of the paper study
    (re.compile(r"outputs/paper/<date-time>"), lambda match: 'outputs/paper/"$(ls outputs/paper | tail -n 1)"'),
]
"""Text substitutions that make a documented command runnable in the scratch copy (pattern, replacement)."""

TAB_LINE = re.compile(r"^(?P<line>.*?)<TAB>\s*(?:#\s*(?P<expected>.*))?$")

PRELUDE = r"""
set -eo pipefail
doc_has_extras() {  # the extras a documented 'pip install' asks for are installed (checked, never installed)
    .venv/bin/python - "$1" <<'PY'
import re, sys
from importlib import metadata
wanted, checked, missing = {extra for extra in sys.argv[1].split(",") if extra}, set(), []
while wanted - checked:
    extras = wanted - checked
    checked |= extras
    for requirement in metadata.requires("quasi-eigen-workbench") or []:
        name = re.split(r"[\s<>=!~;\[]", requirement, maxsplit=1)[0]
        extra = re.search(r"extra\s*==\s*['\"]([\w-]+)['\"]", requirement)
        if extra is not None and extra.group(1) not in extras:
            continue
        if name == "quasi-eigen-workbench":  # an extra made of other extras
            wanted |= set(re.search(r"\[([\w,-]+)\]", requirement).group(1).split(","))
            continue
        try:
            metadata.version(name)
        except metadata.PackageNotFoundError:
            missing.append(name)
if missing:
    sys.exit(f"not installed: {', '.join(sorted(set(missing)))}")
PY
}
doc_has_tool() {  # a tool a documented install command installs is there; exit 77 (skip the block) if not
    if [ "$1" = gltf-validator ]; then test -d .ci/node/node_modules/gltf-validator && return 0
    elif command -v "$1" >/dev/null; then return 0; fi
    echo "$1 is not installed" >&2
    if [ "${WORKBENCH_REQUIRE_TOOLS:-}" = 1 ] || [ "${WORKBENCH_REQUIRE_BROWSER:-}" = 1 ]; then exit 1; fi
    exit 77
}
doc_short_tmp() {  # run a command with TMPDIR in a short folder of its own: Chromium's socket path (in TMPDIR) must
    # fit in 108 bytes, and the scratch's tmp under pytest's tmp_path can be longer
    local folder code=0
    folder=$(mktemp -d /tmp/wb-doc-XXXXXX)
    TMPDIR=$folder "$@" || code=$?
    rm -rf "$folder"
    return $code
}
doc_complete() {  # doc_complete LINE EXPECTED: bash completes LINE (after <TAB>) to the words EXPECTED
    local COMP_LINE="$1" COMP_POINT=${#1} COMP_WORDS COMP_CWORD function got expected
    read -ra COMP_WORDS <<< "$1"
    if [[ "$1" == *" " ]]; then COMP_WORDS+=(""); fi
    COMP_CWORD=$(( ${#COMP_WORDS[@]} - 1 ))
    function=$(complete -p "${COMP_WORDS[0]}" | sed -E 's/.* -F ([^ ]+) .*/\1/')
    COMPREPLY=()
    set +e
    "$function"
    set -e
    got=$(printf '%s\n' "${COMPREPLY[@]}" | sort | xargs)
    expected=$(printf '%s\n' $2 | sort | xargs)
    if [ "$got" != "$expected" ]; then
        echo "bash completes '$1' to '$got'; the doc says '$expected'" >&2
        return 1
    fi
}
"""
"""Shell functions every command can use (the rewritten install commands and completions call them)."""

STATE = re.compile(r"^\s*(?:source|\.|eval|export|cd)\s")
"""Commands that change the shell rather than files: replayed before each later command of their block."""


@dataclass(frozen=True)
class Command:
    """One command of a documented shell block, as written (continuation lines and here-documents included)."""

    doc: str
    line: int
    block: int
    text: str

    @property
    def key(self) -> str:
        """Identifies the command in docs/commands.md across edits elsewhere in its document."""
        return hashlib.sha1(f"{self.doc}\n{normalised(self.text)}".encode()).hexdigest()[:10]

    @property
    def code(self) -> str:
        """The command without its trailing comment (on its first line) and without here-document bodies."""
        first = self.text.split("\n")
        if HEREDOC.search(first[0]):
            return strip_comment(first[0])
        return "\n".join(strip_comment(line) for line in first)

    @property
    def heredoc(self) -> str:
        return "\n".join(self.text.split("\n")[1:]) if HEREDOC.search(self.text.split("\n")[0]) else ""

    @property
    def summary(self) -> str:
        """The command on one line, for tables and messages."""
        text = " ".join(part.strip().rstrip("\\").strip() for part in self.code.split("\n"))
        return text if len(text) <= 110 else text[:107] + "..."


def normalised(text: str) -> str:
    return " ".join(text.split())


def strip_comment(line: str) -> str:
    """A shell line without its comment (a ``#`` after white space, outside quotes)."""
    quote = None
    for i, character in enumerate(line):
        if quote:
            quote = None if character == quote else quote
        elif character in "'\"":
            quote = character
        elif character == "#" and (i == 0 or line[i - 1].isspace()):
            return line[:i].rstrip()
    return line.rstrip()


def documents(root: Path = REPO_ROOT) -> list[str]:
    """The README and every Markdown file under ``docs/``, as paths relative to ``root``."""
    return ["README.md", *sorted(path.relative_to(root).as_posix() for path in (root / "docs").rglob("*.md"))]


def commands(doc: str, root: Path = REPO_ROOT) -> list[Command]:
    """The commands of a document's shell blocks, in order."""
    lines = (root / doc).read_text().splitlines()
    found, i, block = [], 0, None
    while i < len(lines):
        if block is None:
            block = i + 1 if FENCE.match(lines[i]) else None
            i += 1
            continue
        if lines[i].startswith("```"):
            block, i = None, i + 1
            continue
        if not lines[i].strip() or lines[i].lstrip().startswith("#"):
            i += 1
            continue
        start, text = i, [lines[i]]
        while strip_comment(text[-1]).endswith("\\") and i + 1 < len(lines):
            i += 1
            text.append(lines[i])
        heredoc = HEREDOC.search(strip_comment(lines[start]))
        if heredoc:
            while i + 1 < len(lines) and lines[i].strip() != heredoc.group(1):
                i += 1
                text.append(lines[i])
        found.append(Command(doc, start + 1, block, "\n".join(text)))
        i += 1
    return found


def all_commands(root: Path = REPO_ROOT) -> dict[str, list[Command]]:
    """The commands of every document, by document."""
    return {doc: commands(doc, root) for doc in documents(root)}


# --- what a command writes and reads -------------------------------------------------------------------------


def plain_path(token: str) -> str:
    return token.strip("'\"").removeprefix("$PWD/").rstrip("/")


def workbench_args(code: str) -> list[str] | None:
    """The arguments of the first ``workbench`` (or ``python -m workbench``) the command runs, or None."""
    for segment in re.split(r"&&|\|\||;|\|", code.replace("\\\n", " ")):
        try:
            words = shlex.split(segment)
        except ValueError:
            words = segment.split()
        for i, word in enumerate(words):
            if Path(word).name == "workbench" and not word.endswith(".py"):
                if i == 0 or words[i - 1] == "-m" or "=" in words[i - 1]:
                    return words[i + 1 :]
    return None


def writes(command: Command) -> set[str]:
    """Output folders and files the command makes (Hydra's run and sweep folders, a study's default sweep folder,
    a plain run's ``outputs/paper``, ``--out``, the files a here-document script writes)."""
    code = command.code
    if "<TAB>" in code or not_run_reason(command):
        return set()
    made = {plain_path(value) for value in re.findall(r"hydra\.(?:run|sweep)\.dir=(\S+)", code)}
    made |= {plain_path(value) for value in re.findall(r"--out[ =](\S+)", code)}
    args = workbench_args(code)
    if args is not None and not made and not (args and args[0] in ("report", "collect", "mlflow", "export")):
        study = next(
            (
                args[i + 1] if arg in ("--config-name", "-cn") else arg.split("=", 1)[1]
                for i, arg in enumerate(args)
                if arg in ("--config-name", "-cn") or arg.startswith(("--config-name=", "-cn="))
            ),
            None,
        )
        if study:
            made.add(f"outputs/{study}/default")
        elif "-m" in args or "--multirun" in args:
            made.add("outputs/paper-multirun/default")
        elif not {"--help", "-h", "--version", "--cfg", "--info", "-sc"} & set(args):
            made.add("outputs/paper")
    made |= {plain_path(path) for path in OUTPUT_PATH.findall(command.heredoc)}
    return {path for path in made if path.startswith("outputs/")}


def reads(command: Command) -> set[str]:
    """Output folders and files the command reads: every ``outputs/...`` it names and does not make."""
    named = {plain_path(path) for path in OUTPUT_PATH.findall(command.code)}
    made = writes(command)
    return {path for path in named if path not in made and not path.startswith("outputs/.mlflow")}


def covers(made: str, path: str) -> bool:
    """Whether a command that makes ``made`` makes ``path`` (the same, or inside it)."""
    return path == made or path.startswith(made + "/")


def prerequisites(doc: str, documented: dict[str, list[Command]]) -> list[Command]:
    """Commands of other documents that make what a command of ``doc`` the test runs reads before anything in
    ``doc`` made it, each after its own prerequisites, in document order."""
    order: list[Command] = []

    def provide(path: str, exclude: str) -> None:
        for other, listed in documented.items():
            if other == exclude:
                continue
            for index, command in enumerate(listed):
                if any(covers(made, path) for made in writes(command)):
                    for earlier in reads(command):
                        if not any(covers(made, earlier) for previous in listed[:index] for made in writes(previous)):
                            provide(earlier, exclude)
                    if command not in order:
                        order.append(command)
                    return

    made: set[str] = set()
    for command in documented[doc]:
        if not_run_reason(command):  # a command the test does not run needs nothing made for it
            continue
        for path in sorted(reads(command)):
            if not any(covers(folder, path) for folder in made):
                provide(path, doc)
        made |= writes(command)
    return order


# --- running --------------------------------------------------------------------------------------------------


@dataclass
class Outcome:
    command: Command
    status: str  # "ok", "failed", "skipped", "long"
    seconds: float = 0.0
    cpu_seconds: float = 0.0
    peak_mb: float = 0.0
    load: float = 0.0  # the machine's load average over the last minute, when the command ended
    note: str = ""
    prerequisite: bool = False
    output: str = field(default="", repr=False)


def not_run_reason(command: Command) -> str | None:
    return next((why for pattern, why in NOT_RUN.items() if re.search(pattern, command.code)), None)


def runnable(command: Command, scratch_tmp: Path) -> str:
    """The command as the scratch copy runs it: rewrites applied, ``/tmp/`` moved into the scratch folder and a
    ``<TAB>`` line turned into a completion check."""
    text = command.text
    tab = TAB_LINE.match(text) if "\n" not in text else None
    if tab:
        return f"doc_complete {shlex.quote(tab.group('line'))} {shlex.quote(tab.group('expected') or '')}"
    for pattern, replace in REWRITES:
        text = pattern.sub(replace, text)
    return re.sub(r"(?<![\w./])/tmp/", f"{scratch_tmp}/", text)


STUDY = re.compile(r"(--config-name|-cn)([= ])(\w+)")


def stand_in(command: Command, needed: bool, root: Path) -> str | None:
    """For a long study run whose folder a later command reads: its small preset writing the same folder."""
    study = STUDY.search(command.code)
    if not needed or study is None or not (root / "studies" / f"{study.group(3)}_small.yaml").is_file():
        return None
    text = command.code.replace(study.group(0), f"{study.group(1)}{study.group(2)}{study.group(3)}_small", 1)
    if "hydra.sweep.dir=" not in text:
        text = text.rstrip() + f" hydra.sweep.dir=outputs/{study.group(3)}/default"
    return text


def study_of(command: Command) -> str | None:
    """The study a command runs (``--config-name <study>``), if any."""
    study = STUDY.search(command.code)
    return study.group(3) if study else None


def run_measured(script: str, cwd: Path, env: dict, timeout: float) -> tuple[int, float, float, float, str]:
    """Run a bash script: exit code, wall seconds, CPU seconds (user and system, of every process it ran), peak
    resident memory in MB of the largest process it ran (from ``wait4``), and its output. The whole process group
    is killed at ``timeout``."""
    started = time.perf_counter()
    process = subprocess.Popen(
        ["bash", "-c", script],
        cwd=cwd,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    output: list[str] = []
    reader = threading.Thread(target=lambda: output.append(process.stdout.read()), daemon=True)
    reader.start()
    timer = threading.Timer(timeout, lambda: os.killpg(process.pid, signal.SIGKILL))
    timer.start()
    try:
        _, status, usage = os.wait4(process.pid, 0)
    finally:
        timer.cancel()
    reader.join()
    process.returncode = os.waitstatus_to_exitcode(status)
    return (
        process.returncode,
        time.perf_counter() - started,
        usage.ru_utime + usage.ru_stime,
        usage.ru_maxrss / 1024,
        "".join(output),
    )


class Scratch:
    """A copy of the checkout's files (tracked, and new ones git does not ignore, with numba's cache of the compiled
    solvers) with ``../shared`` beside it, the running virtual environment as ``.venv`` and the glTF validator of
    ``.ci/node`` when installed; staged in
    a git index of its own so that :meth:`changes` lists what the commands left in it."""

    def __init__(self, folder: Path, root: Path = REPO_ROOT, venv: Path = Path(sys.prefix)):
        self.folder, self.root = folder, folder / "checkout"
        self.tmp = folder / "tmp"
        self.tmp.mkdir(parents=True)
        listed = subprocess.run(
            ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
            cwd=root,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.split("\0")
        for name in filter(None, listed):
            if (root / name).is_file():
                (self.root / name).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(root / name, self.root / name)
        # numba's compiled solvers, cached beside the sources (valid while a source's time and size are the same,
        # which copy2 keeps): without them every scratch copy compiles them again, about 12 s per document
        for cached in (root / "workbench").rglob("__pycache__/*.nb[ic]"):
            (self.root / cached.relative_to(root)).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(cached, self.root / cached.relative_to(root))
        (self.root / ".venv").symlink_to(venv)
        if (root / ".ci" / "node").is_dir():
            (self.root / ".ci" / "node").symlink_to(root / ".ci" / "node")
        shared = root.parent / "shared"
        if os.environ.get("WORKBENCH_DATA_ROOT"):
            (folder / "shared").mkdir()
            (folder / "shared" / "data").symlink_to(Path(os.environ["WORKBENCH_DATA_ROOT"]).resolve())
        elif shared.is_dir():
            (folder / "shared").symlink_to(shared.resolve())
        git = ["git", "-c", "core.hooksPath=/dev/null", "-C", str(self.root)]
        subprocess.run([*git, "init", "-q"], check=True)
        subprocess.run([*git, "add", "-A"], check=True)
        self.git = git
        self.env = {
            key: value
            for key, value in os.environ.items()
            if key not in ("WORKBENCH_DATA_ROOT", "VIRTUAL_ENV", "PYTHONPATH")
        }
        self.env.update(PYTHONPATH=str(self.root), TMPDIR=str(self.tmp))

    def changes(self) -> list[str]:
        """Files the commands added, changed or removed in the checkout (outside what git ignores)."""
        status = subprocess.run(
            [*self.git, "status", "--porcelain", "--untracked-files=all", "--", ".", ":!.venv", ":!.ci/node"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        return [line for line in status.splitlines() if not line.startswith("A  ")]

    def run(self, command: Command, text: str, state: list[str], timeout: float) -> Outcome:
        script = PRELUDE + "\n".join(state) + "\n" + text + "\n"
        code, seconds, cpu, peak, output = run_measured(script, self.root, self.env, timeout)
        status = "ok" if code == 0 else "skipped" if code == 77 else "failed"
        note = "" if code == 0 else "a tool is not installed" if code == 77 else f"exit {code}"
        if code == -signal.SIGKILL:
            note = f"killed after {timeout:.0f} s"
        return Outcome(command, status, seconds, cpu, peak, os.getloadavg()[0], note, output=output)


def checkout_files(root: Path) -> dict[str, tuple[int, int]]:
    """Size and modification time of every file in a scratch checkout, by path (git's folder, the linked
    environment and validator, and Python's and numba's caches aside)."""
    found = {}
    for folder, names, files in os.walk(root):
        names[:] = [name for name in names if name not in (".git", "__pycache__")]
        for name in files:
            stat = os.lstat(os.path.join(folder, name))
            found[os.path.relpath(os.path.join(folder, name), root)] = (stat.st_size, stat.st_mtime_ns)
    return found


UNSET = re.compile(r"^env((?:\s+-u\s+\w+)+)\s+")


def identity(text: str, environment: dict, heredoc: bool = False) -> str:
    """What makes two commands the same command: the text without comments (a here-document's included) and without
    an ``env -u`` of variables the environment does not set, white space normalised."""
    if not heredoc:
        text = "\n".join(strip_comment(line) for line in text.split("\n"))
    unset = UNSET.match(text)
    if unset and not any(name in environment for name in unset.group(1).split()[1::2]):
        text = text[unset.end() :]
    return normalised(text)


def repeated_commands(documented: dict[str, list[Command]], environment: dict) -> set[str]:
    """The commands (:func:`identity`) that the tests of the documents run twice or more, prerequisites included."""
    seen: dict[str, int] = {}
    for doc, listed in documented.items():
        for command in [*prerequisites(doc, documented), *listed]:
            if not not_run_reason(command):
                same = identity(command.text, environment, bool(command.heredoc))
                seen[same] = seen.get(same, 0) + 1
    return {text for text, count in seen.items() if count > 1}


class Reuse:
    """What a command wrote in a scratch copy, kept for a later run of the same command (:func:`identity`) in this
    test run: copied into the later scratch copy (its absolute paths in text files changed to the new copy's)
    instead of running the command again. The first run is checked as before.

    Kept only for a command that runs twice or more in the documents' tests, reads no output folder, has no ``cd``,
    ``source`` or ``export`` before it in its block, writes nothing or only folders its scratch copy does not hold
    yet and, when it ran, left nothing else in the checkout: the same text then writes the same folders.
    ``folder`` is shared by the run's test processes (pytest-xdist): an entry appears whole (a rename), and a lock
    per command makes a process that reaches a command another one is running wait for it rather than run it beside
    it."""

    def __init__(self, folder: Path, root: Path = REPO_ROOT):
        self.folder = folder
        folder.mkdir(parents=True, exist_ok=True)
        self.repeated = repeated_commands(all_commands(root), os.environ)

    def run(self, scratch: Scratch, command: Command, text: str, state: list[str], timeout: float) -> Outcome:
        made = sorted(writes(command))
        fresh = not any((scratch.root / path).exists() for path in made)
        repeated = identity(command.text, scratch.env, bool(command.heredoc)) in self.repeated
        kept = repeated and fresh and not reads(command)
        if not kept or state or str(scratch.folder) in text:
            return scratch.run(command, text, state, timeout)
        same = identity(text, scratch.env, bool(command.heredoc))
        entry = self.folder / hashlib.sha1(same.encode()).hexdigest()[:16]
        with open(f"{entry}.lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            if entry.is_dir():
                return self.take(entry, scratch, command, made)
            before = checkout_files(scratch.root)
            outcome = scratch.run(command, text, state, timeout)
            after = checkout_files(scratch.root)
            changed = {path for path in before.keys() | after.keys() if before.get(path) != after.get(path)}
            if outcome.status == "ok" and all(any(covers(m, path) for m in made) for path in changed):
                self.keep(entry, scratch, command, made)
            return outcome

    def keep(self, entry: Path, scratch: Scratch, command: Command, made: list[str]) -> None:
        """Keep what the command wrote, unless a file that names the scratch copy's folder cannot have it changed
        to a later copy's: not text, or checked by its run record (a ``done`` file's SHA-256)."""
        named = naming(scratch.folder, scratch.root, made)
        if any(not text or checked for text, checked in named.values()):
            return
        part = entry.with_name(f".{entry.name}.{os.getpid()}")
        (part / "files").mkdir(parents=True)
        for path in made:
            source, target = scratch.root / path, part / "files" / path
            target.parent.mkdir(parents=True, exist_ok=True)
            if source.is_dir():
                shutil.copytree(source, target, symlinks=True)
            elif source.is_file():
                shutil.copy2(source, target)
        (part / "origin").write_text("\n".join([f"{command.doc}:{command.line}", str(scratch.folder), *named]))
        os.rename(part, entry)

    def take(self, entry: Path, scratch: Scratch, command: Command, made: list[str]) -> Outcome:
        started = time.perf_counter()
        where, origin, *named = (entry / "origin").read_text().split("\n")
        shutil.copytree(entry / "files", scratch.root, symlinks=True, dirs_exist_ok=True)
        for name in named:
            file = scratch.root / name
            file.write_bytes(file.read_bytes().replace(origin.encode(), str(scratch.folder).encode()))
        note = f"not run again: ran for {where} in this test run" + (", its output copied" if made else "")
        return Outcome(command, "ok", time.perf_counter() - started, load=os.getloadavg()[0], note=note)


def naming(folder: Path, root: Path, made: list[str]) -> dict[str, tuple[bool, bool]]:
    """The files under ``made`` (paths in ``root``) that name ``folder``, by path: whether each is UTF-8 text, and
    whether a run record's ``done`` file beside it checks its SHA-256."""
    files = [file for path in made for file in ([root / path] if (root / path).is_file() else (root / path).rglob("*"))]
    files = [file for file in files if file.is_file() and not file.is_symlink()]
    checked = set()
    for done in (file for file in files if file.name == "done"):
        try:
            checked |= {done.parent / name for name in json.loads(done.read_text()).get("sha256", {})}
        except (ValueError, AttributeError, UnicodeDecodeError):
            checked.add(done)  # not a record's: kept only if it does not name the folder
    named = {}
    for file in files:
        data = file.read_bytes()
        if str(folder).encode() in data:
            try:
                data.decode()
                text = True
            except UnicodeDecodeError:
                text = False
            named[file.relative_to(root).as_posix()] = (text, file in checked or file.name == "done")
    return named


def table_rows(root: Path = REPO_ROOT) -> dict[str, list[str]]:
    """The measured rows of docs/commands.md by command key: the cells page:line, command, wall time, CPU time,
    peak memory, doc test, measured, key."""
    path = root / TIMES_DOC
    if not path.is_file() or TABLE_START not in path.read_text():
        return {}
    rows = path.read_text().split(TABLE_START)[1].split(TABLE_END)[0]
    cells = [
        [cell.strip() for cell in re.split(r"(?<!\\)\|", line.strip())[1:-1]]
        for line in rows.splitlines()
        if line.startswith("|")
    ]
    return {row[-1].strip("`"): row for row in cells}


def measured_times(root: Path = REPO_ROOT) -> dict[str, float]:
    """CPU seconds per command key, from docs/commands.md."""
    return {key: float(row[3].removesuffix(" s")) for key, row in table_rows(root).items()}


def run_document(
    doc: str,
    scratch: Scratch,
    *,
    measure: bool = False,
    timeout: float = 900.0,
    report=print,
    reuse: Reuse | None = None,
) -> list[Outcome]:
    """Run a document's commands (after their prerequisites from other documents) in ``scratch``. Without
    ``measure``, commands measured at a minute or more are not run (a small preset stands in for a long study whose
    folder a later command reads); with it, everything runs. With ``reuse``, a command another document ran in
    this test run may have its output copied instead (:class:`Reuse`)."""
    run = scratch.run if reuse is None else lambda *args: reuse.run(scratch, *args)
    documented = all_commands(scratch.root)
    times = measured_times(scratch.root)
    outcomes: list[Outcome] = []
    planned = [(command, True) for command in prerequisites(doc, documented)]
    planned += [(command, False) for command in documented[doc]]
    # the same command again (another comment, a later block) is as long as its first run: measured after that, it
    # only resumed the complete records
    slowest: dict[str, float] = {}
    for command, _ in planned:
        slowest[command.code] = max(slowest.get(command.code, 0.0), times.get(command.key, 0.0))
    state: dict[tuple[str, int], list[str]] = {}
    skip_block: set[tuple[str, int]] = set()
    small: set[str] = set()  # studies that ran as their small preset: later runs of them do too
    for index, (command, prerequisite) in enumerate(planned):
        block = (command.doc, command.block)
        lines = state.setdefault(block, [])
        later_reads = {path for other, _ in planned[index + 1 :] for path in reads(other)}
        needed = prerequisite or any(covers(made, path) for made in writes(command) for path in later_reads)
        why = not_run_reason(command)
        # a long command runs only where a later one reads what it makes: a study as its small preset
        long = (prerequisite or not measure) and slowest[command.code] >= LONG_SECONDS
        instead = stand_in(command, needed, scratch.root) if long else None
        follows = instead is None and not long and study_of(command) in small
        if follows:
            instead = stand_in(command, True, scratch.root)
        if block in skip_block or why:
            outcome = Outcome(command, "skipped", note=why or "a tool of its block is not installed")
        elif long and not needed:
            outcome = Outcome(command, "long", note=f"{slowest[command.code]:.0f} CPU s measured")
        elif instead is not None:
            outcome = run(
                command,
                runnable(Command(command.doc, command.line, command.block, instead), scratch.tmp),
                lines,
                timeout,
            )
            copied = f" ({outcome.note})" if outcome.note else ""
            reason = (
                "its study ran as its small preset above" if follows else f"{slowest[command.code]:.0f} CPU s measured"
            )
            outcome.note = f"{reason}; ran {instead}{copied}"
            small.add(study_of(command))
        else:
            outcome = run(command, runnable(command, scratch.tmp), lines, timeout)
        outcome.prerequisite = prerequisite
        if outcome.status == "skipped" and outcome.note.startswith("a tool"):
            skip_block.add(block)
        if STATE.match(command.code) and outcome.status == "ok":
            lines.append(runnable(command, scratch.tmp))
        outcomes.append(outcome)
        report(
            f"{outcome.status:8s} {outcome.seconds:7.1f} s {outcome.cpu_seconds:7.1f} s CPU {outcome.peak_mb:7.0f} MB"
            f" load {outcome.load:4.1f}  {command.doc}:{command.line}"
            f"{' (prerequisite)' if prerequisite else ''}  {command.summary}  {outcome.note}"
        )
        if outcome.status == "failed" and not measure:
            break
    return outcomes


# --- docs/commands.md -------------------------------------------------------------------------------------------

TABLE_START = "<!-- measured rows: written by tests/doc_blocks.py measure -->"
TABLE_END = "<!-- end of measured rows -->"


def write_times(outcomes: list[Outcome], root: Path = REPO_ROOT) -> None:
    """Replace the rows of the measured commands in docs/commands.md (rows of other commands are kept, at their
    current page and line, while they are still documented), in the order of the documents."""
    path = root / TIMES_DOC
    head, rest = path.read_text().split(TABLE_START)
    tail = rest.split(TABLE_END)[1]
    rows = {key: "| " + " | ".join(cells) + " |" for key, cells in table_rows(root).items()}
    date = time.strftime("%Y-%m-%d")
    for outcome in outcomes:
        if outcome.status != "ok" or outcome.prerequisite:
            continue
        command = outcome.command
        long = "long: not run" if outcome.cpu_seconds >= LONG_SECONDS else "run"
        shown = command.summary.replace("|", "\\|")
        rows[command.key] = (
            f"| {command.doc}:{command.line} | `{shown}` | {outcome.seconds:.0f} s | "
            f"{outcome.cpu_seconds:.0f} s | {outcome.peak_mb / 1024:.1f} GB | {long} | {date}, "
            f"load {outcome.load:.1f} | `{command.key}` |"
        )
    places = {
        command.key: f"{command.doc}:{command.line}" for listed in all_commands(root).values() for command in listed
    }
    kept = [re.sub(r"^\| [^|]+ \|", f"| {place} |", rows[key], count=1) for key, place in places.items() if key in rows]
    path.write_text(head + TABLE_START + "\n" + "".join(row + "\n" for row in kept) + TABLE_END + tail)


def main(argv: list[str]) -> int:
    import tempfile

    if not argv or argv[0] != "measure":
        print(__doc__)
        return 2
    docs = argv[1:] or documents()
    outcomes = []
    for doc in docs:
        with tempfile.TemporaryDirectory(prefix="doc-measure-") as folder:
            outcomes += run_document(
                doc, Scratch(Path(folder)), measure=True, timeout=4 * 3600, report=lambda line: print(line, flush=True)
            )
        write_times(outcomes)
    failed = [outcome for outcome in outcomes if outcome.status == "failed"]
    for outcome in failed:
        print(
            f"FAILED {outcome.command.doc}:{outcome.command.line}: {outcome.command.summary}\n{outcome.output[-3000:]}"
        )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
