"""Materials as string arrays (CityEngine 2021.0+): ``setMaterial(material)``,
``getMaterial(source, mode)`` and ``readMaterial(filePath)``.

A material is a string array of attribute names (without ``material.``) and values, one pair
per row (``(n x 2)``, as ``getMaterial``, ``readMaterial`` and ``readStringTable`` of a
two-column CSV give it) or flat, ``[name0, value0, name1, value1, …]`` (reference, "setMaterial
operation").  ``setMaterial`` is ``set(material.name, value)`` for each pair.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..values import CGARuntimeError, format_float, from_numpy, to_str
from . import operation, shape_function
from .appearance import set_material
from .geometry import asset_file, asset_material_keys

#: CityEngine's material attributes with the values of its default material, in the order
#: ``getMaterial(…, all)`` lists them (colour maps and the PBR and classic parameters).
DEFAULTS: dict[str, str] = {
    "name": "", "shader": "CityEnginePBRShader",
    "color.r": "1", "color.g": "1", "color.b": "1", "opacity": "1", "metallic": "0",
    "roughness": "1", "shininess": "0", "reflectivity": "0",
    "ambient.r": "0", "ambient.g": "0", "ambient.b": "0",
    "specular.r": "0", "specular.g": "0", "specular.b": "0",
    "emissive.r": "0", "emissive.g": "0", "emissive.b": "0",
    "colormap": "", "bumpmap": "", "dirtmap": "", "specularmap": "", "opacitymap": "",
    "normalmap": "", "emissivemap": "", "occlusionmap": "", "roughnessmap": "",
    "metallicmap": "", "opacitymap.mode": "blend", "opacitymap.cutoff": "0.5",
}


def _pairs(material) -> list[tuple[str, str]]:
    """``(name, value)`` pairs of a material array (rows of two, or flat pairs)."""
    if not isinstance(material, np.ndarray):
        raise CGARuntimeError(f"setMaterial needs a string array of names and values, not "
                              f"'{to_str(material)}'")
    cells = [to_str(from_numpy(x)) for x in material.reshape(-1)]
    if material.ndim == 2 and material.shape[1] != 2:
        raise CGARuntimeError(f"setMaterial: a material array has two columns (name, value), "
                              f"not {material.shape[1]}")
    if len(cells) % 2:
        raise CGARuntimeError("setMaterial: the material array has a name without a value")
    return [(cells[k].strip().removeprefix("material."), cells[k + 1])
            for k in range(0, len(cells), 2)]


@operation("setMaterial", 1)
def op_set_material(call):
    """``setMaterial(material)``: every name/value pair of ``material`` set on the shape's
    material, as ``set(material.<name>, value)`` would; ``builtin:default`` or an empty value
    clears a texture map."""
    for name, value in _pairs(call.args[0]):
        if not name:
            continue
        if name.endswith("map") and value in ("", "builtin:default"):
            call.state.material.pop(name, None)
            continue
        set_material(call.state, name, value)


def _flat(m: dict) -> dict[str, str]:
    """A material dict (``color``, ``ambient``… as triples) as attribute name → text."""
    out = {}
    for k, v in m.items():
        if isinstance(v, tuple) and len(v) == 3:
            out.update({f"{k}.{c}": format_float(float(x)) for c, x in zip("rgb", v)})
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            out[k] = format_float(float(v))
        else:
            out[k] = to_str(v)
    return out


def _geometry_material(st) -> dict:
    """The material the geometry brings: an inserted asset's (its first, with several)."""
    col = st.geometry.column("material")
    if col is not None and len(col) and col[0] is not None:
        am = col[0]
        m = {"name": am.name, "color": tuple(am.color), "opacity": am.opacity}
        if am.texture:
            m["colormap"] = am.texture
        return m
    return dict(asset_material_keys(st))


@shape_function("getMaterial")
def _get_material(env, args):
    """``getMaterial([used|shape|geometry[, changed|all]])``: the material as an ``(n x 2)``
    string array of attribute names and values; ``used`` is the geometry's material under the
    shape's, ``changed`` (the default) leaves out attributes at their default value."""
    source = to_str(args[0]) if args else "used"
    mode = to_str(args[1]) if len(args) > 1 else "changed"
    if source not in ("used", "shape", "geometry") or mode not in ("changed", "all"):
        raise CGARuntimeError("getMaterial(used|shape|geometry, changed|all)")
    st = env.state
    geometry = _geometry_material(st)
    own = asset_material_keys(st)
    shape = {k: v for k, v in st.material.items() if own.get(k, object()) != v}
    chosen = {"shape": shape, "geometry": geometry, "used": {**geometry, **shape}}[source]
    values = _flat(chosen)
    if mode == "all":
        values = {**DEFAULTS, **values}
    names = sorted(values)
    if not names:
        return np.zeros(0, dtype=object)
    return np.array([[n, values[n]] for n in names], dtype=object).reshape(len(names), 2)


def _mtl_material(path: Path) -> dict[str, str]:
    """The first material of a Wavefront ``.mtl`` as CGA material attributes and values."""
    from ...geometry.assets import read_mtl

    return _flat(next(iter(read_mtl(path).values()), {}))


def _read_cgamat(path: Path) -> dict[str, str]:
    """A ``.cgamat`` read as a table of name/value rows (comma, semicolon, tab or spaces apart),
    texture paths resolved beside the file."""
    out: dict[str, str] = {}
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        for sep in (",", ";", "\t", None):
            parts = line.split(sep, 1) if sep else line.split(None, 1)
            if len(parts) == 2:
                break
        else:
            continue
        name, value = parts[0].strip().strip('"'), parts[1].strip().strip('"')
        if name.endswith("map") and value:
            tex = (path.parent / value.replace("\\", "/")).resolve()
            value = str(tex) if path.parent.resolve() in tex.parents and tex.is_file() else value
        out[name.removeprefix("material.")] = value
    return out


@shape_function("readMaterial")
def _read_material(env, args):
    """``readMaterial(filePath)``: a ``.mtl`` (its first material) or ``.cgamat`` file under the
    asset root as an ``(n x 2)`` string array for ``setMaterial``."""
    if len(args) != 1:
        raise CGARuntimeError("readMaterial(filePath)")
    name = to_str(args[0])
    path = Path(asset_file(env, name, "material file"))
    suffix = path.suffix.lower()
    if suffix not in (".mtl", ".cgamat"):
        raise CGARuntimeError(f"readMaterial reads .mtl and .cgamat files, not '{name}'")
    from ...geometry.assets import MAX_TEXT_BYTES

    if path.stat().st_size > MAX_TEXT_BYTES:
        raise CGARuntimeError(f"readMaterial: '{name}' is larger than {MAX_TEXT_BYTES >> 20} MiB")
    try:
        values = _mtl_material(path) if suffix == ".mtl" else _read_cgamat(path)
    except (OSError, ValueError) as e:
        raise CGARuntimeError(f"readMaterial: cannot read '{name}': {e}") from None
    names = sorted(values)
    if not names:
        return np.zeros(0, dtype=object)
    return np.array([[n, values[n]] for n in names], dtype=object).reshape(len(names), 2)
