"""Geometry clean-up operations: ``cleanupGeometry``, ``resetGeometry``, ``deleteHoles``,
``reduceGeometry``, ``setNormals`` and ``softenNormals``.

The mesh algorithms live in :mod:`facadeforge.geometry.cleanup`; this module reads the arguments,
keeps per-face data (materials of inserted assets, ``comp`` face kinds) in step with the faces,
and leaves the scope as it is (these operations do not move the shape).
"""

from __future__ import annotations

import math
from dataclasses import replace

from ...geometry import cleanup as kernel
from ...geometry.mesh import corner_sources_anywhere
from ..values import CGARuntimeError
from . import operation
from .tagging import without_tags

#: context entries that describe the current geometry: invalid once the geometry is replaced by
#: the initial shape's
_GEOMETRY_CONTEXT = ("pivot",)


def _unit_tolerance(call, i: int, what: str) -> float:
    t = call.num(i)
    if not 0.0 <= t <= 1.0 or math.isnan(t):
        raise CGARuntimeError(f"{call.name}: {what} must be between 0 and 1, not {t:g}; "
                              f"e.g. {call.name}({'all, ' if call.name == 'cleanupGeometry' else ''}0.1)")
    return t


def _face_groups(mesh) -> list | None:
    """Per face, what must stay apart when faces merge: its own material, ``offset`` kind and
    geometry tags (face columns, see ``geometry.mesh.FACE_COLUMNS``)."""
    if mesh.face_data is None:
        return None
    cols = [mesh.face_data.get(k) for k in ("material", "kind", "tags", "group")]
    return [tuple(None if c is None else (id(c[f]) if k == 0 else c[f]) for k, c in enumerate(cols))
            for f in range(mesh.n_faces)]


@operation("cleanupGeometry", 2, 2, selectors=(0,))
def op_cleanup_geometry(call):
    """``cleanupGeometry(components, tolerance)``: merge vertices, then per ``components`` drop
    collinear corners (``vertices``), merge coplanar neighbour faces (``edges``), drop duplicate
    and degenerate faces (``faces``), or all of these (``all``).

    Reference: https://doc.arcgis.com/en/cityengine/latest/cga/cga-cleanup-geometry.htm.
    ``tolerance`` in [0, 1] scales the reference's limits (1 m vertex distance, 10° between
    collinear edges and coplanar normals, 1 m² face area); 0 cleans only exact matches (within
    1e-6 m / 1e-6 rad numerically).  Where the reference is silent: a vertex merges into the
    first vertex (lower id) within the tolerance, without chains; a merged face starts at its
    first face's first vertex (the 2024.1 change "preserves the first edge"); faces never merge
    into a polygon with a hole;
    a vertex is dropped as collinear only where it is straight in every face using it, so no
    crack opens; faces of different materials or ``comp`` kinds (inside / border of ``offset``)
    never merge; back-to-back faces are not duplicates.  Texture coordinates must be continuous
    (one affine map) for faces or corners to be merged away, as the reference says.
    """
    comp = call.sel(0)
    if comp not in kernel.COMPONENTS:
        raise CGARuntimeError(f"cleanupGeometry: components must be one of "
                              f"{', '.join(kernel.COMPONENTS)}, not '{comp}'")
    tol = _unit_tolerance(call, 1, "the tolerance")
    st = call.state
    if not st.geometry.n_faces:
        return
    old = st.geometry
    mesh, source = kernel.cleanup(old, comp, tol, _face_groups(old))
    # a merged face's edges come from several faces: edge and vertex tags found by position
    corners = corner_sources_anywhere(mesh, old) if old.corner_data is not None else None
    st.geometry = mesh.inherit(old, source, corner_source=corners)


@operation("resetGeometry", 0)
def op_reset_geometry(call):
    """``resetGeometry()``: the initial shape's geometry, scope and pivot come back.

    Reference: https://doc.arcgis.com/en/cityengine/latest/cga/cga-reset-geometry-operation.htm.
    As documented, trim planes are removed and shape attributes (material, colour), rule
    attributes set with ``set`` and projections (``setupProjection``) stay.  Per-face data of the
    old geometry (its faces' materials and tags, ``offset`` parts) goes with it.
    """
    st = call.state
    initial = call.derivation.initial
    st.geometry = initial.geometry
    st.scope = initial.scope
    st.pivot = initial.pivot
    if st.trim is not None:
        st.trim = replace(st.trim, planes=None)
    for key in _GEOMETRY_CONTEXT:
        st.context.pop(key, None)


@operation("deleteHoles", 0)
def op_delete_holes(call):
    """``deleteHoles()``: faces with holes lose them.

    Reference: https://doc.arcgis.com/en/cityengine/latest/cga/cga-delete-holes.htm.  Our meshes
    hold simple polygons only: a face with holes (``offset(d, border)``, a courtyard lot, a
    ``setback`` remainder) is stored as coplanar pieces around the hole.  Each connected set of
    such pieces whose outline has inner loops becomes one polygon, its outer outline, as in
    CityEngine where the holed face becomes one face; other faces stay as they are.
    """
    st = call.state
    if not st.geometry.n_faces:
        return
    mesh, source = kernel.fill_holes(st.geometry, _face_groups(st.geometry))
    st.geometry = mesh.inherit(st.geometry, source)


@operation("reduceGeometry", 1)
def op_reduce_geometry(call):
    """``reduceGeometry(tolerance)``: remove ``tolerance`` × the vertex count by edge collapses.

    Reference: https://doc.arcgis.com/en/cityengine/latest/cga/cga-reduce-geometry.htm.  The
    collapses of least quadric error go first (the reference: "the least possible delta to the
    appearance"); outlines are kept stiff.  Where the reference is silent: the result is triangles
    (its terrain example has more faces than vertices after reduction); vertex counts are of
    merged (coincident) vertices; fewer vertices go when more collapses would turn a triangle
    over or pinch the surface.
    """
    frac = _unit_tolerance(call, 0, "the tolerance")
    st = call.state
    if not st.geometry.n_faces or frac == 0:
        return
    mesh, source = kernel.reduce(st.geometry, frac)
    st.geometry = without_tags(mesh.inherit(st.geometry, source))  # CityEngine clears tags


NORMAL_MODES = ("hard", "conform", "soft", "auto")


@operation("setNormals", 1, 1, selectors=(0,))
def op_set_normals(call):
    """``setNormals(hard|conform|soft|auto)``.

    Reference: https://doc.arcgis.com/en/cityengine/latest/cga/cga-set-normals.htm.  ``conform``
    turns faces so that neighbours agree, each connected part facing outwards when closed, else
    favouring the world's up direction: face orientation is what every exporter writes (OBJ and
    glTF winding), so this is carried.  ``hard``, ``soft`` and ``auto`` only set shading (vertex)
    normals, which no exporter of ours writes (OBJ has no ``vn``, glTF no ``NORMAL``: clients shade
    flat, which is ``hard``); they are checked and otherwise leave the shape as it is.
    """
    mode = call.sel(0)
    if mode not in NORMAL_MODES:
        raise CGARuntimeError(f"setNormals: mode must be one of {', '.join(NORMAL_MODES)}, "
                              f"not '{mode}'")
    st = call.state
    if mode == "conform" and st.geometry.n_faces:
        mesh, source = kernel.conform(st.geometry)
        st.geometry = mesh.inherit(st.geometry, source)


@operation("softenNormals", 1)
def op_soften_normals(call):
    """``softenNormals(angle)``: shading normals averaged across edges flatter than ``angle``.

    Reference: https://doc.arcgis.com/en/cityengine/latest/cga/cga-soften-normals.htm.  Shading
    normals are not carried by our exports (see ``setNormals``), so after checking the angle
    (0 to 180 degrees) the shape is left as it is.
    """
    angle = call.num(0)
    if not 0.0 <= angle <= 180.0:
        raise CGARuntimeError(f"softenNormals: the angle must be between 0 and 180 degrees, "
                              f"not {angle:g}; e.g. softenNormals(30)")
