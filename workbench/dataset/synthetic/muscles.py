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

Every step is per point: a point's new position depends only on its own rest position and the activations. The
model runs compiled (numba), a point of a frame at a time, frames in parallel threads; what is the same for every
point of a frame (the jaw angle, the muscles on the mandible turned with it) is computed beforehand, vectorised.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.dataset.synthetic.face_mesh import skin_point
from workbench.numerics.compiled import njit, prange

UPPER_FACE: tuple[str, ...] = (
    "frontalis_inner_L",
    "frontalis_inner_R",
    "frontalis_outer_L",
    "frontalis_outer_R",
    "corrugator_L",
    "corrugator_R",
)
LOWER_FACE: tuple[str, ...] = (
    "zygomatic_major_L",
    "zygomatic_major_R",
    "levator_labii_L",
    "levator_labii_R",
    "depressor_anguli_L",
    "depressor_anguli_R",
    "risorius_L",
    "risorius_R",
    "depressor_labii",
    "mentalis",
    "orbicularis_oris",
    "jaw_open",
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
    LinearMuscle("frontalis_inner_L", (17.0, 92.0), 6.0, (16.0, 26.0), 22.0, 1.25, 9.0, 0.0),
    LinearMuscle("frontalis_outer_L", (44.0, 88.0), 6.0, (45.0, 24.0), 20.0, 1.25, 8.0, 0.0),
    LinearMuscle("corrugator_L", (8.0, 16.0), 8.0, (30.0, 29.0), 35.0, 1.6, 5.5, 0.0),
    LinearMuscle("zygomatic_major_L", (60.0, -5.0), 8.0, (24.0, -55.0), 20.0, 1.3, 13.0, 3.0),
    LinearMuscle("levator_labii_L", (20.0, -8.0), 8.0, (12.0, -49.0), 22.0, 1.25, 7.0, 1.0),
    LinearMuscle("depressor_anguli_L", (34.0, -88.0), 6.0, (24.0, -57.0), 22.0, 1.3, 9.0, 0.0, True),
    LinearMuscle("risorius_L", (52.0, -60.0), 6.0, (24.0, -56.0), 18.0, 1.3, 9.0, 0.0),
    LinearMuscle("depressor_labii", (0.0, -92.0), 8.0, (0.0, -62.0), 35.0, 1.25, 6.0, 0.0, True),
    LinearMuscle("mentalis", (0.0, -72.0), 10.0, (0.0, -92.0), 40.0, 1.3, 5.0, 3.0, True),
)
ORBICULARIS_ORIS = SphincterMuscle(
    "orbicularis_oris",
    centre_xy=(0.0, -55.5),
    semi_axes=(36.0, 24.0),
    flat_fraction=0.55,
    contraction=(0.4, 0.25),
    pucker=8.0,
)
JAW = JawRotation(
    "jaw_open",
    joint_yz=(-20.0, 12.0),
    joint_half_span=52.0,
    max_angle_deg=18.0,
    mouth_line_y=-55.5,
    lip_band=3.5,
    mouth_half_width=24.0,
    band_widening=0.3,
)


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
    return replace(
        muscle,
        name=muscle.name[:-2] + "_R",
        attachment_xy=(-muscle.attachment_xy[0], muscle.attachment_xy[1]),
        insertion_xy=(-muscle.insertion_xy[0], muscle.insertion_xy[1]),
    )


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
"""Default of :func:`deform`'s ``chunk_points`` (kept for callers; the compiled model needs no chunking)."""

_ZONE_MARGIN = 1.0
"""mm of extra slack when choosing which points a step looks at (guards the choice against rounding)."""

_BLOCKS = 64
"""Blocks of frames the parallel loop hands out (each allocates its work space once)."""

_STEP_NAMES: tuple[str, ...] = (
    (JAW.name,) + tuple(muscle.spec.name for muscle in LINEAR_MUSCLES) + (ORBICULARIS_ORIS.name,)
)
"""The steps in the order they act: the jaw, the linear muscles, the sphincter."""


def deform(points: np.ndarray, activations: np.ndarray, *, chunk_points: int = DEFAULT_CHUNK_POINTS) -> np.ndarray:
    """Positions of skin points under muscle activations.

    Parameters
    ----------
    points : ndarray of shape (n_points, 3)
        Rest positions in the head frame, mm.
    activations : ndarray of shape (n_frames, 18)
        Activation of each muscle of :data:`MUSCLE_NAMES` in [0, 1].
    chunk_points : int, optional
        A positive integer, checked and otherwise unused: the compiled model moves one point of one frame at a
        time and needs no work space beyond the result, whatever the chunk.

    Returns
    -------
    ndarray of shape (n_frames, n_points, 3)
        Deformed positions in the head frame, mm. Zero activations give the rest points exactly.
    """
    points = _checked_points(points)
    activations = _checked_activations(activations)
    if isinstance(chunk_points, bool) or not isinstance(chunk_points, (int, np.integer)) or chunk_points < 1:
        raise WorkbenchError(f"chunk_points must be a positive integer, got {chunk_points!r}")
    positions = np.empty((activations.shape[0], points.shape[0], 3))
    _run_kernel(points, activations, positions, subtract_rest=False)
    return positions


def deform_displacements(points: np.ndarray, activations: np.ndarray, out: np.ndarray) -> np.ndarray:
    """Displacements of skin points from rest under muscle activations, written into ``out``.

    The same model as :func:`deform`: each displacement is ``deform(points, activations) - points`` computed in
    float64 and rounded once to the dtype of ``out``, with no full-size float64 temporary.

    Parameters
    ----------
    points : ndarray of shape (n_points, 3)
        Rest positions in the head frame, mm.
    activations : ndarray of shape (n_frames, 18)
        Activation of each muscle of :data:`MUSCLE_NAMES` in [0, 1].
    out : ndarray of shape (n_frames, 3 * n_points), float32 or float64
        C-contiguous and writeable; row ``f`` receives ``[dx0, dy0, dz0, dx1, ...]`` of frame ``f``, mm.

    Returns
    -------
    ndarray of shape (n_frames, 3 * n_points)
        ``out``.
    """
    points = _checked_points(points)
    activations = _checked_activations(activations)
    shape = (activations.shape[0], 3 * points.shape[0])
    if not isinstance(out, np.ndarray) or out.dtype not in (np.float32, np.float64):
        raise WorkbenchError(
            f"out must be a float32 or float64 array, got {type(out).__name__} {getattr(out, 'dtype', '')}".rstrip()
        )
    if out.shape != shape or not out.flags.c_contiguous or not out.flags.writeable:
        raise WorkbenchError(f"out must be a writeable C-contiguous array of shape {shape}, got shape {out.shape}")
    _run_kernel(points, activations, out.reshape(shape[0], points.shape[0], 3), subtract_rest=True)
    return out


def saturate(drive: np.ndarray) -> np.ndarray:
    """Soft saturation ``tanh(k s) / tanh(k)``: 0 at 0, 1 at 1, steeper than linear near 0."""
    return np.tanh(SATURATION * drive) / np.tanh(SATURATION)


def _run_kernel(points: np.ndarray, activations: np.ndarray, out: np.ndarray, *, subtract_rest: bool) -> None:
    """Fill ``out`` (n_frames, n_points, 3) with the deformed ``points``, less the rest points if
    ``subtract_rest``.

    What does not depend on the point (each frame's jaw angle, where the muscles on the mandible are turned with
    it) is computed here, vectorised; the compiled kernel then moves every point of every frame through the
    steps, skipping those a step cannot reach (:func:`_reachable_points`).
    """
    jaw_angle = np.deg2rad(JAW.max_angle_deg) * saturate(activations[:, _JAW_COLUMN])
    attachments, axes = _muscle_frames(jaw_angle)
    reachable = _reachable_points(points)
    step_points = np.concatenate([np.asarray(reachable[name], dtype=np.int64) for name in _STEP_NAMES])
    step_start = np.cumsum([0] + [len(reachable[name]) for name in _STEP_NAMES], dtype=np.int64)
    # Writeable C-contiguous inputs whatever the caller passes (read-only take arrays, slices): one compiled
    # version per dtype of ``out`` only.
    points, activations = (np.require(array, np.float64, ("C", "W")) for array in (points, activations))
    _deform_frames(
        points,
        activations,
        jaw_angle,
        attachments,
        axes,
        _LINEAR_CONSTANTS,
        _LINEAR_COLUMNS,
        step_points,
        step_start,
        out,
        subtract_rest,
    )


def _muscle_frames(jaw_angle: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Attachment and unit axis (attachment to insertion, over the rest length) of every linear muscle per frame.

    Parameters
    ----------
    jaw_angle : ndarray of shape (n_frames,)
        Radians.

    Returns
    -------
    attachments, axes : ndarray of shape (n_frames, n_linear_muscles, 3)
        Muscles on the mandible turn with the jaw; the others are the same in every frame.
    """
    n_frames = jaw_angle.shape[0]
    attachments = np.empty((n_frames, len(LINEAR_MUSCLES), 3))
    axes = np.empty_like(attachments)
    for index, muscle in enumerate(LINEAR_MUSCLES):
        if muscle.spec.on_jaw:
            attachment, insertion = _on_jaw(muscle.attachment, jaw_angle), _on_jaw(muscle.insertion, jaw_angle)
        else:
            attachment = np.broadcast_to(muscle.attachment, (n_frames, 3))
            insertion = np.broadcast_to(muscle.insertion, (n_frames, 3))
        attachments[:, index] = attachment
        axes[:, index] = (insertion - attachment) / muscle.rest_length
    return attachments, axes


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
    near = (np.abs(points[:, 0] - _SPHINCTER_CENTRE[0]) < ORBICULARIS_ORIS.semi_axes[0] + slack) & (
        np.abs(points[:, 1] - _SPHINCTER_CENTRE[1]) < ORBICULARIS_ORIS.semi_axes[1] + slack
    )
    reachable[ORBICULARIS_ORIS.name] = np.flatnonzero(near)
    return reachable


def _rotation_about_x_displacement(offsets: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """``R(angle) r - r`` for rotations about +x (Rodrigues), exactly zero where the angle is zero.

    offsets : (..., 3) vectors from the pivot; angle : broadcastable to offsets[..., 0].
    """
    sin_a, one_minus_cos = np.sin(angle), 1.0 - np.cos(angle)
    y, z = offsets[..., 1], offsets[..., 2]
    return np.stack([np.zeros_like(y * sin_a), -sin_a * z - one_minus_cos * y, sin_a * y - one_minus_cos * z], axis=-1)


def _on_jaw(point: np.ndarray, jaw_angle: np.ndarray) -> np.ndarray:
    """Where a mandible point is for each frame's jaw angle: shape (n_frames, 3)."""
    offset = np.broadcast_to(point - _JAW_PIVOT, (jaw_angle.shape[0], 3))
    return point + _rotation_about_x_displacement(offset, jaw_angle)


# --- the compiled steps -------------------------------------------------------------------------------------
# Each step takes a point's current position (x, y, z) and returns its new one, with the arithmetic of the
# vectorised model this replaces, operation for operation (the tests keep that model as their reference):
# outside its zone, or at zero activation, a step returns the point bit-for-bit unchanged. The steps are inlined
# into the kernel: run once per point and step, a call would cost as much as the step.

_HALF_PI = 0.5 * np.pi
_TANH_SATURATION = float(np.tanh(SATURATION))

# Columns of _LINEAR_CONSTANTS, one row per linear muscle in LINEAR_MUSCLES order.
_REST_LENGTH, _ZONE_END, _COS_CONE_SQUARED, _CONE, _MAX_DISPLACEMENT, _BULGE = range(6)


def _linear_constants(muscle: _ResolvedLinearMuscle) -> list[float]:
    cone = float(np.deg2rad(muscle.spec.cone_half_angle_deg))
    cos_cone = float(np.cos(cone))
    return [
        muscle.rest_length,
        muscle.spec.falloff_ratio * muscle.rest_length,
        cos_cone * cos_cone,
        cone,
        muscle.spec.max_displacement,
        muscle.spec.bulge,
    ]


_LINEAR_CONSTANTS = np.array([_linear_constants(muscle) for muscle in LINEAR_MUSCLES])
_LINEAR_COLUMNS = np.array([muscle.column for muscle in LINEAR_MUSCLES], dtype=np.int64)

# The geometry as plain floats, which compiled code takes as constants.
_MOUTH_LINE_Y, _MOUTH_HALF_WIDTH = JAW.mouth_line_y, JAW.mouth_half_width
_LIP_BAND, _BAND_WIDENING = JAW.lip_band, JAW.band_widening
_JAW_PIVOT_Y, _JAW_PIVOT_Z = float(_JAW_PIVOT[1]), float(_JAW_PIVOT[2])
_SPHINCTER_X, _SPHINCTER_Y = float(_SPHINCTER_CENTRE[0]), float(_SPHINCTER_CENTRE[1])
_SEMI_AXIS_X, _SEMI_AXIS_Y = ORBICULARIS_ORIS.semi_axes
_FLAT_FRACTION = ORBICULARIS_ORIS.flat_fraction
_CONTRACTION_X, _CONTRACTION_Y = ORBICULARIS_ORIS.contraction
_PUCKER = ORBICULARIS_ORIS.pucker


@njit(inline="always")
def _saturate(drive):
    """:func:`saturate` of one value."""
    return np.tanh(SATURATION * drive) / _TANH_SATURATION


@njit(inline="always")
def _turn_with_jaw(x, y, z, jaw_angle):
    """A point below the mouth line turns about the joint axis by its weight times the frame's jaw angle.

    The weight is 1 on the chin and lower lip and rises from 0 at the mouth line over a band that widens toward
    the jaw angles. A rotation, not a linear blend of positions, so the lower face swings on an arc.
    """
    if not (y < _MOUTH_LINE_Y and jaw_angle > 0.0):
        return x, y, z
    beyond_mouth = max(abs(x) - _MOUTH_HALF_WIDTH, 0.0)
    band = _LIP_BAND + _BAND_WIDENING * beyond_mouth
    t = min(max((_MOUTH_LINE_Y - y) / band, 0.0), 1.0)
    angle = t * t * (3.0 - 2.0 * t) * jaw_angle
    sin_a, one_minus_cos = np.sin(angle), 1.0 - np.cos(angle)
    offset_y, offset_z = y - _JAW_PIVOT_Y, z - _JAW_PIVOT_Z
    return x, y + (-sin_a * offset_z - one_minus_cos * offset_y), z + (sin_a * offset_y - one_minus_cos * offset_z)


@njit(inline="always")
def _pull_linear_muscle(x, y, z, activation, attachments, axes, constants, frame, muscle):
    """Waters linear muscle: pull toward the attachment with angular and radial fall-off.

    The muscle is placed in this frame by ``attachments[frame, muscle]`` and ``axes[frame, muscle]`` and shaped
    by ``constants[muscle]`` (:data:`_LINEAR_CONSTANTS`); whole arrays and indices are passed, as views taken
    per point would cost more than the step.
    """
    if not activation > 0.0:
        return x, y, z
    offset_x = x - attachments[frame, muscle, 0]
    offset_y = y - attachments[frame, muscle, 1]
    offset_z = z - attachments[frame, muscle, 2]
    squared_distance = offset_x * offset_x + offset_y * offset_y + offset_z * offset_z
    axis_x, axis_y, axis_z = axes[frame, muscle, 0], axes[frame, muscle, 1], axes[frame, muscle, 2]
    along_axis = offset_x * axis_x + offset_y * axis_y + offset_z * axis_z
    rest_length, zone_end = constants[muscle, _REST_LENGTH], constants[muscle, _ZONE_END]
    if not (
        along_axis > 0.0
        and along_axis * along_axis > constants[muscle, _COS_CONE_SQUARED] * squared_distance
        and squared_distance < zone_end * zone_end
    ):
        return x, y, z
    distance = np.sqrt(squared_distance)
    cos_angle = min(along_axis / distance, 1.0)
    relative_angle = min(np.arccos(cos_angle) / constants[muscle, _CONE], 1.0)
    angular = np.cos(_HALF_PI * relative_angle)
    angular = angular * angular
    if distance < rest_length:
        radial = np.sin(_HALF_PI * min(distance / rest_length, 1.0))
    else:
        radial = np.cos(_HALF_PI * min(max((distance - rest_length) / (zone_end - rest_length), 0.0), 1.0))
    radial = radial * radial
    response = _saturate(activation * angular * radial)
    # Never pull a point past half its distance to the attachment.
    pull_over_distance = min(constants[muscle, _MAX_DISPLACEMENT] * response, 0.5 * distance) / distance
    x = x - pull_over_distance * offset_x
    y = y - pull_over_distance * offset_y
    z = z - pull_over_distance * offset_z
    if constants[muscle, _BULGE] != 0.0:
        z = z + constants[muscle, _BULGE] * response
    return x, y, z


@njit(inline="always")
def _contract_sphincter(x, y, z, activation):
    """Orbicularis oris: the lips contract toward the mouth centre and push forward (pucker)."""
    if not activation > 0.0:
        return x, y, z
    dx, dy = x - _SPHINCTER_X, y - _SPHINCTER_Y
    scaled_x, scaled_y = dx / _SEMI_AXIS_X, dy / _SEMI_AXIS_Y
    squared_radius = scaled_x * scaled_x + scaled_y * scaled_y
    if not squared_radius < 1.0:
        return x, y, z
    radius = np.sqrt(squared_radius)
    fall = min(max((radius - _FLAT_FRACTION) / (1.0 - _FLAT_FRACTION), 0.0), 1.0)
    weight = np.cos(_HALF_PI * fall)
    response = _saturate(activation * (weight * weight))
    return (
        x - _CONTRACTION_X * dx * response,
        y - _CONTRACTION_Y * dy * response,
        z + _PUCKER * response * (1.0 - 0.6 * squared_radius),
    )


@njit(cache=True, parallel=True)
def _deform_frames(
    points,
    activations,
    jaw_angle,
    attachments,
    axes,
    linear_constants,
    linear_columns,
    step_points,
    step_start,
    out,
    subtract_rest,
):
    """Every point of every frame through the jaw, the linear muscles and the sphincter, into ``out``.

    points (n_points, 3); activations (n_frames, 18); jaw_angle (n_frames,); attachments, axes
    (n_frames, n_linear, 3); step_points, step_start: the points step ``s`` can reach are
    ``step_points[step_start[s]:step_start[s + 1]]`` (step 0 the jaw, then the linear muscles, last the
    sphincter); out (n_frames, n_points, 3), float32 or float64: the positions, or their displacements from
    ``points`` if ``subtract_rest``, rounded once to the dtype of ``out``.

    Within a frame each step runs over its points before the next step starts: a point's steps still come in
    order, and the points of one step, independent of each other, keep the processor busy while one of them
    waits on sqrt, arccos or tanh (a point's own steps form one long chain of dependent operations).
    """
    n_frames, n_points, n_linear = activations.shape[0], points.shape[0], linear_constants.shape[0]
    n_blocks = min(n_frames, _BLOCKS)
    for block in prange(n_blocks):
        positions = np.empty((n_points, 3))  # float64 work space, once per block of frames
        for frame in range(block * n_frames // n_blocks, (block + 1) * n_frames // n_blocks):
            positions[:] = points
            angle = jaw_angle[frame]
            if angle > 0.0:
                for k in range(step_start[0], step_start[1]):
                    p = step_points[k]
                    positions[p, 0], positions[p, 1], positions[p, 2] = _turn_with_jaw(
                        positions[p, 0], positions[p, 1], positions[p, 2], angle
                    )
            for muscle in range(n_linear):
                activation = activations[frame, linear_columns[muscle]]
                if activation > 0.0:
                    for k in range(step_start[1 + muscle], step_start[2 + muscle]):
                        p = step_points[k]
                        positions[p, 0], positions[p, 1], positions[p, 2] = _pull_linear_muscle(
                            positions[p, 0],
                            positions[p, 1],
                            positions[p, 2],
                            activation,
                            attachments,
                            axes,
                            linear_constants,
                            frame,
                            muscle,
                        )
            activation = activations[frame, _SPHINCTER_COLUMN]
            if activation > 0.0:
                for k in range(step_start[n_linear + 1], step_start[n_linear + 2]):
                    p = step_points[k]
                    positions[p, 0], positions[p, 1], positions[p, 2] = _contract_sphincter(
                        positions[p, 0], positions[p, 1], positions[p, 2], activation
                    )
            for p in range(n_points):
                for c in range(3):
                    out[frame, p, c] = positions[p, c] - points[p, c] if subtract_rest else positions[p, c]


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
