"""Fuzzing the command line with mutated inputs (see the package docstring).

Short run (default ``pytest``): a fixed seed, a few dozen cases a target, in-process, the CLI's
derivation budget lowered.  Long run (``make fuzz``): cases until a time budget is spent, each in
a forked child bounded to 60 s and 3 GiB (one in ten as a fresh ``python -m facadeforge.cli``).
A failure is reduced (mutation steps, options, then lines and characters of text inputs) and
reported with the case that replays it and the reduced input.
"""

from __future__ import annotations

import os
import random
import shutil
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from . import mutate as M
from . import oracle
from .oracle import ddmin, run_forked, run_inprocess, run_subprocess
from .targets import TARGETS, Case

LONG = os.environ.get("FACADEFORGE_FUZZ", "short") == "long"
SEED = int(os.environ.get("FACADEFORGE_FUZZ_SEED", "20261201"))
BUDGET_S = float(os.environ.get("FACADEFORGE_FUZZ_SECONDS", "600"))
#: Cases a target in the short run (each a few tens of milliseconds in-process).
SHORT_CASES = {"cga": 60, "geojson": 40, "obj": 30, "npz": 30, "rpk": 20, "render": 25,
               "gml": 40}
#: Oracle calls spent reducing one failure (a run past the time bound: a few only).
REDUCE_CALLS = 400 if LONG else 60
REDUCE_HANG_CALLS = 8 if LONG else 0
if not LONG:
    oracle.HANG_SECONDS = 15   # 3x the derivation budget the short run passes


#: Failures already reported, each with a strict-xfail reproducer in test_known.py: a run tolerates
#: them (and prints them) so that ``make test`` stays green while they are open; remove an entry
#: when its reproducer starts passing.  (signature pattern, input pattern or None, reproducer)
KNOWN: list[tuple[str, str | None, str]] = []


def _known(target, case: Case, signature: str) -> str | None:
    import re

    for sig, pattern, where in KNOWN:
        if re.search(sig, signature):
            if pattern is None:
                return where
            data = target.build(case)
            text = data.decode("latin-1") if isinstance(data, bytes) else data
            if re.search(pattern, text):
                return where
    return None


def _limits() -> list[str]:
    """Lower derivation limits for the in-process run where the CLI takes them (the acceptance's
    own 60 s / 3 GiB bound the long run's children)."""
    import argparse

    from facadeforge.cli import build_parser

    sub = next(a for a in build_parser("derive")._actions
               if isinstance(a, argparse._SubParsersAction))
    text = sub.choices["derive"].format_help()
    limits = []
    if "--max-seconds" in text:
        limits += ["--max-seconds", "20" if LONG else "5"]
    if "--max-memory" in text:
        limits += ["--max-memory", "1536" if LONG else "400"]
    return limits


class Runner:
    def __init__(self, root: Path, mode: str):
        self.root, self.mode, self.n = root, mode, 0
        self.limits = _limits()

    def __call__(self, target, case: Case):
        self.n += 1
        work = self.root / f"case{self.n}"
        work.mkdir()
        try:
            forks = self.mode != "inprocess"
            argv, expected, stats = target.materialize(
                case, work, self.limits if self.mode == "inprocess" else [], forks)
            run = {"inprocess": run_inprocess, "forked": run_forked,
                   "subprocess": run_subprocess}[self.mode]
            return argv, run(argv, work, expected, stats)
        finally:
            shutil.rmtree(work, ignore_errors=True)


def _reduce(target, case: Case, runner: Runner, signature: str) -> Case:
    budget = [REDUCE_HANG_CALLS if signature.startswith("no end") else REDUCE_CALLS]
    if budget[0] <= 0:
        return case

    def fails(c: Case) -> bool:
        try:
            return runner(target, c)[1].signature == signature
        except Exception:  # noqa: BLE001 - a reduced case the target cannot build
            return False

    steps = ddmin(list(case.steps), lambda s: fails(Case(case.target, case.seed, s, case.options)),
                  budget)
    case = Case(case.target, case.seed, steps, dict(case.options))
    for key in list(case.options):
        if budget[0] <= 0:
            break
        trial = dict(case.options)
        if key in target.defaults:
            trial[key] = target.defaults[key]
        else:
            trial.pop(key)
        if trial != case.options:
            budget[0] -= 1
            if fails(Case(case.target, case.seed, case.steps, trial)):
                case.options = trial
    if target.text:
        text = target.build(case)
        lines = text.splitlines(keepends=True)
        lines = ddmin(lines, lambda ls: fails(Case(case.target, case.seed, [], case.options,
                                                   "".join(ls))), budget)
        chars = list("".join(lines))
        if len(chars) <= 4000:
            chars = ddmin(chars, lambda cs: fails(Case(case.target, case.seed, [], case.options,
                                                       "".join(cs))), budget)
        literal = "".join(chars)
        if fails(Case(case.target, case.seed, [], case.options, literal)):
            case = Case(case.target, case.seed, [], case.options, literal)
    return case


def _report(target, failures: dict, runner: Runner, keep: Path) -> str:
    """Each failure reduced, with the case that replays it (``TARGETS[name].materialize(case,
    folder)``), its command and input, and the input saved under ``keep``."""
    out = []
    keep.mkdir(exist_ok=True)
    for n, (sig, (case, argv, outcome)) in enumerate(failures.items()):
        small = _reduce(target, case, runner, sig)
        argv2, outcome2 = (argv, outcome) if small is case else runner(target, small)
        shown = target.build(small)
        saved = keep / f"{target.name}-{n}.input"
        saved.write_bytes(shown if isinstance(shown, bytes)
                          else shown.encode("utf-8", "surrogateescape"))
        if isinstance(shown, bytes):
            shown = shown[:600]
        out.append(f"\n[{target.name}] {sig}\n  case:    {case!r}\n  reduced: {small!r}\n"
                   f"  saved:   {saved}\n"
                   f"  command: facadeforge {' '.join(argv2[:1] + [Path(a).name if '/' in a else a for a in argv2[1:]])}\n"
                   f"  input:   {str(shown)[:1500]!r}\n  outcome: {outcome2.describe()}")
    return "\n".join(out)


@pytest.fixture(scope="module")
def seeds_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fuzz-seeds")
    TARGETS["render"].prepare(folder)
    return folder


@pytest.mark.parametrize("name", sorted(TARGETS))
def test_fuzz(name, tmp_path, seeds_folder):
    target = TARGETS[name]
    rng = random.Random(f"{SEED}:{name}")
    inproc = Runner(tmp_path, "forked" if LONG else "inprocess")
    fresh = Runner(tmp_path, "subprocess")
    deadline = time.monotonic() + BUDGET_S / len(TARGETS)
    failures: dict[str, tuple] = {}
    exits: dict[int, int] = {}
    known: dict[str, tuple] = {}
    i = 0
    while (time.monotonic() < deadline) if LONG else (i < SHORT_CASES[name]):
        case = target.generate(rng)
        runner = fresh if LONG and i % 10 == 9 else inproc
        argv, outcome = runner(target, case)
        exits[outcome.rc] = exits.get(outcome.rc, 0) + 1
        sig = outcome.signature
        if sig and _known(target, case, sig):
            known.setdefault(sig, (case, _known(target, case, sig)))
        elif sig and sig not in failures:
            failures[sig] = (case, argv, outcome)
        i += 1
    print(f"fuzz {name}: {i} cases, exits {dict(sorted(exits.items()))}, "
          f"{len(failures)} distinct failure(s)")
    for sig, (case, where) in known.items():
        print(f"  known ({where}): {sig}\n    {case!r}"[:1500])
    if failures:
        pytest.fail(f"{len(failures)} distinct failure(s) in {i} {name} cases:"
                    + _report(target, failures, inproc, tmp_path / "failures"), pytrace=False)


# -- CGA from tokens, shrunk by Hypothesis --------------------------------------------------

WORDS = [w for w in M.CGA_TOKENS if len(w) < 60]


@settings(max_examples=300 if LONG else 40, deadline=None, database=None, derandomize=not LONG,
          suppress_health_check=list(HealthCheck))
@given(body=st.lists(st.sampled_from(WORDS), max_size=12),
       head=st.sampled_from(["Lot -->", "Lot --> extrude(3)", "Lot --> extrude(3) comp(f) { side :",
                             "attr a =", "f(x) =", ""]),
       output=st.sampled_from(["glb", "obj", "city.json", "svg"]))
def test_token_soup(tmp_path_factory, head, body, output):
    work = tmp_path_factory.mktemp("soup")
    try:
        rules = work / "r.cga"
        rules.write_text(f"{head} {' '.join(body)}\nA --> X.\nB --> X.\nX --> color(1, 0, 0)\n"
                         "Rec --> A\n", encoding="utf-8")
        out = work / f"o.{output}"
        outcome = run_inprocess(["derive", str(rules), "--lot", "8x6", "-o", str(out),
                                 "--workers", "1", *_limits()], work, [out])
        assert outcome.signature is None, (f"{rules.read_text()!r}: {outcome.describe()}")
    finally:
        shutil.rmtree(work, ignore_errors=True)
