"""Whole frames in and out of `amaranth.lib.stream` ports, with seeded random stalls.

The bridge between the golden models (whole frames as NumPy arrays) and the RTL (one beat per
transfer). A *frame* is a dict ``{field: 2-D integer array}`` with every array of the same shape;
a *beat* is the payload packed into one integer exactly as the RTL's ``data.Struct`` packs it
(fields from the low bits in declaration order), so the same words drive the Amaranth simulator,
the Verilator harness and cocotb.

Simulation helpers (Amaranth async testbenches):

* :func:`stream_put` offers words with seeded random idle cycles on ``valid``;
* :func:`stream_get` takes words with seeded random backpressure on ``ready`` and fails with
  :class:`Deadlock` when nothing moves for ``timeout`` cycles;
* :func:`run_stream_unit` runs a unit end to end and writes a VCD when asked for (``vcd=`` or the
  environment variable ``WAVES=1``).
"""
import os
import random
from dataclasses import dataclass, field

import numpy as np
from amaranth.hdl import ClockDomain, Module, ResetInserter, Shape, Signal
from amaranth.lib import data
from amaranth.sim import Simulator

from hdl.types import FRAMING

__all__ = ["Packer", "frame_words", "frames_words", "words_to_frames", "Reset", "Configure",
           "Deadlock",
           "malformed_cases", "run_streams", "run_simulation",
           "stream_put", "stream_get", "run_stream_unit", "StreamRun"]


class Packer:
    """Packs and unpacks the fields of a :class:`data.StructLayout` to and from integers:
    element-wise over NumPy arrays (``pack``, ``unpack``: layouts of at most 64 bits, the stream
    payloads) or one Python integer of any width (``pack_int``, for configuration ports)."""

    def __init__(self, layout):
        self.layout = data.StructLayout(dict(layout)) if not isinstance(layout, data.Layout) else layout
        self.fields = {name: (fld.offset, Shape.cast(fld.shape).width)
                       for name, fld in self.layout}
        self.width = self.layout.size

    def pack_int(self, **values):
        """One word as a Python integer (no width limit)."""
        word = 0
        for name, value in values.items():
            offset, width = self.fields[name]
            word |= (int(value) & ((1 << width) - 1)) << offset
        return word

    def _check_array_width(self):
        if self.width > 64:
            raise ValueError(f"a {self.width}-bit layout does not fit the 64-bit NumPy words; "
                             f"use pack_int")

    def pack(self, **values):
        self._check_array_width()
        word = np.zeros(np.broadcast(*values.values()).shape, dtype=np.uint64) if values else 0
        for name, value in values.items():
            offset, width = self.fields[name]
            word = word | ((np.asarray(value, dtype=np.uint64) & np.uint64((1 << width) - 1))
                           << np.uint64(offset))
        return word

    def unpack(self, words):
        self._check_array_width()
        words = np.asarray(words, dtype=np.uint64)
        return {name: ((words >> np.uint64(offset)) & np.uint64((1 << width) - 1)).astype(np.int64)
                for name, (offset, width) in self.fields.items()}


def frame_words(packer, frame):
    """The beats of one frame in raster order, with ``sof``, ``eol`` and ``eof`` set."""
    shape = next(iter(frame.values())).shape
    for name, arr in frame.items():
        if arr.shape != shape:
            raise ValueError(f"field {name!r} has shape {arr.shape}, expected {shape}")
    h, w = shape
    sof = np.zeros(shape, dtype=np.uint64); sof[0, 0] = 1
    eol = np.zeros(shape, dtype=np.uint64); eol[:, w - 1] = 1
    eof = np.zeros(shape, dtype=np.uint64); eof[h - 1, w - 1] = 1
    return packer.pack(**frame, sof=sof, eol=eol, eof=eof).reshape(-1)


def frames_words(packer, frames):
    """All beats of a list of frames, as a list of Python ints."""
    if not frames:
        return []
    return np.concatenate([frame_words(packer, f) for f in frames]).astype(np.uint64).tolist()


def words_to_frames(packer, words, *, strict=True):
    """Cut a sequence of output words into frames (dicts of 2-D arrays, without the flags).

    With ``strict`` (the default) a frame must start with ``sof``, have lines of equal length
    ending in ``eol`` and end at ``eof``; anything else raises :class:`ValueError`, which a test
    reports as a framing mismatch."""
    if len(words) == 0:
        return []
    f = packer.unpack(np.array(words, dtype=np.uint64))
    frames, start = [], 0
    ends = np.flatnonzero(f["eof"])
    starts = np.flatnonzero(f["sof"])
    if strict and (len(starts) != len(ends) or ends[-1] != len(words) - 1):
        raise ValueError(f"{len(starts)} sof and {len(ends)} eof flags in {len(words)} words, "
                         f"last eof at {ends[-1] if len(ends) else None}")
    for end in ends:
        sl = slice(start, end + 1)
        if strict and (not f["sof"][start] or f["sof"][start + 1:end + 1].any()):
            raise ValueError(f"frame at word {start} is not framed by exactly one sof")
        eols = np.flatnonzero(f["eol"][sl])
        width = int(eols[0]) + 1
        n = end + 1 - start
        if strict and (n % width or not np.array_equal(eols, np.arange(width - 1, n, width))):
            raise ValueError(f"frame at word {start}: lines of unequal length (eol at {eols[:8]}...)")
        frames.append({name: f[name][sl].reshape(-1, width) for name in f if name not in FRAMING})
        start = end + 1
    return frames


class Reset:
    """In a word list given to :func:`stream_put`: hold the unit's reset for ``cycles`` cycles."""

    def __init__(self, cycles=1):
        self.cycles = cycles


class Configure:
    """In a word list given to :func:`run_streams`: wait until the unit has delivered every frame
    offered before this item on each frame-counted output (it is idle), then run ``setup(ctx)``
    (async) to change configuration inputs between frames."""

    def __init__(self, setup):
        self.setup = setup


class Deadlock(AssertionError):
    pass


async def stream_put(ctx, port, words, *, rng=None, idle=0.0, reset=None):
    """Offer ``words`` on a stream sink ``port`` (drives valid/payload, waits for ready), with a
    random idle cycle before a word with probability ``idle``. :class:`Reset` items pulse
    ``reset`` (a reset signal) instead; a word taken while ``reset`` is high (pulsed by another
    producer) was lost in the reset and is offered again."""
    payload = port.payload.as_value() if hasattr(port.payload, "as_value") else port.payload
    for word in words:
        if isinstance(word, Reset):
            ctx.set(port.valid, 0)
            ctx.set(reset, 1)
            await ctx.tick().repeat(word.cycles)
            ctx.set(reset, 0)
            continue
        while idle and rng.random() < idle:
            ctx.set(port.valid, 0)
            await ctx.tick()
        ctx.set(payload, word)
        ctx.set(port.valid, 1)
        if reset is None:
            await ctx.tick().until(port.ready)
            continue
        while True:
            _, _, ready, in_reset = await ctx.tick().sample(port.ready, reset)
            if ready and not in_reset:
                break
    ctx.set(port.valid, 0)


async def stream_get(ctx, port, *, count=None, until_eof=None, eof_bit=None, rng=None,
                     stall=0.0, timeout=10000, at_eof=(), eof_values=None, reset=None,
                     on_eof=None):
    """Take words from a stream source ``port`` until ``count`` words or ``until_eof`` frames
    (words with the ``eof`` bit, whose position is ``eof_bit``) have arrived. ``ready`` is held low
    with probability ``stall`` each cycle. Raises :class:`Deadlock` after ``timeout`` cycles
    without a transfer. With ``eof_values`` (a list), the signals ``at_eof`` are sampled with
    every eof word and their values appended as a tuple (per-frame status such as statistics).
    With ``reset`` (the unit's reset signal), a cycle with it high discards the words of the
    frame being output (those after the last eof word). ``on_eof()`` (optional) is called at
    every eof word."""
    payload = port.payload.as_value() if hasattr(port.payload, "as_value") else port.payload
    words, frames, quiet, frame_start = [], 0, 0, 0
    watch = [reset] if reset is not None else []
    while (count is None or len(words) < count) and (until_eof is None or frames < until_eof):
        ready = not (stall and rng.random() < stall)
        ctx.set(port.ready, ready)
        _, _, valid, word, *rest = await ctx.tick().sample(port.valid, payload, *at_eof, *watch)
        if watch and rest[-1]:
            del words[frame_start:]
            continue
        if valid and ready:
            words.append(word)
            quiet = 0
            if eof_bit is not None and (word >> eof_bit) & 1:
                frames += 1
                frame_start = len(words)
                if eof_values is not None:
                    eof_values.append(tuple(int(v) for v in rest[:len(at_eof)]))
                if on_eof is not None:
                    on_eof()
        else:
            quiet += 1
            if quiet > timeout:
                raise Deadlock(f"no output for {timeout} cycles after {len(words)} words")
    ctx.set(port.ready, 0)
    return words


@dataclass
class StreamRun:
    words: object = field(default_factory=list)   # output words (a dict per port for run_streams)
    cycles: int = 0          # from the first word offered to the last word taken
    first_in: int = 0        # cycle of the first offer
    last_out: int = 0        # cycle of the last output transfer
    probes: dict = field(default_factory=dict)   # values of the probed ports at the end
    eof_values: dict = field(default_factory=dict)  # per output: ``eof_probes`` at each eof


def run_simulation(sim, vcd=None, *, name="unit"):
    """Run ``sim`` to the end, writing a VCD to ``vcd`` when given or when the environment
    variable ``WAVES=1`` is set (then to ``build/waves/<name>.vcd``)."""
    if vcd is None and os.environ.get("WAVES") == "1":
        vcd = f"build/waves/{name}.vcd"
    if vcd:
        os.makedirs(os.path.dirname(vcd) or ".", exist_ok=True)
        with sim.write_vcd(vcd):
            sim.run()
    else:
        sim.run()


def _eof_bit(port):
    shape = port.payload.shape() if hasattr(port.payload, "shape") else None
    if isinstance(shape, data.StructLayout) and "eof" in dict(shape):
        return shape["eof"].offset
    return None


def run_streams(dut, inputs, outputs, *, seed=0, idle=0.0, stall=0.0, setup=None, vcd=None,
                timeout=10000, settle=20, probes=("errors", "dropped"), eof_probes=None,
                reset_aborts_frames=False, processes=(), same_idle=False):
    """Simulate ``dut`` under Amaranth's simulator with several stream ports.

    ``inputs`` maps input port names to word lists (which may hold :class:`Reset` and
    :class:`Configure` items);
    ``outputs`` maps output port names to the number of frames (words with ``eof``) to collect,
    or to ``("count", n)`` for a fixed number of words. Every port has its own seeded random
    generator, so a failure is reproducible from ``seed`` (with ``same_idle`` every input's is
    seeded alike: inputs that are never held see the same idle cycles, as genlocked cameras).
    ``setup(ctx)`` (optional, async) sets configuration inputs before the first word; the ports
    named in ``probes`` are read ``settle`` cycles after the last output. ``eof_probes`` maps
    output names to signals sampled with each of their eof words (``eof_values``); with
    ``reset_aborts_frames`` a :class:`Reset` discards the partly output frame; ``processes``
    are more async testbenches, run in the background. Returns a :class:`StreamRun` whose
    ``words`` maps output names to word lists."""
    m = Module()
    m.domains.sync = ClockDomain("sync")
    # The unit's reset is a separate signal: asserting the domain's own reset would stop the
    # testbenches (Amaranth raises DomainReset in them).
    unit_reset = Signal()
    m.submodules.dut = ResetInserter(unit_reset)(dut)
    sim = Simulator(m)
    sim.add_clock(1e-8, domain="sync")
    result = StreamRun(words={})
    state = {"cycle": 0, "start": None, "last": 0, "done": 0}
    delivered = {name: 0 for name, want in outputs.items() if not isinstance(want, tuple)}

    async def clock_counter(ctx):
        async for _ in ctx.tick():
            state["cycle"] += 1

    async def configure(ctx):
        if setup is not None:
            await setup(ctx)
        await ctx.tick()
        state["start"] = state["cycle"]

    def producer(k, name, words):
        async def run(ctx):
            if k == 0:
                await configure(ctx)
            else:
                while state["start"] is None:
                    await ctx.tick()
            port = getattr(dut, name)
            rng = random.Random(seed * 16 + 1 + (0 if same_idle else k))
            eof_bit, offered, chunk = _eof_bit(port), 0, []
            for word in list(words) + [None]:
                if word is not None and not isinstance(word, Configure):
                    chunk.append(word)
                    continue
                await stream_put(ctx, port, chunk, rng=rng, idle=idle, reset=unit_reset)
                offered += sum(1 for w in chunk if not isinstance(w, Reset) and eof_bit is not None
                               and (w >> eof_bit) & 1)
                chunk = []
                if word is not None:
                    while min(delivered.values(), default=offered) < offered:
                        await ctx.tick()
                    await word.setup(ctx)
        return run

    def consumer(k, name, want):
        async def run(ctx):
            await ctx.tick()
            port = getattr(dut, name)
            count, frames = (want[1], None) if isinstance(want, tuple) else (None, want)
            at_eof = (eof_probes or {}).get(name, ())
            result.eof_values[name] = []
            result.words[name] = await stream_get(
                ctx, port, count=count, until_eof=frames, eof_bit=_eof_bit(port),
                rng=random.Random(seed * 16 + 9 + k), stall=stall, timeout=timeout,
                at_eof=at_eof, eof_values=result.eof_values[name],
                reset=unit_reset if reset_aborts_frames else None,
                on_eof=(lambda: delivered.__setitem__(name, delivered[name] + 1))
                if name in delivered else None)
            state["last"] = max(state["last"], state["cycle"])
            state["done"] += 1
            if state["done"] == len(outputs):
                await ctx.tick().repeat(settle)
                for probe in probes:
                    if hasattr(dut, probe):
                        result.probes[probe] = ctx.get(getattr(dut, probe))
        return run

    sim.add_process(clock_counter)
    for k, (name, words) in enumerate(inputs.items()):
        sim.add_testbench(producer(k, name, words), background=True)
    for k, (name, want) in enumerate(outputs.items()):
        sim.add_testbench(consumer(k, name, want))
    for process in processes:
        sim.add_testbench(process, background=True)
    run_simulation(sim, vcd, name=type(dut).__name__)
    result.first_in = state["start"] or 0
    result.last_out = state["last"]
    result.cycles = state["last"] - result.first_in
    return result


def run_stream_unit(dut, words, *, out_frames=None, out_count=None, out_port="o", in_port="i",
                    **kwargs):
    """:func:`run_streams` for a unit with one input ``i`` and one output ``o``; the result's
    ``words`` is the output word list."""
    want = out_frames if out_count is None else ("count", out_count)
    result = run_streams(dut, {in_port: words}, {out_port: want}, **kwargs)
    result.words = result.words[out_port]
    return result


def _with_flags(packer, word, **flags):
    f = {name: int(v[0]) for name, v in packer.unpack(np.array([word], dtype=np.uint64)).items()}
    f.update(flags)
    return int(packer.pack(**f))


def malformed_cases(packer, frame):
    """Malformed versions of one good ``frame`` (H >= 3, W >= 4), each as
    ``(words, errors, dropped)``: the words to send and the ``errors``/``dropped`` counts that the
    rules of :mod:`hdl.framing` give for a unit that receives them first after reset.

    * ``missing_sof``: the frame without its ``sof`` (every beat dropped);
    * ``short_line``: row 1 two pixels short (its early ``eol`` is the first bad beat);
    * ``long_line``: row 1 two pixels long (the pixel at x = W is the first bad beat);
    * ``eof_without_eol``: the last beat has ``eof`` but not ``eol``;
    * ``cut_short``: the first rows only, no ``eof``: the next ``sof`` cuts the frame;
    * ``reset``: reset after the first rows, then the rest of the frame (dropped: no ``sof``).
    """
    h, w = next(iter(frame.values())).shape
    if h < 3 or w < 4:
        raise ValueError(f"malformed cases need a frame of at least 4x3, not {w}x{h}")
    good = [int(v) for v in frame_words(packer, frame)]
    n = len(good)
    cases = {}
    cases["missing_sof"] = ([_with_flags(packer, good[0], sof=0)] + good[1:], 1, n)
    row1 = good[w:2 * w - 2]
    row1[-1] = _with_flags(packer, row1[-1], eol=1)
    short = good[:w] + row1 + good[2 * w:]
    cases["short_line"] = (short, 1, len(short) - (2 * w - 3))
    row1 = good[w:2 * w - 1] + [_with_flags(packer, good[2 * w - 1], eol=0)] * 2 + [good[2 * w - 1]]
    long = good[:w] + row1 + good[2 * w:]
    cases["long_line"] = (long, 1, len(long) - 2 * w)
    cases["eof_without_eol"] = (good[:-1] + [_with_flags(packer, good[-1], eol=0)], 1, 1)
    cases["cut_short"] = (good[:(h // 2) * w], 1, 0)
    half = (h // 2) * w + 1
    cases["reset"] = (good[:half] + [Reset(2)] + good[half:], 1, n - half)
    return cases


def check_unit(make_dut, in_packer, out_packer, in_frames, expected, *, name, seed=0, idle=0.0,
               stall=0.0, setup=None, extra_words=(), **kwargs):
    """Run a fresh unit from ``make_dut()`` on ``extra_words`` (e.g. a malformed frame) followed
    by ``in_frames``; assert that the output's last ``len(expected)`` frames equal ``expected``
    (dicts of arrays, compared with ``np.array_equal`` field by field). On a mismatch the run is
    repeated with a VCD written to ``build/waves/<name>.vcd``, named in the assertion message.
    Returns the :class:`StreamRun`."""
    words = list(extra_words) + frames_words(in_packer, in_frames)
    n_out = sum(next(iter(f.values())).size for f in expected)

    def run(vcd=None):
        dut = make_dut()
        return run_stream_unit(dut, words, out_frames=len(expected), seed=seed, idle=idle,
                               stall=stall, setup=(lambda ctx: setup(ctx, dut)) if setup else None,
                               vcd=vcd, **kwargs)

    def problem(result):
        try:
            got = words_to_frames(out_packer, result.words[len(result.words) - n_out:])
        except ValueError as e:
            return f"bad framing: {e}"
        if len(got) != len(expected):
            return f"{len(got)} frames out, {len(expected)} expected"
        for k, (g, e) in enumerate(zip(got, expected)):
            for field_name, arr in e.items():
                if not np.array_equal(g[field_name], arr):
                    bad = np.argwhere(g[field_name] != arr)
                    y, x = bad[0]
                    return (f"frame {k} field {field_name!r}: {len(bad)} mismatches, first at "
                            f"(x={x}, y={y}): rtl {g[field_name][y, x]} != golden {arr[y, x]}")
        return None

    try:
        result = run()
        msg = problem(result)
    except Deadlock as e:
        msg = f"deadlock: {e}"
    if msg:
        vcd = f"build/waves/{name}.vcd"
        try:
            run(vcd)
        except Deadlock:
            pass
        raise AssertionError(f"{name}: {msg} (waveform: {vcd})")
    return result
