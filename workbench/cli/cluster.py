"""A study's sweep on a SLURM cluster (``hydra/launcher=slurm``, extra: cluster).

Hydra's submitit launcher submits one array job, one task per run, and waits for them. The workbench's launcher
(``hydra_plugins/workbench_slurm``) keeps that and changes three things a lab cluster needs:

- runs whose folder already holds a complete record of the same config are not submitted again (one ``skip``
  line each), so resubmitting an interrupted sweep queues only the missing runs;
- job states come from ``squeue`` when the cluster keeps no accounting (``sacct`` says "Slurm accounting storage
  is disabled"): one line says so, instead of a warning at every poll, and a cancelled task is seen as ended
  instead of being waited for forever;
- when tasks end without a result (cancelled, timed out, failed), the launcher waits for the whole array, then
  stops with one line naming each such task, its state and its log, and how to resume.
"""

from __future__ import annotations

import logging
import subprocess
import time
from pathlib import Path
from typing import Any, Sequence

from submitit.slurm.slurm import SlurmExecutor, SlurmInfoWatcher, SlurmJob, read_job_id

from workbench.core.errors import WorkbenchError

log = logging.getLogger("workbench.cli.cluster")

LEFT_QUEUE = "LEFT_QUEUE"
"""State of a task that squeue no longer lists (ended longer than the cluster's MinJobAge ago)."""


def accounting_disabled(stderr: str) -> bool:
    """Whether sacct's error output says the cluster keeps no accounting."""
    return "accounting storage is disabled" in stderr.lower()


def squeue_states(text: str) -> dict[str, dict[str, str]]:
    """Job states from ``squeue --noheader --array --format=%i|%T|%N`` output, by job id (``123_4`` for array
    tasks; a pending range ``123_[5-9]`` gives every task of it)."""
    states = {}
    for line in text.splitlines():
        fields = line.strip().split("|")
        if len(fields) != 3:
            continue
        job_id, state, nodes = fields
        info = {"JobID": job_id, "State": state, "NodeList": nodes}
        for parts in read_job_id(job_id):
            states["_".join(parts[:2])] = info
            if len(parts) == 3:
                states.update({f"{parts[0]}_{index}": info for index in range(int(parts[1]), int(parts[2]) + 1)})
    return states


class QueueWatcher(SlurmInfoWatcher):
    """Job states from ``sacct``, or from ``squeue`` on a cluster without accounting."""

    def __init__(self, delay_s: int = 60) -> None:
        super().__init__(delay_s=delay_s)
        self.use_squeue = False

    def _make_command(self) -> list[str] | None:
        if not self.use_squeue:
            return super()._make_command()
        to_check = sorted({job_id.split("_")[0] for job_id in self._registered - self._finished})
        if not to_check:
            return None
        return ["squeue", "--noheader", "--array", "--states=all", "--format=%i|%T|%N", "--jobs=" + ",".join(to_check)]

    def update(self) -> None:
        command = self._make_command()
        if command is None:
            return
        self._num_calls += 1
        try:
            done = subprocess.run(command, capture_output=True, text=True, timeout=120)
        except (OSError, subprocess.SubprocessError) as error:
            if command[0] == "sacct" and isinstance(error, FileNotFoundError):
                self._switch_to_squeue("sacct is not installed")
                return self.update()
            log.debug(f"{command[0]} failed ({error}); job states kept as they were")
            return
        if command[0] == "sacct":
            if done.returncode != 0 and accounting_disabled(done.stderr):
                self._switch_to_squeue(f"sacct: {done.stderr.strip().splitlines()[0]}")
                return self.update()
            if done.returncode == 0:
                self._output = done.stdout.encode()
                self._info_dict.update(self.read_info(done.stdout))
        elif done.returncode == 0 or "invalid job id" in done.stderr.lower():
            states = squeue_states(done.stdout if done.returncode == 0 else "")
            for job_id in self._registered - self._finished:
                self._info_dict[job_id] = states.get(job_id, {"JobID": job_id, "State": LEFT_QUEUE})
        else:
            log.debug(f"squeue failed ({done.stderr.strip()}); job states kept as they were")
        self._last_status_check = time.time()
        for job_id in self._registered - self._finished:
            if self.is_done(job_id, mode="cache"):
                self._finished.add(job_id)

    def _switch_to_squeue(self, why: str) -> None:
        self.use_squeue = True
        log.info(f"SLURM keeps no job accounting on this cluster ({why}): job states are read from squeue")


WATCHER = QueueWatcher(delay_s=60)
"""Watches the jobs of every sweep this process submits (submitit's own watcher asks sacct only)."""


def watched(job: SlurmJob) -> SlurmJob:
    """``job`` with its state read by :data:`WATCHER`."""
    job.watcher = WATCHER
    WATCHER.register_job(job.job_id)
    return job


class ArrayExecutor(SlurmExecutor):
    """submitit's SLURM executor taking the launcher's generic parameter names (``timeout_min``, ``mem_gb``,
    ``tasks_per_node``, ...) as Hydra's submitit launcher does."""

    def set_parameters(self, **params: Any) -> None:
        self.update_parameters(**self._convert_parameters(params))


def complete_runs(launcher, job_overrides: Sequence[Sequence[str]]) -> dict[int, Path]:
    """The runs of a sweep whose folder holds a complete record of the same config, by position in the sweep.

    A folder holding a complete record of another config is left to the run itself, which refuses it in one line.
    """
    from hydra.core.hydra_config import HydraConfig

    from workbench.record.record import config_hash, record_state
    from workbench.record.tracking import recorded_config_hash
    from workbench.settings.config import resolved_yaml_text

    found = {}
    for index, overrides in enumerate(job_overrides):
        sweep_config = launcher.hydra_context.config_loader.load_sweep_config(launcher.config, list(overrides))
        HydraConfig.instance().set_config(sweep_config)
        folder = Path(str(sweep_config.hydra.sweep.dir)) / str(sweep_config.hydra.sweep.subdir)
        if record_state(folder) == "complete" and recorded_config_hash(folder) == config_hash(
            resolved_yaml_text(sweep_config)
        ):
            found[index] = folder
    HydraConfig.instance().set_config(launcher.config)
    return found


def skipped_return(launcher, overrides: Sequence[str], folder: Path):
    """The Hydra job return of a run that was not submitted because its record is complete."""
    from hydra.core.utils import JobReturn, JobStatus

    sweep_config = launcher.hydra_context.config_loader.load_sweep_config(launcher.config, list(overrides))
    return JobReturn(
        overrides=list(overrides),
        cfg=sweep_config,
        hydra_cfg=sweep_config,
        working_dir=str(folder),
        task_name=str(sweep_config.hydra.job.name),
        status=JobStatus.COMPLETED,
        _return_value=None,
    )


def unfinished_line(job, overrides: Sequence[str]) -> str:
    """``<job id> (<overrides>): <state>, <last line of its error log>`` for a task that left no result."""
    from hydra.core.utils import filter_overrides

    state = job.watcher.get_state(job.job_id, mode="cache")
    last = ""
    if job.paths.stderr.is_file():
        lines = [line.strip() for line in job.paths.stderr.read_text(errors="replace").splitlines() if line.strip()]
        # the run's own error line, or SLURM's line saying why the task ended, else the last line
        telling = [line for line in lines if "workbench: error" in line or "***" in line]
        last = (telling or lines or [""])[-1]
    return (
        f"{job.job_id} ({' '.join(filter_overrides(overrides))}): {state}"
        + (f", '{last[:200]}'" if last else "")
        + f" [log {job.paths.stderr}]"
    )


def launch(launcher, job_overrides: Sequence[Sequence[str]], initial_job_idx: int) -> list:
    """Submit the runs of a sweep that are not complete yet as one SLURM array job, wait for every task and return
    Hydra's job returns in sweep order.

    Parameters
    ----------
    launcher : hydra_plugins.workbench_slurm.workbench_slurm.WorkbenchSlurmLauncher
        Holds the launcher's parameters, Hydra's context and the sweep's config.
    job_overrides : sequence of sequence of str
        Each run's sweep overrides.
    initial_job_idx : int
        Hydra's number of the first run.

    Raises
    ------
    WorkbenchError
        When tasks ended without a result: one line naming each, after every task has ended.
    """
    from hydra.core.singleton import Singleton
    from hydra.core.utils import filter_overrides

    params = dict(launcher.params)
    folder = params.pop("submitit_folder")
    executor = ArrayExecutor(folder=folder, max_num_timeout=params.pop("max_num_timeout", 0))
    executor.set_parameters(**params)
    sweep_dir = Path(str(launcher.config.hydra.sweep.dir))
    sweep_dir.mkdir(parents=True, exist_ok=True)

    complete = complete_runs(launcher, job_overrides)
    from workbench.cli.main import shown_folder
    from workbench.reporting.tables.width import printed

    for index, run_folder in complete.items():
        log.info(printed(f"skip {shown_folder(run_folder)}: complete record, not submitted"))
    pending = [index for index in range(len(job_overrides)) if index not in complete]
    jobs = []
    if pending:
        job_params = [
            (
                list(job_overrides[index]),
                "hydra.sweep.dir",
                initial_job_idx + index,
                f"job_id_for_{initial_job_idx + index}",
                Singleton.get_state(),
            )
            for index in pending
        ]
        jobs = [watched(job) for job in executor.map_array(launcher, *zip(*job_params))]
        array_id = jobs[0].job_id.split("_")[0]
        log.info(
            f"submitted SLURM array job {array_id}: {len(jobs)} of {len(job_overrides)} runs "
            f"(partition {params.get('partition') or 'default'}); job logs in "
            f"{str(folder).replace('%j', array_id + '_<task>') if len(jobs) > 1 else jobs[0].paths.folder}"
        )
        for index, job in zip(pending, jobs):
            log.info(f"\t{job.job_id} : {' '.join(filter_overrides(job_overrides[index]))}")
    results, unfinished = {}, []
    for index, job in zip(pending, jobs):
        error = job.exception()  # waits for the task to end
        if error is None:
            results[index] = job.results()[0]
        else:
            unfinished.append(unfinished_line(job, job_overrides[index]))
    if unfinished:
        raise WorkbenchError(
            f"{len(unfinished)} of {len(jobs)} submitted runs ended without a result: {'; '.join(unfinished)}. "
            "Complete records are kept: submit the same command again to run only the missing ones"
        )
    for index, run_folder in complete.items():
        results[index] = skipped_return(launcher, job_overrides[index], run_folder)
    return [results[index] for index in range(len(job_overrides))]
