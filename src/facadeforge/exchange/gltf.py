"""Binary glTF 2.0 (``.glb``) export and import.

Layout of an exported file
--------------------------
* one scene; one node and one mesh per :class:`~facadeforge.model.Model`.  The node is named
  after ``model.name``; its ``extras`` hold ``{"facadeforge_model": true, "attributes": ...,
  "reports": ..., "warnings": ...}`` (pygltflib drops empty strings, lists and ``null`` values
  from the JSON, so such attribute values do not survive a round trip).
* within a mesh, one indexed triangle primitive per (material, label) group of parts: one vertex
  per polygon corner, no ``NORMAL`` (clients compute flat normals), ``TEXCOORD_0`` when any face
  of the group has UVs (glTF's v axis points down: ``v_gltf = 1 - v``).
* primitive ``extras``::

      {"label": "window",                 # canonical label of every triangle of the primitive
       "symbols": ["Window", "Glass"],    # distinct shape symbols of the group
       "parts_accessor": 7}               # accessor (VEC4 uint32) of [symbol index, first
                                          # triangle, triangle count, shape id], one per Part

  so the label and symbol of every face can be read without facadeforge.
* PBR materials: ``baseColorFactor`` from ``Material.color``/``opacity`` (``alphaMode`` BLEND
  when the opacity is below 1); a readable texture file is embedded in the binary chunk (PNG and
  JPEG bytes as they are, other formats re-encoded as PNG); an unreadable one is skipped.

Import
------
:func:`load_glb` reads such files (and plain glTF binaries from other tools) back into models.
Faces come back as triangles.  Embedded textures are written as files to ``texture_dir`` (a new
temporary directory when not given, left in place for the caller) because ``Material.texture``
is a file path.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pygltflib as gl

from ..geometry.mesh import Mesh, column_bounds
from ..jsonfile import json_type
from ..model.model import MAX_COORDINATE, Material, Model, Part
from ._common import (
    Staging,
    corner_uvs,
    face_corners,
    image_extension,
    iter_models,
    joined_attributes,
    jsonable,
    mesh_from_flat,
    read_texture,
    split_attributes,
    triangulate_corners,
)
from .errors import ExportError, LoadError

__all__ = ["export_glb", "load_glb"]

_COMPONENT_DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16,
                     5125: np.uint32, 5126: np.float32}
_TYPE_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


# -- export -----------------------------------------------------------------------------------

def export_glb(models: Model | Sequence[Model], path: str | os.PathLike, *,
               double_sided: bool = True) -> list[Path]:
    """Write models to a binary glTF file.

    Parameters
    ----------
    models : Model, sequence or iterable of Model
        Written as they come (a generator such as ``engine.derive_iter`` keeps memory to a
        few buildings).
        What to write; one glTF node and mesh per model.
    path : path-like
        Destination ``.glb``; written atomically.
    double_sided : bool
        Mark materials double-sided (facade quads are often seen from behind).

    Returns
    -------
    list of Path
        The file written.
    """
    with Staging() as stage:
        final = stage.path(path)
        # the binary chunk waits beside the destination, not in a /tmp that may be RAM
        with _GlbBuilder(double_sided=double_sided, spill_dir=final.parent) as builder:
            for model in iter_models(models):  # one at a time: a city never sits in memory
                builder.add_model(model)
            with open(final, "wb") as fh:
                builder.write(fh)
    return [Path(path)]


class _GlbBuilder:
    """Accumulates glTF JSON (plain dicts) and one binary buffer, written as a GLB container.

    The writer builds the JSON itself rather than through pygltflib's object model: for a city
    with a million faces that is the difference between seconds and a fraction of one.
    """

    def __init__(self, double_sided: bool = True, spill_dir=None) -> None:
        self.double_sided = double_sided
        self.json: dict = {"asset": {"generator": "facadeforge", "version": "2.0"},
                           "buffers": [], "bufferViews": [], "accessors": [], "materials": [],
                           "meshes": [], "nodes": [], "images": [], "textures": [],
                           "samplers": []}
        # the binary chunk goes to a temporary file as models come (written out last)
        self.blob = tempfile.TemporaryFile(dir=spill_dir)
        self.size = 0
        self._materials: dict[tuple, int] = {}
        self._textures: dict[str, int | None] = {}

    def __enter__(self) -> _GlbBuilder:
        return self

    def __exit__(self, *exc) -> None:
        self.blob.close()

    # buffers ---------------------------------------------------------------------------------
    def _append(self, data: bytes) -> None:
        if self.size + len(data) > MAX_GLB_BYTES:
            raise ExportError("a GLB file holds at most 4 GiB of geometry and images; export "
                              "fewer buildings per file (or to .city.jsonl)")
        self.blob.write(data)
        self.size += len(data)

    def _view(self, data: bytes, target: int | None) -> int:
        pad = -self.size % 4
        if pad:
            self._append(b"\0" * pad)
        view = {"buffer": 0, "byteOffset": self.size, "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        self._append(data)
        self.json["bufferViews"].append(view)
        return len(self.json["bufferViews"]) - 1

    def _add_accessor(self, array: np.ndarray, component: int, kind: str, bounds=False) -> int:
        target = gl.ELEMENT_ARRAY_BUFFER if kind == "SCALAR" and component == gl.UNSIGNED_INT \
            else (gl.ARRAY_BUFFER if component == gl.FLOAT else None)
        acc = {"bufferView": self._view(array.tobytes(), target), "componentType": component,
               "count": int(len(array) if kind != "SCALAR" else array.size), "type": kind}
        if bounds:
            lo, hi = column_bounds(array)
            acc["min"], acc["max"] = lo.astype(float).tolist(), hi.astype(float).tolist()
        self.json["accessors"].append(acc)
        return len(self.json["accessors"]) - 1

    def _accessor(self, array: np.ndarray, kind: str, bounds: bool = False) -> int:
        return self._add_accessor(np.ascontiguousarray(array, dtype=np.float32), gl.FLOAT, kind,
                                  bounds)

    def _index_accessor(self, tri: np.ndarray) -> int:
        return self._add_accessor(np.ascontiguousarray(tri, dtype=np.uint32).reshape(-1),
                                  gl.UNSIGNED_INT, "SCALAR")

    def _int_accessor(self, table: np.ndarray) -> int:
        """An (N, 4) table of non-negative ints as a VEC4 UNSIGNED_INT accessor (no JSON bulk)."""
        return self._add_accessor(np.ascontiguousarray(table, dtype=np.uint32).reshape(-1, 4),
                                  gl.UNSIGNED_INT, "VEC4")

    # materials -------------------------------------------------------------------------------
    def _texture(self, path: str | None) -> int | None:
        if not path:
            return None
        if path not in self._textures:
            self._textures[path] = self._embed_texture(path)
        return self._textures[path]

    def _embed_texture(self, path: str) -> int | None:
        found = read_texture(path)
        if found is None:
            return None
        data, mime = found
        j = self.json
        if not j["samplers"]:
            j["samplers"].append({"magFilter": gl.LINEAR, "minFilter": gl.LINEAR_MIPMAP_LINEAR,
                                  "wrapS": gl.REPEAT, "wrapT": gl.REPEAT})
        j["images"].append({"bufferView": self._view(data, None), "mimeType": mime,
                            "name": Path(path).name})
        j["textures"].append({"sampler": 0, "source": len(j["images"]) - 1})
        return len(j["textures"]) - 1

    def material(self, mat: Material) -> int:
        key = mat.key()
        if key in self._materials:
            return self._materials[key]
        tex = self._texture(mat.texture)
        pbr = {"baseColorFactor": [*map(float, mat.color), float(mat.opacity)],
               "metallicFactor": float(mat.metallic), "roughnessFactor": float(mat.roughness)}
        if tex is not None:
            pbr["baseColorTexture"] = {"index": tex}
        entry = {"name": mat.name, "pbrMetallicRoughness": pbr, "doubleSided": self.double_sided,
                 "alphaMode": "BLEND" if mat.opacity < 1.0 else "OPAQUE"}
        if mat.texture:
            entry["extras"] = {"texture": mat.texture}
        self.json["materials"].append(entry)
        self._materials[key] = len(self.json["materials"]) - 1
        return self._materials[key]

    # geometry --------------------------------------------------------------------------------
    def add_model(self, model: Model) -> None:
        primitives = []
        for (_, label), parts in _group_parts(model.parts).items():
            prim = self._primitive(parts, label)
            if prim is not None:
                primitives.append(prim)
        data, geo = split_attributes(model.attributes)
        extras = jsonable({"facadeforge_model": True, "attributes": data,
                           "reports": model.reports, "warnings": model.warnings})
        if geo:
            extras["georeference"] = geo
        node = {"name": model.name, "extras": extras}
        if primitives:
            self.json["meshes"].append({"name": model.name, "primitives": primitives})
            node["mesh"] = len(self.json["meshes"]) - 1
        self.json["nodes"].append(node)

    def _primitive(self, parts: list[Part], label: str) -> dict | None:
        # one merged mesh per group: triangulation and the part records are vectorised
        meshes = [p.mesh for p in parts]
        merged = Mesh.merge(meshes)
        if not merged.n_faces:
            return None
        tri, face_of = triangulate_corners(merged)
        corners, _ = face_corners(merged)
        uv_all, any_uv = corner_uvs(merged)
        face_counts = np.array([m.n_faces for m in meshes])
        part_of_face = np.repeat(np.arange(len(parts)), face_counts)
        tris_per_part = np.bincount(part_of_face[face_of], minlength=len(parts))
        first_tri = np.concatenate([[0], np.cumsum(tris_per_part)[:-1]])
        symbols: list[str] = []
        records = []
        for k, part in enumerate(parts):
            if tris_per_part[k] == 0:
                continue
            if part.symbol not in symbols:
                symbols.append(part.symbol)
            records.append([symbols.index(part.symbol), int(first_tri[k]), int(tris_per_part[k]),
                            int(part.shape_id)])
        # indexed face corners and no NORMAL: glTF clients compute flat normals themselves
        # (glTF 2.0 §3.7.2.1), which halves the file against flat, unindexed triangles
        attrs = {"POSITION": self._accessor(merged.vertices[corners], "VEC3", bounds=True)}
        if any_uv:
            attrs["TEXCOORD_0"] = self._accessor(
                np.column_stack([uv_all[:, 0], 1.0 - uv_all[:, 1]]), "VEC2")
        return {"attributes": attrs, "mode": gl.TRIANGLES, "indices": self._index_accessor(tri),
                "material": self.material(parts[0].material),
                "extras": {"label": label, "symbols": symbols,
                           "parts_accessor": self._int_accessor(np.array(records))}}

    def write(self, fh) -> None:
        """The GLB container: header, JSON chunk, then the binary chunk copied from its
        temporary file."""
        import json
        import shutil
        import struct

        j = {k: v for k, v in self.json.items() if v or k == "asset"}
        j["scenes"] = [{"nodes": list(range(len(self.json["nodes"])))}]
        j["scene"] = 0
        pad = -self.size % 4
        if pad:
            self._append(b"\0" * pad)
        if self.size:
            j["buffers"] = [{"byteLength": self.size}]
        else:  # glTF allows no empty arrays (an empty model: a rule that deletes everything)
            j.pop("buffers", None)
            j.pop("bufferViews", None)
        text = json.dumps(j, separators=(",", ":")).encode("utf-8")
        text += b" " * (-len(text) % 4)
        total = 12 + 8 + len(text) + (8 + self.size if self.size else 0)
        if total >= 1 << 32:
            raise ExportError(f"a GLB file holds at most 4 GiB; this one would be "
                              f"{total / 2**30:.1f} GiB: export fewer buildings per file")
        fh.write(struct.pack("<III", 0x46546C67, 2, total))
        fh.write(struct.pack("<II", len(text), 0x4E4F534A))
        fh.write(text)
        if self.size:
            fh.write(struct.pack("<II", self.size, 0x004E4942))
            self.blob.seek(0)
            shutil.copyfileobj(self.blob, fh, 1 << 20)


def _group_parts(parts: Sequence[Part]) -> dict[tuple, list[Part]]:
    """Parts grouped by (material key, label), groups in order of first appearance."""
    groups: dict[tuple, list[Part]] = {}
    for part in parts:
        groups.setdefault((part.material.key(), part.label), []).append(part)
    return groups


# -- import -----------------------------------------------------------------------------------

def load_glb(path: str | os.PathLike, *, texture_dir: str | os.PathLike | None = None
             ) -> list[Model]:
    """Read a binary glTF file into models.

    Parameters
    ----------
    path : path-like
        A ``.glb`` file.
    texture_dir : path-like, optional
        Where embedded images are written so that ``Material.texture`` can name a file; a new
        temporary directory (not removed afterwards) when omitted and the file has textures.

    Returns
    -------
    list of Model
        One model per node with a mesh (node transforms applied), plus facadeforge nodes that
        carried an empty model.  Faces are triangles; parts, labels and symbols come from the
        primitive ``extras`` when present (one part per primitive otherwise).

    Raises
    ------
    FileNotFoundError
        When ``path`` does not exist.
    LoadError
        When the file is not a readable glTF binary.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such file: {path}")
    try:
        gltf = gl.GLTF2.load_binary(str(path))
    except Exception as exc:
        raise LoadError(f"cannot read {path} as binary glTF: {exc}") from exc
    if gltf is None:
        raise LoadError(f"cannot read {path} as binary glTF")
    return _GlbReader(gltf, path, texture_dir).models()


#: The binary chunk of one GLB (its byte counts are 32-bit), less room for the JSON chunk.
MAX_GLB_BYTES = (1 << 32) - (1 << 26)
#: The most elements one accessor may claim (a 2 GB binary's worth of floats).
MAX_ACCESSOR_COUNT = 1 << 27


def gltf_triangles(gltf: gl.GLTF2, path: Path, texture_dir) -> list:
    """``(positions, triangles, uv or None, material)`` of every triangle primitive of a loaded
    glTF, in scene coordinates (what inserting a ``.glb``/``.gltf`` asset needs); embedded
    images are written to ``texture_dir``."""
    return _GlbReader(gltf, Path(path), texture_dir).triangles()


class _GlbReader:
    """Models (or triangles) from a loaded glTF.  pygltflib keeps the JSON's values as they
    are, so every member read is checked here for its type, and every index for its range,
    before numpy sees it: a wrong one is a :class:`LoadError` naming the file and the member's
    JSON path (``accessors[3].count``).  Accessors are checked against the binary chunk before
    any array is made, so a small file cannot claim gigabytes."""

    def __init__(self, gltf: gl.GLTF2, path: Path, texture_dir) -> None:
        self.gltf = gltf
        self.path = path
        self.blob = gltf.binary_blob() or b""
        self.texture_dir = None if texture_dir is None else Path(texture_dir)
        self._materials: dict[int | None, Material] = {}
        self._images: dict[int, str | None] = {}

    # typed reads -----------------------------------------------------------------------------
    def _error(self, where: str, problem: str) -> LoadError:
        return LoadError(f"glTF file '{self.path}': {where} {problem}; export the file again")

    def _int(self, v, where: str, below: int | None = None) -> int:
        """``v`` when it is an integer in ``[0, below)`` (no upper bound when ``below`` is
        None)."""
        if type(v) is not int:
            raise self._error(where, f"must be an integer, not {json_type(v)}")
        if v < 0 or (below is not None and v >= below):
            shown = str(v) if len(str(v)) <= 24 else str(v)[:12] + "…"
            bound = "" if below is None else f" below {below}"
            raise self._error(where, f"is {shown}, not an integer from 0{bound}")
        return v

    def _list(self, v, where: str) -> list:
        """``v`` when it is an array (None: empty)."""
        if v is None:
            return []
        if not isinstance(v, list):
            raise self._error(where, f"must be an array, not {json_type(v)}")
        return v

    def _ref(self, index, table: str, where: str, kind: type):
        """The entry ``index`` of the top-level array ``table``, which must be a ``kind``."""
        items = self._list(getattr(self.gltf, table), table)
        i = self._int(index, where, len(items))
        if not isinstance(items[i], kind):
            raise self._error(f"{table}[{i}]", f"must be an object, not {json_type(items[i])}")
        return items[i]

    def _numbers(self, v, where: str, n: int) -> np.ndarray | None:
        """``v`` as ``n`` finite floats (None when absent or empty)."""
        if v is None or (isinstance(v, list) and not v):
            return None
        if not isinstance(v, list) or len(v) != n:
            raise self._error(where, f"must be an array of {n} numbers")
        for j, x in enumerate(v):
            if isinstance(x, bool) or not isinstance(x, (int, float)):
                raise self._error(f"{where}[{j}]", f"must be a number, not {json_type(x)}")
            try:
                finite = np.isfinite(float(x))
            except OverflowError:
                finite = False
            if not finite:
                raise self._error(f"{where}[{j}]", "must be a finite number")
        return np.array(v, float)

    def _dict(self, v, where: str) -> dict:
        """``v`` when it is an object (None: empty)."""
        if v is None:
            return {}
        if not isinstance(v, dict):
            raise self._error(where, f"must be an object, not {json_type(v)}")
        return v

    # scene -----------------------------------------------------------------------------------
    def _walk(self):
        """``(index, node, world matrix)`` of every node of the scene, depth first in order."""
        g = self.gltf
        nodes = self._list(g.nodes, "nodes")
        for i, node in enumerate(nodes):
            if not isinstance(node, gl.Node):
                raise self._error(f"nodes[{i}]", f"must be an object, not {json_type(node)}")
        scenes = self._list(g.scenes, "scenes")
        if scenes:
            s = 0 if g.scene is None else g.scene
            scene = self._ref(s, "scenes", "scene", gl.Scene)
            roots = [(n, f"scenes[{s}].nodes[{k}]")
                     for k, n in enumerate(self._list(scene.nodes, f"scenes[{s}].nodes"))]
        else:
            children = {c for i, n in enumerate(nodes)
                        for c in self._list(n.children, f"nodes[{i}].children")
                        if type(c) is int}
            roots = [(i, "") for i in range(len(nodes)) if i not in children]
        stack = [(i, where, np.eye(4), 0) for i, where in reversed(roots)]
        seen: set[int] = set()
        while stack:
            idx, where, parent, depth = stack.pop()
            if depth > 256:
                raise self._error(where, "is deeper than 256 nodes in the hierarchy (a cycle?)")
            idx = self._int(idx, where, len(nodes))
            if idx in seen:
                # glTF: a node has at most one parent (else a tiny file could repeat a mesh
                # 2^depth times)
                raise self._error(where, f"is node {idx}, which is reached twice")
            seen.add(idx)
            node = nodes[idx]
            world = parent @ self._node_matrix(node, f"nodes[{idx}]")
            yield idx, node, world
            kids = self._list(node.children, f"nodes[{idx}].children")
            stack.extend((c, f"nodes[{idx}].children[{k}]", world, depth + 1)
                         for k, c in reversed(list(enumerate(kids))))

    def _node_matrix(self, node: gl.Node, where: str) -> np.ndarray:
        """Local 4×4 transform of a node (``matrix`` or translation/rotation/scale)."""
        matrix = self._numbers(node.matrix, f"{where}.matrix", 16)
        if matrix is not None:
            return matrix.reshape(4, 4).T
        m = np.eye(4)
        rotation = self._numbers(node.rotation, f"{where}.rotation", 4)
        if rotation is not None:
            x, y, z, w = rotation
            m[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        scale = self._numbers(node.scale, f"{where}.scale", 3)
        if scale is not None:
            m[:3, :3] = m[:3, :3] * scale
        translation = self._numbers(node.translation, f"{where}.translation", 3)
        if translation is not None:
            m[:3, 3] = translation
        return m

    def _primitives(self, node: gl.Node, idx: int) -> list[tuple[gl.Primitive, str]]:
        """``(primitive, JSON path)`` of the node's mesh (none without a mesh)."""
        if node.mesh is None:
            return []
        mesh = self._ref(node.mesh, "meshes", f"nodes[{idx}].mesh", gl.Mesh)
        where = f"meshes[{node.mesh}].primitives"
        prims = self._list(mesh.primitives, where)
        for k, prim in enumerate(prims):
            if not isinstance(prim, gl.Primitive):
                raise self._error(f"{where}[{k}]", f"must be an object, not {json_type(prim)}")
        return [(prim, f"{where}[{k}]") for k, prim in enumerate(prims)]

    def models(self) -> list[Model]:
        out: list[Model] = []
        for idx, node, world in self._walk():
            model = self._node_model(node, idx, world)
            if model is not None:
                out.append(model)
        return out

    def triangles(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray | None, Material]]:
        """``(positions, triangles, uv or None, material)`` of every triangle primitive, the
        positions in scene coordinates and shared by the primitive's triangles."""
        out = []
        for idx, node, world in self._walk():
            for prim, where in self._primitives(node, idx):
                got = self._primitive_triangles(prim, world, where)
                if got is not None:
                    out.append((*got, self._material(prim.material, f"{where}.material")))
        return out

    def _node_model(self, node: gl.Node, idx: int, world: np.ndarray) -> Model | None:
        where = f"nodes[{idx}].extras"
        extras = node.extras if isinstance(node.extras, dict) else {}
        if node.mesh is None and not extras.get("facadeforge_model"):
            return None
        reports = self._dict(extras.get("reports"), f"{where}.reports")
        name = node.name if isinstance(node.name, str) and node.name else f"node{idx}"
        model = Model(name=name,
                      attributes=joined_attributes(
                          self._dict(extras.get("attributes"), f"{where}.attributes"),
                          self._dict(extras.get("georeference"), f"{where}.georeference")),
                      reports={str(k): list(self._list(v, f"{where}.reports.{k}"))
                               for k, v in reports.items()},
                      warnings=[str(w) for w in self._list(extras.get("warnings"),
                                                           f"{where}.warnings")])
        for prim, pw in self._primitives(node, idx):
            model.parts.extend(self._primitive_parts(prim, world, pw))
        return model

    # geometry --------------------------------------------------------------------------------
    def _primitive_triangles(self, prim: gl.Primitive, world: np.ndarray, where: str):
        """``(positions, triangles, uv or None)`` of a triangle primitive, else ``None``."""
        attrs = prim.attributes
        if prim.mode not in (None, gl.TRIANGLES) or not isinstance(attrs, gl.Attributes) \
                or attrs.POSITION is None:
            return None
        aw = f"{where}.attributes"
        pos = self._accessor(attrs.POSITION, f"{aw}.POSITION", "VEC3").astype(float)
        with np.errstate(over="ignore", invalid="ignore"):  # checked just below
            pos = pos @ world[:3, :3].T + world[:3, 3]
        if not (np.abs(pos) <= MAX_COORDINATE).all():
            raise self._error(f"{aw}.POSITION", f"holds positions that are not finite or lie "
                              f"beyond ±{MAX_COORDINATE:.0e} (node transforms applied)")
        if prim.indices is not None:
            tris = self._accessor(prim.indices, f"{where}.indices", "SCALAR",
                                  (gl.UNSIGNED_BYTE, gl.UNSIGNED_SHORT, gl.UNSIGNED_INT))
            if len(tris) % 3:
                raise self._error(f"{where}.indices", f"holds {len(tris)} indices, not whole "
                                  "triangles (a multiple of 3)")
            tris = tris.reshape(-1, 3).astype(np.int64)
        else:
            tris = np.arange(len(pos) - len(pos) % 3).reshape(-1, 3)
        if len(tris) and (tris.min() < 0 or tris.max() >= len(pos)):
            raise self._error(f"{where}.indices", f"refers to vertex {int(tris.max())} (or a "
                              f"negative one) of {len(pos)}")
        uv = None
        if attrs.TEXCOORD_0 is not None:
            uv = self._accessor(attrs.TEXCOORD_0, f"{aw}.TEXCOORD_0", "VEC2").astype(float)
            if len(uv) != len(pos):
                raise self._error(f"{aw}.TEXCOORD_0", f"has {len(uv)} elements for "
                                  f"{len(pos)} positions")
            if not np.isfinite(uv).all():
                raise self._error(f"{aw}.TEXCOORD_0", "holds numbers that are not finite")
            uv = np.column_stack([uv[:, 0], 1.0 - uv[:, 1]])
        if np.linalg.det(world[:3, :3]) < 0:
            tris = tris[:, ::-1]
        return pos, tris, uv

    def _primitive_parts(self, prim: gl.Primitive, world: np.ndarray, where: str) -> list[Part]:
        got = self._primitive_triangles(prim, world, where)
        if got is None:
            return []
        pos, tris, uv = got
        extras = prim.extras if isinstance(prim.extras, dict) else {}
        label = str(extras.get("label", ""))
        symbols = [str(s) for s in self._list(extras.get("symbols"), f"{where}.extras.symbols")]
        records = self._part_records(extras, f"{where}.extras", len(tris))
        material = self._material(prim.material, f"{where}.material")
        parts = []
        for sym, first, count, *rest in records:
            sel = tris[first:first + count]
            parts.append(Part(_triangle_mesh(pos, uv, sel), label=label, material=material,
                              symbol=symbols[sym] if 0 <= sym < len(symbols) else "",
                              shape_id=int(rest[0]) if rest else 0))
        return parts

    def _part_records(self, extras: dict, where: str, n_tris: int) -> list[list[int]]:
        """``[symbol, first triangle, triangle count, shape id]`` of each part of a primitive
        (one part of all its triangles without facadeforge's extras), checked against the
        primitive's ``n_tris`` triangles."""
        if isinstance(extras.get("parts_accessor"), int):
            table = self._accessor(extras["parts_accessor"], f"{where}.parts_accessor")
            if table.size % 4:
                raise self._error(f"{where}.parts_accessor", "must hold 4 numbers a part")
            records = table.reshape(-1, 4).astype(np.int64).tolist()
        else:
            records = self._list(extras.get("parts"), f"{where}.parts") or [[0, 0, n_tris, 0]]
        for k, r in enumerate(records):
            rw = f"{where}.parts[{k}]"
            if not (isinstance(r, list) and len(r) >= 3
                    and all(type(v) is int and abs(v) < 2**63 for v in r)):
                raise self._error(rw, "must be an array [symbol, first triangle, count, shape]")
            if r[1] < 0 or r[2] < 0 or r[1] + r[2] > n_tris:
                raise self._error(rw, f"selects triangles {r[1]} to {r[1] + r[2]} of the "
                                  f"primitive's {n_tris}")
        return records

    def _accessor(self, index, where: str, kind: str | None = None,
                  components: tuple[int, ...] | None = None) -> np.ndarray:
        """The elements of accessor ``index`` ((N, width) or (N,) for scalars), checked to be
        of type ``kind`` and one of the ``components`` types when given."""
        acc = self._ref(index, "accessors", where, gl.Accessor)
        aw = f"accessors[{index}]"
        if type(acc.componentType) is not int or acc.componentType not in _COMPONENT_DTYPES:
            raise self._error(f"{aw}.componentType", f"is {acc.componentType!r}, not one of "
                              f"{sorted(_COMPONENT_DTYPES)}")
        if components is not None and acc.componentType not in components:
            raise self._error(f"{aw}.componentType", f"is {acc.componentType}, but {where} "
                              f"must be one of {list(components)}")
        if not isinstance(acc.type, str) or acc.type not in _TYPE_WIDTH:
            raise self._error(f"{aw}.type", f"is {acc.type!r}, not one of {list(_TYPE_WIDTH)}")
        if kind is not None and acc.type != kind:
            raise self._error(f"{aw}.type", f"is {acc.type}, but {where} must be {kind}")
        dtype = np.dtype(_COMPONENT_DTYPES[acc.componentType])
        width = _TYPE_WIDTH[acc.type]
        count = self._int(acc.count or 0, f"{aw}.count")
        if count > MAX_ACCESSOR_COUNT:
            raise self._error(f"{aw}.count", f"claims {count} elements, more than the "
                              f"{MAX_ACCESSOR_COUNT} one accessor may have")
        element = dtype.itemsize * width
        if acc.bufferView is None:  # all zeros (sparse data is not read)
            if count * element > len(self.blob) + 1_000_000:
                raise self._error(aw, f"has no data for its {count} elements (no "
                                  "bufferView), more than the file could hold")
            return np.zeros((count, width), dtype).squeeze(axis=1) if width == 1 else \
                np.zeros((count, width), dtype)
        view = self._ref(acc.bufferView, "bufferViews", f"{aw}.bufferView", gl.BufferView)
        vw = f"bufferViews[{acc.bufferView}]"
        if view.buffer not in (0, None):
            raise self._error(f"{vw}.buffer", "is not 0: only the GLB's binary chunk is read")
        inside = self._int(acc.byteOffset or 0, f"{aw}.byteOffset")  # where it starts in its view
        view_offset = self._int(view.byteOffset or 0, f"{vw}.byteOffset")
        view_length = self._int(view.byteLength or 0, f"{vw}.byteLength")
        stride = element if view.byteStride is None else self._int(view.byteStride,
                                                                   f"{vw}.byteStride")
        if not element <= stride <= max(252, element):
            # glTF 2.0 §3.6.2.4: at least an element, at most 252 bytes; an element never
            # overlaps the next, so an array is never larger than the bytes it is read from
            raise self._error(f"{vw}.byteStride", f"is {stride}, not from {element} "
                              "(the element's size) to 252")
        offset = view_offset + inside
        span = stride * (count - 1) + element if count else 0
        if inside + span > view_length or offset + span > len(self.blob):
            raise self._error(aw, f"runs past its buffer view ({count} elements of {element} "
                              f"bytes every {stride} from byte {offset}; the view ends at "
                              f"{view_offset + view_length}, the binary chunk at "
                              f"{len(self.blob)})")
        arr = np.ndarray((count, width), dtype, buffer=self.blob, offset=offset,
                         strides=(stride, dtype.itemsize)).copy()
        if acc.normalized and dtype.kind in "iu":
            arr = arr.astype(float) / np.iinfo(dtype).max
        return arr[:, 0] if width == 1 else arr

    # appearance ------------------------------------------------------------------------------
    def _material(self, index, where: str) -> Material:
        if index is None:
            return Material()
        key = self._int(index, where, len(self._list(self.gltf.materials, "materials")))
        if key not in self._materials:
            self._materials[key] = self._make_material(key)
        return self._materials[key]

    def _make_material(self, index: int) -> Material:
        where = f"materials[{index}]"
        mat = self._ref(index, "materials", where, gl.Material)
        pbr = mat.pbrMetallicRoughness
        if pbr is None:
            pbr = gl.PbrMetallicRoughness()
        elif not isinstance(pbr, gl.PbrMetallicRoughness):
            raise self._error(f"{where}.pbrMetallicRoughness", "must be an object")
        pw = f"{where}.pbrMetallicRoughness"
        factor = self._numbers(pbr.baseColorFactor, f"{pw}.baseColorFactor", 4)
        factor = np.ones(4) if factor is None else np.clip(factor, 0.0, 1.0)
        texture = None
        info = pbr.baseColorTexture
        if info is not None:
            if not isinstance(info, gl.TextureInfo):
                raise self._error(f"{pw}.baseColorTexture", "must be an object")
            tex = self._ref(info.index, "textures", f"{pw}.baseColorTexture.index", gl.Texture)
            if tex.source is not None:
                images = self._list(self.gltf.images, "images")
                texture = self._image_file(self._int(tex.source, f"textures[{info.index}].source",
                                                     len(images)))
        metallic = self._numbers([pbr.metallicFactor], f"{pw}.metallicFactor", 1) \
            if pbr.metallicFactor is not None else None
        roughness = self._numbers([pbr.roughnessFactor], f"{pw}.roughnessFactor", 1) \
            if pbr.roughnessFactor is not None else None
        return Material(name=mat.name if isinstance(mat.name, str) and mat.name
                        else f"material{index}",
                        color=tuple(float(c) for c in factor[:3]), opacity=float(factor[3]),
                        texture=texture,
                        metallic=1.0 if metallic is None else float(metallic[0]),
                        roughness=1.0 if roughness is None else float(roughness[0]))

    def _image_file(self, index: int) -> str | None:
        if index in self._images:
            return self._images[index]
        where = f"images[{index}]"
        image = self._ref(index, "images", where, gl.Image)
        result = None
        if image.bufferView is not None:
            view = self._ref(image.bufferView, "bufferViews", f"{where}.bufferView",
                             gl.BufferView)
            vw = f"bufferViews[{image.bufferView}]"
            start = self._int(view.byteOffset or 0, f"{vw}.byteOffset")
            length = self._int(view.byteLength or 0, f"{vw}.byteLength")
            if start + length > len(self.blob):
                raise self._error(vw, "runs past the binary chunk")
            data = bytes(self.blob[start:start + length])
            if self.texture_dir is None:
                self.texture_dir = Path(tempfile.mkdtemp(prefix="facadeforge-glb-"))
            self.texture_dir.mkdir(parents=True, exist_ok=True)
            digest = hashlib.sha1(data).hexdigest()[:12]  # same name, same content
            mime = image.mimeType if isinstance(image.mimeType, str) else ""
            target = self.texture_dir / (f"{self.path.stem}_image{index}_{digest}"
                                         f"{image_extension(mime)}")
            if not target.is_file() or target.is_symlink():
                # written whole and then renamed: parallel workers never read half a file
                part = target.with_name(f".{target.name}.{os.getpid()}.part")
                try:
                    part.write_bytes(data)
                    os.replace(part, target)
                except OSError:
                    part.unlink(missing_ok=True)
                    raise
            result = str(target)
        elif isinstance(image.uri, str) and image.uri and not image.uri.startswith("data:") \
                and "://" not in image.uri:
            # an image beside the file or below it, as glTF's relative URIs are; never a
            # file elsewhere that the model names
            folder = self.path.parent.resolve()
            candidate = (folder / image.uri).resolve()
            if folder in candidate.parents and candidate.is_file():
                result = str(candidate)
        self._images[index] = result
        return result


def _triangle_mesh(pos: np.ndarray, uv: np.ndarray | None, tris: np.ndarray) -> Mesh:
    """A mesh of unshared triangles (one face per triangle)."""
    corners = tris.reshape(-1)
    n = len(corners)
    return mesh_from_flat(pos[corners], np.arange(n), np.arange(0, n + 1, 3),
                          None if uv is None else uv[corners])

