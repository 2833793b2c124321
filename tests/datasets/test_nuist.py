"""NUIST facade scans: loading a facade folder, its element instances, and the shared scan."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from facadeforge.datasets.nuist import (
    canonical_name,
    instances,
    list_facades,
    load_facade,
    write_fixture,
)
from facadeforge.points.cloud import PointCloud, PointCloudError

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"
NUIST = DATA / "pointclouds" / "nuist"


def test_fixture_facade_loads_with_labels_and_instances(tmp_path: Path):
    folder = tmp_path / "building_1" / "facade_1"
    counts = write_fixture(folder, rng=3)
    c = load_facade(folder)
    assert len(c) == sum(counts.values()) and c.source == str(folder) and c.up == 2
    assert c.label_names == ("wall", "window", "door", "balcony")
    assert c.intensity is not None and c.intensity.min() >= 0
    found = instances(c)
    # one instance per file, in (label, number) order
    assert [(n, i) for n, i, _ in found] == [("wall", 0), ("window", 1), ("window", 2),
                                            ("door", 3), ("balcony", 4)]
    files = ["wall_1.txt", "windows_1.txt", "windows_2.txt", "door_1.txt", "balcony_1.txt"]
    for (name, _, idx), f in zip(found, files, strict=True):
        table = np.loadtxt(folder / f, ndmin=2)
        np.testing.assert_array_equal(c.xyz[idx], table[:, :3])
        np.testing.assert_array_equal(c.intensity[idx], table[:, 3].astype(np.float32))
        assert (c.labels[idx] == c.label_of(name)).all()
    assert len(np.unique(c.instance)) == len(files)


def test_other_element_names_are_kept_and_plurals_canonical(tmp_path: Path):
    folder = tmp_path / "f"
    folder.mkdir()
    (folder / "Windows_2.txt").write_text("0 0 0 1\n0 1 0 2\n")
    (folder / "roof_1.txt").write_text("0 0 5 1\n")
    (folder / "wall.txt").write_text("0 0 1 1\n")
    (folder / "notes.md").write_text("not an element\n")
    c = load_facade(folder)
    assert c.label_names == ("wall", "window", "roof")
    assert [(n, i, len(x)) for n, i, x in instances(c)] == [("wall", 0, 1), ("window", 1, 2),
                                                            ("roof", 2, 1)]
    assert canonical_name("Balconies") == "balcony" and canonical_name("doors") == "door"


def test_list_facades_natural_order(tmp_path: Path):
    for b, f in [(10, 1), (2, 1), (2, 3), (1, 12), (1, 2)]:
        write_fixture(tmp_path / f"building_{b}" / f"facade_{f}", spacing=1.0)
    (tmp_path / "building_3").mkdir()                      # no facade in it
    got = [p.relative_to(tmp_path).as_posix() for p in list_facades(tmp_path)]
    assert got == ["building_1/facade_2", "building_1/facade_12", "building_2/facade_1",
                   "building_2/facade_3", "building_10/facade_1"]
    assert list_facades(tmp_path / "building_2" / "facade_3") == [tmp_path / "building_2" /
                                                                  "facade_3"]


def test_instances_of_any_cloud():
    c = PointCloud(np.zeros((6, 3)), labels=[0, 0, 1, -1, 1, 1], label_names=("a", "b"),
                   instance=[5, 5, 2, -1, 2, 7])
    got = instances(c)
    assert [(n, i) for n, i, _ in got] == [("b", 2), ("a", 5), ("b", 7)]
    np.testing.assert_array_equal(got[0][2], [2, 4])
    assert instances(PointCloud(np.zeros((2, 3)), instance=[-1, -1])) == []
    with pytest.raises(PointCloudError, match="no instance ids"):
        instances(PointCloud(np.zeros((2, 3))))


def test_errors(tmp_path: Path):
    with pytest.raises(PointCloudError, match="not found; pass a building_K/facade_M"):
        load_facade(tmp_path / "nope")
    with pytest.raises(PointCloudError, match="holds no element file"):
        load_facade(tmp_path)
    with pytest.raises(PointCloudError, match="holds no facade"):
        list_facades(tmp_path)
    with pytest.raises(PointCloudError, match="NUIST folder .* not found"):
        list_facades(tmp_path / "nope")
    folder = tmp_path / "facade_1"
    write_fixture(folder, spacing=0.5)
    (folder / "door_2.txt").write_text("1 2 3 4\n1 2 3\n")
    with pytest.raises(PointCloudError, match=r"door_2\.txt: line 2 has 3 columns"):
        load_facade(folder)
    (folder / "door_2.txt").unlink()
    n = len(load_facade(folder))
    with pytest.raises(PointCloudError, match="max_points"):
        load_facade(folder, max_points=n - 1)
    assert len(load_facade(folder, max_points=n)) == n


@pytest.mark.skipif(not NUIST.is_dir(),
                    reason=f"shared NUIST scans {NUIST} are absent (expected ../shared/data)")
def test_shared_nuist_facade():
    facades = list_facades(NUIST)
    assert NUIST / "building_1" / "facade_1" in facades
    c = load_facade(NUIST / "building_1" / "facade_1")
    assert len(c) == 54_864
    assert c.label_names == ("wall", "window", "door")
    found = instances(c)
    assert len(found) == 9
    assert sorted({n for n, _, _ in found}) == ["door", "wall", "window"]
    assert sum(len(i) for _, _, i in found) == 54_864
    lo, hi = c.bounds
    size = np.sort(hi - lo)[::-1]
    assert 18 < size[0] < 24 and 9 < size[1] < 13           # about 21 m × 11 m
