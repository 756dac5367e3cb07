"""Bad input that was accepted silently, crashed or was reported without naming its culprit: each case is one
line naming the setting or the file and the rule it breaks (exit 2 on the command line).

The tiny face, its data root and its C3D writer are those of ``test_bad_input.py``.
"""

import re
import struct

import numpy as np
import pytest
from test_bad_input import tiny_config, tiny_root, write_c3d  # noqa: F401 - tiny_root is a fixture

from workbench.core.errors import WorkbenchError
from workbench.dataset import build_captures
from workbench.formats.c3d import read_c3d_markers
from workbench.formats.weight_curves import read_weight_curves
from workbench.settings.config import compose
from workbench.settings.schema import check_study_config

SMALL = ["dataset.n_frames=200", "solver=lstsq"]


# ----------------------------------------------------------------------------------------------------------
# Settings: keys no schema knows are refused whatever the prefix; the weight curves' frame rate has a range
# ----------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "override, message",
    [
        ("+basis.nope=1", "setting basis.nope does not exist; basis has ["),
        ("++basis.nope=1", "setting basis.nope does not exist; basis has ["),
        ("+paths.nope=1", "setting paths.nope does not exist; paths has ['cache_dir', 'data_root', 'output_root']"),
        ("+basis.hand_basis=x", "setting basis.hand_basis does not exist (did you mean dataset.hand_basis?)"),
        ("+metric.nope=1", "setting metric.nope does not exist"),
        (
            "+solver.lstsq.nope=1",
            "setting solver.lstsq.nope does not exist; solver.lstsq has ['kind', 'lower', 'upper']",
        ),
        ("+basis.spca.nope=1", "setting basis.spca.nope does not exist; basis.spca has ['alpha', 'max_iter']"),
        ("+paper.alpha.X=3", "setting paper.alpha.X does not exist; paper.alpha has ['H', 'PCA', 'QE']"),
        (
            "++dataset.foo=1",
            "dataset.foo has no effect with dataset=synthetic: dataset kind 'synthetic' has no such setting",
        ),
    ],
)
def test_unknown_keys_are_refused_whatever_the_prefix(override, message):
    cfg = compose("paper", SMALL + [override])
    with pytest.raises(WorkbenchError, match=re.escape(message)) as error:
        check_study_config(cfg, [override], refuse_ineffective=True)
    assert "\n" not in str(error.value)


def test_dataset_settings_added_with_plus_are_still_taken():
    cfg = compose(
        "paper",
        [
            "dataset=ict_livelink",
            "+dataset.weight_curves=take.json",
            "+dataset.weight_frame_rate=30",
            "+dataset.eval_on=mesh",
        ],
    )
    check_study_config(cfg)


@pytest.mark.parametrize("rate", ["-30", "0", "1e9"])
def test_weight_frame_rate_must_be_a_capture_rate(rate):
    cfg = compose(
        "paper", ["dataset=ict_livelink", "+dataset.weight_curves=take.json", f"+dataset.weight_frame_rate={rate}"]
    )
    with pytest.raises(WorkbenchError, match=r"^dataset\.weight_frame_rate must be in \(0, 10000\] or null, got "):
        check_study_config(cfg)


# ----------------------------------------------------------------------------------------------------------
# Plausibility: the neutral face's size, on every dataset with a unit setting
# ----------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["ict_livelink", "animface"])
@pytest.mark.parametrize("unit_mm, spans", [(0.1, "7 mm"), (1000.0, "7e+04 mm")])
def test_face_size_names_the_unit_setting(tiny_root, kind, unit_mm, spans):  # noqa: F811
    cfg = tiny_config(tiny_root, kind, blendshapes={"unit_mm": unit_mm})
    message = (
        f"face: with dataset.blendshapes.unit_mm={unit_mm:g} the neutral face spans {spans}, not a human "
        "face's size (40-1000 mm); dataset.blendshapes.unit_mm (mm per file unit) is off by a factor; set "
        "dataset.plausibility=warn"
    )
    with pytest.raises(WorkbenchError, match=re.escape(message)):
        build_captures(cfg)


def test_face_size_is_a_warning_under_warn(tiny_root):  # noqa: F811
    cfg = tiny_config(tiny_root, "ict_livelink", blendshapes={"unit_mm": 0.1}, plausibility="warn")
    capture = build_captures(cfg)["mesh"]
    assert any("the neutral face spans 7 mm" in note for note in capture.notes)


def test_missing_blendshape_folder_is_named(tiny_root):  # noqa: F811
    cfg = tiny_config(tiny_root, "ict_livelink", blendshapes={"folder": "nope"})
    with pytest.raises(WorkbenchError, match=r"^\S*nope: blendshape folder not found$"):
        build_captures(cfg)


# ----------------------------------------------------------------------------------------------------------
# Readers: C3D frame ranges, weight curves nested too deep
# ----------------------------------------------------------------------------------------------------------


def test_c3d_header_frames_running_backwards(tmp_path):
    path = write_c3d(tmp_path / "take.c3d", np.random.default_rng(0).uniform(-100, 100, (10, 3, 3)), "ABC")
    data = bytearray(path.read_bytes())
    assert struct.unpack("<HH", data[6:10]) == (1, 10)  # the header's first and last frame
    data[6:10] = struct.pack("<HH", 10, 5)
    path.write_bytes(bytes(data))
    with pytest.raises(
        WorkbenchError, match=re.escape(f"{path}: its header says the last frame (5) precedes the first (10)")
    ):
        read_c3d_markers(path)


def test_one_frame_c3d_names_the_file(tmp_path):
    path = write_c3d(tmp_path / "one.c3d", np.random.default_rng(0).uniform(-100, 100, (1, 3, 3)), "ABC")
    with pytest.raises(WorkbenchError, match=re.escape(f"{path}: holds 1 frame; a take needs at least 2")):
        read_c3d_markers(path)


def test_weight_curves_nested_deep_are_refused(tmp_path):
    path = tmp_path / "deep.json"
    path.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(WorkbenchError, match=re.escape(f"{path}: JSON nested too deeply to be weight curves")):
        read_weight_curves(path)


def test_a_marker_never_seen_is_named_without_warnings(tmp_path, recwarn):
    from workbench.formats.c3d import MarkerTake

    positions = np.random.default_rng(1).uniform(-50, 50, (20, 3, 3))
    positions[:, 1] = np.nan
    take = MarkerTake(
        labels=("A", "B", "C"),
        positions=positions,
        frame_rate=60.0,
        units="mm",
        first_frame=1,
        path=tmp_path / "take.c3d",
    )
    with pytest.raises(
        WorkbenchError,
        match=re.escape(
            f"{tmp_path / 'take.c3d'}: marker(s) ['B'] named in table.csv have no sample in any of the take's 20 frames"
        ),
    ):
        take.index_of(["A", "B"], named_in="table.csv")
    assert take.index_of(["C", "A"], named_in="table.csv").tolist() == [2, 0]
    assert not [warning for warning in recwarn if issubclass(warning.category, RuntimeWarning)]


def test_a_linked_obj_is_named_by_the_link(tmp_path):
    from workbench.formats.obj import load_blendshapes

    (tmp_path / "face").mkdir()
    (tmp_path / "face" / "neutral.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "elsewhere.obj").write_text("v 1 2\nv 0 1 0\nv 0 0 1\n")
    (tmp_path / "face" / "smile.obj").symlink_to(tmp_path / "elsewhere.obj")
    with pytest.raises(WorkbenchError, match=re.escape(f"{tmp_path / 'face' / 'smile.obj'}: vertex 1 has fewer")):
        load_blendshapes(tmp_path / "face", neutral_file="neutral.obj")


# ----------------------------------------------------------------------------------------------------------
# Messages naming the setting: sizes beyond the data, units beyond any face mesh
# ----------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "override, message",
    [
        (
            "dataset.n_face_markers=1000000000000000",
            "dataset.n_face_markers must not exceed the synthetic mesh's "
            "dataset.mesh_rows x dataset.mesh_cols = 4200 vertices (the markers "
            "sit on them), got 1000000000000000",
        ),
        (
            "dataset=ict_livelink dataset.blendshapes.unit_mm=1e300",
            "dataset.blendshapes.unit_mm must be in (0, 10000], got 1e+300",
        ),
        ("dataset=mesh_sequence dataset.unit_mm=1e300", "dataset.unit_mm must be in (0, 10000], got 1e+300"),
    ],
)
def test_sizes_and_units_name_their_setting(override, message):
    with pytest.raises(WorkbenchError, match="^" + re.escape(message) + "$"):
        check_study_config(compose("paper", override.split()))


def test_basis_sizes_name_their_setting():
    from workbench.numerics.alternatives import sparse_pca_basis
    from workbench.numerics.bases import Eigenfaces

    capture = np.random.default_rng(0).normal(size=(20, 12))
    with pytest.raises(
        WorkbenchError, match=re.escape("basis.n_components must be between 1 and the capture's rank 12, got 500")
    ):
        Eigenfaces(n_components=500).fit(capture)
    with pytest.raises(
        WorkbenchError,
        match=re.escape(
            "basis.alternatives_n: n_components must be between 1 and min(n_frames, n_dims) = 12, got 1000000"
        ),
    ):
        sparse_pca_basis(capture, n_components=1_000_000)


# ----------------------------------------------------------------------------------------------------------
# The command line: names that are not UTF-8 refused before anything runs; Hydra's own arguments in one line
# ----------------------------------------------------------------------------------------------------------


def run_cli(*args, cwd):
    import os
    import subprocess
    import sys

    from workbench.settings.config import REPO_ROOT

    env = dict(os.environ, PYTHONPATH=str(REPO_ROOT))
    return subprocess.run(
        [sys.executable, "-m", "workbench", *args], cwd=cwd, env=env, capture_output=True, timeout=120
    )


@pytest.mark.process
@pytest.mark.parametrize(
    "arguments, line",
    [
        (
            (b"study='p\xff'", b"dataset.n_frames=200"),
            b"workbench: error: argument 'study='p\\xff'' is not valid UTF-8 (byte 0xff at position 8); name files, "
            b"folders and settings in UTF-8",
        ),
        (
            (b"report", b"run\xfe"),
            b"workbench: error: argument 'run\\xfe' is not valid UTF-8 (byte 0xfe at position 3); name files, folders and "
            b"settings in UTF-8",
        ),
        ((b"--nope",), b"workbench: error: unrecognized arguments: --nope (see workbench --help)"),
        (
            (b"--cfg", b"bogus"),
            b"workbench: error: argument --cfg/-c: invalid choice: 'bogus' (choose from 'job', "
            b"'hydra', 'all') (see workbench --help)",
        ),
    ],
)
def test_command_line_refusals_are_one_line(tmp_path, arguments, line):
    result = run_cli(*arguments, cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert result.stderr.splitlines() == [line]
    assert list(tmp_path.iterdir()) == []  # nothing ran, nothing written


def test_names_that_are_not_utf8_are_refused_in_the_config():
    cfg = compose("paper", SMALL + ["study='p\udcff'"])
    with pytest.raises(WorkbenchError, match=re.escape("setting study 'p\\xff' is not valid UTF-8 (byte 0xff")):
        check_study_config(cfg)


# ----------------------------------------------------------------------------------------------------------
# A sweep with a bad value is refused before any run starts; a run failing once started lets the others run
# ----------------------------------------------------------------------------------------------------------

REFUSED_SWEEPS = {
    "dataset.n_frames=300,abc,400": "the sweep's run dataset.n_frames=abc is refused: Error merging override "
    "dataset.n_frames=abc; Value 'abc' of type 'str' could not be converted to Integer",
    "solver=lstsq,bogus,nnls": "the sweep's run solver=bogus is refused: In 'paper': Could not find 'solver/bogus'",
    "dataset.n_frames=300,-5,400": "the sweep's run dataset.n_frames=-5 is refused: dataset.n_frames must be an "
    "integer >= 2, got -5",
    "basis.coverage=0.9,1.5": "the sweep's run basis.coverage=1.5 is refused: basis.coverage must be in (0, 1], "
    "got 1.5",
}


@pytest.mark.parametrize("sweep", list(REFUSED_SWEEPS))
@pytest.mark.parametrize("launcher", [[], ["hydra/launcher=joblib"]])
def test_a_sweep_with_a_bad_value_is_refused_in_one_line_before_any_run(tmp_path, sweep, launcher):
    from in_process import run_workbench

    other = [] if sweep.startswith("solver") else ["solver=lstsq"]
    done = run_workbench("-m", sweep, *other, *launcher, "paths.output_root=out", cwd=tmp_path)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"workbench: error: {REFUSED_SWEEPS[sweep]}"), lines
    assert lines[0].endswith("no run of the sweep started: fix the value and run it again")
    assert list(tmp_path.iterdir()) == []  # no run started, no folder made


@pytest.mark.slow
@pytest.mark.process
def test_a_sweep_runs_every_other_run_when_one_fails_once_started_and_then_names_it(tmp_path):
    from workbench.record.record import DONE

    sweep = tmp_path / "sweep"
    refused = sweep / "basis.coverage=0.9,dataset.n_frames=200,solver=lstsq"
    refused.mkdir(parents=True)
    (refused / "mine.txt").write_text("a user's file")
    result = run_cli(
        "-m",
        "dataset.n_frames=200",
        "solver=lstsq",
        "basis.coverage=0.9,0.95",
        f"hydra.sweep.dir={sweep}",
        cwd=tmp_path,
    )
    assert result.returncode == 2, result.stderr
    ran = sorted(path.parent.name for path in sweep.glob(f"*/{DONE}"))
    assert ran == ["basis.coverage=0.95,dataset.n_frames=200,solver=lstsq"]
    lines = result.stderr.decode().splitlines()
    assert len(lines) == 1 and lines[0].startswith(
        f"workbench: error: 1 run(s) of the sweep failed, every other run ran: run {refused.name}: {refused} is not "
        "empty and holds no run record (mine.txt)"
    ), lines
    assert lines[0].endswith("; fix what each names and run the sweep again (complete runs are skipped)")
    assert (refused / "mine.txt").read_text() == "a user's file"


def test_ctrl_c_after_a_command_has_finished_is_ignored(monkeypatch):
    """Once a command has printed its summary, only the libraries' exit remains (MLflow's among them): a Ctrl-C
    then must not kill the process by the signal with no line."""
    import signal
    import sys

    from workbench.cli import main as cli

    monkeypatch.setitem(cli.COMMANDS, "finished", "builtins:len")  # takes the arguments, returns an exit code
    monkeypatch.setattr(sys, "argv", ["workbench", "finished", "0"])
    before = signal.getsignal(signal.SIGINT)
    try:
        with pytest.raises(SystemExit) as stopped:
            cli.main()
        assert stopped.value.code == 1  # len(["0"])
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, before)


def test_a_second_take_with_the_first_takes_seed_is_refused_when_the_settings_are_checked():
    """split other_take evaluates on another take: its seed (eval_seed) must differ from dataset.seed; the study's
    check says so before anything is built, as the Python API's build_captures does."""
    message = r"^dataset\.eval_seed 3 equals dataset\.seed: split 'other_take' evaluates on another take"
    cfg = compose("paper", ["dataset.split=other_take", "dataset.seed=3", "dataset.eval_seed=3"])
    with pytest.raises(WorkbenchError, match=message):
        check_study_config(cfg)
    with pytest.raises(WorkbenchError, match=message):
        build_captures({"kind": "synthetic", "split": "other_take", "seed": 3, "eval_seed": 3})
    check_study_config(compose("paper", ["dataset.split=other_take", "dataset.seed=3"]))  # null: seed + 1
