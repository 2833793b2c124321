"""``facadeforge edit`` and ``facadeforge view`` as a user runs them: the URL with the token on
the first line, bad input in one line with exit status 2."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import urllib.request

import pytest

from facadeforge.cli import main


@pytest.mark.parametrize("argv, message", [
    (["edit", "{tmp}/nowhere"], "is not a folder"),
    (["edit", "{tmp}"], "holds no shape_tree.json"),
    (["view", "{tmp}/nothing.glb"], "is not a file"),
    (["edit", "{rec}", "--facade", "facade_09"], "--facade facade_09 is not a facade"),
    (["edit", "{rec}", "--port", "70000", "--no-browser"], "--port 70000"),
])
def test_bad_input_is_one_line_and_exit_2(argv, message, tmp_path, reconstructed, capsys):
    argv = [a.format(tmp=tmp_path, rec=reconstructed) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err


def test_edit_prints_the_token_url_first_and_serves_until_interrupted(outdir):
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    p = subprocess.Popen([sys.executable, "-m", "facadeforge.cli", "edit", str(outdir),
                          "--no-browser"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, env=env)
    try:
        url = p.stdout.readline().strip()
        assert url.startswith("http://127.0.0.1:") and "?token=" in url
        with urllib.request.urlopen(url.replace("/?", "/api/state?"), timeout=30) as r:
            assert json.loads(r.read())["state"]["version"] == 0
    finally:
        p.send_signal(signal.SIGINT)
        p.wait(timeout=30)
    assert p.returncode in (0, 130)
