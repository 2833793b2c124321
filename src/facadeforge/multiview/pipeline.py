"""Calibrated photo set → whole 3D building: ``facadeforge multiview`` and :func:`multiview`
(``simon2011`` ch. 5).

Stages (each timed in ``report["timings"]``):

1. **load** — the photos and their cameras (:func:`facadeforge.datasets.cameras.read_cameras`:
   VisualSFM, Bundler, COLMAP), paired by id or file name;
2. **classify** — each photo's class probabilities from the shipped street classifier (``ecp7``;
   §5.3.1's pixel likelihood, as the single-view ``parse`` uses it);
3. **stereo** — a dense coloured cloud and a depth map per photo (:mod:`.mvs`), or the points of a
   given cloud in the cameras' frame (``cloud=``: PMVS, COLMAP, a laser scan registered to them,
   as the thesis takes PMVS's, §5.1);
4. **frame** — the local metric z-up frame (:mod:`.frame`): up from the photos and the ground
   plane, metres from the cameras' eye height, unless ``metres_per_unit`` is given;
5. **planes** — RANSAC planes of the cloud (:func:`facadeforge.points.planes.detect_planes`,
   CityFit §3); the vertical ones wide and high enough are facades; facades meeting at a corner
   belong to one building;
6. **evidence** — per facade, its orthographic rasters (:mod:`facadeforge.points.maps`): the
   cloud's depth relative to the wall, and the photos' class probabilities fused over every
   view that sees the cell unoccluded (:mod:`.appearance`, eq. 5.4–5.8) with the facade's
   texture from the photos;
7. **fit** — the ``grid`` parse grammar fitted with E_a and E_d (eq. 5.9) as two objectives,
   SPEA-II, the automatic α and the solution's strength (§5.2.3;
   :func:`facadeforge.parsing.fit.fit_grammar`), largest facade of a building first; the other
   facades of the building keep its floor heights in metres (Fig. 5.14);
8. **model** — every facade's fitted rules derived on its rectangle, placed in the local frame;
   its labels rendered into every photo (:mod:`.labels`).

OUTDIR: ``model.glb``, ``model.obj``, ``model.city.json`` (local frame, metres, z up; the 4 × 4
local → cameras matrix is ``report["frame"]["local_to_world"]``), ``cloud.ply`` (the fused cloud,
local frame), ``labels/NAME.png`` (each photo's labels from the model, 8-bit class ids as
RueMonge stores them: 0 unlabelled, 1 window, 2 wall, 3 balcony, 4 door, 5 roof, 6 sky, 7 shop)
and ``labels_color/NAME.png``, ``pareto.png``, ``facade_NN/`` (``ortho.png``, ``depth.png``,
``evidence.png``, ``structure.png``, ``rules.cga``, ``rules.gml``, ``shape_tree.json``) and
``report.json`` (frame, planes, per facade α, its range, energies, the Pareto set; timings).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..datasets import get_label_set
from ..datasets.cameras import Camera
from ..errors import InputError
from ..points.cloud import PointCloud
from ..points.maps import FacadeFrame, FacadeMaps
from .appearance import FacadeEvidence, ViewEvidence, fuse
from .frame import BuildingFrame

__all__ = ["MultiviewResult", "multiview", "load_photo_set"]

#: Facades modelled, largest first.
MAX_FACADES = 8
#: Raster cell (m) of the facade evidence.
RESOLUTION = 0.1
#: Derivations of the grammar search per facade (the thesis allows 20,000 per facade, §5.4.3).
BUDGET = 1500
#: Offset (m) within which parallel facade planes are pieces of one wall.
MERGE_OFFSET = 0.6
#: Distance (m) between the ends of two facades that meet at a corner of one building.
CORNER_GAP = 2.5
#: Storey attributes of the ``grid`` grammar shared by the facades of one building.
_STOREYS = ("groundTop", "nFloors", "roofLine", "atticFrac", "roofFrac", "balconyFrac")
#: Guess of the median distance (m) from a street photo to what it sees, used only until the
#: ground plane gives the scale.
_STREET_DEPTH_M = 9.0
#: RANSAC inlier distance (m): stereo points scatter more than a laser's.
_PLANE_THRESHOLD = 0.08
#: Rounds of frame estimation (planes → up and scale → planes) at most.
_FRAME_ROUNDS = 4


@dataclass
class FacadeFit:
    index: int
    plane: int
    building: int
    frame: FacadeFrame                 # local frame
    maps: FacadeMaps
    evidence: FacadeEvidence
    fit: object = None                 # parsing.fit.FitResult
    rules: str = ""
    tree: object = None
    model: object = None
    depths: dict = field(default_factory=dict)
    report: dict = field(default_factory=dict)


@dataclass
class MultiviewResult:
    views: list[ViewEvidence]
    frame: BuildingFrame
    cloud: PointCloud                  # local frame
    planes: list
    facades: list[FacadeFit]
    labels: dict[str, np.ndarray]      # photo id → canonical labels
    report: dict = field(default_factory=dict)
    inputs: dict = field(default_factory=dict)

    def models(self) -> list:
        return [f.model for f in self.facades if f.model is not None]

    def save(self, out_dir: str | os.PathLike) -> list[Path]:
        from ..outdir import write_outdir

        return write_outdir(Path(out_dir), lambda stage: _write(self, stage), self.inputs)


# --------------------------------------------------------------------------------- loading

def load_photo_set(photos, cameras, *, max_photos: int = 400
                   ) -> tuple[dict[str, np.ndarray], dict[str, Camera]]:
    """Photos (a folder, or a mapping id → path or array) and cameras (a file or a mapping id
    → :class:`Camera`) paired by id: the camera's id, or its file name's stem."""
    from ..datasets.folder import read_image

    if isinstance(cameras, (str, os.PathLike)):
        from ..datasets.cameras import read_cameras

        cams = read_cameras(cameras)
    else:
        cams = dict(cameras)
    if isinstance(photos, (str, os.PathLike)):
        from ..datasets.cameras import photo_files

        photos = photo_files(photos, cams)
    images: dict[str, np.ndarray] = {}
    for cid in sorted(photos):
        if cid not in cams:
            raise InputError(f"photo {cid}: the cameras file has no camera of that name")
        src = photos[cid]
        images[cid] = src if isinstance(src, np.ndarray) else read_image(src)
        if len(images) > max_photos:
            raise InputError(f"more than {max_photos} photos: reconstruct one building (the "
                             "photos that see it) at a time")
    if len(images) < 2:
        raise InputError(f"{len(images)} photo with a camera: multi-view needs at least two "
                         "calibrated photos of the building")
    return images, {k: cams[k] for k in images}


def classify_views(images: dict[str, np.ndarray], cameras: dict[str, Camera], classifier=None,
                   probabilities: dict[str, np.ndarray] | None = None) -> list[ViewEvidence]:
    """Each photo's ``ecp7`` class probabilities: given (``probabilities``, id → ``(h, w, 7)``
    at any resolution of the photo's aspect) or from the classifier at its own scale."""
    ls = get_label_set("ecp7")
    out = []
    clf = None
    for cid, img in images.items():
        if probabilities is not None and cid in probabilities:
            prob = np.asarray(probabilities[cid], np.float32)
            if prob.ndim != 3 or prob.shape[2] != ls.num_classes:
                raise InputError(f"probabilities of photo {cid}: expected (h, w, "
                                 f"{ls.num_classes}) ecp7 probabilities, got {prob.shape}")
        else:
            if clf is None:
                from ..classify import resolve_classifier

                clf = resolve_classifier(classifier, "ecp7")
            prob = get_label_set(clf.label_set).project_proba(clf.predict_proba_coarse(img),
                                                              clf.classes)
        out.append(ViewEvidence(cid, cameras[cid], img, prob.astype(np.float32)))
    return out


# ----------------------------------------------------------------------------- the frame

def _local_cloud(cloud: PointCloud, frame: BuildingFrame) -> PointCloud:
    return PointCloud(frame.to_local(cloud.xyz), intensity=cloud.intensity, rgb=cloud.rgb,
                      up=2, source=cloud.source)


def _find_frame(cloud: PointCloud, cameras: dict[str, Camera], shapes, metres_per_unit,
                seed: int) -> tuple[BuildingFrame, PointCloud, list]:
    """The local frame (module docstring, stage 4) and the planes found in it: a provisional
    frame from the photos, then rounds of planes → up (the walls pin the vertical down,
    :func:`.vertical`; then the ground plane's normal) and scale (eye height above the ground,
    or the largest wall's foot) → planes again, until up turns by less than 0.5° and the scale
    changes by less than 1 %."""
    from ..points.planes import detect_planes
    from .frame import initial_frame

    centres = np.array([c.C for c in cameras.values()])
    frame = initial_frame(cameras, shapes, metres_per_unit=metres_per_unit)
    if metres_per_unit is None:          # a provisional scale: the median depth of the points
        sample = cloud.xyz[:: max(1, len(cloud) // 20000)]
        d = np.concatenate([cameras[k].depth(sample) for k in list(cameras)[:8]])
        d = d[d > 0]
        if len(d):
            frame.scale = _STREET_DEPTH_M / float(np.median(d))
            frame.scale_source = "typical street depth (no ground plane found)"

    def planes_in(fr: BuildingFrame):
        loc = _local_cloud(cloud, fr)
        return loc, detect_planes(loc, seed=seed, threshold=_PLANE_THRESHOLD)

    local, planes = planes_in(frame)
    for _ in range(_FRAME_ROUNDS):     # until up and scale settle
        steep = [p for p in planes[:12] if abs(p.normal[2]) < 0.5 and len(p.inliers) >= 0.2
                 * max(len(q.inliers) for q in planes[:12])]
        normals = np.array([p.normal @ frame.rotation for p in steep[:3]]) if steep else None
        new = initial_frame(cameras, shapes, metres_per_unit=metres_per_unit,
                            facade_normals=normals)
        new.scale, new.scale_source = frame.scale, frame.scale_source
        ground = [p for p in planes if p.kind == "ground"]
        g = max(ground, key=lambda p: len(p.inliers)) if ground else None
        n_world = None if g is None else g.normal @ frame.rotation
        pt_world = None if g is None else frame.to_world(local.xyz[g.inliers].mean(0))[0]
        walls = [p for p in planes if p.kind == "facade"]
        if g is None and walls:
            # no pavement in the cloud: the foot of the largest wall stands on the ground
            foot = np.percentile(local.xyz[walls[0].inliers, 2], 1)
            pt_world = frame.to_world(np.array([0.0, 0.0, foot]))[0]
        new = new.refine(n_world, pt_world, centres, metres_per_unit=metres_per_unit)
        if g is None and walls and metres_per_unit is None:
            new.scale_source = "eye height above the foot of the largest wall (no ground plane)"
        turn = np.degrees(np.arccos(np.clip(new.up_world @ frame.up_world, -1, 1)))
        settled = turn < 0.5 and abs(new.scale / frame.scale - 1) < 0.01
        frame = new
        local, planes = planes_in(frame)
        if settled:
            break
    return frame, local, planes


def _facing(planes: list, local: PointCloud, centres_local: np.ndarray) -> None:
    """Turn every facade plane's normal towards the cameras: a photo sees a wall's front."""
    from ..points.planes import _flip

    c = centres_local.mean(0)
    for p in planes:
        if p.kind == "facade" and (c @ p.normal + p.offset) < 0:
            _flip(p)


def _merged_facades(planes: list, local: PointCloud) -> list:
    """The facade planes with the pieces of one wall joined: RANSAC returns a facade whose
    shop fronts or upper floors stand a few centimetres apart as several parallel planes; planes
    within :data:`MERGE_OFFSET` m of each other, parallel to 10° and overlapping or touching
    along the wall, become one — the largest one's plane, all their points."""
    from dataclasses import replace

    idx = [i for i, p in enumerate(planes) if p.kind == "facade"]
    groups: list[list[int]] = []
    for i in idx:                               # largest first (RANSAC's order)
        p = planes[i]
        u = np.cross([0.0, 0.0, 1.0], p.normal)
        u /= max(np.linalg.norm(u), 1e-12)
        span = np.percentile(local.xyz[p.inliers] @ u, [1, 99])
        for g in groups:
            q = planes[g[0]]
            if abs(p.normal @ q.normal) < np.cos(np.radians(10)):
                continue
            off = abs(float(np.median(local.xyz[p.inliers] @ q.normal)) + q.offset)
            gspan = np.percentile(local.xyz[np.concatenate([planes[j].inliers for j in g])] @ u,
                                  [1, 99])
            if off <= MERGE_OFFSET and span[0] <= gspan[1] + 1.0 and gspan[0] <= span[1] + 1.0:
                g.append(i)
                break
        else:
            groups.append([i])
    out = []
    for g in groups:
        main = planes[g[0]]
        inl = np.unique(np.concatenate([planes[j].inliers for j in g]))
        out.append((g[0], replace(main, inliers=inl, area=sum(planes[j].area for j in g))))
    return out


def _buildings(frames: list[FacadeFrame]) -> list[int]:
    """A building id per facade: facades whose ends meet at a corner (within
    :data:`CORNER_GAP`, not parallel) share one (connected components of that relation)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    ends = [(f.origin, f.origin + f.width * f.u) for f in frames]
    pairs = [(i, j) for i in range(len(frames)) for j in range(i + 1, len(frames))
             if abs(frames[i].n @ frames[j].n) <= 0.7
             and min(np.linalg.norm((a - b)[:2]) for a in ends[i] for b in ends[j]) <= CORNER_GAP]
    n = len(frames)
    if not n:
        return []
    r = [i for i, _ in pairs]
    c = [j for _, j in pairs]
    _, ids = connected_components(coo_matrix((np.ones(len(r)), (r, c)), shape=(n, n)),
                                  directed=False)
    order = {b: k for k, b in enumerate(dict.fromkeys(ids.tolist()))}
    return [order[b] for b in ids.tolist()]


# ------------------------------------------------------------------------------ fitting

def _class_depths(rel: np.ndarray, prob: np.ndarray, ls) -> dict[str, float]:
    """Measured depth (m, relative to the wall) of the classes the photos see on the facade:
    the median over the cells where the class is the likeliest."""
    top = np.argmax(prob, axis=2)
    out = {}
    for lab in ("window", "door", "balcony", "shop"):
        if lab not in ls.classes:
            continue
        m = (top == ls.index(lab)) & np.isfinite(rel)
        if m.sum() >= 20:
            d = float(np.median(rel[m]))
            lo, hi = (-0.8, 0.0) if lab != "balcony" else (0.0, 1.5)
            out[lab] = float(np.clip(d, lo, hi))
    return out


def _shared_storeys(attrs: dict, height_from: float, height_to: float) -> dict:
    """The storey attributes of a fitted facade for another facade of the building: floor lines
    kept at the same heights in metres (the grammar's fractions rescaled by the heights)."""
    out = {}
    ratio = height_from / max(height_to, 1e-6)
    for k, v in attrs.items():
        if k == "nFloors":
            out[k] = v
        elif k in _STOREYS or k.startswith("floor") and k[5:].isdigit():
            if k in ("atticFrac", "roofFrac", "balconyFrac"):
                out[k] = v
            else:
                out[k] = float(np.clip(v * ratio, 0.0, 1.0))
    return out


def _fit(f: FacadeFit, *, rules, text: str, budget: int, seed: int, fixed: dict,
         use_depth: bool = True) -> None:
    from ..engine import derive_facade, load_rules
    from ..parsing.fit import fit_grammar
    from ..parsing.init import initialiser_for, pinned_for
    from ..parsing.parse import write_fitted_rules
    from ..points.elements import wall_depth

    ls = get_label_set("ecp7")
    rel = f.maps.depth - wall_depth(f.maps)[None, :]
    depths = _class_depths(rel, f.evidence.prob, ls)
    width = f.maps.shape[1] * f.maps.resolution
    pins = {**pinned_for(rules, ls), "facadeWidth": width, **fixed}
    t = time.perf_counter()
    fit = fit_grammar(f.evidence.prob, ls, rules, method="evolution", budget=budget, seed=seed,
                      fixed=pins, initialiser=initialiser_for(rules, one_facade=True),
                      depth=rel if use_depth else None, depths=depths)
    seconds = time.perf_counter() - t
    s = fit.search
    from ..parsing.energy import DepthEnergy, SegmentationEnergy
    from ..parsing.fit import ENERGY_SIDE, _resize_depth, shrink_proba

    small = shrink_proba(f.evidence.prob, ENERGY_SIDE)
    chosen = [SegmentationEnergy(small, ls)(fit.layout),
              DepthEnergy(_resize_depth(rel.astype(np.float32), small.shape[:2]), depths)(
                  fit.layout)]
    f.fit, f.depths = fit, depths
    f.rules = write_fitted_rules(text, {**fit.attrs, **{f"{k}Depth": v for k, v in depths.items()}})
    height = f.maps.shape[0] * f.maps.resolution
    f.tree = derive_facade(load_rules(f.rules), fit.width_m, height, name="facade").root
    f.report.update({
        "fit": {"alpha": _r(getattr(s, "alpha", None)),
                "alpha_range": [_r(v) for v in (getattr(s, "alpha_range", None) or ())],
                "strength": _r(_strength(getattr(s, "alpha_range", None))),
                "energies": [_r(v) for v in chosen],
                "pareto": [[_r(a), _r(b)] for a, b in (getattr(s, "front", None) or [])],
                "derivations": int(s.derivations), "seconds": round(seconds, 3)},
        "class_depths_m": {k: round(v, 3) for k, v in depths.items()},
        "shared_storeys": sorted(fixed), "attrs": fit.attrs,
        "elements": {lab: sum(1 for leaf in f.tree.leaves() if leaf.label == lab)
                     for lab in ("window", "door", "balcony", "shop")}})


def _strength(rng) -> float | None:
    return None if not rng else float(rng[1] - rng[0])


def _r(v, nd: int = 6):
    return None if v is None else round(float(v), nd)


# ------------------------------------------------------------------------------ pipeline

def multiview(photos, cameras, *, cloud=None, metres_per_unit: float | None = None, classifier=None, budget: int = BUDGET, resolution: float = RESOLUTION,
              max_facades: int = MAX_FACADES, seed: int = 0,
              out_dir: str | os.PathLike | None = None, stereo_options: dict | None = None,
              probabilities: dict[str, np.ndarray] | None = None, depth_energy: bool = True
              ) -> MultiviewResult:
    """Reconstruct the building a calibrated photo set shows (module docstring).

    Parameters
    ----------
    photos : folder, or mapping id → path or (H, W, 3) array
    cameras : camera file (VisualSFM ``cameras_v2.txt``, Bundler ``bundle.out``, COLMAP text
        model) or mapping id → :class:`~facadeforge.datasets.cameras.Camera`
    cloud : path or PointCloud, optional
        A cloud in the cameras' frame to use instead of the stereo.
    metres_per_unit : float, optional
        The cameras' scale; by default from their eye height above the ground plane.
    probabilities : mapping id → (h, w, 7), optional
        The photos' ``ecp7`` class probabilities from elsewhere (another segmentation, or the
        perfect cues of the thesis's artificial experiments, §5.4.2) instead of the classifier.
    """
    from ..parsing.fit import grammar_path
    from ..parsing.parse import _load_grammar, _stamp
    from ..points.maps import facade_frame, facade_points, rasterize

    timings: dict[str, float] = {}
    inputs = {"photos": photos, "--cameras": cameras, "--cloud": cloud}
    if out_dir is not None:
        from ..outdir import check_outdir

        check_outdir(out_dir, {k: v for k, v in inputs.items()
                               if isinstance(v, (str, os.PathLike))})
    if not isinstance(budget, int) or budget < 1:
        raise InputError(f"--budget {budget}: give a positive number of derivations")
    if metres_per_unit is not None and not (0 < metres_per_unit < 1e6):
        raise InputError(f"--scale {metres_per_unit}: give the metres one camera unit spans (> 0)")
    t = time.perf_counter()
    images, cams = load_photo_set(photos, cameras)
    shapes = {k: v.shape[:2] for k, v in images.items()}
    timings["load"] = time.perf_counter() - t

    t = time.perf_counter()
    views = classify_views(images, cams, classifier, probabilities)
    timings["classify"] = time.perf_counter() - t

    t = time.perf_counter()
    stereo_report: dict = {}
    if cloud is None:
        from .mvs import dense_cloud

        mvs = dense_cloud(images, cams, seed=seed, **(stereo_options or {}))
        world_cloud = mvs.cloud
        for v in views:
            dm = mvs.depths.get(v.id)
            if dm is not None:
                v.depth = dm
                v.depth_scale = (dm.shape[1] / v.shape[1], dm.shape[0] / v.shape[0])
        stereo_report = mvs.report
    else:
        from ..points.io import read_cloud

        world_cloud = cloud if isinstance(cloud, PointCloud) else read_cloud(cloud)
    if len(world_cloud) < 200:
        raise InputError(f"the photos give {len(world_cloud)} 3D points, too few for a facade: "
                         "give overlapping photos of the building (neighbours a few metres "
                         "apart), or a cloud with --cloud")
    timings["stereo"] = time.perf_counter() - t

    t = time.perf_counter()
    frame, local, planes = _find_frame(world_cloud, cams, shapes, metres_per_unit, seed)
    timings["frame_planes"] = time.perf_counter() - t

    t = time.perf_counter()
    ground = [p for p in planes if p.kind == "ground"]
    ground_level = float(np.median(local.xyz[ground[0].inliers, 2])) if ground else None
    _facing(planes, local, frame.to_local(np.array([c.C for c in cams.values()])))
    walls = _merged_facades(planes, local)[:max_facades]
    on_ground = np.zeros(len(local), bool)
    for g in ground:
        on_ground[g.inliers] = True
    facades: list[FacadeFit] = []
    for pi, wall in walls:
        fr = facade_frame(local, wall, ground_level=ground_level)
        idx, uvd = facade_points(local, fr, exclude=on_ground)
        maps = rasterize(local, fr, resolution=resolution, index=idx, uvd=uvd)
        ev = fuse(fr, maps.shape, maps.resolution, views, frame)
        facades.append(FacadeFit(len(facades), pi, 0, fr, maps, ev))
    for f, b in zip(facades, _buildings([f.frame for f in facades])):
        f.building = b
    timings["evidence"] = time.perf_counter() - t

    t = time.perf_counter()
    gpath = grammar_path("grid")
    rules, _ = _load_grammar(str(gpath), *_stamp(gpath))
    text = Path(gpath).read_text(encoding="utf-8")
    first: dict[int, FacadeFit] = {}
    for f in sorted(facades, key=lambda f: -f.frame.width * f.frame.height):
        fixed = {}
        lead = first.get(f.building)
        if lead is not None and lead.fit is not None:
            fixed = _shared_storeys(lead.fit.attrs, lead.maps.shape[0], f.maps.shape[0])
        try:
            _fit(f, rules=rules, text=text, budget=budget, seed=seed, fixed=fixed,
                 use_depth=depth_energy)
        except InputError as e:
            f.report["fit"] = f"not modelled: {e}"
            continue
        first.setdefault(f.building, f)
    timings["fit"] = time.perf_counter() - t

    t = time.perf_counter()
    from ..points.pipeline import _place

    for f in facades:
        if f.tree is None:
            continue
        from ..engine import derive_facade, load_rules

        m = derive_facade(load_rules(f.rules), f.fit.width_m, f.maps.shape[0] * f.maps.resolution,
                          name=f"facade_{f.index:02d}")
        f.model = _place(m, f.frame, np.zeros(3), 2)
    labels = _render_labels(facades, views, frame)
    timings["model_labels"] = time.perf_counter() - t

    result = MultiviewResult(views=views, frame=frame, cloud=local, planes=planes,
                             facades=facades, labels=labels, inputs=inputs)
    result.report = _report(result, timings, stereo_report)
    if not any(f.model is not None for f in facades):
        result.report["notes"] = [
            "no facade modelled: the photos' cloud has no vertical plane wide and high enough "
            "(planes: " + (", ".join(sorted({p.kind for p in planes})) or "none") + ")"]
    if out_dir is not None:
        t = time.perf_counter()
        result.save(out_dir)
        timings["write"] = time.perf_counter() - t
    timings["total"] = sum(v for k, v in timings.items() if k != "total")
    result.report["timings"] = {k: round(v, 3) for k, v in timings.items()}
    return result


def model_triangles_local(models) -> tuple[np.ndarray, list[str]]:
    """Triangles of placed facade models (CGA axes, local origin) in the local frame."""
    from ..points.evaluate import model_triangles

    return model_triangles(models, np.zeros(3))


def _render_labels(facades, views, frame: BuildingFrame) -> dict[str, np.ndarray]:
    from ..parsing.fit import EVIDENCE
    from .labels import blend, model_label_indices, render_labels

    models = [f.model for f in facades if f.model is not None]
    tris, names = model_triangles_local(models)
    world = frame.to_world(tris.reshape(-1, 3)).reshape(-1, 3, 3) if len(tris) else tris
    idx = model_label_indices(names)
    ls = get_label_set("ecp7")
    out = {}
    for v in views:
        lab, _ = render_labels(world, idx, v.camera, v.shape)
        out[v.id] = blend(lab, v.prob, ls, EVIDENCE)
    return out


# ------------------------------------------------------------------------------- writing

def _report(r: MultiviewResult, timings: dict, stereo: dict) -> dict:
    fac = []
    for f in r.facades:
        fac.append({"index": f.index, "plane": f.plane, "building": f.building,
                    "frame": f.frame.to_dict(),
                    "raster": {"width": int(f.maps.shape[1]), "height": int(f.maps.shape[0]),
                               "resolution_m": f.maps.resolution},
                    "points": int(f.maps.count.sum()),
                    "seen_share": round(float((f.evidence.views > 0).mean()), 4),
                    "views_per_cell": round(float(f.evidence.views.mean()), 3),
                    **f.report})
    planes = [p.to_dict() for p in r.planes]
    return {"input": {"photos": [v.id for v in r.views], "points": len(r.cloud)},
            "frame": r.frame.to_dict(), "stereo": stereo, "planes": planes, "facades": fac,
            "axes": "model.*: local frame (metres, z up; glTF y up), report.frame.local_to_world "
                    "maps it to the cameras' frame",
            "timings": timings}


def _write(r: MultiviewResult, stage: Path) -> None:
    from PIL import Image

    from ..datasets.labelsets import get_label_set as _gls
    from ..exchange import export
    from ..outdir import write_json
    from ..points.io import write_ply
    from ..points.pipeline import depth_image

    ls = _gls("ecp7")
    (stage / "labels").mkdir()
    (stage / "labels_color").mkdir()
    for cid, lab in r.labels.items():
        idx = ls.from_canonical(lab)
        ids = np.where(idx == 255, 0, idx.astype(np.int64) + 1).astype(np.uint8)
        Image.fromarray(ids).save(stage / "labels" / f"{cid}.png")
        Image.fromarray(ls.to_color(idx)).save(stage / "labels_color" / f"{cid}.png")
    for f in r.facades:
        d = stage / f"facade_{f.index:02d}"
        d.mkdir()
        Image.fromarray(f.evidence.rgb).save(d / "ortho.png")
        Image.fromarray(depth_image(f.maps)).save(d / "depth.png")
        top = np.argmax(f.evidence.prob, axis=2).astype(np.uint8)
        Image.fromarray(ls.to_color(top)).save(d / "evidence.png")
        if f.tree is not None:
            from ..exchange.raster import PALETTE, label_map
            from ..reconstruction import _write_gml

            lab = label_map(f.tree, size=f.maps.shape)
            img = np.clip(0.55 * f.evidence.rgb + 0.45 * PALETTE[lab], 0, 255).astype(np.uint8)
            Image.fromarray(img).save(d / "structure.png")
            (d / "rules.cga").write_text(f.rules, encoding="utf-8")
            write_json(d / "shape_tree.json", f.tree.to_dict())
            _write_gml(f.tree, d / "rules.gml", f.report)
    write_ply(r.cloud, stage / "cloud.ply")
    _pareto_png(r, stage / "pareto.png")
    models = r.models()
    if models:
        export(models, stage / "model.glb")
        export(models, stage / "model.obj")
        export(models, stage / "model.city.json")
    write_json(stage / "report.json", r.report)


def _pareto_png(r: MultiviewResult, path: Path) -> None:
    """The Pareto sets of the facades' fits (E_a, E_d), normalised per facade, the chosen
    solutions marked (Fig. 5.4, 5.6)."""
    from PIL import Image, ImageDraw

    w, h, m = 520, 400, 50
    img = Image.new("RGB", (w, h), "white")
    d = ImageDraw.Draw(img)
    d.line([(m, h - m), (w - 20, h - m)], fill="black")
    d.line([(m, h - m), (m, 20)], fill="black")
    d.text((w // 2 - 60, h - m + 15), "appearance E_a (normalised)", fill="black")
    d.text((5, 5), "depth E_d (normalised)", fill="black")
    colours = [(214, 39, 40), (31, 119, 180), (44, 160, 44), (148, 103, 189), (255, 127, 14),
               (140, 86, 75), (227, 119, 194), (127, 127, 127)]
    for k, f in enumerate(r.facades):
        fit = f.report.get("fit")
        if not isinstance(fit, dict) or not fit.get("pareto"):
            continue
        P = np.array(fit["pareto"], float)
        lo, hi = P.min(0), P.max(0)
        span = np.where(hi - lo > 0, hi - lo, 1.0)
        Q = (P - lo) / span
        c = colours[k % len(colours)]
        for x, y in Q:
            px, py = m + x * (w - m - 30), h - m - y * (h - m - 30)
            d.ellipse([px - 3, py - 3, px + 3, py + 3], outline=c)
        e = np.array(fit.get("energies") or [], float)
        if e.size == 2:
            x, y = (e - lo) / span
            px, py = m + x * (w - m - 30), h - m - y * (h - m - 30)
            d.rectangle([px - 5, py - 5, px + 5, py + 5], outline=c, width=2)
        d.text((w - 150, 20 + 14 * k), f"facade {f.index:02d} α={fit.get('alpha')}", fill=c)
    img.save(path)
