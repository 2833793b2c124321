"""Label sets: dataset ids, colours and canonical labels to class-index maps (hand-computed)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from facadeforge.datasets import (
    CANONICAL_INDEX,
    IGNORE,
    LABEL_SETS,
    LabelSet,
    convert,
    get_label_set,
)
from facadeforge.errors import InputError
from facadeforge.model.labels import Labels

CMP12, CMP6, ECP7 = LABEL_SETS["cmp12"], LABEL_SETS["cmp6"], LABEL_SETS["ecp7"]
LMF9 = LABEL_SETS["lmf9"]


def test_builtin_sets_and_lookup():
    assert list(LABEL_SETS)[:4] == ["cmp12", "cmp6", "ecp7", "lmf9"]
    assert get_label_set("CMP6") is CMP6
    assert get_label_set(ECP7) is ECP7
    assert CMP12.classes == ("background", "wall", "window", "door", "cornice", "sill",
                             "balcony", "blind", "deco", "molding", "pillar", "shop")
    assert CMP12.dataset_names[1] == "facade"
    assert CMP6.classes == ("background", "wall", "window", "door", "balcony", "shop")
    assert ECP7.classes == ("window", "wall", "balcony", "door", "roof", "sky", "shop")
    assert (CMP12.ignore_index, CMP6.ignore_index, ECP7.ignore_index) == (None, None, 0)
    for s in LABEL_SETS.values():
        assert s.colors.shape == (s.num_classes, 3) and s.colors.dtype == np.uint8


def test_unknown_label_set_lists_names():
    with pytest.raises(InputError, match="cmp12, cmp6, ecp7"):
        get_label_set("cmp7")


def test_from_dataset_cmp12_and_cmp6():
    ids = np.array([[1, 2, 3, 4, 5, 6], [7, 8, 9, 10, 11, 12]])
    assert CMP12.from_dataset(ids).tolist() == [[0, 1, 2, 3, 4, 5], [6, 7, 8, 9, 10, 11]]
    # background | wall (facade cornice sill deco molding pillar) | window (window blind) |
    # door | balcony | shop
    assert CMP6.from_dataset(ids).tolist() == [[0, 1, 2, 3, 1, 1], [4, 2, 1, 1, 1, 5]]
    out = CMP6.from_dataset(np.array([[0, 13], [-1, 255]], np.int32))
    assert out.dtype == np.uint8 and out.tolist() == [[IGNORE, IGNORE], [IGNORE, IGNORE]]


def test_from_dataset_ecp7_ignores_zero():
    ids = np.array([[0, 1, 2, 3], [4, 5, 6, 7]], np.uint8)
    assert ECP7.from_dataset(ids).tolist() == [[255, 0, 1, 2], [3, 4, 5, 6]]


def test_from_dataset_strict_and_dtype_errors():
    ECP7.from_dataset(np.array([0, 7]), strict=True)  # the ignore id is known
    with pytest.raises(InputError, match=r"\[9\]"):
        ECP7.from_dataset(np.array([0, 9]), strict=True)
    with pytest.raises(InputError, match="integers"):
        ECP7.from_dataset(np.array([0.5]))


def test_convert_cmp12_to_cmp6_equals_merge():
    ids = np.arange(1, 13).reshape(3, 4)
    assert np.array_equal(convert(CMP12.from_dataset(ids), "cmp12", "cmp6"),
                          CMP6.from_dataset(ids))
    # ignored pixels stay ignored; ecp7 roof/sky → cmp6 background
    m = np.array([[IGNORE, 4, 5, 0]], np.uint8)
    assert convert(m, ECP7, CMP6).tolist() == [[IGNORE, 0, 0, 2]]


def test_from_canonical_names():
    names = np.array([["sky", "cornice", "blind"], ["other", "roof", "shop"]])
    assert CMP6.from_canonical(names).tolist() == [[0, 1, 2], [1, 0, 5]]
    assert CMP12.from_canonical(names).tolist() == [[0, 4, 7], [1, 0, 11]]
    # ecp7 has no background: background → sky; vegetation, ground, other → wall
    names = np.array(["background", "vegetation", "ground", "other", "roof", "blind"])
    assert ECP7.from_canonical(names).tolist() == [5, 1, 1, 1, 4, 0]
    # occluders and the street: background in CMP, wall in ecp7 (in front of the facade, or the
    # street RueMonge leaves unlabelled), their own classes in lmf9 (people are "various")
    names = np.array(["car", "person", "pavement", "road"])
    assert CMP6.from_canonical(names).tolist() == [0, 0, 0, 0]
    assert CMP12.from_canonical(names).tolist() == [0, 0, 0, 0]
    assert ECP7.from_canonical(names).tolist() == [1, 1, 1, 1]
    assert LMF9.from_canonical(names).tolist() == [2, 0, 4, 5]
    # Labels members and dataset words are accepted
    assert CMP6.from_canonical([Labels.DOOR, "facade"]).tolist() == [3, 1]
    with pytest.raises(InputError, match="not a canonical label"):
        CMP6.from_canonical(["xyzzy"])


def test_from_canonical_indices():
    canon = np.array([[CANONICAL_INDEX["window"], CANONICAL_INDEX["pillar"]],
                      [CANONICAL_INDEX["sky"], IGNORE]], np.uint8)
    assert CMP6.from_canonical(canon).tolist() == [[2, 1], [0, IGNORE]]
    assert ECP7.from_canonical(canon).tolist() == [[0, 1], [5, IGNORE]]
    with pytest.raises(InputError, match="out of range"):
        CMP6.from_canonical(np.array([len(Labels)]))


def test_every_canonical_label_maps_in_every_set():
    all_names = np.array([label.value for label in Labels])
    all_indices = np.arange(len(Labels))
    for s in LABEL_SETS.values():
        assert set(s.canonical_map) == {label.value for label in Labels}
        by_name = s.from_canonical(all_names)
        assert np.array_equal(by_name, s.from_canonical(all_indices))
        assert (by_name < s.num_classes).all()
        # a class's own canonical label maps onto it
        assert [s.index(c) for c in s.classes] == list(range(s.num_classes))


def test_canonical_index_matches_raster_numbering():
    from facadeforge.exchange.raster import LABEL_INDEX

    assert dict(CANONICAL_INDEX) == LABEL_INDEX


def test_canonical_round_trip():
    for s in LABEL_SETS.values():
        m = np.append(np.arange(s.num_classes), IGNORE).astype(np.uint8).reshape(1, -1)
        assert np.array_equal(s.from_canonical(s.to_canonical(m)), m)


def test_to_color_and_back():
    m = np.array([[0, 1], [6, IGNORE]], np.uint8)
    rgb = ECP7.to_color(m)
    assert rgb.shape == (2, 2, 3) and rgb.dtype == np.uint8
    assert rgb.tolist() == [[[255, 0, 0], [255, 255, 0]], [[0, 255, 0], [0, 0, 0]]]
    assert np.array_equal(ECP7.from_color(rgb), m)
    cmp = CMP12.to_color(np.array([[0, 11]]))
    assert cmp.tolist() == [[[0, 0, 170], [170, 0, 0]]]
    with pytest.raises(InputError, match="out of range"):
        CMP6.to_color(np.array([[6]]))


def test_from_color_unknown_colours():
    rgb = np.array([[[1, 2, 3], [255, 0, 0]]], np.uint8)
    assert ECP7.from_color(rgb).tolist() == [[IGNORE, 0]]
    with pytest.raises(InputError, match="not class colours"):
        ECP7.from_color(rgb, strict=True)
    ECP7.from_color(np.zeros((1, 1, 3), np.uint8), strict=True)  # the ignore colour is known


def test_label_set_is_immutable_and_validated():
    with pytest.raises(dataclasses.FrozenInstanceError):
        CMP6.name = "x"
    assert not CMP6.colors.flags.writeable
    with pytest.raises(TypeError):
        CMP6.id_map[1] = 3
    with pytest.raises(InputError, match="more than once"):
        LabelSet("dup", ("wall", "facade"), np.zeros((2, 3)), {0: 0, 1: 1})
    with pytest.raises(InputError, match="not a canonical label"):
        LabelSet("bad", ("wall", "qwerty"), np.zeros((2, 3)), {0: 0, 1: 1})
    with pytest.raises(InputError, match="colors"):
        LabelSet("bad", ("wall", "window"), np.zeros((3, 3)), {0: 0, 1: 1})
    with pytest.raises(InputError, match="ignore id"):
        LabelSet("bad", ("wall",), np.zeros((1, 3)), {0: 0}, ignore_index=0)


def test_custom_set_defaults():
    s = LabelSet("two", ("wall", "window"), np.array([[1, 2, 3], [4, 5, 6]]), {10: 0, 20: 1})
    assert s.from_dataset(np.array([10, 20, 30])).tolist() == [0, 1, IGNORE]
    # no background, no sky: everything non-building falls back to wall (or class 0)
    assert s.from_canonical(["sky", "door", "blind", "background"]).tolist() == [0, 0, 1, 0]


def test_windows_behind_follows_each_dataset_convention():
    """CMP draws windows whole behind balcony railings, RueMonge stops them at the railing."""
    from facadeforge.datasets import get_label_set

    assert get_label_set("cmp6").windows_behind == ("balcony",)
    assert get_label_set("cmp12").windows_behind == ("balcony",)
    assert get_label_set("ecp7").windows_behind == ()
    with pytest.raises(InputError, match="windows_behind"):
        LabelSet("x", ("wall", "window"), np.zeros((2, 3), np.uint8), {1: 0, 2: 1},
                 windows_behind=("balcony",))


def test_windows_covering_names_cmp_closed_shutters():
    """CMP draws its window rectangles over closed shutters (``blind``); RueMonge has none."""
    from facadeforge.datasets import get_label_set

    assert get_label_set("cmp12").windows_covering == ("blind",)
    assert get_label_set("ecp7").windows_covering == ()
    with pytest.raises(InputError, match="windows_covering"):
        LabelSet("x", ("wall", "window"), np.zeros((2, 3), np.uint8), {1: 0, 2: 1},
                 windows_covering=("blind",))


def test_project_proba_sums_fine_classes_into_the_merged_ones():
    cmp12, cmp6 = get_label_set("cmp12"), get_label_set("cmp6")
    rng = np.random.default_rng(0)
    p = rng.dirichlet(np.ones(cmp12.num_classes), size=(4, 5)).astype(np.float32)
    out = cmp6.project_proba(p, cmp12.classes, floor=0.0)
    assert out.shape == (4, 5, 6) and out.dtype == np.float32
    np.testing.assert_allclose(out.sum(axis=2), 1.0, rtol=1e-5)
    c12 = list(cmp12.classes)
    np.testing.assert_allclose(out[:, :, cmp6.index("window")],
                               p[:, :, c12.index("window")] + p[:, :, c12.index("blind")],
                               rtol=1e-5)
    wall_parts = [c12.index(c) for c in ("wall", "cornice", "sill", "deco", "molding", "pillar")]
    np.testing.assert_allclose(out[:, :, cmp6.index("wall")], p[:, :, wall_parts].sum(axis=2),
                               rtol=1e-5)
    # glass 0.3 + shutters 0.3 outweigh wall 0.4 once merged, as in the merged truth
    q = np.zeros((1, 1, cmp12.num_classes), np.float32)
    q[0, 0, [c12.index("window"), c12.index("blind"), c12.index("wall")]] = 0.3, 0.3, 0.4
    assert np.argmax(q[0, 0]) == c12.index("wall")
    assert np.argmax(cmp6.project_proba(q, cmp12.classes)[0, 0]) == cmp6.index("window")


def test_project_proba_floors_classes_no_channel_reaches_and_keeps_its_own():
    cmp6 = get_label_set("cmp6")
    p = np.zeros((2, 2, 2), np.float32)
    p[..., 0] = 1.0
    out = cmp6.project_proba(p, ("window", "wall"))
    assert out[..., cmp6.index("door")].min() > 0          # unlikely, not impossible
    assert np.argmax(out, axis=2).tolist() == [[cmp6.index("window")] * 2] * 2
    own = np.full((2, 2, 6), 1 / 6, np.float32)
    assert cmp6.project_proba(own, cmp6.classes) is own    # already in this set: unchanged
    with pytest.raises(InputError, match="one channel per class"):
        cmp6.project_proba(own, ("window", "wall"))


# ------------------------------------------------------------------------------- LabelMeFacade
def test_lmf9_classes_names_and_colours():
    assert LMF9.classes == ("other", "wall", "car", "door", "pavement", "road", "sky",
                            "vegetation", "window")
    assert LMF9.dataset_names == ("various", "building", "car", "door", "pavement", "road", "sky",
                                  "vegetation", "window")
    assert LMF9.colors.tolist() == [[0, 0, 0], [128, 0, 0], [128, 0, 128], [128, 128, 0],
                                    [128, 128, 128], [128, 64, 0], [0, 128, 128], [0, 128, 0],
                                    [0, 0, 128]]
    assert LMF9.ignore_index is None and LMF9.ignore_color is None
    rgb = LMF9.colors[np.array([[1, 8], [6, 0]])]
    assert LMF9.from_color(rgb).tolist() == [[1, 8], [6, 0]]
    assert LMF9.from_color(np.array([[[1, 2, 3]]], np.uint8)).tolist() == [[IGNORE]]


def test_lmf9_canonical_fallbacks():
    """building is the facade with its balconies, shops, roofs and parts; blinds are windows;
    CMP's background (mostly sky) is sky; the ground in front of a facade is its pavement."""
    def name(label):
        return LMF9.dataset_names[LMF9.index(label)]

    assert {c: name(c) for c in ("wall", "balcony", "shop", "roof", "cornice", "sill", "deco",
                                 "molding", "pillar")} == dict.fromkeys(
        ("wall", "balcony", "shop", "roof", "cornice", "sill", "deco", "molding", "pillar"),
        "building")
    assert name("blind") == "window"
    assert name("background") == "sky"
    assert name("other") == "various" and name("person") == "various"
    assert name("ground") == "pavement"
    # a cmp12 truth map in lmf9, and lmf9 truth in cmp6 (everything not the building is
    # background there) and ecp7
    assert convert(np.arange(12).reshape(1, -1), CMP12, LMF9).tolist() == [
        [6, 1, 8, 3, 1, 1, 1, 8, 1, 1, 1, 1]]
    assert convert(np.arange(9).reshape(1, -1), LMF9, CMP6).tolist() == [
        [1, 1, 0, 3, 0, 0, 0, 0, 2]]
    assert convert(np.arange(9).reshape(1, -1), LMF9, ECP7).tolist() == [
        [1, 1, 1, 3, 1, 1, 5, 1, 0]]


def test_name_hints_of_occluders_and_street():
    from facadeforge.model.labels import label_for_name

    guesses = {n: label_for_name(n) for n in (
        "CarBody", "ParkedCars", "Vehicle", "Pedestrian", "People", "person", "Sidewalk",
        "SidewalkTile", "road", "Roadway", "Street", "StreetFacade", "StreetFloor", "CarDoor",
        "CarriageBay", "Cartouche", "Broadway", "TreeCrown", "PalmTree", "StreetTree")}
    assert {n: (g.value if g else None) for n, g in guesses.items()} == {
        "CarBody": "car", "ParkedCars": "car", "Vehicle": "car", "Pedestrian": "person",
        "People": "person", "person": "person", "Sidewalk": "pavement",
        "SidewalkTile": "pavement", "road": "road", "Roadway": "road", "Street": "road",
        "StreetFacade": "wall", "StreetFloor": "wall", "CarDoor": "door",
        "CarriageBay": None, "Cartouche": None, "Broadway": None, "TreeCrown": "vegetation",
        "PalmTree": "vegetation", "StreetTree": "vegetation"}
    # the canonical indices of earlier labels did not move
    assert [label.value for label in Labels][-5:] == ["ground", "car", "person", "pavement",
                                                      "road"]
    assert CANONICAL_INDEX["ground"] == 16 and CANONICAL_INDEX["road"] == 20
