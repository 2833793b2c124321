"""The facade U-Net evaluated with numpy: layers against direct references, batch-norm folding,
model files, and the training entry point (PyTorch is optional: the CI machine has none)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.signal import correlate

from facadeforge.classify import load_classifier, save_classifier
from facadeforge.classify.convnet import (
    ConvNetClassifier,
    ConvNetSpec,
    _conv,
    _up2,
    fold_batchnorm,
    network_input,
)
from facadeforge.classify.model import ClassifierFileError
from facadeforge.errors import InputError

CLASSES = ("background", "wall", "window", "door", "balcony", "shop")


def random_weights(spec: ConvNetSpec, k: int, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    out = {}
    for name, shape in spec.shapes(k).items():
        fan_in = int(np.prod(shape[:-1])) if len(shape) > 1 else 1
        out[name] = (rng.normal(size=shape) * np.sqrt(2 / fan_in)).astype(np.float32)
    return out


def reference_conv(x, w, b):
    """Zero-padded same-size correlation, one output channel at a time (scipy)."""
    k = w.shape[0]
    r = k // 2
    xp = np.pad(x, ((r, r), (r, r), (0, 0)))
    out = np.stack([correlate(xp, w[:, :, :, o], mode="valid")[:, :, 0] for o in
                    range(w.shape[3])], axis=2)
    return out + b


@pytest.mark.parametrize("k", [1, 3])
def test_conv_matches_direct_correlation(k):
    rng = np.random.default_rng(k)
    x = rng.normal(size=(9, 7, 4)).astype(np.float32)
    w = rng.normal(size=(k, k, 4, 5)).astype(np.float32)
    b = rng.normal(size=5).astype(np.float32)
    chw = np.ascontiguousarray(x.transpose(2, 0, 1))
    np.testing.assert_allclose(_conv(chw, w, b, relu=False).transpose(1, 2, 0),
                               reference_conv(x, w, b), atol=1e-4)
    assert (_conv(chw, w, b) >= 0).all()


def test_upsampling_is_half_pixel_bilinear():
    """×2 up-sampling equals OpenCV's bilinear resize (half-pixel centres, edge clamping)."""
    rng = np.random.default_rng(0)
    x = rng.normal(size=(5, 6, 3)).astype(np.float32)
    ref = cv2.resize(x, (12, 10), interpolation=cv2.INTER_LINEAR)
    np.testing.assert_allclose(_up2(x.transpose(2, 0, 1)).transpose(1, 2, 0), ref, atol=1e-5)


def test_batchnorm_folding_equals_conv_then_norm():
    rng = np.random.default_rng(2)
    x = rng.normal(size=(3, 6, 6)).astype(np.float32)
    w = rng.normal(size=(3, 3, 3, 4)).astype(np.float32)
    gamma, beta, mean = (rng.normal(size=4).astype(np.float32) for _ in range(3))
    var = rng.uniform(0.5, 2, 4).astype(np.float32)
    plain = _conv(x, w, np.zeros(4, np.float32), relu=False)
    expected = ((plain.transpose(1, 2, 0) - mean) / np.sqrt(var + 1e-5) * gamma + beta
                ).transpose(2, 0, 1)
    fw, fb = fold_batchnorm(w, gamma, beta, mean, var)
    np.testing.assert_allclose(_conv(x, fw, fb, relu=False), expected, atol=1e-4)


def test_network_input_channels():
    img = np.zeros((4, 8, 3), np.uint8)
    x = network_input(img)
    assert x.shape == (4, 8, 5)
    np.testing.assert_allclose(x[:, 0, 3], [-0.75, -0.25, 0.25, 0.75])  # rows, top = -1
    np.testing.assert_allclose(x[0, :, 4], (np.arange(8) + 0.5) / 8 * 2 - 1)


def test_prediction_shape_and_file_round_trip(tmp_path):
    spec = ConvNetSpec(width=2, multipliers=(1, 2, 3), rowcol=(2,))
    clf = ConvNetClassifier(spec, random_weights(spec, 6), CLASSES, "cmp6", {"note": "random"})
    img = np.random.default_rng(0).integers(0, 255, (50, 37, 3), dtype=np.uint8)
    prob = clf.predict_proba(img)
    assert prob.shape == (50, 37, 6) and prob.dtype == np.float32
    np.testing.assert_allclose(prob.sum(axis=2), 1, atol=1e-5)
    back = load_classifier(save_classifier(clf, tmp_path / "net.npz"))
    assert isinstance(back, ConvNetClassifier) and back.spec == spec
    assert back.meta["note"] == "random"
    np.testing.assert_allclose(back.predict_proba(img), prob, atol=2e-3)  # float16 weights


def test_damaged_network_file_is_refused(tmp_path):
    spec = ConvNetSpec(width=2, multipliers=(1, 2), rowcol=())
    clf = ConvNetClassifier(spec, random_weights(spec, 6), CLASSES, "cmp6")
    path = save_classifier(clf, tmp_path / "net.npz")
    with np.load(path) as z:
        arrays = dict(z)
    arrays["head_w"] = arrays["head_w"][:, :, :, :3]  # wrong class count
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(ClassifierFileError, match="damaged"):
        load_classifier(tmp_path / "bad.npz")
    with pytest.raises(ValueError, match="unsupported network shape"):
        ConvNetSpec(width=0)
    with pytest.raises(ValueError, match="more than"):
        ConvNetSpec(width=256, multipliers=(64, 64), rowcol=())   # a zip bomb's shape
    # untrusted metadata: non-finite or absurd spec values are a ClassifierFileError
    import json
    meta = json.loads(arrays["__meta__"].tobytes().decode())
    meta["meta"]["spec"]["width"] = 1e400   # Infinity once written as JSON
    arrays["head_w"] = np.load(path)["head_w"]
    arrays["__meta__"] = np.frombuffer(json.dumps(meta).encode(), np.uint8)
    np.savez(tmp_path / "inf.npz", **arrays)
    with pytest.raises(ClassifierFileError):
        load_classifier(tmp_path / "inf.npz")
    arrays["__meta__"] = np.frombuffer(b"[1, 2]", np.uint8)
    np.savez(tmp_path / "list.npz", **arrays)
    with pytest.raises(ClassifierFileError, match="not a facadeforge"):
        load_classifier(tmp_path / "list.npz")


def test_training_without_torch_says_how_to_install(monkeypatch):
    import builtins

    from facadeforge.classify.convnet_train import train_convnet

    real = builtins.__import__

    def no_torch(name, *args, **kwargs):
        if name == "torch" or name.startswith("torch."):
            raise ImportError("no torch here")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_torch)
    img = np.zeros((32, 32, 3), np.uint8)
    with pytest.raises(InputError, match="train extra"):
        train_convnet([img] * 8, [np.zeros((32, 32), np.uint8)] * 8, CLASSES, "cmp6")


def test_shipped_defaults_prefer_the_networks_where_they_are_shipped():
    from facadeforge.classify import default_classifier, shipped_model_path

    assert shipped_model_path("cmp6").name == "ensemble-cmp6.npz"
    assert shipped_model_path("ecp7").name == "autocontext-ecp7.npz"   # no ecp7 network
    assert shipped_model_path("cmp6", "autocontext").name == "autocontext-cmp6.npz"
    shipped = default_classifier("cmp6")
    assert shipped.kind == "ensemble" and shipped.label_set == "cmp6"
    assert [(m.kind, m.label_set) for m in shipped.members] == [("convnet", "cmp6"),
                                                                ("convnet", "cmp12")]
    with pytest.raises(InputError, match="no shipped convnet classifier"):
        default_classifier("ecp7", "convnet")


def test_grey_input_is_refused_with_a_clear_error():
    spec = ConvNetSpec(width=2, multipliers=(1, 2), rowcol=())
    clf = ConvNetClassifier(spec, random_weights(spec, 6), CLASSES, "cmp6")
    with pytest.raises(InputError, match="RGB"):
        clf.predict_small(np.zeros((20, 20), np.uint8))


def test_exported_numpy_network_equals_torch():
    """With PyTorch present: export (batch norm folded, layout changed) preserves the network."""
    torch = pytest.importorskip("torch", reason="PyTorch (the train extra) is not installed")
    from facadeforge.classify.convnet import forward, network_input, pad_to
    from facadeforge.classify.convnet_train import _build, export_weights

    torch.manual_seed(0)
    spec = ConvNetSpec(width=4)
    net = _build(torch, spec, 6)
    for m in net.modules():
        if isinstance(m, torch.nn.BatchNorm2d):
            m.running_mean.uniform_(-0.5, 0.5)
            m.running_var.uniform_(0.5, 2)
    net.eval()
    img = np.random.default_rng(0).integers(0, 255, (40, 27, 3), dtype=np.uint8)
    x = pad_to(network_input(img), spec.stride)
    with torch.no_grad():
        ref = net(torch.from_numpy(np.ascontiguousarray(x)).permute(2, 0, 1)[None])
    np.testing.assert_allclose(forward(spec, export_weights(net), x),
                               ref[0].permute(1, 2, 0).numpy(), atol=1e-4)


def test_training_learns_a_toy_facade():
    """With PyTorch present (the train extra), a few epochs separate dark windows from wall."""
    pytest.importorskip("torch", reason="PyTorch (the train extra) is not installed")
    from facadeforge.classify.convnet_train import train_convnet

    rng = np.random.default_rng(0)
    imgs, labs = [], []
    for _ in range(8):
        lab = np.ones((64, 64), np.uint8)
        for r in range(6, 60, 20):
            for c in range(rng.integers(2, 8), 58, 16):
                lab[r:r + 10, c:c + 8] = 2
        img = np.where(lab[:, :, None] == 2, 50, 200) + rng.normal(0, 10, (64, 64, 3))
        imgs.append(np.clip(img, 0, 255).astype(np.uint8))
        labs.append(lab)
    spec = ConvNetSpec(width=4, multipliers=(1, 2, 2), rowcol=(2,))
    clf = train_convnet(imgs, labs, CLASSES, "cmp6", spec=spec, epochs=40, batch=4, crop=48,
                        lr=1e-2, seed=0)
    pred = clf.predict_small(imgs[0]).argmax(axis=2)
    assert (pred == labs[0]).mean() > 0.9


def test_an_ensemble_averages_its_members_in_its_own_label_set(tmp_path):
    from facadeforge.classify.ensemble import EnsembleClassifier
    from facadeforge.datasets import get_label_set

    cmp6, cmp12 = get_label_set("cmp6"), get_label_set("cmp12")
    spec = ConvNetSpec(width=2, multipliers=(1, 2), rowcol=())
    coarse = ConvNetClassifier(spec, random_weights(spec, 6, seed=1), cmp6.classes, "cmp6")
    fine = ConvNetClassifier(spec, random_weights(spec, 12, seed=2), cmp12.classes, "cmp12")
    ens = EnsembleClassifier([coarse, fine], "cmp6", {"command": "test"})
    assert ens.classes == cmp6.classes and ens.label_set == "cmp6"
    img = np.random.default_rng(1).integers(0, 255, (24, 40, 3), np.uint8)
    want = (coarse.predict_proba(img)
            + cmp6.project_proba(fine.predict_proba(img), cmp12.classes)) / 2
    got = ens.predict_proba(img)
    assert got.shape == (24, 40, 6)
    np.testing.assert_allclose(got, want, atol=2e-3)
    np.testing.assert_allclose(got.sum(axis=2), 1.0, atol=1e-4)
    from facadeforge.classify.features import ANALYSIS_SIDE, resize_proba

    coarse_p = ens.predict_proba_coarse(img)        # the working scale, the photo's aspect
    assert max(coarse_p.shape[:2]) == ANALYSIS_SIDE and coarse_p.shape[2] == 6
    assert abs(coarse_p.shape[0] / coarse_p.shape[1] - 24 / 40) < 0.01
    np.testing.assert_allclose(resize_proba(coarse_p, (24, 40)), got, atol=1e-5)
    again = load_classifier(save_classifier(ens, tmp_path / "ens.npz"))
    assert again.kind == "ensemble" and [m.label_set for m in again.members] == ["cmp6", "cmp12"]
    assert again.meta["command"] == "test"
    # the weights are stored as float16
    np.testing.assert_allclose(again.predict_proba(img), got, atol=5e-3)
    with pytest.raises(InputError, match="1 to"):
        EnsembleClassifier([], "cmp6")
    with pytest.raises(InputError, match="another ensemble"):
        EnsembleClassifier([ens], "cmp6")


def test_a_damaged_ensemble_file_is_refused_with_a_clear_error(tmp_path):
    import json

    from facadeforge.classify.ensemble import EnsembleClassifier

    spec = ConvNetSpec(width=2, multipliers=(1, 2), rowcol=())
    member = ConvNetClassifier(spec, random_weights(spec, 6), CLASSES, "cmp6")
    path = save_classifier(EnsembleClassifier([member], "cmp6"), tmp_path / "e.npz")
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(arrays["__meta__"].tobytes())

    def damaged(edit, drop=()):
        m = json.loads(json.dumps(meta))
        edit(m["meta"])
        bad = {k: a for k, a in arrays.items() if not k.startswith(drop) or not drop}
        bad["__meta__"] = np.frombuffer(json.dumps(m).encode(), np.uint8)
        np.savez(tmp_path / "bad.npz", **bad)
        with pytest.raises(ClassifierFileError, match="damaged"):
            load_classifier(tmp_path / "bad.npz")

    damaged(lambda m: m["members"][0].update(kind="ensemble"))   # no nested ensembles
    damaged(lambda m: m.update(members=[]))
    damaged(lambda m: m.update(members="m0"))
    damaged(lambda m: m["members"][0].update(classes=["bogus"] * 6))
    damaged(lambda m: m["members"][0].update(classes=list(reversed(CLASSES))))  # reordered
    damaged(lambda m: None, drop="m0.")                          # member arrays missing


def test_cli_combines_models_into_an_ensemble(tmp_path, capsys):
    from facadeforge.cli import main
    from facadeforge.datasets import get_label_set

    spec = ConvNetSpec(width=2, multipliers=(1, 2), rowcol=())
    cmp12 = get_label_set("cmp12")
    a = save_classifier(ConvNetClassifier(spec, random_weights(spec, 6), CLASSES, "cmp6"),
                        tmp_path / "a.npz")
    b = save_classifier(ConvNetClassifier(spec, random_weights(spec, 12), cmp12.classes,
                                          "cmp12"), tmp_path / "b.npz")
    out = tmp_path / "ens.npz"
    assert main(["train-classifier", "--kind", "ensemble", "--members", str(a), str(b),
                 "-o", str(out)]) == 0
    ens = load_classifier(out)
    assert ens.kind == "ensemble" and ens.label_set == "cmp6"      # the first member's set
    assert ens.meta["command"].startswith("facadeforge")        # from sys.argv
    capsys.readouterr()
    for bad, says in ((["--members", str(tmp_path / "missing.npz")], "no such file"),
                      ([], "needs --members"),
                      (["--members", str(out)], "another ensemble")):
        assert main(["train-classifier", "--kind", "ensemble", *bad,
                     "-o", str(tmp_path / "x.npz")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and says in err, err
    assert not (tmp_path / "x.npz").exists()
