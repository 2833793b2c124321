"""Operations on attributes and bookkeeping: ``set report print label`` and the inference tags
of seed ``simon2011`` §3.2.3 (``consistent`` / ``differentiate``)."""

from __future__ import annotations

from ..state import splitmix64
from ..values import CGARuntimeError, to_float, to_str
from . import operation
from .appearance import set_material
from .trimming import set_trim


@operation("set", 2, names=(0,))
def op_set(call):
    """``set(attr, value)`` for this shape and its descendants; ``set(material.x, v)``."""
    st = call.state
    name = call.sel(0)
    value = call.args[1]
    if name.startswith("material."):
        set_material(st, name[len("material."):], value)
        return
    if name.startswith("trim."):
        set_trim(st, name[len("trim."):], value)
        return
    if name.startswith("pivot."):
        raise CGARuntimeError(f"set({name}, …) is not supported; move the pivot with setPivot(…) "
                              "or alignScopeToGeometry(…)")
    if name.startswith("scope."):
        _set_scope(call, st, name[len("scope."):], to_float(value))
        return
    if name.startswith("comp.") or name.startswith("split."):
        raise CGARuntimeError(f"'{name}' cannot be set")
    found = call.env.module.attr(name)
    if found is None:
        raise CGARuntimeError(f"set: unknown attribute '{name}' (declare it with attr)")
    mod, adef = found
    if adef.const:
        raise CGARuntimeError(f"set: '{name}' is a const and cannot be set")
    st.attrs[(id(mod), adef.name)] = value


@operation("report", 2)
def op_report(call):
    key = call.text(0)
    value = call.args[1]
    if not isinstance(value, (str, bool)):
        value = to_float(value)
    call.derivation.reports.setdefault(key, []).append(value)


@operation("print", 1)
def op_print(call):
    call.derivation.prints.append(to_str(call.args[0]))


@operation("label", 1)
def op_label(call):
    """Semantic label of the shape and its descendants (also CityEngine's occlusion label)."""
    call.state.context["label"] = call.text(0)
    labeled = getattr(call.derivation, "labeled_shapes", None)
    if labeled is not None:  # first pass of the context queries (ops/queries.py)
        labeled.append((call.text(0), call.state.scope.copy(), call.state.geometry))


@operation("consistent", 1)
def op_consistent(call):
    """Consistency tag (simon2011 §3.2.3): shapes with the same tag derive identically below.

    All shapes tagged ``consistent("windows")`` in one building share one random stream, so every
    stochastic choice and ``rand`` below them comes out the same.
    """
    st = call.state
    tag = call.text(0)
    st.tags["consistency"] = tag
    h = 0
    for ch in tag.encode():
        h = splitmix64(h ^ ch)
    st.seed = splitmix64(call.derivation.seed ^ h)
    st.draws = 0


@operation("differentiate", 1)
def op_differentiate(call):
    """Differentiation tag (simon2011 §3.2.3): the n-th shape with a tag gets the n-th random
    stream of that tag, so consecutive tagged shapes never share a stream and, for stochastic
    rules with k branches, successive shapes cycle through different branches first."""
    st = call.state
    tag = call.text(0)
    counts = call.derivation.__dict__.setdefault("_diff_counts", {})
    n = counts.get(tag, 0)
    counts[tag] = n + 1
    st.tags["differentiation"] = f"{tag}#{n}"
    h = 0
    for ch in tag.encode():
        h = splitmix64(h ^ ch)
    st.seed = splitmix64(call.derivation.seed ^ h ^ (n * 0x9E3779B97F4A7C15))
    st.draws = 0


def _set_scope(call, st, key: str, value: float) -> None:
    """``set(scope.tx|ty|tz|sx|sy|sz, v)``: the translation is the scope origin's position in
    the pivot's frame (reference, "scope attribute"), so the scope (and its geometry) moves
    along that pivot axis; the size scales the geometry as ``s()`` does."""
    import numpy as np

    from .scoping import pivot_frame

    axis = "xyz".find(key[-1:])
    if axis < 0 or key[:1] not in ("t", "s"):
        raise CGARuntimeError(f"scope.{key} cannot be set (use scope.tx…tz or scope.sx…sz)")
    sc = st.own_scope()
    if key[0] == "t":
        origin, rotation = pivot_frame(st, call.derivation)
        d = value - float((sc.origin - origin) @ rotation[:, axis])
        shift = rotation[:, axis] * d
        sc.origin = sc.origin + shift
        if st.geometry.n_faces:
            st.geometry = st.geometry.with_vertices(st.geometry.vertices + shift)
        return
    old = float(sc.size[axis])
    new = sc.size.copy()
    new[axis] = max(value, 0.0)
    if st.geometry.n_faces and old > 1e-12:
        f = np.ones(3)
        f[axis] = new[axis] / old
        local = sc.to_local(st.geometry.vertices) * f
        st.geometry = st.geometry.with_vertices(sc.to_world(local))
    sc.size = new
