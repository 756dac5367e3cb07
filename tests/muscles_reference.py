"""The synthetic actor's muscle model as vectorised NumPy steps: the reference the compiled model is held to.

This is the model :mod:`workbench.dataset.synthetic.muscles` computed before it was compiled per point, kept
independent of it apart from the geometry (muscle placement, jaw and sphincter constants), and without the
pruning of unreachable points (which changes no result). Each step moves ``positions`` (n_frames, n_points, 3)
in place and evaluates its weights only on the frame-points inside its zone with a non-zero activation.
"""

import numpy as np

from workbench.dataset.synthetic.muscles import (
    _JAW_COLUMN,
    _JAW_PIVOT,
    _SPHINCTER_CENTRE,
    _SPHINCTER_COLUMN,
    JAW,
    LINEAR_MUSCLES,
    ORBICULARIS_ORIS,
    SATURATION,
)


def deform_reference(points: np.ndarray, activations: np.ndarray) -> np.ndarray:
    """Positions of skin points under muscle activations, step by step over all frames at once.

    Parameters
    ----------
    points : ndarray of shape (n_points, 3)
        Rest positions in the head frame, mm.
    activations : ndarray of shape (n_frames, 18)
        Activations in [0, 1].

    Returns
    -------
    ndarray of shape (n_frames, n_points, 3)
    """
    points, activations = np.asarray(points, dtype=float), np.asarray(activations, dtype=float)
    positions = np.empty((activations.shape[0],) + points.shape)
    positions[...] = points
    jaw_angle = np.deg2rad(JAW.max_angle_deg) * saturate(activations[:, _JAW_COLUMN])
    if jaw_angle.max(initial=0.0) > 0.0:
        turn_with_jaw(positions, jaw_angle)
    for muscle in LINEAR_MUSCLES:
        activation = activations[:, muscle.column]
        if activation.max(initial=0.0) > 0.0:
            pull_linear_muscle(positions, muscle, activation, jaw_angle)
    activation = activations[:, _SPHINCTER_COLUMN]
    if activation.max(initial=0.0) > 0.0:
        contract_sphincter(positions, activation)
    return positions


def saturate(drive: np.ndarray) -> np.ndarray:
    return np.tanh(SATURATION * drive) / np.tanh(SATURATION)


def jaw_weight(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    beyond_mouth = np.maximum(np.abs(x) - JAW.mouth_half_width, 0.0)
    band = JAW.lip_band + JAW.band_widening * beyond_mouth
    t = np.clip((JAW.mouth_line_y - y) / band, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def rotation_about_x_displacement(offsets: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """``R(angle) r - r`` for rotations about +x; offsets (..., 3), angle broadcastable to offsets[..., 0]."""
    sin_a, one_minus_cos = np.sin(angle), 1.0 - np.cos(angle)
    y, z = offsets[..., 1], offsets[..., 2]
    return np.stack([np.zeros_like(y * sin_a), -sin_a * z - one_minus_cos * y, sin_a * y - one_minus_cos * z], axis=-1)


def turn_with_jaw(positions: np.ndarray, jaw_angle: np.ndarray) -> None:
    inside = (positions[..., 1] < JAW.mouth_line_y) & (jaw_angle[:, None] > 0.0)
    frame_index = np.nonzero(inside)[0]
    moving = positions[inside]
    angle = jaw_weight(moving[:, 0], moving[:, 1]) * jaw_angle[frame_index]
    positions[inside] = moving + rotation_about_x_displacement(moving - _JAW_PIVOT, angle)


def on_jaw(point: np.ndarray, jaw_angle: np.ndarray) -> np.ndarray:
    offset = np.broadcast_to(point - _JAW_PIVOT, (jaw_angle.shape[0], 3))
    return point + rotation_about_x_displacement(offset, jaw_angle)


def pull_linear_muscle(positions: np.ndarray, muscle, activation: np.ndarray, jaw_angle: np.ndarray) -> None:
    spec = muscle.spec
    n_frames = positions.shape[0]
    if spec.on_jaw:
        attachment, insertion = on_jaw(muscle.attachment, jaw_angle), on_jaw(muscle.insertion, jaw_angle)
    else:
        attachment = np.broadcast_to(muscle.attachment, (n_frames, 3))
        insertion = np.broadcast_to(muscle.insertion, (n_frames, 3))
    rest_length = muscle.rest_length
    zone_end = spec.falloff_ratio * rest_length
    axis = (insertion - attachment) / rest_length

    offset = [positions[..., k] - attachment[:, None, k] for k in range(3)]
    squared_distance = offset[0] * offset[0] + offset[1] * offset[1] + offset[2] * offset[2]
    along_axis = offset[0] * axis[:, None, 0] + offset[1] * axis[:, None, 1] + offset[2] * axis[:, None, 2]
    cos_cone = np.cos(np.deg2rad(spec.cone_half_angle_deg))
    inside = (
        (along_axis > 0.0)
        & (along_axis * along_axis > cos_cone * cos_cone * squared_distance)
        & (squared_distance < zone_end * zone_end)
        & (activation[:, None] > 0.0)
    )
    frame_index = np.nonzero(inside)[0]

    distance = np.sqrt(squared_distance[inside])
    cos_angle = np.minimum(along_axis[inside] / distance, 1.0)
    relative_angle = np.minimum(np.arccos(cos_angle) / np.deg2rad(spec.cone_half_angle_deg), 1.0)
    angular = np.cos(0.5 * np.pi * relative_angle) ** 2
    rising = np.sin(0.5 * np.pi * np.minimum(distance / rest_length, 1.0)) ** 2
    falling = np.cos(0.5 * np.pi * np.clip((distance - rest_length) / (zone_end - rest_length), 0.0, 1.0)) ** 2
    radial = np.where(distance < rest_length, rising, falling)

    response = saturate(activation[frame_index] * angular * radial)
    pull_over_distance = np.minimum(spec.max_displacement * response, 0.5 * distance) / distance
    moving = positions[inside]
    moving -= pull_over_distance[:, None] * (moving - attachment[frame_index])
    if spec.bulge:
        moving[:, 2] += spec.bulge * response
    positions[inside] = moving


def contract_sphincter(positions: np.ndarray, activation: np.ndarray) -> None:
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
