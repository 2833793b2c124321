"""Rule packages leave no unpacked folder behind: not on SIGTERM, not after a SIGKILL."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from facadeforge.grammar.rulepackage import open_rpk
from facadeforge.scratch import owner_tag

RULES = "@StartRule\nLot --> extrude(3)\n"


def make_rpk(tmp_path: Path) -> Path:
    import py7zr

    src = tmp_path / "src" / "rules"
    src.mkdir(parents=True)
    (src / "main.cga").write_text(RULES)
    rpk = tmp_path / "pkg.rpk"
    with py7zr.SevenZipFile(rpk, "w") as z:
        z.write(src / "main.cga", arcname="rules/main.cga")
    return rpk


def leftovers(tmp: Path) -> list[str]:
    return sorted(p.name for p in tmp.iterdir() if p.name.startswith("facadeforge-rpk-"))


def test_sigterm_while_unpacking_removes_the_folder(tmp_path):
    """The reproducer: SIGTERM during a large unpack left its temporary folder (485 MB)."""
    rpk = make_rpk(tmp_path)
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    # the unpacker, stopped by SIGTERM after it wrote a file into its folder
    code = ("import os, signal, py7zr\n"
            "from facadeforge.grammar.rulepackage import open_rpk\n"
            "def extractall(self, path=None, **kw):\n"
            "    (path / 'big.bin').write_bytes(b'0' * 1000)\n"
            "    os.kill(os.getpid(), signal.SIGTERM)\n"
            "    while True: pass\n"
            "py7zr.SevenZipFile.extractall = extractall\n"
            f"open_rpk({str(rpk)!r})\n")
    res = subprocess.run([sys.executable, "-c", code], env={**os.environ, "TMPDIR": str(tmp)},
                         timeout=120, check=False)
    assert res.returncode == 143
    assert leftovers(tmp) == []


def test_a_killed_runs_folder_is_removed_by_the_next(tmp_path, monkeypatch):
    import tempfile

    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    host = owner_tag().split("-")[0]
    stale = tmp / f"facadeforge-rpk-{host}-{dead.pid}-abc"
    (stale / "rules").mkdir(parents=True)
    (stale / "rules" / "main.cga").write_text(RULES)
    package = open_rpk(make_rpk(tmp_path))
    assert package.main.read_text() == RULES
    assert leftovers(tmp) == [package.root.name]        # the stale one is gone
    package.cleanup()
    assert leftovers(tmp) == []


def test_derive_of_a_package_to_obj_copies_its_textures(tmp_path, capsys):
    """``derive PKG.rpk -o x.obj``: the package's textures are copied as the OBJ is written,
    while the package is still unpacked (they were copied at the end, after the derivation had
    removed its folder: 'No such file or directory …/assets/….jpg')."""
    import numpy as np
    import py7zr
    from PIL import Image

    from facadeforge.cli import main

    src = tmp_path / "src"
    (src / "rules").mkdir(parents=True)
    (src / "assets").mkdir()
    (src / "rules" / "main.cga").write_text(
        '@StartRule\nLot --> extrude(6) comp(f) { side : Wall | top : Roof. }\n'
        'Wall --> setupProjection(0, scope.xy, 3, 3) projectUV(0) texture("brick.png") Wall.\n')
    Image.fromarray(np.full((8, 8, 3), 120, np.uint8)).save(src / "assets" / "brick.png")
    rpk = tmp_path / "pkg.rpk"
    with py7zr.SevenZipFile(rpk, "w") as z:
        z.write(src / "rules" / "main.cga", arcname="rules/main.cga")
        z.write(src / "assets" / "brick.png", arcname="assets/brick.png")
    out = tmp_path / "out" / "city.obj"
    out.parent.mkdir()
    assert main(["derive", str(rpk), "--lot", "10x8", "-o", str(out)]) == 0, capsys.readouterr()
    assert (out.parent / "textures" / "brick.png").is_file()
    assert "map_Kd textures/brick.png" in out.with_suffix(".mtl").read_text()
