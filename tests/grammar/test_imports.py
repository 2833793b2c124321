"""Import statements as CityEngine's "import" keyword defines them: each import is its own
instance of the file, attributes propagate from the importer unless protected, the import
statement may redefine attributes and list the styles it imports."""

import pytest

from facadeforge import derive, load_rules
from facadeforge.errors import RuleError
from facadeforge.grammar import module as module_mod

IMP = """attr height = 10
attr width = 3
const depth = 2
Lot --> extrude(height) report("h", height) report("w", width)
style mystyle
attr height = 20
"""


def write(tmp_path, files):
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    return tmp_path / "main.cga"


def reports(tmp_path, main, style=None, **kw):
    rules = load_rules(write(tmp_path, {"imp.cga": IMP, "main.cga": main}), style=style)
    return derive(rules, None, lot_size="10x10", **kw)[0].reports


def test_one_file_imported_twice_is_two_instances(tmp_path):
    r = reports(tmp_path, 'import a : "imp.cga" (height = 5)\n'
                          'import b : "imp.cga" (height = 7)\n'
                          'Lot --> split(x) { 5 : a.Lot | 5 : b.Lot }\n')
    assert r["h"] == [5, 7]


def test_a_rule_redefined_for_one_import_only(tmp_path):
    r = reports(tmp_path, 'import a : "imp.cga"\nimport b : "imp.cga"\n'
                          'a.Lot --> report("a", 1)\n'
                          'Lot --> split(x) { 5 : a.Lot | 5 : b.Lot }\n')
    assert r == {"a": [1], "h": [10], "w": [3]}


def test_attribute_override_of_the_second_instance_from_outside(tmp_path):
    r = reports(tmp_path, 'import a : "imp.cga"\nimport b : "imp.cga"\n'
                          'Lot --> split(x) { 5 : a.Lot | 5 : b.Lot }\n',
                attrs={"b.height": "4"})
    assert r["h"] == [10, 4]


def test_propagation_and_protection(tmp_path):
    main = 'attr height = 30\nattr width = 9\nLot --> imp.Lot\n'
    # an importer's attribute gives its value to the same-named attribute of the import
    assert reports(tmp_path, 'import imp : "imp.cga"\n' + main) == {"h": [30], "w": [9]}
    # (height) protects height; () protects every attribute
    assert reports(tmp_path, 'import imp : "imp.cga" (height)\n' + main) == {"h": [10], "w": [9]}
    assert reports(tmp_path, 'import imp : "imp.cga" ()\n' + main) == {"h": [10], "w": [3]}
    # protection and redefinition combine
    assert reports(tmp_path, 'import imp : "imp.cga" (height, width = height / 3)\n'
                   + main) == {"h": [10], "w": [10]}


def test_set_in_the_importer_reaches_the_propagated_attribute(tmp_path):
    r = reports(tmp_path, 'import imp : "imp.cga"\nattr height = 30\n'
                          'Lot --> split(x) { 5 : set(height, 6) imp.Lot | 5 : imp.Lot }\n')
    assert r["h"] == [6, 30]


def test_propagation_runs_along_each_import(tmp_path):
    files = {"imp.cga": IMP,
             "mid.cga": 'import imp : "imp.cga"\nattr height = 12\nLot --> imp.Lot\n',
             "main.cga": 'import mid : "mid.cga"\nattr height = 40\nattr width = 8\n'
                         'Lot --> mid.Lot\n'}
    m = derive(load_rules(write(tmp_path, files)), None, lot_size="10x10")[0]
    # main's height reaches imp through mid's; main's width does not (mid has none)
    assert m.reports == {"h": [40], "w": [3]}


def test_import_with_a_style_list(tmp_path):
    assert reports(tmp_path, 'import imp (mystyle) : "imp.cga"\nLot --> imp.Lot\n')["h"] == [20]
    with pytest.raises(RuleError, match="style 'other' is not defined in imp.cga"):
        reports(tmp_path, 'import imp (other) : "imp.cga"\nLot --> imp.Lot\n')


@pytest.mark.parametrize("statement, message", [
    ('(heigth = 5)', "redefines 'heigth', not an attribute of it.*did you mean 'height'"),
    ('(widht)', "protects 'widht', not an attribute.*did you mean 'width'"),
    ('(depth = 1)', "'depth', a constant, not an attribute"),
    ('( Lto --> X. )', "redefines rule 'Lto', which imp.cga does not define.*'Lot'"),
])
def test_import_statement_naming_what_the_file_lacks(tmp_path, statement, message):
    with pytest.raises(RuleError, match=message):
        reports(tmp_path, f'import imp : "imp.cga" {statement}\nLot --> imp.Lot\n')


def test_import_cycle_is_an_error(tmp_path):
    files = {"a.cga": 'import b : "b.cga"\nA --> b.B\n',
             "main.cga": 'import a : "a.cga"\nLot --> a.A\n',
             "b.cga": 'import a : "a.cga"\nB --> X.\n'}
    with pytest.raises(RuleError, match=r"import cycle: a.cga → b.cga → a.cga"):
        load_rules(write(tmp_path, files))


def test_a_file_is_parsed_once_however_often_imported(tmp_path, monkeypatch):
    calls = []
    real = module_mod.parse_rules
    monkeypatch.setattr(module_mod, "parse_rules",
                        lambda text, path: calls.append(path) or real(text, path))
    files = {"imp.cga": IMP,
             "main.cga": "".join(f'import i{k} : "imp.cga"\n' for k in range(5))
             + "Lot --> i0.Lot\n"}
    load_rules(write(tmp_path, files))
    assert sorted(p.rsplit("/", 1)[-1] for p in calls) == ["imp.cga", "main.cga"]


def test_anonymous_import_brings_its_own_imports(tmp_path):
    files = {"imp.cga": IMP,
             "lib.cga": 'import imp : "imp.cga"\nBuilding --> imp.Lot\n',
             "main.cga": 'import "lib.cga"\nLot --> Building\n'}
    m = derive(load_rules(write(tmp_path, files)), None, lot_size="10x10")[0]
    assert m.reports["h"] == [10]


@pytest.mark.parametrize("main, message", [
    ('import x : "imp.cga" (height = 5)\nimport x : "imp.cga"\nLot --> x.Lot\n',
     "import id 'x' is used twice"),
    ('import imp : "imp.cga" (Lot(a) --> X.)\nLot --> imp.Lot\n',
     "redefines rule 'Lot' with 1 parameters; imp.cga defines it with 0"),
    ('import imp : "imp.cga" (height = undefinedName)\nLot --> imp.Lot\n',
     r"main.cga:1:\d+: unknown attribute or variable 'undefinedName'"),
    ('import imp : "imp.cga" (Lot --> Nope(2))\nLot --> imp.Lot\n', None),
])
def test_import_statements_are_checked_when_the_rules_load(tmp_path, main, message):
    if message is None:  # a rule override's body may call rules that do not exist: leaves
        assert reports(tmp_path, main) == {}
        return
    with pytest.raises(RuleError, match=message):
        reports(tmp_path, main)


def test_propagation_through_an_anonymous_import(tmp_path):
    files = {"imp.cga": IMP,
             "lib.cga": 'import imp : "imp.cga"\nBuilding --> imp.Lot\n',
             "main.cga": 'import "lib.cga"\nattr height = 9\nLot --> Building\n'}
    m = derive(load_rules(write(tmp_path, files)), None, lot_size="10x10")[0]
    assert m.reports["h"] == [9]


def test_the_chosen_style_reaches_imports_that_have_it(tmp_path):
    main = 'import imp : "imp.cga"\nLot --> imp.Lot\nstyle mystyle\n'
    assert reports(tmp_path, main)["h"] == [10]
    assert reports(tmp_path, main, style="mystyle")["h"] == [20]
    # an import statement listing styles lets only those in
    listed = 'import imp (Default) : "imp.cga"\nLot --> imp.Lot\nstyle mystyle\n'
    assert reports(tmp_path, listed, style="mystyle")["h"] == [10]


def test_an_anonymous_import_uses_its_importers_names(tmp_path):
    files = {"lib.cga": "Mass --> extrude(height) X.\n",
             "main.cga": 'import "lib.cga"\nattr height = 7\nLot --> Mass\n'}
    m = derive(load_rules(write(tmp_path, files)), None, lot_size="4x4")[0]
    assert not m.warnings and m.stats()["bbox"][1][1] == 7


@pytest.mark.parametrize("instancing", [True, False])
def test_extension_forwarding_reuses_the_default(tmp_path, instancing):
    # CityEngine 2024.0: ( Ext -> MyExt ) sends the file's calls of Ext to MyExt, which can
    # call imp.Ext for the file's own version without recursing forever
    files = {"imp.cga": 'extension Ext --> report("ext", 1) X.\nLot --> split(x){ 2 : Ext }*\n',
             "main.cga": 'import imp : "imp.cga" ( Ext -> MyExt )\n'
                         'extension MyExt --> report("my", 1) imp.Ext\n'
                         '@StartRule\nLot --> imp.Lot\n'}
    m = derive(load_rules(write(tmp_path, files)), None, lot_size="4x4",
               keep_tree=not instancing)[0]
    assert m.reports == {"my": [1, 1], "ext": [1, 1]}


@pytest.mark.parametrize("statement, message", [
    ("( Nope -> MyExt )", "sends rule 'Nope' on, which imp.cga does not define"),
    ("( Ext -> Nope )", "sends rule 'Ext' to 'Nope', which main.cga does not define"),
])
def test_extension_forwarding_names_are_checked(tmp_path, statement, message):
    files = {"imp.cga": "extension Ext --> X.\nLot --> Ext\n",
             "main.cga": f'import imp : "imp.cga" {statement}\nMyExt --> X.\nLot --> imp.Lot\n'}
    with pytest.raises(RuleError, match=message):
        load_rules(write(tmp_path, files))
