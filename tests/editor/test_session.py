"""facadeforge.editor.session: edits re-derive the model, undo/redo, the atomic save."""

from __future__ import annotations

import hashlib
import json
import os

import numpy as np
import pytest

from facadeforge.editor.edits import EditError
from facadeforge.editor.session import EditSession
from facadeforge.errors import InputError
from facadeforge.exchange import load

SAVED = ("shape_tree.json", "rules.cga", "model.glb", "model.obj", "model.city.json",
         "labels.png", "structure.png", "report.json")


def _digest(folder, names=SAVED):
    return {n: hashlib.sha256((folder / n).read_bytes()).hexdigest() for n in names}


def _window(session):
    for path, node in _paths(session.tree):
        if node.label == "window" and not node.children:
            return path, node
    raise AssertionError("no window leaf")


def _paths(tree):
    stack = [([], tree)]
    while stack:
        p, n = stack.pop()
        yield p, n
        stack.extend((p + [i], c) for i, c in enumerate(n.children))


def test_opening_rederives_the_rules_written_by_reconstruct(outdir):
    s = EditSession(outdir)
    assert s.derived.rules == (outdir / "rules.cga").read_text()
    assert s.glb()[:4] == b"glTF"
    assert s.state()["dirty"] is False


def test_edits_undo_redo_and_save_rewrite_the_outdir(outdir):
    before = _digest(outdir)
    s = EditSession(outdir)
    rules0 = s.derived.rules
    s.apply({"op": "move_split", "path": [], "index": 1, "delta": 0.3})
    path, _ = _window(s)
    s.apply({"op": "set_depth", "path": path, "depth": -0.6})
    assert s.derived.rules != rules0 and "0.6" in s.derived.rules
    assert _digest(outdir) == before              # nothing written before save
    assert s.undo() and s.state()["can_redo"]
    assert s.redo() and not s.redo()
    files = s.save()
    assert set(SAVED) <= set(files)
    after = _digest(outdir)
    assert all(after[n] != before[n] for n in ("shape_tree.json", "rules.cga", "model.glb",
                                               "report.json", "labels.png"))
    report = json.loads((outdir / "report.json").read_text())
    assert [e["edit"]["op"] for e in report["edits"]] == ["move_split", "set_depth"]
    tree = json.loads((outdir / "shape_tree.json").read_text())
    first = tree["children"][0]["scope"]["size"][1]
    assert first == pytest.approx(s.tree.children[0].scope.size[1])
    # what was saved is what the page showed, and loads back
    assert (outdir / "rules.cga").read_text() == s.derived.rules
    models = load(outdir / "model.glb")
    assert models and sum(len(m.parts) for m in models) > 0
    assert s.state()["dirty"] is False and not s.state()["can_undo"]
    # a second session sees the saved tree, and reproduces the saved rules
    s2 = EditSession(outdir)
    assert s2.derived.rules == s.derived.rules


def test_a_save_keeps_files_the_user_added_and_the_marker_lists_only_ours(outdir):
    (outdir / "notes.txt").write_text("mine")
    s = EditSession(outdir)
    s.apply({"op": "move_split", "path": [], "index": 1, "delta": 0.2})
    s.save()
    assert (outdir / "notes.txt").read_text() == "mine"
    marker = json.loads((outdir / ".facadeforge-outdir.json").read_text())
    assert "notes.txt" not in marker["files"] and "rules.cga" in marker["files"]


def test_a_failing_save_leaves_every_file_as_it_was(outdir, monkeypatch):
    s = EditSession(outdir)
    s.apply({"op": "move_split", "path": [], "index": 1, "delta": 0.2})
    before = _digest(outdir)
    import facadeforge.exchange as exchange

    def broken(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(exchange, "export", broken)
    with pytest.raises(OSError, match="disk full"):
        s.save()
    assert _digest(outdir) == before
    assert not [p for p in outdir.parent.iterdir() if ".staging-" in p.name]
    assert s.state()["dirty"] is True          # the edits are still there to save


def test_a_bad_edit_changes_nothing(outdir):
    s = EditSession(outdir)
    tree0, v0 = s.tree_dict(), s.version
    with pytest.raises(EditError):
        s.apply({"op": "set_depth", "path": [], "depth": 1})
    assert s.tree_dict() == tree0 and s.version == v0 and not s.log


@pytest.mark.parametrize("make, message", [
    (lambda d: d / "missing", "is not a folder"),
    (lambda d: (d / "empty").mkdir() or d / "empty", "holds no shape_tree.json"),
])
def test_bad_outdirs_are_refused(tmp_path, make, message):
    with pytest.raises(InputError, match=message):
        EditSession(make(tmp_path))


def test_a_corrupt_shape_tree_is_refused_with_the_file_named(outdir):
    (outdir / "shape_tree.json").write_text('{"symbol": "Facade"}')
    with pytest.raises(InputError, match="shape_tree.json is not a facadeforge shape tree"):
        EditSession(outdir)


def test_facade_folders_of_a_street_photo(outdir, tmp_path):
    street = tmp_path / "street"
    street.mkdir()
    os.rename(outdir, street / "facade_01")
    s = EditSession(street)
    assert s.facades == ["facade_01"] and s.facade == "facade_01"
    with pytest.raises(InputError, match="choose one of facade_01"):
        EditSession(street, facade="facade_07")


def test_reanalyse_replaces_only_the_inside_of_the_shape(outdir):
    s = EditSession(outdir)
    s.apply({"op": "move_split", "path": [], "index": 1, "delta": 0.2})   # a fix to hold
    floors = len(s.tree.children)
    target = max(range(floors), key=lambda i: s.tree.children[i].scope.size[1])
    others = {i: s.tree.children[i].to_dict() for i in range(floors) if i != target}
    box = s.tree.children[target].scope
    o, size = box.origin.copy(), box.size.copy()
    done = s.apply({"op": "reanalyse", "path": [target]})
    assert done["shapes"] >= 1
    node = s.tree.children[target]
    assert (node.scope.origin == o).all() and (node.scope.size == size).all()
    assert {i: s.tree.children[i].to_dict() for i in others} == others   # all else held
    inside = [n for n in node.walk() if n is not node]
    assert inside and all(str(n.tags.get("cluster", "R1.")).startswith("R1.") for n in inside)
    for n in inside:   # inside the shape's rectangle
        assert n.scope.origin[0] >= o[0] - 1e-6 and n.scope.origin[1] >= o[1] - 1e-6
        assert n.scope.origin[0] + n.scope.size[0] <= o[0] + size[0] + 1e-6
        assert n.scope.origin[1] + n.scope.size[1] <= o[1] + size[1] + 1e-6
    assert s.undo() and s.tree.children[target].to_dict() != node.to_dict()
    with pytest.raises(EditError, match="through"):
        from facadeforge.editor.edits import apply_edit

        apply_edit(s.tree, {"op": "reanalyse", "path": []})


def test_reanalyse_refuses_a_sliver(outdir):
    s = EditSession(outdir)
    s.apply({"op": "move_split", "path": [], "index": 1, "delta": -100})   # floor 0 → 5 cm
    with pytest.raises(EditError, match="at least"):
        s.apply({"op": "reanalyse", "path": [0]})


def test_a_facade_of_a_laser_scan_is_edited_and_the_scan_model_rebuilt(tmp_path):
    from pathlib import Path

    scan = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "pointclouds" / \
        "lille_street_small.ply"
    if not scan.is_file():
        pytest.skip(f"shared point clouds not found at {scan.parent}")
    from facadeforge.cli import main

    out = tmp_path / "scan-out"
    assert main(["points", str(scan), "-o", str(out)]) == 0
    before = load(out / "model.glb")
    s = EditSession(out)
    assert s.scan and s.facade == "facade_00" and s.textured
    assert s.derived.rules == (out / "facade_00" / "rules.cga").read_text()
    s.apply({"op": "move_split", "path": [], "index": 1, "delta": 0.3})
    files = s.save()
    assert {"model.glb", "report.json", "facade_00/rules.cga"} <= set(files)
    after = load(out / "model.glb")
    assert [m.name for m in after] == [m.name for m in before]
    # every facade still stands where the scan has it (the edit moves a floor line only)
    for a, b in zip(after, before):
        assert np.allclose(a.stats()["bbox"], b.stats()["bbox"], atol=0.05)
    report = json.loads((out / "report.json").read_text())
    assert report["edits"][0]["facade"] == "facade_00" and "origin" in report


def test_undo_restores_every_value_an_edit_changed(outdir):
    """Snapshots share nothing with the live tree: tags, params and pixel boxes come back."""
    s = EditSession(outdir)
    tree0 = s.tree_dict()
    path, _ = _window(s)
    from facadeforge.editor.edits import node_at, partition

    split_path = next(p for p, n in _paths(s.tree) if len(partition(n)[0]) == 3)
    dual = "dual-" + partition(node_at(s.tree, split_path))[1]
    for edit in ({"op": "set_depth", "path": path, "depth": -1.5},
                 {"op": "move_split", "path": [], "index": 1, "delta": 0.4},
                 {"op": "reverse_split", "path": split_path},
                 {"op": "set_split", "path": split_path, "split": dual}):
        s.apply(edit)
    assert s.tree_dict() != tree0
    while s.undo():
        pass
    assert s.tree_dict() == tree0
    assert s.derived.rules == (outdir / "rules.cga").read_text()


def test_saving_from_inside_the_outdir_is_refused(outdir, monkeypatch):
    s = EditSession(outdir)
    s.apply({"op": "move_split", "path": [], "index": 1, "delta": 0.2})
    monkeypatch.chdir(outdir)
    with pytest.raises(InputError, match="current folder"):
        s.save()
    assert (outdir / "rules.cga").is_file()


def test_reanalysed_regions_never_reuse_a_prefix():
    from facadeforge.editor.session import _next_region
    from facadeforge.model.shape import Shape

    t = Shape("Facade")
    assert _next_region(t) == 1
    t.add(Shape("Floor", tags={"cluster": "R1.F0"}))
    t.add(Shape("Floor", tags={"cluster": "R3.T2.1"}))
    assert _next_region(t) == 4
