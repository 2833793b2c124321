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
