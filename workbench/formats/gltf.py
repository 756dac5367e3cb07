"""glTF 2.0 meshes with morph targets and morph-weight animations, written and read with pygltflib.

glTF lengths are metres; the workbench's are millimetres, converted on the way in and out. glTF's axes are +Y up
with the asset's front towards +Z, which is how ICT FaceKit and the synthetic actor already lie, so coordinates
are written as they are. Morph target names go where Blender, three.js and most engines look for them:
``mesh.extras.targetNames``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from workbench.core.errors import WorkbenchError
from workbench.core.files import input_path

MM_PER_METRE = 1000.0
FLOAT32, UINT8, UINT16, UINT32 = 5126, 5121, 5123, 5125
COMPONENTS = {"SCALAR": 1, "VEC3": 3}
INDEX_TYPES = {UINT8: np.uint8, UINT16: np.uint16, UINT32: np.uint32}


@dataclass(frozen=True)
class MorphAnimation:
    """Morph-target weights over time, one glTF animation.

    Attributes
    ----------
    name : str
    seconds : ndarray of shape (n_frames,)
        Key times, increasing.
    weights : ndarray of shape (n_frames, n_targets)
        Weight of every morph target at every key.
    extras : dict
        The animation's ``extras`` (facts about it: its take, frame rate).
    """

    name: str
    seconds: np.ndarray
    weights: np.ndarray
    extras: dict = field(default_factory=dict)


@dataclass(frozen=True)
class MorphMesh:
    """A mesh with named morph targets (and any morph-weight animations), in millimetres.

    Attributes
    ----------
    neutral : ndarray of shape (n_vertices, 3)
    triangles : ndarray of shape (n_triangles, 3) of int
    names : tuple of str
        One per morph target.
    deltas : ndarray of shape (n_targets, n_vertices, 3)
        Displacement of every vertex by each morph target at weight 1.
    animations : tuple of MorphAnimation
    path : pathlib.Path or None
        The file read (None for a mesh being written).
    extras : dict
        ``asset.extras``: facts about the file (units, axes, where it came from).
    mesh_extras : dict
        More of the mesh's ``extras`` beside ``targetNames`` (written, not read back).
    """

    neutral: np.ndarray
    triangles: np.ndarray
    names: tuple[str, ...]
    deltas: np.ndarray
    animations: tuple[MorphAnimation, ...] = ()
    path: Path | None = None
    extras: dict = field(default_factory=dict)
    mesh_extras: dict = field(default_factory=dict)


class _BinaryChunk:
    """The GLB binary chunk being built: arrays appended 4-byte aligned, one buffer view and accessor each."""

    def __init__(self, gltf):
        self.gltf, self.parts, self.length = gltf, [], 0

    def add(self, array: np.ndarray, kind: str, *, target: int | None = None, bounds: bool = False) -> int:
        import pygltflib

        data = np.ascontiguousarray(array)
        component = {np.dtype(np.float32): FLOAT32, np.dtype(np.uint32): UINT32}[data.dtype]
        self.gltf.bufferViews.append(
            pygltflib.BufferView(buffer=0, byteOffset=self.length, byteLength=data.nbytes, target=target)
        )
        flat = data.reshape(-1, COMPONENTS[kind])
        self.gltf.accessors.append(
            pygltflib.Accessor(
                bufferView=len(self.gltf.bufferViews) - 1,
                componentType=component,
                count=len(flat),
                type=kind,
                min=flat.min(axis=0).tolist() if bounds else None,
                max=flat.max(axis=0).tolist() if bounds else None,
            )
        )
        padding = -data.nbytes % 4
        self.parts.append(data.tobytes() + b"\0" * padding)
        self.length += data.nbytes + padding
        return len(self.gltf.accessors) - 1

    def blob(self) -> bytes:
        return b"".join(self.parts)


def glb_bytes(mesh: MorphMesh, *, mesh_name: str = "face", generator: str = "quasi-eigen workbench") -> bytes:
    """A binary glTF 2.0 file (``.glb``) holding one mesh, its morph targets and their animations.

    Parameters
    ----------
    mesh : MorphMesh
        In millimetres; written in metres as float32 (glTF's lengths and precision).
    mesh_name : str
        Name of the mesh and of its node.
    generator : str
        ``asset.generator``.

    Returns
    -------
    bytes
    """
    import pygltflib

    check_morph_mesh(mesh)
    gltf = pygltflib.GLTF2(asset=pygltflib.Asset(generator=generator, extras=dict(mesh.extras)))
    chunk = _BinaryChunk(gltf)
    metres = 1.0 / MM_PER_METRE
    position = chunk.add((mesh.neutral * metres).astype(np.float32), "VEC3", target=pygltflib.ARRAY_BUFFER, bounds=True)
    indices = chunk.add(mesh.triangles.astype(np.uint32).reshape(-1), "SCALAR", target=pygltflib.ELEMENT_ARRAY_BUFFER)
    targets = [
        pygltflib.Attributes(
            POSITION=chunk.add((delta * metres).astype(np.float32), "VEC3", target=pygltflib.ARRAY_BUFFER, bounds=True)
        )
        for delta in mesh.deltas
    ]
    gltf.meshes.append(
        pygltflib.Mesh(
            name=mesh_name,
            weights=[0.0] * len(targets),
            extras={"targetNames": list(mesh.names), **mesh.mesh_extras},
            primitives=[
                pygltflib.Primitive(
                    attributes=pygltflib.Attributes(POSITION=position),
                    indices=indices,
                    targets=targets,
                    mode=pygltflib.TRIANGLES,
                )
            ],
        )
    )
    gltf.nodes.append(pygltflib.Node(name=mesh_name, mesh=0))
    gltf.scenes.append(pygltflib.Scene(nodes=[0]))
    gltf.scene = 0
    for animation in mesh.animations:
        times = chunk.add(np.asarray(animation.seconds, dtype=np.float32), "SCALAR", bounds=True)
        values = chunk.add(np.asarray(animation.weights, dtype=np.float32).reshape(-1), "SCALAR")
        gltf.animations.append(
            pygltflib.Animation(
                name=animation.name,
                extras=dict(animation.extras) or None,
                samplers=[pygltflib.AnimationSampler(input=times, output=values, interpolation=pygltflib.ANIM_LINEAR)],
                channels=[
                    pygltflib.AnimationChannel(
                        sampler=0, target=pygltflib.AnimationChannelTarget(node=0, path="weights")
                    )
                ],
            )
        )
    blob = chunk.blob()
    gltf.buffers.append(pygltflib.Buffer(byteLength=len(blob)))
    gltf.set_binary_blob(blob)
    return b"".join(gltf.save_to_bytes())


def check_morph_mesh(mesh: MorphMesh) -> None:
    """Raise a :class:`WorkbenchError` unless the arrays of ``mesh`` fit together and are finite."""
    n_vertices = len(mesh.neutral)
    if mesh.neutral.ndim != 2 or mesh.neutral.shape[1] != 3 or n_vertices < 3:
        raise WorkbenchError(f"mesh neutral must have shape (n_vertices >= 3, 3), got {mesh.neutral.shape}")
    if mesh.deltas.shape != (len(mesh.names), n_vertices, 3):
        raise WorkbenchError(
            f"morph targets must have shape ({len(mesh.names)}, {n_vertices}, 3) for "
            f"{len(mesh.names)} names, got {mesh.deltas.shape}"
        )
    if mesh.triangles.ndim != 2 or mesh.triangles.shape[1] != 3 or not len(mesh.triangles):
        raise WorkbenchError(f"mesh triangles must have shape (n_triangles >= 1, 3), got {mesh.triangles.shape}")
    if mesh.triangles.min() < 0 or mesh.triangles.max() >= n_vertices:
        raise WorkbenchError(f"mesh triangles refer to vertices outside [0, {n_vertices})")
    for animation in mesh.animations:
        seconds = np.asarray(animation.seconds, dtype=np.float32)  # as the file holds them
        increasing = len(seconds) > 0 and seconds[0] >= 0 and np.all(np.diff(seconds) > 0)
        if animation.weights.shape != (len(seconds), len(mesh.names)) or not increasing:
            raise WorkbenchError(
                f"animation {animation.name!r}: needs increasing times from 0 on (as float32) and "
                f"weights of shape ({len(seconds)}, {len(mesh.names)}), got "
                f"{animation.weights.shape}"
            )
    arrays = [mesh.neutral, mesh.deltas] + [a.weights for a in mesh.animations]
    if not all(np.all(np.isfinite(array)) for array in arrays):
        raise WorkbenchError("mesh positions, morph targets and animation weights must be finite (no NaN/Inf)")


MAX_ELEMENTS = 100_000_000
"""Most elements an accessor may declare (a count beyond it is a damaged file, not a face)."""


def _get(item, name: str):
    """A field of a glTF object, which pygltflib gives as a dataclass or (morph targets, extras) a plain dict."""
    return item.get(name) if isinstance(item, dict) else getattr(item, name, None)


def _whole(value, what: str, path: Path, *, minimum: int = 0, maximum: int | None = None) -> int:
    """A whole-number field of the file, checked (pygltflib passes whatever the JSON holds)."""
    if (
        isinstance(value, bool)
        or not isinstance(value, int)
        or value < minimum
        or (maximum is not None and value > maximum)
    ):
        bound = f"in [{minimum}, {maximum}]" if maximum is not None else f">= {minimum}"
        raise WorkbenchError(f"{path}: {what} must be an integer {bound}, got {value!r}")
    return value


def _entry(items, index, what: str, path: Path):
    """``items[index]`` of one of the file's arrays (accessors, buffer views, samplers), or a one-line error when
    the index is not one of them."""
    items = items or []
    if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(items):
        raise WorkbenchError(f"{path}: {what} {index!r} does not exist (the file has {len(items)})")
    return items[index]


ACCESSOR_KINDS = {
    "positions": ("VEC3", (FLOAT32,)),
    "scalars": ("SCALAR", (FLOAT32,)),
    "indices": ("SCALAR", tuple(INDEX_TYPES)),
}
"""What the workbench reads -> the accessor type and component types it takes: float32 positions, weights and
times, unsigned integer indices."""


def _accessor_array(gltf, blob: bytes, index: int, path: Path, kind: str) -> np.ndarray:
    """The values of accessor ``index`` as float64 (indices as int64), shape (count, components), checked: the
    accessor, its buffer views and its sparse part must exist, fit in the binary data and be of ``kind``
    (:data:`ACCESSOR_KINDS`); values must be finite, sparse indices inside the accessor."""
    accessor = _entry(gltf.accessors, index, "accessor", path)
    what = f"accessor {index}"
    expected_type, components = ACCESSOR_KINDS[kind]
    dtype = {FLOAT32: np.float32, **INDEX_TYPES}.get(accessor.componentType)
    if accessor.type != expected_type or accessor.componentType not in components or accessor.normalized:
        raise WorkbenchError(
            f"{path}: {what} is {accessor.type} of component type "
            f"{accessor.componentType}{' (normalized)' if accessor.normalized else ''}, but holds "
            f"{kind}; the workbench reads float32 positions, weights and times, and unsigned integer "
            "indices (quantized meshes: export without quantization)"
        )
    width = COMPONENTS[accessor.type]
    count = _whole(accessor.count, f"{what} count", path, maximum=MAX_ELEMENTS)
    values = np.zeros((count, width), dtype=np.float64)
    if accessor.bufferView is not None:
        values[:] = _view_values(
            gltf,
            blob,
            accessor.bufferView,
            _whole(accessor.byteOffset or 0, f"{what} byteOffset", path),
            count,
            dtype,
            width,
            path,
        )
    if accessor.sparse is not None:  # targets that move few vertices are often stored sparse
        sparse = accessor.sparse
        n_sparse = _whole(sparse.count, f"{what} sparse count", path, minimum=1, maximum=count)
        index_type = INDEX_TYPES.get(sparse.indices.componentType)
        if index_type is None:
            raise WorkbenchError(
                f"{path}: {what} sparse indices have component type {sparse.indices.componentType}; "
                "they must be unsigned integers (5121, 5123 or 5125)"
            )
        rows = _view_values(
            gltf,
            blob,
            sparse.indices.bufferView,
            _whole(sparse.indices.byteOffset or 0, f"{what} sparse indices byteOffset", path),
            n_sparse,
            index_type,
            1,
            path,
        )[:, 0]
        if rows.max() >= count or np.any(np.diff(rows) <= 0):
            raise WorkbenchError(
                f"{path}: {what} sparse indices must increase and stay below its {count} elements, "
                f"got {rows.min():.0f} to {rows.max():.0f}"
            )
        values[rows.astype(np.int64)] = _view_values(
            gltf,
            blob,
            sparse.values.bufferView,
            _whole(sparse.values.byteOffset or 0, f"{what} sparse values byteOffset", path),
            n_sparse,
            dtype,
            width,
            path,
        )
    if not np.all(np.isfinite(values)):
        bad = int(np.argmax(~np.all(np.isfinite(values), axis=1)))
        raise WorkbenchError(f"{path}: {what} element {bad} holds NaN or Inf ({kind})")
    return values.astype(np.int64) if kind == "indices" else values


def _view_values(
    gltf, blob: bytes, view_index: int, offset: int, count: int, dtype, width: int, path: Path
) -> np.ndarray:
    view = _entry(gltf.bufferViews, view_index, "buffer view", path)
    item = np.dtype(dtype).itemsize * width
    stride = _whole(view.byteStride or item, f"buffer view {view_index} byteStride", path, minimum=item)
    view_start = _whole(view.byteOffset or 0, f"buffer view {view_index} byteOffset", path)
    start = view_start + offset
    end = start + stride * (count - 1) + item if count else start
    if (
        view.buffer != 0
        or end > len(blob)
        or end > view_start + _whole(view.byteLength, f"buffer view {view_index} byteLength", path)
    ):
        raise WorkbenchError(
            f"{path}: buffer view {view_index} reaches past the binary data (or lies in an "
            "external buffer); the workbench reads self-contained .glb files"
        )
    raw = np.frombuffer(blob, dtype=np.uint8, count=end - start, offset=start)
    if stride != item:
        raw = np.lib.stride_tricks.as_strided(raw, shape=(count, item), strides=(stride, 1)).copy()
    return np.frombuffer(raw.tobytes(), dtype=dtype).reshape(count, width).astype(np.float64)


def _check_buffer_views(gltf, blob: bytes, path: Path) -> None:
    """Every buffer view of the binary chunk (buffer 0) lies inside it: a view claiming more bytes than the file
    holds is a damaged file even where no accessor reads past the data."""
    for index, view in enumerate(gltf.bufferViews or []):
        if view.buffer != 0:
            continue  # an external buffer: refused where it is read (_view_values)
        start = _whole(view.byteOffset or 0, f"buffer view {index} byteOffset", path)
        length = _whole(view.byteLength, f"buffer view {index} byteLength", path, minimum=1)
        if start + length > len(blob):
            raise WorkbenchError(
                f"{path}: buffer view {index} reaches past the binary data: it claims bytes "
                f"{start} to {start + length} of a {len(blob)}-byte binary chunk (a truncated or "
                "damaged file)"
            )


def _load_gltf(path: Path):
    """The file parsed by pygltflib, its warnings kept out of the output (a problem it only warns about is
    refused below with the file named, or does not matter to what the workbench reads)."""
    import warnings

    import pygltflib

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return pygltflib.GLTF2.load_binary(str(path))
    except Exception as error:  # the reader raises many kinds of error on a damaged file
        reason = str(error).splitlines()[0] if str(error) else ""
        raise WorkbenchError(f"{path}: not a readable glTF file ({type(error).__name__}: {reason})") from None


def read_morph_mesh(path: str | os.PathLike, *, mesh_name: str | None = None) -> MorphMesh:
    """Read a mesh's morph targets (and its morph-weight animations) from a binary glTF 2.0 file.

    Parameters
    ----------
    path : path-like
        A ``.glb`` file.
    mesh_name : str, optional
        The mesh to read; when None, the file's only mesh with morph targets.

    Returns
    -------
    MorphMesh
        In millimetres: ``neutral`` of shape (n_vertices, 3), ``triangles``, ``names``, ``deltas`` of shape
        (n_targets, n_vertices, 3), ``animations``. The primitives of the mesh are concatenated in order (vertices and triangles), each
        needing the same morph targets.

    Raises
    ------
    WorkbenchError
        Naming the file and the part at fault: the file is missing or not binary glTF 2.0; it has no (or several,
        without ``mesh_name``) meshes with morph targets; an index names no accessor, buffer view or sampler; data
        reach past the binary chunk; positions are not float32 triangles or indices not unsigned integers;
        a value is NaN or Inf, a vertex lies far outside the face (:func:`~workbench.formats.plausibility.
        mesh_outlier_problems`), or key times do not increase.
    """
    import pygltflib

    path = input_path(path, "glTF file")
    with open(path, "rb") as stream:
        if stream.read(4) != b"glTF":
            raise WorkbenchError(
                f"{path}: not a binary glTF file (.glb starts with 'glTF'); convert a .gltf with "
                "external buffers to .glb first"
            )
    gltf = _load_gltf(path)
    if not str(_get(gltf.asset, "version")).startswith("2."):
        raise WorkbenchError(f"{path}: glTF version {_get(gltf.asset, 'version')}; the workbench reads glTF 2.0")
    blob = gltf.binary_blob() or b""
    _check_buffer_views(gltf, blob, path)
    chosen = _morph_mesh_index(gltf, mesh_name, path)
    mesh = gltf.meshes[chosen]
    n_targets = len(mesh.primitives[0].targets)
    neutral, deltas, triangles, offset = [], [], [], 0
    for number, primitive in enumerate(mesh.primitives):
        where = f"mesh {mesh.name!r} primitive {number}"
        if primitive.mode not in (None, pygltflib.TRIANGLES) or len(primitive.targets) != n_targets:
            raise WorkbenchError(
                f"{path}: {where}: needs triangles (mode 4) and the same {n_targets} morph targets as primitive 0"
            )
        if _get(primitive.attributes, "POSITION") is None:
            raise WorkbenchError(f"{path}: {where} has no POSITION attribute (the vertices)")
        positions = _accessor_array(gltf, blob, _get(primitive.attributes, "POSITION"), path, "positions")
        count = len(positions)
        index = (
            np.arange(count)
            if primitive.indices is None
            else _accessor_array(gltf, blob, primitive.indices, path, "indices")[:, 0]
        )
        if len(index) % 3 or (len(index) and (index.min() < 0 or index.max() >= count)):
            raise WorkbenchError(f"{path}: {where}: indices are not triangles over its {count} vertices")
        neutral.append(positions)
        moved = [_get(target, "POSITION") for target in primitive.targets]
        deltas.append(
            np.stack(
                [
                    np.zeros((count, 3))
                    if accessor is None
                    else _accessor_array(gltf, blob, accessor, path, "positions")
                    for accessor in moved
                ]
            )
        )
        if any(len(delta) != count for delta in deltas[-1]):
            raise WorkbenchError(f"{path}: {where}: every morph target needs its {count} vertices")
        triangles.append(index.reshape(-1, 3) + offset)
        offset += count
    names = _get(mesh.extras or {}, "targetNames") or [f"target_{i + 1:02d}" for i in range(n_targets)]
    if (
        not isinstance(names, list)
        or len(names) != n_targets
        or len(set(map(str, names))) != len(names)
        or not all(isinstance(name, str) for name in names)
    ):
        raise WorkbenchError(
            f"{path}: mesh {mesh.name!r}: extras.targetNames must name its {n_targets} morph "
            f"targets once each, got {names!r:.100}"
        )
    result = MorphMesh(
        neutral=np.concatenate(neutral) * MM_PER_METRE,
        triangles=np.concatenate(triangles),
        names=tuple(names),
        deltas=np.concatenate(deltas, axis=1) * MM_PER_METRE,
        animations=_morph_animations(gltf, blob, chosen, n_targets, path),
        path=path,
        extras=dict(gltf.asset.extras or {}) if isinstance(gltf.asset.extras, dict) else {},
    )
    _check_plausible_shapes(result, path)
    return result


def _morph_mesh_index(gltf, mesh_name: str | None, path: Path) -> int:
    """The index of the file's one mesh with morph targets (named ``mesh_name`` if given), or a WorkbenchError
    naming the file's meshes with morph targets."""
    candidates = [i for i, mesh in enumerate(gltf.meshes) if any(p.targets for p in mesh.primitives)]
    if mesh_name is not None:
        candidates = [i for i in candidates if gltf.meshes[i].name == mesh_name]
    if len(candidates) != 1:
        named = [gltf.meshes[i].name for i, mesh in enumerate(gltf.meshes) if any(p.targets for p in mesh.primitives)]
        raise WorkbenchError(
            f"{path}: {len(candidates)} meshes with morph targets"
            f"{f' named {mesh_name!r}' if mesh_name is not None else ''}; the file's are {named} "
            "(name one with mesh_name)"
        )
    return candidates[0]


def _check_plausible_shapes(mesh: MorphMesh, path: Path) -> None:
    """Refuse a neutral or morph target with a vertex far outside the face (a coordinate of 1e6 or 1e30), as the
    OBJ reader does."""
    from workbench.formats.plausibility import mesh_outlier_problems

    problems = mesh_outlier_problems(mesh.neutral, mesh.neutral, f"{path} (neutral)", unit="mm")
    for name, delta in zip(mesh.names, mesh.deltas):
        problems += mesh_outlier_problems(
            mesh.neutral + delta, mesh.neutral, f"{path} (morph target {name})", unit="mm"
        )
    if problems:
        raise WorkbenchError(problems[0])


def _morph_animations(gltf, blob: bytes, mesh_index: int, n_targets: int, path: Path) -> tuple:
    """The morph-weight animations of the nodes that show mesh ``mesh_index``."""
    nodes = {i for i, node in enumerate(gltf.nodes) if node.mesh == mesh_index}
    found = []
    for animation in gltf.animations:
        for channel in animation.channels:
            if channel.target.node in nodes and channel.target.path == "weights":
                sampler = _entry(animation.samplers, channel.sampler, f"animation {animation.name!r} sampler", path)
                seconds = _accessor_array(gltf, blob, sampler.input, path, "scalars")[:, 0]
                values = _accessor_array(gltf, blob, sampler.output, path, "scalars")[:, 0]
                if sampler.interpolation == "CUBICSPLINE" or values.size != seconds.size * n_targets:
                    raise WorkbenchError(
                        f"{path}: animation {animation.name!r}: {values.size} weights for "
                        f"{seconds.size} keys of {n_targets} targets ({sampler.interpolation}); "
                        "the workbench reads LINEAR or STEP keys, one weight per target"
                    )
                if np.any(np.diff(seconds) <= 0):
                    key = int(np.argmax(np.diff(seconds) <= 0)) + 1
                    raise WorkbenchError(
                        f"{path}: animation {animation.name!r}: key times must increase (key {key} "
                        f"at {seconds[key]:g} s follows {seconds[key - 1]:g} s)"
                    )
                found.append(
                    MorphAnimation(
                        name=animation.name or f"animation_{len(found) + 1}",
                        seconds=seconds,
                        weights=values.reshape(seconds.size, n_targets),
                    )
                )
    return tuple(found)
