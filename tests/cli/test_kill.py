"""Real process kills (SIGKILL) at random points never leave a half-written record.

A run writes each record file atomically (a temporary ``.<name>.<random>.tmp`` beside it, then a rename) and the
``done`` marker last (:mod:`workbench.record.record`). So a folder a killed run leaves holds either a complete record
(``done`` and every file whole) or no ``done``, and then only whole files and perhaps one temporary file; running
the same command again clears it and completes the record (:mod:`workbench.record.tracking`).

The kills are drawn from a seeded generator: most uniformly over the measured duration of a run, some in the
window in which the record is being written (after the run's first record file appears), where a non-atomic writer
would be caught. Each killed run is followed by the same command into the same folder, which is itself killed (so
kills also fall while a rerun clears what the last one left), until a last run completes the record. Two such
chains run side by side (the machine has two cores; a run is mostly Python start-up). A killed tracked sweep is
checked the same way, run folder by run folder and its collected tables, and then resumed.
"""

import json
import os
import re
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from workbench.core.files import OUTPUT_MARKER, TEMPORARY_SUFFIX
from workbench.core.files import sha256_of_file as file_checksum
from workbench.record.tracking import DONE, LOCK_FILE, record_state
from workbench.settings.config import REPO_ROOT

RUN = ["dataset.n_frames=300", "solver=lstsq", "save_inputs=true", "basis.paper_regime=false"]  # one inputs.npz
SWEEP = [
    "--config-name",
    "coverage",
    "dataset.n_frames=300",
    "dataset.seed=0",
    "basis.coverage=0.9,0.99",
    "save_inputs=true",
]
PARALLEL = 2
"""Processes at a time (the machine has two cores)."""
N_UNIFORM = 7
"""Kills per chain at a delay drawn uniformly over (a little more than) a run's duration."""
N_WRITING = 4
"""Kills per chain at a delay drawn uniformly over the record-writing window, after the run's first file appears."""
N_SWEEPS = 2
SEED = 20261123

RECORD_FILES = (
    "config.yaml",
    "alpha_table.csv",
    "alpha_table.md",
    "metrics.json",
    "timings.json",
    "inputs.npz",
    "alpha_per_frame.npz",
    DONE,
)
SAME_BYTES = ("config.yaml", "alpha_table.csv", "alpha_table.md")
"""Files whose content is the same in every run of the same config."""
LOG_FILES = ("workbench.log",)
"""What the run printed, in every run folder (a plain run's also holds Hydra's ``.hydra`` folder): not the record."""
COLLECTED_FILES = (
    "runs.csv",
    "runs.parquet",
    "summary.csv",
    "summary.parquet",
    "comparisons.csv",
    "comparisons.md",
    "alpha_table.md",
    "alpha_table.tex",
    "findings.md",
    OUTPUT_MARKER,  # what the workbench wrote there (core.files.output_folder)
)
TEMPORARY = re.compile(r"^\.(?P<name>.+)\.[A-Za-z0-9_]+" + re.escape(TEMPORARY_SUFFIX) + "$")


def command(*arguments: str) -> list[str]:
    return [sys.executable, "-m", "workbench", *arguments]


@dataclass
class Job:
    """One process of the workbench, killed by a rule or left to finish.

    ``kill`` is None (run to the end), ``("after", seconds)`` from the start, or ``("writing", seconds)`` after
    ``watch`` (a file of the record) appears.
    """

    arguments: list
    cwd: Path
    log: Path
    kill: tuple | None = None
    watch: Path | None = None
    process: subprocess.Popen | None = None
    started: float = 0.0
    due: float | None = None
    duration: float | None = None
    killed: bool = False
    output: dict = field(default_factory=dict)
    watched_before: int | None = None

    def start(self) -> None:
        self.watched_before = _inode(self.watch)
        self.log.parent.mkdir(parents=True, exist_ok=True)
        with open(self.log, "wb") as out, open(self.log.with_suffix(".err"), "wb") as err:
            self.process = subprocess.Popen(
                command(*self.arguments),
                cwd=self.cwd,
                stdout=out,
                stderr=err,
                env=dict(os.environ, PYTHONPATH=str(REPO_ROOT)),
                start_new_session=True,
            )
        self.started = time.monotonic()
        if self.kill is not None and self.kill[0] == "after":
            self.due = self.started + self.kill[1]

    def step(self) -> bool:
        """Kill when due; True once the process has ended."""
        if self.process.poll() is not None:
            self.duration = self.duration or time.monotonic() - self.started
            return True
        now = time.monotonic()
        if (
            self.kill is not None
            and self.due is None
            and self.kill[0] == "writing"
            and _inode(self.watch) not in (None, self.watched_before)
        ):
            self.due = now + self.kill[1]
        if self.due is not None and now >= self.due:
            os.killpg(self.process.pid, signal.SIGKILL)
            self.process.wait()
            self.killed = True
            return True
        return False

    def finish(self) -> None:
        self.output = {
            "returncode": self.process.returncode,
            "stdout": self.log.read_text(),
            "stderr": self.log.with_suffix(".err").read_text(),
        }


def _inode(path: Path | None) -> int | None:
    try:
        return path.stat().st_ino if path is not None else None
    except FileNotFoundError:
        return None


def run_chains(chains, timeout: float = 300.0) -> None:
    """Run chains of jobs side by side, polling every 2 ms to kill each job when its rule says.

    A chain is a generator that yields a :class:`Job`, is resumed when that job has ended (to check what it left
    and yield the next one) and returns when it is done; so its jobs run one after another, the chains in parallel.
    """
    active = {}
    try:
        for chain in chains:
            active[chain] = next(chain)
            active[chain].start()
        deadline = time.monotonic() + timeout
        while active:
            for chain, job in list(active.items()):
                if not job.step():
                    continue
                job.finish()
                try:
                    active[chain] = chain.send(None)
                    active[chain].start()
                except StopIteration:
                    del active[chain]
            assert time.monotonic() < deadline, "the jobs did not end in time"
            time.sleep(0.002)
    finally:
        for job in active.values():
            if job.process is not None and job.process.poll() is None:
                os.killpg(job.process.pid, signal.SIGKILL)
                job.process.wait()


def run_jobs(jobs, timeout: float = 300.0) -> None:
    """Run jobs side by side (each its own chain)."""

    def single(job):
        yield job

    run_chains([single(job) for job in jobs], timeout)


def npz_arrays(path: Path) -> dict:
    with np.load(path, allow_pickle=False) as stored:
        return {name: stored[name] for name in stored.files}


def parse(path: Path):
    """Read a record or collected file completely; any half-written file fails here."""
    name = path.name
    if name == DONE:  # the checksums of the record's other files, each matching
        checksums = json.loads(path.read_text())["sha256"]
        for other, digest in checksums.items():
            assert file_checksum(path.parent / other) == digest, f"{path.parent / other}: checksum differs"
        return checksums
    if name.endswith(".npz"):
        return npz_arrays(path)
    if name.endswith(".json"):
        return json.loads(path.read_text())
    if name.endswith(".yaml"):
        value = yaml.safe_load(path.read_text())
        assert isinstance(value, dict), path
        return value
    if name.endswith(".csv"):
        return pd.read_csv(path)
    if name.endswith(".parquet"):
        return pd.read_parquet(path)
    text = path.read_text()
    assert text.strip(), f"{path} is empty"
    return text


def temporary_of(name: str) -> str | None:
    """The final name a temporary file was being written for, or None if ``name`` is not a temporary file."""
    match = TEMPORARY.match(name)
    return match.group("name") if match else None


def check_run_folder(folder: Path, reference: Path, *, hydra_files: bool) -> str:
    """Check a run folder against a complete reference record of the same config.

    Returns
    -------
    str
        ``complete``, ``partial`` (no ``done``, some whole record files) or ``empty`` (no record file).
    """
    if not folder.exists():
        return "empty"
    names = sorted(path.name for path in folder.iterdir() if path.is_file())
    if hydra_files:
        assert {path.name for path in folder.iterdir() if path.is_dir()} <= {".hydra"}, folder
    temporary = [name for name in names if temporary_of(name) is not None]
    assert all(temporary_of(name) in RECORD_FILES for name in temporary), temporary
    unknown = set(names) - set(RECORD_FILES) - set(temporary) - {LOCK_FILE} - set(LOG_FILES)
    assert not unknown, f"{folder}: files that are no part of a record: {unknown}"
    present = [name for name in names if name in RECORD_FILES]
    for name in present:  # every file there is whole: it parses, and equals the reference where that is fixed
        value = parse(folder / name)
        if name in SAME_BYTES:
            assert (folder / name).read_bytes() == (reference / name).read_bytes(), f"{folder / name} differs"
        elif name.endswith(".npz"):
            expected = npz_arrays(reference / name)
            assert value.keys() == expected.keys(), name
            for key in expected:
                np.testing.assert_array_equal(value[key], expected[key], err_msg=f"{folder / name}[{key}]")
        else:
            assert value.keys() == parse(reference / name).keys(), f"{folder / name}: keys differ"
    if DONE in names:
        assert record_state(folder) == "complete"
        assert set(RECORD_FILES) <= set(names), f"{folder}: done without {set(RECORD_FILES) - set(names)}"
        assert not temporary, f"{folder}: a complete record with temporary files {temporary}"
        assert (
            json.loads((folder / "metrics.json").read_text())["config_hash"]
            == json.loads((reference / "metrics.json").read_text())["config_hash"]
        )
        return "complete"
    return "partial" if present else "empty"


def snapshot(folder: Path) -> dict:
    return {
        path.name: (path.stat().st_ino, path.stat().st_mtime_ns, path.read_bytes())
        for path in sorted(folder.iterdir())
        if path.is_file()
    }


def kill_chain(number: int, root: Path, reference: Path, rules: list, outcomes: list):
    """Kill runs of the same command one after another by ``rules``; each starts in the folder the last one left
    (so it is also the rerun that must clear and redo that folder), and a new folder follows a complete record. A
    last run is not killed and must complete the record. Appends (folder, state after the kill) to ``outcomes``."""
    folders = [root / f"chain{number}_run0"]
    for trial, rule in enumerate(rules):
        folder = folders[-1]
        yield Job(
            RUN + [f"hydra.run.dir={folder}"],
            root,
            root / "logs" / f"chain{number}_{trial:02d}.log",
            kill=rule,
            watch=folder / "config.yaml",
        )
        state = check_run_folder(folder, reference, hydra_files=True)
        outcomes.append((folder, rule, state))
        if state == "complete":
            folders.append(root / f"chain{number}_run{len(folders)}")
    last = Job(RUN + [f"hydra.run.dir={folders[-1]}"], root, root / "logs" / f"chain{number}_last.log")
    yield last
    assert last.output["returncode"] == 0, last.output["stderr"]
    # Every folder of the chain now holds a complete record, with nothing a killed run left.
    for folder in folders:
        assert check_run_folder(folder, reference, hydra_files=True) == "complete"
    # The same command on a complete record skips it and touches nothing of it. A run killed after writing `done`
    # and before removing its lock file leaves that file beside the complete record; the skipping run removes it,
    # as every run ending on a complete record does (workbench.record.tracking.release_run_dir).
    before = snapshot(folders[0])
    before.pop(LOCK_FILE, None)
    again = Job(RUN + [f"hydra.run.dir={folders[0]}"], root, root / "logs" / f"chain{number}_again.log")
    yield again
    assert again.output["returncode"] == 0 and again.output["stdout"].startswith("skip "), again.output["stdout"]
    named = again.output["stdout"].split(":")[0].removeprefix("skip ")  # relative to the working folder
    assert (root / named).resolve() == Path(folders[0]).resolve(), again.output["stdout"]
    assert snapshot(folders[0]) == before, f"{folders[0]}: a complete record was touched"


@pytest.mark.process
@pytest.mark.slow
class TestKilledRuns:  # a class: a scope of its own for pytest-xdist, as TestKilledSweeps (each of both processes)
    def test_runs_killed_at_random_points_leave_whole_records_or_none(self, tmp_path):
        rng = np.random.default_rng(SEED)
        # Complete runs side by side measure the duration and the record-writing window, and are the reference.
        references = [
            Job(RUN + [f"hydra.run.dir={tmp_path / f'reference{i}'}"], tmp_path, tmp_path / f"reference{i}.log")
            for i in range(PARALLEL)
        ]
        run_jobs(references)
        for job in references:
            assert job.output["returncode"] == 0, job.output["stderr"]
        reference = tmp_path / "reference0"
        assert check_run_folder(reference, tmp_path / "reference1", hydra_files=True) == "complete"
        duration = float(np.median([job.duration for job in references]))
        writing = float(
            np.median(
                [
                    (
                        (tmp_path / f"reference{i}" / DONE).stat().st_mtime_ns
                        - (tmp_path / f"reference{i}" / "config.yaml").stat().st_mtime_ns
                    )
                    / 1e9
                    for i in range(PARALLEL)
                ]
            )
        )
        assert 0 < writing < duration

        chains, outcomes = [], []
        for number in range(PARALLEL):
            rules = [("after", float(delay)) for delay in rng.uniform(0.0, 1.1 * duration, N_UNIFORM)] + [
                ("writing", float(delay)) for delay in rng.uniform(0.0, writing, N_WRITING)
            ]
            rules = [rules[i] for i in rng.permutation(len(rules))]
            chains.append(kill_chain(number, tmp_path, reference, rules, outcomes))
        run_chains(chains)

        states = [state for _, _, state in outcomes]
        assert len(states) == PARALLEL * (N_UNIFORM + N_WRITING) >= 20
        assert "partial" in states, f"no kill fell while a record was written: {outcomes}"
        assert "empty" in states, f"no kill fell before a record: {outcomes}"


@pytest.mark.process
@pytest.mark.slow
class TestKilledSweeps:
    def test_killed_tracked_sweeps_resume_to_the_uninterrupted_result(self, tmp_path):
        rng = np.random.default_rng(SEED + 1)
        reference_job = Job(SWEEP + [f"hydra.sweep.dir={tmp_path / 'reference'}"], tmp_path, tmp_path / "reference.log")
        run_jobs([reference_job])
        assert reference_job.output["returncode"] == 0, reference_job.output["stderr"]
        reference = tmp_path / "reference"
        run_names = sorted(path.name for path in reference.iterdir() if path.is_dir() and path.name != "collected")
        assert len(run_names) == 2
        for name in run_names:
            assert check_run_folder(reference / name, reference / name, hydra_files=False) == "complete"

        delays = rng.uniform(0.3, 1.0, N_SWEEPS) * reference_job.duration
        sweeps = [
            Job(
                SWEEP + [f"hydra.sweep.dir={tmp_path / f'sweep{i}'}"],
                tmp_path,
                tmp_path / f"sweep{i}.log",
                kill=("after", float(delay)),
            )
            for i, delay in enumerate(delays)
        ]
        run_jobs(sweeps)
        before = {}
        for i in range(N_SWEEPS):
            sweep = tmp_path / f"sweep{i}"
            for name in run_names:
                if check_run_folder(sweep / name, reference / name, hydra_files=False) == "complete":
                    before[(i, name)] = snapshot(sweep / name)
            collected = sweep / "collected"
            if collected.exists():  # tables written so far are whole
                for path in collected.iterdir():
                    if temporary_of(path.name) is None:
                        assert path.name in COLLECTED_FILES, path
                        parse(path)

        resumes = [Job(job.arguments, tmp_path, tmp_path / f"resume{i}.log") for i, job in enumerate(sweeps)]
        run_jobs(resumes)
        for i, job in enumerate(resumes):
            sweep = tmp_path / f"sweep{i}"
            assert job.output["returncode"] == 0, job.output["stderr"]
            for name in run_names:
                assert check_run_folder(sweep / name, reference / name, hydra_files=False) == "complete"
                if (i, name) in before:
                    assert snapshot(sweep / name) == before[(i, name)], f"{sweep / name}: a complete record was touched"
            assert sorted(path.name for path in (sweep / "collected").iterdir()) == sorted(COLLECTED_FILES)
            assert (sweep / "collected" / "alpha_table.md").read_text() == (
                reference / "collected" / "alpha_table.md"
            ).read_text()


# ----------------------------------------------------------------------------------------------------------
# Every file the package writes goes through the atomic writer
# ----------------------------------------------------------------------------------------------------------

WRITERS = re.compile(
    r"\.write_(text|bytes)\(|\bopen\([^)]*['\"][wa]b?['\"]|\.savefig\((?!buffer)"
    r"|\.to_(csv|parquet|json)\((?!index=False\)|buffer)"
)
NOT_YET_ATOMIC: dict[str, str] = {}
"""Files allowed to fail the check (with the reason): none."""


def non_atomic_writes(path: Path) -> list[str]:
    return [
        f"{path.relative_to(REPO_ROOT)}:{number}: {line.strip()}"
        for number, line in enumerate(path.read_text().splitlines(), start=1)
        if WRITERS.search(line) and not line.lstrip().startswith("#")
    ]


def writer_cases():
    for path in sorted((REPO_ROOT / "workbench").rglob("*.py")):
        name = path.relative_to(REPO_ROOT).as_posix()
        marks = [pytest.mark.xfail(strict=True, reason=NOT_YET_ATOMIC[name])] if name in NOT_YET_ATOMIC else []
        yield pytest.param(path, marks=marks, id=name)


@pytest.mark.parametrize("path", list(writer_cases()))
def test_files_are_written_through_the_atomic_writer(path):
    """Records, tables and reports are written by :func:`workbench.core.files.write_atomic` only."""
    assert non_atomic_writes(path) == []


def test_the_writer_check_sees_writes():
    """The pattern above finds the usual ways of writing a file (guards against a vacuous pass)."""
    lines = [
        'path.write_text("x")',
        'open(path, "w")',
        "open(path, 'wb')",
        'figure.savefig(path, format="svg")',
        'table.to_csv(out / "runs.csv", index=False)',
    ]
    assert all(WRITERS.search(line) for line in lines)
    assert not any(
        WRITERS.search(line)
        for line in [
            "table.to_csv(index=False)",
            "figure.savefig(buffer)",
            'open(path, "rb")',
            "write_atomic(path, text)",
        ]
    )
