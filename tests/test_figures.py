"""Figures: the analogy computed by the core, headless mesh rendering, the study plots on constructed tables,
and the files they are saved to."""

import io
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from matplotlib.collections import PolyCollection
from PIL import Image

from workbench.errors import WorkbenchError
from workbench.reporting.figures import png_bytes, save_figure
from workbench.reporting.figures.analogy import figure_analogy, make_analogy_example
from workbench.reporting.figures.faces import expressive_frames, nice_exaggeration, point_norms, spread_by_rank
from workbench.reporting.figures.render import MeshView, crop_background, render_meshes
from workbench.reporting.figures.studies import (ci_columns, plot_alpha_against, plot_alpha_over_time, plot_coverage_curve,
                                       plot_marker_vs_mesh)


def grid_mesh(n: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """A bumpy square patch facing +z: vertices (n*n, 3) and triangles."""
    x, y = np.meshgrid(np.linspace(-50, 50, n), np.linspace(-50, 50, n))
    z = 20 * np.exp(-(x ** 2 + y ** 2) / 800)
    vertices = np.c_[x.ravel(), y.ravel(), z.ravel()]
    index = np.arange(n * n).reshape(n, n)
    a, b, c, d = index[:-1, :-1].ravel(), index[:-1, 1:].ravel(), index[1:, :-1].ravel(), index[1:, 1:].ravel()
    return vertices, np.r_[np.c_[a, b, d], np.c_[a, d, c]]


def test_analogy_projections_lie_on_the_plane_at_least_distance():
    example = make_analogy_example(np.random.default_rng(1))
    eigen = example.eigenfaces
    assert eigen.n_components_ == 2
    normal = np.cross(*eigen.components_)
    # On the plane through the mean, and each hand vector moved straight along the normal (least distance).
    np.testing.assert_allclose((example.quasi_eigen - eigen.mean_) @ normal, 0, atol=1e-12)
    np.testing.assert_allclose((example.hand - example.quasi_eigen) @ eigen.components_.T, 0, atol=1e-12)
    assert np.all(np.abs((example.hand - eigen.mean_) @ normal) > 0.5)  # the hand vectors are off the plane


def test_analogy_figure_is_labelled_and_saved(tmp_path):
    figure = figure_analogy(make_analogy_example(np.random.default_rng(1)))
    texts = [t.get_text() for ax in figure.axes for t in ax.texts]
    assert {"$e_1^{PCA}$", "$e_2^{PCA}$", "$e_1^H$", "$e_1^{QE}$"} <= set(texts)
    assert "computed by the workbench core" in figure._suptitle.get_text()
    png, svg = save_figure(figure, tmp_path, "fig1")
    assert Image.open(png).size[0] > 600 and png.stat().st_size > 20_000
    assert svg.read_text().lstrip().startswith("<?xml") and "<svg" in svg.read_text()


def test_svg_and_png_are_byte_identical_when_rebuilt(tmp_path):
    example = make_analogy_example(np.random.default_rng(1))
    first = save_figure(figure_analogy(example), tmp_path / "a", "fig")
    second = save_figure(figure_analogy(example), tmp_path / "b", "fig")
    for one, two in zip(first, second):
        assert one.read_bytes() == two.read_bytes(), one.name


def test_png_is_full_colour_at_print_resolution():
    from workbench.reporting.figures import new_figure

    figure = new_figure(4, 3)
    figure.add_subplot().imshow(np.random.default_rng(0).random((50, 50, 3)))
    image = Image.open(io.BytesIO(png_bytes(figure)))
    assert image.mode in ("RGB", "RGBA") and image.size == (800, 600)  # 200 dpi, no palette


def test_openings_are_closed_by_dark_caps_and_missing_values_are_grey():
    from workbench.reporting.figures.render import CAP_COLOUR, hole_loops

    vertices, faces = grid_mesh(13)
    centre = np.linalg.norm(vertices[:, :2], axis=1) < 20
    holed = faces[~centre[faces].all(axis=1) & ~centre[faces].any(axis=1)]
    loops = hole_loops(holed)
    assert len(loops) == 1 and np.all(np.linalg.norm(vertices[loops[0], :2], axis=1) < 35)
    values = np.where(vertices[:, 0] > 30, np.nan, 0.0)
    image = render_meshes([vertices], holed, [values], MeshView(cmap="Greens", clim=(0.0, 1.0),
                                                                 window_size=(200, 200), view=(0, 0, 1)))[0]
    middle = image[90:110, 90:110].reshape(-1, 3).astype(int)
    cap = np.array([int(CAP_COLOUR[i:i + 2], 16) for i in (1, 3, 5)])
    assert np.all(middle.max(axis=1) < 120), "the opening shows the background"
    assert np.abs(middle.mean(axis=0) - cap).max() < 60
    right = image[100, 150:175].astype(int)  # x > 30: no value, grey (equal channels), not the map's green
    assert np.all(np.ptp(right, axis=1) < 12) and np.all(right.mean(axis=1) > 90)


def test_render_meshes_gives_one_shaded_coloured_image_per_mesh():
    vertices, faces = grid_mesh()
    values = np.linalg.norm(vertices[:, :2], axis=1)
    view = MeshView(cmap="YlOrRd", clim=(0.0, float(values.max())), window_size=(120, 100))
    images = render_meshes([vertices, vertices + [0, 0, 5]], faces, [values, values[::-1]], view)
    assert len(images) == 2
    for image in images:
        assert image.shape == (100, 120, 3) and image.dtype == np.uint8
        covered = np.any(image < 250, axis=2).mean()
        assert 0.05 < covered < 0.99
    cropped = crop_background(images)
    assert cropped[0].shape == cropped[1].shape and cropped[0].shape[0] <= 100


def test_rendering_works_in_a_plain_subprocess_without_a_display(tmp_path):
    script = (
        "import numpy as np\n"
        "from workbench.reporting.figures.render import MeshView, render_meshes\n"
        "v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.3]], float)\n"
        "f = np.array([[0, 1, 2], [1, 3, 2]])\n"
        "image = render_meshes([v], f, [v[:, 2]], MeshView(cmap='viridis', clim=(0, 0.3), window_size=(64, 48)))[0]\n"
        "assert image.shape == (48, 64, 3)\n"
        "print('covered', float(np.any(image < 250, axis=2).mean()))\n")
    env = {key: value for key, value in os.environ.items() if key not in ("DISPLAY", "WAYLAND_DISPLAY")}
    done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert float(done.stdout.split()[-1]) > 0.05


def test_render_rejects_non_triangles():
    vertices, _ = grid_mesh(3)
    with pytest.raises(WorkbenchError, match="triangles"):
        render_meshes([vertices], np.zeros((2, 4), int), [vertices[:, 0]], MeshView(cmap="viridis", clim=(0, 1)))


def test_selection_helpers():
    assert spread_by_rank([0.5, 0.1, 0.9, 0.3, 0.7], 3) == [1, 0, 2]
    assert spread_by_rank([0.2, 0.1], 4) == [1, 0]
    captured = np.zeros((9, 6))
    captured[[1, 5, 6], 0] = [3.0, 2.0, 4.0]
    assert expressive_frames(captured, 3) == [1, 5, 6]
    assert nice_exaggeration(0.9, 10.0) == 10 and nice_exaggeration(1.6, 10.0) == 5 and nice_exaggeration(0, 1) == 1
    np.testing.assert_allclose(point_norms(np.array([[3.0, 4.0, 0.0, 0.0, 0.0, 2.0]])), [[5.0, 2.0]])


def sweep_table(ci_style: str = "prefixed") -> pd.DataFrame:
    """A tidy table as the sweep plots expect: 3 noise levels x 2 data variants x 4 bases."""
    rows = []
    for noise in (0.0, 0.1, 0.2):
        for data in ("markers", "mesh"):
            for basis, solver, base in (("H", "lstsq", 0.3), ("QE", "lstsq", 0.15), ("QE-linear", "lstsq", 0.18),
                                        ("PCA", "projection", 0.16)):
                value = base + noise
                row = {"dataset.marker_noise_mm": noise, "data": data, "basis": basis, "projection": "-",
                       "solver": solver, "n_seeds": 3, "m": 10.0, "alpha_abs_mean": value}
                low, high = ("alpha_abs_mean_ci_low", "alpha_abs_mean_ci_high") if ci_style == "prefixed" \
                    else ("ci_low", "ci_high")
                row.update({low: value - 0.02, high: value + 0.02})
                rows.append(row)
    return pd.DataFrame(rows)


@pytest.mark.parametrize("ci_style", ["prefixed", "plain"])
def test_alpha_against_a_setting_draws_a_line_and_a_band_per_basis(ci_style):
    table = sweep_table(ci_style)
    assert ci_columns(table, "alpha_abs_mean") is not None
    figure = plot_alpha_against(table, "dataset.marker_noise_mm", "alpha_abs_mean", title="noise")
    assert len(figure.axes) == 2  # one panel per data variant
    for ax in figure.axes:
        assert len(ax.lines) == 4
        assert sum(isinstance(c, PolyCollection) for c in ax.collections) == 4
        np.testing.assert_allclose(ax.lines[0].get_xdata(), [0.0, 0.1, 0.2])
        assert ax.get_xlabel() == "marker noise (mm per coordinate)"
    assert "(95 % interval: geometric mean, t-interval on log values; n = 3 seeds)" in figure._suptitle.get_text()
    labels = [t.get_text() for t in figure.legends[0].get_texts()]
    assert labels[0] == "hand $E^H$" and len(labels) == 4


def test_alpha_against_without_ci_and_with_categories():
    table = sweep_table().drop(columns=["alpha_abs_mean_ci_low", "alpha_abs_mean_ci_high"])
    table["basis.hand_subset"] = table["dataset.marker_noise_mm"].map({0.0: "all", 0.1: "upper", 0.2: "lower"})
    figure = plot_alpha_against(table, "basis.hand_subset", title="subset")
    ax = figure.axes[0]
    assert not any(isinstance(c, PolyCollection) for c in ax.collections)
    assert [t.get_text() for t in ax.get_xticklabels()] == ["all", "upper", "lower"]
    with pytest.raises(WorkbenchError, match="no column"):
        plot_alpha_against(table, "basis.coverage", title="x")
    with pytest.raises(WorkbenchError, match="solver"):
        plot_alpha_against(table[table["basis"] != "PCA"], "basis.hand_subset", solver="box", title="x")


def test_marker_vs_mesh_draws_one_panel_per_evaluation_set_and_measure():
    table = sweep_table()
    table = table[table["dataset.marker_noise_mm"] == 0.0]
    # fitted on markers and on the mesh, each scored on the markers and on the mesh's face region
    table = pd.concat([table.assign(data=f"{data}->{scored}") for data in ("markers", "mesh")
                       for scored in ("markers", "face")], ignore_index=True).drop_duplicates(["data", "basis"])
    table["rms_mm"] = table["alpha_abs_mean"] / 2
    figure = plot_marker_vs_mesh(table, ("alpha_abs_mean", "rms_mm"), title="marker versus mesh")
    assert len(figure.axes) == 4  # 2 measures x 2 evaluation sets
    first = figure.axes[0]
    assert first.get_title(loc="left") == "scored on markers" and figure.axes[1].get_title(loc="left") == \
        "scored on face"
    assert len(first.patches) == 8  # 4 bases x fitted on 2 variants
    assert [t.get_text() for t in figure.legends[0].get_texts()] == ["fitted on markers", "fitted on mesh"]
    assert len(first.containers) >= 2 and "error bars: 95 % interval" in figure._suptitle.get_text()
    assert figure.axes[2].get_ylabel() == "RMS point error (mm)"
    # a run's own table, each variant scored on its own points: one panel each, never side by side
    own = sweep_table().query("`dataset.marker_noise_mm` == 0.0").drop(
        columns=["alpha_abs_mean_ci_low", "alpha_abs_mean_ci_high"])
    figure = plot_marker_vs_mesh(own, "alpha_abs_mean", title="own points")
    assert [ax.get_title(loc="left") for ax in figure.axes] == ["scored on markers", "scored on mesh"]
    assert all(len(ax.patches) == 4 for ax in figure.axes)


def test_coverage_curve_marks_threshold_and_chosen_m():
    ratios = {"markers": np.array([0.8, 0.15, 0.045, 0.004, 0.001]), "mesh": np.array([0.9, 0.096, 0.004])}
    figure = plot_coverage_curve(ratios, {"markers": 3, "mesh": 2}, threshold=0.995, title="coverage")
    near, tail = figure.axes
    labels = [t.get_text() for t in near.get_legend().get_texts()]
    assert labels == ["markers: m = 3, 0.9950", "mesh: m = 2, 0.9960", "threshold 0.995"]
    assert tail.get_yscale() == "log"


def test_alpha_over_time_has_a_panel_per_variant_and_seconds_on_x():
    from workbench.dataset.capture import Timeline

    frames = np.random.default_rng(0).random(240)
    seconds = np.arange(240) / 120.0
    figure = plot_alpha_over_time({"markers": {"H": frames, "QE": frames / 2}, "mesh": {"H": frames}}, seconds,
                                  ylabel="alpha (%)", title="over time")
    assert len(figure.axes) == 2
    assert figure.axes[0].lines[0].get_xdata()[-1] == pytest.approx(239 / 120.0)
    assert figure.axes[-1].get_xlabel() == "time in the take (s)"
    # Two takes, each starting at 0 s in its file: one axis through both, the boundary drawn and named.
    timeline = Timeline.concatenate([Timeline.uniform("jaw", np.arange(0, 120, 4), 60.0),
                                     Timeline.uniform("cheeks", np.arange(0, 120, 4), 60.0)])
    elapsed = timeline.elapsed()
    assert elapsed[29] == pytest.approx(116 / 60) and elapsed[30] == pytest.approx(120 / 60)
    takes = [(str(timeline.take[start]), float(elapsed[start])) for start, _ in timeline.take_spans()]
    figure = plot_alpha_over_time({"markers": {"H": frames[:60]}}, elapsed, ylabel="alpha", title="t", takes=takes)
    assert [t.get_text() for t in figure.axes[0].texts] == ["jaw", "cheeks"]
    assert figure.axes[0].lines[1].get_xdata()[0] == pytest.approx(2.0)  # boundary of the second take


def test_alpha_against_in_a_grid_keeps_settings_apart_and_wraps_panels():
    table = pd.concat([sweep_table().assign(**{"dataset.gap_rate": rate}) for rate in (0.0, 0.1)],
                      ignore_index=True)
    figure = plot_alpha_against(table, "dataset.marker_noise_mm", by=["dataset.gap_rate"], title="grid")
    assert len(figure.axes[0].lines) == 8  # 4 bases x 2 gap rates, never one line through both
    labels = [t.get_text() for t in figure.legends[0].get_texts()]
    assert "H (gap_rate=0.0)" in labels and "PCA (gap_rate=0.1)" in labels
    # Two settings at the same x (as 'lower' and 'random12' are both 12 hand shapes): points with error bars.
    table["n_hand"] = 12.0
    figure = plot_alpha_against(table, "n_hand", by=["dataset.gap_rate"], title="same x")
    assert not [line for line in figure.axes[0].lines if line.get_linestyle() not in ("None", "none")
                and len(line.get_xdata()) > 2]
    assert len(figure.axes[0].containers) == 8
    many = pd.concat([sweep_table().assign(data=f"variant{k}") for k in range(4)], ignore_index=True)
    figure = plot_alpha_against(many, "dataset.marker_noise_mm", title="four variants")
    assert sum(ax.get_visible() for ax in figure.axes) == 4 and len(figure.axes) == 6  # 2 rows of 3 panels
