"""Esri's runtime through PyPRT on OBJ initial shapes: the peer of ``facadeforge derive``.

Run by ``benchmarks/vs_prt.py`` under the interpreter of ``.venv-prt`` (``make prt-env``), which
holds PyPRT and nothing of facadeforge:

    .venv-prt/bin/python benchmarks/prt_generate.py SHAPES.obj RULES.rpk OUTDIR [--count]

Each face of the OBJ is one initial shape, as facadeforge reads it.  Without ``--count`` the
buildings go to ``OUTDIR/prt.glb`` through PRT's glTF encoder (the timed run); with it, PRT's
Python encoder hands the geometry back and one JSON line with the face count and area is
printed (untimed, for the comparison of what each engine made).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path


def read_obj(path: str) -> list[tuple[list[float], list[int], list[int]]]:
    """Per face: flat vertex coordinates, indices into them, and the face count list."""
    verts: list[tuple[float, float, float]] = []
    faces: list[list[int]] = []
    for line in Path(path).read_text().splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            verts.append(tuple(float(x) for x in parts[1:4]))
        elif parts[0] == "f":
            faces.append([int(p.split("/")[0]) - 1 for p in parts[1:]])
    shapes = []
    for f in faces:
        coords = [c for i in f for c in verts[i]]
        shapes.append((coords, list(range(len(f))), [len(f)]))
    return shapes


def _polygon_area(pts: list[tuple[float, float, float]]) -> float:
    sx = sy = sz = 0.0
    n = len(pts)
    for i in range(n):
        x0, y0, z0 = pts[i]
        x1, y1, z1 = pts[(i + 1) % n]
        sx += y0 * z1 - z0 * y1
        sy += z0 * x1 - x0 * z1
        sz += x0 * y1 - y0 * x1
    return 0.5 * math.sqrt(sx * sx + sy * sy + sz * sz)


def main(argv: list[str]) -> int:
    import pyprt

    obj, rpk, outdir = argv[:3]
    count = "--count" in argv
    shapes = [pyprt.InitialShape(c, i, n) for c, i, n in read_obj(obj)]
    gen = pyprt.ModelGenerator(shapes)
    attrs = [{"seed": 0} for _ in shapes]
    if not count:
        Path(outdir).mkdir(parents=True, exist_ok=True)
        gen.generate_model(attrs, rpk, "com.esri.prt.codecs.GLTFEncoder",
                           {"outputPath": outdir, "baseName": "prt"})
        return 0
    models = gen.generate_model(attrs, rpk, "com.esri.pyprt.PyEncoder",
                                {"emitReport": True, "emitGeometry": True})
    faces, area, reports = 0, 0.0, {}
    for m in models:
        v = m.get_vertices()
        pts = [tuple(v[i:i + 3]) for i in range(0, len(v), 3)]
        indices, at = m.get_indices(), 0
        for n in m.get_faces():
            idx = indices[at:at + n]
            at += n
            faces += 1
            area += _polygon_area([pts[i] for i in idx])
        for k, val in m.get_report().items():
            reports[k] = reports.get(k, 0.0) + float(val)
    print(json.dumps({"buildings": len(models), "faces": faces, "area": round(area, 1),
                      "reports": reports}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
