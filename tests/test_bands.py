"""Per-band obstacle summary: the golden rule (golden/bands.py) against the firmware's radio
summary (station.radio.summarise_matches, itself checked against the C firmware), per frame and
merged over frames, with ties, empty bands and ignored records; the divide-free band table."""
import numpy as np
import pytest

from golden.bands import (MAX_BANDS, SLOTS, band_from_table, band_of_column, band_values,
                          check_config, column_table, frame_top, frames_of_records, merge_tops,
                          summary_words, table_shift, words_to_top)
from station.radio import summarise_matches


def random_records(rng, n, width, *, d_max=255, ties=False):
    """(x, d) int64 arrays: columns partly past the frame, some d = 0, and with ``ties`` few
    distinct disparities."""
    x = rng.integers(0, width + width // 8 + 1, n)
    d = rng.integers(0, 4 if ties else d_max + 1, n)
    return x.astype(np.int64), d.astype(np.int64)


def reference(x, d, width, n_bands, k):
    return np.array(summarise_matches(zip(x.tolist(), [0] * len(x), d.tolist()), width,
                                      n_bands, k), dtype=np.uint8)


@pytest.mark.parametrize("width, n_bands", [(720, 32), (720, 64), (1, 1), (64, 64), (1024, 1),
                                            (1024, 64), (100, 7), (33, 32)])
def test_frame_summary_equals_firmware_rule(width, n_bands):
    rng = np.random.default_rng(width * 100 + n_bands)
    for trial in range(6):
        n = int(rng.choice([0, 1, 5, 50, 3000]))
        x, d = random_records(rng, n, width, ties=trial % 2 == 1)
        top = frame_top(x, d, width, n_bands)
        assert top.dtype == np.uint8 and top.shape == (n_bands, SLOTS)
        assert (np.diff(top.astype(np.int64), axis=1) <= 0).all()      # descending
        for k in range(1, SLOTS + 1):
            assert np.array_equal(band_values(top, k), reference(x, d, width, n_bands, k))


def test_frames_merge_to_the_report_of_their_records():
    """The firmware merges the frames of a report period: the same as summarising all their
    records at once, for every min_support the unit keeps."""
    rng = np.random.default_rng(5)
    width, n_bands = 720, 32
    frames = [random_records(rng, int(rng.integers(0, 400)), width, ties=bool(k % 2))
              for k in range(7)]
    merged = merge_tops([frame_top(x, d, width, n_bands) for x, d in frames])
    allx = np.concatenate([x for x, _ in frames])
    alld = np.concatenate([d for _, d in frames])
    for k in range(1, SLOTS + 1):
        assert np.array_equal(band_values(merged, k), reference(allx, alld, width, n_bands, k))


def test_no_records_empty_bands_and_ties():
    assert not frame_top([], [], 720, 32).any()
    # one band, more equal disparities than slots: every slot holds the value
    top = frame_top([3] * 9 + [4], [7] * 9 + [200], 720, 32)
    assert top[0].tolist() == [200, 7, 7, 7] and not top[1:].any()
    # records past the frame and d = 0 are ignored; fewer matches than slots leave zeros
    top = frame_top([719, 720, 1000, 5], [9, 50, 60, 0], 720, 32)
    assert top[31].tolist() == [9, 0, 0, 0] and top.sum() == 9
    assert band_values(top, 1)[31] == 9 and band_values(top, 2)[31] == 0
    with pytest.raises(ValueError):
        band_values(top, SLOTS + 1)


def test_frames_of_records_publish_and_abort():
    x = [1, 2, 0, 3, 0, 4, 5]
    d = [9, 8, 0, 7, 0, 6, 5]
    eof = [0, 0, 1, 0, 1, 0, 0]
    abort = [0, 0, 0, 0, 1, 0, 0]
    frames, aborted = frames_of_records(x, d, eof, abort)
    assert aborted == 1 and len(frames) == 1
    assert frames[0][0].tolist() == [1, 2] and frames[0][1].tolist() == [9, 8]


def test_band_boundaries():
    # band i starts at floor(i * width / n): 720 / 32 = 22.5
    b = band_of_column(np.arange(720), 720, 32)
    starts = np.flatnonzero(np.diff(b)) + 1
    assert starts.tolist() == [i * 720 // 32 for i in range(1, 32)]
    assert b[0] == 0 and b[-1] == 31


def table_cases():
    rng = np.random.default_rng(3)
    cases = [(1, 1), (2, 1), (2, 2), (64, 64), (128, 64), (129, 64), (256, 64), (257, 64),
             (512, 64), (513, 64), (1024, 64), (1024, 1), (720, 32), (720, 64), (752, 63),
             (1023, 64), (100, 3)]
    for _ in range(300):
        n = int(rng.integers(1, MAX_BANDS + 1))
        cases.append((int(rng.integers(n, 1025)), n))
    return cases


def test_band_table_equals_the_division():
    for width, n_bands in table_cases():
        table = column_table(width, n_bands)
        x = np.arange(width)
        assert np.array_equal(band_from_table(x, table), band_of_column(x, width, n_bands)), \
            (width, n_bands)
        assert width <= 128 << table_shift(width)


def test_config_limits():
    check_config(1024, 64)
    for width, n_bands in ((10, 11), (1025, 1), (100, 0), (100, 65)):
        with pytest.raises(ValueError):
            check_config(width, n_bands)


def test_register_words_round_trip():
    rng = np.random.default_rng(1)
    for slots in (1, 3, 4, 5, 8):
        top = rng.integers(0, 256, (9, slots)).astype(np.uint8)
        words = summary_words(top)
        assert words.dtype == np.uint32 and words.size == 9 * -(-slots // 4)
        assert np.array_equal(words_to_top(words, 9, slots), top)
    assert summary_words(np.array([[1, 2, 3, 4]], dtype=np.uint8)).tolist() == [0x04030201]
