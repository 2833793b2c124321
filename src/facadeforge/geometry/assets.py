"""Asset resolution and loading: OBJ meshes (other formats: ``asset_formats``) and textures,
confined to an asset root.

Paths in rules resolve like CityEngine's: relative paths against the asset folder (also tried
against the rule file's folder), project-absolute paths (``/Project/assets/x.obj``) through a
rule package's resolve map or by stripping the project prefix.  A resolved path that leaves every
allowed root is refused: rule text cannot read arbitrary files (``SECURITY.md``).

The roots of a rule file (:func:`rule_roots`) are its own folder and, when it lies in a
CityEngine project (``<project>/rules/…`` beside ``<project>/assets`` or ``.project``), that
project; never the folder above a project, and never a folder that holds other people's files
as well (the home folder, the temporary folder, the file system's root).  Hidden files and
folders (``.ssh``, ``.env``) are never read, whatever the root.
"""

from __future__ import annotations

import fnmatch
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..model.model import MAX_COORDINATE
from .mesh import Mesh

MAX_ASSET_BYTES = 256 * 1024 * 1024
#: Largest text or table file a rule may read (``readTextFile``, ``readStringTable``…): such
#: files are a few kilobytes; their cells become Python objects of ten times their size.
MAX_TEXT_BYTES = 16 * 1024 * 1024
#: Largest texture file a model may name (an 8k × 8k RGBA PNG is about 100 MiB at most).
MAX_TEXTURE_BYTES = 128 * 1024 * 1024
#: Files ``fileSearch``/``fileRandom`` may look through under the asset root.
MAX_SEARCH_FILES = 100_000


def _shared_folders() -> set[Path]:
    """Folders that hold more than one project's files: a rule file lying directly in one of
    them gets no folder of its own to read from."""
    import tempfile

    out = {Path("/").resolve(), Path(tempfile.gettempdir()).resolve()}
    try:
        out.add(Path.home().resolve())
    except (KeyError, RuntimeError, OSError):  # no home folder (a service account)
        pass
    return out


def rule_roots(folder: Path) -> list[Path]:
    """The folders a rule file in ``folder`` may read: ``folder`` itself and, when it lies in a
    CityEngine project (an ancestor called ``rules`` whose parent holds ``assets/`` or a
    ``.project`` file), the project folder.  Shared folders (home, temporary folder, root) are
    left out.

    Parameters
    ----------
    folder : Path
        The rule file's folder.

    Returns
    -------
    list of Path
        Resolved roots, the rule's folder first (empty when it is a shared folder).
    """
    folder = Path(folder).resolve()
    shared = _shared_folders()
    roots = [] if folder in shared else [folder]
    for d in [folder, *folder.parents]:
        if d.name == "rules":
            project = d.parent
            if project not in shared and ((project / "assets").is_dir()
                                          or (project / ".project").is_file()):
                roots.append(project)
            break
    return roots


def inside(root: Path, p: Path) -> bool:
    """Whether resolved path ``p`` is ``root`` or lies below it, through no hidden file or
    folder (a name starting with a dot)."""
    if p == root:
        return True
    if root not in p.parents:
        return False
    return not any(part.startswith(".") for part in p.relative_to(root).parts)


@dataclass
class AssetMaterial:
    name: str = ""
    color: tuple = (1.0, 1.0, 1.0)
    texture: str | None = None
    opacity: float = 1.0


@dataclass
class Asset:
    """A loaded mesh with its materials: ``face_material[i]`` indexes ``materials``."""

    mesh: Mesh
    material: AssetMaterial = field(default_factory=AssetMaterial)
    materials: list = field(default_factory=list)
    face_material: np.ndarray | None = None
    _column: np.ndarray | None = field(default=None, repr=False, compare=False)

    def material_column(self) -> np.ndarray:
        """(F,) object array: each face's material (made once; meshes share it, unchanged)."""
        if self._column is None:
            col = np.empty(len(self.face_material), dtype=object)
            col[:] = [self.materials[k] for k in self.face_material]
            self._column = col
        return self._column


class AssetResolver:
    """Find and load assets for one rule set.

    Parameters
    ----------
    roots : list of Path
        Folders assets may be read from (the asset root, the rule file's folder, an unpacked
        rule package).  The first is where relative paths are looked up first.
    resolve_map : dict of str to Path
        Project-absolute path → file (from a rule package's ``.resolvemap.xml``).
    """

    def __init__(self, roots=(), resolve_map: dict | None = None):
        self.roots = [Path(r).resolve() for r in roots if r]
        self.resolve_map = {k: Path(v).resolve() for k, v in (resolve_map or {}).items()}
        self._mesh_cache: dict[Path, Asset] = {}
        self._resolved: dict[str, Path | None] = {}
        self._searched: dict[str, list[str]] = {}

    # -- paths ---------------------------------------------------------------------------------
    def allowed(self, p: Path) -> bool:
        """Whether resolved path ``p`` may be read: inside a root (see :func:`inside`) or a
        file of the resolve map."""
        return any(inside(r, p) for r in self.roots) or p in self.resolve_map.values()

    def resolve(self, name: str) -> Path | None:
        """Readable file for an asset name, or ``None`` when there is none.

        Raises
        ------
        InputError
            When the path points outside every asset root.
        """
        if name in self._resolved:
            return self._resolved[name]
        found = self._resolve(name)
        self._resolved[name] = found
        return found

    def _resolve(self, name: str) -> Path | None:
        name = name.strip().replace("\\", "/")
        if not name:
            return None
        if name in self.resolve_map:
            return self.resolve_map[name]
        candidates = []
        if name.startswith("/"):
            direct = Path(name).resolve()
            if direct.is_file() and self.allowed(direct):
                return direct
            parts = [p for p in name.split("/") if p]
            # "/Project/assets/a.obj" → try "assets/a.obj" and "a.obj" beneath each root
            for k in range(1, len(parts)):
                candidates.append("/".join(parts[k:]))
        else:
            candidates.append(name)
        for rel in candidates:
            for root in self.roots:
                p = (root / rel).resolve()
                if not self.allowed(p):
                    raise InputError(f"asset path '{name}' leaves the asset root {root}; "
                                     "keep assets inside the asset folder")
                if p.is_file():
                    return p
        return None

    def search(self, pattern: str) -> list[str]:
        """Asset paths (relative to the first root) matching a glob pattern (``fileSearch``)."""
        if pattern in self._searched:
            return self._searched[pattern]
        out = []
        pat = pattern.lstrip("/")
        seen = 0
        for root in self.roots[:1]:
            for dirpath, dirs, files in os.walk(root):
                dirs[:] = [d for d in dirs if not d.startswith(".")]  # hidden folders stay shut
                seen += len(files)
                if seen > MAX_SEARCH_FILES:
                    raise InputError(f"fileSearch('{pattern}'): the asset root {root} holds more "
                                     f"than {MAX_SEARCH_FILES} files; give a smaller --assets "
                                     "folder")
                for f in files:
                    if f.startswith("."):
                        continue
                    rel = os.path.relpath(os.path.join(dirpath, f), root).replace(os.sep, "/")
                    if fnmatch.fnmatch(rel, pat) or fnmatch.fnmatch(f, pat):
                        out.append(rel)
        self._searched[pattern] = sorted(out)
        return self._searched[pattern]

    def read_bytes(self, name: str, limit: int = MAX_TEXT_BYTES) -> bytes | None:
        """The contents of a small file under the asset roots (tables, text), ``None`` when
        there is none.

        Raises
        ------
        InputError
            When the path leaves the asset roots or the file is larger than ``limit`` bytes.
        """
        p = self.resolve(name)
        if p is None:
            return None
        size = p.stat().st_size
        if size > limit:
            raise InputError(f"'{name}' is {size >> 20} MiB, larger than the {limit >> 20} MiB a "
                             "rule may read as text")
        return p.read_bytes()

    # -- loading -------------------------------------------------------------------------------
    def mesh(self, name: str) -> Asset | None:
        p = self.resolve(name)
        if p is None:
            return None
        cached = self._mesh_cache.get(p)
        if cached is None:
            from .asset_formats import ASSIMP_SUFFIXES, GLTF_SUFFIXES, load_assimp, load_gltf

            suffix = p.suffix.lower()
            if p.stat().st_size > MAX_ASSET_BYTES:
                raise InputError(f"asset {p} is larger than {MAX_ASSET_BYTES >> 20} MiB")
            if suffix == ".obj":
                cached = load_obj(p)
            elif suffix in GLTF_SUFFIXES:
                cached = load_gltf(p)
            elif suffix in ASSIMP_SUFFIXES:
                cached = load_assimp(p)
            else:
                raise InputError(f"asset '{name}': {p.suffix or 'a file without suffix'} cannot "
                                 "be inserted; use .obj, " + ", ".join(
                                     s for s in (*GLTF_SUFFIXES, *ASSIMP_SUFFIXES)))
            self._mesh_cache[p] = cached
        return cached

    def texture(self, name: str, derivation=None) -> str | None:
        from .asset_formats import cached_texture

        cached = cached_texture(name)  # an image taken out of an inserted .glb asset
        if cached is not None:
            return cached
        try:
            p = self.resolve(name)
        except InputError as e:
            if derivation is not None:
                derivation.warn(str(e))
            return None
        if p is None:
            if derivation is not None:
                derivation.warn(f"texture '{name}' not found under the asset root")
            return None
        if p.stat().st_size > MAX_TEXTURE_BYTES:
            if derivation is not None:
                derivation.warn(f"texture '{name}' is larger than {MAX_TEXTURE_BYTES >> 20} MiB; "
                                "not used (make it smaller)")
            return None
        return str(p)


def load_obj(path: Path) -> Asset:
    """Read a Wavefront OBJ (positions, polygons, uv set 0, first material's colour/texture)."""
    path = Path(path)
    if path.stat().st_size > MAX_ASSET_BYTES:
        raise InputError(f"asset {path} is larger than {MAX_ASSET_BYTES >> 20} MiB")
    verts, uvs, faces, face_uv = [], [], [], []
    mtllibs, first_mtl, current_mtl, face_mtl = [], None, None, []
    group, face_group = None, []
    with open(path, encoding="utf-8", errors="replace") as fh:
        for number, line in enumerate(fh, 1):
            if not line or line[0] == "#":
                continue
            parts = line.split()
            if not parts:
                continue
            tag = parts[0]
            try:
                if tag == "v":
                    verts.append(_coordinates(parts[1:4], 3, path, number))
                elif tag == "vt":
                    # "vt u" is legal OBJ: v defaults to 0
                    uvs.append(_coordinates((parts[1:3] + ["0"] * (len(parts) == 2))[:2], 2,
                                            path, number))
                elif tag == "f":
                    vi, ti = [], []
                    for tok in parts[1:]:
                        fields = tok.split("/")
                        v = int(fields[0])
                        vi.append(v - 1 if v > 0 else len(verts) + v)
                        if len(fields) > 1 and fields[1]:
                            t = int(fields[1])
                            ti.append(t - 1 if t > 0 else len(uvs) + t)
                    if len(vi) >= 3:
                        faces.append(vi)
                        face_uv.append(ti if len(ti) == len(vi) else None)
                        face_mtl.append(current_mtl)
                        face_group.append(group)
                elif tag in ("g", "o"):
                    group = " ".join(parts[1:]) or None
                elif tag == "mtllib":
                    mtllibs.append(" ".join(parts[1:]))
                elif tag == "usemtl":
                    current_mtl = " ".join(parts[1:])
                    first_mtl = first_mtl or current_mtl
            except (ValueError, IndexError):
                raise InputError(f"{path}: malformed OBJ line: {line.strip()[:80]}") from None
    if not faces:
        raise InputError(f"{path}: the OBJ file has no faces")
    v = np.asarray(verts, float)
    if any(max(f) >= len(v) or min(f) < 0 for f in faces):
        raise InputError(f"{path}: a face refers to a vertex that does not exist")
    uv_arr = np.asarray(uvs, float) if uvs else np.zeros((0, 2))
    corner_uvs = None
    if uvs and all(t is not None for t in face_uv):
        corner_uvs = [uv_arr[t] for t in face_uv]
    mesh = Mesh(v, faces, corner_uvs)
    order = list(dict.fromkeys(g for g in face_group if g is not None))
    if len(order) > 1:  # comp(g): one component per group, in the file's order
        rank = {g: k for k, g in enumerate(order)}
        mesh = mesh.with_column("group", [None if g is None else (rank[g], g) for g in face_group])
    mats: dict[str, AssetMaterial] = {}
    for lib in mtllibs:
        mp = (path.parent / lib).resolve()
        if mp.parent == path.parent.resolve() and mp.is_file():
            mats.update({name: AssetMaterial(name, m.get("color", (1.0, 1.0, 1.0)),
                                             m.get("colormap"), m.get("opacity", 1.0))
                         for name, m in read_mtl(mp).items()})
    names = sorted({m for m in face_mtl if m is not None})
    material_list = [mats.get(n, AssetMaterial(n)) for n in names]
    face_material = None
    if len(names) > 1:
        lookup = {n: i for i, n in enumerate(names)}
        face_material = np.array([lookup.get(m, 0) for m in face_mtl], np.int64)
    material = mats.get(first_mtl) if first_mtl in mats else (
        next(iter(mats.values())) if mats else AssetMaterial())
    return Asset(mesh, material, material_list, face_material)


def _coordinates(tokens: list[str], n: int, path: Path, number: int) -> list[float]:
    """The ``n`` numbers of a ``v``/``vt`` line (line ``number``), refused unless finite and
    of magnitude at most :data:`~facadeforge.geometry.footprints.MAX_COORDINATE`: ``float``
    reads ``nan`` and ``1e300`` without complaint, and such a vertex would otherwise surface
    far away as a polygon that is not horizontal, or an exporter's overflow."""
    values = [float(x) for x in tokens]  # ValueError: a malformed line, reported by the caller
    if len(values) < n:
        kind = "vertex" if n == 3 else "texture vertex"
        raise InputError(f"{path}:{number}: a {kind} needs {n} numbers, this one has "
                         f"{len(values)}; fix the OBJ file")
    for v in values:
        if not abs(v) <= MAX_COORDINATE:  # NaN compares false too
            raise InputError(f"{path}:{number}: coordinate {v:g} is not a finite number of "
                             f"magnitude at most {MAX_COORDINATE:.0e}; fix the OBJ file "
                             "(coordinates in metres)")
    return values


#: MTL keys → CGA material attributes: colours, numbers, texture maps.
_MTL_COLORS = {"Kd": "color", "Ka": "ambient", "Ks": "specular", "Ke": "emissive"}
_MTL_NUMBERS = {"Ns": "shininess", "Pr": "roughness", "Pm": "metallic"}
_MTL_MAPS = {"map_kd": "colormap", "map_bump": "bumpmap", "bump": "bumpmap",
             "map_ks": "specularmap", "map_d": "opacitymap", "norm": "normalmap",
             "map_ke": "emissivemap", "map_pr": "roughnessmap", "map_pm": "metallicmap"}


def read_mtl(path: Path) -> dict[str, dict]:
    """The materials of a Wavefront ``.mtl`` file, in file order, each as CGA material
    attributes: ``name``, ``color``/``ambient``/``specular``/``emissive`` (r, g, b),
    ``opacity``, ``shininess``, ``roughness``, ``metallic`` and texture maps (``colormap``…)
    as paths of readable files in the file's folder or below (others are left out).
    Malformed lines are skipped."""
    path = Path(path)
    folder = path.parent.resolve()
    found: dict[str, dict] = {}
    current: dict | None = None
    with open(path, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            parts = line.split()
            if not parts or parts[0].startswith("#"):
                continue
            key = parts[0]
            if key == "newmtl":
                name = " ".join(parts[1:])
                current = found.setdefault(name, {"name": name})
                continue
            if current is None:
                continue
            try:
                if key in _MTL_COLORS and len(parts) >= 4:
                    current[_MTL_COLORS[key]] = tuple(float(x) for x in parts[1:4])
                elif key == "d" and len(parts) >= 2:
                    current["opacity"] = float(parts[1])
                elif key == "Tr" and len(parts) >= 2 and "opacity" not in current:
                    current["opacity"] = 1.0 - float(parts[1])
                elif key in _MTL_NUMBERS and len(parts) >= 2:
                    current[_MTL_NUMBERS[key]] = float(parts[1])
                elif key.lower() in _MTL_MAPS and len(parts) >= 2:
                    tex = (folder / parts[-1].replace("\\", "/")).resolve()
                    if folder in tex.parents and tex.is_file():
                        current[_MTL_MAPS[key.lower()]] = str(tex)
            except ValueError:
                continue
    return found
