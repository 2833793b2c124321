"""Models cross process boundaries (derive's worker pool, batch): nothing of a face is lost."""

import pickle

from facadeforge import derive, load_rules

RULES = """Lot --> extrude(6) comp(f){ side : F | top : T. }
F --> tag("wall") split(x){ ~2 : Tile }*
Tile --> setback(0.4){ all : Frame. | remainder : NIL }
"""


def test_pickled_model_keeps_faces_with_holes_and_tags():
    (m,) = derive(load_rules(RULES), lot_size="12x8")
    back = pickle.loads(pickle.dumps(m))
    assert len(back.parts) == len(m.parts)
    for a, b in zip(m.parts, back.parts):
        assert a.mesh.n_faces == b.mesh.n_faces
        assert (a.mesh.face_data is None) == (b.mesh.face_data is None)
        if a.mesh.face_data is not None:
            assert set(a.mesh.face_data) == set(b.mesh.face_data)
            for k in a.mesh.face_data:
                assert [x is None for x in a.mesh.face_data[k]] == \
                    [x is None for x in b.mesh.face_data[k]]
    assert any(p.mesh.face_data for p in m.parts)  # the test has columns to lose
