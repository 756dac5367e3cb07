"""One streamed pass over the evaluated frames that gives every basis what its weights (eq. 5) and alpha (eq. 6)
need, so that no basis reads the frames again and no reconstruction is ever formed.

Each basis is an affine subspace ``offset + span(U)`` with orthonormal columns ``U`` (the left singular vectors of
a hand or quasi-eigen basis, offset 0; the eigenfaces with the capture mean as offset). For a frame ``y`` the pass
keeps the coordinates ``q = U^T (y - offset)`` and the squared distance to the subspace,
``|y - offset - U q|^2``. The weights of eq. 5 are a function of ``q`` alone, and the error of any reconstruction
``offset + U a`` is ``|y - offset - U q|^2 + |q - a|^2``. The squared distance is taken as
``|y - offset|^2 - |q|^2`` from the pass's dot products, and recomputed from the explicit residual for the
frames where that difference cancels (distance below ``EXPLICIT_BELOW`` of the terms' size), so it is accurate
to rounding for every frame.

Given a part of the points (the face region, coordinates ``R``), the same pass also keeps, per subspace, the region's
part of the distance, ``|d_R|^2`` with ``d = y - offset - U q``, and ``U_R^T d_R``. The region's error of any
reconstruction ``offset + U a`` is then ``|U_R e + d_R|^2 = e^T U_R^T U_R e + 2 e.(U_R^T d_R) + |d_R|^2`` with
``e = q - a`` (:func:`region_error_sq`), so scoring the region reads the frames no second time.

When the subspaces share directions (the quasi-eigen faces lie in the span of the eigenfaces and the mean, which
also holds PCA's subspace), the pass multiplies the frames by an orthonormal basis ``W`` of their joint span only,
fewer columns than all of theirs together, and takes every subspace's terms from ``W``'s by algebra of its own
size (:func:`project_through_span`): with ``U = W A`` and ``offset = W b``, ``q = A^T (p - b)`` for ``p = W^T y``, and
the residual ``d = d_W + W c`` with ``c = p - b - A q``, so ``|d|^2 = |d_W|^2 + |c|^2`` (``d_W`` is orthogonal to
``W``) and the region's terms follow from ``W``'s in the same way.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping

import numpy as np

from workbench.numerics.frames import LARGE_FRAMES, frame_chunks

EXPLICIT_BELOW = 1e-4
"""Frames whose squared distance is below this fraction of ``|y|^2 + |offset|^2`` get the explicit residual."""

JOINT_SPAN_RTOL = 1e-12
"""A direction belongs to the subspaces' joint span when its singular value among their columns and unit offsets
exceeds this (every column has norm 1); a quasi-eigen face lies in its eigenfaces' span to about 1e-15."""


@dataclass(frozen=True)
class Subspace:
    """An affine subspace ``offset + span(columns)`` of frame space.

    Attributes
    ----------
    columns : ndarray of shape (n_dims, k)
        Orthonormal.
    offset : ndarray of shape (n_dims,) or None
        None for a linear subspace.
    """

    columns: np.ndarray
    offset: np.ndarray | None = None


@dataclass(frozen=True)
class FrameProjections:
    """What one pass over the frames keeps.

    Attributes
    ----------
    coordinates : dict
        Subspace label -> ndarray of shape (n_frames, k), ``U^T (y - offset)``.
    distance_sq : dict
        Subspace label -> ndarray of shape (n_frames,), ``|y - offset - U U^T (y - offset)|^2``.
    displacement_sq, position_sq : ndarray of shape (n_frames,)
        ``|y|^2`` and ``|v0 + y|^2`` (the references of eq. 6, as
        :func:`workbench.numerics.metrics.reference_squares`).
    n_explicit : int
        Frame-subspace pairs whose distance was recomputed from the explicit residual.
    region : RegionProjections or None
        The part of the points ``project_frames`` was given (None when it was given none).
    span_pass : SpanPass or None
        The pass through the subspaces' joint span (:func:`project_through_span`), which a later call over the same
        frames can be handed (``kept``); None when the pass went over each subspace.
    """

    coordinates: dict
    distance_sq: dict
    displacement_sq: np.ndarray
    position_sq: np.ndarray
    n_explicit: int
    region: "RegionProjections | None" = None
    span_pass: "SpanPass | None" = None


@dataclass(frozen=True)
class RegionProjections:
    """What the pass keeps of a part of the points, coordinates ``R``, per subspace ``offset + span(U)``.

    Attributes
    ----------
    distance_sq : dict
        Label -> ndarray of shape (n_frames,), ``|d_R|^2`` with ``d = y - offset - U q``.
    cross : dict
        Label -> ndarray of shape (n_frames, k), ``U_R^T d_R``.
    gram : dict
        Label -> ndarray of shape (k, k), ``U_R^T U_R``.
    """

    distance_sq: dict
    cross: dict
    gram: dict


def region_error_sq(region: RegionProjections, label: str, difference: np.ndarray | None = None) -> np.ndarray:
    """Squared error over the region of each frame's reconstruction ``offset + U a`` in subspace ``label``:
    ``e^T U_R^T U_R e + 2 e.(U_R^T d_R) + |d_R|^2`` with ``e = q - a``.

    Parameters
    ----------
    region : RegionProjections
    label : str
    difference : ndarray of shape (n_frames, k), optional
        ``q - a``, the coordinates' difference within the span (``None``: the orthogonal projection, ``a = q``).

    Returns
    -------
    ndarray of shape (n_frames,)
    """
    if difference is None:
        return region.distance_sq[label]
    inside = np.einsum("ij,ij->i", difference @ region.gram[label], difference)
    return np.maximum(
        inside + 2.0 * np.einsum("ij,ij->i", difference, region.cross[label]) + region.distance_sq[label], 0.0
    )


def project_frames(
    frames,
    subspaces: Mapping[str, Subspace],
    neutral: np.ndarray,
    *,
    chunk_size: int | None = None,
    region: np.ndarray | None = None,
    also_span: np.ndarray | None = None,
    kept: "SpanPass | None" = None,
) -> FrameProjections:
    """Coordinates of every frame in every subspace, and its squared distance to each, in one pass (frames of at
    least :data:`~workbench.numerics.frames.LARGE_FRAMES` values go through the subspaces' joint span when it has
    fewer columns than they have together: :func:`joint_span`, :func:`project_through_span`).

    Parameters
    ----------
    frames : ndarray of shape (n_frames, n_dims) or FramesOnDisk
        Float64 or float32 in memory, or on disk; read a chunk at a time as float64.
    subspaces : mapping
        Label -> :class:`Subspace`, all with ``n_dims`` rows.
    neutral : ndarray of shape (n_dims,)
        Neutral positions ``v0`` (for the absolute reference ``|v0 + y|^2``).
    chunk_size : int, optional
        Frames per chunk (:func:`workbench.numerics.frames.chunk_frames` when None).
    region : ndarray of shape (n_dims,) of bool, optional
        Coordinates of a part of the points: the pass then also keeps :class:`RegionProjections` of them.
    also_span : ndarray of shape (n_dims, j), optional
        More directions for the joint span, so that a later call over the same frames whose subspaces lie in them
        reads no frame again (:func:`project_through_span`); ignored by the pass over each subspace.
    kept : SpanPass, optional
        The ``span_pass`` of an earlier call over these very frames (:func:`project_through_span`); ignored by the
        pass over each subspace.

    Returns
    -------
    FrameProjections
    """
    span = joint_span(subspaces, also_span) if frames.shape[0] * frames.shape[1] >= LARGE_FRAMES else None
    if span is None:
        return project_onto_each(frames, subspaces, neutral, chunk_size=chunk_size, region=region)
    return project_through_span(frames, subspaces, neutral, span, chunk_size=chunk_size, region=region, kept=kept)


def joint_span(subspaces: Mapping[str, Subspace], also_span: np.ndarray | None = None) -> np.ndarray | None:
    """An orthonormal basis of the span of every subspace's columns and offset (and of ``also_span``'s columns),
    or None when it has as many columns as the subspaces have together (nothing to share).

    Returns
    -------
    ndarray of shape (n_dims, w) or None
    """
    vectors = [subspace.columns for subspace in subspaces.values()]
    for subspace in subspaces.values():
        if subspace.offset is not None and np.any(subspace.offset):
            offset = np.asarray(subspace.offset, dtype=float)
            vectors.append((offset / np.linalg.norm(offset))[:, None])
    if also_span is not None:
        vectors.append(also_span / np.maximum(np.linalg.norm(also_span, axis=0), np.finfo(float).tiny))
    together = np.hstack(vectors)
    if together.shape[1] >= together.shape[0]:
        return None
    left, singular, _ = np.linalg.svd(together, full_matrices=False)
    rank = int(np.sum(singular > JOINT_SPAN_RTOL * max(1.0, singular[0])))
    total = sum(subspace.columns.shape[1] for subspace in subspaces.values())
    return left[:, :rank] if rank < total else None


def project_through_span(
    frames,
    subspaces: Mapping[str, Subspace],
    neutral: np.ndarray,
    span: np.ndarray,
    *,
    chunk_size: int | None = None,
    region: np.ndarray | None = None,
    kept: "SpanPass | None" = None,
) -> FrameProjections:
    """:func:`project_frames` with one product by the subspaces' joint span ``W`` per chunk.

    Per frame the pass keeps ``p = W^T y`` and ``|d_W|^2 = |y|^2 - |p|^2`` (and, given a region, ``|d_W,R|^2`` and
    ``W_R^T d_W,R``); each subspace's terms then follow from them. A frame gets its explicit residual ``y - W p``
    where any subspace's distance (or its region's part) is below ``EXPLICIT_BELOW`` of its terms' size, the
    frames whose distances the difference would cancel.

    A pass handed on (``kept``, an earlier call's ``span_pass`` over the same frames) serves subspaces that lie in
    its span, over the same neutral and region (the paper's m = n variant, whose bases lie in the span of the same
    eigenfaces): they take their terms from it, reading again only the frames that now need their explicit
    residual.

    Parameters
    ----------
    frames, subspaces, neutral, chunk_size, region
        As :func:`project_frames`.
    span : ndarray of shape (n_dims, w)
        ``W``: orthonormal, holding every subspace's columns and offset (:func:`joint_span`).
    kept : SpanPass, optional
        An earlier pass over these very frames (the caller's promise: the frames are not compared, and must not
        have changed in place); a pass of their own when it does not serve them (:meth:`SpanPass.serves`).

    Returns
    -------
    FrameProjections
        ``n_explicit`` counts the frames given their explicit residual by this call; ``span_pass`` is the pass
        taken, ``kept`` or a new one.
    """
    if kept is None or not kept.serves(len(frames), neutral, region, subspaces):
        kept = SpanPass.of(frames, neutral, span, region, chunk_size)
    terms = {label: subspace_in_span(subspace, kept.span) for label, subspace in subspaces.items()}
    n_explicit = kept.take(frames, terms, chunk_size)
    return replace(kept.projections(terms, n_explicit), span_pass=kept)


@dataclass
class SpanPass:
    """What a pass over the frames keeps of their joint span ``W``, per frame: ``p = W^T y``, ``|y|^2``,
    ``|d_W|^2`` (exact where marked), and, given a region, ``|y_R|^2``, ``|d_W,R|^2`` and ``W_R^T d_W,R``."""

    span: np.ndarray
    neutral: np.ndarray
    inside_span: np.ndarray
    squares: np.ndarray
    gap: np.ndarray
    exact: np.ndarray
    neutral_dot: np.ndarray
    inside: np.ndarray | None = None
    gram: np.ndarray | None = None
    region_squares: np.ndarray | None = None
    region_gap: np.ndarray | None = None
    region_cross: np.ndarray | None = None
    region_exact: np.ndarray | None = None

    @classmethod
    def of(cls, frames, neutral: np.ndarray, span: np.ndarray, region, chunk_size: int | None = None) -> "SpanPass":
        """The pass: one product of each chunk by ``W``, its neutral positions and ``W`` zero outside the region."""
        n_frames, width = len(frames), span.shape[1]
        blocks = [span, neutral[:, None]]
        inside = None if region is None else np.asarray(region, dtype=bool)
        if inside is not None:
            blocks.append(np.where(inside[:, None], span, 0.0))
            runs = _runs(inside)
        together = np.hstack(blocks)
        kept = cls(
            span=span,
            neutral=np.array(neutral, dtype=float),
            inside_span=np.empty((n_frames, width)),
            squares=np.empty(n_frames),
            gap=np.empty(n_frames),
            exact=np.zeros(n_frames, dtype=bool),
            neutral_dot=np.empty(n_frames),
        )
        if inside is not None:
            kept.inside, kept.gram = inside, span[inside].T @ span[inside]
            kept.region_squares, kept.region_gap = np.empty(n_frames), np.empty(n_frames)
            kept.region_cross, kept.region_exact = np.empty((n_frames, width)), np.zeros(n_frames, dtype=bool)
        for rows, chunk in frame_chunks(frames, chunk_size):
            products = chunk @ together
            p = products[:, :width]
            kept.inside_span[rows], kept.neutral_dot[rows] = p, products[:, width]
            kept.squares[rows] = np.einsum("ij,ij->i", chunk, chunk)
            kept.gap[rows] = kept.squares[rows] - np.einsum("ij,ij->i", p, p)
            if inside is not None:
                along_region = products[:, width + 1 :]  # W_R^T y_R
                kept.region_squares[rows] = sum(np.einsum("ij,ij->i", chunk[:, a:b], chunk[:, a:b]) for a, b in runs)
                kept.region_cross[rows] = along_region - p @ kept.gram  # W_R^T (y_R - W_R p)
                kept.region_gap[rows] = (
                    kept.region_squares[rows]
                    - 2.0 * np.einsum("ij,ij->i", p, along_region)
                    + np.einsum("ij,ij->i", p @ kept.gram, p)
                )
        return kept

    def serves(self, n_frames: int, neutral: np.ndarray, region, subspaces: Mapping[str, Subspace]) -> bool:
        """Whether this pass can give the terms of ``subspaces`` over ``n_frames`` frames (taken to be the pass's
        own), ``neutral`` and ``region``: the same neutral and region, and every subspace in its span."""
        if n_frames != len(self.gap) or not np.array_equal(neutral, self.neutral):
            return False
        if (region is None) != (self.inside is None) or (
            region is not None and not np.array_equal(np.asarray(region, dtype=bool), self.inside)
        ):
            return False
        for subspace in subspaces.values():
            outside = subspace.columns - self.span @ (self.span.T @ subspace.columns)
            if np.abs(outside).max(initial=0.0) > JOINT_SPAN_RTOL:
                return False
            if subspace.offset is not None and np.any(subspace.offset):
                offset = np.asarray(subspace.offset, dtype=float)
                if np.abs(offset - self.span @ (self.span.T @ offset)).max() > JOINT_SPAN_RTOL * np.abs(offset).max():
                    return False
        return True

    def take(self, frames, terms: Mapping[str, tuple], chunk_size: int | None = None) -> int:
        """Give the explicit residual to every frame whose distance to a subspace of ``terms``
        (:func:`subspace_in_span`), or its region's part, the difference would cancel; returns their number."""
        close = np.zeros(len(self.gap), dtype=bool)
        close_in_region = np.zeros(len(self.gap), dtype=bool)
        for along, offset, offset_sq in terms.values():
            rest = in_span_rest(self.inside_span, along, offset)
            close |= self.gap + np.einsum("ij,ij->i", rest, rest) <= EXPLICIT_BELOW * (self.squares + offset_sq)
            if self.inside is not None:
                part = self.region_error(rest)
                close_in_region |= part <= EXPLICIT_BELOW * (self.region_squares + float(offset @ self.gram @ offset))
        # only where the distances cancel, so that the region's terms leave the rest of the pass as it was
        close &= ~self.exact
        if self.inside is not None:
            close_in_region &= ~self.region_exact
        needed = close | close_in_region
        if not needed.any():
            return 0
        for rows, chunk in frame_chunks(frames, chunk_size, wanted=needed):  # on disk, only the chunks needed
            explicit = np.flatnonzero(needed[rows])
            at = rows.start + explicit
            residual = chunk[explicit]
            residual -= self.inside_span[at] @ self.span.T
            exact = np.einsum("ij,ij->i", residual, residual)
            self.gap[at] = np.where(close[at], exact, self.gap[at])
            if self.inside is not None:
                residual *= self.inside
                self.region_gap[at] = np.where(
                    close_in_region[at], np.einsum("ij,ij->i", residual, residual), self.region_gap[at]
                )
                self.region_cross[at] = np.where(
                    close_in_region[at][:, None], residual @ self.span, self.region_cross[at]
                )
        self.exact |= close
        if self.inside is not None:
            self.region_exact |= close_in_region
        return int(needed.sum())

    def region_error(self, rest: np.ndarray) -> np.ndarray:
        """``|d_W,R + W_R c|^2`` of each frame for residual coordinates ``c`` in ``W``, shape (n_frames, w)."""
        return (
            self.region_gap
            + 2.0 * np.einsum("ij,ij->i", rest, self.region_cross)
            + np.einsum("ij,ij->i", rest @ self.gram, rest)
        )

    def projections(self, terms: Mapping[str, tuple], n_explicit: int) -> FrameProjections:
        """Every subspace's coordinates, distances and region terms: ``q = A^T (p - b)`` and, for the residual
        ``d = d_W + W c``, ``|d|^2 = |d_W|^2 + |c|^2``; over the region ``|d_W,R + W_R c|^2`` and
        ``U_R^T d_R = A^T (W_R^T d_W,R + W_R^T W_R c)``."""
        coordinates, distance_sq = {}, {}
        region = None if self.inside is None else RegionProjections({}, {}, {})
        gap = np.maximum(self.gap, 0.0)
        for label, (along, offset, _) in terms.items():
            rest = in_span_rest(self.inside_span, along, offset)
            coordinates[label] = (self.inside_span - offset) @ along
            distance_sq[label] = gap + np.einsum("ij,ij->i", rest, rest)
            if region is not None:
                region.distance_sq[label] = np.maximum(self.region_error(rest), 0.0)
                region.cross[label] = (self.region_cross + rest @ self.gram) @ along
                region.gram[label] = along.T @ self.gram @ along
        return FrameProjections(
            coordinates=coordinates,
            distance_sq=distance_sq,
            displacement_sq=self.squares.copy(),
            position_sq=np.maximum(self.squares + 2.0 * self.neutral_dot + self.neutral @ self.neutral, 0.0),
            n_explicit=n_explicit,
            region=region,
        )


def _runs(inside: np.ndarray) -> np.ndarray:
    """``(start, stop)`` of each run of True in a boolean vector, shape (n_runs, 2): a region's squares summed over
    slices are faster than a weighted sum over every coordinate."""
    return np.flatnonzero(np.diff(np.concatenate([[0], inside.astype(np.int8), [0]]))).reshape(-1, 2)


def subspace_in_span(subspace: Subspace, span: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """A subspace ``offset + span(U)`` inside ``span(W)``, as ``U = W A`` and ``offset = W b``.

    Returns
    -------
    along : ndarray of shape (w, k)
        ``A = W^T U``.
    offset : ndarray of shape (w,)
        ``b = W^T offset`` (zeros for a linear subspace).
    offset_sq : float
        ``|offset|^2``.
    """
    if subspace.offset is None:
        return span.T @ subspace.columns, np.zeros(span.shape[1]), 0.0
    offset = np.asarray(subspace.offset, dtype=float)
    return span.T @ subspace.columns, span.T @ offset, float(offset @ offset)


def in_span_rest(inside_span: np.ndarray, along: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """``c = p - b - A A^T (p - b)``: the coordinates in ``W`` of each frame's residual from ``offset + span(U)``,
    of shape (n_frames, w), for ``p`` of shape (n_frames, w)."""
    centred = inside_span - offset
    return centred - (centred @ along) @ along.T


def project_onto_each(
    frames,
    subspaces: Mapping[str, Subspace],
    neutral: np.ndarray,
    *,
    chunk_size: int | None = None,
    region: np.ndarray | None = None,
) -> FrameProjections:
    """:func:`project_frames` (same parameters and return) with every subspace's own columns in the product: the
    pass itself, which :func:`project_frames` makes onto the joint span when that is narrower."""
    n_frames, n_dims = frames.shape
    labels = list(subspaces)
    columns = [subspaces[label].columns for label in labels]
    offsets = [
        np.zeros(n_dims) if subspaces[label].offset is None else np.asarray(subspaces[label].offset, float)
        for label in labels
    ]
    # One matrix product per chunk: every subspace's columns, then every offset and the neutral positions (then the
    # same columns and offsets zero outside the region).
    widths = [basis.shape[1] for basis in columns]
    stops = np.cumsum(widths)
    blocks = columns + [np.column_stack(offsets + [neutral])]
    if region is not None:
        inside = np.asarray(region, dtype=bool)
        masked = [np.where(inside[:, None], basis, 0.0) for basis in columns]
        masked_offsets = [np.where(inside, offset, 0.0) for offset in offsets]
        blocks += masked + [np.column_stack(masked_offsets)]
        first_masked = int(stops[-1]) + len(labels) + 1
        region_columns = [basis[inside] for basis in columns]
        region_gram = [basis.T @ basis for basis in region_columns]
        region_offset_coordinates = [offset @ basis for offset, basis in zip(masked_offsets, masked)]
        region_offset_sq = [float(offset @ offset) for offset in masked_offsets]
        inside_weight = inside.astype(float)
        region_distance = {label: np.empty(n_frames) for label in labels}
        region_cross = {label: np.empty((n_frames, width)) for label, width in zip(labels, widths)}
    together = np.hstack(blocks)
    offset_coordinates = [offset @ basis for offset, basis in zip(offsets, columns)]
    offset_sq = [float(offset @ offset) for offset in offsets]
    coordinates = {label: np.empty((n_frames, width)) for label, width in zip(labels, widths)}
    distance_sq = {label: np.empty(n_frames) for label in labels}
    displacement_sq, neutral_dot = np.empty(n_frames), np.empty(n_frames)
    n_explicit = 0
    for rows, chunk in frame_chunks(frames, chunk_size):
        products = chunk @ together
        squares = np.einsum("ij,ij->i", chunk, chunk)
        if region is not None:
            region_squares = np.einsum("ij,ij,j->i", chunk, chunk, inside_weight)
        displacement_sq[rows], neutral_dot[rows] = squares, products[:, stops[-1] + len(labels)]
        for index, label in enumerate(labels):
            q = products[:, stops[index] - widths[index] : stops[index]] - offset_coordinates[index]
            scale = squares + offset_sq[index]
            distance = squares - 2.0 * products[:, stops[-1] + index] + offset_sq[index] - np.einsum("ij,ij->i", q, q)
            close = distance <= EXPLICIT_BELOW * scale
            if region is not None:
                start = first_masked + int(stops[index]) - widths[index]
                along = products[:, start : start + widths[index]] - region_offset_coordinates[index]  # U_R^T (y-o)_R
                region_scale = region_squares + region_offset_sq[index]
                part = (
                    region_squares
                    - 2.0 * products[:, first_masked + int(stops[-1]) + index]
                    + region_offset_sq[index]
                    - 2.0 * np.einsum("ij,ij->i", q, along)
                    + np.einsum("ij,ij->i", q @ region_gram[index], q)
                )
                cross = along - q @ region_gram[index]
                explicit = np.flatnonzero(close | (part <= EXPLICIT_BELOW * region_scale))
            else:
                explicit = np.flatnonzero(close)
            if explicit.size:
                residual = chunk[explicit] - offsets[index] - q[explicit] @ columns[index].T
                exact = np.einsum("ij,ij->i", residual, residual)
                distance[close] = exact[close[explicit]]
                n_explicit += int(close.sum())
                if region is not None:
                    residual = residual[:, inside]
                    part[explicit] = np.einsum("ij,ij->i", residual, residual)
                    cross[explicit] = residual @ region_columns[index]
            coordinates[label][rows], distance_sq[label][rows] = q, np.maximum(distance, 0.0)
            if region is not None:
                region_distance[label][rows], region_cross[label][rows] = np.maximum(part, 0.0), cross
    position_sq = np.maximum(displacement_sq + 2.0 * neutral_dot + neutral @ neutral, 0.0)
    return FrameProjections(
        coordinates=coordinates,
        distance_sq=distance_sq,
        displacement_sq=displacement_sq,
        position_sq=position_sq,
        n_explicit=n_explicit,
        region=(
            None if region is None else RegionProjections(region_distance, region_cross, dict(zip(labels, region_gram)))
        ),
    )
