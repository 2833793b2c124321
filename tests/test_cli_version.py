"""``facadeforge --version``: the installed distribution's version, from package metadata."""

from importlib.metadata import version

import pytest

from facadeforge.cli import main


def test_version(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    out = capsys.readouterr().out.strip()
    assert out == f"facadeforge {version('facadeforge')}"
    assert out.split()[1].count(".") >= 2   # X.Y.Z


def test_every_subcommand_help_shows_an_example():
    import re
    import subprocess
    import sys
    from pathlib import Path

    cli = str(Path(sys.executable).with_name("facadeforge"))
    top = subprocess.run([cli, "--help"], capture_output=True, text=True).stdout
    names = sorted(set(re.findall(r"^    ([a-z][a-z-]+)", top, re.M)))
    assert len(names) >= 10
    missing = [n for n in names if "examples:\n  facadeforge " + n not in
               subprocess.run([cli, n, "--help"], capture_output=True, text=True).stdout]
    assert not missing, f"no examples in --help of {missing}"
