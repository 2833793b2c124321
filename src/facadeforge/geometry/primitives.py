"""Built-in primitives (``i("builtin:cube")``, ``primitiveCube()``…) as unit meshes in [0, 1]³.

Each comes with UVs so that textures projected by the primitive's own parameterisation work.
"""

from __future__ import annotations

import numpy as np

from .mesh import Mesh


def unit_cube() -> Mesh:
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                  [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    # every side face starts with its bottom edge, so comp(f) gives walls x along the ground
    # and y up, as the walls of an extruded lot
    faces = [[1, 0, 3, 2], [4, 5, 6, 7], [0, 1, 5, 4], [3, 7, 6, 2], [5, 1, 2, 6], [0, 4, 7, 3]]
    uv = [np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)] * 6
    return Mesh(v, faces, uv)


def unit_quad() -> Mesh:
    """The xy unit square facing +z (a facade-like quad)."""
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    return Mesh(v, [[0, 1, 2, 3]], [v[:, :2].copy()])


def unit_ring(n: int = 16) -> np.ndarray:
    """``n`` points of the circle inscribed in the unit square, counter-clockwise."""
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.column_stack([0.5 + 0.5 * np.cos(a), 0.5 + 0.5 * np.sin(a)])


def unit_cylinder(n: int = 16) -> Mesh:
    """Cylinder along y, radius 0.5, in the unit cube."""
    r = unit_ring(n)
    bottom = np.column_stack([r[:, 0], np.zeros(n), r[:, 1]])
    top = bottom + [0, 1, 0]
    polys = [bottom, top[::-1]]
    for j in range(n):
        k = (j + 1) % n
        polys.append(np.array([bottom[j], top[j], top[k], bottom[k]]))
    return Mesh.from_polygons([_orient_out(p) for p in polys])


def unit_cone(n: int = 16) -> Mesh:
    r = unit_ring(n)
    bottom = np.column_stack([r[:, 0], np.zeros(n), r[:, 1]])
    apex = np.array([0.5, 1.0, 0.5])
    polys = [bottom]
    for j in range(n):
        k = (j + 1) % n
        polys.append(np.array([bottom[j], apex, bottom[k]]))
    return Mesh.from_polygons([_orient_out(p) for p in polys])


def unit_disk(n: int = 16) -> Mesh:
    r = unit_ring(n)
    return Mesh.from_polygons([np.column_stack([r[:, 0], np.zeros(n), r[:, 1]])[::-1]])


def unit_sphere(n_lat: int = 8, n_lon: int = 16) -> Mesh:
    lat = np.linspace(0, np.pi, n_lat + 1)
    lon = np.linspace(0, 2 * np.pi, n_lon, endpoint=False)
    pts = lambda la, lo: 0.5 + 0.5 * np.array([np.sin(la) * np.cos(lo), np.cos(la),  # noqa: E731
                                              np.sin(la) * np.sin(lo)])
    polys = []
    for i in range(n_lat):
        for j in range(n_lon):
            a, b = lon[j], lon[(j + 1) % n_lon]
            q = [pts(lat[i], a), pts(lat[i], b), pts(lat[i + 1], b), pts(lat[i + 1], a)]
            if i == 0:
                q = [q[0], q[2], q[3]]
            elif i == n_lat - 1:
                q = [q[0], q[1], q[2]]
            polys.append(_orient_out(np.array(q)))
    return Mesh.from_polygons(polys)


def _orient_out(p: np.ndarray) -> np.ndarray:
    """Flip a face of a shape centred at (0.5, 0.5, 0.5) so its normal points away from the centre."""
    from .mesh import polygon_normal

    n = polygon_normal(p)
    return p if n @ (p.mean(axis=0) - 0.5) >= 0 else p[::-1]


PRIMITIVES = {"cube": unit_cube, "unitCube": unit_cube, "quad": unit_quad, "cylinder": unit_cylinder,
              "cone": unit_cone, "disk": unit_disk, "sphere": unit_sphere}
