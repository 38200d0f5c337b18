#!/usr/bin/env python3
"""Independent checks of a nusselt output folder.

Usage: python3 tools/check_outputs.py OUTDIR

Reads OUTDIR/solution.exr with the OpenEXR (>= 3) Python bindings and checks
the layout the contract fixes: parts `vertices` and `triangles`, width 1024,
heights ceil(count / 1024) (at least 1), the channels and their types, the
`vertexCount` / `triangleCount` attributes, unused pixels zero, finite
values, unit normals, non-negative radiosity and triangle indices in range.

Then reads OUTDIR/baked.gltf + its buffer with plain json/numpy and checks
that its nodes hold the same vertices (through the node transforms) and
triangles, each once by the primitives' patch table, with COLOR_0 equal to
clamp(B / pi * exposure, 0, 1) for the exposure in asset.extras; finally it
runs the Khronos glTF Validator (tools/validate_gltf.mjs) on baked.gltf and
fails on any error-severity message. With `--lightmap`, it also reads the
atlases and checks them against the vertices through TEXCOORD_1.

Setup: pip install OpenEXR numpy; npm install --prefix tools
Exit status: 0 when everything holds, 1 with one `error:` line otherwise,
2 on a usage error.
"""

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

WIDTH = 1024
VERTEX_FLOATS = ["R", "G", "B", "H.R", "H.G", "H.B", "P.X", "P.Y", "P.Z", "N.X", "N.Y", "N.Z"]
TRIANGLE_UINTS = ["I0", "I1", "I2"]


class CheckError(Exception):
    """A violated expectation; its message is printed after `error:`."""


def require(condition, message):
    if not condition:
        raise CheckError(message)


def rows_for(count):
    return max(1, math.ceil(count / WIDTH))


def check_part(part, name, count_attribute, channels, file):
    """Checks one part's size, attribute and channels; returns (count, {name: flat array})."""
    import OpenEXR

    where = f"{file}: part {name!r}"
    header = part.header
    require(part.width() == WIDTH, f"{where} is {part.width()} pixels wide, expected {WIDTH}")
    require(count_attribute in header, f"{where} lacks the attribute {count_attribute!r}")
    count = header[count_attribute]
    require(
        isinstance(count, int) and not isinstance(count, bool),
        f"{where}: {count_attribute} is {count!r}, not an int",
    )
    require(count >= 0, f"{where}: {count_attribute} = {count} is negative")
    require(
        part.height() == rows_for(count),
        f"{where} has height {part.height()}, expected ceil({count} / {WIDTH}) = {rows_for(count)}",
    )
    lossless = {
        OpenEXR.NO_COMPRESSION,
        OpenEXR.RLE_COMPRESSION,
        OpenEXR.ZIPS_COMPRESSION,
        OpenEXR.ZIP_COMPRESSION,
        OpenEXR.PIZ_COMPRESSION,
    }
    require(part.compression() in lossless, f"{where} uses lossy compression {part.compression()}")
    present = set(part.channels)
    expected = set(channels)
    require(
        present == expected,
        f"{where} has channels {sorted(present)}, expected {sorted(expected)}",
    )
    flat = {}
    for channel_name, pixel_type in channels.items():
        channel = part.channels[channel_name]
        require(
            channel.type() == pixel_type,
            f"{where}: channel {channel_name!r} is {channel.type()}, expected {pixel_type}",
        )
        pixels = channel.pixels
        require(
            pixels.shape == (part.height(), WIDTH),
            f"{where}: channel {channel_name!r} has shape {pixels.shape}",
        )
        values = pixels.reshape(-1)
        require(
            not values[count:].any(),
            f"{where}: channel {channel_name!r} has non-zero unused pixels",
        )
        flat[channel_name] = values[:count]
    return count, flat


def check_solution(path):
    """Checks solution.exr; returns (positions, normals, radiosity, triangles) as numpy arrays."""
    try:
        import numpy as np
        import OpenEXR
    except ImportError as e:
        raise CheckError(f"{e}: install the readers with `pip install OpenEXR numpy`") from e

    require(path.is_file(), f"{path} does not exist")
    try:
        exr = OpenEXR.File(str(path), separate_channels=True)
    except Exception as e:  # the bindings raise plain exceptions
        raise CheckError(f"{path}: not readable by OpenEXR: {e}") from e
    names = [p.name() for p in exr.parts]
    require(names == ["vertices", "triangles"], f"{path}: parts are {names}, expected ['vertices', 'triangles']")
    vertices, triangles = exr.parts

    float_type, uint_type = OpenEXR.FLOAT, OpenEXR.UINT
    vertex_channels = {c: float_type for c in VERTEX_FLOATS}
    vertex_channels["patch"] = uint_type
    n, v = check_part(vertices, "vertices", "vertexCount", vertex_channels, path)
    m, t = check_part(triangles, "triangles", "triangleCount", {c: uint_type for c in TRIANGLE_UINTS}, path)

    for name in VERTEX_FLOATS:
        bad = np.flatnonzero(~np.isfinite(v[name]))
        require(bad.size == 0, f"{path}: vertex {int(bad[0]) if bad.size else -1} has a non-finite {name}")
    positions = np.stack([v["P.X"], v["P.Y"], v["P.Z"]], axis=1)
    normals = np.stack([v["N.X"], v["N.Y"], v["N.Z"]], axis=1)
    radiosity = np.stack([v["R"], v["G"], v["B"]], axis=1)
    irradiance = np.stack([v["H.R"], v["H.G"], v["H.B"]], axis=1)
    if n:
        lengths = np.linalg.norm(normals.astype(np.float64), axis=1)
        worst = int(np.argmax(np.abs(lengths - 1.0)))
        require(abs(lengths[worst] - 1.0) < 1e-3, f"{path}: normal of vertex {worst} has length {lengths[worst]}")
        require(radiosity.min() >= 0.0, f"{path}: negative radiosity at vertex {int(np.argmin(radiosity.min(axis=1)))}")
        require(irradiance.min() >= 0.0, f"{path}: negative irradiance at vertex {int(np.argmin(irradiance.min(axis=1)))}")
    indices = np.stack([t["I0"], t["I1"], t["I2"]], axis=1)
    if m:
        out = np.flatnonzero((indices >= n).any(axis=1))
        require(out.size == 0, f"{path}: triangle {int(out[0]) if out.size else -1} indexes beyond the {n} vertices")
    print(f"{path.name}: {n} vertices, {m} triangles: layout and values OK")
    return positions, normals, radiosity, irradiance, indices


def accessor_array(gltf, buffers, index, path):
    """The data of accessor `index` as an (count, components) numpy array."""
    import numpy as np

    accessor = gltf["accessors"][index]
    components = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[accessor["type"]]
    dtype = {5126: np.float32, 5125: np.uint32}.get(accessor["componentType"])
    require(dtype is not None, f"{path}: accessor {index} has component type {accessor['componentType']}")
    view = gltf["bufferViews"][accessor["bufferView"]]
    require("byteStride" not in view, f"{path}: buffer view {accessor['bufferView']} is interleaved")
    start = view.get("byteOffset", 0) + accessor.get("byteOffset", 0)
    count = accessor["count"] * components
    data = np.frombuffer(buffers[view["buffer"]], dtype=dtype, count=count, offset=start)
    return data.reshape(accessor["count"], components)


def local_matrix(node):
    """A node's local transform as a 4x4 numpy matrix (glTF's matrix or T*R*S)."""
    import numpy as np

    if "matrix" in node:
        return np.array(node["matrix"], dtype=np.float64).reshape(4, 4).T
    x, y, z, w = node.get("rotation", [0.0, 0.0, 0.0, 1.0])
    rotation = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    m = np.eye(4)
    m[:3, :3] = rotation * np.array(node.get("scale", [1.0, 1.0, 1.0]))
    m[:3, 3] = node.get("translation", [0.0, 0.0, 0.0])
    return m


def world_matrices(gltf):
    """World transform of every node reached from the default scene."""
    import numpy as np

    scene = gltf["scenes"][gltf.get("scene", 0)]
    stack = [(n, np.eye(4)) for n in scene["nodes"]]
    world = {}
    while stack:
        n, parent = stack.pop()
        require(n not in world, f"node {n} is reached twice")
        world[n] = parent @ local_matrix(gltf["nodes"][n])
        stack.extend((c, world[n]) for c in gltf["nodes"][n].get("children", []))
    return world


def expand(run_list):
    """[[start, count], ...] as a flat list of indices."""
    return [start + k for start, count in run_list for k in range(count)]


def check_baked(path, solution):
    """Checks that baked.gltf holds the solution's mesh on the scene's nodes:
    every vertex and triangle once, world positions and normals through the
    node transforms, B, H and COLOR_0; returns nothing."""
    import numpy as np

    require(path.is_file(), f"{path} does not exist")
    try:
        gltf = json.loads(path.read_text(encoding="utf-8"))
        buffers = [(path.parent / b["uri"]).read_bytes() for b in gltf["buffers"]]
        world = world_matrices(gltf)
    except (OSError, ValueError, KeyError, TypeError, IndexError) as e:
        raise CheckError(f"{path}: cannot read the glTF, its nodes and its buffer: {e}") from e
    exposure = gltf.get("asset", {}).get("extras", {}).get("exposure")
    require(isinstance(exposure, (int, float)), f"{path}: asset.extras.exposure is missing")

    positions, normals, radiosity, irradiance, indices = solution
    scale = float(np.abs(positions).max(initial=1.0))
    seen_vertices = np.zeros(len(positions), dtype=np.int64)
    seen_triangles = np.zeros(len(indices), dtype=np.int64)
    primitives = 0
    for n, matrix in sorted(world.items()):
        node = gltf["nodes"][n]
        if "mesh" not in node:
            continue
        linear = matrix[:3, :3]
        for primitive in gltf["meshes"][node["mesh"]]["primitives"]:
            primitives += 1
            where = f"{path}: node {n} primitive {primitives}"
            attributes = primitive.get("attributes", {})
            for name in ["POSITION", "NORMAL", "COLOR_0", "_RADIOSITY", "_IRRADIANCE"]:
                require(name in attributes, f"{where} lacks the attribute {name}")
            try:
                baked = {name: accessor_array(gltf, buffers, attributes[name], path) for name in attributes}
                local = accessor_array(gltf, buffers, primitive["indices"], path).reshape(-1, 3)
                vertices = np.array(expand(primitive["extras"]["solution_vertices"]), dtype=np.int64)
                triangles = np.array(expand(primitive["extras"]["solution_triangles"]), dtype=np.int64)
            except (KeyError, ValueError, IndexError, TypeError) as e:
                raise CheckError(f"{where}: malformed accessor or patch table: {e}") from e
            require(len(vertices) == len(baked["POSITION"]), f"{where}: the patch table's vertex count differs")
            require(len(triangles) == len(local), f"{where}: the patch table's triangle count differs")
            seen_vertices[vertices] += 1
            seen_triangles[triangles] += 1
            p = baked["POSITION"].astype(np.float64) @ linear.T + matrix[:3, 3]
            error = np.abs(p - positions[vertices]).max(initial=0.0)
            require(error <= 1e-5 * scale, f"{where}: world positions differ from solution.exr by {error}")
            nw = baked["NORMAL"].astype(np.float64) @ np.linalg.inv(linear)
            nw /= np.linalg.norm(nw, axis=1, keepdims=True)
            error = np.abs(nw - normals[vertices]).max(initial=0.0)
            require(error <= 1e-4, f"{where}: world normals differ from solution.exr by {error}")
            for name, expected in [("_RADIOSITY", radiosity), ("_IRRADIANCE", irradiance)]:
                require(np.array_equal(baked[name], expected[vertices]), f"{where}: {name} differs from solution.exr")
            display = np.clip(radiosity[vertices].astype(np.float64) / math.pi * exposure, 0.0, 1.0)
            error = np.abs(baked["COLOR_0"] - display).max(initial=0.0)
            require(error < 1e-5, f"{where}: COLOR_0 differs from clamp(B / pi * exposure, 0, 1) by {error}")
            tris = vertices[local]
            if np.linalg.det(linear) < 0:
                tris = tris[:, [0, 2, 1]]
            require(np.array_equal(tris, indices[triangles]), f"{where}: triangles differ from solution.exr")
    require((seen_vertices == 1).all(), f"{path}: not every solution.exr vertex is baked exactly once")
    require((seen_triangles == 1).all(), f"{path}: not every solution.exr triangle is baked exactly once")
    print(
        f"{path.name}: the {len(positions)} vertices and {len(indices)} triangles of solution.exr, once each, "
        f"in {primitives} primitive(s) on the scene's nodes; COLOR_0 OK (exposure {exposure})"
    )


def run_validator(path):
    node = shutil.which("node")
    require(node is not None, "node is not installed; the glTF Validator needs Node.js")
    script = Path(__file__).resolve().parent / "validate_gltf.mjs"
    result = subprocess.run([node, str(script), str(path)], capture_output=True, text=True)
    sys.stdout.write(result.stdout)
    if result.returncode != 0:
        lines = [line for line in result.stderr.splitlines() if line.strip()]
        reason = lines[-1].removeprefix("error: ") if lines else f"exit status {result.returncode}"
        raise CheckError(f"glTF Validator: {reason}")


REC709 = (0.64, 0.33, 0.30, 0.60, 0.15, 0.06, 0.3127, 0.3290)


def check_header(path, quantity):
    """Every part of an EXR names its software, Rec. 709 chromaticities and,
    in the `nusselt` string vector, `quantity` (e.g. `R G B=radiance [...]`)."""
    import OpenEXR

    for k, part in enumerate(OpenEXR.File(str(path), separate_channels=True).parts):
        header, where = part.header, f"{path}: part {k}"
        require(str(header.get("software", "")).startswith("nusselt "), f"{where}: no nusselt software attribute")
        c = header.get("chromaticities")
        require(
            c is not None and all(abs(a - b) < 1e-6 for a, b in zip(c, REC709)),
            f"{where}: chromaticities {c!r} are not Rec. 709",
        )
        entries = header.get("nusselt")
        require(
            isinstance(entries, list) and any(e.startswith(quantity) for e in entries),
            f"{where}: the nusselt attribute {entries!r} lacks {quantity!r}",
        )


def read_rgb(path):
    """A one-part float RGB EXR as an (height, width, 3) numpy array."""
    import numpy as np
    import OpenEXR

    try:
        exr = OpenEXR.File(str(path), separate_channels=True)
        channels = exr.parts[0].channels
        rgb = np.stack([channels[c].pixels for c in "RGB"], axis=-1).astype(np.float64)
    except Exception as e:  # the bindings raise plain exceptions
        raise CheckError(f"{path}: not a readable RGB EXR: {e}") from e
    return rgb


def bilinear(image, uv):
    """Samples `image` at texture coordinates `uv` (n, 2) as a viewer does:
    texel centres at half-integers, clamped at the edges."""
    import numpy as np

    h, w, _ = image.shape
    x = uv[:, 0] * w - 0.5
    y = uv[:, 1] * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    xi = [np.clip(x0 + d, 0, w - 1).astype(int) for d in (0, 1)]
    yi = [np.clip(y0 + d, 0, h - 1).astype(int) for d in (0, 1)]
    top = image[yi[0], xi[0]] * (1 - fx) + image[yi[0], xi[1]] * fx
    bottom = image[yi[1], xi[0]] * (1 - fx) + image[yi[1], xi[1]] * fx
    return top * (1 - fy) + bottom * fy


def check_lightmap(outdir, solution):
    """With lightmap-B.exr: the atlases are square, finite and non-negative,
    every baked primitive has TEXCOORD_1 in [0, 1], and the B atlas read at
    each vertex's TEXCOORD_1 is that vertex's B (median within 2 %)."""
    import numpy as np

    atlases = [read_rgb(outdir / f"lightmap-{layer}.exr") for layer in "BH"]
    for layer, atlas in zip("BH", atlases):
        require(atlas.shape[0] == atlas.shape[1], f"lightmap-{layer}.exr is not square: {atlas.shape}")
        require(np.isfinite(atlas).all() and (atlas >= 0).all(), f"lightmap-{layer}.exr has negative or non-finite texels")
    path = outdir / "baked.gltf"
    gltf = json.loads(path.read_text(encoding="utf-8"))
    buffers = [(outdir / b["uri"]).read_bytes() for b in gltf["buffers"]]
    radiosity = solution[2].astype(np.float64)
    uv = np.full((len(radiosity), 2), np.nan)
    for mesh in gltf["meshes"]:
        for primitive in mesh["primitives"]:
            attributes = primitive["attributes"]
            require("TEXCOORD_1" in attributes, f"{path}: a primitive of mesh {mesh.get('name')} lacks TEXCOORD_1")
            coords = accessor_array(gltf, buffers, attributes["TEXCOORD_1"], path)
            uv[expand(primitive["extras"]["solution_vertices"])] = coords
    require(np.isfinite(uv).all() and (uv >= 0).all() and (uv <= 1).all(), f"{path}: TEXCOORD_1 outside [0, 1]")
    got = bilinear(atlases[0], uv)
    scale = np.maximum(radiosity.max(axis=1), 0.01 * radiosity.max())
    error = np.abs(got - radiosity).max(axis=1) / scale
    median = float(np.median(error))
    require(median <= 0.02, f"lightmap-B.exr at the vertices' TEXCOORD_1 differs from B by {median:.3%} (median)")
    print(f"lightmap-B.exr, lightmap-H.exr: {atlases[0].shape[1]}² texels; B at the vertices within {median:.3%} (median)")


def main(argv):
    if len(argv) != 2:
        print("usage: python3 tools/check_outputs.py OUTDIR", file=sys.stderr)
        return 2
    outdir = Path(argv[1])
    try:
        require(outdir.is_dir(), f"{outdir} is not a folder")
        solution = check_solution(outdir / "solution.exr")
        check_header(outdir / "solution.exr", "R G B=radiosity [W/m^2]")
        check_header(outdir / "render.exr", "R G B=radiance [W/(m^2 sr)]")
        if (outdir / "lightmap-H.exr").exists():
            check_header(outdir / "lightmap-H.exr", "R G B=irradiance [W/m^2]")
        if (outdir / "baked.glb").exists():
            # `--glb`: the same document in one file; the validator reads it.
            run_validator(outdir / "baked.glb")
        else:
            check_baked(outdir / "baked.gltf", solution)
            if (outdir / "lightmap-B.exr").exists():
                check_lightmap(outdir, solution)
            run_validator(outdir / "baked.gltf")
    except CheckError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    print(f"{outdir}: all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
