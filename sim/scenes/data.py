"""Test and demo images: the Middlebury 2014 motorcycle pair shipped with scikit-image."""
from functools import lru_cache
from pathlib import Path

import numpy as np

__all__ = ["motorcycle", "crop", "parse_crop"]


@lru_cache(maxsize=1)
def motorcycle():
    """(left, right, disparity): two (500, 741, 3) uint8 RGB images and the float32 ground-truth
    disparity of the left image (inf where unknown), what ``skimage.data.stereo_motorcycle()``
    returns, read here straight from scikit-image's data folder (importing ``skimage.data``
    costs about a second, half a warm ``sim run``)."""
    import importlib.util
    from PIL import Image
    folder = Path(importlib.util.find_spec("skimage").origin).parent / "data"
    left, right = (np.asarray(Image.open(folder / f"motorcycle_{side}.png").convert("RGB"))
                   for side in ("left", "right"))
    with np.load(folder / "motorcycle_disp.npz") as data:
        disp = data["arr_0"]
    return left, right, disp


def parse_crop(spec):
    """Parse 'WxH+X+Y' into (w, h, x, y); ValueError on anything else."""
    try:
        size, x, y = spec.split("+")
        w, h = size.lower().split("x")
        w, h, x, y = int(w), int(h), int(x), int(y)
    except ValueError:
        raise ValueError(f"crop {spec!r} is not of the form WxH+X+Y") from None
    if w < 1 or h < 1 or x < 0 or y < 0:
        raise ValueError(f"crop {spec!r} has a non-positive size or a negative offset")
    return w, h, x, y


def crop(image, w, h, x, y):
    """The w x h window at (x, y); ValueError when it does not fit inside the image."""
    ih, iw = image.shape[:2]
    if x + w > iw or y + h > ih:
        raise ValueError(f"crop {w}x{h}+{x}+{y} falls outside the {iw}x{ih} image")
    return np.ascontiguousarray(image[y:y + h, x:x + w])
