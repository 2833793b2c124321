"""PointStore (points/store.py): every query against a brute-force scan of the fixed-point
coordinates, with the query moved into the fixed frame the same way: positions onto the grid
(``rint((x − origin) · 65536)``), the ray unrounded (``(x − origin) · 65536``)."""

import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from facadeforge.points.cloud import PointCloud, PointCloudError
from facadeforge.points.store import MERGE_RADIUS, RESOLUTION, SCALE, PointStore, RayHit

UTM = np.array([500000.0, 5400000.0, 300.0])
ENGINES = ("numba", "numpy")


# ------------------------------------------------------------------------------ brute force
def frame(store, x):
    return (np.asarray(x, np.float64) - store.origin) * SCALE


def grid(store, x):
    return np.rint(frame(store, x))


def bf_box(store, lo, hi):
    p = store.fixed().astype(np.float64)
    ulo, uhi = grid(store, lo), grid(store, hi)
    return np.flatnonzero(((p >= ulo) & (p <= uhi)).all(axis=1))


def bf_rect(store, lo, hi):
    p = store.fixed().astype(np.float64)
    ax = list(store.axes)
    ulo = np.rint((np.asarray(lo, float) - store.origin[ax]) * SCALE)
    uhi = np.rint((np.asarray(hi, float) - store.origin[ax]) * SCALE)
    return np.flatnonzero(((p[:, ax] >= ulo) & (p[:, ax] <= uhi)).all(axis=1))


def bf_d2(store, c):
    p = store.fixed().astype(np.float64)
    cf = grid(store, c)
    return (p[:, 0] - cf[0]) ** 2 + (p[:, 1] - cf[1]) ** 2 + (p[:, 2] - cf[2]) ** 2


def bf_radius(store, c, r):
    rf = r * SCALE
    return np.flatnonzero(bf_d2(store, c) <= rf * rf)


def bf_ray(store, o, d, radius):
    """(index, t metres) of the first sphere entered at t > 0, or None."""
    p = store.fixed().astype(np.float64)
    of = frame(store, o)
    dn = np.asarray(d, float) / np.sqrt(np.asarray(d, float) @ np.asarray(d, float))
    rho = radius * SCALE
    w0, w1, w2 = p[:, 0] - of[0], p[:, 1] - of[1], p[:, 2] - of[2]
    tc = w0 * dn[0] + w1 * dn[1] + w2 * dn[2]
    q0, q1, q2 = w0 - tc * dn[0], w1 - tc * dn[1], w2 - tc * dn[2]
    h2 = q0 * q0 + q1 * q1 + q2 * q2
    inside = h2 <= rho * rho
    t = tc - np.sqrt(np.where(inside, rho * rho - h2, 0.0))
    ok = np.flatnonzero(inside & (t > 0))
    if not len(ok):
        return None
    best = ok[np.lexsort((ok, t[ok]))[0]]
    return int(best), t[best] / SCALE


# ------------------------------------------------------------------------------ clouds
def street(n, rng, base=(0.0, 0.0, 0.0), length=60.0):
    """Two facades, a ground plane and some clutter; 10 % exact duplicates."""
    kind = rng.integers(0, 4, n)
    x = rng.uniform(0, length, n)
    y = np.select([kind == 0, kind == 1], [-8 + rng.normal(0, 0.02, n), 8 + rng.normal(0, 0.02, n)],
                  rng.uniform(-8, 8, n))
    z = np.select([kind < 2, kind == 2], [rng.uniform(0, 15, n), rng.normal(0, 0.01, n)],
                  rng.uniform(0, 3, n))
    xyz = np.c_[x, y, z] + np.asarray(base)
    dup = rng.choice(n, n // 10, replace=False)
    xyz[dup] = xyz[rng.integers(0, n, len(dup))]
    return xyz


@pytest.fixture(scope="module", params=["local", "utm"])
def store(request):
    rng = np.random.default_rng(7)
    base = np.zeros(3) if request.param == "local" else UTM
    return PointStore.from_cloud(PointCloud(street(6000, rng, base)))


def queries(store, rng, n):
    lo, hi = store.bounds
    return rng.uniform(lo - 3, hi + 3, (n, 3))


# ------------------------------------------------------------------------------ fixed point
def test_fixed_point_is_round_of_offset_times_65536():
    xyz = np.array([[0.0, 0.0, 0.0], [1.0, -2.5, 3.25], [RESOLUTION / 2 * 0.999, 0, 0]])
    s = PointStore.from_cloud(PointCloud(xyz), origin=[0, 0, 0])
    assert s.fixed().tolist() == [[0, 0, 0], [65536, -163840, 212992], [0, 0, 0]]
    assert s.fixed().dtype == np.int32
    assert np.array_equal(s.to_fixed(xyz), s.fixed())


@pytest.mark.parametrize("base", [np.zeros(3), UTM, np.array([-3.2e6, 1.0e5, -50.0])])
def test_round_trip_error_is_at_most_half_a_unit(base):
    rng = np.random.default_rng(1)
    xyz = base + rng.uniform(-30000, 30000, (20000, 3))
    s = PointStore.from_cloud(PointCloud(xyz))
    err = np.abs(s.xyz() - xyz)
    # 2^-17 m, plus float64's rounding of the metric result (half an ulp of the coordinate).
    assert (err <= 2.0**-17 + np.spacing(np.abs(xyz))).all()
    assert err.max() > 2.0**-18                                    # really quantised
    assert np.array_equal(s.to_fixed(s.xyz()), s.fixed())          # stored positions are exact
    assert np.array_equal(s.xyz([5, 2]), s.xyz()[[5, 2]])
    assert np.array_equal(s.fixed([3]), s.fixed()[[3]])


def test_default_origin_is_the_floored_centre_on_the_cell_grid():
    xyz = UTM + np.array([[1.3, 2.7, 0.2], [13.9, 20.1, 9.9]])
    s = PointStore.from_cloud(PointCloud(xyz))
    assert s.origin.tolist() == [500004.0, 5400008.0, 305.0]       # x, y multiples of 4 m
    s = PointStore.from_cloud(PointCloud(xyz), origin=UTM)
    assert s.origin.tolist() == UTM.tolist()


def test_out_of_range_coordinates_raise_a_clear_error():
    xyz = np.array([[0.0, 0, 0], [40000.0, 0, 0]])
    with pytest.raises(PointCloudError, match="32768 m"):
        PointStore.from_cloud(PointCloud(xyz), origin=[0, 0, 0])
    with pytest.raises(PointCloudError, match="origin"):
        PointStore.from_cloud(PointCloud(np.array([[0.0, 0, 0], [70000.0, 0, 0]])))
    s = PointStore.from_cloud(PointCloud(xyz[:1]), origin=[0, 0, 0])
    assert s.to_fixed([32768 - RESOLUTION, 0, 0])[0] == 2**31 - 1    # the last unit that fits
    assert s.to_fixed([0, -32768.0, 0])[1] == -(2**31)
    with pytest.raises(PointCloudError):
        s.to_fixed([32768.0, 0, 0])
    with pytest.raises(PointCloudError):
        s.to_fixed([0, -32769.0, 0])
    with pytest.raises(PointCloudError, match="finite"):
        s.to_fixed([np.nan, 0, 0])
    # 65 km across fits with the default (centred) origin
    s = PointStore.from_cloud(PointCloud(np.array([[0.0, 0, 0], [65000.0, 1, 1]])))
    assert len(s) == 2


def test_bad_arguments_raise():
    s = PointStore.from_cloud(PointCloud(np.zeros((3, 3))))
    for bad in (0.0, -4.0, np.nan, 1e9):
        with pytest.raises(PointCloudError):
            PointStore.from_cloud(PointCloud(np.zeros((3, 3))), cell=bad)
    with pytest.raises(PointCloudError):
        s.radius([0, 0], 1.0)
    with pytest.raises(PointCloudError):
        s.radius([0, 0, np.inf], 1.0)
    with pytest.raises(PointCloudError):
        s.radius([0, 0, 0], -1.0)
    with pytest.raises(PointCloudError):
        s.ray([0, 0, 0], [0, 0, 0])
    with pytest.raises(PointCloudError):
        s.nearest([0, 0, 0], 0)
    with pytest.raises(PointCloudError):
        s.radius_many(np.zeros((2, 2)), 1.0)
    with pytest.raises(PointCloudError):
        s.engine = "cuda"
    with pytest.raises(PointCloudError):
        PointStore.from_cloud(np.zeros((3, 3)))


# ------------------------------------------------------------------------------ layout
def test_points_are_grouped_by_cell_and_sorted_by_height(store):
    p = store._p
    cu = store._cu
    cells = np.c_[p[store.axes[0]] // cu, p[store.axes[1]] // cu]
    off = store.offsets
    assert off[0] == 0 and off[-1] == len(store) and (np.diff(off) > 0).all()
    assert store.cells == len(np.unique(cells, axis=0))
    for c in range(store.cells):
        s, n = store.leaf(c)
        assert (cells[s:s + n] == cells[s]).all()
        assert (np.diff(p[store.up, s:s + n]) >= 0).all()
    assert len(np.unique(cells[off[:-1]], axis=0)) == store.cells   # each cell in one run
    assert np.array_equal(np.sort(store.order), np.arange(len(store)))
    # the permutation maps store positions to the cloud's points
    assert np.array_equal(store.fixed()[store.order], p.T)


def test_quadtree_nodes_cover_contiguous_leaf_ranges(store):
    d = store.depth
    starts = store._level_start
    assert starts[1] == 1                                          # one root
    for level in range(d):
        for node in range(starts[level], starts[level + 1]):
            kids = store._node_child[node]
            kids = kids[kids >= 0]
            assert len(kids) >= 1
            if level < d - 1:
                assert store._node_lo[node] == store._node_lo[kids].min()
                assert store._node_hi[node] == store._node_hi[kids].max()
            else:
                assert store._node_lo[node] == kids.min()
                assert store._node_hi[node] == kids.max() + 1
    assert store._node_lo[0] == 0 and store._node_hi[0] == store.cells


def test_lookup_by_binary_search_equals_tree_descent(store):
    rng = np.random.default_rng(3)
    lo, hi = store.bounds
    ax = list(store.axes)
    h = rng.uniform(lo[ax] - 10, hi[ax] + 10, (3000, 2))
    got = store.lookup(h)
    assert np.array_equal(got, store.descend(h))
    assert (got >= 0).any() and (got < 0).any()
    pts = store.xyz()[:, ax]
    leaf = store.lookup(pts[store.order])                          # in store order
    assert np.array_equal(leaf, np.repeat(np.arange(store.cells), np.diff(store.offsets)))


def test_memory_and_sizes(store):
    assert len(store) == 6000
    assert store.memory_bytes >= len(store) * 16                   # 12 B coordinates + 4 B order
    assert store.memory_bytes < len(store) * 40
    assert "PointStore(6000 points" in repr(store)


# ------------------------------------------------------------------------------ queries
@pytest.mark.parametrize("engine", ENGINES)
def test_box_column_radius_nearest_equal_brute_force(store, engine):
    store.engine = engine
    rng = np.random.default_rng(11)
    try:
        for c in queries(store, rng, 60):
            h = rng.uniform(0, 6, 3)
            assert np.array_equal(store.box(c - h, c + h), bf_box(store, c - h, c + h))
            ax = list(store.axes)
            got = store.column(c[ax], h[:2])
            assert np.array_equal(got, bf_rect(store, c[ax] - h[:2], c[ax] + h[:2]))
            for r in (0.3, 2.0, 5.5):
                assert np.array_equal(store.radius(c, r), bf_radius(store, c, r))
            idx, dist = store.nearest(c, 7)
            d2 = bf_d2(store, c)
            want = np.lexsort((np.arange(len(d2)), d2))[:7]
            assert np.array_equal(idx, want)
            assert np.allclose(dist, np.sqrt(d2[want]) / SCALE)
        idx, _ = store.nearest(c, 100)                             # beyond the kernel's top-k
        assert np.array_equal(idx, np.lexsort((np.arange(len(d2)), d2))[:100])
        assert len(store.nearest(c, 10**6)[0]) == len(store)
    finally:
        store.engine = "numba"


@pytest.mark.parametrize("engine", ENGINES)
def test_queries_at_point_coordinates_find_the_point_and_include_the_faces(store, engine):
    store.engine = engine
    try:
        p = store.xyz()
        for i in (0, 17, 999):                   # metric coordinates of far points round back
            assert i in store.box(p[i], p[i])
            assert np.array_equal(store.box(p[i], p[i]), bf_box(store, p[i], p[i]))
            assert i in store.radius(p[i], 0.0)
            assert store.nearest(p[i], 1)[1][0] == 0.0
    finally:
        store.engine = "numba"
    u = RESOLUTION
    xyz = UTM + np.array([[0, 0, 0], [3 * u, 4 * u, 0], [0, 0, 7 * u], [2 * u, 0, 0]])
    s = PointStore.from_cloud(PointCloud(xyz), origin=UTM)
    s.engine = engine
    assert s.radius(xyz[0], 5 * u).tolist() == [0, 1, 3]           # distance 5 units: included
    assert s.radius(xyz[0], 4.99 * u).tolist() == [0, 3]
    assert s.box(xyz[0], xyz[0] + [3 * u, 4 * u, 0]).tolist() == [0, 1, 3]
    assert s.box(xyz[0], xyz[0] + [3 * u, 3.4 * u, 0]).tolist() == [0, 3]   # rounds to 3 units
    assert s.column(UTM[:2], 2 * u).tolist() == [0, 2, 3]


@pytest.mark.parametrize("engine", ENGINES)
def test_large_rectangles_use_the_tree_and_equal_brute_force(engine):
    rng = np.random.default_rng(5)
    xyz = UTM + np.c_[rng.uniform(0, 300, 8000), rng.uniform(0, 200, 8000), rng.uniform(0, 30, 8000)]
    xyz = xyz[~((xyz[:, 0] - UTM[0] > 100) & (xyz[:, 0] - UTM[0] < 180))]   # an empty band
    s = PointStore.from_cloud(PointCloud(xyz), cell=2.0)
    s.engine = engine
    assert s.depth >= 7
    for _ in range(40):
        c = UTM + rng.uniform([-20, -20, -5], [320, 220, 35])
        h = rng.uniform([20, 20, 1], [200, 200, 20])            # hundreds of cells
        assert np.array_equal(s.box(c - h, c + h), bf_box(s, c - h, c + h))
        lo, hi = (c - h)[:2], (c + h)[:2]
        assert np.array_equal(s.rectangle(lo, hi), bf_rect(s, lo, hi))
    assert len(s.rectangle(UTM[:2] - 1000, UTM[:2] + 1000)) == len(s)


@pytest.mark.parametrize("engine", ENGINES)
def test_radius_many_equals_radius(store, engine):
    store.engine = engine
    rng = np.random.default_rng(12)
    try:
        cs = queries(store, rng, 150)
        for r in (0.5, 2.0):
            many = store.radius_many(cs, r)
            assert len(many) == len(cs)
            for c, got in zip(cs, many):
                assert np.array_equal(got, bf_radius(store, c, r))
            off, idx = store.radius_many(cs, r, csr=True)
            assert np.array_equal(idx, np.concatenate(many))
            assert np.array_equal(np.diff(off), [len(g) for g in many])
        assert store.radius_many(np.empty((0, 3)), 1.0) == []
    finally:
        store.engine = "numba"


def test_engines_agree_on_unsorted_results_as_sets(store):
    rng = np.random.default_rng(4)
    c = store.xyz()[10]
    a = store.box(c - 3, c + 3, sort=False)
    store.engine = "numpy"
    b = store.box(c - 3, c + 3, sort=False)
    store.engine = "numba"
    assert np.array_equal(np.sort(a), np.sort(b)) and len(a) > 10
    assert not np.array_equal(queries(store, rng, 1), c)


@pytest.mark.parametrize("engine", ENGINES)
def test_empty_results(store, engine):
    store.engine = engine
    try:
        far = store.bounds[1] + 100
        assert store.box(far, far + 1).size == 0
        assert store.box(far + 1, far).size == 0                   # lo > hi
        assert store.radius(far, 5.0).size == 0
        assert store.column(far[list(store.axes)], 2.0).size == 0
        assert all(g.size == 0 for g in store.radius_many(np.array([far, far + 3]), 1.0))
        assert store.box(far, far).dtype == np.int64
        assert store.ray(far, [1, 1, 1]) is None                   # pointing away
    finally:
        store.engine = "numba"


@pytest.mark.parametrize("engine", ENGINES)
def test_empty_store(engine):
    s = PointStore.from_cloud(PointCloud(np.empty((0, 3))))
    s.engine = engine
    assert len(s) == 0 and s.cells == 0
    assert s.box([0, 0, 0], [1, 1, 1]).size == 0
    assert s.radius([0, 0, 0], 3.0).size == 0
    assert s.column([0, 0], 3.0).size == 0
    assert s.ray([0, 0, 0], [1, 0, 0]) is None
    assert s.nearest([0, 0, 0], 3)[0].size == 0
    assert len(s.unique().keep) == 0
    with pytest.raises(PointCloudError):
        _ = s.bounds


# ------------------------------------------------------------------------------ ray
@pytest.mark.parametrize("engine", ENGINES)
def test_ray_equals_brute_force(store, engine):
    store.engine = engine
    rng = np.random.default_rng(21)
    p = store.xyz()
    hits = 0
    try:
        for _ in range(150):
            target = p[rng.integers(len(p))]
            o = target + rng.normal(size=3) * rng.choice([3.0, 30.0])
            d = target - o + rng.normal(size=3) * 0.3
            radius = rng.choice([0.02, 0.1, 0.5, 5.0])
            got, want = store.ray(o, d, radius), bf_ray(store, o, d, radius)
            if want is None:
                assert got is None
                continue
            hits += 1
            assert isinstance(got, RayHit) and got.index == want[0]
            assert got.t == pytest.approx(want[1], abs=1e-9)
        assert hits > 50
        for d in ([0, 0, -1], [0, 0, 1], [1, 0, 0], [0, -1, 0]):     # axis-parallel rays
            for target in p[:20]:
                o = target - np.asarray(d, float) * 7.3 + [0.01, -0.02, 0.03]
                got, want = store.ray(o, d, 0.1), bf_ray(store, o, d, 0.1)
                assert (got is None) == (want is None)
                if want is not None:
                    assert got.index == want[0]
    finally:
        store.engine = "numba"


@pytest.mark.parametrize("engine", ENGINES)
def test_ray_picks_the_front_point_and_misses_between_points(engine):
    # a wall of points 1 m apart at y = 10 and one point in front of it at y = 5
    gx, gz = np.meshgrid(np.arange(-20.0, 21.0), np.arange(0.0, 10.0))
    wall = np.c_[gx.ravel(), np.full(gx.size, 10.0), gz.ravel()]
    xyz = np.vstack([wall, [[0.0, 5.0, 3.0]]]) + UTM
    s = PointStore.from_cloud(PointCloud(xyz))
    s.engine = engine
    front = len(xyz) - 1
    hit = s.ray(UTM + [0, -10, 3], [0, 1, 0], 0.1)
    assert hit.index == front and hit.t == pytest.approx(14.9, abs=1e-6)
    # the same ray with the front point behind the origin hits the wall point behind it
    hit = s.ray(UTM + [0, 6, 3], [0, 1, 0], 0.1)
    wall_pt = int(np.flatnonzero((wall == [0, 10, 3]).all(axis=1))[0])
    assert hit.index == wall_pt and hit.t == pytest.approx(3.9, abs=1e-6)
    # between the wall's points (0.5 m off each) with 10 cm spheres: no hit
    assert s.ray(UTM + [0.5, -10, 3.5], [0, 1, 0], 0.1) is None
    # but spheres of 0.8 m reach: the nearest of the four tied points by index
    hit = s.ray(UTM + [0.5, -10, 3.5], [0, 1, 0], 0.8)
    assert hit is not None and hit.index == bf_ray(s, UTM + [0.5, -10, 3.5], [0, 1, 0], 0.8)[0]
    # a ray starting inside a sphere does not hit that sphere
    hit = s.ray(UTM + [0, 5.02, 3], [0, 1, 0], 0.1)
    assert hit.index == wall_pt
    # slanted, long ray across many empty cells: hits the wall
    o = UTM + [-300.0, -400.0, 3.0]
    target = UTM + np.array([7.0, 10.0, 3.0])
    hit = s.ray(o, target - o, 0.1)
    assert hit.index == bf_ray(s, o, target - o, 0.1)[0]
    assert np.allclose(s.xyz([hit.index])[0], target, atol=1.5)


# ------------------------------------------------------------------------------ equality
def test_unique_groups_equal_integer_triples():
    xyz = UTM + np.array([[0, 0, 0], [1, 1, 1], [0, 0, 0], [1, 1, 1 + RESOLUTION / 4],
                          [2, 2, 2], [0, 0, RESOLUTION]])
    s = PointStore.from_cloud(PointCloud(xyz))
    g = s.unique()
    assert g.keep.tolist() == [0, 1, 4, 5]
    assert g.group.tolist() == [0, 1, 0, 1, 2, 3]
    assert np.array_equal(g.group[g.keep], np.arange(len(g.keep)))


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("base", [np.zeros(3), UTM, np.array([-20000.0, 31000.0, 0.0])])
def test_merge_joins_points_closer_than_the_radius_anywhere(base, engine):
    eps = MERGE_RADIUS                                             # 2^-13 m, 8 units
    pts = np.array([[0, 0, 0], [0.9 * eps, 0, 0],                  # merged
                    [5, 5, 5], [5, 5 + 1.2 * eps, 5],              # not merged
                    [9, 9, 9], [9 + 0.6 * eps, 9, 9], [9 + 1.2 * eps, 9, 9],   # a chain
                    [3, 3, 3], [3, 3, 3]])                         # exact duplicates
    s = PointStore.from_cloud(PointCloud(pts + base), origin=base)
    s.engine = engine
    g = s.merge()
    assert g.keep.tolist() == [0, 2, 3, 4, 7]
    assert g.group.tolist() == [0, 0, 1, 2, 3, 3, 3, 4, 4]
    assert len(s.merge(0.5 * RESOLUTION).keep) == len(s.unique().keep) == 8
    assert len(s.merge(20.0).keep) == 1


@pytest.mark.parametrize("engine", ENGINES)
def test_merge_equals_brute_force_components(engine):
    from scipy.sparse.csgraph import connected_components

    rng = np.random.default_rng(9)
    base = rng.uniform(0, 2, (300, 3))
    xyz = np.vstack([base, base + rng.normal(0, MERGE_RADIUS, base.shape), base[:40]]) + UTM
    s = PointStore.from_cloud(PointCloud(xyz))
    s.engine = engine
    g = s.merge()
    p = s.fixed().astype(np.float64)
    d2 = ((p[:, None] - p[None]) ** 2).sum(-1)
    n, comp = connected_components(d2 < (MERGE_RADIUS * SCALE) ** 2, directed=False)
    assert len(g.keep) == n
    same = g.group[:, None] == g.group[None]
    assert np.array_equal(same, comp[:, None] == comp[None])
    assert np.array_equal(g.group[g.keep], np.arange(n))
    assert all(g.keep[k] == np.flatnonzero(g.group == k).min() for k in range(n))
    assert 300 < n < 600
    u = s.unique()
    assert len(u.keep) == 600 and np.array_equal(u.group[640 - 40:], u.group[:40])


# ------------------------------------------------------------------------------ files, axes
def test_save_load_round_trip(tmp_path, store):
    path = store.save(tmp_path / "sub" / "street.npz")
    assert [f.name for f in path.parent.iterdir()] == ["street.npz"]   # no temporary left
    back = PointStore.load(path)
    assert np.array_equal(back.fixed(), store.fixed())
    assert np.array_equal(back.order, store.order)
    assert np.array_equal(back.offsets, store.offsets)
    assert np.array_equal(back._node_child, store._node_child)
    assert back.origin.tolist() == store.origin.tolist() and back.cell == store.cell
    c = store.xyz()[5]
    assert np.array_equal(back.radius(c, 2.0), store.radius(c, 2.0))
    assert back.ray(c + 5, -np.ones(3)) == store.ray(c + 5, -np.ones(3))
    store.save(path)                                               # overwrite in place
    assert sorted(os.listdir(path.parent)) == ["street.npz"]


def test_load_rejects_other_files(tmp_path):
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    with pytest.raises(PointCloudError, match="cannot read"):
        PointStore.load(bad)
    other = tmp_path / "other.npz"
    np.savez(other, a=np.zeros(3))
    with pytest.raises(PointCloudError, match="not a facadeforge point store"):
        PointStore.load(other)
    with pytest.raises(PointCloudError):
        PointStore.load(tmp_path / "missing.npz")


def test_y_up_clouds_use_x_and_z_as_the_grid():
    rng = np.random.default_rng(2)
    xyz = rng.uniform(-20, 20, (3000, 3))
    s = PointStore.from_cloud(PointCloud(xyz, up=1))
    assert s.axes == (0, 2) and s.up == 1
    for c in rng.uniform(-22, 22, (30, 3)):
        assert np.array_equal(s.box(c - 2, c + 3), bf_box(s, c - 2, c + 3))
        assert np.array_equal(s.column(c[[0, 2]], 1.5), bf_rect(s, c[[0, 2]] - 1.5, c[[0, 2]] + 1.5))
        o, d = c, rng.normal(size=3)
        want = bf_ray(s, o, d, 0.5)
        got = s.ray(o, d, 0.5)
        assert (got is None) == (want is None) and (got is None or got.index == want[0])


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 400), spread=st.sampled_from([0.5, 9.0, 300.0]),
       cell=st.sampled_from([0.5, 4.0, 16.0]))
def test_random_clouds_equal_brute_force(seed, n, spread, cell):
    rng = np.random.default_rng(seed)
    xyz = UTM + rng.uniform(-spread, spread, (n, 3)) * [1, 1, 0.2]
    xyz[rng.random(n) < 0.2] = xyz[0]
    s = PointStore.from_cloud(PointCloud(xyz), cell=cell)
    for engine in ENGINES:
        s.engine = engine
        for c in rng.uniform(xyz.min(0) - 1, xyz.max(0) + 1, (4, 3)):
            h = rng.uniform(0, spread, 3)
            assert np.array_equal(s.box(c - h, c + h), bf_box(s, c - h, c + h))
            assert np.array_equal(s.radius(c, h[0]), bf_radius(s, c, h[0]))
            assert np.array_equal(s.column(c[:2], h[:2]), bf_rect(s, c[:2] - h[:2], c[:2] + h[:2]))
            d = rng.normal(size=3)
            got, want = s.ray(c, d, h[2] / 4 + 0.01), bf_ray(s, c, d, h[2] / 4 + 0.01)
            assert (got is None) == (want is None) and (got is None or got.index == want[0])
    assert len(s.unique().keep) == len(np.unique(s.fixed(), axis=0))


@pytest.mark.parametrize("radius", [MERGE_RADIUS, 0.001, 0.03, 0.7, 3.0])
def test_merge_across_column_borders_and_radii(radius):
    from scipy.sparse.csgraph import connected_components

    rng = np.random.default_rng(13)
    # points crowded around the corners and edges of 4 m columns (x, y near multiples of 4)
    near = rng.integers(-2, 3, (500, 2)) * 4.0 + rng.normal(0, 1.5 * radius, (500, 2))
    xyz = np.c_[near, rng.normal(0, 2 * radius, 500)]
    xyz = np.vstack([xyz, xyz[:50] + rng.normal(0, radius / 3, (50, 3))]) + UTM
    s = PointStore.from_cloud(PointCloud(xyz))
    p = s.fixed().astype(np.float64)
    d2 = ((p[:, None] - p[None]) ** 2).sum(-1)
    n, comp = connected_components(d2 < (radius * SCALE) ** 2, directed=False)
    for engine in ENGINES:
        s.engine = engine
        g = s.merge(radius)
        assert len(g.keep) == n
        assert np.array_equal(g.group[:, None] == g.group[None], comp[:, None] == comp[None])
    assert 1 < n < len(xyz)
