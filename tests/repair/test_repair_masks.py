"""Occlusion masks: user masks read strictly, occluder probabilities, cleaning, repetition breaks."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from facadeforge.errors import InputError
from facadeforge.repair.masks import (
    clean_mask,
    mask_from_labels,
    occluder_probability,
    read_mask,
    repetition_breaks,
)


def test_read_mask_from_png_and_arrays(tmp_path):
    m = np.zeros((40, 60), np.uint8)
    m[10:20, 5:25] = 255
    Image.fromarray(m).save(tmp_path / "m.png")
    got = read_mask(tmp_path / "m.png", (40, 60))
    assert got.dtype == bool and got.sum() == 200 and got[15, 10]
    rgb = np.zeros((40, 60, 3), np.uint8)
    rgb[0, 0, 2] = 9
    assert read_mask(rgb, (40, 60)).sum() == 1
    rgba = np.full((40, 60, 4), 255, np.uint8)
    rgba[..., 3] = 0
    rgba[5, 5, 3] = 255
    assert read_mask(rgba, (40, 60)).sum() == 1      # the alpha counts when it is not all opaque


def test_read_mask_refuses_other_sizes_and_shapes(tmp_path):
    with pytest.raises(InputError, match="same size"):
        read_mask(np.zeros((10, 10), bool), (40, 60))
    with pytest.raises(InputError, match="black-and-white"):
        read_mask(np.zeros((2, 3, 4, 5)), (2, 3))
    with pytest.raises(InputError, match="does not exist"):
        read_mask(tmp_path / "missing.png", (40, 60))


def test_occluder_probability_sums_the_occluder_channels():
    prob = np.zeros((4, 4, 4), np.float32)
    prob[..., 0], prob[..., 1], prob[..., 2], prob[..., 3] = 0.1, 0.2, 0.3, 0.4
    p = occluder_probability(prob, ("wall", "vegetation", "window", "car"))
    assert np.allclose(p, 0.6)
    assert occluder_probability(prob, ("wall", "sky", "window", "door")).max() == 0


def test_mask_from_labels():
    lab = np.array([[1, 14, 17], [2, 18, 1]])
    assert mask_from_labels(lab, [14, 17, 18]).tolist() == [[False, True, True],
                                                           [False, True, False]]


def test_clean_mask_drops_specks_fills_and_grows():
    m = np.zeros((200, 200), bool)
    m[100:160, 40:120] = True
    m[120:130, 60:70] = False           # a hole inside the occluder
    m[10, 10] = True                    # a speck
    out = clean_mask(m)
    assert not out[10, 10]
    assert out[125, 65]
    assert out[98, 80] and not out[90, 80]        # grown by a few pixels only
    assert out.sum() > m.sum()


def test_repetition_breaks_finds_the_odd_instance():
    rng = np.random.default_rng(0)
    img = np.full((120, 300, 3), 200, np.uint8)
    boxes = []
    for i in range(5):
        x0 = 20 + 55 * i
        img[30:80, x0:x0 + 30] = (40, 50, 60)
        img[30:80, x0 + 14:x0 + 16] = 230                 # a mullion
        boxes.append((x0, 30, x0 + 30, 80))
    img = np.clip(img + rng.normal(0, 2, img.shape), 0, 255).astype(np.uint8)
    img[40:70, 135:160] = (30, 140, 40)                   # a bush in front of the third window
    br = repetition_breaks(img, [boxes])
    assert br[40:70, 135:160].mean() > 0.8
    others = np.zeros(img.shape[:2], bool)
    for j, (x0, y0, x1, y1) in enumerate(boxes):
        if j != 2:
            others[y0:y1, x0:x1] = True
    assert br[others].mean() < 0.02
    assert not repetition_breaks(img, [boxes[:2]]).any()   # two instances: no majority
