"""Laser scans → facades: reading clouds, the fixed-point store, planes, depth maps, fitting.

``hohmann2009`` §3 (CityFit: point store, RANSAC planes, depth maps) and ``simon2011`` §5.3.2
(depth energy), §5.4.3 (geometric accuracy).  Modules, in the order data flows through them:

- :mod:`.cloud` — :class:`PointCloud`, the one in-memory type;
- :mod:`.io` — readers (PLY, LAS/LAZ, XYZ/TXT);
- :mod:`.store` — 16.16 fixed-point storage in a quadtree of 4 m columns, spatial queries;
"""

from .cloud import PointCloud, PointCloudError

__all__ = ["PointCloud", "PointCloudError"]
