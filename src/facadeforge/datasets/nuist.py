"""NUIST facade point clouds: one labelled laser scan per facade, one text file per element.

The Commercial Street set of the NUIST facade datasets (Zang et al. 2024, FTG-Net; see
``../shared/data/README.md``, section ``pointclouds/``) is laid out as
``building_K/facade_M/<element>_<n>.txt``: ``wall_1.txt``, ``windows_3.txt``, ``door_2.txt``,
``balcony_1.txt``…, each holding the points of one element instance as ``x y z intensity``
(metres, z up; laser return intensity).  :func:`load_facade` gathers a facade's files into one
:class:`~facadeforge.points.cloud.PointCloud` with semantic ``labels`` (canonical names:
``wall``, ``window`` — the files say ``windows`` —, ``door``, ``balcony``; other names kept) and
an ``instance`` id per file; :func:`instances` splits it back into elements.  These are the
labelled scans the CityFit pipeline (``hohmann2009`` §3–4: point store, planes, element fitting)
is measured against.  :func:`write_fixture` writes a tiny facade in the same layout for tests.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from ..points.cloud import PointCloud, PointCloudError
from ..points.io import read_text

__all__ = ["CANONICAL", "ELEMENT_FILE", "canonical_name", "instances", "list_facades",
           "load_facade", "write_fixture"]

#: Canonical element names, in label-index order (names found in no file are left out).
CANONICAL: tuple[str, ...] = ("wall", "window", "door", "balcony")
_ALIASES = {"windows": "window", "walls": "wall", "doors": "door", "balconies": "balcony",
            "balconys": "balcony"}
#: An element file: a name, optionally ``_<number>``, ``.txt``.
ELEMENT_FILE = re.compile(r"^(?P<name>[A-Za-z][A-Za-z0-9 -]*?)(?:_(?P<num>\d+))?\.txt$",
                          re.IGNORECASE)


def canonical_name(name: str) -> str:
    """The canonical label of an element file's name (``"Windows"`` → ``"window"``)."""
    low = name.strip().lower()
    return _ALIASES.get(low, low)


def _natural(s: str) -> list:
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", s)]


def _element_files(folder: Path) -> list[tuple[str, int, Path]]:
    out = []
    for p in folder.iterdir():
        m = ELEMENT_FILE.match(p.name)
        if m and p.is_file():
            out.append((canonical_name(m.group("name")), int(m.group("num") or 0), p))
    return out


def list_facades(root: str | os.PathLike) -> list[Path]:
    """The facade folders under ``root`` (any depth), in natural order.

    Parameters
    ----------
    root : str or Path
        The NUIST folder (``…/pointclouds/nuist``), a building folder, or a facade folder.

    Returns
    -------
    list of Path
        Every folder holding at least one element file (``<name>_<n>.txt``), sorted so that
        ``building_2`` comes before ``building_10``.

    Raises
    ------
    PointCloudError
        ``root`` is not a folder, or holds no facade.
    """
    root = Path(root)
    if not root.is_dir():
        raise PointCloudError(f"NUIST folder {root} not found; pass the folder holding "
                              "building_K/facade_M/ (../shared/data/pointclouds/nuist)")
    found = {p.parent for p in root.rglob("*.txt") if ELEMENT_FILE.match(p.name) and p.is_file()}
    if not found:
        raise PointCloudError(f"{root} holds no facade: no building_K/facade_M/ folder with "
                              "element files like wall_1.txt, windows_2.txt")
    return sorted(found, key=lambda p: _natural(p.relative_to(root).as_posix()))


def load_facade(folder: str | os.PathLike, *, max_points: int | None = None) -> PointCloud:
    """One facade folder as a labelled cloud.

    Parameters
    ----------
    folder : str or Path
        A ``facade_M`` folder of ``<element>_<n>.txt`` files (columns ``x y z intensity``).
    max_points : int or None
        Raise when the facade holds more points in all.

    Returns
    -------
    PointCloud
        ``xyz`` (N, 3) float64 metres (z up), ``intensity``, ``labels`` into ``label_names``
        (canonical names, :data:`CANONICAL` order first, then other names alphabetically),
        ``instance`` 0…k−1, one per file in (label, number) order; ``source`` is the folder.

    Raises
    ------
    PointCloudError
        Missing folder, no element file, a file that cannot be read (named), more points than
        ``max_points``.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise PointCloudError(f"NUIST facade folder {folder} not found; pass a "
                              "building_K/facade_M folder")
    files = _element_files(folder)
    if not files:
        raise PointCloudError(f"{folder} holds no element file (<element>_<n>.txt, e.g. "
                              "wall_1.txt); pass a NUIST building_K/facade_M folder")
    present = {name for name, _, _ in files}
    names = tuple(n for n in CANONICAL if n in present) + tuple(sorted(present - set(CANONICAL)))
    files.sort(key=lambda f: (names.index(f[0]), f[1], f[2].name))
    parts, total = [], 0
    for k, (name, _, path) in enumerate(files):
        part = read_text(path, max_points=max_points)
        total += len(part)
        if max_points is not None and total > max_points:
            raise PointCloudError(f"{folder} holds more than max_points={max_points:,} points "
                                  f"(reached at {path.name}); raise max_points")
        parts.append((part, names.index(name), k))
    xyz = np.concatenate([p.xyz for p, _, _ in parts])
    with_intensity = all(p.intensity is not None for p, _, _ in parts)
    return PointCloud(
        xyz,
        intensity=np.concatenate([p.intensity for p, _, _ in parts]) if with_intensity else None,
        labels=np.concatenate([np.full(len(p), lab, np.int32) for p, lab, _ in parts]),
        label_names=names,
        instance=np.concatenate([np.full(len(p), k, np.int32) for p, _, k in parts]),
        up=2, source=str(folder))


def instances(cloud: PointCloud) -> list[tuple[str, int, np.ndarray]]:
    """The element instances of a labelled cloud.

    Parameters
    ----------
    cloud : PointCloud
        With ``instance`` ids (−1 = none); ``labels`` name each instance by its points'
        most frequent label.

    Returns
    -------
    list of (str, int, (M,) int64)
        ``(label_name, instance_id, point indices)`` per instance id ≥ 0, by increasing id;
        the name is ``""`` when the cloud has no labels or the points are unlabelled.

    Raises
    ------
    PointCloudError
        The cloud has no instance ids.
    """
    if cloud.instance is None:
        raise PointCloudError(f"{cloud.source}: the cloud has no instance ids; load it with "
                              "load_facade or a reader of a file that has them")
    order = np.argsort(cloud.instance, kind="stable")
    ids = cloud.instance[order]
    start = np.searchsorted(ids, 0)
    order, ids = order[start:], ids[start:]
    if not len(ids):
        return []
    cuts = np.flatnonzero(np.diff(ids)) + 1
    out = []
    for idx, first in zip(np.split(order, cuts), np.r_[0, cuts], strict=True):
        name = ""
        if cloud.labels is not None:
            lab = cloud.labels[idx]
            lab = lab[lab >= 0]
            if len(lab):
                top = int(np.bincount(lab).argmax())
                name = cloud.label_names[top] if top < len(cloud.label_names) else str(top)
        out.append((name, int(ids[first]), idx.astype(np.int64)))
    return out


def write_fixture(folder: str | os.PathLike, *, rng: np.random.Generator | int | None = 0,
                  spacing: float = 0.25) -> dict[str, int]:
    """Write a tiny NUIST-style facade into ``folder`` (created) for tests.

    A 6 m × 4 m wall in the plane x = 0 (y along the facade, z up) with two windows, one door
    and one balcony 0.1–0.6 m in front; points on a jittered ``spacing`` grid, intensity
    0–65535, columns ``x y z intensity`` with 6 decimals as the real files.

    Parameters
    ----------
    folder : str or Path
    rng : numpy Generator, int or None
        Jitter and intensity seed.
    spacing : float
        Grid step, metres.

    Returns
    -------
    dict
        File name → number of points written.
    """
    rng = np.random.default_rng(rng)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    # (file, y0, y1, z0, z1, x offset from the wall)
    boxes = [("windows_1.txt", 0.8, 2.0, 2.2, 3.4, -0.1), ("windows_2.txt", 3.4, 4.6, 2.2, 3.4, -0.1),
             ("door_1.txt", 2.4, 3.4, 0.0, 2.0, -0.05), ("balcony_1.txt", 3.2, 4.8, 1.9, 2.2, 0.6)]
    ys, zs = np.meshgrid(np.arange(0.0, 6.0, spacing), np.arange(0.0, 4.0, spacing), indexing="ij")
    ys, zs = ys.ravel(), zs.ravel()
    wall = np.ones(len(ys), bool)
    counts = {}
    for name, y0, y1, z0, z1, dx in boxes:
        inside = wall & (ys >= y0) & (ys < y1) & (zs >= z0) & (zs < z1)   # each point once
        wall &= ~inside
        counts[name] = _write_points(folder / name, np.full(inside.sum(), dx), ys[inside],
                                     zs[inside], rng, spacing)
    counts["wall_1.txt"] = _write_points(folder / "wall_1.txt", np.zeros(wall.sum()), ys[wall],
                                         zs[wall], rng, spacing)
    return counts


def _write_points(path: Path, x, y, z, rng: np.random.Generator, spacing: float) -> int:
    n = len(x)
    jitter = rng.uniform(-0.2, 0.2, (n, 3)) * spacing
    table = np.c_[x, y, z] + jitter
    table = np.c_[table, rng.uniform(0, 65535, n)]
    np.savetxt(path, table, fmt="%.6f")
    return n
