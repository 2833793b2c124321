"""Occluders cut from LabelMeFacade-like labels and pasted onto facades: what is cut and what is
dropped, determinism, mask vs changed pixels, coverage bounds, cars on the bottom edge, and the
benchmark set on the shared data (CMP val facades, LabelMeFacade test occluders only)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from facadeforge.datasets import CANONICAL_INDEX, CMP_VAL_IDS, LABEL_SETS
from facadeforge.datasets.labelmefacade import read_split_file
from facadeforge.datasets.occluded import (
    Occluder,
    occluded_cmp,
    occluders_from_labelmefacade,
    paste_occluders,
)
from facadeforge.errors import InputError

SHARED = Path(__file__).resolve().parents[2].parent / "shared" / "data"
LMF9 = LABEL_SETS["lmf9"]
COLOR = {name: tuple(int(c) for c in LMF9.colors[i]) for i, name in
         enumerate(LMF9.dataset_names)}


def _street(tmp_path: Path) -> Path:
    """A LabelMeFacade-like folder: one test photo (160 × 200) holding a kept car, a kept tree,
    a bottom-touching car (kept), a car cut by the left border, a car touching the top, a tiny
    car and a thin tree (all dropped); one train photo with a car."""
    root = tmp_path / "lmf"
    (root / "images").mkdir(parents=True)
    (root / "labels").mkdir()
    h, w = 160, 200
    lab = np.zeros((h, w, 3), np.uint8)
    lab[:] = COLOR["building"]
    img = np.full((h, w, 3), 150, np.uint8)

    def put(name: str, ys: slice, xs: slice, rgb: tuple[int, int, int]) -> None:
        lab[ys, xs] = COLOR[name]
        img[ys, xs] = rgb

    put("car", slice(100, 124), slice(40, 100), (200, 30, 30))         # kept
    yy, xx = np.mgrid[:h, :w]
    tree = ((yy - 50) / 30) ** 2 + ((xx - 150) / 20) ** 2 <= 1         # an ellipse crown
    lab[tree] = COLOR["vegetation"]
    img[tree] = (40, 140, 40)
    put("car", slice(136, 160), slice(120, 170), (30, 30, 200))        # touches the bottom: kept
    put("car", slice(60, 80), slice(0, 40), (200, 30, 30))             # cut by the left border
    put("car", slice(0, 15), slice(60, 100), (200, 30, 30))            # touches the top
    put("car", slice(30, 34), slice(10, 16), (200, 30, 30))            # tiny
    put("vegetation", slice(20, 90), slice(110, 113), (40, 140, 40))   # a thin strip
    Image.fromarray(img).save(root / "images" / "street_a.png")
    Image.fromarray(lab).save(root / "labels" / "street_a.png")
    lab2 = np.zeros((h, w, 3), np.uint8)
    lab2[:] = COLOR["building"]
    lab2[60:90, 50:120] = COLOR["car"]
    Image.fromarray(img).save(root / "images" / "street_b.png")
    Image.fromarray(lab2).save(root / "labels" / "street_b.png")
    (root / "test.txt").write_text("street_a\n")
    (root / "train.txt").write_text("street_b\n")
    return root


def test_occluders_are_cut_from_the_labels(tmp_path):
    root = _street(tmp_path)
    found = occluders_from_labelmefacade(root, "test", min_area=100, min_side=8)
    by_label = {}
    for o in found:
        by_label.setdefault(o.label, []).append(o)
        assert o.source == "street_a"
        assert o.rgba.dtype == np.uint8 and o.rgba.shape[2] == 4
    assert len(by_label["car"]) == 2 and len(by_label["vegetation"]) == 1
    boxes = sorted(o.box for o in by_label["car"])
    assert boxes == [(40, 100, 100, 124), (120, 136, 170, 160)]
    car = next(o for o in by_label["car"] if o.box[0] == 40)
    alpha = car.rgba[..., 3]
    assert alpha.shape == (24, 60)
    assert alpha[1:-1, 1:-1].min() > 127            # the body, opaque
    assert alpha[0].max() < 128 and alpha[:, 0].max() < 128   # the 1-px rim eroded away
    body = alpha > 127
    assert np.all(car.rgba[..., :3][body] == (200, 30, 30))
    tree = by_label["vegetation"][0]
    assert np.all(tree.rgba[..., :3][tree.rgba[..., 3] > 0] == (40, 140, 40))  # no background
    # the train photo's car comes with split="train" only; a limit cuts the list
    train = occluders_from_labelmefacade(root, "train", min_area=100, min_side=8)
    assert [o.source for o in train] == ["street_b"]
    assert len(occluders_from_labelmefacade(root, "test", min_area=100, min_side=8,
                                            limit=1)) == 1
    with pytest.raises(InputError, match="unknown LabelMeFacade class"):
        occluders_from_labelmefacade(root, "test", labels=("tree",))


def _pool() -> list[Occluder]:
    car = np.zeros((40, 100, 4), np.uint8)
    car[..., :3] = (220, 20, 20)
    car[..., 3] = 255
    yy, xx = np.mgrid[:100, :60]
    crown = ((yy - 50) / 50) ** 2 + ((xx - 30) / 30) ** 2 <= 1
    tree = np.zeros((100, 60, 4), np.uint8)
    tree[..., :3] = (20, 200, 20)
    tree[..., 3] = np.where(crown, 255, 0)
    return [Occluder(car, "car", "a"), Occluder(tree, "vegetation", "b"),
            Occluder(car[:, :80].copy(), "car", "c")]


def _facade(h: int = 200, w: int = 300) -> np.ndarray:
    rng = np.random.default_rng(5)
    return (100 + rng.integers(0, 30, (h, w, 3))).astype(np.uint8)


def test_paste_is_deterministic_for_a_generator():
    pool, facade = _pool(), _facade()
    a = paste_occluders(facade, pool, rng=np.random.default_rng(3))
    b = paste_occluders(facade, pool, rng=np.random.default_rng(3))
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]) and a[2] == b[2]
    c = paste_occluders(facade, pool, rng=np.random.default_rng(4))
    assert not np.array_equal(a[1], c[1])


def test_mask_is_where_the_pixels_changed():
    pool, facade = _pool(), _facade()
    for seed in range(10):
        occluded, mask, placed = paste_occluders(facade, pool, rng=np.random.default_rng(seed))
        changed = np.any(occluded != facade, axis=2)
        # the matte is feathered inwards: no pixel outside the mask is tinted (no halo), and
        # every masked pixel is covered (the pool's colours differ from the facade's)
        assert np.array_equal(changed, mask)
        assert placed and mask.any()
        # the rim is soft: some masked pixels are blends, neither facade nor object colour
        blend = mask & np.all(occluded != (220, 20, 20), axis=2) & np.all(
            occluded != (20, 200, 20), axis=2)
        assert blend.any()


@pytest.mark.parametrize("coverage", [(0.08, 0.25), (0.05, 0.1), (0.15, 0.3)])
def test_coverage_stays_within_bounds(coverage):
    pool, facade = _pool(), _facade()
    lo, hi = coverage
    for seed in range(12):
        _, mask, placed = paste_occluders(facade, pool, rng=np.random.default_rng(seed),
                                          coverage=coverage, max_items=3)
        assert lo <= mask.mean() <= hi, (seed, mask.mean())
        assert 1 <= len(placed) <= 3


def test_cars_stand_on_the_bottom_edge_and_keep_their_size_rule():
    pool, facade = _pool(), _facade()
    H, W = facade.shape[:2]
    cars = 0
    for seed in range(15):
        _, mask, placed = paste_occluders(facade, pool, rng=np.random.default_rng(seed))
        for rec in placed:
            x0, y0, x1, y1 = rec["box"]
            assert y1 == H and 0 <= x0 < x1 <= W       # on the bottom edge, inside the facade
            assert mask[-1, x0:x1].any()
            if rec["label"] == "car":
                cars += 1
                assert 0.2 - 1e-3 <= (x1 - x0) / W <= 0.4 + 1e-3
            else:
                assert (y1 - y0) / H <= 0.6 + 1e-3
        # trees are drawn behind cars
        labels = [r["label"] for r in placed]
        assert labels == sorted(labels, key=lambda s: s != "vegetation")
    assert cars > 0


def test_paste_rejects_bad_input():
    pool, facade = _pool(), _facade()
    with pytest.raises(InputError, match="no occluders"):
        paste_occluders(facade, [], rng=np.random.default_rng(0))
    with pytest.raises(InputError, match="coverage"):
        paste_occluders(facade, pool, rng=np.random.default_rng(0), coverage=(0.3, 0.1))
    with pytest.raises(InputError, match="uint8"):
        paste_occluders(facade.astype(float), pool, rng=np.random.default_rng(0))


@pytest.mark.skipif(not (SHARED / "cmp").is_dir() or not (SHARED / "labelmefacade").is_dir(),
                    reason="shared data ../shared/data/cmp and labelmefacade not present")
def test_benchmark_set_is_cmp_val_with_labelmefacade_test_occluders():
    samples = occluded_cmp(SHARED / "cmp", SHARED / "labelmefacade", n=30, seed=0)
    assert len(samples) == 30 and len({s.id for s in samples}) == 30
    assert {s.id for s in samples} <= set(CMP_VAL_IDS)
    test = set(read_split_file(SHARED / "labelmefacade" / "test.txt"))
    train = set(read_split_file(SHARED / "labelmefacade" / "train.txt"))
    sources = {p["source"] for s in samples for p in s.placed}
    assert sources <= test and not sources & train
    labels = {p["label"] for s in samples for p in s.placed}
    assert labels == {"car", "vegetation"}
    for s in samples:
        assert s.clean.shape == s.occluded.shape and s.mask.shape == s.clean.shape[:2]
        assert s.labels.shape == s.mask.shape
        assert 0.08 - 0.02 <= s.meta["coverage"] <= 0.25
        assert set(np.unique(s.occluder_labels[s.mask])) <= {CANONICAL_INDEX["car"],
                                                              CANONICAL_INDEX["vegetation"],
                                                              255}
        assert np.all(s.occluder_labels[~s.mask] == 255)
        assert s.meta["facade_split"] == "val" and s.meta["occluder_split"] == "test"
    again = occluded_cmp(SHARED / "cmp", SHARED / "labelmefacade", n=2, seed=0)
    first = {s.id: s for s in samples}
    for s in again:   # a facade's sample does not depend on n
        assert np.array_equal(s.occluded, first[s.id].occluded)
