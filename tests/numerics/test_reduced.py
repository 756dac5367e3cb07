"""The shared pass over the frames (workbench.numerics.reduced) and frame storage (workbench.numerics.frames): known answers against
the explicit residuals and reconstructions."""

import numpy as np
import pytest

from workbench.core.errors import WorkbenchError
from workbench.numerics import reduced
from workbench.numerics.frames import (
    FramesOnDisk,
    FrameWriter,
    checksum_path,
    frame_chunks,
    is_stored_frames,
    written_intact,
)
from workbench.numerics.metrics import reference_squares, summarise_alpha, summarise_squares
from workbench.numerics.reduced import (
    Subspace,
    joint_span,
    project_frames,
    project_onto_each,
    project_through_span,
    region_error_sq,
)
from workbench.numerics.solve import in_span_difference, in_span_error_sq, reduce_basis, solve_projected, solve_weights


def problem(seed=0, n_frames=300, n_dims=60, n_shapes=7):
    rng = np.random.default_rng(seed)
    shapes = rng.standard_normal((n_shapes, n_dims))
    frames = rng.standard_normal((n_frames, n_shapes)) @ shapes + 0.05 * rng.standard_normal((n_frames, n_dims))
    frames[:5] = rng.standard_normal(n_shapes)[None, :] @ shapes  # exactly in the span: distance 0
    neutral = 50.0 + rng.standard_normal(n_dims)
    return shapes, frames, neutral


def test_distances_equal_the_explicit_residuals_including_frames_in_the_span():
    shapes, frames, neutral = problem()
    reduction = reduce_basis(shapes)
    mean = frames.mean(axis=0)
    centred_basis = np.linalg.qr((frames - mean)[:40].T)[0][:, :5]
    spaces = {"B": Subspace(reduction.u), "PCA": Subspace(centred_basis, mean)}
    out = project_frames(frames, spaces, neutral, chunk_size=64)
    explicit = frames - (frames @ reduction.u) @ reduction.u.T
    np.testing.assert_allclose(out.distance_sq["B"], np.sum(explicit**2, axis=1), rtol=1e-10, atol=1e-20)
    assert np.all(out.distance_sq["B"][:5] < 1e-20)  # no cancellation noise where the frame is in the span
    assert out.n_explicit >= 5
    explicit = (frames - mean) - ((frames - mean) @ centred_basis) @ centred_basis.T
    np.testing.assert_allclose(out.distance_sq["PCA"], np.sum(explicit**2, axis=1), rtol=1e-10, atol=1e-20)
    np.testing.assert_allclose(out.coordinates["PCA"], (frames - mean) @ centred_basis, rtol=1e-12, atol=1e-12)
    displacement_sq, position_sq = reference_squares(neutral, frames)
    np.testing.assert_allclose(out.displacement_sq, displacement_sq, rtol=1e-13)
    np.testing.assert_allclose(out.position_sq, position_sq, rtol=1e-13)


@pytest.mark.parametrize("kind, bounds", [("lstsq", {}), ("nnls", {}), ("box", {"lower": 0.0, "upper": 1.0})])
def test_alpha_from_projections_equals_alpha_of_the_reconstruction(kind, bounds):
    shapes, frames, neutral = problem(seed=1)
    reduction = reduce_basis(shapes)
    out = project_frames(frames, {"B": Subspace(reduction.u)}, neutral)
    solution = solve_projected(reduction, out.coordinates["B"], kind=kind, **bounds)
    direct = solve_weights(shapes, frames, kind=kind, **bounds)
    np.testing.assert_allclose(solution.weights, direct.weights, rtol=1e-8, atol=1e-10)
    error_sq = out.distance_sq["B"] + in_span_error_sq(reduction, out.coordinates["B"], solution.weights)
    fast = summarise_squares(error_sq, out.displacement_sq, out.position_sq, frames.size // 3)
    slow = summarise_alpha(neutral, frames, solution.weights @ shapes)
    for field in ("absolute_mean", "absolute_pooled", "displacement_mean", "displacement_pooled", "rms_mm"):
        assert getattr(fast, field) == pytest.approx(getattr(slow, field), rel=1e-11)


@pytest.mark.parametrize("kind, bounds", [("lstsq", {}), ("nnls", {}), ("box", {"lower": 0.0, "upper": 1.0})])
def test_region_error_from_the_projection_pass_equals_the_explicit_residual_over_the_region(kind, bounds):
    shapes, frames, neutral = problem(seed=3)
    frames[5:8] = 0.0  # at rest: zero error everywhere
    region = np.zeros(frames.shape[1], dtype=bool)
    region[:30] = True
    reduction = reduce_basis(shapes)
    mean = frames.mean(axis=0)
    pca = np.linalg.svd((frames - mean).T, full_matrices=False)[0][:, :4]
    spaces = {"B": Subspace(reduction.u), "PCA": Subspace(pca, mean)}
    out = project_frames(frames, spaces, neutral, chunk_size=16, region=region)
    plain = project_frames(frames, spaces, neutral, chunk_size=16)
    for label in spaces:  # the region's terms leave the rest of the pass as it was
        np.testing.assert_array_equal(out.distance_sq[label], plain.distance_sq[label])
        np.testing.assert_array_equal(out.coordinates[label], plain.coordinates[label])
    weights = solve_projected(reduction, out.coordinates["B"], kind=kind, **bounds).weights
    fitted = region_error_sq(out.region, "B", in_span_difference(reduction, out.coordinates["B"], weights))
    residual = (frames - weights @ shapes)[:, region]
    np.testing.assert_allclose(fitted, np.sum(residual**2, axis=1), rtol=1e-10, atol=1e-24)
    projected = (frames - mean) - ((frames - mean) @ pca) @ pca.T
    np.testing.assert_allclose(
        region_error_sq(out.region, "PCA"), np.sum(projected[:, region] ** 2, axis=1), rtol=1e-10, atol=1e-24
    )
    assert np.all(fitted[5:8] == 0.0) and out.n_explicit >= 8  # in the span (5) and at rest (3): explicit residuals


@pytest.mark.parametrize("dtype", ["float32", "float64"])
def test_frames_written_chunk_by_chunk_read_back(tmp_path, dtype):
    frames = np.random.default_rng(2).standard_normal((37, 12))
    writer = FrameWriter(tmp_path / "frames.npy", 37, 12, dtype)
    for start in range(0, 37, 10):
        writer.write(frames[start : start + 10])
    stored = writer.close()
    assert isinstance(stored, FramesOnDisk) and stored.shape == (37, 12) and is_stored_frames(stored)
    expected = frames.astype(dtype).astype(float)
    np.testing.assert_array_equal(np.load(tmp_path / "frames.npy"), frames.astype(dtype))
    np.testing.assert_array_equal(np.asarray(stored), expected)
    np.testing.assert_array_equal(stored[3:9], expected[3:9])
    np.testing.assert_array_equal(stored[[4, 0]], expected[[4, 0]])
    chunks = list(frame_chunks(stored, 8))
    assert [rows.start for rows, _ in chunks] == [0, 8, 16, 24, 32]
    np.testing.assert_array_equal(np.vstack([chunk for _, chunk in chunks]), expected)
    # no temporary file left: the frames and the SHA-256 their writer recorded beside them
    assert sorted(tmp_path.iterdir()) == [tmp_path / "frames.npy", checksum_path(tmp_path / "frames.npy")]
    assert written_intact(tmp_path / "frames.npy") is None


def test_frame_writer_refuses_a_short_file(tmp_path):
    writer = FrameWriter(tmp_path / "frames.npy", 5, 3)
    writer.write(np.zeros((2, 3)))
    with pytest.raises(WorkbenchError, match="2 of 5 frames written"):
        writer.close()
    assert not list(tmp_path.iterdir())


def test_a_bad_frames_file_is_named(tmp_path):
    path = tmp_path / "frames.npy"
    np.save(path, np.zeros((2, 3, 4)))
    with pytest.raises(WorkbenchError, match="frames.npy.*shape"):
        FramesOnDisk(path)


def test_rows_of_frames_on_disk_read_their_part(tmp_path):
    frames = np.arange(40.0).reshape(10, 4)
    np.save(tmp_path / "frames.npy", frames)
    part = FramesOnDisk(tmp_path / "frames.npy").rows(6, 10)
    assert part.shape == (4, 4) and part.first == 6
    np.testing.assert_array_equal(np.asarray(part), frames[6:])
    np.testing.assert_array_equal(part[1:3], frames[7:9])


def test_randomised_pca_of_stored_frames_equals_the_in_memory_one(tmp_path):
    from workbench.numerics.bases import Eigenfaces

    rng = np.random.default_rng(3)
    frames = (rng.standard_normal((400, 12)) * np.geomspace(10, 0.1, 12)) @ rng.standard_normal((12, 90))
    frames = frames.astype(np.float32)
    np.save(tmp_path / "frames.npy", frames)
    reference = Eigenfaces(coverage=0.99, svd_solver="randomized").fit(frames.astype(np.float64))
    for stored in (frames, FramesOnDisk(tmp_path / "frames.npy")):
        fitted = Eigenfaces(coverage=0.99, svd_solver="randomized").fit(stored)
        assert fitted.n_components_ == reference.n_components_
        np.testing.assert_allclose(fitted.explained_variance_, reference.explained_variance_, rtol=1e-10)
        np.testing.assert_allclose(fitted.components_, reference.components_, atol=1e-9)
        np.testing.assert_allclose(fitted.mean_, reference.mean_, rtol=1e-12, atol=1e-12)


def study_alphas(tmp_path, *overrides):
    from workbench.api import run_study
    from workbench.dataset.cache import clear_memory
    from workbench.settings.config import compose, resolved_without_hydra

    clear_memory()
    cfg = resolved_without_hydra(
        compose(
            "paper",
            [
                "dataset.n_frames=400",
                "dataset.mesh_rows=24",
                "dataset.mesh_cols=20",
                "dataset.train_on=mesh",
                "solver=all",
                "basis.paper_regime=false",
                f"paths.cache_dir={tmp_path}",
                *overrides,
            ],
        )
    )
    (result,) = run_study(cfg)
    return result, np.array(
        [[row.alpha.absolute_mean, row.alpha.displacement_mean, row.alpha.rms_mm] for row in result.rows]
    )


def test_mesh_study_in_float32_and_on_disk_matches_float64_in_memory(tmp_path):
    _, reference = study_alphas(tmp_path)
    float32, in_memory = study_alphas(tmp_path, "dataset.dtype=float32")
    assert float32.capture.train.dtype == np.float32
    np.testing.assert_allclose(in_memory, reference, rtol=1e-6)
    on_disk, stored = study_alphas(tmp_path, "dataset.dtype=float32", "dataset.storage=disk")
    assert isinstance(on_disk.capture.train, FramesOnDisk) and on_disk.capture.eval is on_disk.capture.train
    np.testing.assert_allclose(stored, in_memory, rtol=1e-10)
    again, from_cache = study_alphas(tmp_path, "dataset.dtype=float32", "dataset.storage=disk")  # from the cache
    assert again.capture.train.path == on_disk.capture.train.path
    np.testing.assert_array_equal(from_cache, stored)


def test_disk_storage_needs_a_cache_dir():
    from workbench.dataset import build_captures

    with pytest.raises(WorkbenchError, match="dataset.storage=disk .*paths.cache_dir"):
        build_captures({"kind": "synthetic", "storage": "disk"}, cache_dir=None)
    with pytest.raises(WorkbenchError, match="dataset.dtype must be one of"):
        build_captures({"kind": "synthetic", "dtype": "float16"}, cache_dir=None)


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_exact_pca_of_stored_frames_streams_the_covariance_and_equals_the_in_memory_one(tmp_path, dtype):
    from workbench.numerics.bases import Eigenfaces, frames_covariance

    rng = np.random.default_rng(4)
    frames = rng.standard_normal((500, 6)) @ rng.standard_normal((6, 24)) + 5.0  # rank 6, far from the origin
    writer = FrameWriter(tmp_path / "frames.npy", 500, 24, dtype)
    writer.write(frames)
    stored = writer.close()
    exact = frames.astype(dtype).astype(np.float64)
    mean = exact.mean(axis=0)
    np.testing.assert_allclose(
        frames_covariance(stored, mean, chunk_size=7), np.cov(exact.T, bias=True), rtol=0, atol=1e-12
    )
    from_disk, in_memory = Eigenfaces(svd_solver="exact").fit(stored), Eigenfaces(svd_solver="exact").fit(exact)
    assert from_disk.method_ == in_memory.method_ == "covariance" and from_disk.n_components_ == 6
    np.testing.assert_allclose(from_disk.explained_variance_, in_memory.explained_variance_, rtol=1e-12)
    np.testing.assert_allclose(from_disk.components_, in_memory.components_, rtol=0, atol=1e-10)


def test_subspaces_sharing_a_span_are_taken_through_it_with_the_explicit_answers(monkeypatch):
    """Quasi-eigen-like subspaces inside span(PCA, mean): the pass goes through the joint span (fewer columns than
    the subspaces together) and every term equals the explicit residual's, as the pass over each subspace's own
    columns gives it."""
    shapes, frames, neutral = problem(seed=4)
    frames[5:8] = 0.0  # at rest
    mean = frames.mean(axis=0)
    pca = np.linalg.svd((frames - mean).T, full_matrices=False)[0][:, :4]
    frames[8:11] = mean + np.random.default_rng(5).standard_normal((3, 4)) @ pca.T  # on PCA's hyperplane
    on_plane = mean + (shapes - mean) @ pca @ pca.T  # hand shapes projected onto it: rank 5 of 7
    spaces = {
        "B": Subspace(reduce_basis(shapes).u),
        "QE": Subspace(reduce_basis(on_plane).u),
        "PCA": Subspace(pca, mean),
    }
    region = np.zeros(frames.shape[1], dtype=bool)
    region[10:40] = True
    span = joint_span(spaces)
    assert span is not None and span.shape[1] < 7 + 7 + 4
    out = project_through_span(frames, spaces, neutral, span, chunk_size=16, region=region)
    each = project_onto_each(frames, spaces, neutral, chunk_size=16, region=region)
    for label, subspace in spaces.items():
        offset = 0.0 if subspace.offset is None else subspace.offset
        coordinates = (frames - offset) @ subspace.columns
        residual = frames - offset - coordinates @ subspace.columns.T
        np.testing.assert_allclose(out.coordinates[label], coordinates, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(out.distance_sq[label], np.sum(residual**2, axis=1), rtol=1e-10, atol=1e-20)
        np.testing.assert_allclose(out.distance_sq[label], each.distance_sq[label], rtol=1e-10, atol=1e-20)
        in_region = region_error_sq(out.region, label)
        np.testing.assert_allclose(in_region, np.sum(residual[:, region] ** 2, axis=1), rtol=1e-10, atol=1e-20)
        difference = np.random.default_rng(6).standard_normal(coordinates.shape)
        np.testing.assert_allclose(
            region_error_sq(out.region, label, difference),
            region_error_sq(each.region, label, difference),
            rtol=1e-10,
        )
    assert np.all(out.distance_sq["PCA"][8:11] < 1e-20) and np.all(out.distance_sq["B"][5:8] == 0.0)
    assert out.n_explicit >= 6  # on the hyperplane (3) and at rest (3)
    np.testing.assert_allclose(out.position_sq, each.position_sq, rtol=1e-13)
    np.testing.assert_array_equal(out.displacement_sq, each.displacement_sq)
    monkeypatch.setattr(reduced, "LARGE_FRAMES", frames.size)  # project_frames takes this route from here
    plain = project_frames(frames, spaces, neutral, chunk_size=16)
    assert plain.n_explicit >= 6
    for label in spaces:  # the region's terms leave the rest of the pass as it was
        np.testing.assert_array_equal(out.distance_sq[label], plain.distance_sq[label])
        np.testing.assert_array_equal(out.coordinates[label], plain.coordinates[label])


def test_a_later_pass_handed_the_kept_span_reads_only_the_frames_it_must(monkeypatch):
    """The m = n variant's case: its eigenfaces were taken into the first pass's span (also_span), so a second
    call over the same frames handed that pass takes its terms from it, with the answers of a pass of its own."""
    shapes, frames, neutral = problem(seed=7)
    mean = frames.mean(axis=0)
    eigen = np.linalg.svd((frames - mean).T, full_matrices=False)[0]
    frames[:4] = mean + np.random.default_rng(8).standard_normal((4, 6)) @ eigen[:, :6].T  # on the wider plane
    monkeypatch.setattr(reduced, "LARGE_FRAMES", 0)
    region = np.zeros(frames.shape[1], dtype=bool)
    region[::3] = True
    first = {
        "B": Subspace(reduce_basis(shapes).u),
        "QE": Subspace(reduce_basis(mean + (shapes - mean) @ eigen[:, :6] @ eigen[:, :6].T).u),
        "PCA": Subspace(eigen[:, :3], mean),
    }
    before = project_frames(frames, first, neutral, chunk_size=32, region=region, also_span=eigen[:, :6])
    kept = before.span_pass
    assert kept is not None and kept.span.shape[1] < frames.shape[1]
    assert before.n_explicit >= 4  # the frames on the plane, close to the first QE's span
    on_plane = mean + (shapes - mean) @ eigen[:, :6] @ eigen[:, :6].T
    second = {"B": first["B"], "QE": Subspace(reduce_basis(on_plane).u), "PCA": Subspace(eigen[:, :6], mean)}
    read, real_of = [], reduced.SpanPass.of
    monkeypatch.setattr(reduced.SpanPass, "of", lambda *args, **kw: read.append(args) or real_of(*args, **kw))
    out = project_frames(frames, second, neutral, chunk_size=32, region=region, kept=kept)
    assert out.span_pass is kept and not read  # no new pass
    assert out.n_explicit < len(frames)  # only the frames that now need their explicit residual
    each = project_onto_each(frames, second, neutral, chunk_size=32, region=region)
    for label in second:
        np.testing.assert_allclose(out.coordinates[label], each.coordinates[label], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(out.distance_sq[label], each.distance_sq[label], rtol=1e-10, atol=1e-20)
        np.testing.assert_allclose(
            out.region.distance_sq[label], each.region.distance_sq[label], rtol=1e-10, atol=1e-20
        )
        np.testing.assert_allclose(out.region.cross[label], each.region.cross[label], rtol=1e-9, atol=1e-10)
    assert np.all(out.distance_sq["PCA"][:4] < 1e-20)
    fresh = project_frames(frames, second, neutral, chunk_size=32, region=region)  # nothing handed: a pass of its own
    assert fresh.span_pass is not kept and len(read) == 1
    other = np.linalg.qr(np.random.default_rng(9).standard_normal((frames.shape[1], 2)))[0]
    beside = project_frames(
        frames, {"C": Subspace(other), "D": Subspace(other[:, :1])}, neutral, region=region, kept=kept
    )
    assert beside.span_pass is not kept  # outside the kept span: a pass of its own
    elsewhere = project_frames(frames, second, neutral, chunk_size=32, region=~region, kept=kept)
    assert elsewhere.span_pass is not kept  # another region
    assert not kept.serves(len(frames) - 1, neutral, region, second)  # other frames
    assert not kept.serves(len(frames), neutral + 1.0, region, second)  # another neutral
    assert kept.serves(len(frames), neutral, region, second)


def test_the_study_scores_alike_through_the_joint_span_and_through_each_basis(monkeypatch):
    """Both routes of the scoring pass on the paper's run (mesh, both variants, every solver): alpha to 1e-10.
    The weights of the rank-deficient quasi-eigen basis are not unique and are not compared."""
    from workbench.api import run_study
    from workbench.settings.config import compose, resolved_without_hydra

    config = resolved_without_hydra(compose("paper", ["dataset.n_frames=800", "dataset.train_on=mesh", "solver=all"]))
    alphas = []
    for threshold in (1 << 62, 0):
        monkeypatch.setattr(reduced, "LARGE_FRAMES", threshold)
        results = run_study(config)
        assert [result.data for result in results] == ["mesh m=n", "mesh"]
        alphas.append([(r.data, row.basis, row.solver, row.alpha.absolute_mean) for r in results for row in r.rows])
    assert [row[:3] for row in alphas[0]] == [row[:3] for row in alphas[1]]
    np.testing.assert_allclose([row[3] for row in alphas[1]], [row[3] for row in alphas[0]], rtol=1e-10)


def test_frame_chunks_yield_only_the_chunks_holding_a_wanted_frame(tmp_path):
    frames = np.random.default_rng(10).standard_normal((25, 4))
    np.save(tmp_path / "frames.npy", frames)
    wanted = np.zeros(25, dtype=bool)
    wanted[[3, 4, 21]] = True
    for source in (frames, FramesOnDisk(tmp_path / "frames.npy")):
        chunks = list(frame_chunks(source, 5, wanted=wanted))
        assert [rows for rows, _ in chunks] == [slice(0, 5), slice(20, 25)]
        for rows, chunk in chunks:
            np.testing.assert_array_equal(chunk, frames[rows])
