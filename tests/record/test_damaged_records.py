"""Damaged records: one line naming the file and field (exit 2), and nothing written outside the output folder.

A record's ``done`` holds the checksums of its files, so a file changed after the run is refused by every reader
(report, collect, mlflow, export) before its content is used. The field checks below apply to a record whose
checksums were written anew after the damage (a record made by another tool, or by hand): they are what stands
between a malformed file and the tables.
"""

import json
import shutil
import zipfile

import pytest

from workbench.api import read_record, run
from workbench.core.errors import WorkbenchError
from workbench.core.files import inside, mapped_npz, npz_bytes
from workbench.core.files import sha256_of_file as file_checksum
from workbench.record.record import DONE, is_record_file
from workbench.settings.config import compose


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    folder = tmp_path_factory.mktemp("records") / "sweep" / "run"
    cfg = compose(
        "paper",
        [
            "dataset.n_frames=300",
            "dataset.mesh_rows=20",
            "dataset.mesh_cols=20",
            "solver=lstsq",
            "save_inputs=true",
            "basis.paper_regime=false",
        ],
    )  # one data variant: inputs.npz
    run(cfg, folder)
    return folder


def reseal(folder):
    """Write ``done`` anew with the checksums of the record files now in ``folder``."""
    names = sorted(path.name for path in folder.iterdir() if path.name != DONE and is_record_file(path.name))
    (folder / DONE).write_text(json.dumps({"sha256": {name: file_checksum(folder / name) for name in names}}))


def edit_json(name, change):
    def damage(folder):
        value = json.loads((folder / name).read_text())
        change(value)
        (folder / name).write_text(json.dumps(value))

    return damage


def write(name, text):
    return lambda folder: (folder / name).write_text(text)


def set_row(key, value):
    return edit_json("metrics.json", lambda metrics: metrics["rows"][0].__setitem__(key, value))


def replace_in(name, old, new):
    return lambda folder: (folder / name).write_text((folder / name).read_text().replace(old, new, 1))


DAMAGE = {
    "metrics.json not JSON": (write("metrics.json", "{not json"), "metrics.json: not valid JSON"),
    "metrics.json a list": (write("metrics.json", "[]"), "metrics.json: must hold a JSON object"),
    "metrics.json missing": (lambda folder: (folder / "metrics.json").unlink(), "metrics.json is missing"),
    "rows not a list": (edit_json("metrics.json", lambda m: m.__setitem__("rows", 3)), "field 'rows'"),
    "a row without alpha_abs_mean": (
        edit_json("metrics.json", lambda m: m["rows"][0].pop("alpha_abs_mean")),
        "rows[0] has no 'alpha_abs_mean'",
    ),
    "alpha a string": (set_row("alpha_abs_mean", "12"), "field 'rows[0].alpha_abs_mean' must be a number"),
    "alpha a bool": (set_row("alpha_abs_mean", True), "field 'rows[0].alpha_abs_mean' must be a number"),
    "basis a number": (set_row("basis", 4), "field 'rows[0].basis' must be a string"),
    "alpha NaN while the table has a value": (
        set_row("alpha_abs_mean", float("nan")),
        "field 'rows[0].alpha_abs_mean' must be a finite number equal to alpha_table.csv row 1's",
    ),
    "alpha infinite": (
        set_row("alpha_disp_pooled", float("inf")),
        "field 'rows[0].alpha_disp_pooled' must be a finite",
    ),
    "alpha not the table's": (set_row("rms_mm", 1e6), "field 'rows[0].rms_mm' must be a finite number equal to"),
    "row of unknown data": (set_row("data", "elsewhere"), "rows[0].data 'elsewhere' is not one of"),
    "data entry a list": (
        edit_json("metrics.json", lambda m: m["data"].__setitem__("markers", [])),
        "field 'data.markers' must be an object",
    ),
    "format of a later workbench": (
        edit_json("metrics.json", lambda m: m.__setitem__("format", 99)),
        "field 'format' must be an integer from 0 to 1",
    ),
    "study a path": (edit_json("metrics.json", lambda m: m.__setitem__("study", "../../../x")), "field 'study'"),
    "job_num a string": (edit_json("metrics.json", lambda m: m.__setitem__("job_num", "3")), "field 'job_num'"),
    "overrides a string": (edit_json("metrics.json", lambda m: m.__setitem__("overrides", "a=1")), "field 'overrides'"),
    "timings not numbers": (write("timings.json", '{"total": "slow"}'), "timings.json: field 'total'"),
    "config.yaml not YAML": (write("config.yaml", "study: [unclosed"), "config.yaml: not valid YAML"),
    "config.yaml a list": (write("config.yaml", "- 1\n- 2\n"), "config.yaml: must be a mapping"),
    "config.yaml study a path": (
        replace_in("config.yaml", "study: paper", "study: ../../../x"),
        "config.yaml: must be a mapping whose field 'study' is a plain name",
    ),
    "config.yaml dataset a string": (
        replace_in("config.yaml", "dataset:", "dataset: 3\nunused:"),
        "config.yaml: field 'dataset' must be a mapping",
    ),
    "CSV missing a column": (
        lambda folder: (folder / "alpha_table.csv").write_text(
            "\n".join(",".join(line.split(",")[1:]) for line in (folder / "alpha_table.csv").read_text().splitlines())
        ),
        "alpha_table.csv: missing column(s) ['data']",
    ),
    "CSV missing rows": (
        lambda folder: (folder / "alpha_table.csv").write_text(
            "\n".join((folder / "alpha_table.csv").read_text().splitlines()[:2]) + "\n"
        ),
        "alpha_table.csv has 1 rows",
    ),
    "CSV empty": (write("alpha_table.csv", ""), "alpha_table.csv: not a readable CSV"),
    "CSV binary": (lambda folder: (folder / "alpha_table.csv").write_bytes(b"\xff\xfe\x00\x01"), "alpha_table.csv"),
}


@pytest.mark.parametrize("command", ["report", "collect"])
@pytest.mark.parametrize("case", list(DAMAGE))
def test_damaged_record_is_refused_in_one_line_naming_file_and_field(record, tmp_path, cli, command, case):
    damage, expected = DAMAGE[case]
    folder = tmp_path / "sweep" / "run"
    shutil.copytree(record, folder)
    damage(folder)
    reseal(folder)
    out = tmp_path / "out"
    result = cli(command, str(tmp_path / "sweep"), "--out", str(out))
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2, result.stderr
    assert len(lines) == 1 and lines[0].startswith(f"workbench {command}: error: ") and expected in lines[0], lines
    assert str(folder) in lines[0]


def test_a_value_of_metrics_json_unlike_its_table_is_refused_by_every_reader(record, tmp_path, cli):
    folder = tmp_path / "sweep" / "run"
    shutil.copytree(record, folder)
    set_row("alpha_abs_mean", float("nan"))(folder)
    reseal(folder)  # the checksums pass: only the value itself can be refused
    with pytest.raises(WorkbenchError) as refused:
        read_record(folder)
    message = str(refused.value)
    assert "\n" not in message and str(folder / "metrics.json") in message and "rows[0].alpha_abs_mean" in message
    commands = {
        "export": ["export", str(folder), "--out", str(tmp_path / "export")],
        "mlflow": ["mlflow", str(tmp_path / "sweep"), "--store", str(tmp_path / "store")],
    }
    for command, arguments in commands.items():
        result = cli(*arguments, cwd=tmp_path)
        assert result.returncode == 2, (command, result.stderr)
        assert "field 'rows[0].alpha_abs_mean' must be a finite number" in result.stderr, (command, result.stderr)
        assert len(result.stderr.strip().splitlines()) == 1, result.stderr


def test_a_record_with_undefined_values_in_both_files_is_read(record, tmp_path):
    folder = tmp_path / "run"
    shutil.copytree(record, folder)
    table = (folder / "alpha_table.csv").read_text().splitlines()
    column = table[0].split(",").index("alpha_disp_mean")
    cells = table[1].split(",")
    cells[column] = ""
    (folder / "alpha_table.csv").write_text("\n".join([table[0], ",".join(cells), *table[2:]]) + "\n")
    set_row("alpha_disp_mean", None)(folder)
    reseal(folder)
    assert read_record(folder).metrics["rows"][0]["alpha_disp_mean"] is None


def test_a_record_of_the_layout_before_the_format_field_is_read_in_the_current_layout(record, tmp_path):
    from workbench.record.record import METRICS_FORMAT

    assert read_record(record).metrics["format"] == METRICS_FORMAT
    folder = tmp_path / "run"
    shutil.copytree(record, folder)

    def earlier(metrics):  # what a record of an earlier version leaves out
        del metrics["format"], metrics["versions"], metrics["dataset"]["provenance"]
        for facts in metrics["data"].values():
            del facts["protocol"], facts["notes"], facts["face_region"]
        for row in metrics["rows"]:
            del row["train_on"], row["eval_on"]

    edit_json("metrics.json", earlier)(folder)
    reseal(folder)
    metrics = read_record(folder).metrics
    assert metrics["format"] == METRICS_FORMAT and metrics["versions"] == {} and metrics["dataset"]["provenance"] == {}
    assert metrics["data"]["markers"]["protocol"] == "training frames" and metrics["data"]["markers"]["notes"] == []
    assert all(row["train_on"] == row["eval_on"] == row["data"] for row in metrics["rows"])


def test_a_study_name_cannot_lead_a_reference_report_out_of_reports(record, cli):
    result = cli("report", str(record), "--reference", "--name", "../../x")
    assert result.returncode == 2 and "--name must be a plain folder name" in result.stderr


def test_inside_refuses_paths_leaving_the_folder(tmp_path):
    assert inside(tmp_path, "figures", "a.png") == tmp_path / "figures" / "a.png"
    for escaping in (["..", "x"], ["figures/../../x"], ["/etc/passwd"]):
        with pytest.raises(ValueError, match="is not inside the output folder"):
            inside(tmp_path, *escaping)


def test_an_uncompressed_archive_is_mapped_read_only_with_the_arrays_numpy_reads(tmp_path):
    """mapped_npz gives numpy.load's arrays: mapped read-only from an archive that stores them (any dtype, shape
    and order, empty ones too), read whole from a compressed one; object arrays and a cut archive are refused."""
    import numpy as np

    rng = np.random.default_rng(0)
    arrays = {
        "frames": rng.standard_normal((7, 5)),
        "fortran": np.asfortranarray(rng.standard_normal((4, 3))),
        "names": np.array(["jawOpen", "browInnerUp"]),
        "index": np.arange(6, dtype=np.int32).reshape(2, 3),
        "empty": np.zeros((0, 3)),
        "scalar": np.array(2.5),
    }
    for compressed in (False, True):
        path = tmp_path / f"arrays{compressed}.npz"
        path.write_bytes(npz_bytes(arrays, compressed=compressed))
        found = mapped_npz(path)
        assert found.keys() == arrays.keys()
        for name, expected in arrays.items():
            assert found[name].dtype == expected.dtype and found[name].shape == expected.shape, name
            np.testing.assert_array_equal(found[name], expected)
        assert found["fortran"].flags.f_contiguous
        assert found["frames"].flags.writeable is compressed  # mapped from the file where stored
    objects = tmp_path / "objects.npz"
    np.savez(objects, ragged=np.array([[1], [1, 2]], dtype=object))
    with pytest.raises(ValueError, match="Python objects"):
        mapped_npz(objects)
    cut = tmp_path / "cut.npz"
    cut.write_bytes((tmp_path / "arraysFalse.npz").read_bytes()[:300])
    with pytest.raises((ValueError, OSError, EOFError, zipfile.BadZipFile)):
        mapped_npz(cut)


def edit_bytes(name, change):
    return lambda folder: (folder / name).write_bytes(change((folder / name).read_bytes()))


TAMPERED = {
    "metrics.json edited": (
        edit_json("metrics.json", lambda m: m["rows"][0].__setitem__("alpha_abs_mean", 0.01)),
        "metrics.json was changed after the run",
    ),
    "config.yaml edited": (
        replace_in("config.yaml", "n_frames: 300", "n_frames: 301"),
        "config.yaml was changed after the run",
    ),
    "alpha_table.csv edited": (
        edit_bytes("alpha_table.csv", lambda data: data.replace(b"0.", b"1.", 1)),
        "alpha_table.csv was changed after the run",
    ),
    "inputs.npz edited": (
        edit_bytes("inputs.npz", lambda data: data[:-40] + bytes(40)),
        "inputs.npz was changed after the run",
    ),
    "timings.json removed": (lambda folder: (folder / "timings.json").unlink(), "timings.json is missing"),
    "done damaged": (write(DONE, '{"sha256": 3}'), "'done' is damaged"),
    "done emptied": (write(DONE, ""), "'done' is empty"),
    "alpha_per_frame.npz damaged": (
        edit_bytes("alpha_per_frame.npz", lambda data: data[:-40] + bytes(40)),
        "alpha_per_frame.npz was changed after the run",
    ),
    "an archive added": (
        lambda folder: shutil.copy(folder / "inputs.npz", folder / "inputs_mesh.npz"),
        "inputs_mesh.npz is not one of the files the run wrote",
    ),
}


@pytest.mark.parametrize("case", list(TAMPERED))
def test_a_record_changed_after_its_run_is_refused_by_every_reader(record, tmp_path, case, cli):
    damage, expected = TAMPERED[case]
    folder = tmp_path / "sweep" / "run"
    shutil.copytree(record, folder)
    damage(folder)
    commands = {
        "report": ["report", str(folder), "--out", str(tmp_path / "report")],
        "collect": ["collect", str(tmp_path / "sweep"), "--out", str(tmp_path / "collected")],
        "mlflow": ["mlflow", str(tmp_path / "sweep"), "--store", str(tmp_path / "store")],
        "export": ["export", str(folder), "--out", str(tmp_path / "export")],
    }
    # every reader checks every file of the record, archives included, before it uses or copies any of them
    for command, arguments in commands.items():
        result = cli(*arguments, cwd=tmp_path)
        lines = result.stderr.strip().splitlines()
        assert result.returncode == 2, (command, result.stderr)
        assert len(lines) == 1 and lines[0].startswith(f"workbench {command}: error: run record {folder}"), lines
        assert expected in lines[0], (command, lines)
    for name in ("report", "collected", "export", "store"):
        assert not (tmp_path / name).exists() or not any((tmp_path / name).iterdir()), name


def test_a_record_whose_report_folder_is_a_link_out_of_it_is_refused(record, tmp_path, cli):
    folder = tmp_path / "run"
    shutil.copytree(record, folder)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (folder / "report").symlink_to(elsewhere)
    result = cli("report", str(folder), cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip() == (
        f"workbench report: error: refusing to write {folder / 'report'}: it is not "
        f"inside the output folder {folder} (a symbolic link leads to {elsewhere})"
    )
    assert list(elsewhere.iterdir()) == []


def set_cells(changes):
    """Set ``(row, column) -> value`` in both ``metrics.json``'s rows and ``alpha_table.csv``, as a record changed and
    signed again would have them (the two files agree, the checksums pass)."""

    def damage(folder):
        metrics = json.loads((folder / "metrics.json").read_text())
        lines = (folder / "alpha_table.csv").read_text().splitlines()
        header = lines[0].split(",")
        for (row, column), value in changes(metrics["rows"]).items():
            metrics["rows"][row][column] = value
            cells = lines[row + 1].split(",")
            cells[header.index(column)] = repr(value)
            lines[row + 1] = ",".join(cells)
        (folder / "metrics.json").write_text(json.dumps(metrics))
        (folder / "alpha_table.csv").write_text("\n".join(lines) + "\n")

    return damage


def h_and_qe_swapped(rows):
    """The alphas of the H and QE rows (lstsq, the first data variant) exchanged, the rows' names kept."""
    first = rows[0]["data"]
    h, qe = (
        next(i for i, r in enumerate(rows) if (r["data"], r["basis"], r["solver"]) == (first, b, "lstsq"))
        for b in ("H", "QE")
    )
    return {
        (i, column): rows[j][column] for i, j in ((h, qe), (qe, h)) for column in ("alpha_abs_mean", "alpha_disp_mean")
    }


def without_per_frame_file(damage):
    def both(folder):
        damage(folder)
        (folder / "alpha_per_frame.npz").unlink()

    return both


MEANINGLESS = {
    "alpha -5": (
        set_cells(lambda rows: {(0, "alpha_abs_mean"): -5.0}),
        "alpha_table.csv: field 'alpha_abs_mean' of row 1",
    ),
    "alpha halved": (
        set_cells(lambda rows: {(0, "alpha_abs_mean"): rows[0]["alpha_abs_mean"] / 2}),
        "alpha_per_frame.npz: field 'markers.absolute' row 0",
    ),
    "H and QE swapped": (set_cells(h_and_qe_swapped), "alpha_per_frame.npz: field 'markers.absolute'"),
    "H and QE swapped, no per-frame file": (
        without_per_frame_file(set_cells(h_and_qe_swapped)),
        "metrics.json: field 'data.markers.comparisons[0].estimate'",
    ),
    "n_frames -5": (
        replace_in("config.yaml", "n_frames: 300", "n_frames: -5"),
        "config.yaml: field 'dataset.n_frames' must be",
    ),
    "frames counted below zero": (
        edit_json("metrics.json", lambda m: m["data"]["markers"].__setitem__("n_eval_frames", -5)),
        "metrics.json: field 'data.markers.n_eval_frames' must be a whole number >= 0, got -5",
    ),
}


@pytest.mark.parametrize("case", list(MEANINGLESS))
def test_a_record_signed_again_with_values_no_run_writes_is_refused_by_every_reader(record, tmp_path, case, cli):
    """collect took such records into its tables and findings (export refused them only because it recomputes)."""
    damage, expected = MEANINGLESS[case]
    folder = tmp_path / "sweep" / "run"
    shutil.copytree(record, folder)
    damage(folder)
    reseal(folder)
    commands = {
        "collect": ["collect", str(tmp_path / "sweep"), "--out", str(tmp_path / "tables")],
        "report": ["report", str(folder), "--out", str(tmp_path / "report")],
        "export": ["export", str(folder), "--out", str(tmp_path / "export")],
        "mlflow": ["mlflow", str(tmp_path / "sweep"), "--store", str(tmp_path / "store")],
    }
    for command, arguments in commands.items():
        result = cli(*arguments, cwd=tmp_path)
        lines = result.stderr.strip().splitlines()
        assert result.returncode == 2 and len(lines) == 1, (command, result.stderr)
        assert lines[0].startswith(f"workbench {command}: error: {folder}") and expected in lines[0], (command, lines)
        assert "the record cannot be trusted" in lines[0], lines
    assert sorted(path.name for path in tmp_path.iterdir()) == ["sweep"]


def test_the_records_the_workbench_writes_pass_the_checks_of_meaning(record):
    assert read_record(record).table["alpha_abs_mean"].min() > 0
