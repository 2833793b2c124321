"""rules.gml in the OUTDIRs of reconstruct, parse and points: the shape tree as GML, deriving
the same leaves."""

from __future__ import annotations

import numpy as np

from facadeforge.gml import derive_gml


def _leaf_boxes(tree):
    out = []
    for leaf in tree.leaves():
        if not leaf.label or leaf.label in ("", "void"):
            continue
        o, s = leaf.scope.origin, leaf.scope.size
        out.append((leaf.label, round(float(o[0]), 3), round(float(o[1]), 3),
                    round(float(o[0] + s[0]), 3), round(float(o[1] + s[1]), 3)))
    return sorted(out)


def test_reconstruct_writes_rules_gml(tmp_path):
    from facadeforge.datasets.synthetic import generate
    from facadeforge.reconstruction import reconstruct

    photo = generate(1, seed=11, out_dir=tmp_path, size=320, styles=["haussmann"])[0]
    rec = reconstruct(photo, rectified=True, repair=False, out_dir=tmp_path / "out")
    text = (tmp_path / "out" / "rules.gml").read_text()
    assert "ShapeGrammar.Tools.init" in text and "split" in text
    model = derive_gml(text)
    flat = [b for b in _leaf_boxes(model.root) if b[0] != "wall"]
    assert len(flat) == len([b for b in _leaf_boxes(rec.tree) if b[0] != "wall"])


def test_points_writes_rules_gml(tmp_path):
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "points"))
    from test_points_pipeline import facade_cloud

    from facadeforge.points.pipeline import points

    r = points(facade_cloud(spacing=0.06), out_dir=tmp_path / "out")
    text = (tmp_path / "out" / "facade_00" / "rules.gml").read_text()
    windows = [p for p in derive_gml(text).parts if p.label == "window"]
    assert len(windows) == sum(1 for leaf in r.facades[0].tree.leaves() if leaf.label == "window")
    assert np.isfinite(np.concatenate([p.mesh.vertices for p in windows])).all()


def test_parse_writes_rules_gml(tmp_path):
    from facadeforge.datasets.synthetic import generate
    from facadeforge.parsing.parse import parse

    photo = generate(1, seed=12, out_dir=tmp_path, size=320, styles=["haussmann"])[0]
    p = parse(photo, rectified=True, budget=60, model=False)
    p.save(tmp_path / "out")
    gml = tmp_path / "out" / "rules.gml"
    assert gml.exists(), p.report.get("notes")   # balconies' extruded scopes are quarter turns
    model = derive_gml(gml.read_text())
    assert sum(1 for q in model.parts if q.label == "window") == sum(
        1 for leaf in p.tree.leaves() if leaf.label == "window")
