"""One OUTDIR being edited: its shape tree, the edits made (undo, redo), the model re-derived
after each edit, and the save that rewrites the OUTDIR's files atomically.

The flow is one way: an edit changes the shape tree (:mod:`.edits`); the rules are extracted
from the tree again (:func:`facadeforge.grammar.extract.extract_rules`, Müller §5) and derived
on the facade rectangle (:func:`facadeforge.engine.derive_facade`) in a scratch folder holding
the facade's texture and element assets; the page shows that model.  :meth:`EditSession.save`
writes ``shape_tree.json``, ``rules.cga``, ``model.glb/.obj/.city.json``, ``labels.png``,
``structure.png`` and ``report.json`` (with the edits appended under ``"edits"``) through
:func:`facadeforge.outdir.write_outdir`: the whole OUTDIR is staged beside itself and swapped in,
so a failed save leaves every file as it was.
"""

from __future__ import annotations

import copy
import io
import shutil
import threading
import time
import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..model.shape import Shape
from .edits import EditError, apply_edit, update_boxes

__all__ = ["MAX_HISTORY", "EditSession", "find_facades"]

#: Edits kept for undo.
MAX_HISTORY: int = 500
#: Largest ``shape_tree.json`` read (a photo's tree is a few hundred kB).
MAX_TREE_BYTES: int = 64 * 2**20
#: The images a facade folder may show under its tree, best first.
_BACKDROPS = ("rectified.png", "ortho.png")


def find_facades(outdir: Path) -> list[str]:
    """The facade folders of an OUTDIR, relative to it: ``"."`` for a single facade's OUTDIR
    (``reconstruct``, ``parse``), else each ``facade_NN`` that holds a shape tree."""
    if (outdir / "shape_tree.json").is_file():
        return ["."]
    return sorted(p.parent.name for p in outdir.glob("facade_*/shape_tree.json"))


@dataclass
class _Derived:
    rules: str
    glb: bytes
    model: object
    seconds: float


class EditSession:
    """An OUTDIR of ``reconstruct``, ``parse`` or ``points`` opened for editing.

    Parameters
    ----------
    outdir : path
        The OUTDIR (it holds ``shape_tree.json``, or ``facade_NN/`` folders that do).  For a
        ``points`` OUTDIR the facade is shown and derived on its orthophoto; a save writes the
        facade's files and rebuilds the top ``model.*`` of every facade in the scan's frame.
    facade : str, optional
        Which facade folder (``facade_01``); the first by default.
    """

    def __init__(self, outdir, facade: str | None = None):
        self.outdir = Path(outdir).resolve()
        if not self.outdir.is_dir():
            raise InputError(f"edit: {outdir} is not a folder; give the OUTDIR of "
                             "`facadeforge reconstruct`, `parse` or `points`")
        self.facades = find_facades(self.outdir)
        if not self.facades:
            raise InputError(f"edit: {outdir} holds no shape_tree.json (nor facade_NN/ "
                             "folders with one); give the OUTDIR of `facadeforge reconstruct` "
                             "or `facadeforge parse`")
        facade = facade or self.facades[0]
        if facade not in self.facades:
            raise InputError(f"edit: --facade {facade} is not a facade of {outdir}; choose "
                             f"one of {', '.join(self.facades)}")
        self.facade = facade
        self.folder = (self.outdir / facade).resolve()
        # a `points` OUTDIR: one model of every facade in the scan's frame, at the top
        self.scan = (self.outdir / "planes.json").is_file() and facade != "."
        self.tree = _read_tree(self.folder / "shape_tree.json")
        self.report = _read_json(self.folder / "report.json") if not self.scan else \
            _read_json(self.outdir / "report.json")
        self.backdrop = next((self.folder / n for n in _BACKDROPS
                              if (self.folder / n).is_file()), None)
        self.textured = (self.folder / "texture.jpg").is_file()
        self._undo: list[dict] = []       # tree snapshots before each edit
        self._redo: list[dict] = []
        self.log: list[dict] = []         # the edits in effect (undo pops, redo pushes)
        self._redo_log: list[dict] = []
        self.version = 0
        self.saved_version = 0
        self._rgb: np.ndarray | None = None
        self.lock = threading.RLock()
        from ..scratch import scratch_dir

        self.work = scratch_dir("facadeforge-edit-")
        weakref.finalize(self, shutil.rmtree, self.work, True)
        if self.textured:
            shutil.copy2(self.folder / "texture.jpg", self.work / "texture.jpg")
        elif self.scan and self.backdrop is not None:   # as `points` textured it: the ortho
            _scan_texture(self.folder, self.tree, self.work / "texture.jpg")
            self.textured = True
        if (self.folder / "assets").is_dir():
            shutil.copytree(self.folder / "assets", self.work / "assets", dirs_exist_ok=True)
        update_boxes(self.tree)
        self.derived = self._derive()

    # -- state ------------------------------------------------------------------------------------
    def state(self) -> dict:
        """What the page shows besides the tree: versions, what undo/redo can do, the facade."""
        w, h = (float(v) for v in self.tree.scope.size[:2])
        return {"version": self.version, "saved_version": self.saved_version,
                "dirty": self.version != self.saved_version,
                "can_undo": bool(self._undo), "can_redo": bool(self._redo),
                "edits": len(self.log), "facade": self.facade, "facades": self.facades,
                "size_m": [w, h], "outdir": str(self.outdir),
                "backdrop": self.backdrop.name if self.backdrop else None,
                "flags": self.report.get("flags", []),
                "derive_seconds": round(self.derived.seconds, 3),
                "rules": self.derived.rules}

    def tree_dict(self) -> dict:
        """A copy of the tree as ``shape_tree.json`` holds it (nothing shared with the live
        tree: ``Shape.to_dict`` hands out the shapes' own tag dicts)."""
        with self.lock:
            return self._snapshot()

    def payload(self) -> dict:
        """``{"state", "tree"}`` of one moment (taken under the lock)."""
        with self.lock:
            return {"state": self.state(), "tree": self._snapshot()}

    def _snapshot(self) -> dict:
        return copy.deepcopy(self.tree.to_dict())

    # -- edits ------------------------------------------------------------------------------------
    def apply(self, edit: dict) -> dict:
        """Apply one edit (:mod:`.edits`), re-derive the model; an edit that fails (a bad edit,
        or rules that no longer derive) leaves the session as it was."""
        with self.lock:
            before = self._snapshot()
            if isinstance(edit, dict) and edit.get("op") == "reanalyse":
                done = self._reanalyse(edit)
            else:
                done = apply_edit(self.tree, edit)
            try:
                derived = self._derive()
            except Exception:
                self.tree = Shape.from_dict(before)
                raise
            self.derived = derived
            self._push(before)
            self.log.append({"edit": copy.deepcopy(dict(edit)), "result": done,
                             "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())})
            self._redo_log.clear()
            return done

    def _reanalyse(self, edit: dict) -> dict:
        """The ``reanalyse`` edit (:mod:`.reanalyse`) on a copy of the tree, kept if it works."""
        from .reanalyse import reanalyse

        if self.backdrop is None or self.backdrop.name != "rectified.png":
            raise EditError("reanalyse needs the facade's rectified photo (rectified.png), "
                            "which this OUTDIR does not hold")
        if self._rgb is None:
            from PIL import Image

            with Image.open(self.backdrop) as im:
                self._rgb = np.asarray(im.convert("RGB"))
        trial = Shape.from_dict(self._snapshot())
        done = reanalyse(trial, edit, self._rgb, counter=_next_region(self.tree))
        self.tree = trial
        return done

    def undo(self) -> bool:
        """Take the last edit back; ``False`` when there is none."""
        return self._step(self._undo, self._redo, self.log, self._redo_log)

    def redo(self) -> bool:
        """Make the last undone edit again; ``False`` when there is none."""
        return self._step(self._redo, self._undo, self._redo_log, self.log)

    def _step(self, trees: list, others: list, log: list, other_log: list) -> bool:
        """Move one snapshot (and its log entry) from ``trees`` to ``others`` and restore it."""
        with self.lock:
            if not trees:
                return False
            tree = Shape.from_dict(copy.deepcopy(trees[-1]))
            update_boxes(tree)
            derived = self._derive(tree)        # a failure here changes nothing
            others.append(self._snapshot())
            other_log.append(log.pop())
            trees.pop()
            self.tree, self.derived = tree, derived
            self.version += 1
            return True

    def _push(self, before: dict) -> None:
        self._undo.append(before)
        del self._undo[:-MAX_HISTORY]
        self._redo.clear()
        self.version += 1

    # -- derivation -------------------------------------------------------------------------------
    def _derive(self, tree: Shape | None = None) -> _Derived:
        from ..engine import derive_facade
        from ..exchange import export
        from ..grammar.extract import extract_rules
        from ..reconstruction import DEFAULT_DEPTHS, write_element_assets

        tree = self.tree if tree is None else tree
        t0 = time.perf_counter()
        write_element_assets(tree, self.work)
        # `points` measured its depths per element, and extracted with no class defaults
        rules = extract_rules(tree, texture="texture.jpg" if self.textured else None,
                              depths={} if self.scan else DEFAULT_DEPTHS)
        (self.work / "rules.cga").write_text(rules, encoding="utf-8")
        w, h = (float(v) for v in tree.scope.size[:2])
        model = derive_facade(self.work / "rules.cga", w, h, assets=self.work, name="facade")
        glb = self.work / "preview.glb"
        export(model, glb)
        return _Derived(rules, glb.read_bytes(), model, time.perf_counter() - t0)

    # -- save -------------------------------------------------------------------------------------
    def save(self) -> list[str]:
        """Rewrite the facade's files in the OUTDIR atomically (module docstring); returns the
        files written, relative to the OUTDIR."""
        from PIL import Image

        from ..exchange import export
        from ..exchange.raster import label_map, write_label_png
        from ..outdir import MARKER, write_json, write_outdir
        from ..reconstruction import _write_gml, draw_structure

        with self.lock:
            written: list[str] = []
            rel = Path(self.facade)

            def write(stage: Path) -> None:
                shutil.copytree(self.outdir, stage, dirs_exist_ok=True, symlinks=True,
                                ignore=lambda d, names: [MARKER] if Path(d) == self.outdir
                                else [])
                dest = stage / rel
                top = stage if self.scan else dest     # where the model files live
                for name in ("model.glb", "model.obj", "model.mtl", "model.city.json"):
                    (top / name).unlink(missing_ok=True)
                shutil.rmtree(top / "textures", ignore_errors=True)
                write_json(dest / "shape_tree.json", self.tree.to_dict(), indent=1)
                (dest / "rules.cga").write_text(self.derived.rules, encoding="utf-8")
                report = dict(self.report)
                if (dest / "rules.gml").exists():
                    _write_gml(self.tree, dest / "rules.gml", {})
                if self.scan:
                    models = self._scan_models()
                else:
                    if (self.work / "assets").is_dir():
                        shutil.copytree(self.work / "assets", dest / "assets",
                                        dirs_exist_ok=True)
                    models = self.derived.model
                for suffix in ("glb", "obj", "city.json"):
                    export(models, top / f"model.{suffix}")
                if self.backdrop is not None:
                    with Image.open(self.backdrop) as im:
                        rgb = np.asarray(im.convert("RGB"))
                    write_label_png(label_map(self.tree, size=rgb.shape[:2]), dest / "labels.png")
                    if self.backdrop.name == "rectified.png" and (dest / "structure.png").exists():
                        Image.fromarray(draw_structure(rgb, self.tree)).save(
                            dest / "structure.png", compress_level=1)
                    elif self.scan:      # as `points` draws it: the ortho, leaves tinted
                        from ..exchange.raster import PALETTE

                        tint = PALETTE[label_map(self.tree, size=rgb.shape[:2])]
                        Image.fromarray(np.clip(0.6 * rgb + 0.4 * tint, 0, 255).astype(
                            np.uint8)).save(dest / "structure.png")
                report["edits"] = list(report.get("edits", [])) + [
                    {**e, "facade": self.facade} for e in self.log]
                report["rules_source"] = "facadeforge edit: extracted from the edited shape tree"
                write_json(top / "report.json", report)
                for folder in {dest, top}:
                    written.extend(p.relative_to(stage).as_posix() for p in folder.iterdir()
                                   if p.is_file())
                written.sort()

            write_outdir(self.outdir, write, carry_foreign=True)
            self.report = _read_json((self.outdir if self.scan else self.folder) / "report.json")
            self.log = []
            self._redo_log = []
            self._undo.clear()
            self._redo.clear()
            self.saved_version = self.version
            return written

    def _scan_models(self) -> list:
        """Every facade of a `points` OUTDIR derived and placed in the scan's frame (CGA axes
        relative to the report's origin) as `points` places them; this one from the edited
        tree, the others from their own rules."""
        from ..engine import derive_facade
        from ..points.maps import FacadeFrame
        from ..points.pipeline import _TO_CGA, _place
        from ..reconstruction import write_element_assets
        from ..scratch import scratch_dir

        origin = np.asarray(self.report.get("origin", [0, 0, 0]), float)
        models = []
        for entry in self.report.get("facades", []):
            folder = self.outdir / f"facade_{int(entry['index']):02d}"
            if not (folder / "rules.cga").is_file():
                continue
            f = entry["frame"]
            frame = FacadeFrame(np.asarray(f["origin"], float), np.asarray(f["u"], float),
                                np.asarray(f["v"], float), np.asarray(f["n"], float),
                                float(f["width_m"]), float(f["height_m"]))
            if folder.resolve() == self.folder:     # the rules the page shows
                work, tree = self.work, self.tree
                (work / "rules.cga").write_text(self.derived.rules, encoding="utf-8")
            else:
                tree = _read_tree(folder / "shape_tree.json")
                work = scratch_dir("facadeforge-edit-scan-")
                weakref.finalize(self, shutil.rmtree, work, True)
                if (folder / "ortho.png").is_file():
                    _scan_texture(folder, tree, work / "texture.jpg")
                write_element_assets(tree, work)
                shutil.copy2(folder / "rules.cga", work / "rules.cga")
            w, h = (float(v) for v in tree.scope.size[:2])
            m = derive_facade(work / "rules.cga", w, h, assets=work, name=folder.name)
            m.name = folder.name
            m = _place(m, frame, origin, int(self.report.get("input", {}).get("up", 2)))
            m.attributes["_origin_offset"] = [float(v) for v in _TO_CGA @ origin]
            if self.report.get("input", {}).get("crs"):
                m.attributes["_crs"] = self.report["input"]["crs"]
            models.append(m)
        return models

    def glb(self) -> bytes:
        return self.derived.glb

    def backdrop_png(self) -> bytes:
        if self.backdrop is None:
            raise EditError("this facade has no rectified photo or orthophoto")
        return self.backdrop.read_bytes()


_FIX = "rerun the command that wrote the OUTDIR"


def _read_json(path: Path, max_bytes: int | None = None) -> dict:
    """An OUTDIR's JSON file through the project's reader (:func:`facadeforge.jsonfile.
    read_json`: size cap, BOM, nesting); ``{}`` when it is missing or not an object."""
    from ..jsonfile import MAX_JSON_BYTES, read_json

    if not path.is_file():
        return {}
    data = read_json(path, f"edit: {path.name}", fix=_FIX,
                     max_bytes=max_bytes or MAX_JSON_BYTES)
    return data if isinstance(data, dict) else {}


def _read_tree(path: Path) -> Shape:
    data = _read_json(path, MAX_TREE_BYTES)
    try:
        tree = Shape.from_dict(data)
    except (KeyError, TypeError, ValueError) as e:
        raise InputError(f"edit: {path} is not a facadeforge shape tree ({e!r}); rerun "
                         "`facadeforge reconstruct` to write it again") from None
    w, h = (float(v) for v in tree.scope.size[:2])
    if not (np.isfinite([w, h]).all() and w > 0 and h > 0):
        raise InputError(f"edit: {path}: the facade's size {w} x {h} m is not a rectangle")
    return tree


def png_bytes(rgb: np.ndarray) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(rgb).save(buf, format="PNG")
    return buf.getvalue()


def _scan_texture(folder: Path, tree: Shape, out: Path) -> None:
    """A `points` facade's texture as `points` made it: its orthophoto, every tile replaced by
    its cluster's mean (:func:`facadeforge.reconstruction.cluster_averaged_texture`)."""
    from PIL import Image

    from ..reconstruction import cluster_averaged_texture

    with Image.open(folder / "ortho.png") as im:
        rgb = np.asarray(im.convert("RGB"))
    Image.fromarray(cluster_averaged_texture(rgb, tree)).save(out, quality=90)


def _next_region(tree: Shape) -> int:
    """The next free ``R<n>.`` prefix of re-analysed cluster ids (:mod:`.reanalyse`)."""
    import re

    used = [int(m.group(1)) for s in tree.walk()
            if (m := re.match(r"R(\d+)\.", str(s.tags.get("cluster", ""))))]
    return max(used, default=0) + 1
