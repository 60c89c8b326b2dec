"""The simulation helpers every unit test relies on: packing, framing, malformed cases."""
import numpy as np
import pytest

from golden.frontend import FrontEndParams
from golden.ground import GroundParams
from hdl.ground import GroundClassifier, GroundConfig
from hdl.types import RGBPixel, frame_layout
from sim.config import config_values
from sim.designs import silenced
from sim.streams import Packer, frame_words, frames_words, words_to_frames, malformed_cases, Reset


def test_pack_matches_the_struct_layout():
    p = Packer(RGBPixel)
    word = int(p.pack(r=1, g=2, b=3, sof=1, eol=0, eof=1))
    assert word == 1 | 2 << 8 | 3 << 16 | 1 << 24 | 1 << 26
    assert {k: int(v[0]) for k, v in p.unpack([word]).items()} == \
        dict(r=1, g=2, b=3, sof=1, eol=0, eof=1)


def test_wide_layouts_pack_as_python_ints_and_refuse_arrays():
    """The ground configuration is 82 bits: packing it into uint64 lost the top fields once."""
    p = Packer(GroundConfig)
    assert p.width > 64
    params = GroundParams(s_min=200, hue_centre0=150, luma_centre0=77)
    word = config_values(silenced(GroundClassifier(max_width=8, max_height=8)),
                         FrontEndParams(ground=params))["config"]
    for name, _ in GroundParams.FIELDS:
        offset, width = p.fields[name]
        assert (word >> offset) & ((1 << width) - 1) == int(getattr(params, name)), name
    with pytest.raises(ValueError, match="pack_int"):
        p.pack(s_min=1)


def test_frames_round_trip_and_flags():
    rng = np.random.default_rng(0)
    p = Packer(frame_layout(v=8))
    frames = [dict(v=rng.integers(0, 256, (h, w))) for h, w in ((3, 5), (1, 1), (2, 7))]
    words = frames_words(p, frames)
    flags = p.unpack(words)
    assert flags["sof"].sum() == 3 and flags["eof"].sum() == 3 and flags["eol"].sum() == 6
    back = words_to_frames(p, words)
    assert all(np.array_equal(a["v"], b["v"]) for a, b in zip(frames, back))


def test_words_to_frames_rejects_bad_framing():
    p = Packer(frame_layout(v=8))
    words = [int(w) for w in frame_words(p, dict(v=np.zeros((2, 4), dtype=np.uint8)))]
    with pytest.raises(ValueError):
        words_to_frames(p, words[:-1])                 # no eof
    bad_eol = list(words)
    bad_eol[5] ^= 1 << p.fields["eol"][0]            # an eol in the middle of line 1
    with pytest.raises(ValueError, match="unequal"):
        words_to_frames(p, bad_eol)


def test_malformed_cases_are_what_they_say():
    p = Packer(frame_layout(v=8))
    frame = dict(v=np.arange(20, dtype=np.uint8).reshape(4, 5))
    cases = malformed_cases(p, frame)
    f = lambda words: p.unpack([w for w in words if not isinstance(w, Reset)])
    assert f(cases["missing_sof"][0])["sof"].sum() == 0
    assert len(cases["short_line"][0]) == 18 and len(cases["long_line"][0]) == 22
    assert f(cases["eof_without_eol"][0])["eol"][-1] == 0
    assert f(cases["cut_short"][0])["eof"].sum() == 0
    assert any(isinstance(w, Reset) for w in cases["reset"][0])
    with pytest.raises(ValueError):
        malformed_cases(p, dict(v=np.zeros((2, 5), dtype=np.uint8)))
