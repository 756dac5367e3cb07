"""The synthetic take: a muscle-driven face performing, seen through a marker set in the lab.

Face markers sit on mesh vertices and follow the muscles; head markers sit on a rigid headband. The whole head
then moves rigidly (small smooth rotations about the head centre and translations) and every marker coordinate
gets i.i.d. Gaussian noise, as a Vicon capture of 66 face + 7 head markers at 120 Hz would.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.dataset.synthetic.face_mesh import FaceMesh, eye_opening_mask, face_mesh_of, head_shell_point
from workbench.dataset.synthetic.muscles import MUSCLE_NAMES, N_MUSCLES, deform
from workbench.dataset.synthetic.performance import make_activations


@dataclass(frozen=True)
class MarkerLayout:
    """Where markers may go and how they are spread (face-plane coordinates and mm)."""

    face_x_max: float = 60.0
    face_y_min: float = -96.0
    face_y_max: float = 80.0
    face_z_min: float = 35.0  # leaves out the sides of the head and the underside of the chin
    mouth_priority: float = 1.6  # extra marker density around the mouth
    brow_priority: float = 0.3  # extra marker density on the brows
    headband_azimuth_deg: float = 75.0  # outermost head marker (temples)
    headband_top_y: float = 102.0  # head marker on the midline, above the hairline
    headband_temple_y: float = 50.0  # outermost head markers
    headband_standoff: float = 12.0  # marker ball centre above the skin


@dataclass(frozen=True)
class HeadMotionStyle:
    """Rigid head motion: each component is a sum of sinusoids in these frequency bands (Hz) and weights."""

    bands: tuple[tuple[float, float], ...] = ((0.03, 0.1), (0.1, 0.3), (0.3, 0.6))
    weights: tuple[float, ...] = (0.5, 0.3, 0.2)  # sum to 1: a component never exceeds its amplitude


LAYOUT = MarkerLayout()
MARKER_LANDMARKS: tuple[str, ...] = (
    "nose_tip",
    "upper_lip",
    "lower_lip",
    "mouth_corner_L",
    "mouth_corner_R",
    "chin",
    "brow_inner_L",
    "brow_inner_R",
    "brow_outer_L",
    "brow_outer_R",
    "nose_root",
    "nostril_L",
    "nostril_R",
    "cheek_L",
    "cheek_R",
    "jaw_L",
    "jaw_R",
    "forehead",
)
"""Landmarks that always carry a face marker (the first ``n_face_markers`` of them if fewer are asked for)."""
HEAD_MOTION_STYLE = HeadMotionStyle()
MAX_HEAD_MARKERS = 32


@dataclass(frozen=True)
class HeadMotion:
    """Rigid motion of the head for every frame: ``lab = rotation @ head + translation``.

    Attributes
    ----------
    rotations : ndarray of shape (n_frames, 3, 3)
        Rotation about the head centre (the head-frame origin).
    translations : ndarray of shape (n_frames, 3)
        Translation in mm.
    """

    rotations: np.ndarray
    translations: np.ndarray

    def to_lab(self, positions: np.ndarray) -> np.ndarray:
        """Move head-frame positions of shape (n_frames, n_points, 3) into the lab; same shape out."""
        return positions @ np.swapaxes(self.rotations, 1, 2) + self.translations[:, None, :]


@dataclass(frozen=True)
class SyntheticTake:
    """A synthetic motion-capture take with its ground truth.

    Attributes
    ----------
    mesh : FaceMesh
        The actor's face at rest (head frame, mm).
    muscle_names : tuple of str
        The 18 muscles, columns of ``activations``.
    activations : ndarray of shape (n_frames, 18)
        True muscle activations in [0, 1].
    frame_rate : float
        Frames per second.
    face_marker_vertices : ndarray of shape (n_face_markers,)
        Mesh vertex under each face marker.
    face_marker_rest : ndarray of shape (n_face_markers, 3)
        Face markers at rest, head frame.
    head_marker_rest : ndarray of shape (n_head_markers, 3)
        Rigid head markers, head frame.
    marker_labels : tuple of str
        ``F00 ...`` for face markers, then ``H0 ...`` for head markers.
    face_marker_index, head_marker_index : ndarray of shape (n_face_markers,) and (n_head_markers,)
        Integer positions of the face and head markers along the marker axis of ``markers``.
    markers : ndarray of shape (n_frames, n_face_markers + n_head_markers, 3)
        Marker positions in the lab frame, mm, with head motion and noise.
    head_motion : HeadMotion
        The true rigid head motion per frame.
    provenance : dict
        Kind, seed and every parameter of the generation.
    """

    mesh: FaceMesh
    muscle_names: tuple[str, ...]
    activations: np.ndarray
    frame_rate: float
    face_marker_vertices: np.ndarray
    face_marker_rest: np.ndarray
    head_marker_rest: np.ndarray
    marker_labels: tuple[str, ...]
    face_marker_index: np.ndarray
    head_marker_index: np.ndarray
    markers: np.ndarray
    head_motion: HeadMotion
    provenance: dict

    @property
    def n_frames(self) -> int:
        return self.activations.shape[0]

    def hand_shapes_mesh(self) -> np.ndarray:
        """The hand-made basis on the mesh: each muscle fully contracted, the others relaxed.

        Returns
        -------
        ndarray of shape (18, n_vertices, 3)
            Displacements from the rest mesh, mm.
        """
        return deform(self.mesh.vertices, np.eye(N_MUSCLES)) - self.mesh.vertices

    def hand_shapes_markers(self) -> np.ndarray:
        """The hand-made basis at the face markers (head frame).

        Returns
        -------
        ndarray of shape (18, n_face_markers, 3)
            Displacements from the rest markers, mm; equal to ``hand_shapes_mesh()[:, face_marker_vertices]``.
        """
        return deform(self.face_marker_rest, np.eye(N_MUSCLES)) - self.face_marker_rest

    def mesh_sequence(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """Dense ground-truth positions of the mesh for frames ``start:stop``, computed on demand.

        Parameters
        ----------
        start, stop : int
            Frame range, ``0 <= start < stop <= n_frames``; ``stop=None`` means the last frame.

        Returns
        -------
        ndarray of shape (stop - start, n_vertices, 3)
            Head-frame positions (no head motion, no noise), mm.
        """
        stop = self.n_frames if stop is None else stop
        for name, value in (("start", start), ("stop", stop)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise WorkbenchError(f"{name} must be an integer, got {value!r}")
        if not 0 <= start < stop <= self.n_frames:
            raise WorkbenchError(
                f"frame range must satisfy 0 <= start < stop <= {self.n_frames}, got start={start}, stop={stop}"
            )
        return deform(self.mesh.vertices, self.activations[start:stop])


def make_synthetic_take(
    *,
    n_frames: int = 35000,
    frame_rate: float = 120.0,
    n_face_markers: int = 66,
    n_head_markers: int = 7,
    head_rotation_deg: float = 3.0,
    head_translation_mm: float = 5.0,
    marker_noise_mm: float = 0.05,
    seed: int = 0,
    mesh_rows: int = 70,
    mesh_cols: int = 60,
) -> SyntheticTake:
    """Generate the synthetic actor's take, deterministically from ``seed``.

    Parameters
    ----------
    n_frames : int
        Frames in the take, at least 1 (the paper: 35,000).
    frame_rate : float
        Frames per second, positive (the paper: 120).
    n_face_markers : int
        Face markers, between 1 and the number of usable face vertices of the mesh (the paper: 66).
    n_head_markers : int
        Rigid head markers, between 3 and 32 (the paper: 7).
    head_rotation_deg : float
        Amplitude of each rotation-vector component of the head motion, degrees, in [0, 45].
    head_translation_mm : float
        Amplitude of each translation component of the head motion, mm, >= 0.
    marker_noise_mm : float
        Standard deviation of the Gaussian noise on every marker coordinate, mm, >= 0.
    seed : int
        Seed of the one random generator everything draws from, >= 0.
    mesh_rows, mesh_cols : int
        Grid of the face mesh (see :func:`make_face_mesh`).

    Returns
    -------
    SyntheticTake
    """
    _check_int("n_frames", n_frames, 1)
    _check_float("frame_rate", frame_rate, lower=0.0, lower_inclusive=False)
    _check_int("n_head_markers", n_head_markers, 3, MAX_HEAD_MARKERS)
    _check_float("head_rotation_deg", head_rotation_deg, lower=0.0, upper=45.0)
    _check_float("head_translation_mm", head_translation_mm, lower=0.0)
    _check_float("marker_noise_mm", marker_noise_mm, lower=0.0)
    _check_int("seed", seed, 0)
    _check_int("mesh_rows", mesh_rows, 20)
    _check_int("mesh_cols", mesh_cols, 20)
    return synthetic_take_of(
        n_frames=n_frames,
        frame_rate=frame_rate,
        n_face_markers=n_face_markers,
        n_head_markers=n_head_markers,
        head_rotation_deg=head_rotation_deg,
        head_translation_mm=head_translation_mm,
        marker_noise_mm=marker_noise_mm,
        seed=seed,
        mesh_rows=mesh_rows,
        mesh_cols=mesh_cols,
    )


def synthetic_take_of(
    *,
    n_frames: int,
    frame_rate: float,
    n_face_markers: int,
    n_head_markers: int,
    head_rotation_deg: float,
    head_translation_mm: float,
    marker_noise_mm: float,
    seed: int,
    mesh_rows: int,
    mesh_cols: int,
) -> SyntheticTake:
    """:func:`make_synthetic_take` of parameters already checked (the ``dataset`` settings of the synthetic actor,
    as its builder takes them); only the face markers are checked here, against the usable vertices of the mesh
    (which the settings cannot know)."""
    mesh = face_mesh_of(int(mesh_rows), int(mesh_cols))
    n_usable = int(face_marker_candidates(mesh).sum())
    _check_int("n_face_markers", n_face_markers, 1, n_usable, note=" (usable face vertices of this mesh)")

    performance_rng, head_rng, noise_rng = np.random.default_rng(int(seed)).spawn(3)
    activations = make_activations(int(n_frames), float(frame_rate), performance_rng)
    face_marker_vertices = place_face_markers(mesh, int(n_face_markers))
    face_marker_rest = mesh.vertices[face_marker_vertices]
    head_marker_rest = head_marker_layout(int(n_head_markers))
    head_motion = make_head_motion(
        int(n_frames), float(frame_rate), float(head_rotation_deg), float(head_translation_mm), head_rng
    )

    face_positions = deform(face_marker_rest, activations)
    head_positions = np.broadcast_to(head_marker_rest, (int(n_frames),) + head_marker_rest.shape)
    markers = head_motion.to_lab(np.concatenate([face_positions, head_positions], axis=1))
    if marker_noise_mm > 0:
        markers += noise_rng.normal(0.0, float(marker_noise_mm), markers.shape)

    n_face = int(n_face_markers)
    face_marker_index = np.arange(n_face)
    head_marker_index = np.arange(n_face, n_face + int(n_head_markers))
    labels = tuple(f"F{i:02d}" for i in range(n_face)) + tuple(f"H{i}" for i in range(int(n_head_markers)))
    provenance = _provenance(
        seed=int(seed),
        n_frames=int(n_frames),
        frame_rate=float(frame_rate),
        n_face_markers=n_face,
        n_head_markers=int(n_head_markers),
        head_rotation_deg=float(head_rotation_deg),
        head_translation_mm=float(head_translation_mm),
        marker_noise_mm=float(marker_noise_mm),
        mesh_rows=int(mesh_rows),
        mesh_cols=int(mesh_cols),
        n_vertices=mesh.n_vertices,
    )
    for array in (
        activations,
        face_marker_vertices,
        face_marker_rest,
        head_marker_rest,
        markers,
        head_motion.rotations,
        head_motion.translations,
        face_marker_index,
        head_marker_index,
    ):
        array.setflags(write=False)
    return SyntheticTake(
        mesh=mesh,
        muscle_names=MUSCLE_NAMES,
        activations=activations,
        frame_rate=float(frame_rate),
        face_marker_vertices=face_marker_vertices,
        face_marker_rest=face_marker_rest,
        head_marker_rest=head_marker_rest,
        marker_labels=labels,
        face_marker_index=face_marker_index,
        head_marker_index=head_marker_index,
        markers=markers,
        head_motion=head_motion,
        provenance=provenance,
    )


def _provenance(**settings) -> dict:
    """The take's provenance: what generated it, its ``settings`` (seed, sizes and amplitudes, in the order given)
    and the muscle model."""
    return {
        "kind": "synthetic",
        "generator": "workbench.dataset.synthetic.make_synthetic_take",
        **settings,
        "muscle_model": "Waters linear and sphincter muscles and a rotating jaw, applied in sequence",
        "units": "mm",
        "note": "generated by the workbench; not real capture",
    }


def face_marker_candidates(mesh: FaceMesh) -> np.ndarray:
    """Vertices a face marker may sit on: the front of the face, outside the eye openings.

    Returns
    -------
    ndarray of shape (n_vertices,) of bool
    """
    x, y = mesh.face_plane[:, 0], mesh.face_plane[:, 1]
    return (
        (np.abs(x) <= LAYOUT.face_x_max)
        & (y >= LAYOUT.face_y_min)
        & (y <= LAYOUT.face_y_max)
        & (mesh.vertices[:, 2] >= LAYOUT.face_z_min)
        & ~eye_opening_mask(mesh.face_plane)
    )


def place_face_markers(mesh: FaceMesh, n_markers: int) -> np.ndarray:
    """Lay out face markers: named landmarks first, then farthest-point sampling over the rest of the face.

    Real face marker sets put markers on the lips, mouth corners, brows, nose and chin, then fill the face
    evenly; here the landmarks of :data:`MARKER_LANDMARKS` come first (in that order, the nose tip first) and
    farthest-point sampling adds the others. Distances are scaled up around the mouth and the brows, so those
    regions get more of the filling markers.

    Returns
    -------
    ndarray of shape (n_markers,) of int64
        Vertex indices.
    """
    candidates = np.flatnonzero(face_marker_candidates(mesh))
    positions = mesh.vertices[candidates]
    x, y = mesh.face_plane[candidates, 0], mesh.face_plane[candidates, 1]
    priority = (
        1.0
        + LAYOUT.mouth_priority * np.exp(-((x / 30.0) ** 2) - ((y + 56.0) / 18.0) ** 2)
        + LAYOUT.brow_priority * np.exp(-(((np.abs(x) - 30.0) / 20.0) ** 2) - ((y - 27.0) / 8.0) ** 2)
    )
    position_in_candidates = {int(vertex): i for i, vertex in enumerate(candidates)}
    chosen = [
        position_in_candidates[mesh.landmarks[name]]
        for name in MARKER_LANDMARKS
        if mesh.landmarks[name] in position_in_candidates
    ][:n_markers]
    nearest = np.min(np.linalg.norm(positions[:, None, :] - positions[None, chosen, :], axis=2), axis=1)
    while len(chosen) < n_markers:
        chosen.append(int(np.argmax(nearest * priority)))
        nearest = np.minimum(nearest, np.linalg.norm(positions - positions[chosen[-1]], axis=1))
    return candidates[np.array(chosen, dtype=np.int64)]


def head_marker_layout(n_markers: int) -> np.ndarray:
    """Rigid head markers on a headband: over the forehead above the hairline, dipping to the temples.

    Returns
    -------
    ndarray of shape (n_markers, 3)
        Head-frame positions, mm.
    """
    side = np.linspace(-1.0, 1.0, n_markers)
    azimuth = np.deg2rad(LAYOUT.headband_azimuth_deg) * side
    y = LAYOUT.headband_top_y - (LAYOUT.headband_top_y - LAYOUT.headband_temple_y) * side**2
    return head_shell_point(azimuth, y, LAYOUT.headband_standoff)


def make_head_motion(
    n_frames: int, frame_rate: float, rotation_deg: float, translation_mm: float, rng: np.random.Generator
) -> HeadMotion:
    """Smooth rigid head motion: each rotation-vector and translation component is a sum of slow sinusoids.

    Each component stays within ``+-rotation_deg`` (rotation vector) or ``+-translation_mm``; zero amplitudes
    give identity rotations and zero translations exactly.
    """
    times = np.arange(n_frames) / frame_rate
    rotation_vectors = np.deg2rad(rotation_deg) * _slow_wander(times, 3, rng)
    translations = translation_mm * _slow_wander(times, 3, rng)
    return HeadMotion(rotations=_rotation_matrices(rotation_vectors), translations=translations)


def _slow_wander(times: np.ndarray, n_components: int, rng: np.random.Generator) -> np.ndarray:
    """(n_frames, n_components) sums of sinusoids with weights summing to 1 (so within [-1, 1])."""
    wander = np.zeros((times.size, n_components))
    for (low, high), weight in zip(HEAD_MOTION_STYLE.bands, HEAD_MOTION_STYLE.weights):
        frequency = rng.uniform(low, high, n_components)
        phase = rng.uniform(0.0, 2.0 * np.pi, n_components)
        wander += weight * np.sin(2.0 * np.pi * frequency * times[:, None] + phase)
    return wander


def _rotation_matrices(rotation_vectors: np.ndarray) -> np.ndarray:
    """Rodrigues' formula for rotation vectors of shape (n, 3); returns (n, 3, 3)."""
    angle = np.linalg.norm(rotation_vectors, axis=1)
    safe_angle = np.where(angle > 0, angle, 1.0)
    kx, ky, kz = (rotation_vectors / safe_angle[:, None]).T
    zero = np.zeros_like(kx)
    cross = np.stack(
        [np.stack([zero, -kz, ky], -1), np.stack([kz, zero, -kx], -1), np.stack([-ky, kx, zero], -1)], axis=1
    )
    sin_a, one_minus_cos = np.sin(angle)[:, None, None], (1.0 - np.cos(angle))[:, None, None]
    return np.eye(3) + sin_a * cross + one_minus_cos * (cross @ cross)


def _check_int(name: str, value, lower: int, upper: int | None = None, note: str = "") -> None:
    if upper is not None:
        rule = f"an integer between {lower} and {upper}{note}"
    else:
        rule = {0: "a non-negative integer", 1: "a positive integer"}.get(lower, f"an integer >= {lower}")
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, np.integer))
        or value < lower
        or (upper is not None and value > upper)
    ):
        raise WorkbenchError(f"{name} must be {rule}, got {value!r}")


def _check_float(name: str, value, *, lower: float, upper: float | None = None, lower_inclusive: bool = True) -> None:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float, np.integer, np.floating))
        or not np.isfinite(value)
    ):
        raise WorkbenchError(f"{name} must be a finite number, got {value!r}")
    if value < lower or (value == lower and not lower_inclusive) or (upper is not None and value > upper):
        bound = (">= " if lower_inclusive else "> ") + f"{lower:g}"
        rule = bound + (f" and <= {upper:g}" if upper is not None else "")
        raise WorkbenchError(f"{name} must be {rule}, got {value}")
