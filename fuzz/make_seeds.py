#!/usr/bin/env python3
"""Writes the seed corpus of the `load_gltf` fuzz target (fuzz/corpus/load_gltf).

Small valid scenes exercising each loader path, and broken ones for each
error path. Run from anywhere; the files are committed, so this is only
needed to change the seeds.
"""
import base64
import json
import math
import os
import struct
import zlib

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus", "load_gltf")

QUAD = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
UV = [(0, 1), (1, 1), (1, 0), (0, 0)]


def png(w, h, rgb):
    rows = b"".join(b"\0" + bytes(c for px in rgb[y * w:(y + 1) * w] for c in px) for y in range(h))
    chunk = lambda t, d: struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


class Doc:
    def __init__(self):
        self.bin = bytearray()
        self.j = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": []}], "nodes": [],
                  "meshes": [], "bufferViews": [], "accessors": [], "materials": []}

    def view(self, data):
        while len(self.bin) % 4:
            self.bin.append(0)
        self.j["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)})
        self.bin += data
        return len(self.j["bufferViews"]) - 1

    def acc(self, data, fmt, n, comp, typ, **extra):
        v = self.view(b"".join(struct.pack("<" + fmt, *x) if isinstance(x, tuple) else struct.pack("<" + fmt, x)
                               for x in data))
        self.j["accessors"].append(dict({"bufferView": v, "componentType": comp, "count": n, "type": typ}, **extra))
        return len(self.j["accessors"]) - 1

    def pos(self, p):
        finite = [[c if math.isfinite(c) else 0 for c in v] for v in p]
        return self.acc(p, "3f", len(p), 5126, "VEC3", min=[min(v[k] for v in finite) for k in range(3)],
                        max=[max(v[k] for v in finite) for k in range(3)])

    def idx(self, i):
        return self.acc(i, "H", len(i), 5123, "SCALAR")

    def uv(self, uv):
        return self.acc(uv, "2f", len(uv), 5126, "VEC2")

    def material(self, m):
        self.j["materials"].append(m)
        return len(self.j["materials"]) - 1

    def mesh(self, prims, name=None):
        m = {"primitives": prims}
        if name:
            m["name"] = name
        self.j["meshes"].append(m)
        return len(self.j["meshes"]) - 1

    def node(self, n, root=True):
        self.j["nodes"].append(n)
        i = len(self.j["nodes"]) - 1
        if root:
            self.j["scenes"][0]["nodes"].append(i)
        return i

    def light_quad(self):
        m = self.material({"name": "Light", "emissiveFactor": [1, 1, 1],
                           "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0}})
        mesh = self.mesh([{"attributes": {"POSITION": self.pos(QUAD)}, "indices": self.idx([0, 1, 2, 0, 2, 3]),
                           "material": m}], "Quad")
        return self.node({"name": "Light", "mesh": mesh})

    def gltf(self):
        j = dict(self.j, buffers=[{"byteLength": len(self.bin),
                                   "uri": "data:application/octet-stream;base64," + base64.b64encode(self.bin).decode()}])
        return json.dumps(j, separators=(",", ":")).encode()

    def glb(self):
        j = json.dumps(dict(self.j, buffers=[{"byteLength": len(self.bin)}]), separators=(",", ":")).encode()
        j += b" " * (-len(j) % 4)
        b = bytes(self.bin) + b"\0" * (-len(self.bin) % 4)
        body = struct.pack("<I4s", len(j), b"JSON") + j + struct.pack("<I4s", len(b), b"BIN\0") + b
        return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def write(name, data):
    with open(os.path.join(OUT, name), "wb") as f:
        f.write(data)


def main():
    os.makedirs(OUT, exist_ok=True)

    d = Doc()
    d.light_quad()
    write("quad.gltf", d.gltf())
    write("quad.glb", d.glb())
    write("truncated.glb", d.glb()[:-9])
    write("malformed.gltf", d.gltf()[:40])

    # Textured, double-sided, mirrored, nested, with a camera and strips.
    d = Doc()
    d.light_quad()
    img = png(2, 2, [(255, 0, 0), (0, 255, 0), (0, 0, 255), (128, 128, 128)])
    d.j["images"] = [{"bufferView": d.view(img), "mimeType": "image/png"}]
    d.j["samplers"] = [{"wrapS": 33648, "wrapT": 33071, "magFilter": 9728}]
    d.j["textures"] = [{"source": 0, "sampler": 0}]
    d.j["extensionsUsed"] = ["KHR_materials_emissive_strength", "KHR_texture_transform"]
    tex = d.material({"name": "Checker", "doubleSided": True, "pbrMetallicRoughness": {
        "baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"scale": [2, 2]}}},
        "metallicFactor": 0}, "emissiveFactor": [0.1, 0.1, 0.1], "emissiveTexture": {"index": 0},
        "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 3}}})
    p = d.pos(QUAD)
    mesh = d.mesh([{"attributes": {"POSITION": p, "TEXCOORD_0": d.uv(UV)}, "indices": d.idx([0, 1, 3, 2]),
                    "mode": 5, "material": tex},
                   {"attributes": {"POSITION": p}, "mode": 6}], "Board")
    child = d.node({"mesh": mesh, "scale": [-1, 1, 1]}, root=False)
    d.j["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.7, "aspectRatio": 1.5, "znear": 0.1}}]
    cam = d.node({"camera": 0, "translation": [0, 0, 5]}, root=False)
    d.node({"children": [child, cam], "matrix": [1, 0, 0, 0, 0, 0, 1, 0, 0, -1, 0, 0, 2, 0, 0, 1]})
    write("textured.gltf", d.gltf())
    write("textured.glb", d.glb())

    # A sparse accessor displacing one vertex.
    d = Doc()
    d.light_quad()
    base = d.pos(QUAD)
    d.j["accessors"][base]["sparse"] = {"count": 1,
                                        "indices": {"bufferView": d.view(struct.pack("<H", 2)), "componentType": 5123},
                                        "values": {"bufferView": d.view(struct.pack("<3f", 1, 1, 0.5))}}
    d.node({"mesh": d.mesh([{"attributes": {"POSITION": base}}], "Sparse")})
    write("sparse.gltf", d.gltf())

    # Broken inputs, one per error path.
    d = Doc()
    d.light_quad()
    d.node({"mesh": d.mesh([{"attributes": {"POSITION": d.pos([(0, 0, 0), (1, math.nan, 0), (0, 1, 0)])}}], "NaN")})
    write("nan.gltf", d.gltf())

    d = Doc()
    d.light_quad()
    d.node({"mesh": d.mesh([{"attributes": {"POSITION": d.pos(QUAD)}, "indices": d.idx([0, 1, 17])}], "BadIndex")})
    write("bad_index.gltf", d.gltf())

    d = Doc()
    d.light_quad()
    d.node({"mesh": d.mesh([{"attributes": {"POSITION": d.pos(QUAD)}, "mode": 1}], "Lines")})
    write("lines.gltf", d.gltf())

    d = Doc()
    d.light_quad()
    d.j["nodes"][0]["children"] = [1]
    d.node({"children": [0]}, root=False)
    write("cycle.gltf", d.gltf())

    d = Doc()
    d.light_quad()
    d.j["accessors"][0]["count"] = 4000000000
    write("huge_count.gltf", d.gltf())

    d = Doc()
    m = d.material({"name": "Grey"})
    d.node({"mesh": d.mesh([{"attributes": {"POSITION": d.pos(QUAD)}, "material": m}])})
    write("no_emitters.glb", d.glb())

    issue26()


def lit_quad_doc(**node):
    """A lit scene with a second quad on a node with the given fields."""
    d = Doc()
    d.light_quad()
    d.node(dict({"mesh": 0}, **node))
    return d


def issue26():
    """Malformed or hostile single files of issue 26, each refused (or
    accepted) as tests/fuzz_corpus.rs expects."""
    # A projective node matrix (column-major; m33 = -1 flips the receiver).
    write("projective_matrix.gltf",
          lit_quad_doc(matrix=[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 2, -1]).gltf())
    # A shear: columns 0 and 1 not orthogonal.
    write("shear_matrix.gltf",
          lit_quad_doc(matrix=[1, 0, 0, 0, 1, 1, 0, 0, 0, 0, 1, 0, 0, 0, 2, 1]).gltf())
    # A matrix together with a translation.
    write("matrix_and_trs.gltf",
          lit_quad_doc(matrix=[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 2, 1], translation=[0, 0, 1]).gltf())

    # A sparse index (7) at or past the accessor's count (4).
    d = Doc()
    d.light_quad()
    base = d.pos(QUAD)
    d.j["accessors"][base]["sparse"] = {"count": 1,
                                        "indices": {"bufferView": d.view(struct.pack("<H", 7)), "componentType": 5123},
                                        "values": {"bufferView": d.view(struct.pack("<3f", 1, 1, 0.5))}}
    d.node({"mesh": d.mesh([{"attributes": {"POSITION": base}}], "SparsePast")})
    write("sparse_index_past_count.gltf", d.gltf())

    # A buffer view past the buffer's declared byteLength (the data URI
    # holds the bytes; the declared length is 16 short).
    d = Doc()
    d.light_quad()
    j = json.loads(d.gltf())
    j["buffers"][0]["byteLength"] -= 16
    write("view_past_buffer.gltf", json.dumps(j, separators=(",", ":")).encode())

    # A GLB whose header declares fewer bytes than the file has.
    d = Doc()
    d.light_quad()
    glb = bytearray(d.glb())
    struct.pack_into("<I", glb, 8, len(glb) - 8)
    write("glb_length_short.glb", bytes(glb))

    # asset.version 3.0.
    d = Doc()
    d.light_quad()
    d.j["asset"] = {"version": "3.0"}
    write("version_3.gltf", d.gltf())

    # External buffers outside the scene's folder: climbing, absolute, file:.
    for name, uri in [("uri_parent.gltf", "../../../../etc/passwd"),
                      ("uri_absolute.gltf", "/etc/passwd"),
                      ("uri_file_scheme.gltf", "file:///etc/passwd")]:
        d = Doc()
        d.light_quad()
        j = json.loads(d.gltf())
        j["buffers"].append({"byteLength": 64, "uri": uri})
        j["bufferViews"].append({"buffer": 1, "byteOffset": 0, "byteLength": 48})
        j["accessors"].append({"bufferView": len(j["bufferViews"]) - 1, "componentType": 5126, "count": 4,
                               "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]})
        j["meshes"].append({"primitives": [{"attributes": {"POSITION": len(j["accessors"]) - 1}}]})
        j["nodes"].append({"mesh": len(j["meshes"]) - 1})
        j["scenes"][0]["nodes"].append(len(j["nodes"]) - 1)
        write(name, json.dumps(j, separators=(",", ":")).encode())

    # Names with ESC and carriage return on a broken mesh: its error names it.
    d = Doc()
    d.light_quad()
    d.node({"name": "\x1b[2J\rNode", "mesh": d.mesh(
        [{"attributes": {"POSITION": d.pos([(0, 0, 0), (1, math.nan, 0), (0, 1, 0)])}}], "\x1b[31mRed\rMesh")})
    write("control_names.gltf", d.gltf())

    # An instancing bomb, scaled down: 32 primitives of 1024 triangles on
    # each of the 256 leaves of a node tree, 2^23 triangles (4 GiB loaded)
    # from an 18 KB file, refused from the declared counts before any mesh
    # is read (the memory budget, 2 GiB by default, is what it hits).
    d = Doc()
    d.light_quad()
    p = d.pos(QUAD)
    i = d.idx([0, 1, 2, 0, 2, 3] * 512)
    mesh = d.mesh([{"attributes": {"POSITION": p}, "indices": i, "material": 0}] * 32, "Tiles")

    def tree(depth):
        if depth == 0:
            return d.node({"mesh": mesh}, root=False)
        a, b = tree(depth - 1), tree(depth - 1)
        return d.node({"children": [a, b]}, root=False)

    d.j["scenes"][0]["nodes"].append(tree(8))
    write("instancing_bomb.glb", d.glb())

    # Six image entries sharing one source (a bufferView holding a PNG),
    # each the texture of its own quad: accepted, decoded once.
    d = Doc()
    d.light_quad()
    view = d.view(png(4, 4, [(200, 40, 40)] * 8 + [(40, 40, 200)] * 8))
    d.j["images"] = [{"bufferView": view, "mimeType": "image/png", "name": f"entry {k}"} for k in range(6)]
    d.j["textures"] = [{"source": k} for k in range(6)]
    p, t, i = d.pos(QUAD), d.uv(UV), d.idx([0, 1, 2, 0, 2, 3])
    for k in range(6):
        m = d.material({"name": f"Wall{k}", "pbrMetallicRoughness": {"baseColorTexture": {"index": k},
                                                                      "metallicFactor": 0}})
        mesh = d.mesh([{"attributes": {"POSITION": p, "TEXCOORD_0": t}, "indices": i, "material": m}])
        d.node({"mesh": mesh, "translation": [2 * k, 0, 1]})
    write("shared_image_source.gltf", d.gltf())


if __name__ == "__main__":
    main()
