"""Asset files other than OBJ: glTF (``.glb``/``.gltf``) and, through the Open Asset Import
Library (assimp), FBX, COLLADA, 3DS, DXF, PLY, STL and OFF — the formats CityEngine's ``i()``
inserts besides OBJ.

Each reader returns an :class:`~facadeforge.geometry.assets.Asset`: one mesh in the file's own
coordinates (node transforms applied, y up as CityEngine and glTF have it), uv set 0, and one
material per face when the file has several.  Faces are triangles (assimp triangulates; glTF
holds triangles).  Texture files must lie in the asset's folder or below it, as for OBJ; a
glTF's external buffers and images too.  Embedded glTF images are written once, by content, to
the user's cache folder (``~/.cache/facadeforge/asset-textures``, private to the user), so every
process (and the exporters) can read them.
"""

from __future__ import annotations

import hashlib
import tempfile
import warnings
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..user_cache import cache_root, private_folder
from .mesh import Mesh

#: Where embedded glTF images are written (one sub-folder per asset file content).
TEXTURE_CACHE = cache_root() / "asset-textures"


def _private_cache() -> Path:
    """The texture cache, made if need be; where the user's cache cannot be used (someone else
    owns it), a fresh private temporary folder instead."""
    folder = private_folder(TEXTURE_CACHE.name)
    if folder is not None:
        return folder
    fallback = Path(tempfile.mkdtemp(prefix="facadeforge-textures-"))
    _FALLBACKS.append(fallback.resolve())
    return fallback


_FALLBACKS: list[Path] = []


def cached_texture(name: str) -> str | None:
    """``name`` when it is an image this module wrote to the texture cache, else ``None``."""
    try:
        p = Path(name).resolve()
        roots = [TEXTURE_CACHE.resolve(), *_FALLBACKS]
    except (OSError, ValueError):
        return None
    return str(p) if any(r in p.parents for r in roots) and p.is_file() else None
#: Suffixes read through assimp (lower case, with the dot).
ASSIMP_SUFFIXES = (".fbx", ".dae", ".3ds", ".dxf", ".ply", ".stl", ".off")
GLTF_SUFFIXES = (".glb", ".gltf")


def _inside(folder: Path, target: Path) -> bool:
    folder, target = folder.resolve(), target.resolve()
    return target == folder or folder in target.parents


def _texture(folder: Path, name: str | None) -> str | None:
    """A material's texture file, when it names a readable file in ``folder`` or below."""
    if not name or name.startswith("*"):  # "*0": an embedded texture assimp does not expose
        return None
    tex = (folder / name.replace("\\", "/")).resolve()
    if not _inside(folder, tex) or not tex.is_file():
        return None
    return str(tex)


def _asset(pieces: list, path: Path):
    """One :class:`Asset` from ``[(positions, triangles, uv or None, AssetMaterial)]``."""
    from .assets import Asset

    pieces = [p for p in pieces if len(p[1])]
    if not pieces:
        raise InputError(f"{path}: the asset has no triangles")
    verts, faces, uvs, mats, face_mat = [], [], [], [], []
    offset, with_uv = 0, all(p[2] is not None for p in pieces)
    keys: dict[tuple, int] = {}
    for pos, tris, uv, mat in pieces:
        verts.append(pos)
        faces.append(tris + offset)
        if with_uv:
            uvs.append(uv[tris].reshape(-1, 2))
        key = (mat.name, tuple(mat.color), mat.texture, mat.opacity)
        if key not in keys:
            keys[key] = len(mats)
            mats.append(mat)
        face_mat.append(np.full(len(tris), keys[key], np.int64))
        offset += len(pos)
    v = np.concatenate(verts)
    if not np.isfinite(v).all():
        raise InputError(f"{path}: the asset has vertices that are not finite numbers")
    tris = np.concatenate(faces)
    corner_uvs = list(np.concatenate(uvs).reshape(-1, 3, 2)) if with_uv else None
    mesh = Mesh(v, tris.tolist(), corner_uvs)
    face_material = np.concatenate(face_mat) if len(mats) > 1 else None
    return Asset(mesh, mats[0], mats, face_material)


# -- glTF ----------------------------------------------------------------------------------------

def _check_gltf_uris(path: Path) -> None:
    """Refuse a ``.gltf`` whose buffers or images point outside its folder."""
    from ..jsonfile import read_json

    doc = read_json(path, "glTF asset", fix="export the asset again")
    if not isinstance(doc, dict):
        raise InputError(f"glTF asset '{path}' is not a glTF file (its JSON is not an object); "
                         "export the asset again")
    for kind in ("buffers", "images"):
        items = doc.get(kind) or []
        for item in items if isinstance(items, list) else []:
            uri = item.get("uri") if isinstance(item, dict) else None
            if not uri or uri.startswith("data:"):
                continue
            if "://" in uri or not _inside(path.parent, path.parent / uri):
                raise InputError(f"{path}: {kind[:-1]} '{uri}' lies outside the asset's folder; "
                                 "keep an asset's files beside it")


def load_gltf(path: Path):
    """A ``.glb`` or ``.gltf`` asset (pygltflib), through the reader of our own exports."""
    import pygltflib as gl

    from ..exchange.errors import LoadError
    from ..exchange.gltf import gltf_triangles
    from .assets import AssetMaterial

    path = Path(path)
    data = path.read_bytes()
    cache = _private_cache() / hashlib.sha1(data).hexdigest()[:20]
    try:
        with warnings.catch_warnings():  # pygltflib warns, then fails, on a foreign file
            warnings.simplefilter("ignore")
            if path.suffix.lower() == ".gltf":
                _check_gltf_uris(path)
                gltf = gl.GLTF2().load(str(path))
                gltf.convert_buffers(gl.BufferFormat.BINARYBLOB)
            else:
                gltf = gl.GLTF2.load_from_bytes(data)
        if gltf is None:
            raise LoadError("no glTF content")
        triangles = gltf_triangles(gltf, path, cache)
    except InputError:
        raise
    except Exception as e:  # pygltflib raises many kinds on malformed files
        raise InputError(f"{path}: not a readable glTF asset ({type(e).__name__}: {e})") from None
    pieces = []
    for pos, tris, uv, m in triangles:
        tex = m.texture
        if tex is not None and not (_inside(path.parent, Path(tex)) or _inside(cache, Path(tex))):
            tex = None
        pieces.append((pos, tris, uv, AssetMaterial(m.name, tuple(m.color), tex, m.opacity)))
    return _asset(pieces, path)


# -- assimp --------------------------------------------------------------------------------------

def load_assimp(path: Path):
    """An FBX, COLLADA, 3DS, DXF, PLY, STL or OFF asset through assimp (node transforms baked
    in, faces triangulated, identical vertices joined)."""
    import assimp_py as ai

    from .assets import AssetMaterial

    path = Path(path)
    flags = (ai.Process_Triangulate | ai.Process_PreTransformVertices
             | ai.Process_JoinIdenticalVertices | ai.Process_SortByPType)
    try:
        scene = ai.import_file(str(path), flags)
    except Exception as e:  # assimp reports a malformed file as a RuntimeError
        raise InputError(f"{path}: not a readable {path.suffix[1:].upper()} asset ({e})") from None
    materials = []
    for m in scene.materials or []:
        color = m.get("COLOR_DIFFUSE") or [1.0, 1.0, 1.0]
        textures = (m.get("TEXTURES") or {}).get(ai.TextureType_DIFFUSE) or []
        materials.append(AssetMaterial(str(m.get("NAME", "")), tuple(float(c) for c in color[:3]),
                                       _texture(path.parent, textures[0] if textures else None),
                                       float(m.get("OPACITY", 1.0))))
    pieces = []
    for mesh in scene.meshes:
        pos = np.asarray(mesh.vertices, float).reshape(-1, 3)
        idx = np.asarray(mesh.indices, np.int64)
        if len(idx) % 3 or (len(idx) and (idx.min() < 0 or idx.max() >= len(pos))):
            continue  # points and lines (sorted apart by SortByPType) carry no faces
        uv = None
        if mesh.texcoords and mesh.texcoords[0] is not None:
            raw = np.asarray(mesh.texcoords[0], float)  # 2 or 3 components per vertex
            width = len(raw) // max(len(pos), 1)
            if width >= 2 and width * len(pos) == len(raw):
                uv = raw.reshape(len(pos), width)[:, :2]
        mat = materials[mesh.material_index] if 0 <= mesh.material_index < len(materials) \
            else AssetMaterial()
        pieces.append((pos, idx.reshape(-1, 3), uv, mat))
    return _asset(pieces, path)
