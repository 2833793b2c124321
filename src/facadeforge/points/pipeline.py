"""Laser scan → procedural facades: ``facadeforge points`` and :func:`points`.

Stages (each timed in ``report["timings"]``):

1. **load** — :func:`~.io.read_cloud` (PLY, LAS/LAZ, XYZ/TXT) or a :class:`~.cloud.PointCloud`;
   with photos and cameras, each point coloured from a photo that sees it (:mod:`.colour`,
   ``hohmann2009`` §3);
2. **planes** — sequential RANSAC, largest first, kinds ground / facade / protrusion / recess /
   roof / other (:mod:`.planes`, §3 Fig. 4);
3. **maps** — per facade plane, its orthographic frame and rasters: depth, density, intensity
   or colour (:mod:`.maps`, §3; ``simon2011`` §5.3.2's "virtual orthographic cameras");
4. **elements** — windows and doors as recesses, balconies as protrusions (:mod:`.elements`);
5. **structure** — the elements go through the photo pipeline's own stages (``mueller2007``
   §2–5: floors and tiles laid around the elements, clusters, element matching, the shape
   tree, size-independent CGA rules) on the facade's orthophoto, then every element leaf takes
   its **measured** depth from the depth map (a cluster's rule takes the mean of its
   elements') instead of a per-class default;
6. **model** — the rules derived on the facade rectangle and placed back into the cloud's
   coordinates (the facade frame → the cloud → the CGA y-up axes, relative to
   ``report["origin"]``, which CityJSON's ``transform`` adds back; CityJSON carries the cloud's
   CRS when it has one).

OUTDIR: ``planes.json``; ``facade_NN/`` per facade with ``depth.png``, ``ortho.png``,
``structure.png``, ``shape_tree.json``, ``rules.cga``, ``rules.gml``; at the top ``elements.json`` (one record
per window, door, balcony: ``label``, ``facade``, ``corners`` — the four 3D corners of its
rectangle on the facade plane at its depth, cloud coordinates), ``model.glb``, ``model.obj``,
``model.city.json`` (every facade) and ``report.json`` (planes, facades, timings, and
``accuracy``: the model-to-scan distance of ``simon2011`` eq. 5.10 and, when the cloud is
labelled, eq. 5.11 per class, in cm, on points sampled every 10 cm on the model).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from .cloud import PointCloud, PointCloudError
from .elements import Element, detect_elements, wall_depth
from .maps import (
    RESOLUTION,
    FacadeFrame,
    FacadeMaps,
    facade_box,
    facade_frame,
    facade_points,
    rasterize,
)
from .outline import segments
from .planes import FACADE_MIN_HEIGHT, FACADE_MIN_WIDTH, Plane, detect_planes

__all__ = ["FacadeResult", "PointsResult", "points", "MAX_FACADES"]

#: Facades modelled per cloud, largest first.
MAX_FACADES = 12
#: ``--fit`` choices (see :func:`points`).
FITS = ("elements", "grammar")
#: Classes of the ortho classifier handed to the photo pipeline (order = channel).
_CLASSES = ("wall", "window", "door", "balcony")


@dataclass
class FacadeResult:
    """One facade of the cloud: its plane, frame, rasters, elements and procedural model."""

    index: int
    plane: int                    # index into PointsResult.planes
    frame: FacadeFrame
    maps: FacadeMaps
    elements: list[Element]
    ortho: np.ndarray             # (H, W, 3) uint8, rows down
    rec: object = None            # the photo pipeline's Reconstruction of the orthophoto
    tree: object = None           # the facade's shape tree (facade metres, y up)
    rules: str | None = None      # its CGA rules
    source: str = "elements"      # what the tree is: "elements" (layout) or "grammar" (fit)
    model: object = None          # the derived facade, placed in the cloud (CGA axes)
    report: dict = field(default_factory=dict)
    offset_u: float = 0.0         # where the facade starts along its plane's facade (m)
    whole: int = 0                # index into PointsResult.whole: the plane's whole facade


@dataclass
class PlaneFacade:
    """A facade plane's whole rasters and the elements found on them, before it is cut into
    the segments (:mod:`.outline`) that are modelled each as a facade."""

    plane: int
    frame: FacadeFrame
    maps: FacadeMaps
    elements: list[Element]
    ortho: np.ndarray
    index: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # its points


@dataclass
class PointsResult:
    cloud: PointCloud
    planes: list[Plane]
    facades: list[FacadeResult]
    origin: np.ndarray
    report: dict = field(default_factory=dict)
    inputs: dict = field(default_factory=dict)
    whole: list = field(default_factory=list)      # PlaneFacade per facade plane

    def elements(self) -> list[dict]:
        """``elements.json``: every element of every facade with its 3D corners."""
        out = []
        for f in self.facades:
            for k, e in enumerate(_final_elements(f)):
                out.append({"facade": f.index, "index": k, **e.to_dict(f.frame)})
        return out

    def plane_elements(self, whole: int) -> list[Element]:
        """The model's elements of one facade plane (all its segments), in the plane's frame."""
        out = []
        for f in self.facades:
            if f.whole != whole:
                continue
            for e in _final_elements(f):
                u0, v0, u1, v1 = e.box_m
                out.append(Element(e.label, (u0 + f.offset_u, v0, u1 + f.offset_u, v1),
                                   e.box_px, e.depth, e.score))
        return out

    def models(self) -> list:
        return [f.model for f in self.facades if f.model is not None]

    def save(self, out_dir: str | os.PathLike) -> list[Path]:
        from ..outdir import write_outdir

        return write_outdir(Path(out_dir), lambda stage: _write(self, stage), self.inputs)


# ------------------------------------------------------------------------------ helpers

def ortho_image(maps: FacadeMaps) -> np.ndarray:
    """The facade's orthophoto (rows down): colour when the cloud has it, else intensity
    stretched to its 1st–99th percentile; empty cells take a Gaussian average of the filled
    cells around them, or their nearest filled cell farther out."""
    from scipy import ndimage

    filled = maps.count > 0
    if maps.rgb is not None:
        img = maps.rgb.astype(np.float32)
    elif maps.intensity is not None and np.isfinite(maps.intensity).any():
        v = maps.intensity
        lo, hi = np.nanpercentile(v, [1, 99])
        g = np.clip((np.nan_to_num(v, nan=lo) - lo) / max(hi - lo, 1e-9), 0, 1) * 255
        img = np.repeat(g[:, :, None], 3, axis=2)
    else:                                     # geometry only: depth shading
        d = np.nan_to_num(maps.depth, nan=0.0)
        g = np.clip(160 + d * 300, 0, 255)
        img = np.repeat(g[:, :, None], 3, axis=2)
    if filled.any() and not filled.all():
        # the scan's stripe gaps: a normalised Gaussian average of the cells around; what is
        # farther from any point than a few cells takes its nearest filled cell
        w = ndimage.gaussian_filter(filled.astype(np.float32), 2.0)
        avg = np.stack([ndimage.gaussian_filter(np.where(filled, img[..., k], 0), 2.0)
                        for k in range(3)], -1) / np.maximum(w, 1e-6)[..., None]
        near = ~filled & (w > 0.05)
        img = np.where(near[..., None], avg, img)
        filled = filled | near
        _, (ii, jj) = ndimage.distance_transform_edt(~filled, return_indices=True)
        img = img[ii, jj]
    return np.clip(img, 0, 255).astype(np.uint8)


def depth_image(maps: FacadeMaps, span: float = 0.5) -> np.ndarray:
    """``depth.png``: signed depth as colour — grey on the wall, blue behind it (recesses),
    red in front (protrusions), saturated at ``span`` m; black where no point fell."""
    d = np.clip(maps.depth / span, -1, 1)
    ok = np.isfinite(d)
    img = np.zeros(maps.shape + (3,), np.uint8)
    x = d[ok]
    img[..., 0][ok] = (140 + 115 * np.clip(x, 0, 1) - 100 * np.clip(-x, 0, 1)).astype(np.uint8)
    img[..., 1][ok] = (140 - 100 * np.abs(x)).astype(np.uint8)
    img[..., 2][ok] = (140 + 115 * np.clip(-x, 0, 1) - 100 * np.clip(x, 0, 1)).astype(np.uint8)
    return img


def _map_classifier(elements: list[Element]):
    """The facade's elements for the photo pipeline: as class probabilities, and as the boxes
    themselves (``detected_elements``: the photo pipeline's detector, tuned on CMP photos,
    would drop a small window beside big ones as a fragment)."""
    from ..classify.model import PixelClassifier

    class MapClassifier(PixelClassifier):
        kind = "depth-map"

        def predict_proba_coarse(self, image: np.ndarray) -> np.ndarray:
            h, w = image.shape[:2]
            p = np.zeros((h, w, len(_CLASSES)), np.float32)
            p[:, :, 0] = 1.0
            for e in elements:
                x0, y0, x1, y1 = e.box_px
                p[y0:y1, x0:x1] = 0.0
                p[y0:y1, x0:x1, _CLASSES.index(e.label)] = 1.0
            return p * 0.96 + 0.01

        def detected_elements(self):
            from ..imaging.detect import Element as Box

            inside = [Box(e.label, e.box_px, e.score) for e in elements if e.label != "balcony"]
            fronts = [Box(e.label, e.box_px, e.score) for e in elements if e.label == "balcony"]
            return inside, fronts

        def to_arrays(self):                       # never saved: built per facade
            return {}

        @classmethod
        def from_arrays(cls, arrays, classes, label_set, meta):
            return cls(classes, label_set, meta)

    return MapClassifier(_CLASSES, "depth-map", {"source": "points.elements"})


def _final_elements(f: FacadeResult) -> list[Element]:
    """The elements of the facade's shape tree (what the model has), with their depths; the
    detected elements when there is no tree."""
    if f.tree is None:
        return [e for e in f.elements if e.label in ("window", "door", "balcony")]
    out = []
    h, r = f.maps.shape[0], f.maps.resolution
    for leaf in f.tree.leaves():
        label = "door" if leaf.label == "shop" else leaf.label
        if label not in ("window", "door", "balcony"):
            continue
        o, sz = leaf.scope.origin, leaf.scope.size
        u0, v0, u1, v1 = float(o[0]), float(o[1]), float(o[0] + sz[0]), float(o[1] + sz[1])
        if u1 - u0 <= 1e-6 or v1 - v0 <= 1e-6:
            continue
        box = (int(round(u0 / r)), int(round(h - v1 / r)), int(round(u1 / r)),
               int(round(h - v0 / r)))
        depth = leaf.tags.get("depth")
        if depth is None:
            depth = f.report.get("class_depths", {}).get(leaf.label, 0.0)
        out.append(Element(label, (u0, v0, u1, v1), box, float(depth), 1.0))
    out.sort(key=lambda e: (-e.box_m[3], e.box_m[0]))
    return out


def _shift(elements: list[Element], seg, sub: FacadeMaps) -> list[Element]:
    """The elements whose centre lies in a segment, in the segment's own frame and cells."""
    off = seg.x0 * sub.resolution
    h = sub.shape[0]
    out = []
    for e in elements:
        x0, y0, x1, y1 = e.box_px
        if not seg.x0 <= (x0 + x1) / 2 < seg.x1:
            continue
        box = (max(x0 - seg.x0, 0), max(y0 - seg.top, 0), min(x1 - seg.x0, seg.x1 - seg.x0),
               min(y1 - seg.top, h))
        if box[2] <= box[0] or box[3] <= box[1]:
            continue
        u0, v0, u1, v1 = e.box_m
        out.append(Element(e.label, (max(u0 - off, 0.0), v0, min(u1 - off, sub.frame.width),
                                     min(v1, sub.frame.height)), box, e.depth, e.score))
    return out


def _measured_depth(maps: FacadeMaps, wall: np.ndarray, box, label: str) -> float | None:
    """An element's depth from the wall around it (m): the median of its recessed cells (the
    front-most depths of a balcony's protruding cells)."""
    x0, y0, x1, y1 = box
    if label == "balcony":
        v = maps.front[y0:y1, x0:x1] - wall[None, x0:x1]
        v = v[np.isfinite(v) & (v > 0.1)]
    else:
        v = maps.depth[y0:y1, x0:x1] - wall[None, x0:x1]
        v = v[np.isfinite(v) & (v < -0.03)]
    return float(np.median(v)) if len(v) else None


# cloud (x, y, z up) → CGA (x, y up, z): the inverse of CityJSON's (x, −z, y)
_TO_CGA = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])


def _place(model, frame: FacadeFrame, origin: np.ndarray, up: int):
    """The facade model (facade frame: x right, y up, z out, metres) into the cloud's frame,
    then into CGA axes relative to ``origin``."""
    perm = np.eye(3)
    if up != 2:                                 # a y-up or x-up cloud: rotate up onto z first
        perm = np.roll(np.eye(3), 2 - up, axis=0)
    basis = np.c_[frame.u, frame.v, frame.n]     # facade → cloud
    m = _TO_CGA @ perm @ basis
    off = _TO_CGA @ perm @ (frame.origin - origin)
    for p in model.parts:
        p.mesh = p.mesh.transformed(m, off)
    return model


# ------------------------------------------------------------------------------ pipeline

def points(cloud, *, resolution: float | None = None, photos=None, cameras=None,
           model: bool = True, fit: str = "elements", budget: int = 600,
           max_facades: int = MAX_FACADES, seed: int = 0,
           out_dir: str | os.PathLike | None = None) -> PointsResult:
    """Reconstruct the facades of a laser scan (see the module docstring).

    Parameters
    ----------
    cloud : path or PointCloud
        The scan (``.ply``, ``.las``, ``.laz``, ``.xyz``, ``.txt``, ``.csv``, ``.pts``).
    resolution : float, optional
        Raster cell (m) of the depth maps and orthophotos; by default chosen per facade from
        its point spacing (:func:`auto_resolution`).
    photos, cameras : optional
        A folder (or mapping name → path) of photos and their cameras file (VisualSFM
        ``cameras_v2.txt``): points take their colour from a photo that sees them.
    model : bool
        Derive the 3D model (elements, planes and maps are found either way).
    fit : {"elements", "grammar"}
        ``elements``: the facade's structure is the layout around the detected elements;
        ``grammar``: the ``grid`` parse grammar is also fitted with appearance and depth energies
        (SPEA-II, ``budget`` derivations, :mod:`.fit`) and its derivation replaces the layout
        where the automatic α of ``simon2011`` §5.2.3 prefers it.
    out_dir : path, optional
        Write the OUTDIR (module docstring) atomically.
    """
    timings: dict[str, float] = {}
    t = time.perf_counter()
    inputs = {"cloud": cloud, "--photos": photos, "--cameras": cameras}
    if out_dir is not None:
        from ..outdir import check_outdir

        check_outdir(out_dir, inputs)
    if fit not in FITS:
        raise InputError(f"--fit {fit!r}: use one of {', '.join(FITS)}")
    if not isinstance(budget, int) or budget < 1:
        raise InputError(f"--budget {budget}: give a positive number of derivations")
    if resolution is not None and not (0.005 <= resolution <= 1.0):
        raise InputError(f"--resolution {resolution}: give a cell size between 0.005 and 1 m")
    if not isinstance(cloud, PointCloud):
        from .io import read_cloud

        cloud = read_cloud(cloud)
    if len(cloud) < 100:
        raise PointCloudError(f"{cloud.source}: {len(cloud)} points are too few to find a "
                              "facade; give a scan of a building")
    if photos is not None or cameras is not None:
        cloud = _colour(cloud, photos, cameras)
    origin = np.floor(cloud.xyz.min(0))
    timings["load"] = time.perf_counter() - t

    t = time.perf_counter()
    planes = detect_planes(cloud, seed=seed)
    timings["planes"] = time.perf_counter() - t
    ground = [p for p in planes if p.kind == "ground"]
    ground_level = float(np.median(cloud.xyz[ground[0].inliers, cloud.up])) if ground else None
    facade_ids = [i for i, p in enumerate(planes) if p.kind == "facade"][:max_facades]
    on_ground = np.zeros(len(cloud), bool)
    for g in ground:
        on_ground[g.inliers] = True

    facades: list[FacadeResult] = []
    whole: list[PlaneFacade] = []
    store = None
    ground_at = _Ground(cloud, ground)
    t_maps = t_el = t_rec = 0.0
    for pi in facade_ids:
        t = time.perf_counter()
        frame = facade_frame(cloud, planes[pi],
                             ground_level=ground_at.at(cloud, planes[pi], ground_level))
        if store is None:       # CityFit §3's store: a facade's points by a box query
            from .store import PointStore

            store = PointStore.from_cloud(cloud)
            store.engine = "numpy"       # a few queries: no kernels to compile or load
        idx, uvd = facade_points(cloud, frame, exclude=on_ground,
                                 candidates=store.box(*facade_box(frame)))
        res = resolution if resolution is not None else auto_resolution(planes[pi])
        maps = rasterize(cloud, frame, resolution=res, index=idx, uvd=uvd)
        ortho = ortho_image(maps)
        t_maps += time.perf_counter() - t
        t = time.perf_counter()
        elements = detect_elements(maps)
        t_el += time.perf_counter() - t
        whole.append(PlaneFacade(pi, frame, maps, elements, ortho, idx))
        for seg in segments(maps, elements):
            sub = maps.crop(seg.x0, seg.x1, seg.top)
            f = FacadeResult(index=len(facades), plane=pi, frame=sub.frame, maps=sub,
                             elements=_shift(elements, seg, sub),
                             ortho=np.ascontiguousarray(ortho[seg.top:, seg.x0:seg.x1]),
                             offset_u=seg.x0 * res, whole=len(whole) - 1)
            t = time.perf_counter()
            _structure(f, model=model, origin=origin, up=cloud.up, seed=seed, fit=fit,
                       budget=budget)
            t_rec += time.perf_counter() - t
            facades.append(f)
    timings.update(maps=t_maps, elements=t_el, structure=t_rec)

    result = PointsResult(cloud=cloud, planes=planes, facades=facades, origin=origin,
                          inputs=inputs, whole=whole)
    t = time.perf_counter()
    accuracy = _accuracy(result)
    timings["accuracy"] = time.perf_counter() - t
    result.report = _report(result, timings)
    result.report["accuracy"] = accuracy
    if not facades:
        result.report["notes"] = [
            "no facade plane: a facade is a vertical plane at least "
            f"{FACADE_MIN_WIDTH} m wide and {FACADE_MIN_HEIGHT} m high; planes found: "
            + (", ".join(sorted({p.kind for p in planes})) or "none")]
    if out_dir is not None:
        t = time.perf_counter()
        result.save(out_dir)
        timings["write"] = time.perf_counter() - t
    timings["total"] = sum(v for k, v in timings.items() if k != "total")
    return result


#: Spacing (m) of the points sampled on the model for eq. 5.10–5.11.
ACCURACY_SPACING = 0.1


def _accuracy(r: PointsResult) -> dict:
    """``simon2011`` eq. 5.10 (model → scan, any class) and, for a labelled scan, eq. 5.11 per
    class, on the facades' own points (cm)."""
    from .evaluate import class_distances, model_distance, model_triangles, sample_model

    models = r.models()
    if not models:
        return {}
    tris, labels = model_triangles(models, r.origin)
    pts, lab = sample_model(tris, labels, spacing=ACCURACY_SPACING)
    keep = np.zeros(len(r.cloud), bool)
    for w in r.whole:
        keep[w.index] = True
    out = {"spacing_m": ACCURACY_SPACING, "eq_5_10": model_distance(pts, r.cloud.xyz[keep])}
    if r.cloud.labels is not None:
        out["eq_5_11"] = class_distances(pts, lab, r.cloud.subset(keep),
                                         classes=("wall", "window", "door", "balcony", "roof"))
    return out


#: Cell of the rasters against the facade's point spacing (``auto_resolution``), and bounds (m).
SPACING_SHARE, MIN_RESOLUTION, MAX_RESOLUTION = 0.8, RESOLUTION, 0.25


def auto_resolution(plane: Plane) -> float:
    """A raster cell for a facade plane from its point spacing: :data:`SPACING_SHARE` of the
    mean spacing of its inliers (its area over its point count), within
    [:data:`MIN_RESOLUTION`, :data:`MAX_RESOLUTION`] — a sparse scan gets cells that still hold
    points, a dense one the detail of 5 cm cells."""
    if plane.area <= 0 or not len(plane.inliers):
        return RESOLUTION
    spacing = float(np.sqrt(plane.area / len(plane.inliers)))
    return float(np.clip(round(SPACING_SHARE * spacing, 3), MIN_RESOLUTION, MAX_RESOLUTION))


class _Ground:
    """The ground pieces' points once, for the ground's height in front of each facade."""

    def __init__(self, cloud: PointCloud, ground: list[Plane]):
        self.up = cloud.up
        idx = [g.inliers for g in ground]
        self.xyz = cloud.xyz[np.concatenate(idx)] if idx else np.zeros((0, 3))
        self.piece = np.repeat(np.arange(len(idx)), [len(i) for i in idx])
        self.height = [float(np.median(cloud.xyz[i, cloud.up])) for i in idx]

    def at(self, cloud: PointCloud, plane: Plane, level: float | None) -> float | None:
        """The ground's height in front of a facade: the ground piece nearest to its foot."""
        if not len(self.xyz):
            return level
        foot = cloud.xyz[plane.inliers]
        c = foot[np.argmin(foot[:, self.up])]
        horiz = np.delete(self.xyz - c, self.up, axis=1)
        j = int(np.argmin(np.einsum("ij,ij->i", horiz, horiz)))
        return self.height[int(self.piece[j])]


def _colour(cloud: PointCloud, photos, cameras) -> PointCloud:
    if photos is None or cameras is None:
        raise InputError("--photos and --cameras go together: give the photo folder and its "
                         "cameras (VisualSFM cameras_v2.txt, Bundler bundle.out, COLMAP model)")
    from ..datasets.cameras import read_cameras
    from .colour import colour_from_photos

    cams = read_cameras(cameras)
    if isinstance(photos, (str, os.PathLike)):
        from ..datasets.cameras import photo_files

        photos = photo_files(photos, cams, "--photos")
    return colour_from_photos(cloud, photos, {k: cams[k] for k in photos if k in cams})


def _structure(f: FacadeResult, *, model: bool, origin: np.ndarray, up: int, seed: int,
               fit: str = "elements", budget: int = 600) -> None:
    """Stage 5–6 for one facade (module docstring)."""
    from ..grammar.extract import extract_rules
    from ..imaging.shape_tree import PixelFrame
    from ..reconstruction import _derive_model, reconstruct

    maps = f.maps
    elements = [e for e in f.elements if e.label in _CLASSES]
    clf = _map_classifier(elements)
    try:
        rec = reconstruct(f.ortho, rectified=True, width_m=maps.shape[1] * maps.resolution,
                          height_m=maps.shape[0] * maps.resolution, classifier=clf,
                          repair=False, model=False, seed=seed)
    except InputError as e:               # a facade too small or too odd for the analysis
        f.report["structure"] = f"not modelled: {e}"
        return
    measured = 0
    wall = wall_depth(maps)
    for leaf in rec.tree.leaves():
        if leaf.label in ("window", "door", "balcony") and "box_px" in leaf.tags:
            d = _measured_depth(maps, wall, leaf.tags["box_px"], leaf.label)
            if d is not None:
                leaf.tags["depth"] = round(d, 4)
                measured += 1
    rec.rules = extract_rules(rec.tree, texture="texture.jpg", depths={})
    f.rec, f.tree, f.rules, f.source = rec, rec.tree, rec.rules, "elements"
    f.report["measured_depths"] = measured
    if fit == "grammar":
        _fit_grammar(f, budget=budget, seed=seed)
    if not model:
        return
    if f.source == "elements":
        frame = PixelFrame(maps.shape[1], maps.shape[0], (1 / maps.resolution,) * 2)
        m, rec.workdir = _derive_model(rec, frame)
    else:
        from ..engine import derive_facade, load_rules

        m = derive_facade(load_rules(f.rules), maps.shape[1] * maps.resolution,
                          maps.shape[0] * maps.resolution, name="facade")
        f.tree = m.root
    m.name = f"facade_{f.index:02d}"
    f.model = _place(m, f.frame, origin, up)


def _fit_grammar(f: FacadeResult, *, budget: int, seed: int) -> None:
    """``--fit grammar``: the grid grammar fitted with E_a and E_d (:mod:`.fit`); its derivation
    replaces the element layout when the automatic α prefers it."""
    from ..parsing.fit import grammar_path
    from ..parsing.parse import write_fitted_rules
    from .fit import fit_facade

    df = fit_facade(f.maps, f.elements, f.tree, budget=budget, seed=seed)
    f.report["fit"] = {"chosen": df.chosen, "energies": df.energies,
                       "alpha": round(df.alpha, 6),
                       "alpha_range": [round(float(v), 6) for v in df.alpha_range],
                       "pareto_size": len(df.front), "derivations": df.fit.search.derivations,
                       "seconds": round(df.fit.search.seconds, 3)}
    f.report["class_depths"] = {k: round(v, 4) for k, v in df.depths.items()}
    if df.chosen != "grammar":
        return
    depth_attrs = {f"{k}Depth": v for k, v in df.depths.items()}
    text = Path(grammar_path("grid")).read_text(encoding="utf-8")
    f.rules = write_fitted_rules(text, {**df.fit.attrs, **depth_attrs})
    f.source = "grammar"
    from ..engine import derive_facade, load_rules

    f.tree = derive_facade(load_rules(f.rules), df.fit.width_m,
                           f.maps.shape[0] * f.maps.resolution, name="facade").root


def _planes_report(r: PointsResult) -> list[dict]:
    """``planes.json``: every RANSAC plane; a facade plane holding houses of different heights
    (several segments, :mod:`.outline`) is listed once per house — the facades of a street
    front on one line are coplanar, not one facade."""
    out = []
    for i, p in enumerate(r.planes):
        d = {"index": i, **p.to_dict()}
        segs = [f for f in r.facades if f.plane == i]
        if p.kind != "facade" or len(segs) < 2:
            out.append(d)
            continue
        pts = r.cloud.xyz[p.inliers]
        for f in segs:
            fu = (pts - f.frame.origin) @ f.frame.u
            sel = pts[(fu >= 0) & (fu < f.frame.width)]
            out.append({**d, "facade": f.index, "points": int(len(sel)),
                        "centroid": [round(float(v), 4) for v in
                                     (sel.mean(0) if len(sel) else p.centroid)],
                        "width_m": round(f.frame.width, 3), "height_m": round(f.frame.height, 3)})
    return out


def _report(r: PointsResult, timings: dict) -> dict:
    from collections import Counter

    c = r.cloud
    lo, hi = c.bounds
    facades = []
    for f in r.facades:
        els = _final_elements(f)
        facades.append({
            "index": f.index, "plane": f.plane, "frame": f.frame.to_dict(),
            "offset_along_plane_m": round(f.offset_u, 3),
            "raster": {"width": int(f.maps.shape[1]), "height": int(f.maps.shape[0]),
                       "resolution_m": f.maps.resolution},
            "points": int(f.maps.count.sum()),
            "detected": dict(Counter(e.label for e in f.elements)),
            "structure": f.source,
            "elements": dict(Counter(e.label for e in els)),
            **f.report})
    return {
        "input": {"cloud": c.source, "points": len(c), "crs": c.crs, "up": int(c.up),
                  "bounds": [[round(float(v), 4) for v in lo], [round(float(v), 4) for v in hi]],
                  "attributes": [n for n in ("intensity", "rgb", "normals", "labels")
                                 if getattr(c, n) is not None]},
        "origin": [float(v) for v in r.origin],
        "axes": "model.glb/.obj: CGA axes (x, y up, z = -cloud y) relative to origin; "
                "model.city.json: cloud axes, origin added back",
        "planes": _planes_report(r),
        "facades": facades,
        "timings": timings,
    }


def _leaves_image(f: FacadeResult) -> np.ndarray:
    """``structure.png`` of a fitted grammar: the orthophoto with its leaves' labels tinted."""
    from ..exchange.raster import PALETTE, label_map

    lab = label_map(f.tree, size=f.maps.shape)
    colours = PALETTE[lab].astype(np.float32)
    return np.clip(0.6 * f.ortho + 0.4 * colours, 0, 255).astype(np.uint8)


def _write(r: PointsResult, stage: Path) -> None:
    from PIL import Image

    from ..exchange import export
    from ..outdir import write_json
    from ..reconstruction import structure_image

    write_json(stage / "planes.json", {"planes": r.report["planes"]})
    for f in r.facades:
        d = stage / f"facade_{f.index:02d}"
        d.mkdir()
        Image.fromarray(depth_image(f.maps)).save(d / "depth.png")
        Image.fromarray(f.ortho).save(d / "ortho.png")
        if f.rec is not None and f.source == "elements":
            Image.fromarray(structure_image(f.rec)).save(d / "structure.png")
        elif f.tree is not None:
            Image.fromarray(_leaves_image(f)).save(d / "structure.png")
        if f.tree is not None:
            write_json(d / "shape_tree.json", f.tree.to_dict())
            (d / "rules.cga").write_text(f.rules, encoding="utf-8")
            from ..reconstruction import _write_gml

            _write_gml(f.tree, d / "rules.gml", f.report)
        np.savez_compressed(d / "maps.npz", depth=f.maps.depth.astype(np.float32),
                            front=f.maps.front.astype(np.float32), count=f.maps.count,
                            resolution=f.maps.resolution)
    write_json(stage / "elements.json", {"elements": r.elements(),
                                         "frame": "cloud coordinates, metres"})
    models = r.models()
    if models:
        for m in models:
            # CGA axes, as footprints record it (CityJSON maps it back to x, y, z up)
            m.attributes["_origin_offset"] = [float(v) for v in _TO_CGA @ r.origin]
            if r.cloud.crs:
                m.attributes["_crs"] = r.cloud.crs
        export(models, stage / "model.glb")
        export(models, stage / "model.obj")
        export(models, stage / "model.city.json")
    write_json(stage / "report.json", r.report)
