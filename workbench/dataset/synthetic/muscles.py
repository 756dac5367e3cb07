"""A muscle-driven face: Waters-style linear and sphincter muscles plus a rotating jaw.

Eighteen muscles as in the paper's hand-made basis, 6 for the upper face and 12 for the lower face. A frame's
activations (each in [0, 1]) deform the skin in a fixed sequence, each step acting on the positions the previous
steps left:

1. the jaw rotates the chin, lower lip and jaw line about an axis through the jaw joints;
2. the linear muscles, in :data:`MUSCLE_NAMES` order, pull points inside their zone of influence toward their
   bone attachment (Waters 1987: angular and radial fall-off around the attachment-to-insertion axis);
3. the sphincter (``orbicularis_oris``) draws the lips toward the mouth centre and pushes them forward.

The sequence, the zones evaluated at the current positions, the soft saturation of every response and the true
rotation of the jaw make the face non-linear in its activations, so a performance does not lie in the span of
the single-muscle shapes, as with a real face.

Every step is per point: a point's new position depends only on its own rest position and the activations.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from workbench.dataset.synthetic.face_mesh import skin_point
from workbench.errors import WorkbenchError

UPPER_FACE: tuple[str, ...] = (
    "frontalis_inner_L", "frontalis_inner_R", "frontalis_outer_L", "frontalis_outer_R",
    "corrugator_L", "corrugator_R",
)
LOWER_FACE: tuple[str, ...] = (
    "zygomatic_major_L", "zygomatic_major_R", "levator_labii_L", "levator_labii_R",
    "depressor_anguli_L", "depressor_anguli_R", "risorius_L", "risorius_R",
    "depressor_labii", "mentalis", "orbicularis_oris", "jaw_open",
)
MUSCLE_NAMES: tuple[str, ...] = UPPER_FACE + LOWER_FACE
N_MUSCLES = len(MUSCLE_NAMES)

SATURATION = 1.5
"""Soft saturation of every response: ``sat(s) = tanh(SATURATION * s) / tanh(SATURATION)``, so ``sat(1) = 1``."""


@dataclass(frozen=True)
class LinearMuscle:
    """A Waters linear muscle, in face-plane coordinates (mm) of :func:`face_mesh.skin_point`.

    Attributes
    ----------
    name : str
    attachment_xy : tuple of float
        Face-plane position of the bone attachment.
    attachment_depth : float
        How far below the skin the attachment is, mm.
    insertion_xy : tuple of float
        Face-plane position of the skin insertion (on the skin); the radial weight peaks there.
    cone_half_angle_deg : float
        Half angle of the cone of influence around the attachment-to-insertion axis.
    falloff_ratio : float
        The zone ends at ``falloff_ratio`` times the attachment-to-insertion distance.
    max_displacement : float
        Displacement at the insertion at full contraction, mm (toward the attachment).
    bulge : float
        Forward (+z) push at the insertion at full contraction, mm (muscle belly thickening).
    on_jaw : bool
        The attachment is on the mandible and turns with the jaw.
    """

    name: str
    attachment_xy: tuple[float, float]
    attachment_depth: float
    insertion_xy: tuple[float, float]
    cone_half_angle_deg: float
    falloff_ratio: float
    max_displacement: float
    bulge: float = 0.0
    on_jaw: bool = False


@dataclass(frozen=True)
class SphincterMuscle:
    """A Waters sphincter around the mouth: an elliptical zone contracting toward its centre.

    Attributes
    ----------
    name : str
    centre_xy : tuple of float
        Face-plane centre of the mouth, mm.
    semi_axes : tuple of float
        Horizontal and vertical semi-axes of the zone of influence, mm.
    flat_fraction : float
        Fraction of the elliptical radius with full weight; the weight falls to 0 at the zone edge.
    contraction : tuple of float
        Fraction of the horizontal and vertical offset from the centre removed at full contraction.
    pucker : float
        Forward push of the lips at full contraction, mm.
    """

    name: str
    centre_xy: tuple[float, float]
    semi_axes: tuple[float, float]
    flat_fraction: float
    contraction: tuple[float, float]
    pucker: float


@dataclass(frozen=True)
class JawRotation:
    """The jaw: a rotation about the axis through the two jaw joints (parallel to x).

    Attributes
    ----------
    name : str
    joint_yz : tuple of float
        Height and depth of the joint axis, mm (the joints sit at ``x = +-joint_half_span``).
    joint_half_span : float
        Half the distance between the joints, mm (only for drawing; the axis is the x direction).
    max_angle_deg : float
        Opening at full activation; positive turns the chin down and back.
    mouth_line_y : float
        Above this height nothing turns with the jaw.
    lip_band : float
        Height over which the weight rises from 0 at the mouth line to 1 on the lower lip, mm.
    mouth_half_width : float
        Beyond this ``|x|`` the band widens (the cheeks stretch over the jaw line).
    band_widening : float
        Extra band height per mm of ``|x|`` beyond ``mouth_half_width``.
    """

    name: str
    joint_yz: tuple[float, float]
    joint_half_span: float
    max_angle_deg: float
    mouth_line_y: float
    lip_band: float
    mouth_half_width: float
    band_widening: float


# Geometry of the left-side and midline muscles; right-side muscles mirror the left ones in x.
LINEAR_MUSCLES_LEFT_AND_MIDLINE: tuple[LinearMuscle, ...] = (
    #            name                  attachment      depth  insertion      cone  falloff max mm bulge  on jaw
    LinearMuscle("frontalis_inner_L",  (17.0, 92.0),   6.0,   (16.0, 26.0),  22.0, 1.25,   9.0,   0.0),
    LinearMuscle("frontalis_outer_L",  (44.0, 88.0),   6.0,   (45.0, 24.0),  20.0, 1.25,   8.0,   0.0),
    LinearMuscle("corrugator_L",       (8.0, 16.0),    8.0,   (30.0, 29.0),  35.0, 1.6,    5.5,   0.0),
    LinearMuscle("zygomatic_major_L",  (60.0, -5.0),   8.0,   (24.0, -55.0), 20.0, 1.3,    13.0,  3.0),
    LinearMuscle("levator_labii_L",    (20.0, -8.0),   8.0,   (12.0, -49.0), 22.0, 1.25,   7.0,   1.0),
    LinearMuscle("depressor_anguli_L", (34.0, -88.0),  6.0,   (24.0, -57.0), 22.0, 1.3,    9.0,   0.0,  True),
    LinearMuscle("risorius_L",         (52.0, -60.0),  6.0,   (24.0, -56.0), 18.0, 1.3,    9.0,   0.0),
    LinearMuscle("depressor_labii",    (0.0, -92.0),   8.0,   (0.0, -62.0),  35.0, 1.25,   6.0,   0.0,  True),
    LinearMuscle("mentalis",           (0.0, -72.0),   10.0,  (0.0, -92.0),  40.0, 1.3,    5.0,   3.0,  True),
)
ORBICULARIS_ORIS = SphincterMuscle("orbicularis_oris", centre_xy=(0.0, -55.5), semi_axes=(36.0, 24.0),
                                   flat_fraction=0.55, contraction=(0.4, 0.25), pucker=8.0)
JAW = JawRotation("jaw_open", joint_yz=(-20.0, 12.0), joint_half_span=52.0, max_angle_deg=18.0,
                  mouth_line_y=-55.5, lip_band=3.5, mouth_half_width=24.0, band_widening=0.3)


@dataclass(frozen=True)
class _ResolvedLinearMuscle:
    """A linear muscle placed in 3D (head frame, mm)."""

    spec: LinearMuscle
    column: int
    attachment: np.ndarray  # (3,)
    insertion: np.ndarray  # (3,)

    @property
    def rest_length(self) -> float:
        return float(np.linalg.norm(self.insertion - self.attachment))


def _mirror(muscle: LinearMuscle) -> LinearMuscle:
    return replace(muscle, name=muscle.name[:-2] + "_R",
                   attachment_xy=(-muscle.attachment_xy[0], muscle.attachment_xy[1]),
                   insertion_xy=(-muscle.insertion_xy[0], muscle.insertion_xy[1]))


def _resolve(muscle: LinearMuscle) -> _ResolvedLinearMuscle:
    attachment_skin, normal = skin_point(*muscle.attachment_xy)
    insertion, _ = skin_point(*muscle.insertion_xy)
    attachment = attachment_skin[0] - muscle.attachment_depth * normal[0]
    return _ResolvedLinearMuscle(muscle, MUSCLE_NAMES.index(muscle.name), attachment, insertion[0])


def _linear_muscles_in_order() -> tuple[_ResolvedLinearMuscle, ...]:
    table = {muscle.name: muscle for muscle in LINEAR_MUSCLES_LEFT_AND_MIDLINE}
    table.update({_mirror(m).name: _mirror(m) for m in LINEAR_MUSCLES_LEFT_AND_MIDLINE if m.name.endswith("_L")})
    return tuple(_resolve(table[name]) for name in MUSCLE_NAMES if name in table)


LINEAR_MUSCLES: tuple[_ResolvedLinearMuscle, ...] = _linear_muscles_in_order()
_SPHINCTER_CENTRE = skin_point(*ORBICULARIS_ORIS.centre_xy)[0][0]
_SPHINCTER_COLUMN = MUSCLE_NAMES.index(ORBICULARIS_ORIS.name)
_JAW_COLUMN = MUSCLE_NAMES.index(JAW.name)
_JAW_PIVOT = np.array([0.0, JAW.joint_yz[0], JAW.joint_yz[1]])

DEFAULT_CHUNK_POINTS = 1 << 18
"""Frames are processed in chunks of at most this many frame-points (a (chunk, P, 3) float64 array is 6 MB)."""

_ZONE_MARGIN = 1.0
"""mm of extra slack when choosing which points a step looks at (guards the choice against rounding)."""


def deform(points: np.ndarray, activations: np.ndarray, *,
           chunk_points: int = DEFAULT_CHUNK_POINTS) -> np.ndarray:
    """Positions of skin points under muscle activations.

    Parameters
    ----------
    points : ndarray of shape (n_points, 3)
        Rest positions in the head frame, mm.
    activations : ndarray of shape (n_frames, 18)
        Activation of each muscle of :data:`MUSCLE_NAMES` in [0, 1].
    chunk_points : int, optional
        Bound on frames x points evaluated at once (memory), at least 1.

    Returns
    -------
    ndarray of shape (n_frames, n_points, 3)
        Deformed positions in the head frame, mm. Zero activations give the rest points exactly.
    """
    points = _checked_points(points)
    activations = _checked_activations(activations)
    if isinstance(chunk_points, bool) or not isinstance(chunk_points, (int, np.integer)) or chunk_points < 1:
        raise WorkbenchError(f"chunk_points must be a positive integer, got {chunk_points!r}")
    n_frames, n_points = activations.shape[0], points.shape[0]
    positions = np.empty((n_frames, n_points, 3))
    frames_per_chunk = max(1, int(chunk_points) // max(n_points, 1))
    reachable = _reachable_points(points)
    for start in range(0, n_frames, frames_per_chunk):
        stop = min(start + frames_per_chunk, n_frames)
        _deform_chunk(points, activations[start:stop], positions[start:stop], reachable)
    return positions


def saturate(drive: np.ndarray) -> np.ndarray:
    """Soft saturation ``tanh(k s) / tanh(k)``: 0 at 0, 1 at 1, steeper than linear near 0."""
    return np.tanh(SATURATION * drive) / np.tanh(SATURATION)


# --- the steps ----------------------------------------------------------------------------------------------


def _deform_chunk(points: np.ndarray, activations: np.ndarray, positions: np.ndarray,
                  reachable: dict[str, np.ndarray]) -> None:
    """Fill ``positions`` (n_frames, n_points, 3) with the deformed ``points`` for a chunk of frames.

    Each step only looks at the points in ``reachable[step name]`` (see :func:`_reachable_points`).
    """
    positions[...] = points
    jaw_angle = np.deg2rad(JAW.max_angle_deg) * saturate(activations[:, _JAW_COLUMN])
    if jaw_angle.max() > 0.0:
        _apply_to(positions, reachable[JAW.name], _turn_with_jaw, jaw_angle)
    for muscle in LINEAR_MUSCLES:
        activation = activations[:, muscle.column]
        if activation.max() > 0.0:
            _apply_to(positions, reachable[muscle.spec.name], _pull_linear_muscle, muscle, activation, jaw_angle)
    activation = activations[:, _SPHINCTER_COLUMN]
    if activation.max() > 0.0:
        _apply_to(positions, reachable[ORBICULARIS_ORIS.name], _contract_sphincter, activation)


def _apply_to(positions: np.ndarray, columns: np.ndarray, step, *arguments) -> None:
    """Run an in-place ``step`` on the points ``columns`` of ``positions`` (n_frames, n_points, 3)."""
    if columns.size == 0:
        return
    moving = positions[:, columns]
    step(moving, *arguments)
    positions[:, columns] = moving


def _reachable_points(points: np.ndarray) -> dict[str, np.ndarray]:
    """For each step, the points that could come inside its zone in some frame; a superset, never missing one.

    Decided from the rest positions alone: a point can only have moved, before a step, by the sum of the
    largest displacements of the earlier steps that could reach it. Skipping the other points saves time and
    changes no result (outside its zone a step leaves a point untouched).

    Parameters
    ----------
    points : ndarray of shape (n_points, 3)

    Returns
    -------
    dict of str to ndarray of int
        Point indices per step name (``jaw_open``, each linear muscle, ``orbicularis_oris``).
    """
    jaw_max = np.deg2rad(JAW.max_angle_deg)
    jaw_radius = np.hypot(*(points[:, 1:] - _JAW_PIVOT[1:]).T)
    on_jaw = points[:, 1] < JAW.mouth_line_y
    reachable = {JAW.name: np.flatnonzero(on_jaw)}
    moved = np.where(on_jaw, jaw_max * jaw_radius, 0.0)  # a chord is shorter than its arc
    for muscle in LINEAR_MUSCLES:
        spec = muscle.spec
        slack = moved + _ZONE_MARGIN
        cone = np.deg2rad(spec.cone_half_angle_deg)
        if spec.on_jaw:
            # The attachment travels with the jaw and the axis turns by up to the jaw angle.
            slack = slack + jaw_max * float(np.hypot(*(muscle.attachment[1:] - _JAW_PIVOT[1:])))
            cone = cone + jaw_max
        offset = points - muscle.attachment
        distance = np.linalg.norm(offset, axis=1)
        axis = (muscle.insertion - muscle.attachment) / muscle.rest_length
        angle = np.arccos(np.clip(offset @ axis / np.maximum(distance, 1e-12), -1.0, 1.0))
        outside_angle = np.clip(angle - cone, 0.0, 0.5 * np.pi)
        distance_to_cone = distance * np.sin(outside_angle)
        near = (distance_to_cone < slack) & (distance < spec.falloff_ratio * muscle.rest_length + slack)
        reachable[spec.name] = np.flatnonzero(near)
        moved[near] += spec.max_displacement + spec.bulge
    slack = moved + _ZONE_MARGIN
    near = ((np.abs(points[:, 0] - _SPHINCTER_CENTRE[0]) < ORBICULARIS_ORIS.semi_axes[0] + slack)
            & (np.abs(points[:, 1] - _SPHINCTER_CENTRE[1]) < ORBICULARIS_ORIS.semi_axes[1] + slack))
    reachable[ORBICULARIS_ORIS.name] = np.flatnonzero(near)
    return reachable


# Each step below moves ``positions`` (n_frames, n_points, 3) in place and evaluates its weights only on the
# frame-points inside its zone with a non-zero activation; every other point is left bit-for-bit unchanged.


def _jaw_weight(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """1 on the chin and lower lip, 0 above the mouth line; the band widens toward the jaw angles."""
    beyond_mouth = np.maximum(np.abs(x) - JAW.mouth_half_width, 0.0)
    band = JAW.lip_band + JAW.band_widening * beyond_mouth
    t = np.clip((JAW.mouth_line_y - y) / band, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _rotation_about_x_displacement(offsets: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """``R(angle) r - r`` for rotations about +x (Rodrigues), exactly zero where the angle is zero.

    offsets : (..., 3) vectors from the pivot; angle : broadcastable to offsets[..., 0].
    """
    sin_a, one_minus_cos = np.sin(angle), 1.0 - np.cos(angle)
    y, z = offsets[..., 1], offsets[..., 2]
    return np.stack([np.zeros_like(y * sin_a), -sin_a * z - one_minus_cos * y, sin_a * y - one_minus_cos * z],
                    axis=-1)


def _turn_with_jaw(positions: np.ndarray, jaw_angle: np.ndarray) -> None:
    """Each point below the mouth line turns about the joint axis by ``weight * jaw_angle``.

    A rotation, not a linear blend of positions, so the lower face swings on an arc.
    """
    inside = (positions[..., 1] < JAW.mouth_line_y) & (jaw_angle[:, None] > 0.0)
    frame_index = np.nonzero(inside)[0]
    moving = positions[inside]
    angle = _jaw_weight(moving[:, 0], moving[:, 1]) * jaw_angle[frame_index]
    positions[inside] = moving + _rotation_about_x_displacement(moving - _JAW_PIVOT, angle)


def _on_jaw(point: np.ndarray, jaw_angle: np.ndarray) -> np.ndarray:
    """Where a mandible point is for each frame's jaw angle: shape (n_frames, 3)."""
    offset = np.broadcast_to(point - _JAW_PIVOT, (jaw_angle.shape[0], 3))
    return point + _rotation_about_x_displacement(offset, jaw_angle)


def _pull_linear_muscle(positions: np.ndarray, muscle: _ResolvedLinearMuscle, activation: np.ndarray,
                        jaw_angle: np.ndarray) -> None:
    """Waters linear muscle: pull toward the attachment with angular and radial fall-off.

    positions : (n_frames, n_points, 3), moved in place; activation, jaw_angle : (n_frames,).
    """
    spec = muscle.spec
    n_frames = positions.shape[0]
    if spec.on_jaw:
        attachment, insertion = _on_jaw(muscle.attachment, jaw_angle), _on_jaw(muscle.insertion, jaw_angle)
    else:
        attachment = np.broadcast_to(muscle.attachment, (n_frames, 3))
        insertion = np.broadcast_to(muscle.insertion, (n_frames, 3))
    rest_length = muscle.rest_length
    zone_end = spec.falloff_ratio * rest_length
    axis = (insertion - attachment) / rest_length

    # Written out per coordinate (no BLAS), so every point gets the same arithmetic whatever the array size.
    offset = [positions[..., k] - attachment[:, None, k] for k in range(3)]
    squared_distance = offset[0] * offset[0] + offset[1] * offset[1] + offset[2] * offset[2]
    along_axis = offset[0] * axis[:, None, 0] + offset[1] * axis[:, None, 1] + offset[2] * axis[:, None, 2]
    cos_cone = np.cos(np.deg2rad(spec.cone_half_angle_deg))
    inside = ((along_axis > 0.0) & (along_axis * along_axis > cos_cone * cos_cone * squared_distance)
              & (squared_distance < zone_end * zone_end) & (activation[:, None] > 0.0))
    frame_index = np.nonzero(inside)[0]

    distance = np.sqrt(squared_distance[inside])
    cos_angle = np.minimum(along_axis[inside] / distance, 1.0)
    relative_angle = np.minimum(np.arccos(cos_angle) / np.deg2rad(spec.cone_half_angle_deg), 1.0)
    angular = np.cos(0.5 * np.pi * relative_angle) ** 2
    rising = np.sin(0.5 * np.pi * np.minimum(distance / rest_length, 1.0)) ** 2
    falling = np.cos(0.5 * np.pi * np.clip((distance - rest_length) / (zone_end - rest_length), 0.0, 1.0)) ** 2
    radial = np.where(distance < rest_length, rising, falling)

    response = saturate(activation[frame_index] * angular * radial)
    # Never pull a point past half its distance to the attachment.
    pull_over_distance = np.minimum(spec.max_displacement * response, 0.5 * distance) / distance
    moving = positions[inside]
    moving -= pull_over_distance[:, None] * (moving - attachment[frame_index])
    if spec.bulge:
        moving[:, 2] += spec.bulge * response
    positions[inside] = moving


def _contract_sphincter(positions: np.ndarray, activation: np.ndarray) -> None:
    """Orbicularis oris: the lips contract toward the mouth centre and push forward (pucker).

    positions : (n_frames, n_points, 3), moved in place; activation : (n_frames,).
    """
    sphincter = ORBICULARIS_ORIS
    dx = positions[..., 0] - _SPHINCTER_CENTRE[0]
    dy = positions[..., 1] - _SPHINCTER_CENTRE[1]
    squared_radius = (dx / sphincter.semi_axes[0]) ** 2 + (dy / sphincter.semi_axes[1]) ** 2
    inside = (squared_radius < 1.0) & (activation[:, None] > 0.0)
    frame_index = np.nonzero(inside)[0]
    radius = np.sqrt(squared_radius[inside])
    fall = np.clip((radius - sphincter.flat_fraction) / (1.0 - sphincter.flat_fraction), 0.0, 1.0)
    response = saturate(activation[frame_index] * np.cos(0.5 * np.pi * fall) ** 2)
    moving = positions[inside]
    moving[:, 0] -= sphincter.contraction[0] * dx[inside] * response
    moving[:, 1] -= sphincter.contraction[1] * dy[inside] * response
    moving[:, 2] += sphincter.pucker * response * (1.0 - 0.6 * squared_radius[inside])
    positions[inside] = moving


# --- validation ---------------------------------------------------------------------------------------------


def _checked_points(points: np.ndarray) -> np.ndarray:
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3:
        raise WorkbenchError(f"points must have shape (n_points, 3), got {points.shape}")
    if not np.all(np.isfinite(points)):
        raise WorkbenchError("points must be finite")
    return points


def _checked_activations(activations: np.ndarray) -> np.ndarray:
    activations = np.asarray(activations, dtype=float)
    if activations.ndim != 2 or activations.shape[1] != N_MUSCLES:
        raise WorkbenchError(f"activations must have shape (n_frames, {N_MUSCLES}), got {activations.shape}")
    if not np.all(np.isfinite(activations)) or activations.min(initial=0.0) < 0 or activations.max(initial=0.0) > 1:
        raise WorkbenchError("activations must be finite and within [0, 1]")
    return activations
