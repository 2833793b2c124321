"""Fixed development splits: the every-5th rule, deterministic and disjoint."""

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
    assert val == cmp_split(ids, "val") and train == ruemonge_split(ids[::-1], "train")


def test_samples_pass_through():
    samples = [_Sample(f"IMG_{i}") for i in (5, 3, 9, 1, 7, 2)]
    val = ruemonge_split(samples, "val")
    assert [s.id for s in val] == ["IMG_1", "IMG_9"] and all(isinstance(s, _Sample) for s in val)
    assert DEV_SPLITS["ruemonge"] is ruemonge_split and DEV_SPLITS["cmp"] is cmp_split


def test_errors():
    with pytest.raises(InputError, match="train, val, all"):
        cmp_split(["a"], "test")
    with pytest.raises(InputError, match="more than once"):
        cmp_split(["a", "b", "a"], "val")


def test_recorded_lists_follow_the_rule():
    assert len(CMP_VAL_IDS) == 60 and len(RUEMONGE_VAL_IDS) == 23
    assert list(CMP_VAL_IDS) == sorted(CMP_VAL_IDS)
    assert "every 5th" in SPLITS_DOC and "240 train / 60 val" in SPLITS_DOC
    assert "90 train / 23 val" in SPLITS_DOC


def test_real_data_reproduces_recorded_splits():
    if not DATA.is_dir():
        pytest.skip(f"shared dataset folder {DATA} is absent (expected ../shared/data)")
    cmp = load_cmp(DATA / "cmp")
    assert tuple(s.id for s in cmp_split(cmp, "val")) == CMP_VAL_IDS
    assert len(cmp_split(cmp, "train")) == 240
    rue = load_ruemonge(DATA / "ruemonge", "train")
    assert tuple(s.id for s in ruemonge_split(rue, "val")) == RUEMONGE_VAL_IDS
    assert len(ruemonge_split(rue, "train")) == 90
