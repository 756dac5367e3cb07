"""A face mesh built by code: a front patch of a head with sculpted features.

The skin is a parametric surface. A column ``theta`` (azimuth around the vertical axis) and a height ``y`` give a
point on a smooth base head (a super-elliptic cross-section whose width and depth change with height); smooth
features (nose, brow ridges, eye sockets, cheekbones, lips, mouth line, chin) are then added as heights along the
outward normal of the base. All features are functions of the *face-plane* coordinates ``(x, y)`` of the base
point, so muscles and markers can be placed with the same coordinates (:func:`skin_point`).

Coordinates, in millimetres: origin at the centre of the head, ``+x`` the actor's left, ``+y`` up, ``+z`` forward
out of the face.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.settings.rules import checked, integer


@dataclass(frozen=True)
class HeadProfile:
    """The smooth base head, before any feature is added. Lengths in mm.

    The front depth ``Z(y)`` follows a super-ellipse in ``y`` (different above and below the centre, flatter
    below so the chin stays forward); the half-width ``W(y)`` narrows from the temples to the jaw and chin.
    """

    depth: float = 80.0  # front depth Z at y = 0
    half_height_up: float = 124.0
    exponent_up: float = 2.6
    half_height_down: float = 110.0
    exponent_down: float = 4.0
    half_width: float = 72.0  # W above the cheekbones
    half_width_jaw: float = 60.0  # W at the jaw angle
    half_width_chin: float = 44.0  # W under the chin
    cross_section_exponent: float = 2.3  # > 2 flattens the front of each horizontal section
    top_y: float = 98.0  # top edge of the patch on the midline (hairline)
    top_drop_at_sides: float = 18.0  # the top edge drops this much at the outermost column
    chin_bottom_y: float = -103.0  # bottom edge on the midline (under the chin)
    jaw_angle_y: float = -68.0  # bottom edge at the outermost column (jaw angle)
    max_azimuth_deg: float = 78.0  # outermost column


@dataclass(frozen=True)
class Bump:
    """A smooth height added along the skin normal: ``height * exp(-(|dx|/sx)^px / 2 - (|dy|/sy)^py / 2)``.

    Negative heights are dents. ``mirrored`` bumps exist at ``x`` and ``-x``.
    """

    name: str
    x: float
    y: float
    sx: float
    sy: float
    height: float
    mirrored: bool = False
    px: float = 2.0
    py: float = 2.0


@dataclass(frozen=True)
class NoseRidge:
    """The nasal ridge: a height rising linearly from the root to the tip, widening as it goes down."""

    root_y: float = 14.0
    tip_y: float = -24.0
    root_height: float = 7.0
    tip_height: float = 19.0
    root_width: float = 5.5
    tip_width: float = 9.0
    edge_softness: float = 2.5  # mm over which the ridge fades in at the root and ends under the tip


HEAD = HeadProfile()
NOSE = NoseRidge()

# Feature table (face-plane coordinates in mm). Positions of the landmarks below follow these features.
FEATURES: tuple[Bump, ...] = (
    Bump("forehead", 0.0, 62.0, 40.0, 26.0, 3.0),
    Bump("brow_ridge", 28.0, 27.0, 17.0, 6.5, 6.0, mirrored=True),
    Bump("glabella", 0.0, 24.0, 8.0, 7.0, 3.0),
    Bump("eye_socket", 31.0, 11.0, 15.0, 10.0, -15.0, mirrored=True),
    Bump("eyeball", 31.0, 9.0, 10.5, 5.5, 10.0, mirrored=True, px=2.6, py=2.6),
    Bump("upper_lid_crease", 31.0, 15.5, 11.0, 1.3, -2.5, mirrored=True),
    Bump("lower_lid_crease", 31.0, 2.5, 10.0, 1.3, -1.5, mirrored=True),
    Bump("eye_bag", 32.0, -2.0, 12.0, 3.0, 1.5, mirrored=True),
    Bump("temple", 60.0, 36.0, 10.0, 16.0, -4.0, mirrored=True),
    Bump("cheekbone", 46.0, -8.0, 14.0, 11.0, 6.0, mirrored=True),
    Bump("cheek", 36.0, -32.0, 14.0, 14.0, 3.5, mirrored=True),
    Bump("nasolabial_fold", 24.0, -42.0, 3.0, 9.0, -1.5, mirrored=True),
    Bump("nose_tip", 0.0, -23.0, 7.5, 5.5, 3.0),
    Bump("nostril_wing", 11.0, -29.0, 5.5, 5.0, 6.5, mirrored=True),
    Bump("maxilla", 0.0, -52.0, 28.0, 16.0, 5.0),
    Bump("philtrum", 0.0, -42.0, 3.0, 4.0, 1.2),
    Bump("upper_lip", 0.0, -50.0, 20.0, 3.8, 5.5, px=4.0),
    Bump("mouth_line", 0.0, -55.5, 24.0, 1.6, -4.5, px=6.0),
    Bump("lower_lip", 0.0, -61.0, 18.0, 4.2, 5.5, px=4.0),
    Bump("mentolabial_sulcus", 0.0, -71.0, 14.0, 3.5, -2.5),
    Bump("chin", 0.0, -88.0, 15.0, 8.5, 9.0),
    Bump("jaw_line", 50.0, -82.0, 14.0, 8.0, 2.0, mirrored=True),
)

EYE_OPENINGS: tuple[tuple[float, float, float, float], ...] = ((31.0, 9.0, 13.0, 6.5), (-31.0, 9.0, 13.0, 6.5))
"""Eye openings as face-plane ellipses ``(x, y, semi_x, semi_y)``: no marker can be placed there."""

# Face-plane targets of the named landmarks; each landmark is the front-facing vertex nearest its target.
LANDMARK_TARGETS: dict[str, tuple[float, float]] = {
    "forehead": (0.0, 62.0),
    "brow_inner_L": (15.0, 27.0),
    "brow_inner_R": (-15.0, 27.0),
    "brow_outer_L": (45.0, 25.0),
    "brow_outer_R": (-45.0, 25.0),
    "eye_inner_L": (18.0, 9.0),
    "eye_inner_R": (-18.0, 9.0),
    "eye_outer_L": (44.0, 9.0),
    "eye_outer_R": (-44.0, 9.0),
    "nose_root": (0.0, 14.0),
    "nostril_L": (12.0, -30.0),
    "nostril_R": (-12.0, -30.0),
    "cheek_L": (45.0, -18.0),
    "cheek_R": (-45.0, -18.0),
    "upper_lip": (0.0, -50.0),
    "lower_lip": (0.0, -61.0),
    "mouth_corner_L": (24.0, -55.5),
    "mouth_corner_R": (-24.0, -55.5),
    "chin": (0.0, -90.0),
    "jaw_L": (58.0, -72.0),
    "jaw_R": (-58.0, -72.0),
}


@dataclass(frozen=True)
class FaceMesh:
    """A triangulated face patch.

    Attributes
    ----------
    vertices : ndarray of shape (n_vertices, 3)
        Rest positions in mm (read-only), head frame (origin at the head centre, +x left, +y up, +z forward).
    faces : ndarray of shape (n_triangles, 3)
        Vertex indices of each triangle (int64, read-only), counter-clockwise seen from the front.
    landmarks : dict of str to int
        Vertex index of each named point (``nose_tip``, ``chin``, ``mouth_corner_L``, ...).
    face_plane : ndarray of shape (n_vertices, 2)
        Face-plane coordinates ``(x, y)`` of each vertex's base point, the coordinates of the feature table.
    grid_shape : tuple of int
        ``(n_rows, n_cols)``: vertex ``i`` sits at row ``i // n_cols`` and column ``i % n_cols``.
    """

    vertices: np.ndarray
    faces: np.ndarray
    landmarks: dict
    face_plane: np.ndarray
    grid_shape: tuple[int, int]

    @property
    def n_vertices(self) -> int:
        return self.vertices.shape[0]


def make_face_mesh(n_rows: int = 70, n_cols: int = 60) -> FaceMesh:
    """Build the face mesh on an ``n_rows`` x ``n_cols`` grid.

    Parameters
    ----------
    n_rows, n_cols : int
        Grid size (rows run from the chin to the hairline, columns from the actor's right to left); at least 20
        each. The default gives 4,200 vertices.

    Returns
    -------
    FaceMesh
    """
    for name, value in (("n_rows", n_rows), ("n_cols", n_cols)):
        checked(value, name, integer(20))
    return face_mesh_of(int(n_rows), int(n_cols))


def face_mesh_of(n_rows: int, n_cols: int) -> FaceMesh:
    """:func:`make_face_mesh` of a grid size already checked (``dataset.mesh_rows`` and ``dataset.mesh_cols``, or
    :func:`workbench.dataset.synthetic.make_synthetic_take`'s arguments)."""
    azimuth, height = _grid_parameters(int(n_rows), int(n_cols))
    vertices, face_plane = _surface(azimuth.ravel(), height.ravel())
    faces = _grid_triangles(int(n_rows), int(n_cols))
    landmarks = _find_landmarks(vertices, face_plane)
    for array in (vertices, faces, face_plane):
        array.setflags(write=False)
    return FaceMesh(
        vertices=vertices,
        faces=faces,
        landmarks=landmarks,
        face_plane=face_plane,
        grid_shape=(int(n_rows), int(n_cols)),
    )


def skin_point(x: np.ndarray | float, y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Skin position and outward normal at face-plane coordinates ``(x, y)``.

    Parameters
    ----------
    x, y : float or ndarray of shape (n,)
        Face-plane coordinates in mm; ``|x|`` must be smaller than the head half-width at ``y``.

    Returns
    -------
    position : ndarray of shape (n, 3)
    normal : ndarray of shape (n, 3)
        Unit outward normal of the base head there (the direction features are added along).
    """
    x = np.atleast_1d(np.asarray(x, dtype=float))
    y = np.atleast_1d(np.asarray(y, dtype=float))
    half_width = _half_width(y)
    exponent = 2.0 / HEAD.cross_section_exponent
    sin_azimuth = np.sign(x) * np.abs(np.clip(x / half_width, -1.0, 1.0)) ** (1.0 / exponent)
    position, _ = _surface(np.arcsin(sin_azimuth), y)
    return position, _base_normal(np.arcsin(sin_azimuth), y)


def eye_opening_mask(face_plane: np.ndarray) -> np.ndarray:
    """True where face-plane points fall inside an eye opening.

    Parameters
    ----------
    face_plane : ndarray of shape (n, 2)

    Returns
    -------
    ndarray of shape (n,) of bool
    """
    inside = np.zeros(face_plane.shape[0], dtype=bool)
    for centre_x, centre_y, semi_x, semi_y in EYE_OPENINGS:
        inside |= ((face_plane[:, 0] - centre_x) / semi_x) ** 2 + ((face_plane[:, 1] - centre_y) / semi_y) ** 2 < 1
    return inside


def head_shell_point(azimuth: np.ndarray, y: np.ndarray, standoff: float) -> np.ndarray:
    """Points ``standoff`` mm outside the smooth base head (no facial features), e.g. for a headband.

    Parameters
    ----------
    azimuth : ndarray of shape (n,)
        Angle around the vertical axis in radians, 0 straight ahead, positive toward the actor's left.
    y : ndarray of shape (n,)
        Heights in mm.
    standoff : float
        Distance along the outward normal, mm.

    Returns
    -------
    ndarray of shape (n, 3)
    """
    azimuth = np.asarray(azimuth, dtype=float)
    y = np.asarray(y, dtype=float)
    return _base_point(azimuth, y) + standoff * _base_normal(azimuth, y)


# --- construction -------------------------------------------------------------------------------------------


def _smoothstep(edge0: float, edge1: float, value: np.ndarray) -> np.ndarray:
    t = np.clip((value - edge0) / (edge1 - edge0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _half_width(y: np.ndarray) -> np.ndarray:
    to_jaw = _smoothstep(-5.0, -68.0, y)
    to_chin = _smoothstep(-68.0, -105.0, y)
    return (
        HEAD.half_width
        - (HEAD.half_width - HEAD.half_width_jaw) * to_jaw
        - (HEAD.half_width_jaw - HEAD.half_width_chin) * to_chin
    )


def _front_depth(y: np.ndarray) -> np.ndarray:
    half_height = np.where(y >= 0, HEAD.half_height_up, HEAD.half_height_down)
    exponent = np.where(y >= 0, HEAD.exponent_up, HEAD.exponent_down)
    ratio = np.clip(np.abs(y) / half_height, 0.0, 1.0)
    return HEAD.depth * np.clip(1.0 - ratio**exponent, 0.0, 1.0) ** (1.0 / exponent)


def _base_point(azimuth: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Point of the base head: a super-elliptic horizontal section of half-width W(y) and depth Z(y)."""
    exponent = 2.0 / HEAD.cross_section_exponent
    sin_a, cos_a = np.sin(azimuth), np.cos(azimuth)
    x = _half_width(y) * np.sign(sin_a) * np.abs(sin_a) ** exponent
    z = _front_depth(y) * np.abs(cos_a) ** exponent
    return np.stack([x, y, z], axis=-1)


def _base_normal(azimuth: np.ndarray, y: np.ndarray, step: float = 1e-3) -> np.ndarray:
    """Outward unit normal of the base head, from central differences of the parametrisation."""
    d_azimuth = _base_point(azimuth + step, y) - _base_point(azimuth - step, y)
    d_height = _base_point(azimuth, y + step) - _base_point(azimuth, y - step)
    # +azimuth runs toward +x and +y up, so d_azimuth x d_height points out of the head.
    normal = np.cross(d_azimuth, d_height)
    return normal / np.linalg.norm(normal, axis=-1, keepdims=True)


def _feature_height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    height = _nose_ridge_height(x, y)
    for bump in FEATURES:
        centres = (bump.x, -bump.x) if bump.mirrored and bump.x != 0.0 else (bump.x,)
        for centre_x in centres:
            exponent = (np.abs(x - centre_x) / bump.sx) ** bump.px + (np.abs(y - bump.y) / bump.sy) ** bump.py
            height = height + bump.height * np.exp(-0.5 * exponent)
    return height


def _nose_ridge_height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    along = np.clip((NOSE.root_y - y) / (NOSE.root_y - NOSE.tip_y), 0.0, 1.2)
    crest = NOSE.root_height + (NOSE.tip_height - NOSE.root_height) * along
    width = NOSE.root_width + (NOSE.tip_width - NOSE.root_width) * along
    fade_in = 1.0 / (1.0 + np.exp((y - NOSE.root_y) / NOSE.edge_softness))
    cut_under_tip = 1.0 / (1.0 + np.exp((NOSE.tip_y - 3.0 - y) / NOSE.edge_softness))
    return crest * np.exp(-0.5 * (x / width) ** 2) * fade_in * cut_under_tip


def _surface(azimuth: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    base = _base_point(azimuth, y)
    face_plane = base[:, :2].copy()
    height = _feature_height(face_plane[:, 0], face_plane[:, 1])
    return base + height[:, None] * _base_normal(azimuth, y), face_plane


def _row_warp(n_rows: int) -> np.ndarray:
    """Row parameters in [0, 1], denser around the mouth and the eyes (where the features are small)."""
    fine = np.linspace(0.0, 1.0, 2001)
    y_midline = HEAD.chin_bottom_y + (HEAD.top_y - HEAD.chin_bottom_y) * fine
    density = (
        1.0
        + 1.2 * np.exp(-0.5 * ((y_midline + 56.0) / 11.0) ** 2)
        + 0.5 * np.exp(-0.5 * ((y_midline - 10.0) / 10.0) ** 2)
    )
    cumulative = np.concatenate([[0.0], np.cumsum(0.5 * (density[1:] + density[:-1]))])
    cumulative /= cumulative[-1]
    return np.interp(np.linspace(0.0, 1.0, n_rows), cumulative, fine)


def _grid_parameters(n_rows: int, n_cols: int) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth and height of each grid vertex, shape (n_rows, n_cols) each."""
    column = np.linspace(-1.0, 1.0, n_cols)
    # Slightly denser columns toward the middle of the face.
    azimuth = np.deg2rad(HEAD.max_azimuth_deg) * (column + 0.5 * column**3) / 1.5
    side = (column**2)[None, :]
    bottom = HEAD.chin_bottom_y + (HEAD.jaw_angle_y - HEAD.chin_bottom_y) * side
    top = HEAD.top_y - HEAD.top_drop_at_sides * side
    row = _row_warp(n_rows)[:, None]
    height = bottom + (top - bottom) * row
    return np.broadcast_to(azimuth[None, :], height.shape), height


def _grid_triangles(n_rows: int, n_cols: int) -> np.ndarray:
    rows, cols = np.meshgrid(np.arange(n_rows - 1), np.arange(n_cols - 1), indexing="ij")
    lower_left = (rows * n_cols + cols).ravel()
    lower_right = lower_left + 1
    upper_left = lower_left + n_cols
    upper_right = upper_left + 1
    # Counter-clockwise seen from the front (+z): columns go toward +x, rows toward +y.
    first = np.stack([lower_left, lower_right, upper_right], axis=1)
    second = np.stack([lower_left, upper_right, upper_left], axis=1)
    return np.concatenate([first, second]).astype(np.int64)


def _find_landmarks(vertices: np.ndarray, face_plane: np.ndarray) -> dict[str, int]:
    front = np.flatnonzero(vertices[:, 2] > 0.0)
    near_centre = front[np.abs(face_plane[front, 0]) < 20.0]
    landmarks = {"nose_tip": int(near_centre[np.argmax(vertices[near_centre, 2])])}
    for name, (target_x, target_y) in LANDMARK_TARGETS.items():
        distance = np.hypot(face_plane[front, 0] - target_x, face_plane[front, 1] - target_y)
        landmarks[name] = int(front[np.argmin(distance)])
    return landmarks
