"""Laser scans → facades: reading clouds, the fixed-point store, planes, depth maps, fitting.

``hohmann2009`` §3 (CityFit: point store, RANSAC planes, depth maps) and ``simon2011`` §5.3.2
(depth energy), §5.4.3 (geometric accuracy).  Modules, in the order data flows through them:

- :mod:`.cloud` — :class:`PointCloud`, the one in-memory type;
- :mod:`.io` — readers (PLY, LAS/LAZ, XYZ/TXT/CSV/PTS) and a PLY writer;
- :mod:`.store` — 16.16 fixed-point storage in a quadtree of 4 m columns, spatial queries
  (box, column, radius, nearest, ray picking), merging of duplicate points;
- :mod:`.colour` — each point coloured from a calibrated photo that sees it;
- :mod:`.planes` — sequential RANSAC, largest plane first, and what each plane is;
- :mod:`.maps` — a facade plane's orthographic frame and rasters (depth, density, intensity);
- :mod:`.outline` — a street front on one plane cut into houses of different heights;
- :mod:`.elements` — windows and doors as recesses, balconies as protrusions;
- :mod:`.fit` — a parse grammar fitted with appearance and depth energies (``--fit grammar``);
- :mod:`.evaluate` — detection in the facade plane, eq. 5.10–5.11;
- :mod:`.pipeline` — ``facadeforge points``: all of it, and the OUTDIR.
"""

from .cloud import PointCloud, PointCloudError

__all__ = ["PointCloud", "PointCloudError", "PointStore", "points", "read_cloud"]


def read_cloud(path, **options):
    """Read a point cloud file; see :func:`facadeforge.points.io.read_cloud`."""
    from .io import read_cloud as _read

    return _read(path, **options)


def points(cloud, **options):
    """Scan → facade planes, depth maps, elements, rules and model; see
    :func:`facadeforge.points.pipeline.points`."""
    from .pipeline import points as _points

    return _points(cloud, **options)


def __getattr__(name: str):
    if name == "PointStore":          # numba and the store load only when asked for
        from .store import PointStore

        return PointStore
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
