"""User-interactive colour classifier: one Gaussian mixture per class, fitted on scribbles
(``simon2011`` §4.3.2).

For a building whose style no training set covers, the user paints a few strokes on the photo
itself, one colour per class ("this is wall", "this is window").  Each stroked class ``c_i`` gets
a Gaussian mixture of ``K`` components in RGB (the thesis finds ``K = 3`` a fair choice), fitted by
expectation–maximisation on the stroked pixels:

.. math::  p(f_x | c_i) = \\sum_{k=1}^K \\pi_k^i \\, \\mathcal{N}(f_x | \\mu_k^i, \\Sigma_k^i)
           \\qquad (4.11)

and every pixel gets the class posterior by Bayes' rule (eq. 4.12) with all classes equally
probable (eq. 4.13):

.. math::  p(c_i | f_x) = \\frac{p(f_x | c_i)}{\\sum_j p(f_x | c_j)}  \\qquad (4.13)

Here eq. 4.13 is evaluated in log space with log-sum-exp, so pixels far from every class (whose
densities all underflow to 0 in floating point) still get a proper distribution instead of
``0 / 0``.

Scribble files (:func:`read_scribbles`) are PNGs the size of the photo, in either of two forms:

*colour-coded*
    RGB or RGBA; a stroke is painted in the exact colour of its class in the label set
    (:attr:`~facadeforge.datasets.labelsets.LabelSet.colors`, e.g. ``ecp7`` wall = yellow
    ``(255, 255, 0)``, window = red ``(255, 0, 0)``).  Every other colour — black, white or
    transparent background, anti-aliased stroke edges — means "no stroke", as does alpha 0.
    Palette (``P``) PNGs are read by their colours.
*index*
    single-channel (``L`` or 16-bit): value ``k + 1`` marks class ``k`` of the label set, ``0``
    no stroke.

Model arrays (:meth:`GMMClassifier.to_arrays`), for C classes of K components, in 8-bit RGB
units: ``weights (C, K)``, ``means (C, K, 3)``, ``covariances (C, K, 3, 3)``.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..datasets.labelsets import IGNORE, LabelSet, get_label_set
from ..errors import InputError
from ..imaging.rectify import to_rgb8
from .model import ClassifierFileError, PixelClassifier, register_kind

__all__ = ["MAX_SAMPLES", "REG_COVAR", "GMMClassifier", "ScribbleError", "read_scribbles",
           "train_gmm"]

#: At most this many stroked pixels per class are used for EM (a deterministic subsample).
MAX_SAMPLES: int = 20000

#: Added to the diagonal of every covariance, in squared 8-bit units: about the variance of
#: uint8 quantisation (1/12), so a flat-coloured stroke gives a sharp but regular Gaussian.
REG_COVAR: float = 0.1

_LOG_2PI = float(np.log(2.0 * np.pi))
_CHUNK = 1 << 18  # pixels per block in predict_proba


class ScribbleError(InputError, ValueError):
    """Scribbles cannot train a classifier: wrong size or format, too few classes or pixels."""


@register_kind
class GMMClassifier(PixelClassifier):
    """Per-class Gaussian mixtures in RGB with equal class priors (``simon2011`` eq. 4.11–4.13).

    Parameters
    ----------
    weights : (C, K) float
        Mixture weights ``pi_k^i``; each row sums to one.
    means : (C, K, 3) float
        Component means ``mu_k^i`` in 8-bit RGB units.
    covariances : (C, K, 3, 3) float
        Component covariances ``Sigma_k^i``, symmetric positive definite.
    classes, label_set, meta
        As :class:`~facadeforge.classify.model.PixelClassifier`.

    Raises
    ------
    ClassifierFileError
        Arrays of inconsistent shapes, non-finite values, non-positive weights or covariances
        that are not positive definite.
    """

    kind = "gmm"

    def __init__(self, weights: np.ndarray, means: np.ndarray, covariances: np.ndarray,
                 classes: tuple[str, ...], label_set: str,
                 meta: Mapping[str, Any] | None = None):
        super().__init__(classes, label_set, meta)
        w = np.asarray(weights, np.float64)
        mu = np.asarray(means, np.float64)
        cov = np.asarray(covariances, np.float64)
        c = len(self.classes)
        where = "gmm classifier"
        if w.ndim != 2 or w.shape[0] != c or w.shape[1] < 1:
            raise ClassifierFileError(f"{where}: weights must be ({c}, K) for {c} classes, got "
                                      f"{w.shape}; retrain with train_gmm")
        k = w.shape[1]
        if mu.shape != (c, k, 3) or cov.shape != (c, k, 3, 3):
            raise ClassifierFileError(f"{where}: means {mu.shape} / covariances {cov.shape} do "
                                      f"not match ({c}, {k}, 3) / ({c}, {k}, 3, 3); retrain with "
                                      "train_gmm")
        if not (np.isfinite(w).all() and np.isfinite(mu).all() and np.isfinite(cov).all()):
            raise ClassifierFileError(f"{where}: parameters contain NaN or infinity; retrain "
                                      "with train_gmm")
        if (w < 0).any() or not (w.sum(axis=1) > 0).all():
            raise ClassifierFileError(f"{where}: mixture weights must be >= 0 with a positive "
                                      "sum per class; retrain with train_gmm")
        try:
            chol = np.linalg.cholesky(cov)
        except np.linalg.LinAlgError:
            raise ClassifierFileError(f"{where}: a covariance matrix is not positive definite; "
                                      "retrain with train_gmm") from None
        self.weights, self.means, self.covariances = w, mu, cov
        # log pi_k + log normalisation of N, and the whitening map z = L^-1 (x - mu).
        with np.errstate(divide="ignore"):
            log_w = np.log(w / w.sum(axis=1, keepdims=True))
        log_det = 2.0 * np.log(np.diagonal(chol, axis1=-2, axis2=-1)).sum(axis=-1)
        self._log_norm = log_w - 0.5 * (3 * _LOG_2PI + log_det)        # (C, K)
        self._whiten = np.linalg.inv(chol)                               # (C, K, 3, 3)

    @property
    def num_components(self) -> int:
        """Components per class K."""
        return int(self.weights.shape[1])

    def log_likelihood(self, rgb: np.ndarray) -> np.ndarray:
        """``(N, C)`` float64 ``log p(f_x | c_i)`` (eq. 4.11) of ``(N, 3)`` RGB values."""
        x = np.asarray(rgb, np.float64).reshape(-1, 3).T  # channels first: contiguous rows
        c, k = self.weights.shape
        comp = np.empty((c, k, x.shape[1]))
        for i in range(c):
            for j in range(k):
                # Mahalanobis term |L^-1 (x - mu)|^2 with L^-1 lower triangular, written out:
                # elementwise on channel rows is several times faster than an (N, 3) matmul.
                a = self._whiten[i, j]
                d0, d1, d2 = (x[0] - self.means[i, j, 0], x[1] - self.means[i, j, 1],
                              x[2] - self.means[i, j, 2])
                z0 = a[0, 0] * d0
                z1 = a[1, 0] * d0 + a[1, 1] * d1
                z2 = a[2, 0] * d0 + a[2, 1] * d1 + a[2, 2] * d2
                comp[i, j] = self._log_norm[i, j] - 0.5 * (z0 * z0 + z1 * z1 + z2 * z2)
        return _logsumexp(comp, axis=1).T

    def predict_proba_coarse(self, image: np.ndarray) -> np.ndarray:
        """``(H, W, C)`` float32 posteriors ``p(c_i | f_x)`` of eq. 4.13 (equal class priors), at
        the photo's own scale (the posterior is per colour: there is no working scale).

        ``image`` is ``(H, W, 3)`` uint8 RGB; grey ``(H, W)``, RGBA, 16-bit and float images are
        converted with :func:`~facadeforge.imaging.rectify.to_rgb8`.  The posterior depends on
        the colour only, so it is computed once per distinct colour of the image.
        """
        rgb = to_rgb8(image)
        h, w = rgb.shape[:2]
        flat = rgb.reshape(-1, 3)
        key = ((flat[:, 0].astype(np.int32) << 16) | (flat[:, 1].astype(np.int32) << 8)
               | flat[:, 2])
        keys, inverse = np.unique(key, return_inverse=True)
        colours = np.stack([keys >> 16, (keys >> 8) & 255, keys & 255], axis=1)
        proba = np.empty((len(keys), self.num_classes), np.float32)
        for start in range(0, len(keys), _CHUNK):
            ll = self.log_likelihood(colours[start:start + _CHUNK])
            proba[start:start + _CHUNK] = np.exp(ll - _logsumexp(ll, axis=1)[:, None])
        return proba[inverse.ravel()].reshape(h, w, self.num_classes)

    def to_arrays(self) -> dict[str, np.ndarray]:
        return {"weights": self.weights.copy(), "means": self.means.copy(),
                "covariances": self.covariances.copy()}

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], classes: tuple[str, ...],
                    label_set: str, meta: Mapping[str, Any]) -> GMMClassifier:
        missing = [n for n in ("weights", "means", "covariances") if n not in arrays]
        if missing:
            raise ClassifierFileError(f"gmm classifier: arrays {missing} are missing; retrain "
                                      "with train_gmm")
        return cls(arrays["weights"], arrays["means"], arrays["covariances"], classes,
                   label_set, meta)


def _logsumexp(a: np.ndarray, axis: int) -> np.ndarray:
    """``log(sum(exp(a)))`` along ``axis`` without overflow or underflow (``-inf`` allowed)."""
    m = np.max(a, axis=axis, keepdims=True)
    m = np.where(np.isfinite(m), m, 0.0)
    with np.errstate(divide="ignore"):
        s = np.log(np.sum(np.exp(a - m), axis=axis, keepdims=True)) + m
    return np.squeeze(s, axis=axis)


# ---------------------------------------------------------------------------------- scribbles
def _read_png(path: Path) -> np.ndarray:
    """Pixels of a scribble file: (H, W) int for single-channel images, else (H, W, 4) uint8."""
    from PIL import Image, UnidentifiedImageError

    if not path.is_file():
        raise ScribbleError(f"scribbles {path} does not exist; paint strokes on a copy of the "
                            "photo and save them as PNG")
    try:
        with Image.open(path) as im:
            im.load()
            if im.mode in ("L", "I", "I;16", "I;16B", "I;16L", "I;16N"):
                return np.asarray(im).astype(np.int64)
            return np.asarray(im.convert("RGBA"), np.uint8).copy()
    except (OSError, UnidentifiedImageError, ValueError, SyntaxError) as exc:
        raise ScribbleError(f"scribbles {path} cannot be read ({exc}); save them as PNG") from exc


def read_scribbles(scribbles: str | Path | np.ndarray,
                   label_set: LabelSet | str = "ecp7") -> np.ndarray:
    """Class-index map of a scribble image (see the module docstring for the two formats).

    Parameters
    ----------
    scribbles : path or array
        Scribble PNG, or its pixels: ``(H, W)`` integers are an *index* image (``k + 1`` =
        class ``k``, ``0`` = no stroke); ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA uint8 are
        *colour-coded* with the label set's colours (other colours and alpha 0 = no stroke).
        Grey and 16-bit PNGs are index images; RGB, RGBA and palette PNGs colour-coded.
    label_set : LabelSet or str
        The set whose classes the strokes name (``ecp7``, ``cmp6``, ``cmp12``).

    Returns
    -------
    (H, W) uint8
        Class index of each stroked pixel, :data:`~facadeforge.datasets.labelsets.IGNORE`
        (255) where there is no stroke.

    Raises
    ------
    ScribbleError
        Unreadable file, wrong array shape, or index values that are not classes of the set.
    """
    ls = get_label_set(label_set)
    where = f"scribbles {scribbles}" if isinstance(scribbles, (str, Path)) else "scribbles"
    if isinstance(scribbles, (str, Path)):
        arr = _read_png(Path(scribbles))
    else:
        arr = np.asarray(scribbles)
        if arr.ndim == 3 and arr.shape[2] == 1:
            arr = arr[:, :, 0]
    if arr.ndim == 2:
        if arr.dtype.kind not in "iu":
            raise ScribbleError(f"{where}: an index image must hold integers, got dtype "
                                f"{arr.dtype}; value k+1 marks class k, 0 no stroke")
        bad = (arr < 0) | (arr > ls.num_classes)
        if bad.any():
            vals = np.unique(arr[bad])[:10].tolist()
            raise ScribbleError(
                f"{where}: index values {vals} are not classes of label set {ls.name!r}; value "
                f"k+1 (1..{ls.num_classes}) marks class k of {list(ls.classes)}, 0 no stroke")
        table = np.concatenate([[IGNORE], np.arange(ls.num_classes)]).astype(np.uint8)
        return table[arr.astype(np.intp)]
    if arr.ndim != 3 or arr.shape[2] not in (3, 4):
        raise ScribbleError(f"{where}: expected an (H, W) index image or an (H, W, 3|4) colour "
                            f"image, got shape {arr.shape}")
    if arr.dtype != np.uint8:
        if arr.dtype.kind not in "iu" or arr.min(initial=0) < 0 or arr.max(initial=0) > 255:
            raise ScribbleError(f"{where}: colour scribbles must be 8-bit RGB(A), got dtype "
                                f"{arr.dtype}; save them as an 8-bit PNG")
        arr = arr.astype(np.uint8)
    out = ls.from_color(arr[:, :, :3])
    if arr.shape[2] == 4:
        out[arr[:, :, 3] == 0] = IGNORE
    return out


# ---------------------------------------------------------------------------------- training
def train_gmm(image: np.ndarray | str | Path, scribbles: np.ndarray | str | Path,
              label_set: LabelSet | str = "ecp7", components: int = 3,
              seed: int = 0) -> GMMClassifier:
    """Fit one ``components``-Gaussian mixture per stroked class by EM (``simon2011`` §4.3.2).

    Parameters
    ----------
    image : (H, W, 3) uint8 or path
        The photo the strokes were painted on (grey/RGBA converted; a path is read as RGB).
    scribbles : (H, W) uint8, (H, W, 3|4) uint8 or path
        Strokes: an ``(H, W)`` array is a class-index map as :func:`read_scribbles` returns
        (class index, 255 = no stroke); colour arrays and files go through
        :func:`read_scribbles`.
    label_set : LabelSet or str
        The set the strokes name.
    components : int
        Gaussians per class, K (the thesis uses 3).
    seed : int
        Seeds the subsample and EM's initialisation; same inputs and seed give the same model.

    Returns
    -------
    GMMClassifier
        ``classes`` are the stroked classes only, in label-set order; ``meta`` records the
        components, the stroked and used pixel counts per class, ``reg_covar`` and the seed.

    Raises
    ------
    ScribbleError
        Image and scribbles differ in size, fewer than two classes are stroked, or a class has
        fewer than ``2 * components`` stroked pixels.
    """
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.mixture import GaussianMixture
    from threadpoolctl import threadpool_limits  # a dependency of scikit-learn

    ls = get_label_set(label_set)
    components = int(components)
    if components < 1:
        raise ScribbleError(f"components={components}: use at least 1 Gaussian per class (the "
                            "thesis uses 3)")
    if isinstance(image, (str, Path)):
        from ..datasets.folder import read_image
        image = read_image(image)
    rgb = to_rgb8(image)
    if isinstance(scribbles, np.ndarray) and scribbles.ndim == 2:
        try:
            index = ls.check_indices(scribbles)
        except InputError as exc:
            raise ScribbleError(f"scribbles: {exc} ({IGNORE} = no stroke; decode scribble PNGs "
                                "with read_scribbles)") from None
    else:
        index = read_scribbles(scribbles, ls)
    if index.shape != rgb.shape[:2]:
        raise ScribbleError(
            f"scribbles are {index.shape[1]}x{index.shape[0]} pixels but the image is "
            f"{rgb.shape[1]}x{rgb.shape[0]}; paint the strokes on a copy of this photo at its "
            "full size")
    counts = np.bincount(index[index != IGNORE].ravel(), minlength=ls.num_classes)
    stroked = [k for k in range(ls.num_classes) if counts[k] > 0]
    if len(stroked) < 2:
        got = ", ".join(ls.classes[k] for k in stroked) or "none"
        raise ScribbleError(
            f"scribbles mark {len(stroked)} class(es) ({got}); stroke at least two classes of "
            f"label set {ls.name!r} in their exact colours "
            f"({dict(zip(ls.classes, ls.colors.tolist(), strict=True))})")
    few = [(ls.classes[k], int(counts[k])) for k in stroked if counts[k] < 2 * components]
    if few:
        desc = ", ".join(f"{name} has {n} pixel{'s' * (n != 1)}" for name, n in few)
        raise ScribbleError(f"scribbles: {desc}; a {components}-component mixture needs at "
                            f"least {2 * components} stroked pixels per class — paint longer "
                            "strokes, or erase the class's strokes")
    rng = np.random.default_rng(seed)
    flat_rgb = rgb.reshape(-1, 3)
    flat_idx = index.ravel()
    weights, means, covs, used = [], [], [], {}
    for k in stroked:
        pix = np.flatnonzero(flat_idx == k)
        if pix.size > MAX_SAMPLES:
            pix = np.sort(rng.choice(pix, MAX_SAMPLES, replace=False))
        x = flat_rgb[pix].astype(np.float64)
        gm = GaussianMixture(n_components=components, covariance_type="full",
                             reg_covar=REG_COVAR, random_state=seed, max_iter=200)
        # 3-D data, 3x3 matrices: BLAS/OpenMP threads only add overhead (x100 on a busy machine).
        with warnings.catch_warnings(), threadpool_limits(limits=1):
            # fewer distinct colours than components (flat strokes): k-means init warns, EM copes
            warnings.simplefilter("ignore", ConvergenceWarning)
            gm.fit(x)
        weights.append(gm.weights_)
        means.append(gm.means_)
        covs.append(gm.covariances_)
        used[ls.classes[k]] = int(pix.size)
    meta = {
        "method": "simon2011 §4.3.2 scribble GMM",
        "components": components,
        "pixels": {ls.classes[k]: int(counts[k]) for k in stroked},
        "samples": used,
        "reg_covar": REG_COVAR,
        "seed": int(seed),
    }
    return GMMClassifier(np.stack(weights), np.stack(means), np.stack(covs),
                         tuple(ls.classes[k] for k in stroked), ls.name, meta)
