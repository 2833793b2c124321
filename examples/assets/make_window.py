"""Writes window.obj: an arched, framed window with mullions and a sill (used by the benchmark
and the asset example).  Run: python examples/assets/make_window.py"""

from pathlib import Path

import numpy as np


def box(x0, y0, z0, x1, y1, z1):
    v = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                  [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], float)
    f = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [3, 7, 6, 2], [1, 2, 6, 5], [0, 4, 7, 3]]
    return v, f


def arch_ring(cx, cy, r0, r1, z0, z1, n=16):
    """Half-ring of boxes from angle 0 to pi (the arch frame)."""
    parts = []
    a = np.linspace(0, np.pi, n + 1)
    for k in range(n):
        p = [(cx + r * np.cos(t), cy + r * np.sin(t)) for r, t in
             ((r1, a[k]), (r1, a[k + 1]), (r0, a[k + 1]), (r0, a[k]))]
        v = np.array([[x, y, z0] for x, y in p] + [[x, y, z1] for x, y in p])
        f = [[0, 1, 2, 3][::-1], [4, 5, 6, 7], [0, 1, 5, 4][::-1], [1, 2, 6, 5][::-1],
             [2, 3, 7, 6][::-1], [3, 0, 4, 7][::-1]]
        parts.append((v, f))
    return parts


def main(out: Path | None = None):
    out = out or Path(__file__).with_name("window.obj")
    w, d = 1.0, 0.12
    parts = []
    t = 0.08  # frame
    parts.append(box(0, 0, 0, t, 1.5, d))
    parts.append(box(w - t, 0, 0, w, 1.5, d))
    parts.append(box(0, 0, 0, w, t, d))
    parts += arch_ring(w / 2, 1.5, w / 2 - t, w / 2, 0, d)
    parts.append(box(w / 2 - 0.025, t, 0.02, w / 2 + 0.025, 1.5, 0.08))  # mullion
    for y in (0.55, 1.0):
        parts.append(box(t, y, 0.02, w - t, y + 0.04, 0.08))  # transoms
    parts.append(box(-0.06, -0.06, 0, w + 0.06, 0, 0.2))  # sill
    lines = ["# facadeforge window asset", "mtllib window.mtl"]
    n = 0
    vs, fs = [], []
    for v, f in parts:
        vs.append(v)
        fs += [[i + n for i in face] for face in f]
        n += len(v)
    # glass pane: a rectangle and a fan under the arch, slightly recessed
    glass = [[t, t, 0.05], [w - t, t, 0.05], [w - t, 1.5, 0.05], [t, 1.5, 0.05]]
    a = np.linspace(0, np.pi, 17)
    arc = [[w / 2 + (w / 2 - t) * np.cos(x), 1.5 + (w / 2 - t) * np.sin(x), 0.05] for x in a]
    centre = [[w / 2, 1.5, 0.05]]
    V = np.concatenate(vs + [np.array(glass), np.array(arc), np.array(centre)])
    for p in V:
        lines.append(f"v {p[0]:.4f} {p[1]:.4f} {p[2]:.4f}")
    lines.append("usemtl frame")
    for face in fs:
        lines.append("f " + " ".join(str(i + 1) for i in face))
    lines.append("usemtl glass")
    lines.append("f " + " ".join(str(n + i + 1) for i in range(4)))
    arc0, c = n + 4 + 1, n + 4 + 17 + 1  # 1-based indices of the first arc vertex and the centre
    for k in range(16):
        lines.append(f"f {c} {arc0 + k} {arc0 + k + 1}")
    out.write_text("\n".join(lines) + "\n")
    out.with_suffix(".mtl").write_text("newmtl frame\nKd 0.95 0.94 0.90\nnewmtl glass\nKd 0.35 0.5 0.6\nd 0.85\n")


if __name__ == "__main__":
    main()
