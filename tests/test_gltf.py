"""glTF morph meshes: write and read back, files from other tools (sparse morph targets, several primitives,
interleaved positions), and damaged or unsupported files."""

import numpy as np
import pytest

from workbench.errors import WorkbenchError
from workbench.gltf import MorphAnimation, MorphMesh, glb_bytes, read_morph_mesh


def small_mesh(rng):
    return MorphMesh(neutral=rng.normal(0, 50, (5, 3)), triangles=np.array([[0, 1, 2], [2, 3, 4]]),
                     names=("smile", "blink"), deltas=rng.normal(0, 2, (2, 5, 3)),
                     animations=(MorphAnimation("take", np.arange(4) / 30.0, rng.uniform(0, 1, (4, 2))),),
                     extras={"units": "metres"})


def test_write_then_read_keeps_everything_to_float32(tmp_path):
    mesh = small_mesh(np.random.default_rng(0))
    (tmp_path / "m.glb").write_bytes(glb_bytes(mesh))
    back = read_morph_mesh(tmp_path / "m.glb")
    assert back.names == mesh.names and back.extras == {"units": "metres"}
    np.testing.assert_array_equal(back.triangles, mesh.triangles)
    np.testing.assert_allclose(back.neutral, mesh.neutral, rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(back.deltas, mesh.deltas, rtol=1e-6, atol=1e-6)
    (animation,) = back.animations
    np.testing.assert_allclose(animation.weights, mesh.animations[0].weights, rtol=1e-6)
    np.testing.assert_allclose(animation.seconds, mesh.animations[0].seconds, rtol=1e-6)


def other_tool_file(path, neutral, deltas):
    """A file as other exporters write it: two primitives sharing the morph targets, interleaved positions with a
    byte stride, the second target sparse (only the vertices it moves), no targetNames."""
    import pygltflib

    parts, views, accessors = [], [], []

    def add(data, kind, component, count, stride=None):
        views.append(pygltflib.BufferView(buffer=0, byteOffset=sum(len(p) for p in parts), byteLength=len(data),
                                          byteStride=stride))
        parts.append(data + b"\0" * (-len(data) % 4))
        if kind is not None:
            accessors.append(pygltflib.Accessor(bufferView=len(views) - 1, componentType=component, count=count,
                                                type=kind, min=None, max=None))
        return len(accessors) - 1, len(views) - 1

    primitives = []
    for rows in (np.arange(3), np.arange(3, 6)):
        # interleaved: position then a dummy normal per vertex (24-byte stride)
        block = np.hstack([neutral[rows] / 1000.0, np.zeros((3, 3))]).astype(np.float32).tobytes()
        position, _ = add(block, "VEC3", pygltflib.FLOAT, 3, stride=24)
        indices, _ = add(np.array([0, 1, 2], np.uint16).tobytes(), "SCALAR", pygltflib.UNSIGNED_SHORT, 3)
        dense, _ = add((deltas[0, rows] / 1000.0).astype(np.float32).tobytes(), "VEC3", pygltflib.FLOAT, 3)
        moved = np.flatnonzero(np.any(deltas[1, rows] != 0, axis=1))
        _, index_view = add(moved.astype(np.uint8).tobytes(), None, None, 0)
        _, value_view = add((deltas[1, rows][moved] / 1000.0).astype(np.float32).tobytes(), None, None, 0)
        accessors.append(pygltflib.Accessor(
            componentType=pygltflib.FLOAT, count=3, type="VEC3",
            sparse=pygltflib.Sparse(count=len(moved), indices=pygltflib.AccessorSparseIndices(
                bufferView=index_view, componentType=pygltflib.UNSIGNED_BYTE),
                values=pygltflib.AccessorSparseValues(bufferView=value_view))))
        primitives.append(pygltflib.Primitive(attributes=pygltflib.Attributes(POSITION=position), indices=indices,
                                              targets=[pygltflib.Attributes(POSITION=dense),
                                                       pygltflib.Attributes(POSITION=len(accessors) - 1)]))
    blob = b"".join(parts)
    gltf = pygltflib.GLTF2(asset=pygltflib.Asset(version="2.0"), accessors=accessors, bufferViews=views,
                           buffers=[pygltflib.Buffer(byteLength=len(blob))],
                           meshes=[pygltflib.Mesh(name="head", primitives=primitives)],
                           nodes=[pygltflib.Node(mesh=0)], scenes=[pygltflib.Scene(nodes=[0])], scene=0)
    gltf.set_binary_blob(blob)
    gltf.save_binary(str(path))


def test_sparse_targets_several_primitives_and_strides_are_read(tmp_path):
    rng = np.random.default_rng(1)
    neutral, deltas = rng.normal(0, 50, (6, 3)), rng.normal(0, 2, (2, 6, 3))
    deltas[1, [0, 2, 5]] = 0.0
    other_tool_file(tmp_path / "rig.glb", neutral, deltas)
    mesh = read_morph_mesh(tmp_path / "rig.glb")
    assert mesh.names == ("target_01", "target_02") and mesh.animations == ()
    np.testing.assert_array_equal(mesh.triangles, [[0, 1, 2], [3, 4, 5]])
    np.testing.assert_allclose(mesh.neutral, neutral, rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(mesh.deltas, deltas, rtol=1e-6, atol=1e-6)


def test_bad_files_are_one_line_errors(tmp_path):
    with pytest.raises(WorkbenchError, match=r"none\.glb: glTF file not found"):
        read_morph_mesh(tmp_path / "none.glb")
    mesh = small_mesh(np.random.default_rng(2))
    (tmp_path / "m.glb").write_bytes(glb_bytes(mesh))
    with pytest.raises(WorkbenchError, match=r"m\.glb: 0 meshes with morph targets named 'body'; the file's are "
                                             r"\['face'\]"):
        read_morph_mesh(tmp_path / "m.glb", mesh_name="body")
    data = (tmp_path / "m.glb").read_bytes()
    (tmp_path / "cut.glb").write_bytes(data[:len(data) // 2])  # cut in the JSON chunk
    (tmp_path / "short.glb").write_bytes(data[:-40])  # cut in the binary chunk
    with pytest.raises(WorkbenchError, match=r"short\.glb: buffer view \d+ reaches past the binary data"):
        read_morph_mesh(tmp_path / "short.glb")
    with pytest.raises(WorkbenchError, match=r"cut\.glb: (not a readable glTF file|buffer view \d+ reaches past)"):
        read_morph_mesh(tmp_path / "cut.glb")
    with pytest.raises(WorkbenchError, match=r"morph targets must have shape \(2, 5, 3\) for 2 names"):
        glb_bytes(MorphMesh(neutral=mesh.neutral, triangles=mesh.triangles, names=mesh.names,
                            deltas=mesh.deltas[:, :4]))
    with pytest.raises(WorkbenchError, match=r"must be finite"):
        glb_bytes(MorphMesh(neutral=mesh.neutral * np.nan, triangles=mesh.triangles, names=mesh.names,
                            deltas=mesh.deltas))
