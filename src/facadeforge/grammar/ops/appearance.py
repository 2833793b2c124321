"""Appearance: colours, textures, materials and texture coordinates (uv set 0 is exported)."""

from __future__ import annotations

import re
from functools import lru_cache

import numpy as np

from ..values import CGARuntimeError, Floating, Relative, to_float, to_str
from . import operation

_HEX = re.compile(r"^#?([0-9a-fA-F]{6})([0-9a-fA-F]{2})?$")
_NAMED = {"white": (1, 1, 1), "black": (0, 0, 0), "red": (1, 0, 0), "green": (0, 1, 0),
          "blue": (0, 0, 1), "yellow": (1, 1, 0), "gray": (0.5, 0.5, 0.5), "grey": (0.5, 0.5, 0.5)}


@lru_cache(maxsize=1024)
def parse_color(text: str) -> tuple[float, float, float]:
    m = _HEX.match(text.strip())
    if m:
        h = m.group(1)
        return tuple(int(h[k:k + 2], 16) / 255.0 for k in (0, 2, 4))
    if text.strip().lower() in _NAMED:
        return tuple(float(c) for c in _NAMED[text.strip().lower()])
    raise CGARuntimeError(f"'{text}' is not a colour; write \"#rrggbb\" or color(r, g, b)")


@operation("color", 1, 4)
def op_color(call):
    st = call.state
    if len(call.args) == 1:
        st.material["color"] = parse_color(call.text(0))
    else:
        st.material["color"] = tuple(float(np.clip(call.num(k), 0, 1)) for k in range(3))
        if len(call.args) == 4:
            st.material["opacity"] = float(np.clip(call.num(3), 0, 1))


@operation("texture", 1)
def op_texture(call):
    call.state.material["colormap"] = call.text(0)


def set_material(st, key: str, value) -> None:
    """``set(material.<key>, value)``."""
    m = st.material
    if key in ("color.r", "color.g", "color.b"):
        c = list(m.get("color", (1.0, 1.0, 1.0)))
        c["rgb".index(key[-1])] = float(np.clip(to_float(value), 0, 1))
        m["color"] = tuple(c)
    elif key == "color.rgb":
        m["color"] = parse_color(to_str(value))
    elif key in ("opacity", "color.a"):
        m["opacity"] = float(np.clip(to_float(value), 0, 1))
    elif key in ("name", "colormap", "bumpmap", "normalmap", "specularmap", "opacitymap",
                 "dirtmap", "emissivemap", "roughnessmap", "metallicmap", "occlusionmap"):
        m[key] = to_str(value)
    elif key in ("metallic", "roughness", "shininess", "reflectivity"):
        m[key] = to_float(value)
    else:
        m[key] = value


_AXES = {"x": 0, "y": 1, "z": 2}


@operation("setupProjection", 4, 8, selectors=(1,))
def op_setup_projection(call):
    """``setupProjection(uvSet, scope.xy|scope.xz|…|world.xz, w, h[, uOffset, vOffset])``.

    Relative sizes (``'f``) are fractions of the scope extent; floating sizes (``~w``) are rounded
    so that a whole number of tiles fits the scope.
    """
    st = call.state
    uv_set = int(call.num(0))
    axes = call.sel(1)
    frame, _, pair = axes.partition(".")
    if len(pair) != 2 or any(a not in _AXES for a in pair) or frame not in ("scope", "world"):
        raise CGARuntimeError(f"setupProjection axes must look like scope.xy or world.xz, not '{axes}'")
    rot = st.scope.rotation if frame == "scope" else np.eye(3)
    origin = st.scope.origin.copy() if frame == "scope" else np.zeros(3)
    ua, va = rot[:, _AXES[pair[0]]], rot[:, _AXES[pair[1]]]
    ext = [float(st.scope.size[_AXES[pair[0]]]), float(st.scope.size[_AXES[pair[1]]])]
    sizes = []
    for k, arg in enumerate(call.args[2:4]):
        if isinstance(arg, Relative):
            sizes.append(arg.value * ext[k])
        elif isinstance(arg, Floating):
            n = max(1.0, round(ext[k] / arg.value)) if arg.value > 0 else 1.0
            sizes.append(ext[k] / n if ext[k] > 0 else arg.value)
        else:
            sizes.append(to_float(arg))
    if sizes[0] == 0 or sizes[1] == 0:
        raise CGARuntimeError("setupProjection texture width and height must not be 0")
    off = (call.num(4, 0.0), call.num(5, 0.0))
    st.projections[uv_set] = (origin, ua, va, sizes[0], sizes[1], off)


@operation("projectUV", 1)
def op_project_uv(call):
    st = call.state
    uv_set = int(call.num(0))
    proj = st.projections.get(uv_set)
    if proj is None:
        raise CGARuntimeError(f"projectUV({uv_set}) without setupProjection({uv_set}, …) first")
    if uv_set != 0 or not st.geometry.n_faces:
        return
    origin, ua, va, w, h, off = proj
    p = st.geometry.vertices[st.geometry.corners] - origin
    uv = np.column_stack([(p @ ua - off[0]) / w, (p @ va - off[1]) / h])
    st.geometry = st.geometry.with_uvs(uv)


def _uv_edit(call, fn):
    st = call.state
    if int(call.num(0)) != 0 or st.geometry.corner_uvs is None:
        return
    st.geometry = st.geometry.with_uvs(fn(st.geometry.corner_uvs.copy()))


@operation("tileUV", 3)
def op_tile_uv(call):
    """Scale UVs so one texture tile spans ``w`` × ``h`` metres (0 keeps that direction)."""
    st = call.state
    w_arg, h_arg = call.args[1], call.args[2]

    def fn(uv):
        ext = np.ptp(uv, axis=0) if len(uv) else np.ones(2)
        size = [st.scope.size[0], st.scope.size[1]]
        for k, arg in enumerate((w_arg, h_arg)):
            if isinstance(arg, Relative):
                val = arg.value * size[k]
            elif isinstance(arg, Floating):
                n = max(1.0, round(size[k] / arg.value)) if arg.value > 0 else 1.0
                val = size[k] / n
            else:
                val = to_float(arg)
            if val > 0 and ext[k] > 0:
                uv[:, k] = uv[:, k] * size[k] / val / max(ext[k], 1e-12) if size[k] > 0 else uv[:, k]
        return uv
    _uv_edit(call, fn)


@operation("translateUV", 3)
def op_translate_uv(call):
    du, dv = call.num(1), call.num(2)
    _uv_edit(call, lambda uv: uv + [du, dv])


# ``offsetUV(uvSet, u, v)``: the name Esri's own 2014 library rules use for the same shift
# (ESRI.lib ``Facade_Textures.cga``, version "2014.0"); current references list translateUV only
operation("offsetUV", 3)(op_translate_uv)


@operation("scaleUV", 3)
def op_scale_uv(call):
    su, sv = call.num(1), call.num(2)
    _uv_edit(call, lambda uv: uv * [su, sv])


@operation("rotateUV", 2)
def op_rotate_uv(call):
    a = np.radians(call.num(1))
    r = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    _uv_edit(call, lambda uv: uv @ r.T)


@operation("normalizeUV", 2, 3, selectors=(1, 2))
def op_normalize_uv(call):
    def fn(uv):
        lo, ext = uv.min(axis=0), np.ptp(uv, axis=0)
        return (uv - lo) / np.where(ext > 0, ext, 1.0)
    _uv_edit(call, fn)


@operation("deleteUV", 1)
def op_delete_uv(call):
    if int(call.num(0)) == 0:
        call.state.geometry = call.state.geometry.with_uvs(None)
