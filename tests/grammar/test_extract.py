"""Shape tree → CGA rules (Müller 2007 §5): round trips, size independence, depth, texture."""

from __future__ import annotations

import re

import numpy as np
import pytest

from facadeforge.engine import derive_facade
from facadeforge.errors import InputError
from facadeforge.grammar.extract import extract_rules
from facadeforge.model.scope import Scope
from facadeforge.model.shape import INSERT, Shape

_AXIS_OF = {"left": "x", "right": "x", "dual-x": "x", "top": "y", "bottom": "y", "dual-y": "y"}


# -- building trees by hand -----------------------------------------------------------------------

def _node(symbol, x, y, w, h, cluster, axis, index, split=None) -> Shape:
    params = {"axis": axis, "index": index}
    if split:
        params["split"] = split
    s = Shape(symbol, Scope((x, y, 0.0), np.eye(3), (w, h, 0.0)), operator="split", params=params)
    s.tags = {"cluster": cluster}
    return s


def _fill(node: Shape, content) -> None:
    """``content``: a label, a dict of leaf tags with ``label``, or ``(split, [(size, content)…])``
    with one size ``None`` (the rest of the node)."""
    if isinstance(content, str):
        node.label = content
        return
    if isinstance(content, dict):
        node.label = content["label"]
        node.tags.update({k: v for k, v in content.items() if k != "label"})
        return
    kind, parts = content
    axis = _AXIS_OF[kind]
    k = 0 if axis == "x" else 1
    total = float(node.scope.size[k])
    known = sum(s for s, _ in parts if s is not None)
    pos = float(node.scope.origin[k])
    for i, (size, sub) in enumerate(parts):
        size = total - known if size is None else size
        o = node.scope.origin.copy()
        o[k] = pos
        sz = node.scope.size.copy()
        sz[k] = size
        child = _node("Region", o[0], o[1], sz[0], sz[1], f"{node.tags['cluster']}.{i}", axis, i,
                      kind)
        child.parent = node
        node.children.append(child)
        _fill(child, sub)
        pos += size


def facade(floors) -> Shape:
    """``floors`` bottom first: ``(height, cluster, [(width, cluster, content), …])``."""
    width = sum(w for w, _, _ in floors[0][2])
    height = sum(h for h, _, _ in floors)
    root = Shape("Facade", Scope((0, 0, 0), np.eye(3), (width, height, 0)))
    y = 0.0
    for i, (h, fc, tiles) in enumerate(floors):
        assert abs(sum(w for w, _, _ in tiles) - width) < 1e-9
        f = _node("Floor", 0.0, y, width, h, fc, "y", i)
        f.parent = root
        root.children.append(f)
        x = 0.0
        for j, (w, tc, content) in enumerate(tiles):
            t = _node("Tile", x, y, w, h, tc, "x", j)
            t.parent = f
            f.children.append(t)
            _fill(t, content)
            x += w
        y += h
    return root


WINDOW_TILE = ("dual-x", [(0.6, "wall"), (None, ("bottom", [(0.9, "wall"), (None, "window")])),
                          (0.6, "wall")])


def regular(n_floors=4, n_tiles=4, ground=None, attic=None) -> Shape:
    row = [(0.8, "T1", "wall")] + [(2.5, "T2", WINDOW_TILE)] * n_tiles + [(0.8, "T3", "wall")]
    floors = [(3.0, "F1", row)] * n_floors
    if ground:
        floors = [ground] + floors
    if attic:
        floors = floors + [attic]
    return facade(floors)


# -- checking -------------------------------------------------------------------------------------

def _rect(shape: Shape) -> np.ndarray:
    c = shape.scope.corners()
    return np.array([c[:, 0].min(), c[:, 1].min(), c[:, 0].max(), c[:, 1].max()])


def round_trip(tree: Shape, assets=None, **kw) -> float:
    """Derive the extracted rules at the tree's size; every original leaf must have a derived
    leaf of the same label within 1 % of the facade size.  Returns the largest error (metres)."""
    W, H = float(tree.scope.size[0]), float(tree.scope.size[1])
    model = derive_facade(extract_rules(tree, **kw), W, H, assets=assets)
    assert model.warnings == []
    derived = [(s.label, _rect(s)) for s in model.root.leaves()]
    original = list(tree.leaves())
    assert len(derived) == len(original)
    tol = 0.01 * max(W, H)
    worst = 0.0
    for leaf in original:
        want = _rect(leaf)
        errs = [(np.abs(r - want).max(), k) for k, (lab, r) in enumerate(derived)
                if lab == (leaf.label or "wall")]
        assert errs, f"no derived {leaf.label} leaf"
        err, k = min(errs)
        assert err <= tol, f"{leaf.label} leaf at {want} off by {err:.3f} m"
        worst = max(worst, err)
        derived.pop(k)
    return worst


def labels(model) -> dict[str, int]:
    out: dict[str, int] = {}
    for s in model.root.leaves():
        out[s.label] = out.get(s.label, 0) + 1
    return out


# -- round trips ----------------------------------------------------------------------------------

def test_regular_facade_repeats_floors_and_tiles():
    tree = regular()
    rules = extract_rules(tree)
    assert "{ ~3 : Floor_F1 }*" in rules
    assert "{ ~2.5 : Tile_T2 }*" in rules
    assert "@StartRule\nFacade -->" in rules
    assert round_trip(tree) < 1e-3


def test_ground_floor_and_attic_are_absolute():
    width = 0.8 * 2 + 2.5 * 4
    ground = (4.2, "F0", [(2.0, "T4", "wall"),
                          (1.6, "T5", ("bottom", [(2.4, "door"), (None, "wall")])),
                          (width - 3.6, "T6", ("dual-y", [(0.8, "wall"), (2.6, "shop"),
                                                          (None, "wall")]))])
    attic = (1.5, "F9", [(width, "T7", "wall")])
    tree = regular(3, ground=ground, attic=attic)
    rules = extract_rules(tree)
    assert "split(y) { 4.2 : Floor_F0 | { ~3 : Floor_F1 }* | 1.5 : Floor_F9 }" in rules
    assert round_trip(tree) < 1e-3
    model = derive_facade(rules, width, float(tree.scope.size[1]))
    assert labels(model)["door"] == 1 and labels(model)["shop"] == 1


def test_dual_and_single_splits_follow_section5():
    rules = extract_rules(regular(2, 2))
    # dual: outer parts floating, centre absolute; single: smaller part absolute
    assert "Tile_T2 --> split(x) { ~0.6 : Wall_T2_0 | 1.3 : Region_T2_1 | ~0.6 : Wall_T2_2 }" \
        in rules
    assert "Region_T2_1 --> split(y) { 0.9 : Wall_T2_1_0 | ~1 : Window_T2_1_1 }" in rules


def test_noisy_cluster_members_are_averaged():
    rng = np.random.default_rng(3)
    width = 0.8 * 2 + 2.5 * 5
    floors = []
    for _ in range(5):
        h = 3.0 * (1 + rng.uniform(-0.02, 0.02))
        row, x = [(0.8, "T1", "wall")], 0.8
        for _ in range(5):
            w = 2.5 * (1 + rng.uniform(-0.02, 0.02))
            win = 1.3 * (1 + rng.uniform(-0.02, 0.02))
            side = (w - win) / 2
            row.append((w, "T2", ("dual-x", [(side, "wall"), (win, "window"), (None, "wall")])))
            x += w
        row.append((width - x, "T3", "wall"))
        floors.append((h, "F1", row))
    tree = facade(floors)
    rules = extract_rules(tree)
    sizes = [float(v) for v in re.findall(r"\{ ~([\d.]+) : Tile_T2 \}\*", rules)]
    assert len(sizes) == 1 and abs(sizes[0] - 2.5) < 0.05   # one rule, the cluster mean
    assert round_trip(tree) < 0.01 * float(tree.scope.size[0])


def test_cluster_with_two_structures_becomes_variants():
    sill = ("bottom", [(0.9, "wall"), (None, "window")])
    plain = ("dual-x", [(0.6, "wall"), (None, "window"), (0.6, "wall")])
    row = [(0.8, "T1", "wall"), (2.5, "T2", sill), (2.5, "T2", plain), (2.5, "T2", sill),
           (2.5, "T2", sill), (0.8, "T3", "wall")]
    tree = facade([(3.0, "F1", row)] * 3)
    rules = extract_rules(tree)
    assert "Tile_T2_v1 -->" in rules and "Tile_T2_v2 -->" in rules
    assert round_trip(tree) < 1e-3


def test_no_repetition_first_and_last_absolute():
    floors = []
    for i, h in enumerate([4.0, 3.2, 2.9, 3.1, 2.6]):
        floors.append((h, f"F{i}", [(1.0 + i * 0.1, f"A{i}", "wall"),
                                    (1.5, f"B{i}", ("dual-y", [(0.8, "wall"), (1.6, "window"),
                                                               (None, "wall")])),
                                    (5.0 - i * 0.1, f"C{i}", "wall")]))
    tree = facade(floors)
    rules = extract_rules(tree)
    assert ("Facade --> split(y) { 4 : Floor_F0 | ~3.2 : Floor_F1 | ~2.9 : Floor_F2 "
            "| ~3.1 : Floor_F3 | 2.6 : Floor_F4 }") in " ".join(rules.split())
    assert "*" not in rules.split("@StartRule")[1]
    assert round_trip(tree) < 1e-3


def test_two_repeated_runs_both_keep_their_counts():
    row_a = [(2.5, "T2", WINDOW_TILE)] * 4
    row_b = [(5.0, "T4", ("dual-x", [(1.0, "wall"), (None, "balcony"), (1.0, "wall")]))] * 2
    tree = facade([(4.0, "F0", [(10.0, "T0", "door")])] + [(3.0, "F1", row_a)] * 2
                  + [(3.5, "F2", row_b)] * 3)
    rules = extract_rules(tree)
    assert "{ ~3.5 : Floor_F2 }*" in rules and "{ ~3 : Floor_F1 }* }" in rules
    assert round_trip(tree) < 1e-3


# -- inserted shapes (balconies) ------------------------------------------------------------------

def _hang(host: Shape, x, y, w, h, content, k=0) -> None:
    """Insert a leaf at ``(x, y, w, h)`` (facade metres) in front of ``host``, outside its
    partition, as :mod:`facadeforge.imaging.shape_tree` hangs balconies."""
    s = Shape("Region", Scope((x, y, 0.0), np.eye(3), (w, h, 0.0)), operator=INSERT,
              params={"index": k})
    s.tags = {"cluster": f"{host.tags['cluster']}.p{k}"}
    s.parent = host
    host.children.append(s)
    _fill(s, content)


def _balcony_facade() -> Shape:
    """Three floors of four window tiles: the lower two with a balcony before every window
    (hanging 0.1 m below the floor line), the top one with a band running in front of all."""
    tree = regular(3, 4)
    balcony = {"label": "balcony", "depth": 0.9}
    for floor in tree.children[:2]:
        for tile in floor.children[1:-1]:
            x, y = tile.scope.origin[:2]
            _hang(tile, x + 0.4, y - 0.1, 1.7, 1.2, balcony)
    top = tree.children[2]
    _hang(top, 0.8, float(top.scope.origin[1]), 10.0, 1.0, balcony)
    return tree


def test_inserted_balconies_become_branches_before_the_split():
    tree = _balcony_facade()
    rules = extract_rules(tree)
    assert ("Tile_T2_v1 -->\n\t[ t('0.16, -0.1, 0) s('0.68, 1.2, '1) Balcony_T2_p0 ]\n"
            "\tsplit(x) {") in rules
    assert "[ t('0.069, 0, 0) s('0.8621, 1, '1) Balcony_F1_p0 ]" in rules
    assert "Tile_T2_v2 --> split(x)" in rules          # the top floor's tiles: no balcony
    assert round_trip(tree) < 1e-3
    model = derive_facade(rules, *tree.scope.size[:2])
    assert labels(model) == {"wall": 42, "window": 12, "balcony": 9}
    balcony = next(s for s in model.root.leaves() if s.label == "balcony")
    assert balcony.scope.size[2] == pytest.approx(0.9)       # in front of the facade plane


def test_inserted_balconies_adapt_to_a_wider_facade():
    tree = _balcony_facade()
    W, H = float(tree.scope.size[0]), float(tree.scope.size[1])
    wide = derive_facade(extract_rules(tree), 1.5 * W, H)
    assert wide.warnings == []
    assert labels(wide)["balcony"] == 2 * 6 + 1       # one per window tile, one band
    band = max((s for s in wide.root.leaves() if s.label == "balcony"),
               key=lambda s: s.scope.size[0])
    assert band.scope.size[0] == pytest.approx(1.5 * 10.0, rel=1e-3)   # its share of the floor


# -- size independence ----------------------------------------------------------------------------

def test_rules_adapt_to_a_wider_and_taller_facade():
    tree = regular(4, 4, ground=(4.0, "F0", [(11.6, "T0", "door")]))
    rules = extract_rules(tree)
    W, H = float(tree.scope.size[0]), float(tree.scope.size[1])
    base = labels(derive_facade(rules, W, H))["window"]
    wide = derive_facade(rules, 1.5 * W, H)
    assert wide.warnings == []
    assert labels(wide)["window"] == 4 * 6          # 4 floors × (4 × 1.5) tiles
    tall = derive_facade(rules, W, 1.5 * H)
    assert tall.warnings == []
    assert labels(tall)["window"] > base
    small = derive_facade(rules, 0.7 * W, 0.8 * H)
    assert small.warnings == []


# -- depth, assets, labels ------------------------------------------------------------------------

CUBE_OBJ = """v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1
f 1 2 3 4\nf 5 6 7 8\nf 1 2 6 5\n"""


def _element_tree():
    tile = ("dual-x", [(0.5, "wall"),
                       (None, {"label": "window", "asset": "assets/win.obj", "depth": -0.3}),
                       (0.5, "wall")])
    balcony = ("bottom", [(1.0, {"label": "balcony", "depth": 0.9}), (None, "wall")])
    plain = ("dual-y", [(0.5, "wall"), (1.4, {"label": "window"}), (None, "wall")])
    return facade([(3.0, "F1", [(2.4, "T1", tile), (3.0, "T2", balcony), (2.4, "T1", tile)]),
                   (3.0, "F2", [(2.4, "T3", plain), (3.0, "T4", {"label": "sky"}),
                                (2.4, "T3", plain)])])


def test_depth_and_assets_make_3d_geometry(tmp_path):
    (tmp_path / "assets").mkdir()
    (tmp_path / "assets" / "win.obj").write_text(CUBE_OBJ)
    tree = _element_tree()
    rules = extract_rules(tree)
    assert "attr window_depth = -0.3" in rules and "attr balcony_depth = 0.9" in rules
    assert 'i("assets/win.obj")' in rules
    model = derive_facade(rules, 7.8, 6.0, assets=tmp_path)
    assert model.warnings == []
    parts = {p.symbol: p for p in model.parts}
    win = next(p for s, p in parts.items() if s.startswith("Window_T1"))
    assert win.mesh.vertices[:, 2].min() == pytest.approx(-0.3)
    assert win.mesh.vertices[:, 2].max() == pytest.approx(0.0)
    balcony = next(s for s in model.root.leaves() if s.label == "balcony")
    assert balcony.scope.size[2] == pytest.approx(0.9)
    assert max(p.mesh.vertices[:, 2].max() for p in model.parts if p.label == "balcony") \
        == pytest.approx(0.9)
    flat = [p for s, p in parts.items() if s.startswith("Window_T3")]
    assert flat and np.ptp(flat[0].mesh.vertices[:, 2]) == 0.0
    assert round_trip(tree, assets=tmp_path) < 1e-3
    # editing the class attribute changes every window of that class
    deeper = derive_facade(rules, 7.8, 6.0, assets=tmp_path, attrs={"window_depth": -0.5})
    win = next(p for p in deeper.parts if p.symbol.startswith("Window_T1"))
    assert win.mesh.vertices[:, 2].min() == pytest.approx(-0.5)
    # class depths given for leaves without a depth of their own
    rules = extract_rules(tree, depths={"window": -0.2, "T4": 0.4})
    assert "attr window_depth = -0.2" in rules and "attr sky_depth = 0.4" in rules
    assert "Window_T1_1 --> s('1, '1, 0.3) t(0, 0, -0.3)" in rules   # its own depth: a literal
    model = derive_facade(rules, 7.8, 6.0, assets=tmp_path)
    box = next(p for p in model.parts if p.symbol.startswith("Window_T3"))
    assert box.mesh.vertices[:, 2].min() == pytest.approx(-0.2)


def test_leaf_labels_survive_including_unhinted_ones(tmp_path):
    (tmp_path / "assets").mkdir()
    (tmp_path / "assets" / "win.obj").write_text(CUBE_OBJ)
    tree = _element_tree()
    rules = extract_rules(tree)
    assert 'label("sky")' in rules
    model = derive_facade(rules, 7.8, 6.0, assets=tmp_path)
    assert labels(model) == {"wall": 9, "window": 4, "balcony": 1, "sky": 1}
    # recess without an asset: an open box behind the facade plane
    tree.children[1].children[0].children[1].tags["depth"] = -0.2
    model = derive_facade(extract_rules(tree), 7.8, 6.0, assets=tmp_path)
    box = next(p for p in model.parts if p.symbol.startswith("Window_T3"))
    assert box.mesh.n_faces == 5 and box.mesh.vertices[:, 2].min() == pytest.approx(-0.2)


# -- texture --------------------------------------------------------------------------------------

def test_texture_projects_the_photo_onto_every_leaf(tmp_path):
    from PIL import Image

    (tmp_path / "assets").mkdir()
    (tmp_path / "assets" / "win.obj").write_text(CUBE_OBJ)
    Image.new("RGB", (8, 8), (120, 90, 60)).save(tmp_path / "rect.png")
    rules = extract_rules(_element_tree(), texture="rect.png")
    assert "setupProjection(0, scope.xy, scope.sx, scope.sy) texture(\"rect.png\")" in rules
    model = derive_facade(rules, 7.8, 6.0, assets=tmp_path)
    assert model.warnings == []
    assert model.parts
    for p in model.parts:
        assert p.mesh.corner_uvs is not None, p.symbol
        assert p.material.texture and p.material.texture.endswith("rect.png")
    walls = [p for p in model.parts if p.label == "wall"]
    uv = np.concatenate([p.mesh.corner_uvs for p in walls])
    assert uv.min() >= -1e-9 and uv.max() <= 1 + 1e-9


# -- format and safety ----------------------------------------------------------------------------

GOLDEN = """\
# Facade rules extracted from a photo: small
# (Mueller et al. 2007, section 5; facadeforge.grammar.extract).  Sizes in metres,
# averaged over each cluster; repeats and floating sizes adapt to other facade sizes.
version "2019.0"

@Color
attr wall_color = "#d8c8a8"

# depth of each element class in metres: < 0 recessed behind the wall, > 0 protruding
attr window_depth = -0.25

@StartRule
Facade --> split(y) { 4 : Floor_F0 | { ~3 : Floor_F1 }* }
# cluster F0
Floor_F0 --> split(x) { ~1 : Door_T0 }
# cluster F1, 2 shapes
Floor_F1 --> split(x) { 0.5 : Wall_T1 | { ~2 : Tile_T2 }* }
# cluster T0
Door_T0 --> color("#5a3d2b")
# cluster T1, 2 shapes
Wall_T1 --> color(wall_color)
# cluster T2, 4 shapes
Tile_T2 --> split(x) { ~0.4 : Wall_T2_0 | 1.2 : Window_T2_1 | ~0.4 : Wall_T2_2 }
# cluster T2.0, 4 shapes
Wall_T2_0 --> color(wall_color)
# cluster T2.1, 4 shapes
Window_T2_1 --> s('1, '1, abs(window_depth)) t(0, 0, min(window_depth, 0)) i("builtin:cube") \
comp(f) { front : NIL | all = reverseNormals() color("#6f8fa8") }
# cluster T2.2, 4 shapes
Wall_T2_2 --> color(wall_color)
"""


def test_golden_rules_text():
    win = ("dual-x", [(0.4, "wall"), (1.2, {"label": "window", "depth": -0.25}), (None, "wall")])
    row = [(0.5, "T1", "wall"), (2.0, "T2", win), (2.0, "T2", win)]
    tree = facade([(4.0, "F0", [(4.5, "T0", "door")]), (3.0, "F1", row), (3.0, "F1", row)])
    assert extract_rules(tree, name="small") == GOLDEN
    # the golden text pins the format; check it also means the facade it was extracted from
    model = derive_facade(GOLDEN, 4.5, 10.0)
    assert model.warnings == [] and labels(model) == {"door": 1, "wall": 10, "window": 4}
    assert round_trip(tree) < 1e-3


def test_hostile_text_is_sanitised_and_escaped(tmp_path):
    evil = 'T1"; } Evil --> print("x") #\n'
    win = {"label": "window", "depth": -0.2, "asset": 'assets/a"b\\c\n.obj'}
    tree = facade([(3.0, evil, [(2.0, evil, ("dual-x", [(0.5, "wall"), (None, win),
                                                         (0.5, "wall")]))])])
    tree.children[0].children[0].children[1].label = "Window\")\n"
    rules = extract_rules(tree, name='x\n} Evil -->', texture='t"\nx.png')
    assert "Evil -->" not in rules
    names = re.findall(r"^(\S+) -->", rules, flags=re.M)
    assert all(re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", n) for n in names)
    model = derive_facade(rules, 2.0, 3.0, assets=tmp_path)   # parses; assets are only missing
    assert labels(model) == {"wall": 2, "window": 1}
    assert all("missing" in w or "not found" in w or "texture" in w or "asset" in w
               for w in model.warnings)


def test_unusable_class_depths_are_flat():
    tree = regular(1, 2)
    rules = extract_rules(tree, depths={"window": "deep", "wall": float("nan"), "T1": 1e-6})
    assert "_depth" not in rules and "s('1" not in rules
    assert round_trip(tree, depths={"window": float("inf")}) < 1e-3


def test_unusual_labels_still_give_valid_depth_attrs():
    tree = facade([(3.0, "F1", [(2.0, "T1", {"label": "3d", "depth": -0.2}),
                                (2.0, "T2", {"label": "3d", "depth": -0.2})])])
    rules = extract_rules(tree)
    assert "attr _3d_depth = -0.2" in rules
    assert round_trip(tree) < 1e-3


def test_rejects_trees_larger_than_max_nodes(monkeypatch):
    import facadeforge.grammar.extract as extract

    tree = regular(2, 2)
    n = sum(1 for _ in tree.walk())
    monkeypatch.setattr(extract, "MAX_NODES", n)
    assert "@StartRule" in extract_rules(tree)
    monkeypatch.setattr(extract, "MAX_NODES", n - 1)
    with pytest.raises(InputError, match="more than"):
        extract_rules(tree)


def test_rejects_what_is_not_a_shape_tree():
    with pytest.raises(InputError):
        extract_rules({"symbol": "Facade"})
    leaf = Shape("Facade", Scope((0, 0, 0), np.eye(3), (5, 3, 0)), label="wall")
    model = derive_facade(extract_rules(leaf), 5, 3)
    assert labels(model) == {"wall": 1}
