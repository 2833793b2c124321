"""Fixtures of the editor tests: an OUTDIR of `reconstruct` on a synthetic facade that is not
the demo's (another seed and style), copied fresh for each test that writes."""

from __future__ import annotations

import json
import shutil

import pytest

from facadeforge.datasets.synthetic import generate
from facadeforge.reconstruction import reconstruct


@pytest.fixture(scope="session")
def reconstructed(tmp_path_factory):
    d = tmp_path_factory.mktemp("editor_synth")
    photo = generate(1, seed=29, out_dir=d / "photo", size=560, styles=["residential"])[0]
    meta = json.loads(photo.with_suffix(".meta.json").read_text())
    out = d / "rec"
    reconstruct(photo, rectified=True, width_m=meta["facade_size_m"][0], out_dir=out)
    return out


@pytest.fixture
def outdir(reconstructed, tmp_path):
    """A private copy of the OUTDIR (the marker included)."""
    dest = tmp_path / "rec"
    shutil.copytree(reconstructed, dest)
    return dest
