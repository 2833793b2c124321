"""Point cloud readers and the PLY writer: round trips of every format, typed errors, real files."""

from __future__ import annotations

from pathlib import Path

import laspy
import numpy as np
import plyfile
import pytest

from facadeforge.points import io as pio
from facadeforge.points.cloud import PointCloud, PointCloudError
from facadeforge.points.io import read_cloud, read_las, read_ply, read_text, write_ply

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"
LILLE = DATA / "pointclouds" / "lille_street_small.ply"


def _vertex(n: int = 50, seed: int = 0, xyz_type: str = "f8") -> np.ndarray:
    rng = np.random.default_rng(seed)
    v = np.empty(n, [("x", xyz_type), ("y", xyz_type), ("z", xyz_type), ("red", "u1"),
                     ("green", "u1"), ("blue", "u1"), ("scalar_Intensity", "f4"),
                     ("nx", "f4"), ("ny", "f4"), ("nz", "f4"), ("label", "i4"),
                     ("instance", "i4"), ("gps_time", "f8")])
    v["x"] = rng.uniform(650000, 651000, n)     # Lambert-93 sized coordinates
    v["y"] = rng.uniform(6860000, 6861000, n)
    v["z"] = rng.uniform(30, 60, n)
    for c in ("red", "green", "blue"):
        v[c] = rng.integers(0, 256, n)
    v["scalar_Intensity"] = rng.uniform(0, 4000, n)
    nrm = rng.normal(size=(n, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    v["nx"], v["ny"], v["nz"] = nrm.T
    v["label"] = rng.integers(-1, 5, n)
    v["instance"] = rng.integers(0, 9, n)
    v["gps_time"] = rng.uniform(0, 1e5, n)
    return v


def _write_plyfile(path: Path, v: np.ndarray, fmt: str, comments=(), obj_info=()) -> Path:
    text = fmt == "ascii"
    order = {"ascii": "=", "binary_little_endian": "<", "binary_big_endian": ">"}[fmt]
    plyfile.PlyData([plyfile.PlyElement.describe(v, "vertex")], text=text, byte_order=order,
                    comments=list(comments), obj_info=list(obj_info)).write(str(path))
    return path


# --------------------------------------------------------------------------------------- PLY
@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_ply_round_trip_all_encodings(tmp_path: Path, fmt: str):
    v = _vertex()
    p = _write_plyfile(tmp_path / "c.ply", v, fmt, comments=["crs EPSG:2154"])
    assert fmt.encode() in p.read_bytes()[:60]
    c = read_cloud(p)
    assert len(c) == len(v) and c.up == 2 and c.source == str(p)
    np.testing.assert_array_equal(c.xyz, np.c_[v["x"], v["y"], v["z"]])
    np.testing.assert_array_equal(c.rgb, np.c_[v["red"], v["green"], v["blue"]])
    np.testing.assert_array_equal(c.intensity, v["scalar_Intensity"])
    np.testing.assert_array_equal(c.normals, np.c_[v["nx"], v["ny"], v["nz"]])
    np.testing.assert_array_equal(c.labels, v["label"])
    assert c.label_names == ("0", "1", "2", "3", "4")
    np.testing.assert_array_equal(c.instance, v["instance"])
    np.testing.assert_array_equal(c.extra["gps_time"], v["gps_time"])
    assert c.extra["gps_time"].dtype.isnative
    assert c.crs == "EPSG:2154"


def test_ply_float_coordinates_float_colours_and_other_names(tmp_path: Path):
    n = 20
    rng = np.random.default_rng(1)
    v = np.empty(n, [("X", "f4"), ("Y", "f4"), ("Z", "f4"), ("r", "f4"), ("g", "f4"),
                     ("b", "f4"), ("Reflectance", "u2"), ("scalar_label", "f4"),
                     ("object", "i4")])
    for k in "XYZ":
        v[k] = rng.uniform(-10, 10, n)
    for k in "rgb":
        v[k] = rng.uniform(0, 1, n)
    v["Reflectance"] = rng.integers(0, 60000, n)
    v["scalar_label"] = rng.integers(0, 3, n)
    v["scalar_label"][0] = np.nan
    v["object"] = np.arange(n)
    p = _write_plyfile(tmp_path / "f.ply", v, "binary_big_endian",
                       obj_info=["crs: EPSG:32631"])
    c = read_ply(p)
    np.testing.assert_array_equal(c.xyz, np.c_[v["X"], v["Y"], v["Z"]].astype(np.float64))
    np.testing.assert_array_equal(c.rgb, np.rint(np.c_[v["r"], v["g"], v["b"]] * 255))
    np.testing.assert_array_equal(c.intensity, v["Reflectance"])
    assert c.labels[0] == -1
    np.testing.assert_array_equal(c.labels[1:], v["scalar_label"][1:])
    np.testing.assert_array_equal(c.instance, v["object"])
    assert c.crs == "EPSG:32631" and c.extra == {}


def test_ply_paris_lille_class_and_label(tmp_path: Path):
    """Paris-Lille-3D: 'class' is the semantic class, 'label' the object id."""
    v = np.zeros(4, [("x", "f4"), ("y", "f4"), ("z", "f4"), ("reflectance", "u1"),
                     ("label", "u4"), ("class", "u4")])
    v["label"] = [7, 7, 9, 0]
    v["class"] = [2, 2, 8, 1]
    c = read_ply(_write_plyfile(tmp_path / "pl.ply", v, "binary_little_endian"))
    np.testing.assert_array_equal(c.labels, [2, 2, 8, 1])
    np.testing.assert_array_equal(c.instance, [7, 7, 9, 0])


def test_ply_large_codes_are_compacted(tmp_path: Path):
    v = np.zeros(3, [("x", "f8"), ("y", "f8"), ("z", "f8"), ("class", "i4")])
    v["class"] = [303020000, 202020000, 303020000]
    c = read_ply(_write_plyfile(tmp_path / "big.ply", v, "binary_little_endian"))
    assert c.label_names == ("202020000", "303020000")
    np.testing.assert_array_equal(c.labels, [1, 0, 1])


@pytest.mark.parametrize("binary", [True, False])
def test_write_ply_round_trip(tmp_path: Path, binary: bool):
    v = _vertex(30, seed=3)
    cloud = PointCloud(np.c_[v["x"], v["y"], v["z"]], intensity=v["scalar_Intensity"],
                       rgb=np.c_[v["red"], v["green"], v["blue"]],
                       normals=np.c_[v["nx"], v["ny"], v["nz"]], labels=v["label"],
                       label_names=("wall", "window", "door", "low vegetation", "roof", "unused"),
                       instance=v["instance"], crs='PROJCRS["x",\n BASEGEOGCRS["y"]]', up=1,
                       extra={"gps_time": v["gps_time"], "seen": np.arange(30) % 2 == 0})
    out = write_ply(cloud, tmp_path / "w.ply", binary=binary)
    assert out == tmp_path / "w.ply" and [p.name for p in tmp_path.iterdir()] == ["w.ply"]
    back = read_cloud(out)
    for name in ("xyz", "intensity", "rgb", "normals", "labels", "instance"):
        np.testing.assert_array_equal(getattr(back, name), getattr(cloud, name), err_msg=name)
    assert back.label_names == cloud.label_names
    assert back.crs == 'PROJCRS["x", BASEGEOGCRS["y"]]'
    assert back.up == 1 and read_cloud(out, up=2).up == 2
    np.testing.assert_array_equal(back.extra["gps_time"], v["gps_time"])
    np.testing.assert_array_equal(back.extra["seen"], np.arange(30) % 2 == 0)


def test_write_ply_xyz_only_and_real_precision(tmp_path: Path):
    xyz = np.array([[651234.123456789, 6861234.987654321, 35.000001], [0.1, 0.2, 0.3]])
    back = read_cloud(write_ply(PointCloud(xyz), tmp_path / "p.ply", binary=False))
    np.testing.assert_array_equal(back.xyz, xyz)
    assert back.rgb is None and back.labels is None and back.crs is None


def test_write_ply_is_atomic(tmp_path: Path, monkeypatch):
    target = tmp_path / "keep.ply"
    target.write_bytes(b"old")

    def boom(self, stream):
        stream.write(b"partial")
        raise OSError("disk full")

    monkeypatch.setattr(plyfile.PlyData, "write", boom)
    with pytest.raises(PointCloudError, match="disk full"):
        write_ply(PointCloud(np.zeros((2, 3))), target)
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.ply"]


def test_write_ply_missing_folder(tmp_path: Path):
    with pytest.raises(PointCloudError, match="does not exist"):
        write_ply(PointCloud(np.zeros((2, 3))), tmp_path / "nope" / "a.ply")


# ------------------------------------------------------------------------------------ LAS/LAZ
def _las(n: int = 40, point_format: int = 3, seed: int = 0) -> laspy.LasData:
    rng = np.random.default_rng(seed)
    header = laspy.LasHeader(point_format=point_format, version="1.4")
    header.scales = np.array([0.001, 0.001, 0.001])
    header.offsets = np.array([650000.0, 6860000.0, 0.0])
    las = laspy.LasData(header)
    las.x = rng.uniform(650000, 650100, n)
    las.y = rng.uniform(6860000, 6860100, n)
    las.z = rng.uniform(20, 40, n)
    las.intensity = rng.integers(0, 65535, n)
    las.classification = rng.choice([1, 2, 6, 9], n)
    if "red" in las.point_format.dimension_names:
        las.red = rng.integers(0, 256, n) * 256
        las.green = rng.integers(0, 256, n) * 257
        las.blue = rng.integers(0, 65536, n)
    return las


@pytest.mark.parametrize("suffix", [".las", ".laz"])
def test_las_round_trip(tmp_path: Path, suffix: str):
    import pyproj

    las = _las()
    las.header.add_crs(pyproj.CRS.from_epsg(2154))
    p = tmp_path / f"c{suffix}"
    las.write(str(p))
    src = laspy.read(str(p))                     # what the file holds after quantisation
    c = read_cloud(p)
    np.testing.assert_array_equal(c.xyz, np.c_[src.x, src.y, src.z])
    assert c.xyz.dtype == np.float64
    np.testing.assert_array_equal(c.intensity, np.asarray(src.intensity))
    rgb16 = np.c_[src.red, src.green, src.blue].astype(np.int64)
    np.testing.assert_array_equal(c.rgb, rgb16 >> 8)
    np.testing.assert_array_equal(c.labels, np.asarray(src.classification))
    assert c.label_names[:10] == ("never_classified", "unclassified", "ground", "low_vegetation",
                                  "medium_vegetation", "high_vegetation", "building", "low_point",
                                  "reserved_8", "water")
    assert c.label_names[c.labels[0]] in ("unclassified", "ground", "building", "water")
    np.testing.assert_array_equal(c.extra["gps_time"], np.asarray(src.gps_time))
    assert c.crs == "EPSG:2154" and c.up == 2


def test_las_without_colour_classes_and_with_instance_extra_bytes(tmp_path: Path):
    las = _las(point_format=1)
    las.classification = np.zeros(len(las.x), np.uint8)
    las.add_extra_dim(laspy.ExtraBytesParams(name="instance", type=np.int32))
    las.add_extra_dim(laspy.ExtraBytesParams(name="height", type=np.float32))
    las.instance = np.arange(len(las.x)) // 4
    las.height = np.linspace(0, 1, len(las.x))
    p = tmp_path / "nocolour.las"
    las.write(str(p))
    c = read_las(p)
    assert c.rgb is None and c.labels is None and c.crs is None
    np.testing.assert_array_equal(c.instance, np.arange(len(las.x)) // 4)
    np.testing.assert_array_equal(c.extra["height"], np.linspace(0, 1, len(las.x), dtype=np.float32))


def test_las_user_class_names(tmp_path: Path):
    las = _las(5, point_format=7)          # 8-bit classification
    las.classification = [2, 30, 70, 2, 6]
    p = tmp_path / "u.las"
    las.write(str(p))
    c = read_las(p)
    assert c.label_names[30] == "reserved_30" and c.label_names[70] == "user_70"
    assert len(c.label_names) == 71


# --------------------------------------------------------------------------------------- text
def _table(n: int, ncols: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = rng.uniform(-500, 500, (n, ncols))
    if ncols in (6, 7):
        t[:, -3:] = rng.integers(0, 256, (n, 3))
    if ncols in (4, 7):
        t[:, 3] = rng.uniform(0, 65535, n)
    return t


def _fmt(t: np.ndarray, sep: str = " ") -> str:
    return "\n".join(sep.join(repr(float(x)) for x in row) for row in t) + "\n"


@pytest.mark.parametrize("ncols", [3, 4, 6, 7])
@pytest.mark.parametrize("suffix", [".xyz", ".txt"])
def test_text_layouts_by_column_count(tmp_path: Path, ncols: int, suffix: str):
    t = _table(25, ncols)
    p = tmp_path / f"c{suffix}"
    p.write_text(_fmt(t, sep="\t" if ncols == 4 else " "))
    c = read_cloud(p)
    np.testing.assert_array_equal(c.xyz, t[:, :3])
    if ncols in (4, 7):
        np.testing.assert_array_equal(c.intensity, t[:, 3].astype(np.float32))
    else:
        assert c.intensity is None
    if ncols in (6, 7):
        np.testing.assert_array_equal(c.rgb, t[:, -3:].astype(np.uint8))
    else:
        assert c.rgb is None


def test_text_csv_with_cloudcompare_header(tmp_path: Path):
    t = _table(10, 4)
    p = tmp_path / "cc.csv"
    p.write_text("//X,Y,Z,Intensity\n" + _fmt(t, sep=","))
    c = read_cloud(p)
    np.testing.assert_array_equal(c.xyz, t[:, :3])
    np.testing.assert_array_equal(c.intensity, t[:, 3].astype(np.float32))


def test_text_header_of_names_maps_columns(tmp_path: Path):
    rng = np.random.default_rng(2)
    t = np.c_[rng.uniform(0, 1, (8, 3)), rng.integers(0, 3, 8), rng.uniform(0, 9, 8),
              rng.uniform(0, 1, (8, 3))]
    p = tmp_path / "named.txt"
    p.write_text("x y z class Intensity nx ny nz\n" + "\r\n".join(
        " ".join(repr(float(x)) for x in row) for row in t) + "\r\n")
    c = read_text(p)
    np.testing.assert_array_equal(c.xyz, t[:, :3])
    np.testing.assert_array_equal(c.labels, t[:, 3].astype(int))
    np.testing.assert_array_equal(c.intensity, t[:, 4].astype(np.float32))
    np.testing.assert_array_equal(c.normals, t[:, 5:].astype(np.float32))


def test_text_unknown_named_columns_go_to_extra(tmp_path: Path):
    p = tmp_path / "e.xyz"
    p.write_text("# exported by a scanner\nx;y;z;time\n1;2;3;4.5\n5;6;7;8.5\n")
    c = read_cloud(p)
    np.testing.assert_array_equal(c.xyz, [[1, 2, 3], [5, 6, 7]])
    np.testing.assert_array_equal(c.extra["time"], [4.5, 8.5])


def test_pts_count_line_is_skipped(tmp_path: Path):
    t = _table(12, 7)
    p = tmp_path / "scan.pts"
    p.write_text("12\n" + _fmt(t))
    c = read_cloud(p)
    assert len(c) == 12
    np.testing.assert_array_equal(c.xyz, t[:, :3])
    np.testing.assert_array_equal(c.rgb, t[:, 4:].astype(np.uint8))


def test_text_float_colours_0_1(tmp_path: Path):
    p = tmp_path / "fc.txt"
    p.write_text("0 0 0 0.5 1.0 0.0\n1 1 1 0.25 0.75 0.1\n")
    np.testing.assert_array_equal(read_cloud(p).rgb, [[128, 255, 0], [64, 191, 26]])


def test_suffix_is_case_insensitive(tmp_path: Path):
    p = tmp_path / "UP.XYZ"
    p.write_text("1 2 3\n")
    assert len(read_cloud(p, up=1)) == 1 and read_cloud(p, up=1).up == 1


# ------------------------------------------------------------------------------------- errors
def _ply_bytes(tmp_path: Path, body: str, name: str = "bad.ply") -> Path:
    p = tmp_path / name
    p.write_text(body)
    return p


@pytest.mark.parametrize("make, match", [
    (lambda d: d / "missing.ply", r"missing\.ply not found; check the path \(supported: \.ply"),
    (lambda d: d, "is a folder"),
    (lambda d: (d / "a.e57").write_bytes(b"x") and d / "a.e57",
     r"unknown point cloud format '\.e57'; supported suffixes are \.ply, \.las, \.laz, \.xyz"),
    (lambda d: (d / "empty.xyz").write_bytes(b"") or d / "empty.xyz", "empty file"),
    (lambda d: (d / "blank.xyz").write_text("\n\n  \n") and d / "blank.xyz", "no line of numbers"),
    (lambda d: _ply_bytes(d, "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\n"
                             "property float y\nproperty float z\nend_header\n"), "holds no points"),
    (lambda d: _ply_bytes(d, "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int "
                             "vertex_indices\nend_header\n3 0 1 2\n"), "no 'vertex' element"),
    (lambda d: _ply_bytes(d, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                             "property float y\nproperty float q\nend_header\n1 2 3\n"),
     r"no x, y, z columns \(it has x, y, q\)"),
    (lambda d: _ply_bytes(d, "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                             "property float y\nproperty float z\nend_header\n1 2 3\nnan 1 1\n"),
     r"1 points have NaN or infinite coordinates \(first at point 1\)"),
    (lambda d: _ply_bytes(d, "solid cube\nfacet normal 0 0 1\n"), "not a PLY file"),
    (lambda d: _ply_bytes(d, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                             "property float y\nproperty float z\nend_header\n1 2 3\n"),
     "not a readable PLY file"),
    (lambda d: _ply_bytes(d, "ply\nformat binary_little_endian 1.0\nelement vertex 1000\n"
                             "property double x\nproperty double y\nproperty double z\n"
                             "end_header\n" + "x" * 100), "written completely"),
    (lambda d: (d / "bad.las").write_bytes(b"LASF" + b"\0" * 300) and d / "bad.las",
     "not a readable LAS/LAZ file"),
    (lambda d: (d / "r.txt").write_text("1 2 3\n4 5 6\n7 8\n") and d / "r.txt",
     r"line 3 has 2 columns where line 1 has 3"),
    (lambda d: (d / "n.csv").write_text("x,y,z\n1,2,3\n4,abc,6\n") and d / "n.csv",
     r"line 3, column 2: 'abc' is not a number"),
    (lambda d: (d / "h.txt").write_text("x y z\n1 2 3\nfoo bar baz\n") and d / "h.txt",
     r"line 3, column 1: 'foo' is not a number"),
    (lambda d: (d / "nan.xyz").write_text("# c\n1 2 3\n\n4 nan 6\n") and d / "nan.xyz",
     r"NaN or infinite coordinates \(first at line 4\)"),
    (lambda d: (d / "five.txt").write_text("1 2 3 4 5\n") and d / "five.txt",
     r"5 columns; without a header line the layouts are 3 \(x y z\)"),
    (lambda d: (d / "hdr.txt").write_text("x y z i\n1 2 3\n") and d / "hdr.txt",
     r"header names 4 columns \(x y z i\) but line 2 has 3"),
    (lambda d: (d / "dup.txt").write_text("x y z X\n1 2 3 4\n") and d / "dup.txt",
     "repeats a column name"),
])
def test_errors_name_the_file_and_the_fix(tmp_path: Path, make, match: str):
    path = make(tmp_path)
    with pytest.raises(PointCloudError, match=match) as err:
        read_cloud(path)
    assert str(path) in str(err.value)


def test_size_cap(tmp_path: Path, monkeypatch):
    p = tmp_path / "big.xyz"
    p.write_text("1 2 3\n" * 10)
    monkeypatch.setattr(pio, "MAX_CLOUD_BYTES", 32)
    with pytest.raises(PointCloudError, match=r"over the .* limit \(MAX_CLOUD_BYTES\); tile"):
        read_cloud(p)


def test_max_points_every_format(tmp_path: Path):
    v = _vertex(10)
    ply = _write_plyfile(tmp_path / "m.ply", v, "binary_little_endian")
    las = tmp_path / "m.laz"
    _las(10).write(str(las))
    txt = tmp_path / "m.xyz"
    txt.write_text(_fmt(_table(10, 3)))
    for p in (ply, las, txt):
        assert len(read_cloud(p, max_points=10)) == 10
        with pytest.raises(PointCloudError, match=r"more than max_points=9"):
            read_cloud(p, max_points=9)


def test_bad_up_axis(tmp_path: Path):
    p = tmp_path / "u.xyz"
    p.write_text("1 2 3\n")
    with pytest.raises(PointCloudError, match="up axis must be 0"):
        read_cloud(p, up=3)


# --------------------------------------------------------------------------------- real files
@pytest.mark.skipif(not LILLE.is_file(),
                    reason=f"shared point cloud {LILLE} is absent (expected ../shared/data)")
def test_lille_street_small():
    c = read_cloud(LILLE)
    assert len(c) == 170_610
    assert c.xyz.dtype == np.float64 and c.up == 2
    assert c.rgb is None and c.labels is None and c.intensity is None
    lo, hi = c.bounds
    np.testing.assert_allclose(hi - lo, [25, 37, 13], atol=1.0)
