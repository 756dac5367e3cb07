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

from workbench.core.errors import WorkbenchError
from workbench.reporting.figures import compact_svg, fixed_decimals, raster_bytes, save_figure, shorter_numbers
from workbench.reporting.figures.analogy import figure_analogy, make_analogy_example
from workbench.reporting.figures.bases import place_labels
from workbench.reporting.figures.faces import (
    colour_range,
    face_regions,
    nice_exaggeration,
    point_norms,
    region_frames,
    shape_region,
    spread_by_rank,
)
from workbench.reporting.figures.render import (
    PLAIN_COLOUR,
    MeshView,
    crop_background,
    render_meshes,
    support_weight,
    vertex_colours,
)
from workbench.reporting.figures.shapes import plot_weight_curves
from workbench.reporting.figures.studies import (
    ci_columns,
    plot_alpha_against,
    plot_alpha_over_time,
    plot_coverage_curve,
    plot_marker_vs_mesh,
)


def grid_mesh(n: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """A bumpy square patch facing +z: vertices (n*n, 3) and triangles."""
    x, y = np.meshgrid(np.linspace(-50, 50, n), np.linspace(-50, 50, n))
    z = 20 * np.exp(-(x**2 + y**2) / 800)
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
    svg, png = save_figure(figure, tmp_path, "fig1", ["png"])  # a line drawing: SVG first, a PNG copy on request
    assert svg.name == "fig1.svg" and svg.read_text().lstrip().startswith("<?xml") and "<svg" in svg.read_text()
    assert Image.open(png).size[0] > 1000 and Image.open(png).info["dpi"][0] == pytest.approx(200, abs=1)
    assert [path.name for path in save_figure(figure, tmp_path / "only", "fig1")] == ["fig1.svg"]


def drawn_colours(figure) -> set[str]:
    """Every colour (hex, no alpha) the axes of a figure draw: collections' faces and edges, lines and texts."""
    from matplotlib.colors import to_hex

    colours = set()
    for ax in figure.axes:
        for artist in ax.collections:
            for rgba in [*artist.get_facecolor(), *artist.get_edgecolor()]:
                colours.add(to_hex(rgba, keep_alpha=False))
        colours |= {to_hex(artist.get_color()) for artist in [*ax.lines, *ax.texts]}
    return colours


def test_figure_1_caption_names_only_the_colours_the_figure_draws():
    import re

    from workbench.reporting.figures import OKABE_ITO
    from workbench.reporting.figures.analogy import analogy_colours
    from workbench.reporting.report.run_figures import RUN_FIGURES, draw_analogy

    figure, more = draw_analogy()
    caption = next(row[2] for row in RUN_FIGURES if row[0] == "fig1_analogy") + " " + more
    named = {colour.lower(): name for name, colour in OKABE_ITO.items()}
    drawn = {named[colour] for colour in drawn_colours(figure) if colour in named}
    rest, said = caption, set()
    for name in sorted([*OKABE_ITO, "red", "purple", "green", "violet", "pink"], key=len, reverse=True):
        if re.search(rf"\b{name}\b", rest):
            said.add(name)
            rest = re.sub(rf"\b{name}\b", "", rest)
    assert said == drawn, (said, drawn)  # the palette's colours, named exactly as drawn (the greys are no names)
    # each basis is named with the colour its legend line has
    legend = {
        handle.get_label().split(" ")[0]: named.get(handle.get_color().lower())
        for handle in figure.legends[0].legend_handles
    }
    assert f"PCA axes and their plane {legend['PCA']}" in more and f"hand vectors {legend['hand']}" in more
    assert f"quasi-eigen projections {legend['quasi-eigen']}" in analogy_colours()


def test_svg_and_png_are_byte_identical_when_rebuilt(tmp_path):
    example = make_analogy_example(np.random.default_rng(1))
    first = save_figure(figure_analogy(example), tmp_path / "a", "fig", ["png"])
    second = save_figure(figure_analogy(example), tmp_path / "b", "fig", ["png"])
    for one, two in zip(first, second):
        assert one.read_bytes() == two.read_bytes(), one.name


def test_renders_are_lossless_webp_at_print_resolution(tmp_path):
    from workbench.reporting.figures import new_figure

    figure = new_figure(4, 3)
    figure.add_subplot().imshow(np.random.default_rng(0).random((50, 50, 3)))
    written = save_figure(figure, tmp_path, "faces", ["png", "svg", "pdf"])
    assert [path.name for path in written] == ["faces.webp", "faces.png"]  # no vector copy of a raster
    webp, png = (np.asarray(Image.open(path).convert("RGB")) for path in written)
    assert webp.shape == (330, 440, 3)  # 110 dpi, full colour
    np.testing.assert_array_equal(webp, png)  # lossless: the same pixels as the PNG copy
    image = Image.open(io.BytesIO(raster_bytes(figure, "png")))
    assert image.mode in ("RGB", "RGBA") and image.size == (800, 600)  # a PNG copy at 200 dpi, no palette


def test_svg_numbers_are_cut_in_attributes_only():
    svg = b'<path d="M 179.718736 172.6 L 0.123456 1e-05" style="stroke-width: 0.8123"/><text x="12.3456">0.9958</text>'
    assert shorter_numbers(svg) == (
        b'<path d="M 179.7 172.6 L 0.1 1e-05" style="stroke-width: 0.81"/><text x="12.34">0.9958</text>'
    )


def test_svg_is_compacted_without_changing_what_it_draws():
    svg = (
        b'<svg>\n <!-- a comment -->\n <defs>\n  <path id="m1" d="M 0 0 \nL 1.23456 2 \nz\n"/>\n </defs>\n'
        b' <g id="figure_1">\n  <use xlink:href="#m1" x="3"/>\n  <text x="1">a  b</text>\n </g>\n</svg>'
    )
    assert compact_svg(svg) == (
        b'<svg><defs><path id="m1" d="M 0 0 L 1.2 2 z "/></defs><g><use xlink:href="#m1" '
        b'x="3"/><text x="1">a  b</text></g></svg>'
    )


def test_recurring_svg_styles_become_classes_of_one_sheet_with_the_same_rules():
    import re

    import matplotlib
    from matplotlib.figure import Figure

    from workbench.reporting.figures import shared_styles

    svg = (
        b'<svg width="9"><style type="text/css">*{stroke-linecap: butt}</style>'
        b'<use x="1" style="stroke: #000000; stroke-width: 0.8"/><use x="2" style="stroke: #000000; stroke-width: 0.8"/>'
        b'<path d="M 0 0" style="fill: none"/><text style="font: 8px sans">a</text><text style="font: 8px sans">b</text>'
        b"</svg>"
    )
    shared = shared_styles(svg)
    assert shared == (
        b'<svg width="9"><style>.s0{font: 8px sans}.s1{stroke: #000000; stroke-width: 0.8}</style>'
        b'<style type="text/css">*{stroke-linecap: butt}</style><use x="1" class="s1"/><use x="2" '
        b'class="s1"/><path d="M 0 0" style="fill: none"/><text class="s0">a</text><text class="s0">b'
        b"</text></svg>"
    )
    figure = Figure(figsize=(3, 2))
    figure.subplots().plot(np.arange(30) % 7, "o-")
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "t"}):
        buffer = io.BytesIO()
        figure.savefig(buffer, format="svg", metadata={"Date": None})
    plain = buffer.getvalue()
    shared = shared_styles(plain)
    assert len(shared) < 0.8 * len(plain)
    rules = dict(re.findall(rb"\.(s\d+)\{([^}]*)\}", shared))  # every class back to its inline style: the input
    restored = re.sub(rb' class="(s\d+)"', lambda match: b' style="%s"' % rules[match.group(1)], shared)
    assert restored.replace(re.search(rb"<style>\.s0.*?</style>", shared).group(0), b"") == plain


def test_one_number_format_per_figure():
    assert fixed_decimals([0.17, 0.0955]) == 3 and fixed_decimals([0.17, 0.0955], significant=3) == 4
    assert fixed_decimals([12.5, 3.2]) == 1 and fixed_decimals([250.0]) == 0 and fixed_decimals([0.0, np.nan]) == 0
    assert fixed_decimals([1e-9]) == 4  # at most four


def test_colour_ranges_show_where_they_clip():
    values = [np.r_[np.linspace(0, 1, 999), 4.0], np.array([np.nan, 0.5])]
    clipped = colour_range(values, percentile=99.0)
    assert clipped.extend == "max" and clipped.largest == 4.0 and clipped.high == pytest.approx(0.99, abs=0.01)
    whole = colour_range(values)
    assert (whole.low, whole.high, whole.extend) == (0.0, 4.0, "neither")  # NaN (no data) left out
    signed = colour_range([np.array([-3.46, 0.2, 0.8])], symmetric=True)
    assert (signed.low, signed.high, signed.extend) == (-3.46, 3.46, "neither")  # the largest value is on the bar
    assert colour_range([np.array([-3.0, 0.1, 0.1, 0.1])], symmetric=True, percentile=50).extend == "both"
    assert colour_range([np.zeros(3)]).high == 1.0 and colour_range([np.array([np.nan])]).largest == 0.0


def test_colour_fades_into_the_plain_shade_where_the_capture_has_no_data():
    points = np.c_[np.linspace(0, 100, 101), np.zeros(101), np.zeros(101)]
    support = points[:, 0] < 60
    weight = support_weight(points, support, band=0.1)  # a 10 mm band on a 100 mm face
    assert np.all(weight[~support] == 0) and np.all(weight[:50] == 1)
    np.testing.assert_allclose(weight[55], 0.5)  # 5 mm from the nearest point without data
    assert np.all(np.diff(weight) <= 0)  # no jump: it only fades
    assert support_weight(points, None) is None and support_weight(points, np.ones(101, bool)) is None
    view = MeshView(cmap="YlOrRd", clim=(0.0, 1.0))
    plain = np.array([int(PLAIN_COLOUR[i : i + 2], 16) for i in (1, 3, 5)])
    colours = vertex_colours(np.r_[np.ones(100), np.nan], view, weight).astype(int)
    np.testing.assert_array_equal(colours[60:], np.tile(plain, (41, 1)))  # no data, and NaN: plain
    assert np.abs(colours[0] - plain).max() > 100  # full colour far inside
    np.testing.assert_array_equal(vertex_colours(None, MeshView(), n_points=2), np.tile(plain, (2, 1)))


def test_openings_are_closed_by_dark_caps_and_missing_values_are_plain():
    from workbench.reporting.figures.render import CAP_COLOUR, hole_loops

    vertices, faces = grid_mesh(13)
    centre = np.linalg.norm(vertices[:, :2], axis=1) < 20
    holed = faces[~centre[faces].all(axis=1) & ~centre[faces].any(axis=1)]
    loops = hole_loops(holed)
    assert len(loops) == 1 and np.all(np.linalg.norm(vertices[loops[0], :2], axis=1) < 35)
    values = np.where(vertices[:, 0] > 30, np.nan, 0.0)
    image = render_meshes(
        [vertices], holed, [values], MeshView(cmap="Greens", clim=(0.0, 1.0), window_size=(200, 200), view=(0, 0, 1))
    )[0]
    middle = image[90:110, 90:110].reshape(-1, 3).astype(int)
    cap = np.array([int(CAP_COLOUR[i : i + 2], 16) for i in (1, 3, 5)])
    assert np.all(middle.max(axis=1) < 120), "the opening shows the background"
    assert np.abs(middle.mean(axis=0) - cap).max() < 60
    right = image[100, 150:175].astype(int)  # x > 30: no value, plain grey (equal channels), not the map's green
    assert np.all(np.ptp(right, axis=1) <= 6) and np.all(right.mean(axis=1) > 90)


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


@pytest.mark.process
def test_rendering_works_in_a_plain_subprocess_without_a_display(tmp_path):
    script = (
        "import numpy as np\n"
        "from workbench.reporting.figures.render import MeshView, render_meshes\n"
        "v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.3]], float)\n"
        "f = np.array([[0, 1, 2], [1, 3, 2]])\n"
        "image = render_meshes([v], f, [v[:, 2]], MeshView(cmap='viridis', clim=(0, 0.3), window_size=(64, 48)))[0]\n"
        "assert image.shape == (48, 64, 3)\n"
        "print('covered', float(np.any(image < 250, axis=2).mean()))\n"
    )
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
    assert nice_exaggeration(0.9, 10.0) == 10 and nice_exaggeration(1.6, 10.0) == 5 and nice_exaggeration(0, 1) == 1
    np.testing.assert_allclose(point_norms(np.array([[3.0, 4.0, 0.0, 0.0, 0.0, 2.0]])), [[5.0, 2.0]])


def test_figure_3_frames_cover_the_regions_of_the_face():
    assert [
        shape_region(name)
        for name in (
            "browInnerUp_L",
            "corrugator_R",
            "eyeBlink_L",
            "jawOpen",
            "jaw_open",
            "mouthSmile_L",
            "zygomatic_major_R",
            "mentalis",
        )
    ] == ["brows", "brows", "eyes", "jaw", "jaw", "mouth", "mouth", "mouth"]
    # four points: one each for a brow shape, a mouth shape and the jaw; the last point no shape moves
    hand = np.zeros((3, 12))
    hand[0, 0:3], hand[1, 3:6], hand[2, 6:9] = [0, 5, 0], [0, 3, 0], [0, -20, 0]
    hand[2, 3:6] = [0, -4, 0]  # the jaw drags the mouth point a little: it stays the mouth's (relative reach)
    regions = face_regions(hand, ["browInnerUp_L", "mouthSmile_L", "jawOpen"])
    assert {name: list(np.flatnonzero(points)) for name, points in regions.items()} == {
        "brows": [0],
        "mouth": [1],
        "jaw": [2],
    }
    assert (
        list(face_regions(hand, ["browInnerUp_L", "mouthSmile_L", "jawOpen"], np.array([0, 1, 1, 1], bool))["brows"])
        == [False] * 4
    )
    captured = np.zeros((6, 12))
    captured[1, 1], captured[2, 4], captured[3, 7], captured[4, 7], captured[4, 4] = 2.0, 3.0, 9.0, 8.0, 3.5
    assert region_frames(captured, regions) == [("brows", 1), ("mouth", 4), ("jaw", 3)]
    # frames closer than a second in one take are one moment: the jaw's two strong frames are both within a second
    # of the mouth's, and every other frame of the take within a second of a chosen one, so the jaw gets none
    seconds, takes = np.arange(6) * 0.5, np.array(["a"] * 6)
    assert region_frames(captured, regions, seconds, takes) == [("brows", 1), ("mouth", 4)]
    # in another take the same times are far apart
    assert region_frames(captured, regions, seconds, np.array(list("aaabaa"))) == [
        ("brows", 1),
        ("mouth", 4),
        ("jaw", 3),
    ]


def sweep_table(ci_style: str = "prefixed") -> pd.DataFrame:
    """A tidy table as the sweep plots expect: 3 noise levels x 2 data variants x 4 bases."""
    rows = []
    for noise in (0.0, 0.1, 0.2):
        for data in ("markers", "mesh"):
            for basis, solver, base in (
                ("H", "lstsq", 0.3),
                ("QE", "lstsq", 0.15),
                ("QE-linear", "lstsq", 0.18),
                ("PCA", "projection", 0.16),
            ):
                value = base + noise
                row = {
                    "dataset.marker_noise_mm": noise,
                    "data": data,
                    "basis": basis,
                    "projection": "-",
                    "solver": solver,
                    "n_seeds": 3,
                    "m": 10.0,
                    "alpha_abs_mean": value,
                }
                low, high = (
                    ("alpha_abs_mean_ci_low", "alpha_abs_mean_ci_high")
                    if ci_style == "prefixed"
                    else ("ci_low", "ci_high")
                )
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
    table = pd.concat(
        [table.assign(data=f"{data}->{scored}") for data in ("markers", "mesh") for scored in ("markers", "face")],
        ignore_index=True,
    ).drop_duplicates(["data", "basis"])
    table["rms_mm"] = table["alpha_abs_mean"] / 2
    figure = plot_marker_vs_mesh(table, ("alpha_abs_mean", "rms_mm"), title="marker versus mesh")
    assert len(figure.axes) == 4  # 2 measures x 2 evaluation sets
    first = figure.axes[0]
    assert (
        first.get_title(loc="left") == "scored on markers" and figure.axes[1].get_title(loc="left") == "scored on face"
    )
    assert len(first.patches) == 8  # 4 bases x fitted on 2 variants
    assert [t.get_text() for t in figure.legends[0].get_texts()] == ["fitted on markers", "fitted on mesh"]
    assert len(first.containers) >= 2 and "error bars: 95 % interval" in figure._suptitle.get_text()
    assert figure.axes[2].get_ylabel() == "RMS point error (mm)"
    # a run's own table, each variant scored on its own points: one panel each, never side by side
    own = (
        sweep_table()
        .query("`dataset.marker_noise_mm` == 0.0")
        .drop(columns=["alpha_abs_mean_ci_low", "alpha_abs_mean_ci_high"])
    )
    figure = plot_marker_vs_mesh(own, "alpha_abs_mean", title="own points")
    assert [ax.get_title(loc="left") for ax in figure.axes] == ["scored on markers", "scored on mesh"]
    assert all(len(ax.patches) == 4 for ax in figure.axes)
    # each bar centred on its tick (no empty slot for the variant the panel lacks); every colour in the legend
    figure.draw_without_rendering()
    for ax in figure.axes:
        centres = sorted(patch.get_x() + patch.get_width() / 2 for patch in ax.patches)
        assert centres == pytest.approx(list(ax.get_xticks()), abs=1e-9)
    colours = {tuple(patch.get_facecolor()) for ax in figure.axes for patch in ax.patches}
    entries = {tuple(handle.get_facecolor()) for handle in figure.legends[0].legend_handles}
    assert len(colours) == 2 and colours == entries
    assert [t.get_text() for t in figure.legends[0].get_texts()] == ["fitted on markers", "fitted on mesh"]


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
    figure = plot_alpha_over_time(
        {"markers": {"H": frames, "QE": frames / 2}, "mesh": {"H": frames}},
        seconds,
        ylabel="alpha (%)",
        title="over time",
    )
    assert len(figure.axes) == 2
    assert figure.axes[0].lines[0].get_xdata()[-1] == pytest.approx(239 / 120.0)
    assert figure.axes[-1].get_xlabel() == "time in the take (s)"
    # Two takes, each starting at 0 s in its file: one axis through both, the boundary drawn and named.
    timeline = Timeline.concatenate(
        [Timeline.uniform("jaw", np.arange(0, 120, 4), 60.0), Timeline.uniform("cheeks", np.arange(0, 120, 4), 60.0)]
    )
    elapsed = timeline.elapsed()
    assert elapsed[29] == pytest.approx(116 / 60) and elapsed[30] == pytest.approx(120 / 60)
    takes = [(str(timeline.take[start]), float(elapsed[start])) for start, _ in timeline.take_spans()]
    figure = plot_alpha_over_time({"markers": {"H": frames[:60]}}, elapsed, ylabel="alpha", title="t", takes=takes)
    assert [t.get_text() for t in figure.axes[0].texts] == ["jaw", "cheeks"]
    assert figure.axes[0].lines[1].get_xdata()[0] == pytest.approx(2.0)  # boundary of the second take


def test_alpha_against_in_a_grid_keeps_settings_apart_and_wraps_panels():
    table = pd.concat([sweep_table().assign(**{"dataset.gap_rate": rate}) for rate in (0.0, 0.1)], ignore_index=True)
    figure = plot_alpha_against(table, "dataset.marker_noise_mm", by=["dataset.gap_rate"], title="grid")
    assert len(figure.axes[0].lines) == 8  # 4 bases x 2 gap rates, never one line through both
    labels = [t.get_text() for t in figure.legends[0].get_texts()]
    assert "H (gap_rate=0.0)" in labels and "PCA (gap_rate=0.1)" in labels
    # Two settings at the same x (as 'lower' and 'random12' are both 12 hand shapes): points with error bars.
    table["n_hand"] = 12.0
    figure = plot_alpha_against(table, "n_hand", by=["dataset.gap_rate"], title="same x")
    assert not [
        line
        for line in figure.axes[0].lines
        if line.get_linestyle() not in ("None", "none") and len(line.get_xdata()) > 2
    ]
    assert len(figure.axes[0].containers) == 8
    many = pd.concat([sweep_table().assign(data=f"variant{k}") for k in range(4)], ignore_index=True)
    figure = plot_alpha_against(many, "dataset.marker_noise_mm", title="four variants")
    assert sum(ax.get_visible() for ax in figure.axes) == 4 and len(figure.axes) == 6  # 2 rows of 3 panels


def test_coverage_curve_names_the_paper_m_and_the_basis_size_on_one_line_when_they_coincide():
    ratios = {"mesh": np.r_[0.9, np.full(40, 0.1 / 40)]}
    figure = plot_coverage_curve(ratios, {"mesh": 10}, threshold=0.995, title="c", paper_m=18, basis_size=18)
    near = figure.axes[0]
    labels = [t.get_text() for t in near.get_legend().get_texts()]
    assert "paper: m = 18; hand shapes n = 18" in labels and not any(
        label.startswith("hand shapes") for label in labels
    )
    figure = plot_coverage_curve(ratios, {"mesh": 10}, threshold=0.995, title="c", paper_m=18, basis_size=12)
    labels = [t.get_text() for t in figure.axes[0].get_legend().get_texts()]
    assert "paper: m = 18" in labels and "hand shapes n = 12" in labels


def weight_statistics_example():
    """Statistics as a run records them, with two solvers giving the same roughness (two labels 9.1e4 side by
    side) and a tiny share of frames outside [0, 1]."""
    statistics = {}
    for data in ("markers", "mesh"):
        statistics[data] = {}
        for basis, scale in (("H", 1.0), ("QE", 3.0), ("QE-linear", 2.0)):
            for k, solver in enumerate(("lstsq", "nnls", "box")):
                statistics[data][(basis, solver)] = {
                    "max_abs": 1.1 * scale / (k + 1),
                    "outside_unit_share": 0.002 * (2 - k),
                    "sparsity": 0.4 + 0.1 * k,
                    "roughness": 91234.0 if k else 4.5e3 * scale,
                }
    return statistics


def test_weight_statistics_labels_never_print_over_each_other():
    from workbench.reporting.figures.distributions import WEIGHT_PANELS, bar_text, plot_weight_statistics

    figure = plot_weight_statistics(weight_statistics_example(), title="weights")
    figure.canvas.draw()
    axes = figure.axes
    assert len(axes) == 2 * len(WEIGHT_PANELS)
    for ax in axes:
        texts = [text for text in ax.texts if text.get_text()]
        boxes = [text.get_window_extent() for text in texts]
        assert boxes
        for i in range(len(boxes)):
            for j in range(i + 1, len(boxes)):
                assert not boxes[i].overlaps(boxes[j]), (
                    ax.get_title(loc="left"),
                    texts[i].get_text(),
                    texts[j].get_text(),
                )
        # every label below the panel's top, clear of its title
        top = ax.get_window_extent().y1
        assert all(box.y1 <= top + 1 for box in boxes), ax.get_title(loc="left")
    roughness = axes[len(WEIGHT_PANELS) - 1]
    assert sum(text.get_text() == "9.1e4" for text in roughness.texts) == 6
    assert [bar_text(v) for v in (91234.0, 0.002, 1.0, float("nan"), 2.3e-5)] == ["9.1e4", "0.002", "1", "", "2.3e-5"]


def test_error_cdf_subtitles_and_legend_title_fit_within_the_figure():
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from workbench.reporting.figures import BASIS_COLOURS, OKABE_ITO
    from workbench.reporting.figures.distributions import plot_error_cdf

    probabilities = np.linspace(0, 1, 51)
    curves = {
        data: {
            (basis, solver): np.linspace(0.05, 0.6, 51) * (1 + i)
            for i, (basis, solver) in enumerate(
                [("H", "lstsq"), ("QE", "lstsq"), ("QE", "nnls"), ("QE-linear", "lstsq"), ("PCA", "projection")]
            )
        }
        for data in ("markers", "mesh")
    }
    regions = {
        "markers": "the face region: every one of the 66 markers",
        "mesh": "the face region: the 2218 of 4200 mesh vertices some hand shape moves (the muscles' reach; "
        "the rest of the head patch never moves)",
    }
    figure = plot_error_cdf(curves, probabilities, title="Per-frame error", regions=regions)
    FigureCanvasAgg(figure).draw()
    renderer = figure.canvas.get_renderer()
    width = figure.bbox.width
    titles = [ax.title if ax.get_title() else ax._left_title for ax in figure.axes]
    boxes = [title.get_window_extent(renderer) for title in titles]
    assert all(0 <= box.x0 and box.x1 <= width for box in boxes)
    assert boxes[0].x1 < boxes[1].x0  # the two panels' subtitles never run into each other
    assert "muscles' reach;" in titles[1].get_text() and "\n" in titles[1].get_text()
    legend = figure.legends[0]
    title_box = legend.get_title().get_window_extent(renderer)
    assert title_box.width <= width / 2 and title_box.x0 >= 0 and title_box.x1 <= width
    # the bases' colours: four different colours of the colour-blind-safe palette (QE and PCA were two purples or
    # reds), the same in every figure
    assert len(set(BASIS_COLOURS.values())) == len(BASIS_COLOURS) and set(BASIS_COLOURS.values()) <= set(
        OKABE_ITO.values()
    )
    drawn = {
        line.get_label().split()[0]: line.get_color() for line in figure.axes[0].lines if line.get_label()[0] != "_"
    }
    assert drawn == BASIS_COLOURS


def test_point_labels_do_not_overlap():
    from workbench.reporting.figures import new_figure

    figure = new_figure(4, 3)
    ax = figure.add_subplot()
    points = [(0.274, 0.096, "ICA", "C0"), (0.275, 0.097, "H-fit", "C1"), (0.05, 0.3, "H", "C2")]
    ax.plot([p[0] for p in points], [p[1] for p in points], "o")
    figure.draw_without_rendering()
    place_labels(ax, points)
    figure.draw_without_rendering()
    boxes = [text.get_window_extent() for text in ax.texts]
    assert len(boxes) == 3
    for i in range(3):
        for j in range(i + 1, 3):
            assert not boxes[i].overlaps(boxes[j]), (ax.texts[i].get_text(), ax.texts[j].get_text())


def test_weight_curves_mark_the_frames_and_tell_left_from_right():
    seconds = np.linspace(0, 6, 61)
    weights = {"H": np.random.default_rng(0).random((61, 3)), "QE": np.random.default_rng(1).random((61, 3))}
    windows = [
        {
            "label": f"most displaced {region}: take frame {k}",
            "take": "take",
            "seconds": seconds + k,
            "marked": 3.0 + k,
            "weights": weights,
        }
        for k, region in enumerate(("brows", "jaw"))
    ]
    figure = plot_weight_curves(windows, ["browInnerUp_L", "browInnerUp_R", "jawOpen"], [0, 1, 2], title="w")
    axes = np.array(figure.axes).reshape(2, 2)
    left, right, jaw = axes[0, 0].lines[:3]
    assert left.get_color() == right.get_color() != jaw.get_color()
    assert left.get_linestyle() == "-" and right.get_linestyle() == "--"
    marks = [line for line in axes[1, 1].lines if line.get_linestyle() == ":" and len(set(line.get_xdata())) == 1]
    assert marks and marks[0].get_xdata()[0] == pytest.approx(4.0)  # the second window's frame
    assert axes[0, 1].get_title().startswith("most displaced jaw")


def test_animation_is_wide_full_colour_and_states_its_speed(tmp_path):
    from workbench.reporting.figures.interactive import ANIMATION_WIDTH, write_animation

    vertices, faces = grid_mesh()
    frames = [vertices + [0, 0, 3 * k] for k in range(4)]
    panels = [
        render_meshes(frames, faces, None, MeshView(window_size=(200, 180))),
        render_meshes(
            frames, faces, [vertices[:, 0]] * 4, MeshView(cmap="YlOrRd", clim=(-50, 50), window_size=(200, 180))
        ),
    ]
    path = write_animation(
        tmp_path / "a.webp",
        panels,
        ["captured", "H (error)"],
        [f"frame {k}" for k in range(4)],
        fps=15.0,
        speed="real time: 15 frames per second",
        colour=("YlOrRd", (0.0, 1.0), "max", "error (mm)"),
    )
    image = Image.open(path)
    assert image.format == "WEBP" and image.n_frames == 4 and image.size[0] >= ANIMATION_WIDTH
    image.load()
    assert image.info["duration"] == 67  # ms per frame: 15 frames per second
    colours = np.asarray(image.convert("RGB")).reshape(-1, 3)
    assert len(np.unique(colours, axis=0)) > 1000  # full colour, no palette


def test_view_data_decode_to_the_frames_and_reconstructions():
    import base64
    import zlib

    from workbench.reporting.figures.interactive import STEP_MM, ViewFrame, view_payload

    vertices, faces = grid_mesh(5)
    rng = np.random.default_rng(0)
    captured, shown = rng.normal(size=75), rng.normal(size=75)
    payload = view_payload(
        vertices.ravel(),
        faces,
        [ViewFrame("f", captured, {"H": shown}, {"H": "alpha 1 %"})],
        bases={"H": "hand"},
        displacement_range=(0.0, 2.0, True),
        error_range=(0.0, 1.0, False),
        cmaps=("YlGnBu", "YlOrRd"),
        weight=np.linspace(0, 1, 25),
    )

    def unpack(text, dtype):
        return np.frombuffer(zlib.decompress(base64.b64decode(text)), dtype=dtype)

    def planes(text):
        raw = unpack(text, np.uint8)
        return np.ascontiguousarray(raw.reshape(2, -1).T).view("<i2").ravel().astype(float) * STEP_MM

    frame = payload["frames"][0]
    np.testing.assert_allclose(planes(frame["captured"]), captured, atol=STEP_MM / 2)
    np.testing.assert_allclose(planes(frame["captured"]) + planes(frame["shown"]["H"]), shown, atol=STEP_MM)
    np.testing.assert_array_equal(unpack(payload["faces"], "<u2").reshape(-1, 3), faces)
    assert payload["displacement"]["beyond"] and not payload["error"]["beyond"]
    assert len(payload["error"]["colours"]) == 6 * 64 and unpack(payload["weight"], np.uint8)[-1] == 255


def test_weight_statistics_mark_minimum_norm_weights_of_a_rank_deficient_basis():
    from workbench.reporting.figures.distributions import plot_weight_statistics

    labels = {"markers": {"QE": "minimum-norm, rank 11 of 18"}}
    figure = plot_weight_statistics(weight_statistics_example(), title="weights", minimum_norm=labels)
    markers, mesh = figure.axes[0], figure.axes[4]
    assert [tick.get_text() for tick in markers.get_xticklabels()] == ["H", "QE*", "QE-linear"]
    assert [tick.get_text() for tick in mesh.get_xticklabels()] == ["H", "QE", "QE-linear"]
    notes = [text.get_text() for text in markers.texts if text.get_text().startswith("*")]
    assert notes == ["* lstsq weights:\nQE minimum-norm, rank 11 of 18"]
    assert not any(text.get_text().startswith("*") for text in mesh.texts)


def test_vertex_rms_carried_by_a_linear_map_equals_the_rms_of_every_frame_carried():
    from workbench.dataset.transfer import apply_point_operator
    from workbench.reporting.report.data import vertex_rms

    rng = np.random.default_rng(5)
    frames, fitted = rng.standard_normal((700, 3 * 12)), rng.standard_normal((700, 3 * 12))
    operator = rng.standard_normal((40, 12))
    carried = apply_point_operator(operator, (fitted - frames).reshape(700, 12, 3))
    expected = np.sqrt((carried**2).sum(axis=(0, 2)) / 700)
    rms = vertex_rms(frames, lambda rows: fitted[rows], chunk=256, operator=operator)
    np.testing.assert_allclose(rms, expected, rtol=1e-12)
    plain = vertex_rms(frames, lambda rows: fitted[rows], chunk=256)
    np.testing.assert_allclose(plain, np.sqrt(((fitted - frames).reshape(700, 12, 3) ** 2).sum(axis=(0, 2)) / 700))
    assert vertex_rms(frames[:0], lambda rows: fitted[:0], operator=operator).shape == (40,)


def test_wrapping_measures_only_near_the_width_and_wraps_as_measuring_every_line():
    """wrap_to_width skips measuring a line whose quick estimate is well inside the width: the lines are those of
    measuring every candidate line, on the error CDF's legend title and on texts of mixed words and sizes."""
    import random

    from workbench.reporting.figures import text_width, wrap_to_width
    from workbench.reporting.figures.distributions import CDF_LEGEND_TITLE

    def measured_wrap(text: str, width: float, fontsize: float) -> str:
        lines, line = [], ""
        for word in text.split(" "):
            candidate = f"{line} {word}" if line else word
            if line and text_width(candidate, fontsize) > width:
                lines, line = lines + [line], word
            else:
                line = candidate
        return "\n".join(lines + [line])

    rng = random.Random(5)
    words = (CDF_LEGEND_TITLE + " alpha (QE) m=n 0.0123 mm [1.2, 3.4] quasi-eigen held-out Wj ffi").split()
    texts = [(CDF_LEGEND_TITLE, 4.2, 8)] + [
        (" ".join(rng.choice(words) for _ in range(25)), rng.uniform(1.5, 5.0), rng.choice([7, 9, 11]))
        for _ in range(4)
    ]
    for text, width, fontsize in texts:
        assert wrap_to_width(text, width, fontsize) == measured_wrap(text, width, fontsize)


def regime_record(variants: dict) -> object:
    """A record of data variants (name -> (m, relative distance of every hand shape)), with what the figures'
    variant choice and the intuitiveness bars read."""
    from types import SimpleNamespace

    data = {
        name: {
            "pca": {"m": m},
            "protocol": "training frames",
            "intuitiveness": [
                {"projection": "affine", "shape": shape, "cosine": 1 - distance, "relative_distance": distance}
                for shape in ("jaw_open", "brow_up")
            ],
        }
        for name, (m, distance) in variants.items()
    }
    return SimpleNamespace(
        metrics={"data": data, "dataset": {"name": "constructed", "provenance": {}}},
        data_variants=list(variants),
        config={},
    )


def test_face_and_marker_figures_draw_the_paper_regime_variant_first():
    from workbench.reporting.report.data import figure_order, marker_variant, mesh_variant

    record = regime_record({"markers": (13, 0.1), "mesh": (12, 0.1), "markers m=n": (18, 0.2), "mesh m=n": (18, 0.2)})
    assert figure_order(record.data_variants, "mesh") == ["mesh m=n", "mesh", "markers m=n", "markers"]
    cache = {("inputs", name): {"faces": 1} if "mesh" in name else {} for name in record.data_variants}
    assert mesh_variant(record, cache)[0] == "mesh m=n" and marker_variant(record, cache)[0] == "markers m=n"
    cache[("inputs", "markers m=n")] = None  # a variant whose inputs cannot be had: the coverage rule's next
    assert marker_variant(record, cache)[0] == "markers"
    alone = regime_record({"markers": (13, 0.1)})  # no m = n variant (the coverage rule kept m = n, or it is off)
    assert marker_variant(alone, {("inputs", "markers"): {}})[0] == "markers"


def test_intuitiveness_bars_draw_the_paper_regime_and_say_which_m(monkeypatch):
    import workbench.reporting.figures.shapes as shapes
    from workbench.reporting.report.run_figures import draw_intuitiveness_bars

    seen = {}
    monkeypatch.setattr(shapes, "plot_intuitiveness_bars", lambda *args, **kwargs: seen.update(args=args, **kwargs))
    record = regime_record({"mesh": (13, 0.1), "mesh m=n": (18, 0.3)})
    _, caption = draw_intuitiveness_bars(record, {})
    assert seen["args"][2]["affine"] == [0.3, 0.3]  # the m = n variant's relative distances
    assert "m = 18 (m = n, the paper's regime)" in seen["title"] and "'mesh m=n', m = 18" in caption
    _, caption = draw_intuitiveness_bars(regime_record({"mesh": (13, 0.1)}), {})
    assert seen["args"][2]["affine"] == [0.1, 0.1] and "m = 13 (the coverage rule)" in caption


def test_vtk_log_reaches_python_logging_as_plain_lines_and_no_terminal_codes(capfd, caplog):
    """VTK writes its log (a headless machine's X server warning, any error) with colour codes; a render passes it
    to Python logging instead, one plain line each, and nothing of it reaches the terminal."""
    import logging

    from vtkmodules.vtkCommonCore import vtkLogger

    triangle = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0])
    render_meshes([triangle], np.array([[0, 1, 2]]), None, MeshView())
    capfd.readouterr()
    with caplog.at_level(logging.INFO, logger="workbench.render.vtk"):
        vtkLogger.Log(vtkLogger.VERBOSITY_WARNING, "probe.cxx", 7, "a warning of the probe")
        vtkLogger.Log(vtkLogger.VERBOSITY_ERROR, "probe.cxx", 8, "an error of the probe")
        render_meshes([triangle], np.array([[0, 1, 2]]), None, MeshView())
    out, err = capfd.readouterr()
    assert "\x1b[" not in out + err and "probe" not in out + err
    logged = {(record.levelno, record.getMessage()) for record in caplog.records}
    assert (logging.INFO, "VTK (probe.cxx): a warning of the probe") in logged
    assert (logging.WARNING, "VTK (probe.cxx): an error of the probe") in logged
    assert not any("\x1b" in message for _, message in logged)


def test_marker_versus_mesh_compares_the_paper_regime_variants_when_the_run_has_both(monkeypatch):
    import workbench.reporting.figures.studies as studies
    from workbench.reporting.report.run_figures import draw_marker_vs_mesh

    seen = {}
    monkeypatch.setattr(
        studies, "plot_marker_vs_mesh", lambda table, *args, **kwargs: seen.update(table=table, **kwargs)
    )
    variants = {"markers": (13, 0.1), "mesh": (12, 0.1), "markers m=n": (18, 0.2), "mesh m=n": (18, 0.2)}
    record = regime_record(variants)
    record.config = {"solver": {"lstsq": {}}}
    record.table = pd.DataFrame(
        [{"data": data, "basis": "QE", "solver": "lstsq", "rms_mm": 1.0, "alpha_disp_pooled": 1.0} for data in variants]
    )
    _, caption = draw_marker_vs_mesh(record)
    assert sorted(seen["table"]["data"]) == ["markers m=n", "mesh m=n"] and "m = n" in seen["title"]
    assert "'markers m=n', 'mesh m=n'" in caption
    record.table = record.table[~record.table["data"].str.endswith("m=n")]
    record.metrics["data"] = {name: values for name, values in record.metrics["data"].items() if "m=n" not in name}
    _, caption = draw_marker_vs_mesh(record)  # no m = n variants: the coverage rule's m, and said
    assert sorted(seen["table"]["data"]) == ["markers", "mesh"] and "the coverage rule's m" in caption
