"""Shape and context functions of CityEngine's CGA that read the current shape or its tree.

Geometry queries (``geometry.boundaryLength``, ``geometry.isConcave``, ``geometry.isOriented``…),
file and asset functions (``filesSearch``, ``assetNamingInfo``, the utility library's
``assetBestSize`` family), context queries (``contextCount``, ``contextCompare``,
``minimumDistance``), edge attributes and ``getGeoCoord``.  Each function cites the page of the
CityEngine CGA reference (doc.arcgis.com/en/cityengine/latest/cga/…) it follows.

Context queries run CityEngine's two-pass generation for ``intra`` context: the first time a
derivation asks one, the same initial shape is derived once more with every context query
answering its default, and the labeled shapes of that pass (``label("…")`` records a copy of the
shape) are what the queries of the real derivation see.  Other initial shapes (``inter``) are
not known while buildings derive one by one, so ``inter`` finds no labeled shapes.
"""

from __future__ import annotations

import math

import numpy as np

from ...geometry.mesh import EPS, Mesh, weld_ids
from ..values import CGARuntimeError, to_float, to_str
from . import shape_function
from .geometry import (
    _asset_info,
    _face_selection,
    _file_search,
    _image_info,
    _list,
    _sort_by_ratio,
    asset_file,
    sort_by_size,
)

# ---- geometry ---------------------------------------------------------------------------------


def _edge_uses(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Edges after welding coincident vertices: (E, 2) welded vertex pairs, how many faces use
    each, and the welded positions."""
    weld = weld_ids(mesh.vertices)
    pts = np.zeros((weld.max() + 1 if len(weld) else 0, 3))
    pts[weld] = mesh.vertices
    edges, uses = mesh.welded_edges()
    return edges, uses, pts


@shape_function("geometry.boundaryLength")
def _boundary_length(env, args):
    """``geometry.boundaryLength()``: total length of the edges that belong to no more than one
    face (func_geometry.html#boundaryLength).  Coincident vertices count as one."""
    mesh = env.state.geometry
    if not mesh.n_faces:
        return 0.0
    edges, uses, pts = _edge_uses(mesh)
    border = edges[uses == 1]
    return float(np.linalg.norm(pts[border[:, 1]] - pts[border[:, 0]], axis=1).sum())


def _face_is_concave(p: np.ndarray, normal: np.ndarray) -> bool:
    e = np.roll(p, -1, axis=0) - p
    turn = np.cross(e, np.roll(e, -1, axis=0)) @ normal
    scale = max(float(np.abs(e).max()), EPS) ** 2
    return bool(np.any(turn < -1e-9 * scale))


@shape_function("geometry.isConcave")
def _is_concave(env, args):
    """``geometry.isConcave()``: whether at least one face is concave, i.e. turns the other way
    at some corner (func_geometry.html#isConcave).  Straight corners do not count."""
    mesh = env.state.geometry
    normals = mesh.face_normals()
    for f in np.flatnonzero(mesh.face_sizes > 3):
        if _face_is_concave(mesh.vertices[mesh.face(f)], normals[f]):
            return True
    return False


@shape_function("geometry.isOriented")
def _is_oriented(env, args):
    """``geometry.isOriented(orientation)``: whether at least one face matches the face
    selector (``front``, ``object.top``, ``world.north``…; func_geometry.html#isOriented)."""
    if len(args) != 1:
        raise CGARuntimeError("geometry.isOriented takes one face selector, e.g. "
                              "geometry.isOriented(top)")
    if not env.state.geometry.n_faces:
        return False
    return bool(np.any(_face_selection(env, args)))


@shape_function("geometry.nHoles")
def _n_holes(env, args):
    """``geometry.nHoles()`` (func_geometry.html#nHoles): faces here are simple polygons, so
    a face with holes (an ``offset`` border, a courtyard cut out) is pieces around them; the
    holes are the inner loops of such pieces' outline."""
    from ...geometry.cleanup import count_holes

    return float(count_holes(env.state.geometry))


def _inserted(env):
    """(asset name, mesh) of the last insert when the geometry is still that instance: same
    faces and corners (transformations keep an instance, splits and trims do not)."""
    rec = env.state.context.get("inserted")
    if rec is None:
        return None
    name, mesh = rec
    g = env.state.geometry
    if g is mesh or (np.array_equal(g.starts, mesh.starts) and np.array_equal(g.corners, mesh.corners)):
        return name
    return None


@shape_function("geometry.isInstanced")
def _is_instanced(env, args):
    """``geometry.isInstanced()``: whether the geometry is an inserted asset not altered since
    the insert (func_geometry.html#isInstanced).  Scope transformations keep the instance; any
    operation that changes the faces (split, comp, trim, offset…) ends it."""
    return _inserted(env) is not None


def _material_names(env) -> list[str]:
    own = env.state.geometry.column("material")
    if own is not None:
        names: dict = {}
        for m in own:
            names.setdefault(id(m), str(env.state.material.get("name", "")) if m is None else m.name)
        return list(names.values())
    return [str(env.state.material.get("name", ""))]


@shape_function("geometry.materials")
def _geometry_materials(env, args):
    """``geometry.materials()``: material names in component-split order
    (func_geometry.html#materials): an inserted asset's materials, else the shape's one."""
    return np.array(_material_names(env), dtype=object)


@shape_function("geometry.groups")
def _geometry_groups(env, args):
    """``geometry.groups()``: group names in component-split order (func_geometry.html#groups):
    the OBJ groups of an unaltered inserted asset; any other geometry is one group named after
    the initial shape, as CityEngine names initial-shape geometry.  Faces that keep their
    asset's groups (face column ``group``) name them, in the order ``comp(g)`` takes them."""
    column = env.state.geometry.column("group")
    if column is not None:  # faces before the file's first group are its "default" group
        names = [name for _, name in sorted({g for g in column if g is not None})]
        return np.array(names + (["default"] if any(g is None for g in column) else []),
                        dtype=object)
    name = _inserted(env)
    if name is not None and not name.startswith("builtin:"):
        return np.array(_obj_groups(env, name), dtype=object)
    return np.array([env.derivation.name], dtype=object)


# ---- files and assets -------------------------------------------------------------------------

@shape_function("filesSearch")
def _files_search(env, args):
    """``filesSearch(searchQuery)``: as ``fileSearch`` but a string array
    (func_fileSearch.html)."""
    return np.array(_list(_file_search(env, args)), dtype=object)


def _asset(env, name: str):
    return asset_file(env, name, "asset", mesh=True)


def _obj_groups(env, name: str) -> list[str]:
    """Group names (``g`` and ``o`` lines) of an OBJ asset in order of first appearance; one
    group named after the file when it has none."""
    _asset(env, name)  # found, readable and within the size limit
    names: list[str] = []
    with open(env.derivation.assets.resolve(name), encoding="utf-8", errors="replace") as fh:
        for line in fh:
            if line[:2] in ("g ", "o ", "g\t", "o\t"):
                g = " ".join(line.split()[1:])
                if g and g not in names:
                    names.append(g)
    return names or [name.replace("\\", "/").rsplit("/", 1)[-1].rsplit(".", 1)[0]]


def _naming_info(env, args) -> list[str]:
    if len(args) != 2:
        raise CGARuntimeError("assetNamingInfo(filePath, g|m) takes a path and a selector")
    name, kind = to_str(args[0]), to_str(args[1])
    if kind == "g":
        return _obj_groups(env, name)
    if kind == "m":
        return [m.name for m in _asset(env, name).materials]
    raise CGARuntimeError(f"assetNamingInfo: unknown naming selector '{kind}'; use g (groups) "
                          "or m (materials)")


@shape_function("assetNamingInfo")
def _asset_naming_info(env, args):
    """``assetNamingInfo(filePath, g|m)``: an asset's group or material names as a string list,
    in component-split order (func_assetNamingInfo.html).  Materials come in the order this
    runtime's ``comp(m)`` uses (sorted by name)."""
    return "".join(n + ";" for n in _naming_info(env, args))


@shape_function("assetNamingInfos")
def _asset_naming_infos(env, args):
    """``assetNamingInfos(filePath, g|m)``: as ``assetNamingInfo``, as a string array."""
    return np.array(_naming_info(env, args), dtype=object)


@shape_function("assetMetadata")
def _asset_metadata(env, args):
    """``assetMetadata(filePath, key, defaultValue)`` (func_assetMetadata.html): OBJ assets carry
    no metadata, so the default value (after checking the asset exists)."""
    if len(args) != 3:
        raise CGARuntimeError("assetMetadata(filePath, key, defaultValue) takes 3 arguments")
    _asset(env, to_str(args[0]))
    return args[2]


_AXES = ("x", "y", "z", "xy", "xz", "yz", "xyz")
#: axes of a ratio: the first axis is the width's, the second the height's, so "yx" is the
#: transposed "xy" (Esri's International City rule picks ground textures with "yx")
_RATIO_AXES = ("xy", "xz", "yz", "yx", "zx", "zy")


def _axes(args, k: int, what: str, allowed=_AXES) -> str:
    axes = to_str(args[k]) if len(args) > k else ""
    if axes not in allowed:
        raise CGARuntimeError(f"{what}: axis selector '{axes}' is not one of "
                              + ", ".join(f'"{a}"' for a in allowed))
    return axes


def _pick(env, ranked: list[str], n) -> str:
    """One of the ``n`` best (randomly, from the shape's random stream)."""
    k = int(to_float(n, "n"))
    if k < 1:
        raise CGARuntimeError(f"n must be an integer >= 1, got {to_str(n)}")
    best = ranked[:k]
    if len(best) <= 1:  # the best one: no draw, so later rand() values stay as they were
        return best[0] if best else ""
    return best[min(int(env.random_float() * len(best)), len(best) - 1)]


def _by_ratio(env, query, axes: str, image: bool) -> list[str]:
    files = _list(_file_search(env, [query]))
    if image:
        return _list(_sort_by_ratio(env, files, axes, lambda f: (_image_info(env, [f, "sx"]),
                                                                  _image_info(env, [f, "sy"]))))
    return _list(_sort_by_ratio(env, files, axes, lambda f: (_asset_info(env, [f, "s" + axes[0]]),
                                                              _asset_info(env, [f, "s" + axes[1]]))))


def _by_size(env, query, axes: str) -> list[str]:
    return sort_by_size(env, _list(_file_search(env, [query])), axes)


@shape_function("assetBestRatio")
def _asset_best_ratio(env, args):
    """``assetBestRatio(searchQuery, axesRatio)``: the asset whose size ratio on ``axesRatio``
    ("xy", "xz", "yz", "xyz") is closest to the scope's (celib/assetBestRatio.html).  The ratio
    compares the first two axes, as ``assetsSortRatio`` does."""
    return _pick(env, _by_ratio(env, args[0], _axes(args, 1, "assetBestRatio", (*_RATIO_AXES, "xyz")), False), 1)


@shape_function("assetApproxRatio")
def _asset_approx_ratio(env, args):
    """``assetApproxRatio(searchQuery, axesRatio, n)``: one of the ``n`` best ratio fits, picked
    at random (celib/assetApproxRatio.html); n = 1 is ``assetBestRatio``."""
    axes = _axes(args, 1, "assetApproxRatio", (*_RATIO_AXES, "xyz"))
    return _pick(env, _by_ratio(env, args[0], axes, False), args[2] if len(args) > 2 else 1.0)


@shape_function("assetBestSize")
def _asset_best_size(env, args):
    """``assetBestSize(searchQuery, axesSize)``: the asset that needs the least scaling to fit
    the scope on the given axes (celib/assetBestSize.html); scaling is measured as the largest
    relative change |scope / asset - 1| over the axes."""
    return _pick(env, _by_size(env, args[0], _axes(args, 1, "assetBestSize")), 1)


@shape_function("assetApproxSize")
def _asset_approx_size(env, args):
    """``assetApproxSize(searchQuery, axesSize, n)``: one of the ``n`` best size fits, picked at
    random (celib/assetApproxSize.html); n = 1 is ``assetBestSize``."""
    axes = _axes(args, 1, "assetApproxSize")
    return _pick(env, _by_size(env, args[0], axes), args[2] if len(args) > 2 else 1.0)


@shape_function("assetFitSize")
def _asset_fit_size(env, args):
    """``assetFitSize(searchQuery, axesSize, maxScaleError)``: a random asset among those that
    need at most ``maxScaleError`` relative scaling (0.1 = ±10 %; 0 allows all) on the given axes
    (celib/assetFitSize.html).  When none is close enough, the best size fit (the reference does
    not say; an empty name would insert nothing)."""
    axes = _axes(args, 1, "assetFitSize")
    limit = to_float(args[2], "assetFitSize maxScaleError") if len(args) > 2 else 0.0
    ranked = _by_size(env, args[0], axes)
    fits = sort_by_size(env, ranked, axes, limit)
    return _pick(env, fits or ranked, max(len(fits), 1))


@shape_function("imageBestRatio")
def _image_best_ratio(env, args):
    """``imageBestRatio(searchQuery, axesRatio)``: the image whose width / height is closest to
    the scope's ratio on ``axesRatio`` ("xy", "xz", "yz" or transposed, "yx"…;
    celib/imageBestRatio.html)."""
    return _pick(env, _by_ratio(env, args[0], _axes(args, 1, "imageBestRatio", _RATIO_AXES), True), 1)


@shape_function("imageApproxRatio")
def _image_approx_ratio(env, args):
    """``imageApproxRatio(searchQuery, axesRatio, n)``: one of the ``n`` best image ratio fits,
    picked at random (celib/imageApproxRatio.html)."""
    axes = _axes(args, 1, "imageApproxRatio", _RATIO_AXES)
    return _pick(env, _by_ratio(env, args[0], axes, True), args[2] if len(args) > 2 else 1.0)


# ---- context queries --------------------------------------------------------------------------

def _first_pass(derivation) -> list:
    """Labeled shapes (label, scope, geometry) of the initial shape derived with every context
    query answering its default: CityEngine's first pass (cga_context.html)."""
    from ..interpreter import Derivation

    first = Derivation(derivation.ruleset, derivation.initial, derivation.name,
                       derivation.overrides, derivation.seed, assets=derivation.assets,
                       limits=derivation.limits, start_rule=derivation.start_rule)
    first.labeled_shapes = []  # ops/meta.py: label() records a copy of the shape here
    with np.errstate(all="ignore"):  # defaults such as an infinite distance may reach geometry
        first.run()
    return first.labeled_shapes


def _labeled(env, args, what: str) -> list | None:
    """Labeled shapes a context query sees, or ``None`` when it must answer its default."""
    if len(args) < 2:
        raise CGARuntimeError(f"{what}(intra|inter|all, label, …) needs a target and a label")
    target, label = to_str(args[0]), to_str(args[1])
    if target not in ("intra", "inter", "all"):
        raise CGARuntimeError(f"{what}: unknown target '{target}'; use intra, inter or all")
    d = env.derivation
    if getattr(d, "labeled_shapes", None) is not None or not label or target == "inter":
        return None
    shapes = getattr(d, "context_shapes", None)
    if shapes is None:
        shapes = d.context_shapes = _first_pass(d)
    return [s for s in shapes if s[0] == label]


@shape_function("contextCount")
def _context_count(env, args):
    """``contextCount(target, label)``: how many shapes carry ``label`` (func_contextCount.html);
    every ``label()`` operation makes one.  0 for an empty label or ``inter`` only."""
    shapes = _labeled(env, args, "contextCount")
    return float(len(shapes)) if shapes else 0.0


def _bounds(scope, mesh: Mesh) -> np.ndarray:
    return mesh.bounds() if mesh.n_faces else np.stack([scope.corners().min(0), scope.corners().max(0)])


#: comparison type -> value of (bounds, area) ranked ascending (world north is -z, east +x)
_RANKINGS = {
    "world.northernmost": lambda b, a: b[0, 2], "world.southernmost": lambda b, a: -b[1, 2],
    "world.easternmost": lambda b, a: -b[1, 0], "world.westernmost": lambda b, a: b[0, 0],
    "world.highest": lambda b, a: -b[1, 1], "world.lowest": lambda b, a: b[0, 1],
    "area.largest": lambda b, a: -a, "area.smallest": lambda b, a: a,
}


@shape_function("contextCompare")
def _context_compare(env, args):
    """``contextCompare(target, label, comparisonType)``: the 0-based rank of the current shape
    among the shapes labeled ``label`` (func_contextCompare.html); ties take the lowest rank, so
    the rank is the number of labeled shapes strictly ahead.  Bounds are world bounds of the
    geometry (of the scope box without geometry); areas are surface areas."""
    if len(args) != 3:
        raise CGARuntimeError("contextCompare(target, label, comparisonType) takes 3 arguments")
    rank = _RANKINGS.get(to_str(args[2]))
    if rank is None:
        raise CGARuntimeError(f"contextCompare: unknown comparison '{to_str(args[2])}'; use one "
                              "of " + ", ".join(_RANKINGS))
    shapes = _labeled(env, args, "contextCompare")
    if not shapes:
        return 0.0
    st = env.state
    mine = rank(_bounds(st.scope, st.geometry), st.geometry.area())
    theirs = np.array([rank(_bounds(sc, g), g.area()) for _, sc, g in shapes])
    return float(np.count_nonzero(theirs < mine - 1e-9))


_BOX_EDGES = np.array([(a, b) for a in range(8) for b in range(a + 1, 8)
                       if bin(a ^ b).count("1") == 1])  # Scope.corners(): index 4x + 2y + z


def _to_box(points: np.ndarray, scope) -> np.ndarray:
    local = scope.to_local(points)
    return np.linalg.norm(local - np.clip(local, 0.0, scope.size), axis=1)


def _edges_to_box(corners: np.ndarray, scope) -> float:
    """Shortest distance from the 12 box edges with ``corners`` to the box ``scope``: a
    golden-section search along each edge (the distance is convex along a segment)."""
    a, b = corners[_BOX_EDGES[:, 0]], corners[_BOX_EDGES[:, 1]]
    lo, hi = np.zeros(len(a)), np.ones(len(a))
    r = (math.sqrt(5) - 1) / 2
    for _ in range(60):  # bounded: shrinks the interval by 0.618 per step, to < 1e-12
        t1, t2 = hi - r * (hi - lo), lo + r * (hi - lo)
        left = _to_box(a + t1[:, None] * (b - a), scope) <= _to_box(a + t2[:, None] * (b - a), scope)
        hi, lo = np.where(left, t2, hi), np.where(left, lo, t1)
    t = (lo + hi) / 2
    return float(min(_to_box(a + t[:, None] * (b - a), scope).min(), _to_box(a, scope).min(),
                     _to_box(b, scope).min()))


def scope_distance(s1, s2) -> float:
    """Euclidean distance between two scope boxes (0 when they touch or overlap): the closest
    points of two boxes lie on an edge of one of them."""
    return min(_edges_to_box(s1.corners(), s2), _edges_to_box(s2.corners(), s1))


@shape_function("minimumDistance")
def _minimum_distance(env, args):
    """``minimumDistance(target, label)``: the distance from the current scope to the nearest
    scope of a shape labeled ``label`` (func_minimumDistance.html), infinity when there is none
    (or the label is empty, or only ``inter`` is asked)."""
    if len(args) != 2:
        raise CGARuntimeError("minimumDistance(target, label) takes 2 arguments")
    shapes = _labeled(env, args, "minimumDistance")
    if not shapes:
        return math.inf
    return min(scope_distance(env.state.scope, sc) for _, sc, _ in shapes)


# ---- edge attributes, geo coordinates ---------------------------------------------------------

def _edge_attr(default):
    def fn(env, args):
        if len(args) != 1:
            raise CGARuntimeError("edgeAttr functions take one attribute name")
        to_str(args[0])
        return default
    fn.__doc__ = ("Edge attributes (func_edgeAttr.html) are ``/edgeattr/…`` arrays of a "
                  "CityEngine initial shape; footprints and lots here carry none, so the "
                  "reference's default for a missing attribute.")
    return fn


for _name, _default in (("edgeAttr.getFloat", 0.0), ("edgeAttr.getString", ""),
                        ("edgeAttr.getBool", False)):
    shape_function(_name)(_edge_attr(_default))


@shape_function("getGeoCoord")
def _get_geo_coord(env, args):
    """``getGeoCoord(X|Y|lon|lat)``: the scope origin in scene coordinates, X east and Y north
    (north is -z, as in CityEngine's scene frame; func_getGeoCoord.html).  Scenes here are not
    georeferenced, so lon/lat cannot be given."""
    which = to_str(args[0]) if args else ""
    o = env.state.scope.origin
    if which == "X":
        return float(o[0])
    if which == "Y":
        return float(-o[2])
    if which in ("lon", "lat"):
        raise CGARuntimeError(f"getGeoCoord({which}) needs a georeferenced scene, which this "
                              "runtime does not have; use getGeoCoord(X) / getGeoCoord(Y)")
    raise CGARuntimeError(f"getGeoCoord: unknown coordinate '{which}'; use X, Y, lon or lat")


__all__ = ["scope_distance"]
