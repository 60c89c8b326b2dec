"""Small raster drawing kit for the run views (:mod:`sim.cli.views`): PIL and NumPy only.

matplotlib's import and drawing would take most of a warm ``python -m sim run``; these views
are images with a few marks, so they are drawn directly:
an RGB :class:`Canvas`, text in Pillow's built-in FreeType font, colour maps as polynomial
fits, axes with round ticks, colour bars and legends. PNGs are written with zlib level 1.
"""
import math
import threading

import numpy as np
from PIL import Image, ImageDraw, ImageFont

__all__ = ["Canvas", "Axes", "Norm", "turbo", "viridis", "hsv_to_rgb", "nice_ticks", "PNG_LEVEL"]

#: zlib level of the written PNGs: level 1 encodes much faster than the default 6 for files
#: a little larger.
PNG_LEVEL = 1
#: Pixel sizes of the fonts (matplotlib's 7, 9 and 10 points at 100 dpi).
SMALL, MEDIUM, LARGE = 10, 12, 13


_fonts = threading.local()     # a FreeType face must not be shared between threads


def font(px):
    cache = _fonts.__dict__.setdefault("by_size", {})
    if px not in cache:
        cache[px] = ImageFont.load_default(px)
    return cache[px]


def colour(c):
    """An RGB uint8 triple from ``"#rrggbb"``, a grey level string (``"0.6"``) or floats in
    0..1."""
    if isinstance(c, str):
        if c.startswith("#"):
            return tuple(int(c[k:k + 2], 16) for k in (1, 3, 5))
        return (round(float(c) * 255),) * 3
    return tuple(int(round(v * 255)) for v in c[:3])


# --- colour maps --------------------------------------------------------------------------

def turbo(t):
    """Google's Turbo colour map (polynomial fit by its author), ``t`` in 0..1 -> float RGB."""
    t = np.clip(np.asarray(t, dtype=np.float64), 0, 1)[..., None]
    c = np.array([[0.13572138, 0.09140261, 0.10667330], [4.61539260, 2.19418839, 12.64194608],
                  [-42.66032258, 4.84296658, -60.58204836], [132.13108234, -14.18503333, 110.36276771],
                  [-152.94239396, 4.27729857, -89.90310912], [59.28637943, 2.82956604, 27.34824973]])
    return np.clip(sum(c[k] * t ** k for k in range(6)), 0, 1)


def viridis(t):
    """matplotlib's viridis (a sixth-degree polynomial fit), ``t`` in 0..1 -> float RGB."""
    t = np.clip(np.asarray(t, dtype=np.float64), 0, 1)[..., None]
    c = np.array([[0.2777273272234177, 0.005407344544966578, 0.3340998053353061],
                  [0.1050930431085774, 1.404613529898575, 1.384590162594685],
                  [-0.3308618287255563, 0.214847559468213, 0.09509516302823659],
                  [-4.634230498983486, -5.799100973351585, -19.33244095627987],
                  [6.228269936347081, 14.17993336680509, 56.69055260068105],
                  [4.776384997670288, -13.74514537774601, -65.35303263337234],
                  [-5.435455855934631, 4.645852612178535, 26.3124352495832]])
    return np.clip(sum(c[k] * t ** k for k in range(7)), 0, 1)


def hsv_to_rgb(h, s, v):
    """HSV (arrays in 0..1) to float RGB, as matplotlib.colors.hsv_to_rgb."""
    h, s, v = (np.asarray(a, dtype=np.float64) for a in (h, s, v))
    i = np.floor(h * 6).astype(int) % 6
    f = h * 6 - np.floor(h * 6)
    p, q, t = v * (1 - s), v * (1 - s * f), v * (1 - s * (1 - f))
    table = np.stack([np.stack(x, -1) for x in ((v, t, p), (q, v, p), (p, v, t), (p, q, v),
                                                 (t, p, v), (v, p, q))])
    return np.take_along_axis(table, i[None, ..., None].repeat(3, -1), 0)[0]


def to_uint8(rgb):
    return np.clip(np.rint(np.asarray(rgb) * 255), 0, 255).astype(np.uint8)


# --- scales -------------------------------------------------------------------------------

def nice_ticks(lo, hi, most=8):
    """Round tick values within lo..hi (steps of 1, 2, 2.5 or 5 times a power of ten)."""
    if not hi > lo:
        return [lo]
    raw = (hi - lo) / max(1, most - 1)
    base = 10 ** math.floor(math.log10(raw))
    step = next(m * base for m in (1, 2, 2.5, 5, 10) if m * base >= raw)
    first = math.ceil(lo / step - 1e-9)
    ticks = [k * step for k in range(first, int(math.floor(hi / step + 1e-9)) + 1)]
    return [round(t, 10) for t in ticks]


class Norm:
    """Value -> 0..1, linear or logarithmic; ``ticks()`` gives round values to label."""

    def __init__(self, vmin, vmax, log=False):
        self.vmin, self.vmax, self.log = float(vmin), float(vmax), log
        if not self.vmax > self.vmin:
            self.vmax = self.vmin + (abs(self.vmin) * 0.01 or 1.0)

    def __call__(self, v):
        v = np.asarray(v, dtype=np.float64)
        if self.log:
            with np.errstate(divide="ignore", invalid="ignore"):
                return (np.log(v) - math.log(self.vmin)) / math.log(self.vmax / self.vmin)
        return (v - self.vmin) / (self.vmax - self.vmin)

    def ticks(self):
        if not self.log:
            return nice_ticks(self.vmin, self.vmax)
        ticks = [t for t in (0.3, 0.4, 0.5, 0.6, 0.8, 1, 1.2, 1.5, 2, 2.5, 3, 4, 5, 6, 8, 10,
                             12, 15, 20, 25, 30, 40, 50, 60, 80, 100)
                 if self.vmin <= t <= self.vmax]
        return ticks[::max(1, math.ceil(len(ticks) / 10))]


def label(v):
    return f"{v:g}"


# --- the canvas ---------------------------------------------------------------------------

class Canvas:
    """A white RGB image to draw on; ``pixels`` is its NumPy view (h, w, 3), ``draw`` a
    PIL ImageDraw on the same image (call :meth:`sync` after changing one before the other)."""

    def __init__(self, width, height):
        self.width, self.height = int(round(width)), int(round(height))
        self.pixels = np.full((self.height, self.width, 3), 255, np.uint8)
        self._image = None

    @property
    def image(self):
        if self._image is None:
            self._image = Image.fromarray(self.pixels)
            self.draw = ImageDraw.Draw(self._image)
        return self._image

    def sync(self):
        """Bring the NumPy view up to date after PIL drawing (and back)."""
        if self._image is not None:
            self.pixels = np.array(self._image)
            self._image = None

    def text(self, xy, s, size=SMALL, anchor="la", fill=(0, 0, 0)):
        self.image
        self.draw.text(xy, s, font=font(size), anchor=anchor, fill=fill)

    def text_width(self, s, size=SMALL):
        return font(size).getlength(s)

    def vtext(self, xy, s, size=SMALL):
        """Text turned 90 degrees counter-clockwise, centred on ``xy``."""
        f = font(size)
        w, h = int(f.getlength(s)) + 2, size + 4
        tile = Image.new("L", (w, h), 0)
        ImageDraw.Draw(tile).text((1, 1), s, font=f, fill=255)
        tile = tile.rotate(90, expand=True)
        self.image.paste((0, 0, 0), (int(xy[0] - tile.width / 2), int(xy[1] - tile.height / 2)),
                         tile)

    def blend(self, box, rgb, alpha):
        """Blend the box (x0, y0, x1, y1) with a colour at opacity ``alpha``."""
        self.sync()
        x0, y0, x1, y1 = (int(round(v)) for v in box)
        x0, y0 = max(0, x0), max(0, y0)
        part = self.pixels[y0:y1, x0:x1].astype(np.float32)
        part += alpha * (np.asarray(colour(rgb), np.float32) - part)
        self.pixels[y0:y1, x0:x1] = np.rint(part).astype(np.uint8)

    def paste(self, array, xy):
        self.sync()
        h, w = array.shape[:2]
        x, y = int(xy[0]), int(xy[1])
        self.pixels[y:y + h, x:x + w] = array

    def title(self, s, y=8):
        self.text((self.width * 0.01, y), s, size=MEDIUM, anchor="lt")

    def legend(self, xy, items, *, corner="lower left", title=None, size=SMALL, alpha=0.85):
        """A legend box: ``items`` of (mark, colour, text), mark one of ``"patch"``,
        ``"outline"``, ``"x"``, ``"square"``, ``"dot"``, ``"dashed"``; ``xy``: the corner of the
        area (``corner``) the box sits in."""
        row = size + 5
        widths = [self.text_width(t, size) + 28 for _, _, t in items]
        if title:
            widths.append(self.text_width(title, size) + 10)
        w = max(widths) + 8
        h = row * (len(items) + bool(title)) + 8
        x0 = xy[0] if "left" in corner else xy[0] - w
        y0 = xy[1] - h if "lower" in corner else xy[1]
        self.blend((x0, y0, x0 + w, y0 + h), (1, 1, 1), alpha)
        self.image
        self.draw.rectangle((x0, y0, x0 + w, y0 + h), outline=(204, 204, 204))
        y = y0 + 5
        if title:
            self.text((x0 + w / 2, y + size / 2), title, size, anchor="mm")
            y += row
        for mark, c, t in items:
            cy = y + size / 2
            mx = x0 + 6
            rgb = colour(c) if c is not None else None
            if mark == "patch":
                self.draw.rectangle((mx, cy - 4, mx + 18, cy + 4), fill=rgb)
            elif mark == "outline":
                self.draw.rectangle((mx, cy - 4, mx + 18, cy + 4), outline=rgb, width=2)
            elif mark == "x":
                self.draw.line((mx + 6, cy - 3, mx + 12, cy + 3), fill=rgb, width=1)
                self.draw.line((mx + 6, cy + 3, mx + 12, cy - 3), fill=rgb, width=1)
            elif mark == "square":
                self.draw.rectangle((mx + 7, cy - 2, mx + 11, cy + 2), fill=rgb, outline=(0, 0, 0))
            elif mark == "dot":
                self.draw.ellipse((mx + 7, cy - 2, mx + 11, cy + 2), fill=rgb)
            elif mark == "dashed":
                for a in range(0, 18, 6):
                    self.draw.line((mx + a, cy, mx + a + 3, cy), fill=rgb, width=1)
            self.text((mx + 24, cy), t, size, anchor="lm")
            y += row

    def colorbar(self, box, cmap, norm, text, size=SMALL):
        """A vertical colour bar in ``box`` (x0, y0, x1, y1), the low end at the bottom, with
        round ticks, the ends pointed (values beyond them take the end colours) and ``text``
        along its right side."""
        x0, y0, x1, y1 = (int(round(v)) for v in box)
        tip = max(4, (x1 - x0) // 2)
        y0i, y1i = y0 + tip, y1 - tip
        t = np.linspace(1, 0, max(1, y1i - y0i))
        strip = to_uint8(cmap(t))[:, None, :].repeat(x1 - x0, axis=1)
        self.paste(strip, (x0, y0i))
        self.image
        top, bottom = colour(cmap(np.array(1.0))), colour(cmap(np.array(0.0)))
        self.draw.polygon([(x0, y0i), (x1 - 1, y0i), ((x0 + x1 - 1) / 2, y0)], fill=top,
                          outline=(0, 0, 0))
        self.draw.polygon([(x0, y1i), (x1 - 1, y1i), ((x0 + x1 - 1) / 2, y1)], fill=bottom,
                          outline=(0, 0, 0))
        self.draw.rectangle((x0, y0i, x1 - 1, y1i), outline=(0, 0, 0))
        widest = 0
        for v in norm.ticks():
            f = float(norm(v))
            if not 0 <= f <= 1:
                continue
            y = y1i - f * (y1i - y0i)
            self.draw.line((x1, y, x1 + 3, y), fill=(0, 0, 0))
            s = label(v)
            self.text((x1 + 5, y), s, size - 1, anchor="lm")
            widest = max(widest, self.text_width(s, size - 1))
        self.vtext((x1 + 5 + widest + 4 + size / 2 + 2, (y0 + y1) / 2), text, size)

    def save(self, path):
        self.image.save(path, compress_level=PNG_LEVEL)
        return path


class Axes:
    """A plot area ``box`` (x0, y0, x1, y1 in canvas pixels) for data in ``xlim`` x ``ylim``
    (y up), drawn on its own tile (so marks are clipped to the box) and framed with ticks."""

    def __init__(self, canvas, box, xlim, ylim):
        self.canvas, self.box = canvas, tuple(int(round(v)) for v in box)
        self.xlim, self.ylim = xlim, ylim
        x0, y0, x1, y1 = self.box
        self.w, self.h = x1 - x0, y1 - y0
        self.tile = Image.new("RGB", (self.w, self.h), (255, 255, 255))
        self.draw = ImageDraw.Draw(self.tile)

    def px(self, x):
        return (np.asarray(x, dtype=np.float64) - self.xlim[0]) / (self.xlim[1] - self.xlim[0]) * self.w

    def py(self, y):
        return (self.ylim[1] - np.asarray(y, dtype=np.float64)) / (self.ylim[1] - self.ylim[0]) * self.h

    def points(self, xs, ys):
        return list(zip(self.px(xs).tolist(), self.py(ys).tolist()))

    def blend(self, xspan, rgb, alpha):
        """Shade the data columns xspan = (lo, hi) over the whole height."""
        a = np.array(self.tile)
        c0, c1 = (int(round(float(v))) for v in self.px(xspan))
        c0, c1 = max(0, c0), min(self.w, c1)
        if c1 > c0:
            part = a[:, c0:c1].astype(np.float32)
            part += alpha * (np.asarray(colour(rgb), np.float32) - part)
            a[:, c0:c1] = np.rint(part).astype(np.uint8)
            self.tile = Image.fromarray(a)
            self.draw = ImageDraw.Draw(self.tile)

    def stamp(self, xs, ys, rgb, shape="disc", r=2):
        """Marks at data points ``xs, ys`` coloured ``rgb`` (N x 3 uint8), drawn with NumPy."""
        a = np.array(self.tile)
        stamp_points(a, self.px(xs), self.py(ys), rgb, shape=shape, r=r)
        self.tile = Image.fromarray(a)
        self.draw = ImageDraw.Draw(self.tile)

    def finish(self, *, xticks=None, yticks=None, xlabel=None, ylabel=None, title=None,
               grid=False, size=SMALL, title_size=None):
        """Paste the tile and draw the frame, ticks, labels and title."""
        c, (x0, y0, x1, y1) = self.canvas, self.box
        xticks = nice_ticks(*self.xlim) if xticks is None else xticks
        yticks = nice_ticks(*self.ylim) if yticks is None else yticks
        xs = [(v, float(self.px(v))) for v in xticks if -0.5 <= float(self.px(v)) <= self.w + 0.5]
        ys = [(v, float(self.py(v))) for v in yticks if -0.5 <= float(self.py(v)) <= self.h + 0.5]
        if grid:
            g = ImageDraw.Draw(self.tile)
            for _, x in xs:
                g.line((x, 0, x, self.h), fill=(200, 200, 200))
            for _, y in ys:
                g.line((0, y, self.w, y), fill=(200, 200, 200))
        c.image.paste(self.tile, (x0, y0))
        d = c.draw
        d.rectangle((x0 - 1, y0 - 1, x1, y1), outline=(0, 0, 0))
        for v, x in xs:
            d.line((x0 + x, y1, x0 + x, y1 + 3), fill=(0, 0, 0))
            c.text((x0 + x, y1 + 4), label(v), size, anchor="mt")
        widest = 0
        for v, y in ys:
            d.line((x0 - 4, y0 + y, x0 - 1, y0 + y), fill=(0, 0, 0))
            c.text((x0 - 6, y0 + y), label(v), size, anchor="rm")
            widest = max(widest, c.text_width(label(v), size))
        if xlabel:
            c.text(((x0 + x1) / 2, y1 + 6 + size), xlabel, size, anchor="mt")
        if ylabel:
            c.vtext((x0 - 10 - widest - size / 2, (y0 + y1) / 2), ylabel, size)
        if title:
            c.text(((x0 + x1) / 2, y0 - 4), title, title_size or size, anchor="mb")


def stamp_points(a, xs, ys, rgb, *, shape="square", r=2, edge=None):
    """Draw a mark of radius ``r`` (a (2r+1)-pixel square, disc or x) centred on each pixel
    position ``xs, ys`` of image array ``a`` (h, w, 3), colour ``rgb`` per point (N x 3) or one
    for all; ``edge``: a colour for a square's one-pixel rim (every rim is drawn before every
    inside, so that crowded points keep their colours). Points off the image are clipped."""
    h, w = a.shape[:2]
    xs = np.rint(np.asarray(xs, dtype=np.float64)).astype(np.int64)
    ys = np.rint(np.asarray(ys, dtype=np.float64)).astype(np.int64)
    rgb = np.broadcast_to(np.asarray(rgb, np.uint8), (len(xs), 3))
    offsets = [(dy, dx) for dy in range(-r, r + 1) for dx in range(-r, r + 1)
               if shape == "square" or (shape == "disc" and dx * dx + dy * dy <= r * r + r)
               or (shape == "x" and abs(dx) == abs(dy))]
    if edge is not None and shape == "square":
        rim = [o for o in offsets if max(abs(o[0]), abs(o[1])) == r]
        inside = [o for o in offsets if max(abs(o[0]), abs(o[1])) < r]
        passes = [(rim, np.asarray(edge, np.uint8)), (inside, None)]
    else:
        passes = [(offsets, None)]
    for group, fixed in passes:
        for dy, dx in group:
            y, x = ys + dy, xs + dx
            ok = (y >= 0) & (y < h) & (x >= 0) & (x < w)
            a[y[ok], x[ok]] = fixed if fixed is not None else rgb[ok]


def upscale(image, k):
    """An (h, w, ...) array shown at ``k`` screen pixels per image pixel."""
    return image if k == 1 else image.repeat(k, axis=0).repeat(k, axis=1)
