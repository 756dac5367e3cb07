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

from workbench.errors import WorkbenchError

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
        self.gltf.bufferViews.append(pygltflib.BufferView(buffer=0, byteOffset=self.length,
                                                          byteLength=data.nbytes, target=target))
        flat = data.reshape(-1, COMPONENTS[kind])
        self.gltf.accessors.append(pygltflib.Accessor(
            bufferView=len(self.gltf.bufferViews) - 1, componentType=component, count=len(flat), type=kind,
            min=flat.min(axis=0).tolist() if bounds else None, max=flat.max(axis=0).tolist() if bounds else None))
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
    position = chunk.add((mesh.neutral * metres).astype(np.float32), "VEC3", target=pygltflib.ARRAY_BUFFER,
                         bounds=True)
    indices = chunk.add(mesh.triangles.astype(np.uint32).reshape(-1), "SCALAR",
                        target=pygltflib.ELEMENT_ARRAY_BUFFER)
    targets = [pygltflib.Attributes(POSITION=chunk.add((delta * metres).astype(np.float32), "VEC3",
                                                       target=pygltflib.ARRAY_BUFFER, bounds=True))
               for delta in mesh.deltas]
    gltf.meshes.append(pygltflib.Mesh(
        name=mesh_name, weights=[0.0] * len(targets), extras={"targetNames": list(mesh.names), **mesh.mesh_extras},
        primitives=[pygltflib.Primitive(attributes=pygltflib.Attributes(POSITION=position), indices=indices,
                                        targets=targets, mode=pygltflib.TRIANGLES)]))
    gltf.nodes.append(pygltflib.Node(name=mesh_name, mesh=0))
    gltf.scenes.append(pygltflib.Scene(nodes=[0]))
    gltf.scene = 0
    for animation in mesh.animations:
        times = chunk.add(np.asarray(animation.seconds, dtype=np.float32), "SCALAR", bounds=True)
        values = chunk.add(np.asarray(animation.weights, dtype=np.float32).reshape(-1), "SCALAR")
        gltf.animations.append(pygltflib.Animation(
            name=animation.name, extras=dict(animation.extras) or None,
            samplers=[pygltflib.AnimationSampler(input=times, output=values, interpolation=pygltflib.ANIM_LINEAR)],
            channels=[pygltflib.AnimationChannel(sampler=0, target=pygltflib.AnimationChannelTarget(
                node=0, path="weights"))]))
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
        raise WorkbenchError(f"morph targets must have shape ({len(mesh.names)}, {n_vertices}, 3) for "
                             f"{len(mesh.names)} names, got {mesh.deltas.shape}")
    if mesh.triangles.ndim != 2 or mesh.triangles.shape[1] != 3 or not len(mesh.triangles):
        raise WorkbenchError(f"mesh triangles must have shape (n_triangles >= 1, 3), got {mesh.triangles.shape}")
    if mesh.triangles.min() < 0 or mesh.triangles.max() >= n_vertices:
        raise WorkbenchError(f"mesh triangles refer to vertices outside [0, {n_vertices})")
    for animation in mesh.animations:
        seconds = np.asarray(animation.seconds, dtype=np.float32)  # as the file holds them
        increasing = len(seconds) > 0 and seconds[0] >= 0 and np.all(np.diff(seconds) > 0)
        if animation.weights.shape != (len(seconds), len(mesh.names)) or not increasing:
            raise WorkbenchError(f"animation {animation.name!r}: needs increasing times from 0 on (as float32) and "
                                 f"weights of shape ({len(seconds)}, {len(mesh.names)}), got "
                                 f"{animation.weights.shape}")
    arrays = [mesh.neutral, mesh.deltas] + [a.weights for a in mesh.animations]
    if not all(np.all(np.isfinite(array)) for array in arrays):
        raise WorkbenchError("mesh positions, morph targets and animation weights must be finite (no NaN/Inf)")


def _accessor_array(gltf, blob: bytes, index: int, path: Path) -> np.ndarray:
    """The values of accessor ``index`` as float64 (or int64 for indices), shape (count, components)."""
    accessor = gltf.accessors[index]
    width = COMPONENTS.get(accessor.type)
    dtype = {FLOAT32: np.float32, **INDEX_TYPES}.get(accessor.componentType)
    if width is None or dtype is None or (dtype is not np.float32 and width != 1) or accessor.normalized:
        raise WorkbenchError(f"{path}: accessor {index} is {accessor.type} of component type "
                             f"{accessor.componentType}{' (normalized)' if accessor.normalized else ''}; the workbench "
                             "reads float32 positions, weights and times, and unsigned integer indices (quantized "
                             "meshes: export without quantization)")
    values = np.zeros((accessor.count, width), dtype=np.float64)
    if accessor.bufferView is not None:
        values[:] = _view_values(gltf, blob, accessor.bufferView, accessor.byteOffset or 0, accessor.count, dtype,
                                 width, path)
    if accessor.sparse is not None:  # targets that move few vertices are often stored sparse
        sparse = accessor.sparse
        rows = _view_values(gltf, blob, sparse.indices.bufferView, sparse.indices.byteOffset or 0, sparse.count,
                            INDEX_TYPES[sparse.indices.componentType], 1, path)[:, 0].astype(np.int64)
        values[rows] = _view_values(gltf, blob, sparse.values.bufferView, sparse.values.byteOffset or 0,
                                    sparse.count, dtype, width, path)
    return values


def _view_values(gltf, blob: bytes, view_index: int, offset: int, count: int, dtype, width: int,
                 path: Path) -> np.ndarray:
    view = gltf.bufferViews[view_index]
    item = np.dtype(dtype).itemsize * width
    stride = view.byteStride or item
    start = (view.byteOffset or 0) + offset
    end = start + stride * (count - 1) + item if count else start
    if view.buffer != 0 or end > len(blob) or end > (view.byteOffset or 0) + view.byteLength:
        raise WorkbenchError(f"{path}: buffer view {view_index} reaches past the binary data (or lies in an "
                             "external buffer); the workbench reads self-contained .glb files")
    raw = np.frombuffer(blob, dtype=np.uint8, count=end - start, offset=start)
    if stride != item:
        raw = np.lib.stride_tricks.as_strided(raw, shape=(count, item), strides=(stride, 1)).copy()
    return np.frombuffer(raw.tobytes(), dtype=dtype).reshape(count, width).astype(np.float64)


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
        In millimetres. The primitives of the mesh are concatenated in order (vertices and triangles), each
        needing the same morph targets.

    Raises
    ------
    WorkbenchError
        If the file is missing or not binary glTF 2.0, has no (or several, without ``mesh_name``) meshes with
        morph targets, or stores positions in a form other than float32 triangles.
    """
    import pygltflib

    path = Path(path)
    if not path.is_file():
        raise WorkbenchError(f"{path}: glTF file not found")
    if path.read_bytes()[:4] != b"glTF":
        raise WorkbenchError(f"{path}: not a binary glTF file (.glb starts with 'glTF'); convert a .gltf with "
                             "external buffers to .glb first")
    try:
        gltf = pygltflib.GLTF2.load_binary(str(path))
    except Exception as error:  # the reader raises many kinds of error on a damaged file
        raise WorkbenchError(f"{path}: not a readable glTF file ({type(error).__name__}: {error})") from None
    if not str(gltf.asset.version).startswith("2."):
        raise WorkbenchError(f"{path}: glTF version {gltf.asset.version}; the workbench reads glTF 2.0")
    blob = gltf.binary_blob() or b""
    candidates = [i for i, mesh in enumerate(gltf.meshes) if any(p.targets for p in mesh.primitives)]
    if mesh_name is not None:
        candidates = [i for i in candidates if gltf.meshes[i].name == mesh_name]
    if len(candidates) != 1:
        named = [gltf.meshes[i].name for i, mesh in enumerate(gltf.meshes) if any(p.targets for p in mesh.primitives)]
        raise WorkbenchError(f"{path}: {len(candidates)} meshes with morph targets"
                             f"{f' named {mesh_name!r}' if mesh_name is not None else ''}; the file's are {named} "
                             "(name one with mesh_name)")
    mesh = gltf.meshes[candidates[0]]
    n_targets = len(mesh.primitives[0].targets)
    neutral, deltas, triangles, offset = [], [], [], 0
    for number, primitive in enumerate(mesh.primitives):
        if primitive.mode not in (None, pygltflib.TRIANGLES) or len(primitive.targets) != n_targets:
            raise WorkbenchError(f"{path}: mesh {mesh.name!r} primitive {number}: needs triangles (mode 4) and the "
                                 f"same {n_targets} morph targets as primitive 0")
        positions = _accessor_array(gltf, blob, primitive.attributes.POSITION, path)
        count = len(positions)
        index = (np.arange(count) if primitive.indices is None
                 else _accessor_array(gltf, blob, primitive.indices, path)[:, 0].astype(np.int64))
        if len(index) % 3 or (len(index) and (index.min() < 0 or index.max() >= count)):
            raise WorkbenchError(f"{path}: mesh {mesh.name!r} primitive {number}: indices are not triangles over its "
                                 f"{count} vertices")
        neutral.append(positions)
        # pygltflib loads morph targets as plain dicts
        moved = [target.get("POSITION") if isinstance(target, dict) else target.POSITION
                 for target in primitive.targets]
        deltas.append(np.stack([np.zeros((count, 3)) if accessor is None
                                else _accessor_array(gltf, blob, accessor, path) for accessor in moved]))
        triangles.append(index.reshape(-1, 3) + offset)
        offset += count
    names = (mesh.extras or {}).get("targetNames") or [f"target_{i + 1:02d}" for i in range(n_targets)]
    if len(names) != n_targets or len(set(names)) != len(names):
        raise WorkbenchError(f"{path}: mesh {mesh.name!r}: extras.targetNames must name its {n_targets} morph "
                             f"targets once each, got {names}")
    return MorphMesh(neutral=np.concatenate(neutral) * MM_PER_METRE, triangles=np.concatenate(triangles),
                     names=tuple(str(name) for name in names), deltas=np.concatenate(deltas, axis=1) * MM_PER_METRE,
                     animations=_morph_animations(gltf, blob, candidates[0], n_targets, path), path=path,
                     extras=dict(gltf.asset.extras or {}))


def _morph_animations(gltf, blob: bytes, mesh_index: int, n_targets: int, path: Path) -> tuple:
    """The morph-weight animations of the nodes that show mesh ``mesh_index``."""
    nodes = {i for i, node in enumerate(gltf.nodes) if node.mesh == mesh_index}
    found = []
    for animation in gltf.animations:
        for channel in animation.channels:
            if channel.target.node in nodes and channel.target.path == "weights":
                sampler = animation.samplers[channel.sampler]
                seconds = _accessor_array(gltf, blob, sampler.input, path)[:, 0]
                values = _accessor_array(gltf, blob, sampler.output, path)[:, 0]
                if sampler.interpolation == "CUBICSPLINE" or values.size != seconds.size * n_targets:
                    raise WorkbenchError(f"{path}: animation {animation.name!r}: {values.size} weights for "
                                         f"{seconds.size} keys of {n_targets} targets ({sampler.interpolation}); "
                                         "the workbench reads LINEAR or STEP keys, one weight per target")
                found.append(MorphAnimation(name=animation.name or f"animation_{len(found) + 1}", seconds=seconds,
                                            weights=values.reshape(seconds.size, n_targets)))
    return tuple(found)
