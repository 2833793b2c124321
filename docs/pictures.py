"""Regenerate the README's pictures from a CMP validation facade (``--rectified``) and an
unrectified RueMonge validation photo, both from the development val splits (the shipped
classifiers have not seen them):

- ``docs/images/reconstruct.jpg``: ``facadeforge reconstruct`` — the photo with the found
  elements (input frame), ``structure.png``, ``labels.png`` and the derived model;
- ``docs/images/parse.jpg``: ``facadeforge parse`` (default grammar, search and budget) — the
  photo, the classifier's labels, the derivation's labels (input frame) and the derived model;
- ``docs/images/facades.jpg``: a RueMonge val photo of a corner cut into its facades
  (``reconstruct``'s ``facades.png``) and each usable facade rectified on its own;
- ``docs/images/points.jpg``: ``facadeforge points`` on the NUIST facade scan (depth map with
  the elements found in yellow and the labelled ones in magenta, ``structure.png``, the model)
  and on the Lille street scan (the planes from above, coloured by kind; a facade's depth map).

- ``docs/images/multiview.jpg``: ``facadeforge multiview`` on five neighbouring RueMonge val
  photos with their cameras (:data:`MULTIVIEW`): one photo, the stereo cloud from above, one
  facade's fused evidence and fitted structure, the model's labels seen from the photo.

    .venv/bin/python docs/pictures.py [points|multiview]   # only that picture
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
PHOTOS = (("cmp", "cmp_b0187", True), ("ruemonge", "IMG_5778", False))
CORNER = "IMG_5901"
ROW_HEIGHT = 420
MULTIVIEW = ("IMG_5771", "IMG_5772", "IMG_5773", "IMG_5774", "IMG_5775")


def _fit(img: np.ndarray, height: int = ROW_HEIGHT) -> np.ndarray:
    import cv2

    s = height / img.shape[0]
    return cv2.resize(img, (max(1, round(img.shape[1] * s)), height), interpolation=cv2.INTER_AREA)


def row(dataset: str, sample_id: str, rectified: bool) -> np.ndarray:
    import cv2

    from facadeforge import render
    from facadeforge.evaluation.bench import select_samples
    from facadeforge.exchange.raster import PALETTE
    from facadeforge.reconstruction import reconstruct, structure_image

    val, _, _ = select_samples(dataset, DATA / dataset, "val")
    (sample,) = [s for s in val if s.id == sample_id]
    photo = sample.image()
    rec = reconstruct(photo, rectified=rectified)
    found = photo.copy()
    thick = max(2, round(max(photo.shape[:2]) / 300))
    boxes = np.array(rec.windows(frame="input"), float).reshape(-1, 4)
    for x0, y0, x1, y1 in boxes.astype(int):
        cv2.rectangle(found, (x0, y0), (x1, y1), (40, 120, 255), thick)
    labels = PALETTE[rec.labels]
    model = np.asarray(render(rec.model, None, size=(900, 900), azimuth=25.0,
                              elevation=12.0).convert("RGB"))
    tiles = [_fit(found), _fit(structure_image(rec)), _fit(labels), _fit(model)]
    return _join(tiles, axis=1)


def parse_row(dataset: str, sample_id: str, rectified: bool) -> np.ndarray:
    from facadeforge import render
    from facadeforge.evaluation.bench import select_samples
    from facadeforge.exchange.raster import PALETTE
    from facadeforge.parsing.parse import parse

    val, _, _ = select_samples(dataset, DATA / dataset, "val")
    (sample,) = [s for s in val if s.id == sample_id]
    photo = sample.image()
    p = parse(photo, rectified=rectified)
    model = np.asarray(render(p.model, None, size=(900, 900), azimuth=25.0,
                              elevation=12.0).convert("RGB"))
    tiles = [_fit(photo), _fit(PALETTE[p.fallback]), _fit(PALETTE[p.labels_input()]),
             _fit(model)]
    return _join(tiles, axis=1)


def facades_row(sample_id: str = CORNER) -> np.ndarray:
    from facadeforge.evaluation.bench import select_samples
    from facadeforge.imaging.facades import draw_facades, find_facades
    from facadeforge.photo import analysis_copy

    val, _, _ = select_samples("ruemonge", DATA / "ruemonge", "val")
    (sample,) = [s for s in val if s.id == sample_id]
    photo = sample.image()
    work, to_work = analysis_copy(photo)
    split = find_facades(work)
    drawn = draw_facades(photo, split, np.linalg.inv(to_work))
    crops = [r.rectified(work) for r in split.regions if r.ok]
    return _join([_fit(drawn), *(_fit(c) for c in crops)], axis=1)


def _join(parts: list[np.ndarray], axis: int) -> np.ndarray:
    """Parts side by side (axis 1) or stacked (axis 0) with white 6-px gaps."""
    if axis == 0:
        width = max(r.shape[1] for r in parts)
        parts = [np.pad(r, ((0, 0), (0, width - r.shape[1]), (0, 0)), constant_values=255)
                 for r in parts]
    pad = ((0, 6), (0, 0), (0, 0)) if axis == 0 else ((0, 0), (0, 6), (0, 0))
    return np.concatenate([np.pad(t, pad, constant_values=255) for t in parts], axis=axis)


def _boxes(img: np.ndarray, maps, boxes, colour, scale: int) -> None:
    import cv2

    h, r = maps.shape[0], maps.resolution
    for u0, v0, u1, v1 in boxes:
        cv2.rectangle(img, (round(u0 / r * scale), round((h - v1 / r) * scale)),
                      (round(u1 / r * scale), round((h - v0 / r) * scale)), colour, 2)


def points_rows() -> np.ndarray:
    import cv2

    from facadeforge import render
    from facadeforge.datasets.nuist import load_facade
    from facadeforge.points.evaluate import truth_boxes
    from facadeforge.points.io import read_cloud
    from facadeforge.points.pipeline import depth_image, points

    rows = []
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        cloud = load_facade(DATA / "pointclouds" / "nuist" / "building_1" / "facade_1")
        r = points(cloud, out_dir=Path(tmp) / "nuist")
        f = r.facades[0]
        d = cv2.resize(depth_image(f.maps), None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST)
        _boxes(d, f.maps, [t["box_m"] for t in truth_boxes(cloud, f.frame)], (255, 0, 255), 2)
        _boxes(d, f.maps, [e.box_m for e in f.elements if e.label in ("window", "door")],
               (255, 230, 0), 2)
        from PIL import Image

        structure = np.asarray(Image.open(Path(tmp) / "nuist" / "facade_00" / "structure.png"))
        render(str(Path(tmp) / "nuist" / "model.glb"), str(Path(tmp) / "n.png"),
               size=(900, 600), elevation=15, azimuth=245)
        model = np.asarray(Image.open(Path(tmp) / "n.png").convert("RGB"))
        rows.append(_join([_fit(d), _fit(structure), _fit(model)], axis=1))

        lille = read_cloud(DATA / "pointclouds" / "lille_street_small.ply")
        r = points(lille, model=False)
        xy = lille.xyz[:, :2]
        lo = xy.min(0)
        s = 12
        size = ((xy.max(0) - lo) * s).astype(int) + 1
        top = np.full((size[1], size[0], 3), 255, np.uint8)
        q = ((xy - lo) * s).astype(int)
        top[size[1] - 1 - q[:, 1], q[:, 0]] = 200
        colours = {"ground": (150, 150, 150), "facade": (220, 60, 40), "recess": (60, 90, 220),
                   "protrusion": (40, 170, 60), "roof": (170, 60, 170), "other": (230, 170, 0)}
        for p in r.planes:
            qq = q[p.inliers]
            top[size[1] - 1 - qq[:, 1], qq[:, 0]] = colours.get(p.kind, (0, 0, 0))
        f = r.facades[0]
        d = cv2.resize(depth_image(f.maps), None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST)
        _boxes(d, f.maps, [e.box_m for e in f.elements if e.label in ("window", "door")],
               (255, 230, 0), 2)
        rows.append(_join([_fit(top), _fit(d)], axis=1))
    return _join(rows, axis=0)


def multiview_row() -> np.ndarray:
    import tempfile

    from PIL import Image

    from facadeforge.datasets.cameras import read_cameras
    from facadeforge.multiview.pipeline import multiview

    folder = DATA / "ruemonge" / "train"
    cams = read_cameras(folder / "cameras.txt")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "mv"
        r = multiview({i: folder / "img" / f"{i}.jpg" for i in MULTIVIEW},
                      {i: cams[i] for i in MULTIVIEW}, out_dir=out)
        ref = MULTIVIEW[2]
        photo = np.asarray(Image.open(folder / "img" / f"{ref}.jpg").convert("RGB"))
        labels = np.asarray(Image.open(out / "labels_color" / f"{ref}.png").convert("RGB"))
        big = max(r.facades, key=lambda f: f.frame.width * f.frame.height)
        d = out / f"facade_{big.index:02d}"
        ev = np.asarray(Image.open(d / "evidence.png").convert("RGB"))
        st = np.asarray(Image.open(d / "structure.png").convert("RGB"))
    xy = r.cloud.xyz[:, :2]
    lo, hi = np.percentile(xy, 2, axis=0), np.percentile(xy, 98, axis=0)
    keep = ((xy >= lo) & (xy <= hi)).all(1)
    size = 400
    s = (size - 3) / max(float((hi - lo).max()), 1e-6)
    top = np.full((size, size, 3), 255, np.uint8)
    ij = ((xy[keep] - lo) * s).astype(int) + 1
    rgb = r.cloud.rgb[keep] if r.cloud.rgb is not None else 0
    for dy in (-1, 0, 1):                       # 3 × 3 splats: a thin facade band shows
        for dx in (-1, 0, 1):
            top[size - 1 - ij[:, 1] + dy, ij[:, 0] + dx] = rgb
    return _join([_fit(photo), _fit(top), _fit(ev), _fit(st), _fit(labels)], axis=1)


def main() -> int:
    from PIL import Image

    if "multiview" in sys.argv[1:]:
        if (DATA / "ruemonge").is_dir():
            out = ROOT / "docs" / "images" / "multiview.jpg"
            Image.fromarray(multiview_row()).save(out, quality=85)
            print(f"wrote {out}")
        return 0

    if sys.argv[1:] == ["points"] or "points" in sys.argv[1:]:
        if (DATA / "pointclouds").is_dir():
            out = ROOT / "docs" / "images" / "points.jpg"
            Image.fromarray(points_rows()).save(out, quality=85)
            print(f"wrote {out}")
        return 0

    for name, make, order in (("reconstruct.jpg", row, PHOTOS),
                              ("parse.jpg", parse_row, PHOTOS[::-1])):
        rows = []
        for dataset, sample_id, rectified in order:
            if not (DATA / dataset).is_dir():
                print(f"skipping {dataset}: {DATA / dataset} is absent", file=sys.stderr)
                continue
            rows.append(make(dataset, sample_id, rectified))
        if not rows:
            continue
        out = ROOT / "docs" / "images" / name
        Image.fromarray(_join(rows, axis=0)).save(out, quality=85)
        print(f"wrote {out}")
    if (DATA / "ruemonge").is_dir():
        out = ROOT / "docs" / "images" / "facades.jpg"
        Image.fromarray(facades_row()).save(out, quality=85)
        print(f"wrote {out}")
    if (DATA / "pointclouds").is_dir():
        out = ROOT / "docs" / "images" / "points.jpg"
        Image.fromarray(points_rows()).save(out, quality=85)
        print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
