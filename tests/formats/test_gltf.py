"""glTF morph meshes: write and read back, files from other tools (sparse morph targets, several primitives,
interleaved positions), and damaged or unsupported files."""

import re

import numpy as np
import pytest

from workbench.core.errors import WorkbenchError
from workbench.formats.gltf import MorphAnimation, MorphMesh, glb_bytes, read_morph_mesh


def small_mesh(rng):
    return MorphMesh(
        neutral=rng.normal(0, 50, (5, 3)),
        triangles=np.array([[0, 1, 2], [2, 3, 4]]),
        names=("smile", "blink"),
        deltas=rng.normal(0, 2, (2, 5, 3)),
        animations=(MorphAnimation("take", np.arange(4) / 30.0, rng.uniform(0, 1, (4, 2))),),
        extras={"units": "metres"},
    )


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
        views.append(
            pygltflib.BufferView(
                buffer=0, byteOffset=sum(len(p) for p in parts), byteLength=len(data), byteStride=stride
            )
        )
        parts.append(data + b"\0" * (-len(data) % 4))
        if kind is not None:
            accessors.append(
                pygltflib.Accessor(
                    bufferView=len(views) - 1, componentType=component, count=count, type=kind, min=None, max=None
                )
            )
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
        accessors.append(
            pygltflib.Accessor(
                componentType=pygltflib.FLOAT,
                count=3,
                type="VEC3",
                sparse=pygltflib.Sparse(
                    count=len(moved),
                    indices=pygltflib.AccessorSparseIndices(
                        bufferView=index_view, componentType=pygltflib.UNSIGNED_BYTE
                    ),
                    values=pygltflib.AccessorSparseValues(bufferView=value_view),
                ),
            )
        )
        primitives.append(
            pygltflib.Primitive(
                attributes=pygltflib.Attributes(POSITION=position),
                indices=indices,
                targets=[pygltflib.Attributes(POSITION=dense), pygltflib.Attributes(POSITION=len(accessors) - 1)],
            )
        )
    blob = b"".join(parts)
    gltf = pygltflib.GLTF2(
        asset=pygltflib.Asset(version="2.0"),
        accessors=accessors,
        bufferViews=views,
        buffers=[pygltflib.Buffer(byteLength=len(blob))],
        meshes=[pygltflib.Mesh(name="head", primitives=primitives)],
        nodes=[pygltflib.Node(mesh=0)],
        scenes=[pygltflib.Scene(nodes=[0])],
        scene=0,
    )
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
    with pytest.raises(
        WorkbenchError,
        match=r"m\.glb: 0 meshes with morph targets named 'body'; the file's are "
        r"\['face'\]",
    ):
        read_morph_mesh(tmp_path / "m.glb", mesh_name="body")
    data = (tmp_path / "m.glb").read_bytes()
    (tmp_path / "cut.glb").write_bytes(data[: len(data) // 2])  # cut in the JSON chunk
    (tmp_path / "short.glb").write_bytes(data[:-40])  # cut in the binary chunk
    with pytest.raises(WorkbenchError, match=r"short\.glb: buffer view \d+ reaches past the binary data"):
        read_morph_mesh(tmp_path / "short.glb")
    with pytest.raises(WorkbenchError, match=r"cut\.glb: (not a readable glTF file|buffer view \d+ reaches past)"):
        read_morph_mesh(tmp_path / "cut.glb")
    with pytest.raises(WorkbenchError, match=r"morph targets must have shape \(2, 5, 3\) for 2 names"):
        glb_bytes(
            MorphMesh(neutral=mesh.neutral, triangles=mesh.triangles, names=mesh.names, deltas=mesh.deltas[:, :4])
        )
    with pytest.raises(WorkbenchError, match=r"must be finite"):
        glb_bytes(
            MorphMesh(neutral=mesh.neutral * np.nan, triangles=mesh.triangles, names=mesh.names, deltas=mesh.deltas)
        )


# ----------------------------------------------------------------------------------------------------------
# Damaged files: every one a one-line error naming the file and the part at fault (none an unexpected error)
# ----------------------------------------------------------------------------------------------------------


def split_glb(data):
    import json
    import struct

    n = struct.unpack("<I", data[12:16])[0]
    return json.loads(data[20 : 20 + n]), bytearray(data[20 + n + 8 :])


def join_glb(document, blob):
    import json
    import struct

    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(blob), 0x004E4942) + bytes(blob)
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def first_value(document, accessor):
    """Byte offset of an accessor's first value in the binary chunk."""
    entry = document["accessors"][accessor]
    return document["bufferViews"][entry["bufferView"]].get("byteOffset", 0) + entry.get("byteOffset", 0)


def set_float(document, blob, accessor, value, item=0):
    import struct

    start = first_value(document, accessor) + 4 * item
    blob[start : start + 4] = struct.pack("<f", value)


def add_sparse(document, blob, index, component=5125):
    """Make accessor 2 (the first morph target) sparse with one index, ``index``."""
    import struct

    document["bufferViews"] += [
        {"buffer": 0, "byteOffset": len(blob), "byteLength": 4},
        {"buffer": 0, "byteOffset": len(blob) + 4, "byteLength": 12},
    ]
    blob += struct.pack("<I", index) + bytes(12)
    document["accessors"][2]["sparse"] = {
        "count": 1,
        "values": {"bufferView": len(document["bufferViews"]) - 1},
        "indices": {"bufferView": len(document["bufferViews"]) - 2, "componentType": component},
    }


def primitive(document):
    return document["meshes"][0]["primitives"][0]


DAMAGED = {
    "no POSITION": (
        lambda d, b: primitive(d)["attributes"].pop("POSITION"),
        r"mesh 'face' primitive 0 has no POSITION attribute",
    ),
    "accessor index": (
        lambda d, b: primitive(d)["attributes"].__setitem__("POSITION", 99),
        r"accessor 99 does not exist \(the file has 6\)",
    ),
    "indices accessor": (lambda d, b: primitive(d).__setitem__("indices", -1), r"accessor -1 does not exist"),
    "target accessor": (
        lambda d, b: primitive(d)["targets"][0].__setitem__("POSITION", "2"),
        r"accessor '2' does not exist",
    ),
    "buffer view index": (
        lambda d, b: d["accessors"][0].__setitem__("bufferView", 99),
        r"buffer view 99 does not exist",
    ),
    "component type": (
        lambda d, b: d["accessors"][0].__setitem__("componentType", 9999),
        r"accessor 0 is VEC3 of component type 9999, but holds positions",
    ),
    "float indices": (
        lambda d, b: d["accessors"][1].__setitem__("componentType", 5126),
        r"accessor 1 is SCALAR of component type 5126, but holds indices",
    ),
    "accessor type": (lambda d, b: d["accessors"][0].__setitem__("type", "MAT4"), r"accessor 0 is MAT4"),
    "negative count": (
        lambda d, b: d["accessors"][0].__setitem__("count", -3),
        r"accessor 0 count must be an integer in \[0, 100000000\], got -3",
    ),
    "huge count": (lambda d, b: d["accessors"][0].__setitem__("count", 10**12), r"accessor 0 count must be"),
    "negative offset": (
        lambda d, b: d["accessors"][0].__setitem__("byteOffset", -8),
        r"accessor 0 byteOffset must be an integer >= 0",
    ),
    "short stride": (
        lambda d, b: d["bufferViews"][0].__setitem__("byteStride", 1),
        r"buffer view 0 byteStride must be an integer >= 12, got 1",
    ),
    # a view claiming more than the file holds, even where no accessor reads past the data
    "buffer view past the data": (
        lambda d, b: d["bufferViews"][0].__setitem__("byteLength", 10**9),
        r"buffer view 0 reaches past the binary data: it claims bytes 0 to 1000000000 "
        r"of a \d+-byte binary chunk",
    ),
    "buffer view offset past the data": (
        lambda d, b: d["bufferViews"][1].__setitem__("byteOffset", 10**6),
        r"buffer view 1 reaches past the binary data: it claims bytes 1000000 to",
    ),
    "sampler index": (
        lambda d, b: d["animations"][0]["channels"][0].__setitem__("sampler", 7),
        r"animation 'take' sampler 7 does not exist",
    ),
    "sparse index out of range": (
        lambda d, b: add_sparse(d, b, 100000),
        r"accessor 2 sparse indices must increase and stay below its 5 elements",
    ),
    "sparse component type": (
        lambda d, b: add_sparse(d, b, 1, component=5126),
        r"accessor 2 sparse indices have component type 5126",
    ),
    "index out of range": (
        lambda d, b: b.__setitem__(slice(first_value(d, 1), first_value(d, 1) + 4), (10**6).to_bytes(4, "little")),
        r"indices are not triangles over its 5 vertices",
    ),
    "NaN in the neutral": (
        lambda d, b: set_float(d, b, 0, float("nan")),
        r"accessor 0 element 0 holds NaN or Inf \(positions\)",
    ),
    "Inf weight": (lambda d, b: set_float(d, b, 5, float("inf")), r"accessor 5 element 0 holds NaN or Inf"),
    "vertex at 1e30": (
        lambda d, b: set_float(d, b, 3, 1e30, item=4),
        r"\(morph target blink\): vertex 1 lies 1e\+33 mm from the face's centre",
    ),
    "time going back": (
        lambda d, b: set_float(d, b, 4, -5.0, item=1),
        r"animation 'take': key times must increase \(key 1 at -5 s follows 0 s\)",
    ),
    "target names not text": (
        lambda d, b: d["meshes"][0]["extras"].__setitem__("targetNames", [1, 2]),
        r"extras\.targetNames must name its 2 morph targets once each, got \[1, 2\]",
    ),
    "target names a string": (
        lambda d, b: d["meshes"][0]["extras"].__setitem__("targetNames", "ab"),
        r"extras\.targetNames must name its 2 morph targets once each, got 'ab'",
    ),
    "unknown chunk and version": (lambda d, b: d["asset"].__setitem__("version", "3.0"), r"glTF version 3\.0"),
}


@pytest.mark.parametrize("case", list(DAMAGED))
def test_damaged_files_are_one_line_errors_naming_the_part(tmp_path, case, recwarn):
    change, message = DAMAGED[case]
    document, blob = split_glb(glb_bytes(small_mesh(np.random.default_rng(5))))
    change(document, blob)
    path = tmp_path / "damaged.glb"
    data = join_glb(document, blob)
    if case == "unknown chunk and version":
        data = data[:4] + (3).to_bytes(4, "little") + data[8:] + (8).to_bytes(4, "little") + b"XTRA" + bytes(8)
        data = data[:8] + len(data).to_bytes(4, "little") + data[12:]
    path.write_bytes(data)
    with pytest.raises(WorkbenchError, match=r"^" + re.escape(str(path)) + r".*" + message):
        read_morph_mesh(path)
    assert not [warning for warning in recwarn if "pygltflib" in str(warning.filename)], "pygltflib's warnings leak"
