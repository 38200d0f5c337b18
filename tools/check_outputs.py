#!/usr/bin/env python3
"""Independent checks of a nusselt output folder.

Usage: python3 tools/check_outputs.py OUTDIR

Reads OUTDIR/solution.exr with the OpenEXR (>= 3) Python bindings and checks
the layout the contract fixes: parts `vertices` and `triangles`, width 1024,
heights ceil(count / 1024) (at least 1), the channels and their types, the
`vertexCount` / `triangleCount` attributes, unused pixels zero, finite
values, unit normals, non-negative radiosity and triangle indices in range.

Then reads OUTDIR/baked.gltf + its buffer with plain json/numpy and checks
that it holds the same vertices and triangles, with COLOR_0 equal to
clamp(B / pi * exposure, 0, 1) for the exposure in asset.extras; finally it
runs the Khronos glTF Validator (tools/validate_gltf.mjs) on baked.gltf and
fails on any error-severity message.

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
    components = {"SCALAR": 1, "VEC3": 3}[accessor["type"]]
    dtype = {5126: np.float32, 5125: np.uint32}.get(accessor["componentType"])
    require(dtype is not None, f"{path}: accessor {index} has component type {accessor['componentType']}")
    view = gltf["bufferViews"][accessor["bufferView"]]
    require("byteStride" not in view, f"{path}: buffer view {accessor['bufferView']} is interleaved")
    start = view.get("byteOffset", 0) + accessor.get("byteOffset", 0)
    count = accessor["count"] * components
    data = np.frombuffer(buffers[view["buffer"]], dtype=dtype, count=count, offset=start)
    return data.reshape(accessor["count"], components)


def check_baked(path, solution):
    """Checks that baked.gltf holds the solution's mesh; returns nothing."""
    import numpy as np

    require(path.is_file(), f"{path} does not exist")
    try:
        gltf = json.loads(path.read_text(encoding="utf-8"))
        buffers = [(path.parent / b["uri"]).read_bytes() for b in gltf["buffers"]]
        primitives = [p for mesh in gltf["meshes"] for p in mesh["primitives"]]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise CheckError(f"{path}: cannot read the glTF and its buffer: {e}") from e
    require(len(primitives) == 1, f"{path}: {len(primitives)} primitives, expected 1")
    primitive = primitives[0]
    attributes = primitive.get("attributes", {})
    for name in ["POSITION", "NORMAL", "COLOR_0", "_RADIOSITY", "_IRRADIANCE"]:
        require(name in attributes, f"{path}: the primitive lacks the attribute {name}")
    exposure = gltf.get("asset", {}).get("extras", {}).get("exposure")
    require(isinstance(exposure, (int, float)), f"{path}: asset.extras.exposure is missing")

    positions, normals, radiosity, irradiance, indices = solution
    try:
        baked = {name: accessor_array(gltf, buffers, attributes[name], path) for name in attributes}
        baked_indices = accessor_array(gltf, buffers, primitive["indices"], path).reshape(-1, 3)
    except (KeyError, ValueError, IndexError) as e:
        raise CheckError(f"{path}: malformed accessor: {e}") from e
    for name, expected in [
        ("POSITION", positions),
        ("NORMAL", normals),
        ("_RADIOSITY", radiosity),
        ("_IRRADIANCE", irradiance),
    ]:
        require(
            np.array_equal(baked[name], expected),
            f"{path}: {name} differs from the solution.exr vertices",
        )
    require(np.array_equal(baked_indices, indices), f"{path}: triangles differ from solution.exr")
    display = np.clip(radiosity.astype(np.float64) / math.pi * exposure, 0.0, 1.0)
    error = np.abs(baked["COLOR_0"] - display).max(initial=0.0)
    require(error < 1e-5, f"{path}: COLOR_0 differs from clamp(B / pi * exposure, 0, 1) by {error}")
    print(f"{path.name}: same {len(positions)} vertices and {len(indices)} triangles as solution.exr; COLOR_0 OK (exposure {exposure})")


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


def main(argv):
    if len(argv) != 2:
        print("usage: python3 tools/check_outputs.py OUTDIR", file=sys.stderr)
        return 2
    outdir = Path(argv[1])
    try:
        require(outdir.is_dir(), f"{outdir} is not a folder")
        solution = check_solution(outdir / "solution.exr")
        if (outdir / "baked.glb").exists():
            # `--glb`: the same document in one file; the validator reads it.
            run_validator(outdir / "baked.glb")
        else:
            check_baked(outdir / "baked.gltf", solution)
            run_validator(outdir / "baked.gltf")
    except CheckError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    print(f"{outdir}: all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
