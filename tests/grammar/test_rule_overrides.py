"""Rules of an imported file redefined by the importer: ``st.Facade --> …`` (CityEngine's help,
"Rule file import") and extension rules overridden in the import statement."""

import pytest

from facadeforge import derive, load_rules

STRUCTURE = """attr height = 5
Lot --> extrude(height) comp(f) { side : Facade | top : Roof. }
Facade --> color(1, 0, 0) Wall.
"""

MAIN = """import st : "structure.cga"
attr height = 10
Lot --> st.Lot
st.Facade --> split(y) { 2 : Band. | ~1 : Rest. }*
"""


def write(tmp_path, files):
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    return tmp_path


@pytest.mark.parametrize("instancing", [True, False])
def test_importer_redefines_a_rule_of_its_import(tmp_path, instancing):
    d = write(tmp_path, {"structure.cga": STRUCTURE, "main.cga": MAIN})
    m = derive(load_rules(d / "main.cga"), None, lot_size="10x8", keep_tree=not instancing)[0]
    assert not m.warnings
    symbols = {p.symbol for p in m.parts}
    # the facades run the importer's rule (split into bands), not structure.cga's red wall
    assert symbols == {"Band", "Rest", "Roof"}
    band = sum(p.mesh.area() for p in m.parts if p.symbol == "Band")
    # height 10 (main's attribute propagates): three 2 + ~1.33 m repeats, so 6 m of bands
    # around the 36 m perimeter
    assert band == pytest.approx(3 * 2 * 36)


def test_a_redefined_rule_that_the_import_only_calls(tmp_path):
    # structure.cga calls Facade without defining it: the importer's definition runs
    d = write(tmp_path, {"structure.cga": STRUCTURE.replace(
        "Facade --> color(1, 0, 0) Wall.\n", ""), "main.cga": MAIN})
    m = derive(load_rules(d / "main.cga"), None, lot_size="10x8")[0]
    assert {p.symbol for p in m.parts} == {"Band", "Rest", "Roof"}


def test_extension_rule_overridden_in_the_import_statement(tmp_path):
    d = write(tmp_path, {
        "rule.cga": "extension Roof(angle) --> roofHip(angle) Hip.\nInit --> Roof(30)\n",
        "main.cga": 'import rule : "rule.cga" ( Roof(angle) --> roofShed(angle) Shed. )\n'
                    "Lot --> rule.Init\n"})
    m = derive(load_rules(d / "main.cga"), None, lot_size="10x8")[0]
    assert {p.symbol for p in m.parts} == {"Shed"}
    plain = derive(load_rules(d / "rule.cga", start="Init"), None, lot_size="10x8")[0]
    assert {p.symbol for p in plain.parts} == {"Hip"}
