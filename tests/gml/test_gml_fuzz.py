"""Mutated GML programs: only the package's typed errors or a model, never another exception
and never a hang (the limits bound every run)."""

from __future__ import annotations

import time

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from facadeforge.gml import EXAMPLES, GmlError, Limits, derive_gml
from facadeforge.model.model import Model

SMALL = Limits(max_operations=20_000, max_seconds=1.0, max_stack=5_000, max_call_depth=200,
               max_array=5_000, max_cells=100_000, max_shapes=5_000, max_planes=64)

EXTRA = """
/f { dup 1 le { pop 1 } { dup 1 sub f mul } ifelse } def 5 f pop
1.2 !ww :ww 2 mul pop dict begin /a [ 1 2 3 ] def a 1 get pop end
ShapeGrammar.Tools.init scope (4,3,1) scale 3 /X repeat { [ -1 0.2 ] /Y split-r terminal-box
terminal-void } repeat scope 0.5 /X subdivide { terminal-box } repeat
[ (0,0,0) (0,0,1) (0,1,0) cp-plane (1,0,0) (0,1,0) (0,0,1) cp-plane ] pop
0 1 1 3 { add } for pop [ 1 2 ] { pop } forall 0 { 1 add dup 3 eq { exit } if } loop pop
(1,2,3) getx (1,0,0) (0,1,0) cross normalize pop pop finish
"""


def corpus() -> list[list[str]]:
    texts = [(EXAMPLES / name).read_text()
             for name in ("fig13.gml", "fig14_arch.gml", "fig16_facade.gml")] + [EXTRA]
    out = []
    for t in texts:
        words = []
        for line in t.splitlines():
            words.extend(line.split("%", 1)[0].split())
        out.append(words)
    return out


CORPUS = corpus()
VOCAB = sorted({w for words in CORPUS for w in words} | {"[", "]", "{", "}", "(", ")", "exit",
                                                         "1e308", "1000000000", "-1", "0", "loop",
                                                         "exec", "repeat", "for"})

mutation = st.tuples(st.sampled_from(["delete", "duplicate", "swap", "insert"]),
                     st.integers(0, 10_000), st.integers(0, 10_000), st.sampled_from(VOCAB))


def mutate(words: list[str], ops) -> str:
    w = list(words)
    for kind, i, j, token in ops:
        if not w:
            w.append(token)
            continue
        i, j = i % len(w), j % len(w)
        if kind == "delete":
            del w[i]
        elif kind == "duplicate":
            w.insert(i, w[i])
        elif kind == "swap":
            w[i], w[j] = w[j], w[i]
        else:
            w.insert(i, token)
    # a few words per line, so that positions have lines and columns
    return "\n".join(" ".join(w[k:k + 7]) for k in range(0, len(w), 7))


def check(text: str) -> None:
    t0 = time.monotonic()
    try:
        result = derive_gml(text + "\n", limits=SMALL)
    except GmlError as e:
        assert str(e).splitlines()[0]  # a message, with path:line:column first
    else:
        assert isinstance(result, Model)
    assert time.monotonic() - t0 < 5.0


@settings(max_examples=150, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(range(len(CORPUS))), st.lists(mutation, min_size=1, max_size=4))
def test_mutated_programs(which, ops):
    check(mutate(CORPUS[which], ops))


@settings(max_examples=100, deadline=None, derandomize=True)
@given(st.text(alphabet=st.sampled_from(list("[]{}()/!:%,.-+eE0123456789 \nabXYZ\u2014")),
               max_size=80))
def test_random_text(text):
    check(text)
