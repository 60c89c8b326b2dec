"""Free space per column band (specification: ``golden/freespace.py``, rule
:func:`golden.ground.free_space`), and the table that holds its results for the CPU."""
from amaranth.hdl import Module, Signal, Mux, Cat, Const, signed
from amaranth.lib import data, memory, stream, wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import bits_for

from golden.freespace import FREE_BANDS, FREE_NONE, FreeSpaceParams
from .counter import saturating_inc
from .framing import FramedUnit
from .types import GroundPixel, FreeBand

__all__ = ["FreeSpace", "FreeSpaceTable", "free_space_tables", "free_config_ports", "LATENCY",
           "FREE_BITS"]

#: Register width of each run-time parameter (``band_w``, ``run_r``).
FREE_BITS = dict(FreeSpaceParams.FIELDS)
_DEFAULT = FreeSpaceParams()


def free_config_ports():
    """The ``band_w`` and ``run_r`` input ports (with the golden defaults as reset values) of
    the free-space unit and of the components that pass them on."""
    return {name: In(bits, init=getattr(_DEFAULT, name)) for name, bits in FREE_BITS.items()}


#: Cycles from the transfer of the input beat with ``eof`` to the first result beat offered.
LATENCY = 4


class FreeSpace(FramedUnit):
    """Per column band, the row of the lowest obstacle run of at least ``run_r`` rows; bit-exact
    with :func:`golden.ground.free_space`, one frame's 16 results after each frame.

    Ports
    -----
    i : In(stream of :data:`GroundPixel`)
        Ground classifier output. Never applies backpressure (``ready`` is always 1), so it can
        observe another link's transfers: drive ``valid`` with that link's ``valid & ready``.
    o : Out(stream of :data:`FreeBand`)
        16 beats ``(band, row)`` per well-formed input frame, band 0 with ``sof``, band 15 with
        ``eol`` and ``eof``; ``row`` is ``FREE_NONE`` (0xFFFF) for a band without an obstacle
        run or past the image. The first beat comes :data:`LATENCY` cycles after the input
        ``eof``. A frame's results are held until taken; when the next frame ends before they
        are all taken, the newer results are discarded and counted in ``lost`` (the input is
        never held up).
    band_w, run_r : In(11), In(8)
        Columns per band, obstacle rows a run needs (:class:`golden.freespace.FreeSpaceParams`);
        change them between frames.
    errors, dropped : Out(16), Out(32)
        Malformed-stream counters (:mod:`hdl.framing`): a frame cut short gives no results.
    lost : Out(16)
        Result frames discarded because the previous frame's were not yet taken (saturating).

    Pipeline: input register; frame tracker and stage 1 (band position, a running balance of
    obstacle minus ground pixels of the current band); stage 2 at each band's last pixel of a
    row (obstacle-row test, run counter read-modify-write in a 16-word distributed RAM, result
    write); the output register. Results go to a 32-word distributed RAM, two banks of 16
    {found, row}: one filled by the current frame, the other read by the output. A band's
    state needs no clearing pass: row 0 of a frame writes every band it covers afresh.
    """

    i: In(stream.Signature(GroundPixel))
    o: Out(stream.Signature(FreeBand))
    band_w: free_config_ports()["band_w"]
    run_r: free_config_ports()["run_r"]
    errors: Out(16)
    dropped: Out(32)
    lost: Out(16)

    def elaborate(self, platform):
        m = Module()
        m.submodules.track = track = self.frame_tracker()
        row_bits = len(track.y)

        # input register: the observed beat
        b_valid = Signal()
        b = Signal(GroundPixel)
        m.d.comb += self.i.ready.eq(1)
        m.d.sync += [b_valid.eq(self.i.valid), b.eq(self.i.payload)]
        m.d.comb += [track.beat.eq(b_valid), track.sof.eq(b.sof), track.eol.eq(b.eol),
                     track.eof.eq(b.eof),
                     self.errors.eq(track.errors), self.dropped.eq(track.dropped)]

        # configuration, registered (no path from the ports into the pixel logic)
        band_w = Signal(FREE_BITS["band_w"]); one_wide = Signal()
        run_r = Signal(FREE_BITS["run_r"]); run_m1 = Signal(FREE_BITS["run_r"])
        m.d.sync += [band_w.eq(self.band_w), one_wide.eq(self.band_w == 1),
                     run_r.eq(self.run_r), run_m1.eq(self.run_r - 1)]

        # --- stage 1: where the beat lies in its band -------------------------------------
        v1 = Signal(); obst1 = Signal(); sof1 = Signal(); eol1 = Signal(); end1 = Signal()
        first1 = Signal(); y1 = Signal(row_bits)
        m.d.sync += [v1.eq(track.accept), obst1.eq(~b.ground), sof1.eq(b.sof), eol1.eq(b.eol),
                     end1.eq(track.frame_end), first1.eq(track.y == 0), y1.eq(track.y)]

        # rem: pixels of the band left, this beat included; last: rem == 1 (registered);
        # band: FREE_BANDS once past the last band; balance: obstacle minus ground pixels
        rem = Signal(FREE_BITS["band_w"]); last = Signal()
        band = Signal(range(FREE_BANDS + 1))
        balance = Signal(signed(bits_for(self._max_width) + 1))
        cur_rem = Signal.like(rem); cur_last = Signal(); cur_band = Signal.like(band)
        cur_balance = Signal.like(balance); new_balance = Signal.like(balance)
        band_end = Signal()
        m.d.comb += [
            cur_rem.eq(Mux(sof1, band_w, rem)), cur_last.eq(Mux(sof1, one_wide, last)),
            cur_band.eq(Mux(sof1, 0, band)), cur_balance.eq(Mux(sof1, 0, balance)),
            new_balance.eq(cur_balance + Mux(obst1, 1, -1)),
            band_end.eq(eol1 | cur_last),
        ]
        with m.If(v1):
            with m.If(band_end):
                m.d.sync += [rem.eq(band_w), last.eq(one_wide), balance.eq(0),
                             band.eq(Mux(eol1 | (cur_band == FREE_BANDS), Mux(eol1, 0, FREE_BANDS),
                                         cur_band + 1))]
            with m.Else():
                m.d.sync += [rem.eq(cur_rem - 1), last.eq(cur_rem == 2), balance.eq(new_balance),
                             band.eq(cur_band)]

        # --- stage 2: a band's row is complete --------------------------------------------
        w2 = Signal(); end2 = Signal(); band2 = Signal(4); balance2 = Signal.like(balance)
        first2 = Signal(); y2 = Signal(row_bits)
        m.d.sync += [w2.eq(v1 & band_end & (cur_band != FREE_BANDS)), end2.eq(v1 & end1)]
        with m.If(v1):
            m.d.sync += [band2.eq(cur_band), balance2.eq(new_balance), first2.eq(first1),
                         y2.eq(y1)]

        runs = memory.Memory(shape=FREE_BITS["run_r"], depth=FREE_BANDS, init=[],
                             attrs={"ram_style": "distributed"})
        entry = data.StructLayout({"row": row_bits, "found": 1})
        results = memory.Memory(shape=entry, depth=2 * FREE_BANDS, init=[],
                                attrs={"ram_style": "distributed"})
        m.submodules.runs = runs
        m.submodules.results = results
        run_rd = runs.read_port(domain="comb"); run_wr = runs.write_port()
        res_wr = results.write_port(); res_rd = results.read_port(domain="comb")

        fill_bank = Signal()            # bank of the frame being measured
        obstacle_row = Signal(); run_old = Signal.like(run_r); hit = Signal(); reached = Signal()
        m.d.comb += [
            obstacle_row.eq(~balance2[-1] & (balance2 != 0)),
            run_rd.addr.eq(band2),
            run_old.eq(Mux(first2, 0, run_rd.data)),
            hit.eq(run_old >= run_m1),
            reached.eq(obstacle_row & hit),
            run_wr.addr.eq(band2), run_wr.en.eq(w2),
            run_wr.data.eq(Mux(obstacle_row, Mux(hit, run_r, run_old + 1), 0)),
            res_wr.addr.eq(Cat(band2, fill_bank)), res_wr.en.eq(w2 & (reached | first2)),
            res_wr.data.row.eq(y2), res_wr.data.found.eq(reached),
        ]
        bands_fill = Signal(range(FREE_BANDS + 1))     # bands in the frame (set by row 0)
        bands_now = Signal.like(bands_fill)
        m.d.comb += bands_now.eq(Mux(w2 & first2, band2 + 1, bands_fill))
        m.d.sync += bands_fill.eq(bands_now)

        # --- output: the finished bank, one band per beat ---------------------------------
        busy = Signal(); index = Signal(4); out_bank = Signal()
        bands_out = Signal.like(bands_fill)
        with m.If(end2):
            with m.If(busy):
                m.d.sync += saturating_inc(self.lost)
            with m.Else():
                m.d.sync += [busy.eq(1), index.eq(0), out_bank.eq(fill_bank),
                             fill_bank.eq(~fill_bank), bands_out.eq(bands_now)]
        m.d.comb += res_rd.addr.eq(Cat(index, out_bank))
        o = self.o.payload
        with m.If(~self.o.valid | self.o.ready):
            m.d.sync += self.o.valid.eq(busy)
            with m.If(busy):
                m.d.sync += [o.band.eq(index), o.sof.eq(index == 0),
                             o.eol.eq(index == FREE_BANDS - 1), o.eof.eq(index == FREE_BANDS - 1),
                             o.row.eq(Mux(res_rd.data.found & (index < bands_out),
                                          res_rd.data.row, FREE_NONE)),
                             index.eq(index + 1)]
                with m.If(index == FREE_BANDS - 1):
                    m.d.sync += busy.eq(0)
        return m


class FreeSpaceTable(wiring.Component):
    """The last frame's free-space results of one camera, for the CPU's registers (the
    register block's ``free_left`` / ``free_right`` table: FREE_LEFT_k, FREE_RIGHT_k).

    A band's row is below ``max_height`` or ``FREE_NONE``, so it is kept as ``bits_for(max_height
    - 1)`` bits and a "none" bit, in two 8-word distributed RAMs (even and odd bands) read
    asynchronously, and widened to 16 bits on the way out: a few LUT RAM sites per band,
    instead of 256 flip-flops and a 16-way input of the register block's read multiplexer. A
    band not yet written since reset reads ``FREE_NONE`` (one valid flag per band: the RAMs
    cannot be reset).

    Parameters
    ----------
    max_height : int
        The free-space unit's frame limit (its rows are below it).

    Ports
    -----
    i : In(stream of :data:`FreeBand`)
        A :class:`FreeSpace` output; always ready. The 16 beats of a frame arrive on
        consecutive cycles after its end, so a word changes only in the 16 cycles after each
        frame.
    index : In(range(FREE_BANDS // 2))
        Word ``k``.
    word : Out(32)
        Combinational: band ``2k``'s row in bits 0-15, band ``2k + 1``'s in bits 16-31 (the
        row from the last beat of that band; ``FREE_NONE`` before the first).
    """

    def __init__(self, *, max_height=1024):
        if not isinstance(max_height, int) or not 1 <= max_height <= FREE_NONE:
            self._MustUse__silence = True
            raise ValueError(f"max_height must be an integer in 1..{FREE_NONE}, not {max_height!r}")
        self._row_bits = bits_for(max_height - 1)
        super().__init__({"i": In(stream.Signature(FreeBand)),
                          "index": In(range(FREE_BANDS // 2)), "word": Out(32)})

    def elaborate(self, platform):
        m = Module()
        m.d.comb += self.i.ready.eq(1)
        beat = self.i.payload
        bits = self._row_bits
        none = beat.row == FREE_NONE
        valid = Signal(FREE_BANDS)
        halves = []
        for parity in (0, 1):
            mem = m.submodules[f"band{parity}"] = memory.Memory(
                shape=bits + 1, depth=FREE_BANDS // 2, init=[1 << bits] * (FREE_BANDS // 2))
            wr = mem.write_port()
            rd = mem.read_port(domain="comb")
            m.d.comb += [wr.addr.eq(beat.band[1:]), wr.data.eq(Cat(beat.row[:bits], none)),
                         wr.en.eq(self.i.valid & (beat.band[0] == parity)),
                         rd.addr.eq(self.index)]
            seen = Signal(name=f"seen{parity}")
            m.d.comb += seen.eq(valid.bit_select(Cat(Const(parity, 1), self.index), 1))
            halves.append(Mux(seen & ~rd.data[bits], rd.data[:bits], FREE_NONE))
        with m.If(self.i.valid):
            m.d.sync += valid.bit_select(beat.band, 1).eq(1)
        m.d.comb += self.word.eq(Cat(halves[0][:16], halves[1][:16]))
        return m


def free_space_tables(m, pipe, regs):
    """Both cameras' free-space results of ``pipe`` (a :class:`hdl.pipeline.StereoPipeline`)
    into :class:`FreeSpaceTable` submodules of ``m``, read by the register block ``regs``
    (its ``free_left`` / ``free_right`` tables: hdl/regmap.py FREE_LEFT_k, FREE_RIGHT_k)."""
    for side in ("left", "right"):
        table = m.submodules[f"free_{side}_table"] = FreeSpaceTable(max_height=pipe.max_height)
        wiring.connect(m, getattr(pipe, f"free_{side}"), table.i)
        m.d.comb += [table.index.eq(getattr(regs, f"free_{side}_index")),
                     getattr(regs, f"free_{side}_word").eq(table.word)]
