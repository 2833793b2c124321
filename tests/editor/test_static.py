"""The pages work offline: three.js is bundled in the package (``make web`` from
``web/package-lock.json``), and nothing is fetched from another origin."""

from __future__ import annotations

import json
import re
from pathlib import Path

from facadeforge.editor.server import STATIC

ROOT = Path(__file__).resolve().parents[2]


def test_the_bundle_is_the_locked_three_version():
    lock = json.loads((ROOT / "web" / "package-lock.json").read_text())
    three = lock["packages"]["node_modules/three"]["version"]
    head = (STATIC / "vendor" / "three.bundle.js").read_text(encoding="utf-8")[:200]
    assert head.startswith(f"/* three.js {three} (MIT)"), head[:80]


def test_pages_load_nothing_from_another_origin():
    for f in [*STATIC.glob("*.html"), *STATIC.glob("*.js"), *STATIC.glob("*.css")]:
        text = f.read_text(encoding="utf-8")
        assert not re.search(r"""(src|href)=["']https?://""", text), f.name
        assert not re.search(r"""from\s+['"]https?://""", text), f.name
        assert "@import" not in text, f.name


def test_every_module_import_and_page_asset_exists():
    for f in STATIC.glob("*.js"):
        for spec in re.findall(r"""from\s+['"](\.[^'"]+)['"]""", f.read_text()):
            assert (f.parent / spec).resolve().is_file(), (f.name, spec)
    for f in STATIC.glob("*.html"):
        for ref in re.findall(r"""(?:src|href)=["']/static/([^"']+)["']""", f.read_text()):
            assert (STATIC / ref).is_file(), (f.name, ref)
