"""The workbench's SLURM launcher (``hydra/launcher=slurm``): Hydra's submitit launcher with the changes of
:mod:`workbench.cli.cluster` (complete runs not resubmitted, job states without accounting, one line for tasks that
ended without a result). Hydra takes launchers only from the ``hydra_plugins`` package; the work is done in
:mod:`workbench.cli.cluster`, imported when a sweep is launched."""

try:
    from hydra_plugins.hydra_submitit_launcher.submitit_launcher import BaseSubmititLauncher
except ImportError:  # the cluster extra is not installed: no launcher to offer
    BaseSubmititLauncher = None

if BaseSubmititLauncher is not None:

    class WorkbenchSlurmLauncher(BaseSubmititLauncher):
        _EXECUTOR = "slurm"

        def launch(self, job_overrides, initial_job_idx):
            from workbench.cli.cluster import launch

            return launch(self, job_overrides, initial_job_idx)
