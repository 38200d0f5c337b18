#!/usr/bin/env python3
"""Writes the seed corpus of the `pipeline` fuzz target (fuzz/corpus/pipeline).

The byte layout is the one `nusselt::pipeline::fuzz_pipeline` decodes:
scale (10^(b % 7 - 3) m), parallelograms (1 + b % 4), triangles (b % 4),
then per polygon: origin and two edge vectors (nine coordinates, each
b / 32 - 4), flags (bit 0 emits, always for the first; bit 1 double-sided),
reflectance RGB (b / 256) and, for emitters, radiance RGB (b / 16 + 0.1).
Run from anywhere; the files are committed.
"""
import os
import random

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus", "pipeline")


def c(x):
    """The byte of coordinate x (a multiple of 1/32 in [-4, 4))."""
    return int(round((x + 4) * 32))


def poly(o, a, b, rho=(128, 128, 128), emit=None, double=False):
    flags = (1 if emit else 0) | (2 if double else 0)
    out = [c(v) for v in (*o, *a, *b)] + [flags, *rho]
    return out + list(emit or [])


def scene(scale, quads, tris=()):
    return bytes([scale, len(quads) - 1, len(tris)] + sum(quads, []) + sum(tris, []))


LIGHT = (15, 15, 15)
X, Y, Z = (1, 0, 0), (0, 1, 0), (0, 0, 1)
NX, NY, NZ = (-1, 0, 0), (0, -1, 0), (0, 0, -1)
SEEDS = {
    # An emitting floor facing up, a grey ceiling facing down.
    "facing_pair": scene(3, [poly((0, 0, 0), Z, X, emit=LIGHT), poly((0, 1, 0), X, Z)]),
    # The same at 1 mm and at 1 km.
    "facing_pair_mm": scene(0, [poly((0, 0, 0), Z, X, emit=LIGHT), poly((0, 1, 0), X, Z)]),
    "facing_pair_km": scene(6, [poly((0, 0, 0), Z, X, emit=LIGHT), poly((0, 1, 0), X, Z)]),
    # Nearly a furnace: reflectance 255/256 on both.
    "bright_pair": scene(3, [poly((0, 0, 0), Z, X, (255, 255, 255), LIGHT),
                             poly((0, 0.25, 0), X, Z, (255, 255, 255))]),
    # Floor light and three walls of a box, sharing edges.
    "open_box": scene(3, [poly((0, 0, 0), Z, X, emit=LIGHT), poly((0, 0, 0), X, Y),
                          poly((0, 0, 0), Y, Z), poly((1, 0, 0), Z, Y)]),
    # Two coplanar overlapping quads, one emitting, and a receiver above.
    "coplanar_overlap": scene(3, [poly((0, 0, 0), Z, X, emit=LIGHT),
                                  poly((0.5, 0, 0.5), Z, X, (200, 50, 50)),
                                  poly((0, 1, 0), X, Z)]),
    # A wall penetrating the lit floor, with a triangle nearby.
    "penetrating": scene(3, [poly((0, 0, 0), (0, 0, 2), (2, 0, 0), emit=LIGHT),
                             poly((1, -0.5, 0), X, Y, double=True)],
                         [poly((0, 0.5, 0), X, Z, (30, 200, 30))]),
    # A receiver 1/32 above a big emitter.
    "nearly_touching": scene(3, [poly((0, 0, 0), (0, 0, 3), (3, 0, 0), emit=LIGHT),
                                 poly((1, 0.03125, 1), X, Z)]),
    # Slivers: a long thin emitter and a long thin receiver.
    "slivers": scene(3, [poly((-2, 0, 0), (0, 0, 0.03125), (3.5, 0, 0), emit=LIGHT),
                         poly((-2, 1, 0), (3.5, 0, 0), (0, 0, 0.03125))]),
    # Only degenerate polygons: the scene is refused, not a failure.
    "degenerate": scene(3, [poly((0, 0, 0), X, X, emit=LIGHT)]),
    # An emitter facing away from a double-sided triangle.
    "facing_away": scene(3, [poly((0, 0, 0), X, Z, emit=LIGHT)],
                         [poly((0, 1, 0), X, Z, double=True)]),
    # Issue 26: a fan of three slivers sharing an apex, lit from above
    # (the case that opened every pair of touching clusters).
    "sliver_fan": scene(3, [poly((0, 2, 0), X, Z, emit=LIGHT)],
                        [poly((0, 0, 0), (3, 0, 0.0625), (3, 0, 0.03125)),
                         poly((0, 0, 0), (3, 0, 0.09375), (3, 0, 0.0625)),
                         poly((0, 0, 0), (3, 0, 0.125), (3, 0, 0.09375))]),
    # Issue 26: coplanar quads sharing edges (no link between coplanar
    # nodes), under an emitter.
    "coplanar_touching": scene(3, [poly((0, 1, 0), X, Z, emit=LIGHT),
                                   poly((0, 0, 0), Z, X), poly((1, 0, 0), Z, X), poly((0, 0, 1), Z, X)]),
    # Issue 26: a receiver facing away from the light beside one facing
    # it, at the smallest scale (1 mm).
    "facing_away_mm": scene(0, [poly((0, 0, 0), Z, X, emit=LIGHT), poly((0, 1, 0), Z, X),
                                poly((1.5, 1, 0), X, Z)]),
}


def main():
    os.makedirs(OUT, exist_ok=True)
    for name, data in SEEDS.items():
        with open(os.path.join(OUT, name + ".bin"), "wb") as f:
            f.write(data)
    rng = random.Random(7)
    for k in range(4):
        with open(os.path.join(OUT, f"random{k}.bin"), "wb") as f:
            f.write(bytes(rng.randrange(256) for _ in range(rng.randrange(20, 120))))


if __name__ == "__main__":
    main()
