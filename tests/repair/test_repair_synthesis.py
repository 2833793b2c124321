"""The label → image synthesis network evaluated with numpy: weight files, agreement with the
PyTorch network it was trained as (when PyTorch is installed; the CI machine has none), the
shipped weights following the style photo, and the errors of :func:`synthesize`."""

from __future__ import annotations

import json

import numpy as np
import pytest

from facadeforge.errors import InputError
from facadeforge.repair.synthesis import (
    DEFAULT_WEIGHTS,
    SynthesisNetwork,
    SynthesisSpec,
    _conv,
    _tconv2,
    load_synthesis,
    match_class_colors,
    spec_shapes,
    synthesize,
)

SMALL = SynthesisSpec(size=64, gen_channels=(16, 16, 16, 16, 8, 8, 4, 4),
                      hidden=(8, 8, 8, 8, 8, 4, 4), style_dim=8, enc_channels=(4, 8, 8))
WALL, WINDOW = 1, 2   # cmp12


def random_weights(spec: SynthesisSpec, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    out = {}
    for name, shape in spec_shapes(spec).items():
        if name.endswith("running_var"):
            out[name] = rng.uniform(0.5, 2.0, shape).astype(np.float32)
        else:
            fan_in = int(np.prod(shape[1:])) if len(shape) > 1 else 1
            out[name] = (rng.normal(size=shape) / np.sqrt(fan_in)).astype(np.float32)
    return out


def facade_labels(h: int, w: int) -> np.ndarray:
    """A wall with a 3 × 4 grid of windows, cmp12 indices."""
    lab = np.full((h, w), WALL, np.uint8)
    for r in range(3):
        for c in range(4):
            y0, x0 = int(h * (0.1 + 0.3 * r)), int(w * (0.06 + 0.24 * c))
            lab[y0:y0 + int(h * 0.15), x0:x0 + int(w * 0.12)] = WINDOW
    return lab


def write_weights(path, spec, weights):
    meta = {"format": "facadeforge-synthesis", "version": 1, "label_set": "cmp12",
            "spec": spec.to_json(), "meta": {}}
    np.savez(path, __meta__=np.frombuffer(json.dumps(meta).encode(), np.uint8),
             **{k: v.astype(np.float16) for k, v in weights.items()})


# ----------------------------------------------------------------------------- layers
def test_strided_conv_matches_a_direct_sum():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(3, 9, 8)).astype(np.float32)
    w = rng.normal(size=(5, 3, 3, 3)).astype(np.float32)
    b = rng.normal(size=5).astype(np.float32)
    out = _conv(x, w, b, stride=2)
    xp = np.pad(x, ((0, 0), (1, 1), (1, 1)))
    ref = np.zeros((5, 5, 4), np.float32)
    for y in range(5):
        for xx in range(4):
            ref[:, y, xx] = np.einsum("ocij,cij->o", w, xp[:, 2 * y:2 * y + 3, 2 * xx:2 * xx + 3]) + b
    np.testing.assert_allclose(out, ref, atol=1e-4)


def test_transposed_conv_matches_its_definition():
    """Each input pixel scatters ``w`` into the output at twice its position, minus padding 1."""
    rng = np.random.default_rng(2)
    x = rng.normal(size=(2, 3, 4)).astype(np.float32)
    w = rng.normal(size=(2, 3, 3, 3)).astype(np.float32)
    b = rng.normal(size=3).astype(np.float32)
    full = np.zeros((3, 2 * 3 + 2, 2 * 4 + 2), np.float32)
    for c in range(2):
        for y in range(3):
            for xx in range(4):
                full[:, 2 * y:2 * y + 3, 2 * xx:2 * xx + 3] += x[c, y, xx] * w[c]
    ref = full[:, 1:1 + 6, 1:1 + 8] + b[:, None, None]
    np.testing.assert_allclose(_tconv2(x, w, b), ref, atol=1e-4)


# ----------------------------------------------------------------------------- files
def test_spec_json_round_trip_and_bad_shapes():
    assert SynthesisSpec.from_json(SMALL.to_json()) == SMALL
    with pytest.raises(ValueError):
        SynthesisSpec(size=100)
    with pytest.raises(ValueError):
        SynthesisSpec(gen_channels=(8, 8))


def test_weight_file_round_trip(tmp_path):
    path = tmp_path / "w.npz"
    write_weights(path, SMALL, random_weights(SMALL))
    net = load_synthesis(path)
    assert net.spec == SMALL
    lab = facade_labels(64, 64)
    rgb = np.zeros((64, 64, 3), np.float32)
    out = net.run(lab, rgb, lab)
    assert out.shape == (64, 64, 3) and np.isfinite(out).all() and np.abs(out).max() <= 1


def test_damaged_or_mismatched_weight_files_are_refused(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_synthesis(tmp_path / "missing.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(InputError, match="unusable"):
        load_synthesis(tmp_path / "junk.npz")
    weights = random_weights(SMALL)
    weights.pop("gen.conv_img.bias")
    write_weights(tmp_path / "short.npz", SMALL, weights)
    with pytest.raises(InputError, match="unusable"):
        load_synthesis(tmp_path / "short.npz")
    with pytest.raises(ValueError):
        SynthesisNetwork(SMALL, {**random_weights(SMALL),
                                 "gen.fc.bias": np.full(16, np.nan, np.float32)})


# ----------------------------------------------------------------------------- torch agreement
@pytest.mark.parametrize("which", ["random", "shipped"])
def test_numpy_and_torch_agree(which):
    torch = pytest.importorskip("torch")
    from facadeforge.repair.synthesis_train import build_networks, load_into_torch, one_hot

    if which == "random":
        spec = SMALL
        enc, gen = build_networks(torch, spec)
        names = {f"enc.{k}" for k in enc.state_dict()} | {f"gen.{k}" for k in gen.state_dict()}
        assert {n for n in names if not n.endswith("num_batches_tracked")} == set(
            spec_shapes(spec))
        net = SynthesisNetwork(spec, random_weights(spec, seed=3))
    else:
        net = load_synthesis(DEFAULT_WEIGHTS)
        spec = net.spec
    enc, gen = load_into_torch(torch, spec, net.weights)
    rng = np.random.default_rng(4)
    s = spec.size
    lab = np.kron(rng.integers(0, 13, (s // 8, s // 8)), np.ones((8, 8), int)).astype(np.uint8)
    lab[lab == 12] = 255                    # unlabelled pixels: no class
    slab = rng.integers(0, 12, (s, s)).astype(np.uint8)
    rgb = rng.uniform(-1, 1, (s, s, 3)).astype(np.float32)
    out = net.run(lab, rgb, slab)
    with torch.no_grad():
        style = enc(torch.from_numpy(rgb).permute(2, 0, 1)[None], one_hot(torch, slab[None], 12))
        ref = gen(one_hot(torch, lab[None], 12), style)[0].permute(1, 2, 0).numpy()
    assert np.abs(out - ref).max() < 1e-3


# ----------------------------------------------------------------------------- shipped weights
@pytest.fixture(scope="module")
def red_blue():
    """Labels, a style photo with a red wall and blue windows, and the textures painted by the
    network alone and with the class colours matched."""
    lab = facade_labels(150, 210)
    style = np.zeros((150, 210, 3), np.uint8)
    style[lab == WALL] = (190, 60, 50)
    style[lab == WINDOW] = (40, 60, 170)
    target = facade_labels(97, 131)
    return (target, synthesize(target, style, lab, match_colors=False),
            synthesize(target, style, lab))


def test_shipped_network_follows_the_style_photo(red_blue):
    """The network alone (no colour matching): the wall comes out red-ish, redder and brighter
    than the windows, the windows bluer than the wall."""
    target, raw, _ = red_blue
    assert raw.shape == (97, 131, 3) and raw.dtype == np.uint8
    wall = raw[target == WALL].astype(float).mean(0)
    window = raw[target == WINDOW].astype(float).mean(0)
    assert wall[0] > wall[2] + 30, wall
    assert wall[0] - wall[2] > window[0] - window[2] + 30, (wall, window)
    assert window[2] - window[0] > wall[2] - wall[0] + 30, (wall, window)


def test_matched_colours_are_the_style_photo_s(red_blue):
    target, _, out = red_blue
    np.testing.assert_allclose(out[target == WALL].astype(float).mean(0), (190, 60, 50), atol=4)
    np.testing.assert_allclose(out[target == WINDOW].astype(float).mean(0), (40, 60, 170),
                               atol=4)


def test_match_class_colors_shifts_each_class():
    lab = np.array([[0, 0, 1], [1, 255, 2]], np.uint8)
    image = np.full((2, 3, 3), 100, np.float32)
    image[0, 0] = 120
    style = np.zeros((2, 2, 3), np.uint8)
    style[0] = 50                       # class 0 in the style: mean 50
    style[1] = 200                      # class 1: mean 200; class 2 absent from the style
    slab = np.array([[0, 0], [1, 1]], np.uint8)
    out = match_class_colors(image, lab, style, slab)
    np.testing.assert_allclose(out[0, :2].mean(0), 50)
    np.testing.assert_allclose(out[0, 0] - out[0, 1], 20)      # the structure is kept
    np.testing.assert_allclose(out[[0, 1], [2, 0]], 200)
    np.testing.assert_allclose(out[1, 1:], 100)                # unlabelled, absent: unchanged


def test_other_label_sets_are_converted():
    lab6 = np.ones((40, 30), np.uint8)       # cmp6 wall
    lab6[10:20, 8:20] = 2                    # cmp6 window
    style = np.full((40, 30, 3), 128, np.uint8)
    out = synthesize(lab6, style, lab6, label_set="cmp6")
    assert out.shape == (40, 30, 3)


@pytest.mark.parametrize("call, match", [
    (lambda: synthesize(np.zeros((4, 4, 3), np.uint8), np.zeros((4, 4, 3), np.uint8),
                        np.zeros((4, 4), np.uint8)), "2-d class-index map"),
    (lambda: synthesize(np.full((4, 4), 40, np.uint8), np.zeros((4, 4, 3), np.uint8),
                        np.zeros((4, 4), np.uint8)), "out of range"),
    (lambda: synthesize(np.zeros((4, 4), np.float32), np.zeros((4, 4, 3), np.uint8),
                        np.zeros((4, 4), np.uint8)), "integers"),
    (lambda: synthesize(np.zeros((4, 4), np.uint8), np.zeros((4, 4), np.uint8),
                        np.zeros((4, 4), np.uint8)), "RGB image"),
    (lambda: synthesize(np.zeros((4, 4), np.uint8), np.zeros((4, 4, 3), np.uint8),
                        np.zeros((5, 4), np.uint8)), "differs"),
    (lambda: synthesize(np.zeros((4, 4), np.uint8), np.zeros((4, 4, 3), np.uint8),
                        np.zeros((4, 4), np.uint8), label_set="nope"), "unknown label set"),
    (lambda: synthesize(np.zeros((4, 4), np.uint8), np.zeros((4, 4, 3), np.uint8),
                        np.zeros((4, 4), np.uint8), weights="/nonexistent.npz"), "no such file"),
])
def test_bad_input_is_an_input_error(call, match):
    with pytest.raises(InputError, match=match):
        call()


def test_style_labels_default_to_the_shipped_classifier(red_blue):
    target = red_blue[0]
    style = np.zeros((150, 210, 3), np.uint8)
    style[facade_labels(150, 210) == WALL] = (190, 60, 50)
    style[facade_labels(150, 210) == WINDOW] = (40, 60, 170)
    out = synthesize(target, style)
    assert out.shape == (97, 131, 3) and out.dtype == np.uint8
