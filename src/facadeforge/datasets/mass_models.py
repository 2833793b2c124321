"""A synthetic textured mass model with exact truth: a box building whose walls carry
synthetic facade photos (:mod:`facadeforge.datasets.synthetic`), one texture image each, and a
flat untextured roof, as GLB — the input of ``facadeforge enhance`` (Müller et al. 2007 §1,
Fig. 16) in its tests and in ``benchmarks/enhance.py``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image

from ..exchange import export
from ..geometry.mesh import Mesh
from ..model.model import Material, Model, Part
from .synthetic import generate

__all__ = ["DEPTH", "GABLE_RISE", "HEIGHT", "TEXTURE_PPM", "WIDTH", "box_mass_model",
           "gable_mass_model", "photo_street", "truth_windows"]

GABLE_RISE = 4.0                          # ridge above the eaves of the gable house (m)

WIDTH, DEPTH, HEIGHT = 14.0, 10.0, 16.0   # footprint x, z and height (m)
TEXTURE_PPM = 40                          # px per metre of the full-resolution textures


def walls(W: float = WIDTH, D: float = DEPTH, H: float = HEIGHT, x0: float = 0.0
          ) -> list[tuple[np.ndarray, float]]:
    """The 4 walls of a box ``W`` × ``D`` × ``H`` from ``x`` = ``x0``: corners (bottom-left,
    bottom-right, top-right, top-left seen from outside, counter-clockwise around the outward
    normal) and width; the first faces +z (the street)."""
    quads = [
        [(0, 0, D), (W, 0, D), (W, H, D), (0, H, D)],      # faces +z
        [(W, 0, D), (W, 0, 0), (W, H, 0), (W, H, D)],      # faces +x
        [(W, 0, 0), (0, 0, 0), (0, H, 0), (W, H, 0)],      # faces -z
        [(0, 0, 0), (0, 0, D), (0, H, D), (0, H, 0)],      # faces -x
    ]
    return [(np.array(q, float) + (x0, 0.0, 0.0), W if i % 2 == 0 else D)
            for i, q in enumerate(quads)]


def truth_windows(photo: Path, scale: float = 1.0) -> int:
    """Windows of a synthetic texture large enough to be seen (slivers of windows hidden
    behind a neighbour's edge are left out)."""
    objects = json.loads(photo.with_suffix(".objects.json").read_text())
    boxes = [o["box"] for o in objects if o["label"] == "window"]
    return sum(1 for x0, y0, x1, y1 in boxes if min(x1 - x0, y1 - y0) >= 6)


def box_mass_model(folder: Path, *, textured=(0, 1, 2, 3), ppm: float = TEXTURE_PPM, seed: int = 21
           ) -> tuple[Path, list[int]]:
    """A box building whose walls ``textured`` are textured with synthetic Haussmann photos (one
    image each, UVs 0–1), the others and the flat roof untextured; written as GLB.  Returns
    the path and the truth window count per textured wall."""
    folder.mkdir(parents=True, exist_ok=True)
    parts, truth = [], []
    for i, (quad, width) in enumerate(walls()):
        uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
        if i in textured:
            size = (round(width * TEXTURE_PPM), round(HEIGHT * TEXTURE_PPM))
            photo = generate(1, seed=seed, out_dir=folder / "synth", size=size,
                             styles=["haussmann"], start=i)[0]
            truth.append(truth_windows(photo))
            texture = photo
            if ppm != TEXTURE_PPM:
                texture = folder / f"low_{i}.png"
                Image.open(photo).resize((round(width * ppm), round(HEIGHT * ppm)),
                                         Image.LANCZOS).save(texture)
            mat = Material(name=f"facade{i}", texture=str(texture))
        else:
            mat = Material(name="plaster", color=(0.8, 0.75, 0.7))
        parts.append(Part(Mesh(quad, faces=[np.arange(4)], uvs=[uv]), label="wall",
                          material=mat, symbol="Wall"))
    W, D, H = WIDTH, DEPTH, HEIGHT
    roof = np.array([(0, H, D), (W, H, D), (W, H, 0), (0, H, 0)], float)
    parts.append(Part(Mesh(roof, faces=[np.arange(4)]), label="roof",
                      material=Material(name="roof", color=(0.5, 0.2, 0.2)), symbol="Roof"))
    path = folder / "mass.glb"
    export([Model(parts=parts, name="block")], path)
    return path, truth


def photo_street(folder: Path, photos, *, ppm: float = 50.0, depth: float = DEPTH,
                 gap: float = 2.0) -> Path:
    """A street of box buildings, one per photo, side by side along x: each street wall (+z)
    textured with its photo (UVs 0–1, ``ppm`` pixels a metre: the photo's size sets the wall's),
    the other walls and the flat roof untextured; each building a model named after its photo,
    all in one GLB (the input of ``benchmarks/enhance.py``'s real-photo case).  ``photos``:
    paths of rectified facade photos (CMP's)."""
    folder.mkdir(parents=True, exist_ok=True)
    models, x0 = [], 0.0
    plaster = Material(name="plaster", color=(0.8, 0.75, 0.7))
    roof_mat = Material(name="roof", color=(0.5, 0.2, 0.2))
    for photo in map(Path, photos):
        w_px, h_px = Image.open(photo).size
        w, h, d = w_px / ppm, h_px / ppm, depth
        uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
        parts = []
        for i, (quad, _) in enumerate(walls(w, d, h, x0)):
            street = i == 0
            mat = Material(name=f"facade_{photo.stem}", texture=str(photo)) if street else plaster
            parts.append(Part(Mesh(quad, faces=[np.arange(4)], uvs=[uv] if street else None),
                              label="wall", material=mat, symbol="Wall"))
        roof = np.array([(0, h, d), (w, h, d), (w, h, 0), (0, h, 0)], float) + (x0, 0.0, 0.0)
        parts.append(Part(Mesh(roof, faces=[np.arange(4)]), label="roof", material=roof_mat,
                          symbol="Roof"))
        models.append(Model(parts=parts, name=photo.stem))
        x0 += w + gap
    path = folder / "street.glb"
    export(models, path)
    return path


def gable_mass_model(folder: Path, *, seed: int = 21) -> tuple[Path, int]:
    """A house whose street wall (+z) is a gable end: a pentagon, ``WIDTH`` wide, eaves at
    ``HEIGHT`` and the ridge :data:`GABLE_RISE` higher, textured with one image: a synthetic
    Haussmann facade photo below the eaves and plain render in the gable above.  The pitched
    roof and the other walls are untextured; GLB.  Returns the path and the truth window count
    of the facade photo."""
    folder.mkdir(parents=True, exist_ok=True)
    W, D, H, R = WIDTH, DEPTH, HEIGHT, HEIGHT + GABLE_RISE
    photo = generate(1, seed=seed, out_dir=folder / "synth", size=(round(W * TEXTURE_PPM),
                     round(H * TEXTURE_PPM)), styles=["haussmann"])[0]
    facade = np.asarray(Image.open(photo).convert("RGB"))
    gable = np.empty((round(GABLE_RISE * TEXTURE_PPM), facade.shape[1], 3), np.uint8)
    gable[:] = (196, 182, 160)
    texture = folder / "gable_texture.png"
    Image.fromarray(np.concatenate([gable, facade])).save(texture)
    front = np.array([(0, 0, D), (W, 0, D), (W, H, D), (W / 2, R, D), (0, H, D)], float)
    uv = np.c_[front[:, 0] / W, front[:, 1] / R]
    plaster = Material(name="plaster", color=(0.8, 0.75, 0.7))
    parts = [Part(Mesh(front, faces=[np.arange(5)], uvs=[uv]), label="wall",
                  material=Material(name="gable", texture=str(texture)), symbol="Wall")]
    back = np.array([(W, 0, 0), (0, 0, 0), (0, H, 0), (W / 2, R, 0), (W, H, 0)], float)
    sides = [[(W, 0, D), (W, 0, 0), (W, H, 0), (W, H, D)], [(0, 0, 0), (0, 0, D), (0, H, D),
                                                            (0, H, 0)]]
    parts.append(Part(Mesh(back, faces=[np.arange(5)]), label="wall", material=plaster,
                      symbol="Wall"))
    for q in sides:
        parts.append(Part(Mesh(np.array(q, float), faces=[np.arange(4)]), label="wall",
                          material=plaster, symbol="Wall"))
    roofs = [[(W, H, D), (W, H, 0), (W / 2, R, 0), (W / 2, R, D)],
             [(0, H, 0), (0, H, D), (W / 2, R, D), (W / 2, R, 0)]]
    roof_mat = Material(name="roof", color=(0.5, 0.2, 0.2))
    for q in roofs:
        parts.append(Part(Mesh(np.array(q, float), faces=[np.arange(4)]), label="roof",
                          material=roof_mat, symbol="Roof"))
    path = folder / "gable.glb"
    export([Model(parts=parts, name="house")], path)
    return path, truth_windows(photo)
