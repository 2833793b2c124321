"""Picture sheet of a benchmark run: photo | truth | prediction | error, one row per facade.

The error panel is white where the prediction is right, red where it is wrong (including pixels
the method left unpredicted) and grey where the truth is ignored (not scored).  Label maps are
drawn in the label set's colours; a legend of the classes closes the sheet.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from ..datasets import IGNORE, LabelSet

__all__ = ["SheetRow", "error_map", "write_sheet"]

#: Colours of the error panel.
RIGHT_COLOR = (255, 255, 255)
WRONG_COLOR = (220, 30, 30)
IGNORED_COLOR = (150, 150, 150)
UNPREDICTED_COLOR = (0, 0, 0)  # prediction panel, where the method gave no class

_BACKGROUND = (255, 255, 255)
_TEXT = (20, 20, 20)
_PAD = 6
_LEGEND_STEP = 130
_UMASK = os.umask(0)
os.umask(_UMASK)  # read once: the mode of written files follows the umask


@dataclass(frozen=True)
class SheetRow:
    """One facade of the sheet.

    Attributes
    ----------
    title : str
        Row label, e.g. ``"best 1 · cmp_b0012 · mIoU 0.612"``.
    photo : (H, W, 3) uint8
    truth : (H, W) uint8
        Class indices, :data:`~facadeforge.datasets.IGNORE` where not scored.
    prediction : (H, W) uint8
        Class indices in the photo's frame, :data:`~facadeforge.datasets.IGNORE` where the method
        gave none.
    """

    title: str
    photo: np.ndarray
    truth: np.ndarray
    prediction: np.ndarray


def error_map(truth: np.ndarray, prediction: np.ndarray) -> np.ndarray:
    """Error picture of a prediction.

    Parameters
    ----------
    truth, prediction : (H, W) uint8
        Class indices; :data:`IGNORE` in ``truth`` is not scored, in ``prediction`` it is wrong.

    Returns
    -------
    (H, W, 3) uint8
        :data:`RIGHT_COLOR`, :data:`WRONG_COLOR` or :data:`IGNORED_COLOR` per pixel.
    """
    out = np.empty((*truth.shape, 3), np.uint8)
    out[:] = RIGHT_COLOR
    out[truth != prediction] = WRONG_COLOR
    out[truth == IGNORE] = IGNORED_COLOR
    return out


def _colour(index_map: np.ndarray, label_set: LabelSet, ignore: tuple[int, int, int]
            ) -> np.ndarray:
    table = np.zeros((256, 3), np.uint8)
    table[:] = ignore
    table[:label_set.num_classes] = label_set.colors
    return table[np.asarray(index_map, np.uint8)]


def _font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    try:
        return ImageFont.load_default(size=size)
    except (TypeError, OSError):  # Pillow without FreeType: the fixed bitmap font
        return ImageFont.load_default()


def _panel(arr: np.ndarray, height: int, nearest: bool) -> Image.Image:
    h, w = arr.shape[:2]
    width = max(1, round(w * height / max(h, 1)))
    resample = Image.Resampling.NEAREST if nearest else Image.Resampling.BILINEAR
    return Image.fromarray(arr).resize((width, height), resample)


def write_sheet(rows: Sequence[SheetRow], label_set: LabelSet, path: str | Path,
                panel_height: int = 240, title: str = "") -> Path:
    """Draw the sheet and save it as PNG (atomically: temporary file, then rename).

    Parameters
    ----------
    rows : sequence of SheetRow
        Facades, top to bottom.
    label_set : LabelSet
        Colours and class names.
    path : str or Path
        Output PNG.
    panel_height : int
        Height of each panel in pixels; widths keep the photo's aspect ratio.
    title : str
        Line written above the rows.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    font = _font(14)
    small = _font(12)
    ignore = label_set.ignore_color or UNPREDICTED_COLOR
    line = 18
    blocks: list[tuple[str, list[Image.Image]]] = []
    for row in rows:
        panels = [
            _panel(np.asarray(row.photo, np.uint8), panel_height, nearest=False),
            _panel(_colour(row.truth, label_set, ignore), panel_height, nearest=True),
            _panel(_colour(row.prediction, label_set, UNPREDICTED_COLOR), panel_height,
                   nearest=True),
            _panel(error_map(row.truth, row.prediction), panel_height, nearest=True),
        ]
        blocks.append((row.title, panels))
    heads = ("photo", "truth", "prediction", "error (red wrong, grey ignored)")
    col_width = max([p.width for _, ps in blocks for p in ps] + [200])
    width = _PAD + 4 * (col_width + _PAD)
    per_row = max(1, (width - _PAD) // _LEGEND_STEP)
    legend_rows = 1 + (label_set.num_classes - 1) // per_row
    height = (_PAD + (line if title else 0) + line
              + len(blocks) * (line + panel_height + _PAD) + legend_rows * line + _PAD)
    sheet = Image.new("RGB", (width, height), _BACKGROUND)
    draw = ImageDraw.Draw(sheet)
    y = _PAD
    if title:
        draw.text((_PAD, y), title, fill=_TEXT, font=font)
        y += line
    for i, head in enumerate(heads):
        draw.text((_PAD + i * (col_width + _PAD), y), head, fill=_TEXT, font=small)
    y += line
    for row_title, panels in blocks:
        draw.text((_PAD, y), row_title, fill=_TEXT, font=font)
        y += line
        for i, panel in enumerate(panels):
            sheet.paste(panel, (_PAD + i * (col_width + _PAD), y))
        y += panel_height + _PAD
    for i, name in enumerate(label_set.dataset_names):   # the dataset's own class names
        x = _PAD + (i % per_row) * _LEGEND_STEP
        yy = y + (i // per_row) * line
        draw.rectangle((x, yy + 2, x + 12, yy + 14), fill=tuple(int(c) for c in
                                                              label_set.colors[i]),
                       outline=_TEXT)
        draw.text((x + 18, yy), name, fill=_TEXT, font=small)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    os.close(fd)
    try:
        sheet.save(tmp, format="PNG")
        os.chmod(tmp, 0o666 & ~_UMASK)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
