"""``modify(component[, scopeAlignment]) { selector operator operations | … }``.

Reference: https://doc.arcgis.com/en/cityengine/latest/cga/cga-modify-operation.htm and "Shape
Recomposition: Essential Knowledge".  Like ``comp``, ``modify`` divides the shape into faces, edges
or vertices and runs each branch's operations on the selected ones, but the results are put back
into the shape instead of becoming successors: ``modify(f) { … }`` is
``inline(recompose) comp(f) { … | all : X. }``, and edges and vertices can be edited too.

Recomposition in CityEngine keeps track of which vertices the pieces share, so a piece that moves
carries its shared vertices, and the faces around follow ("if the lower part is translated
sideways, the upper part follows suit").  Here a component whose operations only move it
(``t``, ``r``, ``s``, ``center``, ``translate``, ``rotate``…: same faces, vertices moved) moves its
vertices, and every face of the shape that shares one of them (coincident within 1e-6 m) follows:
``modify(f) { top : s('0.5, '1, '0.5) center(xz) X. }`` tapers a mass, ``modify(e) { ridge :
t(0, 2, 0) X. }`` shifts a roof's ridge sideways.  An edge or vertex moves with its scope (edge and vertex
shapes carry no geometry here).  A face component whose operations build new faces (a split, an
extrusion) is replaced by them and recomposed with the rest (``ops/inlining.recompose``).
"""

from __future__ import annotations

import numpy as np

from ...geometry.holed import HOLED, face_groups
from ...geometry.mesh import EPS, Mesh, weld_ids
from ..values import CGARuntimeError
from . import OpCall, operation


@operation("modify", 1, 2, selectors=(0, 1), body=True, keeps_shape=True)
def op_modify(call):
    from .inlining import derive_now, recompose
    from .subdivision import op_comp

    kind = call.sel(0)
    if kind not in ("f", "e", "v", "fe", "fv"):
        raise CGARuntimeError(f"modify({kind}): components are f, e or v")
    st = call.state
    mesh = st.geometry
    if not mesh.n_faces:
        return []
    comp = OpCall("comp", list(call.args), st.copy(), call.derivation, call.env, call.branches)
    pieces = op_comp(comp) or []
    weld = weld_ids(mesh.vertices)
    groups = face_groups(mesh) if kind == "f" and mesh.column(HOLED) is not None else None
    moved: dict = {}
    replaced: list[int] = []
    built: list[Mesh] = []
    rewritten: list = []  # (faces, corners, the component's mesh): its tags and materials
    for ps, ops, info in pieces:
        results = derive_now(call.run, ops, ps, call.env.with_state(ps))
        if kind == "f":
            chosen = info.get("components") or [info["component"]]
            faces = [f for c in chosen for f in (groups[c] if groups else [c])]
            new = results[0][0].geometry if len(results) == 1 else None
            if new is not None and _same_faces(new, ps.geometry):
                corners = _subset_corners(mesh, faces)
                for k, c in enumerate(corners):
                    moved[weld[mesh.corners[c]]] = new.vertices[new.corners[k]]
                rewritten.append((faces, corners, _own_material(call.derivation, st,
                                                                results[0][0])))
            else:
                replaced.extend(faces)
                built.extend(_own_material(call.derivation, st, r) for r, _ in results
                             if r.geometry.n_faces)
            continue
        if len(results) != 1:
            raise CGARuntimeError(f"modify({kind}): an edge or vertex can only be moved (t, r, s, "
                                  "center…); its operations made several shapes")
        old_pts = _points(ps, kind)
        after = results[0][0].scope
        ratio = np.where(ps.scope.size > EPS, after.size / np.where(ps.scope.size > EPS,
                                                                    ps.scope.size, 1.0), 1.0)
        new_pts = after.to_world(ps.scope.to_local(old_pts) * ratio)
        for p, q in zip(old_pts, new_pts):
            hit = np.flatnonzero(np.abs(mesh.vertices - p).max(axis=1) <= 1e-6)
            for v in hit:
                moved[weld[v]] = q
    if not moved and not replaced and not rewritten:
        return []
    verts = mesh.vertices.copy()
    if moved:
        ids = np.fromiter(moved, np.int64)
        where = np.isin(weld, ids)
        lookup = dict(zip(ids.tolist(), range(len(ids))))
        targets = np.array([moved[i] for i in ids])
        verts[where] = targets[[lookup[w] for w in weld[where]]]
    out = _rewrite(mesh.with_vertices(verts), rewritten)
    if replaced:
        keep = np.setdiff1d(np.arange(mesh.n_faces), replaced)
        rest = out.subset(keep)
        parts = [m for m in (rest, *built) if m.n_faces]
        merged, origin = recompose(parts, call.derivation)
        offsets = np.cumsum([0] + [m.n_faces for m in parts[:-1]])
        out = merged.inherit(Mesh.merge(parts), offsets[origin[:, 0]] + origin[:, 1])
    st.geometry = out
    st.fit_scope()
    return []


def _own_material(d, st, result) -> Mesh:
    """The result's geometry, its faces carrying the result's material (face column
    ``material``) where it is not the modified shape's own, as ``inline`` keeps it."""
    g = result.geometry
    own = g.column("material")
    if own is None and result.material == st.material:
        return g
    made: dict = {}
    column = []
    for am in (own if own is not None else [None] * g.n_faces):
        if id(am) not in made:
            made[id(am)] = d.material(result, am)
        column.append(made[id(am)])
    return g.with_column("material", column)


def _rewrite(mesh: Mesh, rewritten: list) -> Mesh:
    """``mesh`` with the face and corner data of the moved components (their tags and
    materials, as their operations left them) written over their faces and corners."""
    if not rewritten:
        return mesh
    face_data = {k: v.copy() for k, v in (mesh.face_data or {}).items()}
    corner_data = {k: v.copy() for k, v in (mesh.corner_data or {}).items()}
    for faces, corners, comp in rewritten:
        for data, index, columns, n in ((face_data, faces, comp.face_data, mesh.n_faces),
                                        (corner_data, corners, comp.corner_data,
                                         len(mesh.corners))):
            for name, col in (columns or {}).items():
                if name not in data:
                    data[name] = np.empty(n, dtype=object)
                data[name][np.asarray(index, np.int64)] = col
    return Mesh(mesh.vertices, corners=mesh.corners, starts=mesh.starts,
                corner_uvs=mesh.corner_uvs, closed=mesh.closed, face_data=face_data or None,
                corner_data=corner_data or None)


def _same_faces(new: Mesh, old: Mesh) -> bool:
    """Whether ``new`` is ``old`` with its vertices moved (same faces, same corners)."""
    return (new.n_faces == old.n_faces and len(new.corners) == len(old.corners)
            and np.array_equal(new.starts, old.starts) and np.array_equal(new.corners, old.corners))


def _subset_corners(mesh: Mesh, faces) -> np.ndarray:
    """The corners of ``mesh`` that ``mesh.subset(faces)`` copies, in its order."""
    return np.concatenate([np.arange(mesh.starts[f], mesh.starts[f + 1]) for f in faces])


def _points(ps, kind: str) -> np.ndarray:
    """An edge's two ends (its scope runs along it) or a vertex's point, in world coordinates."""
    if kind in ("v", "fv"):
        return ps.scope.origin[None].copy()
    return ps.scope.to_world(np.array([[0.0, 0, 0], [ps.scope.size[0], 0, 0]]))
