"""``repair_model``: the facade textures of a textured 3D model repaired (Shang et al. 2023
§4.2.2: "every textured facade of an existing 3D building model").

The model is read with the exchange readers (:func:`facadeforge.exchange.load`: ``.obj`` with
its ``.mtl`` and texture files, ``.glb`` with its embedded images), and written back with the
exporters (:func:`facadeforge.exchange.export`) with the same geometry; only texture images
change.  For every texture image:

1. its *facade faces*: faces of parts whose material uses the image, that have UVs inside the
   image (a UV range beyond 0–1 is a tiled material such as a brick pattern, not a facade's
   own image: such faces are skipped) and whose normal is within ~17° of horizontal
   (``|n_up| < FACADE_NORMAL_UP``; ``up`` is y, the convention of facadeforge's models and of
   glTF, or z for OBJ files of tools that write z up);
2. their *facade rectangles*: each face's UV bounding box in texture pixels (v up, row
   ``(1 - v) · H``); boxes that overlap or touch are merged, and merged again while the
   bounding boxes of the merged groups overlap, so the rectangles are disjoint;
3. each rectangle of at least :data:`~facadeforge.photo.MIN_SIDE` px a side is cropped and
   repaired with :func:`~.pipeline.repair_photo` (``rectified=True``: a facade's texture
   rectangle is its fronto-parallel image), and only the repaired (masked) pixels are pasted
   back.

A texture with repaired pixels is written as ``<stem>_repaired.png`` (lossless: the pixels
outside the repair keep their values, which re-encoding a JPEG would not); an alpha channel is
kept.  Textures without facade faces, or where nothing was found to repair, are left alone and
written as they were.  Nothing of the input is ever written to: an output that would replace
one of the input files (the model, its ``.mtl``, a texture) is refused, except an unchanged
texture copied onto itself.
"""

from __future__ import annotations

import dataclasses
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError

__all__ = ["FACADE_NORMAL_UP", "FORMATS", "repair_model"]

#: Model formats ``repair-model`` reads and writes.
FORMATS: tuple[str, ...] = ("obj", "glb")
#: A face is a facade when the up component of its unit normal is below this (|n_up| < 0.3:
#: within 17.5° of a vertical wall; a 70° mansard roof has 0.34).
FACADE_NORMAL_UP: float = 0.3
#: UVs this far outside 0–1 make a face "tiled" (a repeated material, not a facade image).
_UV_TOLERANCE = 1e-3
_AXES = {"x": 0, "y": 1, "z": 2}

MaskFunction = Callable[[str, tuple[int, int, int, int], np.ndarray], Any]


def _format(path: Path, what: str) -> str:
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in FORMATS:
        raise InputError(f"{what} {path}: repair-model reads and writes .obj (with its .mtl and "
                         "texture files) or .glb (embedded textures); convert the model to one "
                         "of them first (e.g. facadeforge derive … -o model.glb)")
    return suffix


def _obj_material_libraries(path: Path) -> list[Path]:
    """The ``.mtl`` files an OBJ names (``mtllib``), resolved beside it."""
    found = []
    with open(path, "rb") as fh:
        for line in fh:
            if line.startswith(b"mtllib"):
                for name in line[6:].decode("utf-8", "replace").split():
                    found.append((path.parent / name).resolve())
    return found


def _read_texture(path: str) -> tuple[np.ndarray | None, str | None]:
    """(H, W, 3|4) uint8 of a texture (RGB, or RGBA when it has alpha) or why it is unusable."""
    from PIL import Image

    try:
        with Image.open(path) as im:
            alpha = im.mode in ("RGBA", "LA", "PA") or (im.mode == "P" and
                                                         "transparency" in im.info)
            return np.array(im.convert("RGBA" if alpha else "RGB")), None
    except (OSError, ValueError) as exc:
        return None, f"not a readable image ({exc})"


def _face_boxes(parts, shape: tuple[int, int], up: int) -> tuple[np.ndarray, int, int]:
    """UV boxes ``(x0, y0, x1, y1)`` in texture pixels of the facade faces of ``parts``, and
    how many faces were skipped as tiled and as not facades."""
    h, w = shape
    boxes, tiled, other = [], 0, 0
    for part in parts:
        mesh = part.mesh
        if mesh.corner_uvs is None or not mesh.n_faces:
            continue
        sizes = np.diff(mesh.starts)
        normals = mesh.face_normals()
        ok = sizes >= 3
        facade = ok & (np.abs(normals[:, up]) < FACADE_NORMAL_UP) & (mesh.face_areas() > 0)
        other += int((ok & ~facade).sum())
        if not facade.any():
            continue
        uv = np.asarray(mesh.corner_uvs, float)
        # each face's own corners: the corner ranges of the non-empty faces are consecutive
        full = sizes > 0
        lo = np.minimum.reduceat(uv, mesh.starts[:-1][full], axis=0)[facade[full]]
        hi = np.maximum.reduceat(uv, mesh.starts[:-1][full], axis=0)[facade[full]]
        inside = (lo >= -_UV_TOLERANCE).all(axis=1) & (hi <= 1 + _UV_TOLERANCE).all(axis=1)
        tiled += int((~inside).sum())
        lo, hi = np.clip(lo[inside], 0, 1), np.clip(hi[inside], 0, 1)
        x0 = np.floor(lo[:, 0] * w).astype(np.int64)
        x1 = np.maximum(np.ceil(hi[:, 0] * w).astype(np.int64), x0 + 1)
        y0 = np.floor((1 - hi[:, 1]) * h).astype(np.int64)
        y1 = np.maximum(np.ceil((1 - lo[:, 1]) * h).astype(np.int64), y0 + 1)
        boxes.append(np.column_stack([np.minimum(x0, w - 1), np.minimum(y0, h - 1),
                                      np.minimum(x1, w), np.minimum(y1, h)]))
    return (np.concatenate(boxes) if boxes else np.zeros((0, 4), np.int64)), tiled, other


def facade_rectangles(boxes: np.ndarray, shape: tuple[int, int]) -> list[tuple[int, int, int,
                                                                                int]]:
    """Disjoint rectangles ``(x0, y0, x1, y1)`` covering ``boxes``: boxes that overlap or touch
    are one rectangle (their bounding box), merged again while those overlap."""
    import cv2

    h, w = shape
    rects = sorted({tuple(int(v) for v in b) for b in boxes})
    while rects:
        canvas = np.zeros((h, w), np.uint8)
        for x0, y0, x1, y1 in rects:
            canvas[y0:y1, x0:x1] = 1
        n, _, stats, _ = cv2.connectedComponentsWithStats(canvas, connectivity=4)
        merged = sorted((int(x), int(y), int(x + bw), int(y + bh))
                        for x, y, bw, bh, _ in stats[1:n])
        if merged == rects:     # every rectangle its own component: disjoint, not touching
            break
        rects = merged
    return rects


def _collisions(models, out: Path, fmt: str, inputs: set[Path]) -> None:
    """Refuse an output file that is one of the inputs (an unchanged texture copied onto
    itself excepted: its bytes stay what they are)."""
    finals: list[tuple[Path, Path | None]] = [(out, None)]
    if fmt == "obj":
        from ..exchange.obj import _MaterialLibrary

        finals.append((out.with_suffix(".mtl"), None))
        library = _MaterialLibrary(out.parent, "textures")   # the names export_obj will use
        for model in models:
            for part in model.parts:
                if part.mesh.n_faces:
                    library.name(part.material)
        finals += [(out.parent / rel, Path(src).resolve())
                   for src, rel in library.textures.items() if rel is not None]
    for final, source in finals:
        real = final.resolve()
        if real in inputs and real != source:
            raise InputError(f"-o {out} would overwrite {final}, a file the input model reads; "
                             "write the repaired model into another folder or under another "
                             "name")


def repair_model(path: str | os.PathLike, out: str | os.PathLike, *, seed: int = 0,
                 up: str = "y", mask: MaskFunction | None = None,
                 report_path: str | os.PathLike | None = None, **repair_options) -> dict:
    """Repair every facade texture of a textured model and write it with the same geometry.

    Parameters
    ----------
    path : path-like
        The model, ``.obj`` (its ``.mtl`` and textures beside it) or ``.glb``.
    out : path-like
        Where the repaired model goes, ``.obj`` (plus ``.mtl`` and a ``textures/`` folder) or
        ``.glb``; written whole (the exporters' atomic staging), never one of the input files.
    seed : int
        Seed of the repair (:func:`~.pipeline.repair_photo`).
    up : "y" or "z"
        The model's up axis (y: facadeforge's models and every glTF file).
    mask : callable, optional
        ``mask(texture, box, crop)`` → the (h, w) mask of what to repair in the facade
        rectangle ``box = (x0, y0, x1, y1)`` of the texture file ``texture`` (``crop`` is its
        pixels), or ``None`` to have it found; default: found by the pipeline's classifiers.
    report_path : path-like, optional
        Write the report there as JSON too.
    **repair_options
        More options of :func:`~.pipeline.repair_photo` (``fill``, ``wall``, ``classifier``…).

    Returns
    -------
    dict
        The report: per texture its facade rectangles, the pixels repaired in each and how,
        and a ``summary`` (textures, rectangles, pixels, seconds).

    Raises
    ------
    InputError
        Unsupported file type, a model without textures, an output that is an input file.
    """
    from PIL import Image

    from ..exchange import export, load
    from ..outdir import check_output_file
    from ..photo import MIN_SIDE
    from .pipeline import repair_photo

    t_start = time.perf_counter()
    path, out = Path(path), Path(out)
    in_fmt, out_fmt = _format(path, "MODEL"), _format(out, "-o")
    if up not in ("y", "z"):
        raise InputError(f"up axis {up!r}: use 'y' (facadeforge's models, glTF) or 'z'")
    axis = _AXES[up]
    if not path.is_file():
        raise InputError(f"MODEL {path}: no such file; give a textured .obj or .glb model "
                         "(e.g. model.obj of facadeforge reconstruct)")
    check_output_file(out, {"MODEL": path})
    if report_path is not None:
        check_output_file(report_path, {"MODEL": path, "-o": out})
    inputs = {path.resolve()}
    if in_fmt == "obj":
        inputs.update(_obj_material_libraries(path))

    with tempfile.TemporaryDirectory(prefix="facadeforge-repair-model-") as tmp:
        work = Path(tmp)
        t = time.perf_counter()
        models = load(path, texture_dir=work / "in") if in_fmt == "glb" else load(path)
        load_s = time.perf_counter() - t
        users: dict[str, list] = {}
        for model in models:
            for part in model.parts:
                if part.material.texture and part.mesh.n_faces:
                    users.setdefault(part.material.texture, []).append(part)
        if not users:
            raise InputError(f"MODEL {path} has no textured faces (no material with a texture "
                             "image), so there is no texture to repair; give a textured model "
                             "(e.g. model.obj or model.glb of facadeforge reconstruct)")
        if in_fmt == "obj":
            inputs.update(Path(src).resolve() for src in users)

        textures, replaced, readable = [], {}, 0
        for src, parts in users.items():
            entry: dict[str, Any] = {"texture": Path(src).name, "parts": len(parts)}
            textures.append(entry)
            pixels, problem = _read_texture(src)
            if pixels is None:
                entry["skipped"] = problem
                continue
            readable += 1
            h, w = pixels.shape[:2]
            entry["size_px"] = [int(w), int(h)]
            boxes, tiled, other = _face_boxes(parts, (h, w), axis)
            entry.update(facade_faces=int(len(boxes)), tiled_faces=tiled, other_faces=other)
            rects = facade_rectangles(boxes, (h, w))
            entry["rectangles"], changed = [], 0
            for box in rects:
                x0, y0, x1, y1 = box
                inside = ((boxes[:, 0] >= x0) & (boxes[:, 1] >= y0) & (boxes[:, 2] <= x1)
                          & (boxes[:, 3] <= y1)).sum()
                rect: dict[str, Any] = {"box": list(box), "faces": int(inside)}
                entry["rectangles"].append(rect)
                if min(x1 - x0, y1 - y0) < MIN_SIDE:
                    rect["skipped"] = f"smaller than {MIN_SIDE} px a side"
                    continue
                crop = np.ascontiguousarray(pixels[y0:y1, x0:x1, :3])
                given = None if mask is None else mask(src, tuple(box), crop)
                t = time.perf_counter()
                r = repair_photo(crop, mask=given, rectified=True, seed=seed, **repair_options)
                region = pixels[y0:y1, x0:x1, :3]
                region[r.mask] = r.repaired[r.mask]      # only the repaired pixels
                changed += int(r.mask.sum())
                rect.update(mask=r.report["mask"]["source"], pixels=int(r.mask.sum()),
                            fraction=r.report["mask"]["fraction"], filled=r.report["filled"],
                            seconds=round(time.perf_counter() - t, 3))
            entry["pixels"] = changed
            if changed:
                name = f"{Path(src).stem}_repaired.png"
                target = work / "out" / str(len(replaced)) / name
                target.parent.mkdir(parents=True)
                Image.fromarray(pixels).save(target)
                replaced[src] = str(target)
                entry["output"] = name
        if not readable:
            raise InputError(f"MODEL {path}: none of its textures can be read "
                             f"({textures[0]['texture']}: {textures[0]['skipped']}); put the "
                             "texture files the model names beside it")

        swapped: dict[int, Any] = {}
        for model in models:
            for part in model.parts:
                src = part.material.texture
                if src in replaced:
                    key = id(part.material)
                    if key not in swapped:
                        swapped[key] = dataclasses.replace(part.material, texture=replaced[src])
                    part.material = swapped[key]
        _collisions(models, out, out_fmt, inputs)
        t = time.perf_counter()
        written = export(models, out)
        export_s = time.perf_counter() - t

    rects = [r for e in textures for r in e.get("rectangles", [])]
    report = {
        "input": str(path), "output": str(out), "up": up,
        "written": [str(p) for p in written],
        "textures": textures,
        "summary": {
            "textures": len(textures),
            "textures_repaired": len(replaced),
            "facade_rectangles": len(rects),
            "rectangles_repaired": sum(1 for r in rects if r.get("pixels")),
            "pixels": sum(r.get("pixels", 0) for r in rects),
            "rectangle_pixels": sum((r["box"][2] - r["box"][0]) * (r["box"][3] - r["box"][1])
                                    for r in rects),
            "seconds": {"load": round(load_s, 3), "export": round(export_s, 3),
                        "total": round(time.perf_counter() - t_start, 3)},
        },
    }
    if report_path is not None:
        import json

        from ..exchange._common import Staging, jsonable

        with Staging() as stage:
            stage.write_text(report_path, json.dumps(jsonable(report), indent=2) + "\n")
    return report
