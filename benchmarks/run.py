"""Speed and memory of the workbench's fast paths against their baselines, in one process, on the same data.

Run from the repository root (not part of the test suite):

    python benchmarks/run.py markers      # paper scale on markers: 35,000 frames x 66 markers, n = 18
    python benchmarks/run.py sweep        # 100 runs of the paper study on markers at paper scale, one process
    python benchmarks/run.py mesh         # mesh scale: the synthetic actor's 4,200-vertex mesh
    python benchmarks/run.py mesh --mesh-rows 97 --mesh-cols 97 --dtype float32          # 9,409 vertices
    python benchmarks/run.py mesh --mesh-rows 163 --mesh-cols 164 --dtype float32 --storage disk \
        --cache-dir /tmp/wb-cache                                       # full-head size (26,732), out of core
    python benchmarks/run.py gaps         # masked solve (capture gaps) against per-frame solves on the seen markers
    python benchmarks/run.py mapped       # PCA of RBF-interpolated mesh frames in marker space, lifted, vs direct
    python benchmarks/run.py cache        # the dataset cache (paths.cache_dir) against no cache: ict_livelink,
                                          #   animface and the synthetic actor (write, hit, sizes on disk)
    python benchmarks/run.py pca_switch   # both PCA paths on the ICT mesh at 700-5,000 frames (--switch-frames):
                                          #   times, the path svd_solver="auto" takes, their agreement
    python benchmarks/run.py coverage     # coverage and width (over the known-variance width) of the within-run
                                          #   intervals on AR(1) series, and of the five-seed intervals on skewed
                                          #   log ratios (--replications, --seed, --with-bootstrap), then their
                                          #   coverage on series like the workbench's (rows sharing the frame's
                                          #   difficulty, several takes; --design-replications, --designs-only);
                                          #   not part of "all": it times nothing. Run it with the checkout's
                                          #   workbench importable (PYTHONPATH=. from the repository root)
    python benchmarks/run.py all

The run starts by printing the BLAS library, its kernel and threads (threadpoolctl) and the OpenBLAS variables of
the environment. Each scenario prints absolute times, the time of one streaming pass over the capture (every frame
read once as float64 and its squared norm taken: the floor any method must pay) with each path's time as a ratio
to it, the ratio fast/baseline, agreement of the results and the peak resident memory of the process. Per-frame SciPy baselines that would take minutes are timed on a random subset of frames
(``--baseline-frames``) and extrapolated; the output says so.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import workbench  # noqa: F401  (first: it sets OpenBLAS's thread timeout before NumPy loads OpenBLAS, as the CLI does)

# isort: split
import numpy as np
from scipy.optimize import lsq_linear, nnls

from workbench.dataset import build_captures
from workbench.numerics.bases import Eigenfaces, build_quasi_eigen_basis
from workbench.numerics.frames import frame_chunks
from workbench.numerics.metrics import summarise_alpha, summarise_squares
from workbench.numerics.solve import reconstruct, solve_weights
from workbench.study.fitting import pca_subspace
from workbench.study.results import Timings
from workbench.study.scoring import projected_rows

SYNTHETIC = {
    "kind": "synthetic",
    "n_frames": 35000,
    "frame_rate": 120.0,
    "n_face_markers": 66,
    "n_head_markers": 7,
    "head_rotation_deg": 3.0,
    "head_translation_mm": 5.0,
    "marker_noise_mm": 0.05,
    "seed": 0,
    "mesh_rows": 70,
    "mesh_cols": 60,
    "stabilise": True,
    "split": "same",
}


def peak_mb() -> float:
    """Peak resident memory of this process so far, in MB (Linux reports kilobytes)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def timed(function, *args, **kwargs):
    start = time.perf_counter()
    value = function(*args, **kwargs)
    return value, time.perf_counter() - start


def blas_report() -> str:
    """The BLAS libraries NumPy and SciPy use, with kernel (architecture) and threads, and the OpenBLAS variables
    that can force a kernel."""
    from threadpoolctl import threadpool_info

    libraries = [
        f"{info.get('internal_api')} {info.get('version')} kernel {info.get('architecture')} "
        f"threads {info.get('num_threads')} ({os.path.basename(info.get('filepath', ''))})"
        for info in threadpool_info()
        if info.get("user_api") == "blas"
    ]
    forced = {
        name: os.environ.get(name) for name in ("OPENBLAS_CORETYPE", "OPENBLAS_L2_SIZE", "OPENBLAS_THREAD_TIMEOUT")
    }
    return f"BLAS: {'; '.join(libraries) or 'none found'}; environment {forced}"


def streaming_pass(frames) -> float:
    """Seconds of one pass over the frames: each chunk read as float64 and its rows' squared norms taken."""
    start = time.perf_counter()
    for _, chunk in frame_chunks(frames):
        np.einsum("ij,ij->i", chunk, chunk)
    return time.perf_counter() - start


def paper_method(capture, *, kind="box", lower=0.0, upper=1.0, svd_solver="auto"):
    """PCA, affine QE, weights of H and QE, and alpha of H, QE and PCA: what a run of the study computes, with
    the weights and alpha of every basis from one shared pass over the frames (the pipeline's path)."""
    eigenfaces = Eigenfaces(coverage=0.995, svd_solver=svd_solver).fit(capture.train)
    qe = build_quasi_eigen_basis(capture.hand, capture.hand_names, eigenfaces, projection="affine")
    rows, _, projections, _ = projected_rows(
        capture,
        [("H", "-", capture.hand), ("QE", "affine", qe.shapes)],
        {kind: {"kind": kind, "lower": lower, "upper": upper}},
        Timings(),
        subspaces={"PCA": pca_subspace(eigenfaces)},
    )
    alphas = {row.basis: row.alpha.absolute_mean for row in rows}
    alphas["PCA"] = summarise_squares(
        projections.distance_sq["PCA"], projections.displacement_sq, projections.position_sq, capture.eval.size // 3
    ).absolute_mean
    return eigenfaces, qe, alphas


def paper_method_per_basis(capture, *, kind="box", lower=0.0, upper=1.0):
    """The baseline of :func:`paper_method`: each basis solved on the full frames and scored on its
    reconstruction, a pass over the frames per basis (the pipeline's path before the shared pass)."""
    eigenfaces = Eigenfaces(coverage=0.995).fit(capture.train)
    qe = build_quasi_eigen_basis(capture.hand, capture.hand_names, eigenfaces, projection="affine")
    alphas = {}
    for label, shapes in (("H", capture.hand), ("QE", qe.shapes)):
        weights = solve_weights(shapes, capture.eval, kind=kind, lower=lower, upper=upper).weights
        alphas[label] = summarise_alpha(
            capture.neutral, capture.eval, lambda rows: reconstruct(shapes, weights[rows])
        ).absolute_mean
    alphas["PCA"] = summarise_alpha(
        capture.neutral, capture.eval, lambda rows: eigenfaces.reconstruct(capture.eval[rows])
    ).absolute_mean
    return eigenfaces, qe, alphas


def per_frame(solver, shapes, frames):
    """Weights of each frame by a per-frame SciPy call (the baseline), shape (n_frames, n_shapes)."""
    if solver.startswith("lsq_linear"):  # "lsq_linear" (SciPy's default method, trf) or "lsq_linear/bvls"
        method = solver.partition("/")[2] or "trf"
        return np.array([lsq_linear(shapes.T, frame, bounds=(0.0, 1.0), method=method).x for frame in frames])
    return np.array([nnls(shapes.T, frame)[0] for frame in frames])


def objective(shapes, frames, weights):
    return np.sum((frames - weights @ shapes) ** 2, axis=1)


def bench_markers(args) -> None:
    print(f"== markers, paper scale: {args.frames} frames x 66 markers, n = 18 (synthetic actor, seed 0)")
    captures, build_seconds = timed(build_captures, dict(SYNTHETIC, n_frames=args.frames, train_on="markers"))
    capture = captures["markers"]
    print(f"dataset build (not part of the method): {build_seconds:.2f} s")
    paper_method(capture)  # warm-up: first calls pay for imports, compilation and BLAS start-up
    paper_method_per_basis(capture)
    one_pass = float(np.median([streaming_pass(capture.eval) for _ in range(args.repeats)]))
    print(f"one streaming pass over the capture: {one_pass * 1e3:.1f} ms (median of {args.repeats})")
    repeats, baseline = [], []
    for _ in range(args.repeats):  # interleaved, so that a change in the machine's load hits both alike
        repeats.append(timed(paper_method, capture))
        baseline.append(timed(paper_method_per_basis, capture))
    (eigenfaces, qe, alphas), fast_seconds = repeats[0][0], float(np.median([seconds for _, seconds in repeats]))
    base_alphas, base_seconds = baseline[0][0][2], float(np.median([seconds for _, seconds in baseline]))
    agreement = max(abs(alphas[key] - base_alphas[key]) / base_alphas[key] for key in alphas)
    print(
        f"paper method: PCA + QE + box [0,1] weights of H and QE + alpha of H, QE, PCA: {fast_seconds:.3f} s, "
        f"median of {args.repeats} (min {min(seconds for _, seconds in repeats):.3f} s), "
        f"x{fast_seconds / one_pass:.1f} one pass; per-basis baseline {base_seconds:.3f} s "
        f"(x{base_seconds / fast_seconds:.2f} the shared pass); max relative alpha difference {agreement:.1e} "
        f"(m = {eigenfaces.n_components_}; alpha_abs_mean H {alphas['H']:.3f}, QE {alphas['QE']:.3f}, "
        f"PCA {alphas['PCA']:.3f})"
    )

    gram = float(np.median([timed(np.matmul, capture.train.T, capture.train)[1] for _ in range(args.repeats)]))
    print(
        f"the PCA's covariance product D^T D alone (a floor of any exact PCA): {gram * 1e3:.1f} ms, "
        f"x{gram / one_pass:.1f} one pass"
    )
    centred = capture.train - capture.train.mean(axis=0)
    svd_seconds = float(np.median([timed(np.linalg.svd, centred, full_matrices=False)[1] for _ in range(args.repeats)]))
    pca_seconds = float(
        np.median([timed(Eigenfaces(coverage=0.995).fit, capture.train)[1] for _ in range(args.repeats)])
    )
    print(
        f"PCA: eigenfaces {pca_seconds:.3f} s vs full SVD {svd_seconds:.3f} s, medians of {args.repeats}  "
        f"(x{svd_seconds / pca_seconds:.1f})"
    )

    rng = np.random.default_rng(0)
    for label, shapes in (("H", capture.hand), ("QE", qe.shapes)):
        for kind, baseline, upper, n_timed in (
            ("box", "lsq_linear", 1.0, args.baseline_frames // 4),
            ("box", "lsq_linear/bvls", 1.0, args.baseline_frames),
            ("nnls", "nnls", None, len(capture.eval)),
        ):
            runs = [
                timed(solve_weights, shapes, capture.eval, kind=kind, lower=0.0, upper=upper)
                for _ in range(args.repeats)
            ]
            solution, fast = runs[0][0], float(np.median([seconds for _, seconds in runs]))
            subset = np.sort(rng.choice(len(capture.eval), size=min(n_timed, len(capture.eval)), replace=False))
            frames = capture.eval[subset]
            reference, slow = timed(per_frame, baseline, shapes, frames)
            scale = len(capture.eval) / len(frames)
            mine = solution.weights[subset]
            gap = np.max(
                np.abs(objective(shapes, frames, mine) - objective(shapes, frames, reference))
                / np.maximum(objective(shapes, frames, reference), 1e-12)
            )
            note = "" if scale == 1 else f" (timed on {len(frames)} frames, x{scale:.0f} extrapolated)"
            print(
                f"{label} {kind}: batched {fast:.3f} s (median of {args.repeats}, x{fast / one_pass:.1f} one pass) vs per-frame {baseline} "
                f"{slow * scale:.2f} s{note}  x{slow * scale / fast:.0f}; max relative objective gap {gap:.1e}; "
                f"fallback frames {solution.n_fallback_frames}"
            )
    print(f"peak memory {peak_mb():.0f} MB")


def timed_passes(frames, count: int = 3) -> list[tuple[float, float]]:
    """Wall and CPU seconds of ``count`` streaming passes over the frames."""
    passes = []
    for _ in range(count):
        cpu_start, wall = time.process_time(), streaming_pass(frames)
        passes.append((wall, time.process_time() - cpu_start))
    return passes


def bench_mesh(args) -> None:
    from workbench.api import run_study
    from workbench.settings.config import compose, resolved_without_hydra

    overrides = [
        f"dataset.n_frames={args.mesh_frames}",
        "dataset.train_on=mesh",
        "solver=all",
        f"dataset.mesh_rows={args.mesh_rows}",
        f"dataset.mesh_cols={args.mesh_cols}",
        f"dataset.dtype={args.dtype}",
        f"dataset.storage={args.storage}",
    ]
    if args.cache_dir:
        overrides.append(f"paths.cache_dir={args.cache_dir}")
    cfg = resolved_without_hydra(compose("paper", overrides))
    n_vertices = args.mesh_rows * args.mesh_cols
    print(
        f"== mesh scale: {args.mesh_frames} frames x {n_vertices:,} vertices (synthetic actor's dense mesh), "
        f"n = 18, frames {args.dtype} in {args.storage}"
    )
    captures, build_seconds = timed(build_captures, cfg["dataset"], cfg["paths"]["cache_dir"])
    capture = captures["mesh"]
    size = capture.train.shape[0] * capture.train.shape[1] * np.dtype(args.dtype).itemsize
    print(
        f"dataset build: {build_seconds:.1f} s; capture {size / 2**30:.2f} GiB ({type(capture.train).__name__}); "
        f"peak so far {peak_mb():.0f} MB"
    )
    # one pass: the median of three before the study and two after it (a shared machine's memory runs faster and
    # slower by the minute: 0.67-1.21 s on one machine in one hour); the first touches every page of the capture
    passes = timed_passes(capture.eval)
    cpu_start = time.process_time()
    results, study_seconds = timed(run_study, cfg)  # the dataset comes from the cache
    study_cpu = time.process_time() - cpu_start
    passes += timed_passes(capture.eval, 2)
    one_pass, pass_cpu = sorted(passes)[len(passes) // 2]
    print(
        f"one streaming pass over the capture: {one_pass:.2f} s (CPU {pass_cpu:.2f} s; median of "
        f"{', '.join(f'{wall:.2f}' for wall, _ in passes[:3])} s before the study and "
        f"{', '.join(f'{wall:.2f}' for wall, _ in passes[3:])} s after it)"
    )
    result = results[0]
    stages = ", ".join(f"{name} {seconds:.1f} s" for name, seconds in result.timings.seconds.items())
    pca = result.timings.seconds.get("pca", 0.0)
    print(
        f"whole paper study (solver=all, affine and linear QE, every alpha; dataset cached): {study_seconds:.1f} s "
        f"= x{study_seconds / one_pass:.1f} one pass, PCA {pca:.1f} s = x{pca / one_pass:.1f} one pass (CPU: study "
        f"{study_cpu:.1f} s = x{study_cpu / pass_cpu:.1f} the pass's) ({stages}); "
        + "; ".join(f"{r.data}: m = {r.eigenfaces.n_components_} ({r.eigenfaces.method_})" for r in results)
        + f"; peak {peak_mb():.0f} MB"
    )
    randomized = [r.eigenfaces for r in results if r.eigenfaces.method_ == "randomized"]
    if randomized:  # the fit the other variants reuse found the most eigenpairs: its block was the widest
        product_pass(capture, max(len(fit.explained_variance_) for fit in randomized), one_pass, pca)
    if args.baseline_frames:
        # the scoring of before the shared pass (each basis and solver solved on the frames and scored on its
        # reconstruction) on a subset of frames, extrapolated, against the shared pass on the same subset
        subset = slice(0, min(args.baseline_frames, len(capture.eval)))
        frames = np.asarray(capture.eval[subset], dtype=np.float64)
        bases = [
            (row.basis, row.projection, shapes)
            for row, shapes in zip(result.rows, [capture.hand] + [qe.shapes for qe in result.quasi_eigen.values()])
        ]
        small = replace(capture, train=frames, eval=frames, eval_timeline=None)
        solvers = {name: spec for name, spec in cfg["solver"].items()}
        (_, _, _, _), fast = timed(
            projected_rows, small, bases, solvers, Timings(), subspaces={"PCA": pca_subspace(result.eigenfaces)}
        )

        def per_basis():
            for spec in solvers.values():
                for _, _, shapes in bases:
                    weights = solve_weights(shapes, frames, **spec).weights
                    summarise_alpha(capture.neutral, frames, lambda rows: reconstruct(shapes, weights[rows]))
            summarise_alpha(capture.neutral, frames, lambda rows: result.eigenfaces.reconstruct(frames[rows]))

        _, slow = timed(per_basis)
        scale = len(capture.eval) / len(frames)
        print(
            f"scoring of every basis and solver (weights + alpha): shared pass {fast * scale:.1f} s vs per basis "
            f"and solver {slow * scale:.1f} s (timed on {len(frames)} frames, x{scale:.1f} extrapolated)  "
            f"x{slow / fast:.1f}; peak {peak_mb():.0f} MB"
        )
    if args.pca_reference:
        coverage_rule = min((r.eigenfaces for r in results), key=lambda eigenfaces: eigenfaces.n_components_)
        reference_pca(coverage_rule, capture.train, one_pass)
    if args.with_exact_pca:
        exact, exact_seconds = timed(Eigenfaces(coverage=0.995, svd_solver="exact").fit, capture.train)
        fast, randomized_seconds = timed(Eigenfaces(coverage=0.995, svd_solver="randomized").fit, capture.train)
        print(
            f"PCA: randomised {randomized_seconds:.1f} s vs exact ({exact.method_}) {exact_seconds:.1f} s "
            f"(x{exact_seconds / randomized_seconds:.1f}); same m: {exact.n_components_ == fast.n_components_}; "
            f"coverage {fast.coverage_:.10f} vs {exact.coverage_:.10f}; peak {peak_mb():.0f} MB"
        )


def product_pass(capture, n_eigen: int, one_pass: float, pca: float) -> None:
    """Time one pass of the randomised PCA's products, ``D~^T (D~ Q)`` with ``Q`` as wide as the block of a fit
    that found ``n_eigen`` eigenpairs, and the machine's DGEMM rate on a square product: a pass is arithmetic, not
    a read, when its multiply-adds outrun the memory (the PCA's time over this pass's is about the passes it made)."""
    from workbench.numerics.randomized_pca import OVERSAMPLE, frames_normal_times

    frames = capture.train
    width = min(n_eigen + OVERSAMPLE, *frames.shape)
    rng = np.random.default_rng(0)
    block, mean = rng.standard_normal((frames.shape[1], width)), np.zeros(frames.shape[1])
    seconds = min(timed(frames_normal_times, frames, block, mean)[1] for _ in range(2))
    size = 3000
    square = rng.standard_normal((size, size))
    square_gflop = 2.0 * size**3 / 1e9
    square_seconds = min(timed(np.matmul, square, square)[1] for _ in range(3))
    gflop = 4.0 * frames.shape[0] * frames.shape[1] * width / 1e9
    print(
        f"one product pass of the randomised PCA (D~^T D~ Q, Q {width} columns wide: {gflop:.0f} GFLOP, every frame "
        f"read once): {seconds:.2f} s = x{seconds / one_pass:.1f} one streaming pass, {gflop / seconds:.0f} GFLOP/s "
        f"(a square {size:,} x {size:,} product here: {square_gflop / square_seconds:.0f} GFLOP/s); the PCA took "
        f"{pca / seconds:.1f} product passes' time"
    )


def reference_pca(fitted, frames, one_pass: float) -> None:
    """The study's randomised eigenfaces against a reference fit of the same frames converged much further (Ritz
    residuals within 1e-14 of the largest, up to 16 passes): largest subspace angle at the study's m and at every
    pair it kept for reuse, and the largest relative difference of their eigenvalues."""
    from workbench.numerics import randomized_pca

    tolerance, blocks = randomized_pca.RESIDUAL_RTOL, randomized_pca.MAX_BLOCKS
    randomized_pca.RESIDUAL_RTOL, randomized_pca.MAX_BLOCKS = 1e-14, 16
    try:
        count = fitted._eigenvectors.shape[0]
        reference, seconds = timed(Eigenfaces(n_components=count, svd_solver="randomized", seed=1).fit, frames)
    finally:
        randomized_pca.RESIDUAL_RTOL, randomized_pca.MAX_BLOCKS = tolerance, blocks
    m = fitted.n_components_
    values = fitted.explained_variance_[:count]
    print(
        f"PCA against a reference converged to 1e-14 (another seed, {seconds:.1f} s = x{seconds / one_pass:.1f} one "
        f"pass): largest subspace angle {subspace_angle(fitted.components_, reference.components_[:m]):.1e} rad at "
        f"m = {m}, {subspace_angle(fitted._eigenvectors, reference.components_):.1e} rad at {count}; eigenvalues "
        f"within {np.max(np.abs(values - reference.explained_variance_) / reference.explained_variance_):.1e} "
        "relative"
    )


def subspace_angle(first: np.ndarray, second: np.ndarray) -> float:
    """Largest principal angle in radians between the span of the smaller of two sets of orthonormal rows and the
    other's span, from its sine (the norm of what the other's projection leaves), exact to round-off near zero
    where an arc cosine of the cosines would not resolve angles under 1e-8."""
    if first.shape[0] > second.shape[0]:
        first, second = second, first
    left = first - (first @ second.T) @ second
    return float(np.arcsin(min(1.0, np.linalg.norm(left, 2))))


def bench_pca_switch(args) -> None:
    """Both PCA paths on the ICT mesh frames at frame counts across the switch of ``svd_solver="auto"``: their
    times, which one ``auto`` takes (and the cost model's ratio), and their agreement (m, coverage, angle)."""
    from workbench.numerics.bases import auto_solver, solver_costs
    from workbench.settings.config import compose, resolved_without_hydra

    cfg = resolved_without_hydra(compose("paper", ["dataset=ict_livelink", "dataset.train_on=mesh"]))
    take = np.asarray(build_captures(cfg["dataset"])["mesh"].train, dtype=np.float64)
    frames = np.concatenate([take, take[::-1]])  # the take forwards, then backwards (a frame count past its own)
    del take
    print(
        f"== PCA switch: ICT mesh (ict_livelink, train_on=mesh) frames, {frames.shape[1]:,} columns: the first k "
        f"of the take's {len(frames) // 2:,} frames followed by the same frames in reverse order; coverage 0.995; "
        f"wall seconds (CPU seconds of this process in brackets), medians of 3 below 2,000 frames"
    )
    for n_frames in args.switch_frames:
        capture = np.ascontiguousarray(frames[:n_frames])
        chosen = auto_solver(*capture.shape, None, Eigenfaces.RANDOMIZED_ABOVE)
        exact_cost, randomized_cost = solver_costs(*capture.shape, 32)
        fits, seconds, cpu = {}, {}, {}
        repeats = 3 if n_frames < 2000 else 1  # sub-second fits near the switch: the median of three
        for solver in ("exact", "randomized"):
            runs = []
            for _ in range(repeats):
                start = time.process_time()
                fits[solver], wall = timed(Eigenfaces(coverage=0.995, svd_solver=solver).fit, capture)
                runs.append((wall, time.process_time() - start))
            seconds[solver], cpu[solver] = (float(np.median(column)) for column in zip(*runs))
        other = "exact" if chosen == "randomized" else "randomized"
        exact, fast = fits["exact"], fits["randomized"]
        print(
            f"{n_frames} frames: exact ({exact.method_}) {seconds['exact']:.2f} s ({cpu['exact']:.1f}), randomised "
            f"{seconds['randomized']:.2f} s ({cpu['randomized']:.1f}); auto takes {chosen} (model exact/randomised "
            f"{exact_cost / randomized_cost:.2f}): x{seconds[chosen] / seconds[other]:.2f} the other path "
            f"(CPU x{cpu[chosen] / cpu[other]:.2f}); m {exact.n_components_} vs {fast.n_components_}; coverage "
            f"{exact.coverage_:.10f} vs {fast.coverage_:.10f}; largest subspace angle "
            f"{subspace_angle(exact.components_, fast.components_):.1e} rad"
        )
    print(f"peak memory {peak_mb():.0f} MB")


def per_frame_masked(solver, shapes, frames, visible):
    """The baseline of the masked solve: each frame alone, on the coordinates of the markers it saw."""
    weights = []
    for frame, seen in zip(frames, visible):
        dims = np.repeat(seen, 3)
        design, target = shapes[:, dims].T, frame[dims]
        if solver == "lstsq":
            weights.append(np.linalg.lstsq(design, target, rcond=None)[0])
        elif solver == "nnls":
            weights.append(nnls(design, target)[0])
        else:
            weights.append(lsq_linear(design, target, bounds=(0.0, 1.0), method="bvls").x)
    return np.array(weights)


def masked_objective(shapes, frames, weights, visible):
    error = np.where(np.repeat(visible, 3, axis=1), frames - weights @ shapes, 0.0)
    return np.sum(error**2, axis=1)


def bench_gaps(args) -> None:
    """The masked solve of eq. 5 (capture gaps) on the synthetic actor's markers with 5 % of the samples in
    occlusion gaps, against the same solve frame by frame (NumPy lstsq, SciPy nnls and bounded lsq_linear)."""
    from workbench.settings.config import compose, resolved_without_hydra

    cfg = resolved_without_hydra(
        compose(
            "paper",
            [
                f"dataset.n_frames={args.frames}",
                "dataset.gap_rate=0.05",
                "dataset.gap_policy=masked",
                "dataset.train_on=markers",
            ],
        )
    )
    capture = build_captures(cfg["dataset"])["markers"]
    visible = capture.eval_visible
    print(
        f"== gaps: {len(capture.eval)} frames x 66 markers, {100 * (~visible).mean():.2f} % of the marker "
        f"samples missing; masked solve (each frame on the markers it saw), n = 18"
    )
    eigenfaces = Eigenfaces(coverage=0.995).fit(capture.train)
    qe = build_quasi_eigen_basis(capture.hand, capture.hand_names, eigenfaces, projection="affine")
    rng = np.random.default_rng(0)
    for label, shapes in (("H", capture.hand), ("QE", qe.shapes)):
        for kind, bounds in (("lstsq", {}), ("nnls", {}), ("box", {"lower": 0.0, "upper": 1.0})):
            solution, fast = timed(solve_weights, shapes, capture.eval, kind=kind, visible=visible, **bounds)
            _, unmasked = timed(solve_weights, shapes, capture.train, kind=kind, **bounds)
            subset = np.sort(
                rng.choice(len(capture.eval), size=min(args.baseline_frames, len(capture.eval)), replace=False)
            )
            frames, seen = capture.eval[subset], visible[subset]
            reference, slow = timed(per_frame_masked, kind, shapes, frames, seen)
            scale = len(capture.eval) / len(frames)
            ours = masked_objective(shapes, frames, solution.weights[subset], seen)
            theirs = masked_objective(shapes, frames, reference, seen)
            gap = np.max((ours - theirs) / np.maximum(theirs, 1e-12))
            print(
                f"{label} {kind}: masked batched {fast:.3f} s (unmasked {unmasked:.3f} s) vs per-frame "
                f"{slow * scale:.2f} s (timed on {len(frames)} frames, x{scale:.1f} extrapolated)  "
                f"x{slow * scale / fast:.0f}; max relative objective excess {gap:.1e}; "
                f"fallback frames {solution.n_fallback_frames}"
            )
    print(f"peak memory {peak_mb():.0f} MB")


def bench_mapped(args) -> None:
    """PCA of mesh frames that are an RBF map of marker frames: computed on the markers and lifted
    (``Eigenfaces.fit_mapped``) against the PCA of the materialised mesh frames, on the same capture."""
    from workbench.settings.config import compose, resolved_without_hydra

    overrides = (
        ["dataset=animface", "dataset.train_on=mesh"]
        if args.mapped_dataset == "animface"
        else [f"dataset.n_frames={args.frames}", "dataset.train_on=mesh_rbf"]
    )
    cfg = resolved_without_hydra(compose("paper", overrides))
    capture = next(iter(build_captures(cfg["dataset"]).values()))
    print(
        f"== mapped PCA: {args.mapped_dataset}, {capture.train.shape[0]} frames x {capture.n_points} mesh points "
        f"interpolated from {capture.train_source.shape[1] // 3} markers"
    )
    lifted, lifted_seconds = timed(Eigenfaces(coverage=0.995).fit_mapped, capture.train_source, capture.train_operator)
    direct, direct_seconds = timed(Eigenfaces(coverage=0.995).fit, capture.train)
    m = min(lifted.n_components_, direct.n_components_)
    agreement = np.abs(np.abs(np.sum(lifted.components_[:m] * direct.components_[:m], axis=1)) - 1).max()
    print(
        f"lifted {lifted_seconds:.2f} s vs direct ({direct.method_}) {direct_seconds:.2f} s  "
        f"x{direct_seconds / lifted_seconds:.1f}; m {lifted.n_components_} vs {direct.n_components_}; coverage "
        f"{lifted.coverage_:.10f} vs {direct.coverage_:.10f}; max |1 - |cos|| between eigenfaces {agreement:.1e}; "
        f"peak {peak_mb():.0f} MB"
    )


def bench_sweep(args) -> None:
    """A sweep of the paper study on markers at paper scale, as Hydra's default launcher runs it: one process,
    the dataset built once (the cache) and every run's study (PCA, both QE projections, the chosen solvers,
    both alpha normalisations) after it, without Hydra's per-job overhead and record writing."""
    from workbench.api import run_study
    from workbench.settings.config import compose, resolved_without_hydra

    coverages = np.linspace(0.95, 0.999, args.sweep_runs)
    print(
        f"== sweep: {args.sweep_runs} runs of the paper study (solver={args.solver}) on {args.frames} frames x 66 markers, "
        f"basis.coverage {coverages[0]:.3f} ... {coverages[-1]:.3f}"
    )
    configs = [
        resolved_without_hydra(
            compose(
                "paper", [f"dataset.n_frames={args.frames}", f"solver={args.solver}", f"basis.coverage={coverage:.6f}"]
            )
        )
        for coverage in coverages
    ]
    start = time.perf_counter()
    first, first_seconds = timed(run_study, configs[0])
    for cfg in configs[1:]:
        run_study(cfg)
    total = time.perf_counter() - start
    print(
        f"first run (builds the dataset) {first_seconds:.2f} s; all {args.sweep_runs} runs {total:.1f} s "
        f"({(total - first_seconds) / max(1, args.sweep_runs - 1):.2f} s a run after the first); "
        f"peak {peak_mb():.0f} MB"
    )


CACHE_DATASETS = {"ict_livelink": ["dataset=ict_livelink"], "animface": ["dataset=animface"], "synthetic": []}
"""Datasets of the cache scenario: the paper study's overrides of each (its default variants)."""


def folder_bytes(paths) -> int:
    """Bytes of the files ``paths``."""
    return sum(path.stat().st_size for path in paths)


def captures_digest(captures: dict) -> str:
    """SHA-256 of every array of ``{variant: Capture}`` (frames read a chunk at a time), to compare two builds."""
    import hashlib

    digest = hashlib.sha256()
    for name, capture in captures.items():
        digest.update(name.encode())
        for field in (
            "neutral",
            "train",
            "eval",
            "hand",
            "faces",
            "eval_visible",
            "train_source",
            "train_operator",
            "point_support",
        ):
            value = getattr(capture, field)
            if value is None:
                digest.update(b"none")
                continue
            chunks = frame_chunks(value, dtype=value.dtype) if value.ndim == 2 else [(None, value)]
            for _, chunk in chunks:
                digest.update(np.ascontiguousarray(chunk).tobytes())
    return digest.hexdigest()


def cache_step(overrides: list, cache_dir: str | None, study: bool) -> tuple[float, str]:
    """One step of the cache scenario, run in a new process (:func:`in_new_process`): build the dataset of the
    paper study with ``overrides`` (or run the whole study) with ``paths.cache_dir`` as given; its seconds, imports
    excluded, and a digest of its arrays (or its alpha tables, every digit) to compare routes."""
    from workbench.api import run_study
    from workbench.settings.config import compose, resolved_without_hydra
    from workbench.study.table import alpha_table

    cfg = resolved_without_hydra(compose("paper", [*overrides, f"paths.cache_dir={cache_dir or 'null'}"]))
    if not study:
        captures, seconds = timed(build_captures, cfg["dataset"], cache_dir)
        return seconds, captures_digest(captures)
    results, seconds = timed(run_study, cfg)
    tables = [
        alpha_table(
            result.rows,
            data=result.data,
            m=result.eigenfaces.n_components_,
            coverage=result.eigenfaces.coverage_,
            paper_alpha={},
        ).to_csv(float_format="%.17g")
        for result in results
    ]
    return seconds, "\n".join(tables)


def in_new_process(function, *args):
    """``function(*args)`` in a new Python process (the cache scenario times what a new run pays: nothing that an
    earlier step of the benchmark read or parsed is still in the process's memory)."""
    import multiprocessing

    with multiprocessing.get_context("spawn").Pool(1) as pool:
        return pool.apply(function, args)


def bench_cache(args) -> None:
    """The dataset cache against building without one, per dataset, each step in a new process: the build with no
    cache, a miss (the build and the writing of the entry into an empty cache folder), a hit (the entry read back),
    the size of the entry on disk, and the whole paper study without a cache and from a hit; then what hashing
    costs: the source files (once per process) and the entry's files (every hit checks their SHA-256)."""
    import hashlib

    from workbench.dataset.cache import clear_memory, file_digest, source_files
    from workbench.settings.config import compose, resolved_without_hydra

    def hash_files(paths):
        for path in paths:
            with open(path, "rb") as stream:
                hashlib.file_digest(stream, "sha256")

    root = Path(args.cache_dir) if args.cache_dir else Path(tempfile.mkdtemp(prefix="wb-cache-bench-"))
    print(
        f"== dataset cache: {', '.join(args.cache_datasets)}; each step in a new process (imports not timed); "
        f"medians of {args.repeats}; cache folders under {root}"
    )
    try:
        for name in args.cache_datasets:
            overrides, folder = CACHE_DATASETS[name], root / name
            steps = {"build": [], "miss": [], "hit": [], "study": [], "study hit": []}
            digests = {key: set() for key in steps}
            for _ in range(args.repeats):  # interleaved, so that a change in the machine's load hits each alike
                shutil.rmtree(folder, ignore_errors=True)
                for step, cache_dir, study in (
                    ("build", None, False),
                    ("miss", folder, False),
                    ("hit", folder, False),
                    ("study", None, True),
                    ("study hit", folder, True),
                ):
                    seconds, digest = in_new_process(cache_step, overrides, cache_dir and str(folder), study)
                    steps[step].append(seconds)
                    digests[step].add(digest)
            build, miss, hit, study, study_hit = (float(np.median(steps[step])) for step in steps)
            entry = [path for path in folder.rglob("*") if path.is_file()]
            same = len(digests["build"] | digests["miss"] | digests["hit"]) == 1
            same_tables = len(digests["study"] | digests["study hit"]) == 1
            print(
                f"{name}: build without cache {build:.2f} s; miss (build + write) {miss:.2f} s, so write "
                f"{miss - build:.2f} s (x{miss / build:.2f} the build); hit {hit:.2f} s (x{hit / build:.2f} the "
                f"build); on disk {folder_bytes(entry) / 2**20:.1f} MiB in {len(entry)} files; hit equals build: "
                f"{same}"
            )
            print(
                f"{name} whole paper study: without cache {study:.2f} s, from a cache hit {study_hit:.2f} s "
                f"(x{study_hit / study:.2f}); alpha tables identical to every digit: {same_tables}"
            )
            cfg = resolved_without_hydra(compose("paper", overrides))
            sources = source_files(cfg["dataset"])
            clear_memory()
            source_seconds = timed(lambda: [file_digest(path) for path in sources])[1]
            remembered = timed(lambda: [file_digest(path) for path in sources])[1]
            entry_seconds = float(np.median([timed(hash_files, entry)[1] for _ in range(args.repeats)]))
            print(
                f"{name} hashing (SHA-256): its {len(sources)} source files ({folder_bytes(sources) / 2**20:.1f} "
                f"MiB) {source_seconds:.3f} s once per process, then {remembered * 1e3:.2f} ms (remembered); the "
                f"entry's files {entry_seconds:.3f} s, part of every hit"
            )
    finally:
        if not args.cache_dir:
            shutil.rmtree(root, ignore_errors=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "scenario", choices=["markers", "mesh", "sweep", "gaps", "mapped", "cache", "coverage", "pca_switch", "all"]
    )
    parser.add_argument(
        "--mapped-dataset",
        choices=["animface", "synthetic"],
        default="animface",
        help="data of the mapped scenario (animface reads ../shared/data or WORKBENCH_DATA_ROOT)",
    )
    parser.add_argument("--repeats", type=int, default=5, help="timed repeats of the marker fast path (median)")
    parser.add_argument("--solver", default="box", help="solver group of the sweep scenario (box, all, ...)")
    parser.add_argument("--sweep-runs", type=int, default=100, help="runs of the sweep scenario")
    parser.add_argument("--frames", type=int, default=35000, help="frames of the marker scenario")
    parser.add_argument(
        "--baseline-frames",
        type=int,
        default=2000,
        help="frames on which per-frame lsq_linear/bvls is timed, a quarter of them for the slower "
        "default lsq_linear (then extrapolated)",
    )
    parser.add_argument("--mesh-frames", type=int, default=35000, help="frames of the mesh scenario")
    parser.add_argument("--mesh-rows", type=int, default=70, help="mesh rows of the mesh scenario (97 x 97 = 9,409)")
    parser.add_argument("--mesh-cols", type=int, default=60, help="mesh columns of the mesh scenario")
    parser.add_argument(
        "--dtype", choices=["float64", "float32"], default="float64", help="storage of the mesh frames (dataset.dtype)"
    )
    parser.add_argument(
        "--storage",
        choices=["memory", "disk"],
        default="memory",
        help="where the mesh frames live (dataset.storage; disk needs --cache-dir)",
    )
    parser.add_argument(
        "--cache-dir",
        default=None,
        help="paths.cache_dir of the mesh scenario; folder of the cache scenario's entries (a "
        "temporary folder, removed afterwards, when not given)",
    )
    parser.add_argument(
        "--cache-datasets",
        nargs="+",
        choices=sorted(CACHE_DATASETS),
        default=["ict_livelink", "animface", "synthetic"],
        help="datasets of the cache scenario",
    )
    parser.add_argument(
        "--switch-frames",
        type=int,
        nargs="+",
        default=[700, 800, 850, 900, 950, 1000, 1100, 1250, 3000, 3500, 3999, 4001, 4500, 5000],
        help="frame counts of the pca_switch scenario (at most twice the ICT take's 4,030)",
    )
    parser.add_argument(
        "--pca-reference",
        action="store_true",
        help="mesh: compare the study's eigenfaces with a reference fit converged to 1e-14",
    )
    parser.add_argument("--with-exact-pca", action="store_true", help="also time the exact PCA at mesh scale")
    parser.add_argument("--replications", type=int, default=1000, help="AR(1) series per cell of the coverage table")
    parser.add_argument("--seed", type=int, default=0, help="seed of the coverage scenario's series")
    parser.add_argument(
        "--design-replications",
        type=int,
        default=2000,
        help="coverage: series per cell of the table on series like the workbench's (rows sharing frame difficulty)",
    )
    parser.add_argument(
        "--designs-only", action="store_true", help="coverage: only the table on series like the workbench's"
    )
    parser.add_argument(
        "--with-bootstrap",
        action="store_true",
        help="coverage: also the circular block bootstrap the batch means replaced (slow)",
    )
    args = parser.parse_args()
    if args.scenario == "coverage":
        from interval_coverage import bench_coverage

        bench_coverage(args)
        return
    print(blas_report())
    if args.scenario in ("markers", "all"):
        bench_markers(args)
    if args.scenario in ("sweep", "all"):
        bench_sweep(args)
    if args.scenario in ("gaps", "all"):
        bench_gaps(args)
    if args.scenario in ("mapped", "all"):
        bench_mapped(args)
    if args.scenario in ("mesh", "all"):
        bench_mesh(args)
    if args.scenario in ("cache", "all"):
        bench_cache(args)
    if args.scenario in ("pca_switch", "all"):
        bench_pca_switch(args)


if __name__ == "__main__":
    main()
