"""Dotted names in declarations and references, as CityEngine compiles them: a rule, attribute
or function declared under a dotted name whose prefix is no import is the file's own; a dotted
rule whose prefix is an import redefines that import's rule; references reach either."""

import pytest

from facadeforge import derive, load_rules
from facadeforge.errors import RuleError

STRUCTURE = """attr height = 5
Lot --> extrude(height) comp(f) { side : Facade | top : Roof }
Facade --> Wall.
Roof --> Flat.
"""


def write(tmp_path, files):
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    return tmp_path / "main.cga"


def symbols(model):
    return sorted({p.symbol for p in model.parts})


@pytest.mark.parametrize("instancing", [True, False])
def test_a_rule_under_a_dotted_name_whose_prefix_is_no_import(tmp_path, instancing):
    # the production package's case: lot_street_front is no import of the file
    main = write(tmp_path, {"main.cga": """
Lot --> extrude(6) comp(f) { side : lot_street_front.Green_tile | top : Top. }
lot_street_front.Green_tile --> split(y) { 2 : lot_street_front.Band | ~1 : Rest. }*
lot_street_front.Band --> Band.
"""})
    (m,) = derive(load_rules(main), lot_size="10x8", keep_tree=not instancing)
    assert not m.warnings
    assert symbols(m) == ["Band", "Rest", "Top"]
    band = sum(p.mesh.area() for p in m.parts if p.symbol == "Band")
    assert band == pytest.approx(2 * 2 * 36)  # two 2 m bands around the 36 m perimeter


def test_an_imports_rule_redefined_and_a_local_dotted_rule_side_by_side(tmp_path):
    main = write(tmp_path, {"structure.cga": STRUCTURE, "main.cga": """
import st : "structure.cga"
attr height = 4
Lot --> st.Lot
st.Facade --> split(y) { 1 : Facade.Base | ~1 : Facade.Upper }
Facade.Base --> Plinth.
Facade.Upper --> Upper.
"""})
    (m,) = derive(load_rules(main), lot_size="10x8")
    assert not m.warnings
    # st's facades run the importer's rule, which calls the importer's own dotted rules;
    # st's roof is its own
    assert symbols(m) == ["Flat", "Plinth", "Upper"]


def test_a_dotted_rule_of_an_import_is_reached_through_its_alias(tmp_path):
    main = write(tmp_path, {
        "lib.cga": "Green.Tile --> color(0, 1, 0) GreenTile.\n",
        "main.cga": 'import lib : "lib.cga"\nLot --> lib.Green.Tile\n'})
    (m,) = derive(load_rules(main), lot_size="10x8")
    assert not m.warnings
    assert symbols(m) == ["GreenTile"]


def test_dotted_attributes_and_functions_are_the_files_own(tmp_path):
    main = write(tmp_path, {"main.cga": """
attr Report.enabled = true
attr float Mass.height = 9
Util.half(x) = x / 2
Lot --> extrude(Util.half(Mass.height)) Mass
Mass --> case Report.enabled : report("Volume", geometry.volume) M.
     else : M.
"""})
    rules = load_rules(main)
    (m,) = derive(rules, lot_size="10x8")
    assert m.reports["Volume"] == [pytest.approx(10 * 8 * 4.5)]
    (m,) = derive(rules, lot_size="10x8", attrs={"Report.enabled": False, "Mass.height": 4})
    assert "Volume" not in m.reports
    assert m.parts[0].mesh.bounds()[1][1] == pytest.approx(2)


def test_a_style_redefines_a_dotted_attribute(tmp_path):
    main = write(tmp_path, {"main.cga": """
attr Mass.height = 9
Lot --> extrude(Mass.height) M.
style Low
attr Mass.height = 3
"""})
    (m,) = derive(load_rules(main, style="Low"), lot_size="10x8")
    assert m.parts[0].mesh.bounds()[1][1] == pytest.approx(3)


@pytest.mark.parametrize("declaration, message", [
    ("attr st.height = 3", r"attribute 'st.height' redefines .* import st : .*\(height = …\)"),
    ("st.twice(x) = 2 * x", "function 'st.twice' redefines the function 'twice'"),
])
def test_an_imports_attribute_or_function_cannot_be_redefined(tmp_path, declaration, message):
    main = write(tmp_path, {"structure.cga": STRUCTURE + "twice(x) = x * 2\n",
                            "main.cga": f'import st : "structure.cga"\n{declaration}\n'
                                        "Lot --> st.Lot\n"})
    with pytest.raises(RuleError, match=message):
        load_rules(main)


def test_a_dotted_call_that_names_nothing_still_warns(tmp_path):
    main = write(tmp_path, {"main.cga": "Lot.Green --> G.\nLot --> Lot.Gren\n"})
    (m,) = derive(load_rules(main), lot_size="10x8")
    assert any("Lot.Gren" in w for w in m.warnings)
