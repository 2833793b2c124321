"""Derivations run with Python's cyclic garbage collector paused and its recursion limit raised
(``interpreter.deriving``): they must make no cyclic garbage, and must leave the collector and
the limit as they found them."""

import gc
import sys

import pytest
from cga_helpers import run

from facadeforge.grammar.interpreter import PYTHON_RECURSION_LIMIT, deriving

RULES = """
attr h = 9
Lot --> extrude(h) comp(f){ side : Facade | top : Roof. }
Facade --> split(y){ ~3 : Floor }*
Floor --> split(x){ ~2 : Tile(rand(1)) }*
Tile(r) --> case r > 0.5 : s('0.8, '1, 0.2) center(x) i("builtin:cube") Win.
            else : color(f(scope.sx)) Wall.
f(x) = case x > 1 : "#808080" else : "#a0a0a0"
"""


@pytest.fixture
def saved_garbage():
    gc.collect()
    gc.set_debug(gc.DEBUG_SAVEALL)
    try:
        yield
    finally:
        gc.set_debug(0)
        gc.garbage.clear()


def test_a_derivation_leaves_no_cyclic_garbage(saved_garbage):
    run(RULES, lot="12x8")  # the parser and caches are built once (Lark's tables are cyclic)
    gc.set_debug(0)
    gc.garbage.clear()
    gc.collect()  # freed for good, before anything is saved again
    gc.set_debug(gc.DEBUG_SAVEALL)
    model = run(RULES, lot="12x8")
    assert len(model.parts) > 20
    leaves = list(model.root.leaves())
    assert all(c.parent is n for n in model.root.walk() for c in n.children)
    del model, leaves
    gc.collect()
    # the shape tree's parents are weak references: a dropped model is freed by reference
    # counting alone, however long the collector stays paused
    assert gc.garbage == [], {type(o).__name__ for o in gc.garbage}


def test_parents_survive_pickling_and_copies():
    import copy
    import pickle

    from facadeforge.model.shape import Shape

    model = run(RULES, lot="12x8")
    for root in (pickle.loads(pickle.dumps(model)).root, copy.deepcopy(model).root,
                 Shape.from_dict(model.root.to_dict())):
        assert root.parent is None and sum(1 for _ in root.walk()) > 20
        assert all(c.parent is n for n in root.walk() for c in n.children)
    shallow = copy.copy(model.root)  # shares the children, which stay the original's
    assert shallow.children[0].parent is model.root
    del shallow
    assert all(c.parent is n for n in model.root.walk() for c in n.children)


def test_the_collector_comes_back_as_it_was():
    assert gc.isenabled()
    run(RULES)
    assert gc.isenabled()
    gc.disable()
    try:
        run(RULES)
        assert not gc.isenabled()  # a caller that switched it off keeps it off
    finally:
        gc.enable()
    with deriving():
        with deriving():
            assert not gc.isenabled()
        assert not gc.isenabled()  # the outer derivation is still running
    assert gc.isenabled()


def test_the_recursion_limit_comes_back_as_it_was():
    before = sys.getrecursionlimit()
    assert before < PYTHON_RECURSION_LIMIT
    # a CGA function recursing 900 levels needs the raised limit (about ten frames a call)
    model = run("sum(n) = case n <= 0 : 0 else : 1 + sum(n - 1)\n"
                "Lot --> report(\"n\", sum(900)) X.")
    assert model.reports["n"] == [900.0]
    assert sys.getrecursionlimit() == before
    with deriving():
        with deriving():
            assert sys.getrecursionlimit() == PYTHON_RECURSION_LIMIT
        assert sys.getrecursionlimit() == PYTHON_RECURSION_LIMIT  # the outer one still runs
    assert sys.getrecursionlimit() == before
