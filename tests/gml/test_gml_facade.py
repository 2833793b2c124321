"""Fig. 16 of Hohmann et al. 2009: the Jakoministrasse facade program with its domain words."""

from __future__ import annotations

from collections import Counter

import numpy as np

from facadeforge.exchange import export
from facadeforge.gml import EXAMPLES, derive_gml

FLOOR_RIGHT = "2 :wall-colour 0 0.5 Floor"
FLOOR_CENTER = "1 :wall-colour 0 0 Floor"


def windows_per_floor(model) -> Counter:
    """Glass panes by floor (their lower edge, rounded)."""
    return Counter(round(float(p.mesh.bounds()[0][1]), 1) for p in model.parts
                   if p.symbol == "Glass")


def test_fig16_derives_the_facade():
    m = derive_gml(EXAMPLES / "fig16_facade.gml")
    assert not m.warnings
    labels = Counter(p.label for p in m.parts)
    assert labels["cornice"] == 3 and labels["sill"] == 10 and labels["door"] == 1
    assert labels["shop"] == 4
    # two upper floors of 2 + 1 + 2 windows
    assert windows_per_floor(m) == {3.5: 5, 6.5: 5}
    assert np.allclose(m.stats()["bbox"], [[0, 0, 0], [11.4, 9, 0.15]])
    # windows are 1.2 m wide (the frame 0.06 on each side of the glass)
    glass = [p for p in m.parts if p.symbol == "Glass"]
    assert all(np.isclose(np.ptp(p.mesh.vertices[:, 0]), 1.2 - 0.12) for p in glass)
    assert {c.symbol for c in m.root.children} == {"LeftFacade", "CenterFacade", "RightFacade"}


def test_green_frame_numbers_change_the_windows_per_floor(tmp_path):
    text = (EXAMPLES / "fig16_facade.gml").read_text()
    assert text.count(FLOOR_RIGHT) == 2 and text.count(FLOOR_CENTER) == 2
    more = text.replace(FLOOR_RIGHT, "3 :wall-colour 0 0.5 Floor", 1)  # the right side's 1st floor
    more = more.replace(FLOOR_CENTER, "2 :wall-colour 0 0 Floor")  # both centre floors
    m = derive_gml(more)
    assert windows_per_floor(m) == {3.5: 7, 6.5: 6}
    assert export(m, tmp_path / "facade.city.json")
