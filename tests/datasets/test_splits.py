"""Fixed development splits: CMP's every-5th rule, RueMonge's split by building."""

from __future__ import annotations

import random
from dataclasses import dataclass
from pathlib import Path

import pytest

from facadeforge.datasets import (
    CMP_VAL_IDS,
    DEV_SPLITS,
    RUEMONGE_VAL_IDS,
    SPLITS_DOC,
    cmp_split,
    dev_split,
    load_cmp,
    load_ruemonge,
    ruemonge_split,
)
from facadeforge.datasets.cameras import read_visualsfm, seen_intervals
from facadeforge.datasets.splits import RUEMONGE_GAP_IDS, STREET_DEPTH, STREET_GAP, street_split
from facadeforge.errors import InputError

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"


@dataclass
class _Sample:
    id: str


def test_rule_by_hand():
    ids = [f"x{i:02d}" for i in range(12)]
    assert dev_split(ids, "val") == ["x00", "x05", "x10"]
    assert dev_split(ids, "train") == [i for i in ids if i not in ("x00", "x05", "x10")]
    assert dev_split(ids, "all") == ids


@pytest.mark.parametrize("n, n_val", [(300, 60), (113, 23), (1, 1), (0, 0)])
def test_sizes_disjoint_and_order_free(n: int, n_val: int):
    ids = [f"cmp_b{i:04d}" for i in range(1, n + 1)]
    shuffled = ids[:]
    random.Random(7).shuffle(shuffled)
    val, train = cmp_split(shuffled, "val"), cmp_split(shuffled, "train")
    assert len(val) == n_val and len(train) == n - n_val
    assert not set(val) & set(train) and sorted(val + train) == ids
    assert val == cmp_split(ids, "val") and train == cmp_split(ids[::-1], "train")


def test_samples_pass_through():
    samples = [_Sample(i) for i in ("IMG_5760", "IMG_5717", "IMG_5749", "IMG_5901", "IMG_5800")]
    val = ruemonge_split(samples, "val")
    assert [s.id for s in val] == ["IMG_5760", "IMG_5901"]
    assert all(isinstance(s, _Sample) for s in val)
    assert [s.id for s in ruemonge_split(samples, "train")] == ["IMG_5717", "IMG_5800"]
    assert len(ruemonge_split(samples, "all")) == 5          # the gap photo IMG_5749 too
    assert DEV_SPLITS["ruemonge"] is ruemonge_split and DEV_SPLITS["cmp"] is cmp_split
    # a folder of other photos has no development split: all train, no val
    other = [f"IMG_{i}" for i in range(6)]
    assert ruemonge_split(other, "train") == other and ruemonge_split(other, "val") == []


def test_errors():
    with pytest.raises(InputError, match="train, val, all"):
        cmp_split(["a"], "test")
    with pytest.raises(InputError, match="more than once"):
        cmp_split(["a", "b", "a"], "val")


def test_recorded_lists_follow_the_rule():
    assert len(CMP_VAL_IDS) == 60 and len(RUEMONGE_VAL_IDS) == 28 and len(RUEMONGE_GAP_IDS) == 5
    assert list(CMP_VAL_IDS) == sorted(CMP_VAL_IDS)
    assert list(RUEMONGE_VAL_IDS) == sorted(RUEMONGE_VAL_IDS)
    assert not set(RUEMONGE_VAL_IDS) & set(RUEMONGE_GAP_IDS)
    assert "every 5th" in SPLITS_DOC and "240 train / 60 val" in SPLITS_DOC
    assert "80 train / 5 gap / 28 val" in SPLITS_DOC


def test_real_data_reproduces_recorded_splits():
    if not DATA.is_dir():
        pytest.skip(f"shared dataset folder {DATA} is absent (expected ../shared/data)")
    cmp = load_cmp(DATA / "cmp")
    assert tuple(s.id for s in cmp_split(cmp, "val")) == CMP_VAL_IDS
    assert len(cmp_split(cmp, "train")) == 240
    rue = load_ruemonge(DATA / "ruemonge", "train")
    assert tuple(s.id for s in ruemonge_split(rue, "val")) == RUEMONGE_VAL_IDS
    assert len(ruemonge_split(rue, "train")) == 80
    # the recorded lists are what the cameras give
    cameras = read_visualsfm(DATA / "ruemonge" / "train" / "cameras.txt")
    assert ruemonge_split(rue, "val", cameras) == ruemonge_split(rue, "val")
    assert ruemonge_split(rue, "train", cameras) == ruemonge_split(rue, "train")
    parts = street_split(cameras, cameras)
    assert tuple(sorted(i for i, p in parts.items() if p == "gap")) == RUEMONGE_GAP_IDS


def test_street_split_keeps_every_val_stretch_away_from_train():
    if not DATA.is_dir():
        pytest.skip(f"shared dataset folder {DATA} is absent (expected ../shared/data)")
    cameras = read_visualsfm(DATA / "ruemonge" / "train" / "cameras.txt")
    ids = sorted(cameras)
    seen = dict(zip(ids, seen_intervals([cameras[i] for i in ids], STREET_DEPTH)))
    parts = street_split(cameras, ids)
    for v in (i for i in ids if parts[i] == "val"):
        for t in (i for i in ids if parts[i] == "train"):
            a, b = seen[v], seen[t]
            assert a[1] + STREET_GAP < b[0] or b[1] + STREET_GAP < a[0], (v, t)
    # a larger gap only moves photos from train to gap
    wider = street_split(cameras, ids, gap=3 * STREET_GAP)
    assert {i for i in ids if wider[i] == "val"} == {i for i in ids if parts[i] == "val"}
    assert {i for i in ids if wider[i] == "train"} < {i for i in ids if parts[i] == "train"}


def test_street_split_errors():
    if not DATA.is_dir():
        pytest.skip(f"shared dataset folder {DATA} is absent (expected ../shared/data)")
    cameras = read_visualsfm(DATA / "ruemonge" / "train" / "cameras.txt")
    with pytest.raises(InputError, match="no camera"):
        street_split(cameras, ["IMG_5717", "IMG_0001"])
    one_run = [f"IMG_{i}" for i in range(5717, 5734) if f"IMG_{i}" in cameras]
    with pytest.raises(InputError, match="one unbroken stretch"):
        street_split(cameras, one_run)
