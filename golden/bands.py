"""Per-band obstacle summary of the result records: the hardware unit ``hdl/bands.py`` that
hands the CPU, once a frame, what the radio report needs instead of every record.

The radio report (firmware ``radio_summary_*``, its Python twin
:func:`station.radio.summarise_matches`) gives each of ``n_bands`` column bands the
``min_support``-th largest disparity of the matches in the band over the report period, 0 when
the band has fewer. The ``k``-th largest of a union of sets is the ``k``-th largest of the
union of each set's ``k`` largest, so the hardware keeps, per frame and band, the ``SLOTS``
largest disparities and the firmware merges the frames of a period (any ``min_support`` <=
``SLOTS``): the report is exactly the one the firmware computes from the same frames' records.

Rule, per frame (the records since the previous end-of-frame marker):

1. A record is a match when it is no marker (``eof`` = 0), ``x < width`` and ``d > 0``
   (the firmware ignores the others).
2. Its band is ``((x + 1) * n_bands - 1) // width`` (:func:`band_of_column`, the firmware's
   ``radio_band_of_column``): band ``i`` covers columns ``floor(i * width / n_bands)`` up to
   ``floor((i + 1) * width / n_bands) - 1``.
3. The frame's summary (:func:`frame_top`) is, per band, its ``SLOTS`` largest match
   disparities in descending order, padded with 0 (no match has d = 0): a multiset, so ties
   need no rule; a band with fewer than ``SLOTS`` matches shows zeros in its last slots.
4. An end-of-frame marker (``eof``) publishes the frame; one with ``abort`` (the frame was cut
   by a restart of the video path) discards it; records after the last marker belong to a
   frame that has not ended (:func:`frames_of_records`).

The firmware's report of a set of frames is :func:`band_values` of :func:`merge_tops` of
their summaries.

No divide in hardware: the band of a column comes from a table of ``2**TABLE_BITS`` buckets
of ``2**shift`` columns (:func:`column_table`), each at most as wide as the narrowest band, so
a bucket holds at most one band start: ``band = base + (x % 2**shift >= start)``
(:func:`band_from_table`). The unit fills the table by stepping ``(x + 1) * n_bands - 1``
through the columns with an add and a compare per column (:func:`table_walk`).
"""
import numpy as np

__all__ = ["SLOTS", "MAX_BANDS", "TABLE_BITS", "MAX_WIDTH", "band_of_column", "frame_top",
           "frames_of_records", "merge_tops", "band_values", "table_shift", "column_table",
           "table_walk", "band_from_table", "check_config", "summary_words", "words_to_top"]

#: Disparities kept per band and frame: reports with ``min_support`` up to this are exact.
SLOTS = 4
#: Most bands (the radio payload's limit).
MAX_BANDS = 64
#: Widest frame (x < MAX_WIDTH; hdl/regmap.py MAX_WIDTH).
MAX_WIDTH = 1024
#: Buckets of the column table: 2**TABLE_BITS; 2**(TABLE_BITS - 1) >= MAX_BANDS.
TABLE_BITS = 7


def check_config(width, n_bands, *, max_width=MAX_WIDTH, max_bands=MAX_BANDS):
    """Raise ValueError unless ``1 <= n_bands <= max_bands`` and ``n_bands <= width <=
    max_width`` (what the unit accepts; it drops every record otherwise)."""
    if not 1 <= n_bands <= max_bands:
        raise ValueError(f"n_bands={n_bands} outside 1..{max_bands}")
    if not n_bands <= width <= max_width:
        raise ValueError(f"width={width} outside n_bands..{max_width} ({n_bands}..{max_width})")


def band_of_column(x, width, n_bands):
    """Band (int64 array) of columns ``x`` (< width): ``((x + 1) * n_bands - 1) // width``."""
    x = np.asarray(x, dtype=np.int64)
    return ((x + 1) * np.int64(n_bands) - 1) // np.int64(width)


def frame_top(x, d, width, n_bands, slots=SLOTS):
    """One frame's summary: uint8 array (n_bands, slots), per band its ``slots`` largest
    disparities of the matches (x < width, d > 0) in descending order, then zeros."""
    x = np.asarray(x, dtype=np.int64)
    d = np.asarray(d, dtype=np.int64)
    keep = (x >= 0) & (x < width) & (d > 0)
    x, d = x[keep], d[keep]
    top = np.zeros((n_bands, slots), dtype=np.uint8)
    if x.size == 0:
        return top
    band = band_of_column(x, width, n_bands)
    order = np.lexsort((-d, band))          # by band, then descending disparity
    band, d = band[order], d[order]
    first = np.searchsorted(band, np.arange(n_bands), side="left")
    rank = np.arange(band.size, dtype=np.int64) - first[band]
    sel = rank < slots
    top[band[sel], rank[sel]] = d[sel].astype(np.uint8)
    return top


def frames_of_records(x, d, eof, abort):
    """Cut a record stream into frames: a list of (x, d) int64 array pairs, one per published
    frame (an ``eof`` marker without ``abort``), and the number of aborted frames. Marker
    records carry no match; records after the last marker are not in any frame."""
    x, d = np.asarray(x, dtype=np.int64), np.asarray(d, dtype=np.int64)
    eof, abort = np.asarray(eof, dtype=bool), np.asarray(abort, dtype=bool)
    frames, aborted, start = [], 0, 0
    for end in np.flatnonzero(eof):
        if abort[end]:
            aborted += 1
        else:
            frames.append((x[start:end], d[start:end]))
        start = end + 1
    return frames, aborted


def merge_tops(tops, slots=SLOTS):
    """Summary of the union of the frames whose summaries are ``tops`` (each (n_bands, >=
    slots) uint8): per band the ``slots`` largest of all their slots, descending."""
    tops = [np.asarray(t, dtype=np.uint8) for t in tops]
    allv = np.concatenate(tops, axis=1).astype(np.int64)
    return (-np.sort(-allv, axis=1))[:, :slots].astype(np.uint8)


def band_values(top, min_support):
    """The radio report's band values (uint8, one per band) from a summary: the
    ``min_support``-th largest disparity, 0 when a band has fewer matches (``min_support`` <=
    the summary's slots)."""
    top = np.asarray(top, dtype=np.uint8)
    if not 1 <= min_support <= top.shape[1]:
        raise ValueError(f"min_support={min_support} outside 1..{top.shape[1]}")
    return top[:, min_support - 1].copy()


def table_shift(width, *, table_bits=TABLE_BITS):
    """log2 of the columns per bucket: the least ``s`` with ``width <= 2**(s + table_bits)``."""
    s = 0
    while width > 1 << (s + table_bits):
        s += 1
    return s


def column_table(width, n_bands, *, table_bits=TABLE_BITS):
    """The band table of a configuration: ``(shift, base, has, start)``, int64 arrays of
    ``2**table_bits`` buckets (columns ``c * 2**shift`` onwards): ``base`` the band of the
    bucket's first column, ``has`` 1 when another band starts inside the bucket, at column
    offset ``start`` (0 otherwise). Buckets past the frame hold zeros. The table is what
    :func:`table_walk` writes (the hardware's fill), so it is defined by that walk."""
    return table_walk(width, n_bands, table_bits=table_bits)


def table_walk(width, n_bands, *, table_bits=TABLE_BITS):
    """Fill the band table as the hardware does, one column a cycle with no divide:
    ``r = (x + 1) * n_bands - 1 - band * width`` stays in ``0..width - 1``; from one column to
    the next ``r += n_bands`` and, when that reaches ``width``, ``r -= width`` and the band
    steps (at most by one: ``n_bands <= width``). A bucket's first column writes its ``base``;
    a band step at another column writes ``has`` and ``start``."""
    check_config(width, n_bands, max_width=1 << 30, max_bands=1 << (table_bits - 1))
    shift = table_shift(width, table_bits=table_bits)
    size = 1 << table_bits
    base = np.zeros(size, dtype=np.int64)
    has = np.zeros(size, dtype=np.int64)
    start = np.zeros(size, dtype=np.int64)
    band, r, stepped = 0, n_bands - 1, False
    for x in range(width):
        c, low = x >> shift, x & ((1 << shift) - 1)
        if low == 0:
            base[c], has[c], start[c] = band, 0, 0
        elif stepped:
            has[c], start[c] = 1, low
        r += n_bands
        stepped = r >= width
        if stepped:
            r -= width
            band += 1
    return shift, base, has, start


def band_from_table(x, table):
    """Band (int64) of columns ``x`` from a :func:`column_table`."""
    shift, base, has, start = table
    x = np.asarray(x, dtype=np.int64)
    c, low = x >> shift, x & ((1 << shift) - 1)
    return base[c] + (has[c] & (low >= start[c]))


def summary_words(top):
    """A summary as the unit's registers show it: per band ``ceil(slots / 4)`` 32-bit words
    (uint32), slot ``j`` in bits ``8 (j % 4)`` of word ``j // 4`` (the largest in bits 7..0)."""
    top = np.asarray(top, dtype=np.uint8)
    n, slots = top.shape
    per = -(-slots // 4)
    padded = np.zeros((n, per * 4), dtype=np.uint32)
    padded[:, :slots] = top
    padded = padded.reshape(n, per, 4)
    words = (padded[..., 0] | padded[..., 1] << 8 | padded[..., 2] << 16 | padded[..., 3] << 24)
    return words.reshape(n * per).astype(np.uint32)


def words_to_top(words, n_bands, slots=SLOTS):
    """Inverse of :func:`summary_words`."""
    per = -(-slots // 4)
    w = np.asarray(words, dtype=np.uint32).reshape(n_bands, per)
    b = np.stack([(w >> (8 * k)) & 0xFF for k in range(4)], axis=-1).reshape(n_bands, per * 4)
    return b[:, :slots].astype(np.uint8)
