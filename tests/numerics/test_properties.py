"""Property-based tests (Hypothesis) of the numerical core and the loaders.

Core: eigenfaces of random low-rank data reconstruct it, the PCA reconstruction is a projection (idempotent), a
hand shape on the eigenface hyperplane comes back unchanged, alpha is 0 for a perfect reconstruction and does not
change with the units, the weights of eq. 5 satisfy the KKT conditions and agree with SciPy, and NaN anywhere in
an input is refused. Loaders: random valid OBJ and Live Link Face files round-trip; truncated files, garbage
bytes and NaN text end in :class:`WorkbenchError` or (where the damage leaves a valid file) in a valid result,
never in another exception.

Every test is derandomised (the same examples on every run) with a modest number of examples and no deadline.
"""

import itertools
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy.optimize import lsq_linear, nnls

from workbench.core.errors import WorkbenchError
from workbench.formats.c3d import read_c3d_markers
from workbench.formats.livelink import ARKIT_NAMES, read_livelink_csv
from workbench.formats.obj import read_obj
from workbench.numerics.bases import Eigenfaces, build_quasi_eigen_basis
from workbench.numerics.metrics import summarise_alpha
from workbench.numerics.solve import kkt_violation, solve_weights


def examples(n: int):
    """Deterministic settings with ``n`` examples (files are written to a folder shared by the examples)."""
    return settings(
        max_examples=n,
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
    )


seeds = st.integers(0, 2**32 - 1)
_names = itertools.count()


def fresh(folder, suffix: str):
    """A new file name per example (the OBJ reader caches by path, size and modification time)."""
    return folder / f"example_{next(_names)}{suffix}"


# ----------------------------------------------------------------------------------------------------------
# Eigenfaces and quasi-eigen faces
# ----------------------------------------------------------------------------------------------------------


@st.composite
def low_rank_captures(draw):
    """(capture, rank): frames on a random affine subspace of dimension ``rank``."""
    n_dims = draw(st.integers(3, 24))
    n_frames = draw(st.integers(3, 40))
    rank = draw(st.integers(1, min(n_dims, n_frames - 1)))
    rng = np.random.default_rng(draw(seeds))
    scale = 10.0 ** draw(st.integers(-3, 3))
    scores = rng.normal(size=(n_frames, rank)) * np.geomspace(1.0, 0.1, rank)
    axes = np.linalg.qr(rng.normal(size=(n_dims, rank)))[0].T
    return scale * (rng.normal(size=n_dims) + scores @ axes), rank


@examples(40)
@given(low_rank_captures())
def test_eigenfaces_of_low_rank_data_reconstruct_it(data):
    capture, rank = data
    pca = Eigenfaces(coverage=1.0).fit(capture)
    assert pca.n_components_ == rank
    np.testing.assert_allclose(pca.components_ @ pca.components_.T, np.eye(rank), atol=1e-10)
    scale = np.abs(capture).max()
    np.testing.assert_allclose(pca.reconstruct(capture), capture, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(pca.explained_variance_ratio_.sum(), 1.0, rtol=1e-12)


@examples(40)
@given(low_rank_captures(), st.floats(0.05, 1.0), seeds)
def test_pca_reconstruction_is_idempotent(data, coverage, seed):
    capture, _ = data
    pca = Eigenfaces(coverage=coverage).fit(capture)
    frames = np.random.default_rng(seed).normal(size=(5, capture.shape[1])) * np.abs(capture).max()
    once = pca.reconstruct(frames)
    np.testing.assert_allclose(pca.reconstruct(once), once, rtol=0, atol=1e-9 * (np.abs(once).max() + 1.0))
    assert pca.coverage_ >= coverage - 1e-12


@examples(40)
@given(low_rank_captures(), seeds, st.sampled_from(["affine", "linear"]))
def test_hand_shape_on_the_hyperplane_is_unchanged(data, seed, projection):
    capture, _ = data
    pca = Eigenfaces(coverage=1.0).fit(capture)
    m = pca.n_components_
    rng = np.random.default_rng(seed)
    n_shapes = int(rng.integers(1, m + 1))
    coefficients = rng.normal(size=(n_shapes, m)) * np.abs(capture).max()
    assume(np.linalg.matrix_rank(coefficients) == n_shapes)
    hand = coefficients @ pca.components_ + (pca.mean_ if projection == "affine" else 0.0)
    assume(np.linalg.matrix_rank(hand, tol=1e-6 * np.abs(hand).max()) == n_shapes)
    result = build_quasi_eigen_basis(hand, [f"h{i}" for i in range(n_shapes)], pca, projection=projection)
    np.testing.assert_allclose(result.shapes[:n_shapes], hand, rtol=0, atol=1e-9 * np.abs(hand).max())


# ----------------------------------------------------------------------------------------------------------
# Alpha
# ----------------------------------------------------------------------------------------------------------


@st.composite
def alpha_problems(draw):
    n_points = draw(st.integers(1, 8))
    n_frames = draw(st.integers(1, 12))
    rng = np.random.default_rng(draw(seeds))
    neutral = rng.normal(size=3 * n_points) * 50.0
    captured = rng.normal(size=(n_frames, 3 * n_points))
    reconstructed = captured + rng.normal(size=captured.shape) * draw(st.floats(0.0, 1.0))
    return neutral, captured, reconstructed


@examples(50)
@given(alpha_problems())
def test_alpha_is_zero_for_a_perfect_reconstruction(problem):
    neutral, captured, _ = problem
    summary = summarise_alpha(neutral, captured, captured.copy())
    assert summary.absolute_mean == 0.0 and summary.absolute_pooled == 0.0 and summary.rms_mm == 0.0
    assert summary.displacement_pooled == 0.0


@examples(50)
@given(alpha_problems(), st.floats(1e-3, 1e3), st.integers(1, 5))
def test_alpha_does_not_change_with_units_and_rms_scales(problem, factor, chunk):
    neutral, captured, reconstructed = problem
    base = summarise_alpha(neutral, captured, reconstructed)
    scaled = summarise_alpha(factor * neutral, factor * captured, factor * reconstructed, chunk_frames=chunk)
    for name in ("absolute_mean", "absolute_pooled", "displacement_mean", "displacement_pooled"):
        np.testing.assert_allclose(getattr(scaled, name), getattr(base, name), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(scaled.rms_mm, factor * base.rms_mm, rtol=1e-9, atol=1e-12)


# ----------------------------------------------------------------------------------------------------------
# Weights of eq. 5
# ----------------------------------------------------------------------------------------------------------


@st.composite
def weight_problems(draw):
    n_shapes = draw(st.integers(1, 5))
    n_dims = draw(st.integers(3, 10))
    n_frames = draw(st.integers(1, 4))
    rng = np.random.default_rng(draw(seeds))
    basis = rng.normal(size=(n_shapes, n_dims))
    if n_shapes > 1 and draw(st.booleans()):
        basis[-1] = basis[0] * rng.uniform(0.5, 2.0)  # a duplicate direction: a rank-deficient basis
    targets = rng.normal(size=(n_frames, n_shapes)) @ basis + 0.3 * rng.normal(size=(n_frames, n_dims))
    return basis, targets


def objective(basis, targets, weights):
    return np.sum((targets - weights @ basis) ** 2, axis=1)


@examples(60)
@given(weight_problems(), st.sampled_from(["nnls", "box"]))
def test_constrained_weights_satisfy_kkt_and_agree_with_scipy(problem, kind):
    basis, targets = problem
    lower, upper = (0.0, None) if kind == "nnls" else (-0.5, 1.0)
    solution = solve_weights(basis, targets, kind=kind, lower=lower, upper=upper)
    weights = solution.weights
    assert np.all(weights >= lower - 1e-12) and (upper is None or np.all(weights <= upper + 1e-12))
    gram, rhs = basis @ basis.T, targets @ basis.T
    assert kkt_violation(gram, rhs, weights, lower, upper).max() <= 1e-8
    if kind == "nnls":
        reference = np.array([nnls(basis.T, target)[0] for target in targets])
    else:
        reference = np.array(
            [lsq_linear(basis.T, target, bounds=(lower, upper), method="bvls", tol=1e-14).x for target in targets]
        )
    ours, theirs = objective(basis, targets, weights), objective(basis, targets, reference)
    np.testing.assert_allclose(ours, theirs, rtol=1e-7, atol=1e-10 * (np.sum(targets**2) + 1.0))


@examples(40)
@given(weight_problems())
def test_least_squares_weights_agree_with_numpy(problem):
    basis, targets = problem
    weights = solve_weights(basis, targets).weights
    reference = np.linalg.lstsq(basis.T, targets.T, rcond=None)[0].T
    np.testing.assert_allclose(
        objective(basis, targets, weights),
        objective(basis, targets, reference),
        rtol=1e-9,
        atol=1e-10 * (np.sum(targets**2) + 1.0),
    )


# ----------------------------------------------------------------------------------------------------------
# NaN or Inf anywhere in a core input is refused
# ----------------------------------------------------------------------------------------------------------


@examples(40)
@given(
    low_rank_captures(),
    seeds,
    st.sampled_from([np.nan, np.inf, -np.inf]),
    st.sampled_from(["fit", "solve_basis", "solve_targets", "alpha_captured", "alpha_reconstructed", "hand"]),
)
def test_non_finite_core_inputs_are_refused(data, seed, value, where):
    capture, _ = data
    rng = np.random.default_rng(seed)
    n_dims = capture.shape[1] - capture.shape[1] % 3
    assume(n_dims >= 3)
    capture = capture[:, :n_dims]
    basis = rng.normal(size=(2, n_dims))

    def spoil(array):
        spoiled = np.array(array)
        spoiled[tuple(rng.integers(0, size) for size in spoiled.shape)] = value
        return spoiled

    with pytest.raises(WorkbenchError, match="NaN|Inf|finite"):
        if where == "fit":
            Eigenfaces().fit(spoil(capture))
        elif where == "solve_basis":
            solve_weights(spoil(basis), capture)
        elif where == "solve_targets":
            solve_weights(basis, spoil(capture), kind="nnls")
        elif where == "alpha_captured":
            summarise_alpha(np.zeros(n_dims), spoil(capture), capture)
        elif where == "alpha_reconstructed":
            summarise_alpha(np.zeros(n_dims), capture, spoil(capture))
        else:
            build_quasi_eigen_basis(spoil(basis), ["a", "b"], Eigenfaces(coverage=1.0).fit(capture))


# ----------------------------------------------------------------------------------------------------------
# OBJ files
# ----------------------------------------------------------------------------------------------------------

coordinates = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


@st.composite
def obj_meshes(draw):
    """(text, vertices, polygon sizes, 0-based corners) of a valid OBJ with mixed corner syntax."""
    n_vertices = draw(st.integers(3, 12))
    vertices = np.array(
        draw(st.lists(st.tuples(coordinates, coordinates, coordinates), min_size=n_vertices, max_size=n_vertices))
    )
    polygons = draw(st.lists(st.lists(st.integers(0, n_vertices - 1), min_size=3, max_size=5), max_size=6))
    corner = draw(st.sampled_from(["{i}", "{i}/{i}", "{i}//{i}", "{i}/{i}/{i}"]))
    lines = ["# written by a property test", "o mesh"]
    lines += [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in vertices]
    lines += ["vt 0 0", "vn 0 0 1"] + ["f " + " ".join(corner.format(i=i + 1) for i in polygon) for polygon in polygons]
    sizes = np.array([len(polygon) for polygon in polygons], dtype=np.int64)
    corners = np.array([i for polygon in polygons for i in polygon], dtype=np.int64)
    return "\n".join(lines) + "\n", vertices, sizes, corners


@examples(40)
@given(obj_meshes())
def test_obj_round_trip(tmp_path_factory, mesh):
    text, vertices, sizes, corners = mesh
    path = fresh(tmp_path_factory.getbasetemp(), ".obj")
    path.write_text(text)
    read = read_obj(path)
    np.testing.assert_array_equal(read.vertices, vertices)
    np.testing.assert_array_equal(read.polygon_sizes, sizes)
    np.testing.assert_array_equal(read.polygon_vertices, corners)


@examples(60)
@given(obj_meshes(), st.data())
def test_damaged_obj_is_an_error_or_a_valid_mesh(tmp_path_factory, mesh, data):
    text, vertices, _, _ = mesh
    raw = text.encode()
    damage = data.draw(st.sampled_from(["truncate", "garbage"]))
    if damage == "truncate":
        raw = raw[: data.draw(st.integers(0, len(raw) - 1))]
    else:
        position = data.draw(st.integers(0, len(raw)))
        raw = raw[:position] + data.draw(st.binary(min_size=1, max_size=16)) + raw[position:]
    path = fresh(tmp_path_factory.getbasetemp(), ".obj")
    path.write_bytes(raw)
    try:
        read = read_obj(path)
    except WorkbenchError as error:
        assert str(error).startswith(str(path))
        return
    assert read.vertices.ndim == 2 and read.vertices.shape[1] == 3 and np.all(np.isfinite(read.vertices))
    assert np.all(read.polygon_vertices >= 0) and np.all(read.polygon_vertices < read.n_vertices)


@examples(40)
@given(obj_meshes(), st.data(), st.sampled_from(["nan", "NaN", "inf", "-inf", "1e999"]))
def test_nan_text_in_an_obj_is_an_error(tmp_path_factory, mesh, data, word):
    text, vertices, _, _ = mesh
    lines = text.splitlines()
    vertex_lines = [i for i, line in enumerate(lines) if line.startswith("v ")]
    row, column = data.draw(st.sampled_from(vertex_lines)), data.draw(st.integers(1, 3))
    parts = lines[row].split()
    parts[column] = word
    lines[row] = " ".join(parts)
    path = fresh(tmp_path_factory.getbasetemp(), ".obj")
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(WorkbenchError, match=rf"vertex {vertex_lines.index(row) + 1} is not finite"):
        read_obj(path)


# ----------------------------------------------------------------------------------------------------------
# Live Link Face CSV files
# ----------------------------------------------------------------------------------------------------------


@st.composite
def livelink_takes(draw):
    """(text, weights, frame step in timecode frames) of a valid Live Link Face CSV."""
    n_frames = draw(st.integers(2, 8))
    step = draw(st.integers(1, 4))
    start = draw(st.integers(0, 86000 * 60))
    rng = np.random.default_rng(draw(seeds))
    weights = rng.uniform(0.0, 1.0, (n_frames, len(ARKIT_NAMES)))
    weights[rng.uniform(size=weights.shape) < 0.3] = 0.0
    rows = [",".join(["Timecode", "BlendShapeCount", *ARKIT_NAMES])]
    for i, values in enumerate(weights):
        frame = start + i * step  # timecode frames at 60 per second
        seconds, ff = divmod(frame, 60)
        timecode = f"{seconds // 3600 % 24:02d}:{seconds // 60 % 60:02d}:{seconds % 60:02d}:{ff:02d}.000"
        rows.append(",".join([timecode, "61", *(repr(float(value)) for value in values)]))
    return "\n".join(rows) + "\n", weights, step


@examples(30)
@given(livelink_takes())
def test_livelink_round_trip(tmp_path_factory, take):
    text, weights, step = take
    path = fresh(tmp_path_factory.getbasetemp(), ".csv")
    path.write_text(text)
    read = read_livelink_csv(path)
    np.testing.assert_array_equal(read.weights, weights)
    np.testing.assert_allclose(read.seconds, np.arange(len(weights)) * step / 60.0, rtol=0, atol=1e-9)
    assert read.frame_rate == pytest.approx(60.0 / step, rel=1e-9)


@examples(50)
@given(livelink_takes(), st.data())
def test_damaged_livelink_csv_is_an_error_or_a_valid_take(tmp_path_factory, take, data):
    text, weights, _ = take
    raw = text.encode()
    if data.draw(st.booleans()):
        raw = raw[: data.draw(st.integers(0, len(raw) - 1))]
    else:
        position = data.draw(st.integers(0, len(raw)))
        raw = raw[:position] + data.draw(st.binary(min_size=1, max_size=16)) + raw[position:]
    path = fresh(tmp_path_factory.getbasetemp(), ".csv")
    path.write_bytes(raw)
    try:
        read = read_livelink_csv(path)
    except WorkbenchError as error:
        assert str(error).startswith(str(path))
        return
    assert 2 <= read.n_frames <= len(weights) + 1
    assert np.all(np.isfinite(read.weights)) and np.all(np.diff(read.seconds) > 0)


@examples(30)
@given(livelink_takes(), st.data(), st.sampled_from(["nan", "NaN", "inf", "-inf", "", "n/a"]))
def test_nan_text_in_a_livelink_csv_is_an_error(tmp_path_factory, take, data, word):
    text, weights, _ = take
    lines = text.splitlines()
    row = data.draw(st.integers(1, len(weights)))
    column = data.draw(st.integers(2, 1 + len(ARKIT_NAMES)))
    cells = lines[row].split(",")
    cells[column] = word
    lines[row] = ",".join(cells)
    path = fresh(tmp_path_factory.getbasetemp(), ".csv")
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(
        WorkbenchError,
        match=rf"row {row + 1}, column {ARKIT_NAMES[column - 2]}: .* is not a finite "
        r"number",
    ):
        read_livelink_csv(path)


# ----------------------------------------------------------------------------------------------------------
# C3D files
# ----------------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def small_c3d(tmp_path_factory):
    """Bytes, positions (mm) and the offset of the frame data of a float C3D of 3 markers over 30 frames."""
    import c3d

    positions = np.random.default_rng(7).uniform(-200, 200, (30, 3, 3)).astype(np.float32)
    writer = c3d.Writer(point_rate=100.0, point_units="mm  ")
    writer.set_point_labels(["A", "B", "C"])
    frames = []
    for frame in positions:
        points = np.zeros((3, 5), dtype=np.float32)
        points[:, :3] = frame
        frames.append((points, np.zeros((0, 0), dtype=np.float32)))
    writer.add_frames(frames)
    path = tmp_path_factory.mktemp("c3d") / "take.c3d"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with open(path, "wb") as handle:
            writer.write(handle)
        with open(path, "rb") as handle:
            data_start = 512 * (c3d.Reader(handle).header.data_block - 1)
    return path.read_bytes(), positions.astype(np.float64), data_start


@examples(40)
@given(st.data())
def test_truncated_c3d_is_an_error_unless_only_padding_was_cut(tmp_path_factory, small_c3d, data):
    raw, positions, _ = small_c3d
    path = fresh(tmp_path_factory.getbasetemp(), ".c3d")
    path.write_bytes(raw[: data.draw(st.integers(0, len(raw) - 1))])
    try:
        take = read_c3d_markers(path)
    except WorkbenchError as error:
        assert str(error).startswith(str(path))
        return
    np.testing.assert_array_equal(take.positions, positions)  # the cut fell in the padding of the last block


@examples(40)
@given(st.data())
def test_garbage_in_c3d_frames_is_an_error_or_gaps(tmp_path_factory, small_c3d, data):
    raw, positions, data_start = small_c3d
    position = data.draw(st.integers(data_start, len(raw) - 1))
    garbage = data.draw(st.binary(min_size=1, max_size=32))
    path = fresh(tmp_path_factory.getbasetemp(), ".c3d")
    path.write_bytes(raw[:position] + garbage + raw[position + len(garbage) :])
    try:
        take = read_c3d_markers(path)
    except WorkbenchError as error:
        assert str(error).startswith(str(path))
        return
    values = take.positions[~np.isnan(take.positions)]
    assert take.positions.shape == positions.shape and np.all(np.isfinite(values))
