"""README.md against the live command line: short, set-up commands first, every subcommand of
``facadeforge --help`` shown, the docs site linked (issue 32)."""

import re
from pathlib import Path

import pytest

from facadeforge.cli import main

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
MAX_LINES = 350


def help_text(capsys) -> str:
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    return capsys.readouterr().out


def subcommands(help_out: str) -> list[str]:
    """The subcommands ``facadeforge --help`` lists (its ``{derive,render,…}`` choices)."""
    m = re.search(r"\{([a-z0-9,-]+)\}", help_out)
    assert m, "facadeforge --help lists no {subcommand,…} choices"
    return m.group(1).split(",")


def test_readme_is_short():
    n = len(README.read_text(encoding="utf-8").splitlines())
    assert n <= MAX_LINES, f"README.md has {n} lines; at most {MAX_LINES} (move detail to docs/)"


def test_set_up_commands_near_the_top():
    head = "\n".join(README.read_text(encoding="utf-8").splitlines()[:40])
    for command in ("make demo", "make test"):
        assert command in head, f"`{command}` is not in README.md's first 40 lines"


def test_every_subcommand_is_in_the_readme(capsys):
    names = subcommands(help_text(capsys))
    assert {"derive", "reconstruct", "parse", "points", "repair", "demo"} <= set(names)
    text = README.read_text(encoding="utf-8")
    missing = [n for n in names if not re.search(rf"facadeforge {re.escape(n)} \S", text)]
    assert not missing, ("README.md shows no `facadeforge NAME …` line for: "
                         + ", ".join(missing))


def test_readme_links_the_docs_site():
    text = README.read_text(encoding="utf-8")
    assert "make docs" in text
    for link in re.findall(r"\]\(((?:docs|benchmarks|src|examples)/[^)#\s]*)", text):
        assert (ROOT / link).exists(), f"README.md links {link}, which does not exist"


def test_top_level_help_has_examples(capsys):
    out = help_text(capsys)
    assert "examples:" in out and "facadeforge derive " in out
    assert "--version" in out
