"""The parametric element library of Müller et al. 2007, §4 (geometry and front renders)."""

import numpy as np
import pytest

from facadeforge.elements import (
    LABEL_INDEX,
    element_library,
    element_model,
    element_spec,
    render_front,
)
from facadeforge.errors import InputError
from facadeforge.model.labels import Labels

LIB = element_library()
CANONICAL = {label.value for label in Labels}


def test_library_has_many_unique_variants():
    names = [s.name for s in LIB]
    assert len(names) >= 30
    assert len(set(names)) == len(names)
    kinds = {s.kind for s in LIB}
    assert {"window", "door", "balcony", "sill", "cornice", "shop"} <= kinds
    assert all(s.mount in ("recess", "protrude") for s in LIB)
    assert all(s.default_depth > 0 for s in LIB)


def test_label_index_is_the_canonical_order():
    """The library keeps its own copy of the canonical index (cheap import); it must equal the
    two other definitions of it."""
    from facadeforge.datasets import CANONICAL_INDEX
    from facadeforge.exchange.raster import LABEL_INDEX as RASTER_INDEX

    assert LABEL_INDEX == {label.value: i for i, label in enumerate(Labels)}
    assert LABEL_INDEX == RASTER_INDEX == dict(CANONICAL_INDEX)


@pytest.mark.parametrize("spec", LIB, ids=lambda s: s.name)
def test_mesh_in_unit_box_labelled_and_finite(spec):
    model = element_model(spec)
    assert model.name == spec.name and model.parts
    for part in model.parts:
        v = part.mesh.vertices
        assert part.mesh.n_faces > 0
        assert np.isfinite(v).all()
        assert v.min() >= -1e-9 and v.max() <= 1 + 1e-9, part.symbol
        assert part.label in CANONICAL
        assert part.material.name
    v = model.mesh().vertices
    assert np.allclose(v.min(axis=0)[:2], 0) and np.allclose(v.max(axis=0), 1)
    assert {p.label for p in model.parts} & {spec.kind}


@pytest.mark.parametrize("spec", [s for s in LIB if s.mount == "recess"], ids=lambda s: s.name)
def test_recess_elements_have_a_wall_reveal(spec):
    model = element_model(spec)
    reveal = [p for p in model.parts if p.symbol.endswith(".reveal")]
    assert len(reveal) == 1 and reveal[0].label == "wall"
    mesh = reveal[0].mesh
    n = mesh.face_normals()
    assert np.allclose(n[:, 2], 0)  # side walls of the opening
    assert np.isclose(mesh.vertices[:, 2].max(), 1.0)  # reaching the facade plane
    # inward facing: normals point towards the opening's centre
    centre = np.array([0.5, 0.5])
    mid = np.array([p.mean(axis=0)[:2] for p in mesh.polygons()])
    assert (np.einsum("ij,ij->i", n[:, :2], centre - mid) > 0).mean() > 0.9
    # the glass / leaf faces the viewer and lies behind the facade plane
    inner = [p for p in model.parts if p.symbol.split(".")[-1] in ("glass", "frame", "leaf")]
    assert inner and all(p.mesh.vertices[:, 2].max() < 0.5 for p in inner)


def test_solid_parts_are_outward_wound():
    for name in ("window_mullion_2x2", "window_arched_round", "door_double", "balcony_bars",
                 "cornice_cove"):
        for part in element_model(name).parts:
            if part.symbol.split(".")[-1] in ("frame", "bars", "railing", "leaf", "profile"):
                assert part.mesh.volume() > 0, part.symbol
        glass = [p for p in element_model(name).parts if p.symbol.endswith(".glass")]
        for p in glass:
            assert (p.mesh.face_normals()[:, 2] > 0.99).all()


def test_spec_lookup_and_close_matches():
    assert element_spec("window_mullion_2x2").kind == "window"
    with pytest.raises(InputError, match="window_mullion_2x2"):
        element_spec("window_mulion_2x2")


def test_part_labels_follow_roles():
    parts = {p.symbol.split(".")[-1]: p for p in element_model("window_shutters_open").parts}
    assert parts["shutter"].label == "blind"
    assert parts["glass"].label == "window" and parts["glass"].material.name == "glass"
    assert parts["glass"].material.roughness < 0.2
    assert any(p.label == "sill" for p in element_model("window_sill_2x2").parts)
    assert {p.label for p in element_model("balcony_bars").parts} == {"balcony"}
    assert any(p.material.metallic > 0.5 for p in element_model("balcony_bars").parts)


def test_renders_shape_contrast_and_distinct():
    seen = {}
    for spec in LIB:
        gray, labels = render_front(spec, 24, 40)
        assert gray.shape == (40, 24) and labels.shape == (40, 24)
        assert gray.dtype == np.float32 and labels.dtype == np.uint8
        assert 0 <= gray.min() and gray.max() <= 1
        assert gray.std() > 0.01, spec.name
        assert set(np.unique(labels)) <= set(LABEL_INDEX.values())
        key = np.round(gray, 3).tobytes()
        assert key not in seen, (spec.name, seen.get(key))
        seen[key] = spec.name


def test_render_labels_and_cache():
    gray, labels = render_front("window_mullion_2x2", 48, 64)
    assert (labels == LABEL_INDEX["window"]).mean() > 0.9
    assert render_front("window_mullion_2x2", 48, 64)[0] is gray  # cached
    assert not gray.flags.writeable
    _, lab = render_front("balcony_bars", 90, 40)
    assert (lab == LABEL_INDEX["wall"]).any() and (lab == LABEL_INDEX["balcony"]).any()
    _, lab = render_front("window_shutters_open", 96, 64)
    assert (lab == LABEL_INDEX["blind"]).mean() > 0.3
    with pytest.raises(InputError):
        render_front("window_plain", 0, 10)
