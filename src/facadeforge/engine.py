"""Public engine API: load CGA rules and derive them on initial shapes."""

from __future__ import annotations

import dataclasses
import itertools
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import DerivationError, InputError, RuleError
from .geometry.assets import AssetResolver, rule_roots
from .geometry.footprints import Footprint, load_footprints, lot
from .geometry.mesh import Mesh, plane_basis, polygon_normal
from .grammar.interpreter import PYTHON_RECURSION_LIMIT, Derivation, Limits, deriving
from .grammar.module import RuleSet, link
from .grammar.state import ShapeState
from .model.model import Model, extent_problem
from .model.scope import Scope

MAX_RULE_BYTES = 8 * 1024 * 1024


@dataclass
class Rules:
    """A loaded rule set with its asset resolver (what ``derive`` needs)."""

    ruleset: RuleSet
    assets: AssetResolver
    source: str
    package: object = None  # RulePackage when loaded from an .rpk


def load_rules(rules, *, rule: str | None = None, assets=None, start: str | None = None,
               style: str | None = None) -> Rules:
    """Load a ``.cga`` file, a ``.rpk`` rule package or CGA text.

    Parameters
    ----------
    rules : str or Path
        Path to ``.cga``/``.rpk``, or CGA source text (when it is not an existing path).
    rule : str, optional
        Main rule file inside an ``.rpk``.
    assets : str or Path, optional
        Asset folder; relative asset paths resolve against it (and the rule file's folder).
    start : str, optional
        Start rule (default: ``@StartRule``, else the first rule).
    style : str, optional
        CGA style of the main rule file (``style Name`` sections; default ``Default``).
    """
    package = None
    text_source = isinstance(rules, str) and ("\n" in rules or "-->" in rules) and Path(rules).suffix not in (".cga", ".rpk")
    if text_source:
        main_text, main_path, base = rules, "<rules>", None
    else:
        p = Path(rules)
        if not p.is_file():
            raise InputError(f"rule file '{rules}' does not exist")
        if p.suffix.lower() == ".rpk":
            from .grammar.rulepackage import open_rpk

            package = open_rpk(p, rule)
            p = package.main
        elif p.suffix.lower() != ".cga":
            raise InputError(f"'{rules}' is neither a .cga file nor a .rpk rule package")
        if p.stat().st_size > MAX_RULE_BYTES:
            raise InputError(f"rule file '{p}' is larger than 8 MiB")
        main_text = p.read_text(encoding="utf-8", errors="replace")
        main_path, base = str(p), p.parent
    roots = []
    if assets is not None:
        a = Path(assets)
        if not a.is_dir():
            raise InputError(f"asset folder '{assets}' does not exist")
        roots.append(a)
    if package is not None:
        # as in a CityEngine project (the package root is the project's): the rule's folder, the
        # project's assets/ folder, then the project itself
        roots.extend(dict.fromkeys([package.main.parent, package.root / "assets", package.root]))
        import_roots = [package.root]
    elif base is not None:
        import_roots = rule_roots(base)
        roots.extend(import_roots[:1] + [r / "assets" for r in import_roots[1:]]
                     + import_roots[1:])
    else:
        import_roots = []
    confined = AssetResolver(import_roots)

    def read(importer: str, name: str):
        if package is not None and name.startswith("/") and name in package.resolve_map:
            target = package.resolve_map[name]
        else:
            importer_dir = Path(importer).parent if importer != "<rules>" else None
            target = None
            if importer_dir is not None and not name.startswith("/"):
                target = (importer_dir / name).resolve()
            if target is None or not target.is_file():
                target = None
                parts = [x for x in name.split("/") if x]
                for r in import_roots:
                    for k in range(len(parts)):
                        cand = (Path(r) / "/".join(parts[k:])).resolve()
                        if cand.is_file():
                            target = cand
                            break
                    if target is not None:
                        break
        if target is None or not target.is_file():
            raise OSError(f"file not found: {name}")
        if not confined.allowed(target) and not (package is not None
                                                 and target in package.resolve_map.values()):
            raise OSError(f"'{name}' lies outside the rule's project; keep imported rules "
                          "inside it")
        if target.stat().st_size > MAX_RULE_BYTES:
            raise OSError(f"'{name}' is larger than {MAX_RULE_BYTES >> 20} MiB")
        return target.read_text(encoding="utf-8", errors="replace"), str(target)

    main = link(main_text, main_path, read, style=style)
    ruleset = RuleSet(main, start, roots[0] if roots else None)
    from .grammar.check import check_rules

    with deriving():  # the checker walks expressions as deep as the parser allows
        check_rules(ruleset)
    resolver = AssetResolver(roots, package.resolve_map if package else None)
    return Rules(ruleset, resolver, main_path, package)


def initial_state(fp: Footprint) -> ShapeState:
    """Initial shape: scope x along the first edge, y along the polygon normal (up).  A
    footprint with holes is one face with holes: simple pieces sharing an id (``geometry.holed``)."""
    poly = np.asarray(fp.polygon, float)
    n = polygon_normal(poly)
    if not n.any():
        raise InputError(f"footprint '{fp.name}' has no area")
    if n[1] < 0:  # initial shapes face up, whatever the winding they were given in
        poly, n = poly[::-1], -n
    mesh = Mesh.from_polygons([poly]) if not fp.holes else _holed_face(fp, poly, n)
    x = None
    for k in range(len(poly)):
        e = poly[(k + 1) % len(poly)] - poly[k]
        if np.linalg.norm(e) > 1e-9:
            x = e / np.linalg.norm(e)
            break
    if x is None:
        raise InputError(f"footprint '{fp.name}' is degenerate")
    z = np.cross(x, n)
    scope = Scope(poly[0], np.column_stack([x, n, z]), np.zeros(3))
    scope.fit_to(poly)
    return ShapeState(scope, mesh)


def _holed_face(fp: Footprint, poly: np.ndarray, n: np.ndarray) -> Mesh:
    """The footprint minus its holes as pieces of one face (the outline's first corner
    first)."""
    import shapely

    from .geometry.holed import HOLED, fresh_ids, rings
    from .geometry.polygon import simple_pieces

    basis = plane_basis(n, poly[1] - poly[0])
    flat = [((np.asarray(r, float) - poly[0]) @ basis[:, :2]) for r in [poly, *fp.holes]]
    # one difference with the union of all holes: one difference per hole redid the whole
    # overlay each time, minutes for a footprint with thousands of courtyards
    courtyards = shapely.buffer([shapely.Polygon(h) for h in flat[1:]], 0)
    shape = shapely.Polygon(flat[0]).buffer(0).difference(shapely.union_all(courtyards))
    pieces = [(k, q) for k, (outer, holes) in enumerate(rings(shape))
              for q in simple_pieces(shapely.Polygon(outer, holes))]
    if not pieces:
        raise InputError(f"footprint '{fp.name}': its holes cover it")
    lifted = [poly[0] + q @ basis[:, :2].T for _, q in pieces]
    return Mesh.from_polygons(lifted).with_column(HOLED, fresh_ids([k for k, _ in pieces]))


def facade_state(width: float, height: float) -> ShapeState:
    """A facade rectangle as initial shape: in the xy plane facing +z, scope x right, y up, z
    out (the frame ``comp(f)`` gives a wall), so facade grammars split it in x and y directly."""
    if not (width > 0 and height > 0):
        raise InputError(f"facade size {width} x {height} must be positive")
    poly = np.array([[0, 0, 0], [width, 0, 0], [width, height, 0], [0, height, 0]], float)
    scope = Scope(np.zeros(3), np.eye(3), np.array([width, height, 0.0]))
    return ShapeState(scope, Mesh.from_polygons([poly]))


def derive_facade(rules, width: float, height: float, *, start: str | None = None, attrs=None,
                  seed: int = 0, strict: bool = False, assets=None, name: str = "facade",
                  limits: Limits | None = None) -> Model:
    """Derive facade rules on a ``width`` × ``height`` rectangle (metres); returns the model with
    its shape tree (a 2D facade layout: leaves carry labels, scopes are rectangles in x/y)."""
    loaded = rules if isinstance(rules, Rules) else load_rules(rules, assets=assets, start=start)
    d = Derivation(loaded.ruleset, facade_state(width, height), name, attrs or {}, seed, strict,
                   loaded.assets, limits, start)
    return d.run()


def derive_footprint(rules: Rules, fp: Footprint, *, attrs=None, seed: int = 0, strict=False,
                     start=None, limits: Limits | None = None, keep_tree: bool = True,
                     neighbours=None) -> Model:
    """Derive the rules on one footprint (``keep_tree=False`` drops the shape tree).

    ``neighbours`` are the occluders (``(Mesh, label)``) of the buildings around it, for
    ``inter`` occlusion queries.  When the rules use occlusion queries the model keeps its own
    occluders in ``model.occluders`` for its neighbours."""
    t0 = time.perf_counter()
    merged = {**{k: v for k, v in fp.attributes.items() if not k.startswith("_")}, **(attrs or {})}
    known = set(rules.ruleset.main.attrs)
    if "seed" not in known and "seed" in merged:
        # PRT's shape attribute 'seed' (PyPRT users pass it with the attributes): the initial
        # shape's random seed, unless the rules declare an attribute of that name
        seed = _initial_seed(merged.pop("seed"), fp.name)
    overrides = {k: v for k, v in merged.items() if k in known or "." in k or k in (attrs or {})}
    for k in (attrs or {}):
        if "." not in k and k not in known and k != "seed":
            raise RuleError(f"--attr {k}: the rules have no attribute '{k}'"
                            + _suggest(k, known))
    from .grammar.ops.occlusion import Occluder

    around = [Occluder(-1 - k, mesh, label) for k, (mesh, label) in enumerate(neighbours or ())]
    d = Derivation(rules.ruleset, initial_state(fp), fp.name, overrides, seed, strict,
                   rules.assets, limits, start, instancing=not keep_tree, neighbours=around)
    with deriving():  # the statistics merge the model's meshes: as many objects again
        model = d.run()
        model.occluders = [(o.mesh, o.label) for o in d.occluders] if d.keeps_occluders else []
        model.attributes.update({k: v for k, v in fp.attributes.items()})
        model.attributes["seconds"] = time.perf_counter() - t0
        model.attributes["shapes"] = d.shape_count + 1
        model.attributes["prints"] = list(d.prints)
        if not keep_tree:
            model.root = None
        model.derived_stats = model.stats()  # computed here, in the worker, not in the main process
        problem = extent_problem(model.derived_stats)
        if problem is not None:
            raise DerivationError(f"'{fp.name}': {problem}")
    return model


def _initial_seed(value, name: str) -> int:
    """The ``seed`` attribute as an integer seed, or a ``RuleError`` naming the shape."""
    try:
        f = float(value)
        ok = math.isfinite(f) and f == int(f) and not isinstance(value, bool)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise RuleError(f"'{name}': attribute seed={value!r} is the initial shape's random seed "
                        "and must be an integer, e.g. --attr seed=7")
    return int(f)


def _suggest(name, known) -> str:
    import difflib

    close = difflib.get_close_matches(name, list(known), n=1)
    return f"; did you mean '{close[0]}'?" if close else ""


# -- parallel derivation ------------------------------------------------------------------------

_WORKER: dict = {}
#: Rules the parent loaded, by token: a worker made by fork inherits them and need not parse
#: the rule files again (a large rule set takes a third of a second); spawned workers load.
_PRELOADED: dict = {}
_POOLS = itertools.count()  # the token of each pool's entry in _PRELOADED


def _worker_init(spec):
    # Ctrl-C is the main process's to handle (it stops the pool): workers print no traceback
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # one BLAS thread per worker: the workers already use every core, and oversubscribed BLAS
    # threads made two workers slower than one
    from threadpoolctl import threadpool_limits

    _WORKER["blas"] = threadpool_limits(1)
    # the process is ours: a derivation's shape tree is pickled back after ``deriving`` has put
    # the recursion limit back, and pickling nests about five frames a tree level
    sys.setrecursionlimit(max(sys.getrecursionlimit(), PYTHON_RECURSION_LIMIT))
    inherited = _PRELOADED.get(spec.get("preloaded"))
    _WORKER["rules"] = inherited if inherited is not None else load_rules(
        spec["rules"], rule=spec["rule"], assets=spec["assets"], start=spec["start"],
        style=spec["style"])
    _WORKER["spec"] = spec


def _worker_run(job) -> Model:
    fp, neighbours, keep_tree, occluders_only = job
    s = _WORKER["spec"]
    model = derive_footprint(_WORKER["rules"], fp, attrs=s["attrs"], seed=s["seed"],
                             strict=s["strict"], start=s["start"], limits=s["limits"],
                             keep_tree=keep_tree, neighbours=neighbours)
    return _occluders_only(model) if occluders_only else model


def neighbour_occluders(models: list[Model], reach: float = 0.01) -> list[list]:
    """For each model, the occluders of the other models whose bounds come within ``reach``
    metres of its own (first pass of the ``inter`` occlusion queries)."""
    boxes = []
    for m in models:
        occ = getattr(m, "occluders", [])
        b = np.array([mesh.bounds() for mesh, _ in occ]) if occ else np.zeros((0, 2, 3))
        boxes.append(b)
    has = np.array([len(b) > 0 for b in boxes], bool)
    wlo = np.array([b[:, 0].min(axis=0) if len(b) else np.full(3, np.inf) for b in boxes]
                   ).reshape(-1, 3)
    whi = np.array([b[:, 1].max(axis=0) if len(b) else np.full(3, -np.inf) for b in boxes]
                   ).reshape(-1, 3)
    out = []
    for i in range(len(models)):
        near = []
        if has[i]:
            lo, hi = wlo[i] - reach, whi[i] + reach
            # the buildings whose whole boxes come near, in one test over the city
            close = np.flatnonzero(np.all((wlo <= hi) & (whi >= lo), axis=1) & has)
            for j in close[close != i]:
                hit = np.all((boxes[j][:, 0] <= hi) & (boxes[j][:, 1] >= lo), axis=1)
                near.extend(models[j].occluders[k] for k in np.flatnonzero(hit))
        out.append(near)
    return out


def derive(rules, footprints=None, *, lot_size: str | None = None, start: str | None = None,
           attrs: dict | None = None, assets=None, seed: int = 0, strict: bool = False,
           rule: str | None = None, workers: int | None = None,
           limits: Limits | None = None, keep_tree: bool = True,
           style: str | None = None) -> list[Model]:
    """Derive CGA rules on footprints.

    Parameters
    ----------
    rules : str, Path or Rules
        ``.cga`` file, ``.rpk`` package, CGA text, or an already loaded ``Rules``.
    footprints : str, Path or list of Footprint, optional
        A GeoJSON/OBJ file or footprints; or give ``lot_size`` (``"20x12"``).
    workers : int, optional
        Processes for many footprints (default: all cores when there are 4 or more footprints).
    keep_tree : bool
        Keep each model's shape tree (``Model.root``); exporting needs only the geometry.
    style : str, optional
        CGA style of the main rule file (default ``Default``).

    Returns
    -------
    list of Model
        One per footprint, in input order.  For a city, :func:`derive_iter` hands them out one
        at a time instead, so that only a few are held at once.
    """
    return list(derive_iter(rules, footprints, lot_size=lot_size, start=start, attrs=attrs,
                            assets=assets, seed=seed, strict=strict, rule=rule, workers=workers,
                            limits=limits, keep_tree=keep_tree, style=style))


def derive_iter(rules, footprints=None, *, lot_size: str | None = None,
                start: str | None = None, attrs: dict | None = None, assets=None,
                seed: int = 0, strict: bool = False, rule: str | None = None,
                workers: int | None = None, limits: Limits | None = None,
                keep_tree: bool = True, style: str | None = None):
    """:func:`derive`, one model at a time, in input order: worker processes derive a few
    footprints ahead of the one handed out, so memory holds a handful of buildings however
    many the city has (the exporters write them as they come).  Rules and footprints are
    loaded and checked before the first model is asked for."""
    if _is_gml(rules):
        return _derive_gml_iter(rules, footprints, lot_size, limits)
    if footprints is None and lot_size is None:
        raise InputError("give footprints (--footprint FILE) or a lot size (--lot WxD)")
    if isinstance(footprints, (str, Path)):
        fps = load_footprints(footprints)
    elif footprints is None:
        fps = lot(lot_size)
    else:
        fps = list(footprints)
    if isinstance(rules, Rules) and style is not None:
        raise InputError("style= applies when rules are loaded: pass it to load_rules(…, "
                         "style=…) instead of derive")
    loaded = rules if isinstance(rules, Rules) else load_rules(rules, rule=rule, assets=assets,
                                                                 start=start, style=style)
    n_workers = workers if workers is not None else (os.cpu_count() or 1)
    # ``inter`` occlusion queries need the neighbours' occluders: as CityEngine's runtime does,
    # every initial shape is derived once for its occluders, then for real with its neighbours'
    two_pass = len(fps) > 1 and _queries_neighbours(loaded)
    if len(fps) >= 4 and n_workers > 1 and not isinstance(rules, Rules):
        # the memory budget is the machine's: workers deriving at once share it
        share = dataclasses.replace(limits or Limits())
        share.max_memory_mb /= n_workers
        spec = {"rules": str(rules) if isinstance(rules, Path) else rules, "rule": rule,
                "assets": str(assets) if assets else None, "start": start, "style": style,
                "attrs": attrs, "seed": seed, "strict": strict, "limits": share}
        return _derive_parallel(spec, fps, n_workers, two_pass, keep_tree, loaded)

    def one(fp, around=None, tree=keep_tree):
        return derive_footprint(loaded, fp, attrs=attrs, seed=seed, strict=strict, start=start,
                                limits=limits, keep_tree=tree, neighbours=around)

    def run():
        around = [None] * len(fps)
        if two_pass:
            around = neighbour_occluders([_occluders_only(one(fp, tree=False)) for fp in fps])
        for fp, a in zip(fps, around):
            yield one(fp, a)
    return run()


def _is_gml(rules) -> bool:
    return isinstance(rules, (str, Path)) and str(rules).lower().endswith(".gml") \
        and "\n" not in str(rules)


def _derive_gml_iter(program, footprints, lot_size, limits):
    """A GML program (``hohmann2009`` §5, :mod:`facadeforge.gml`): once on its own scopes, or
    once per initial shape (footprints, ``lot_size``) with that shape's scope on the stack —
    the same :class:`Model` as CGA's, so every exporter takes it."""
    from .gml import Limits as GmlLimits
    from .gml import derive_gml, load_gml

    prog = load_gml(Path(program))          # a bad program fails before anything is derived
    gl = GmlLimits()
    if limits is not None and getattr(limits, "max_seconds", None):
        gl = dataclasses.replace(gl, max_seconds=float(limits.max_seconds))
    if isinstance(footprints, (str, Path)):
        fps = load_footprints(footprints)
    elif footprints is None:
        fps = lot(lot_size) if lot_size is not None else None
    else:
        fps = list(footprints)
    def counted(m: Model) -> Model:
        m.attributes["shapes"] = sum(1 for _ in m.root.walk()) if m.root is not None else 0
        return m

    if fps is None:
        return iter([counted(derive_gml(prog, limits=gl, name=Path(program).stem))])
    return (counted(derive_gml(prog, scope=initial_state(fp).scope, limits=gl, name=fp.name))
            for fp in fps)


def _derive_parallel(spec, fps, n_workers: int, two_pass: bool, keep_tree: bool,
                     loaded: Rules):
    """Models from worker processes, in order, at most a few per worker ahead."""
    from collections import deque

    token = next(_POOLS)
    _PRELOADED[token] = loaded
    spec = {**spec, "preloaded": token}
    pool = ProcessPoolExecutor(n_workers, initializer=_worker_init, initargs=(spec,))
    try:
        around = [None] * len(fps)
        if two_pass:
            chunks = max(1, len(fps) // (n_workers * 4))
            around = neighbour_occluders(list(pool.map(
                _worker_run, [(fp, None, False, True) for fp in fps], chunksize=chunks)))
    except BaseException:
        pool.shutdown(cancel_futures=True)
        _PRELOADED.pop(token, None)
        raise

    def run():
        jobs = iter(zip(fps, around))
        window: deque = deque()

        def submit() -> None:  # the next footprint, if any, to a worker
            job = next(jobs, None)
            if job is not None:
                window.append(pool.submit(_worker_run, (*job, keep_tree, False)))
        finished = False
        try:
            for _ in range(3 * n_workers):
                submit()
            while window:
                model = window.popleft().result()
                submit()
                yield model
            finished = True
        finally:
            # stopped early (an error, Ctrl-C): do not wait for buildings nobody will read
            pool.shutdown(wait=finished, cancel_futures=True)
            _PRELOADED.pop(token, None)
    return run()


def _occluders_only(model: Model) -> Model:
    """What the first pass of ``inter`` occlusion keeps of a model: its occluders."""
    light = Model([], None, {}, [], model.name)
    light.occluders = getattr(model, "occluders", [])
    return light


def _queries_neighbours(rules: Rules) -> bool:
    """Whether an occlusion query of the rules may test the neighbouring buildings (``intra``
    queries alone need no first pass)."""
    from .grammar.instancing import Purity

    ruleset = rules.ruleset
    purity = getattr(ruleset, "_purity", None)
    if purity is None:
        purity = ruleset._purity = Purity(ruleset)
    return purity.queries_neighbours


def summary(model: Model) -> Model:
    """What :func:`stats` reads of a model (its counts, reports, warnings, attributes), without
    its geometry: a city's stats need not keep the city."""
    light = Model([], None, model.reports, model.warnings, model.name, dict(model.attributes))
    light.derived_stats = getattr(model, "derived_stats", None) or model.stats()
    return light


def stats(models: list[Model], seconds: float) -> dict:
    """The ``--stats`` JSON object for a set of derived models."""
    faces = tris = verts = 0
    area = 0.0
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    report: dict[str, list] = {}
    warnings: list[str] = []
    shapes = 0
    for m in models:
        s = getattr(m, "derived_stats", None) or m.stats()
        faces += s["faces"]
        tris += s["triangles"]
        verts += s["vertices"]
        area += s["area"]
        if s["faces"]:
            lo = np.minimum(lo, s["bbox"][0])
            hi = np.maximum(hi, s["bbox"][1])
        for k, v in m.reports.items():
            report.setdefault(k, []).extend(v)
        warnings.extend(f"{m.name}: {w}" for w in m.warnings)
        shapes += int(m.attributes.get("shapes", 0))
    if not np.isfinite(lo).all():
        lo = hi = np.zeros(3)
    return {"shapes": shapes, "faces": faces, "triangles": tris, "vertices": verts,
            "area": round(area, 6), "bbox": [lo.round(6).tolist(), hi.round(6).tolist()],
            "report": {k: [_json_number(v) for v in vs] for k, vs in report.items()},
            "warnings": warnings, "seconds": round(seconds, 4)}


def _json_number(v):
    """A reported value as JSON has it: NaN and infinities (``report("r", 0/0)``) have no
    JSON spelling, so they become ``null``."""
    return None if isinstance(v, float) and not math.isfinite(v) else v
