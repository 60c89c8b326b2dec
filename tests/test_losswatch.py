"""Camera loss indication (hdl/camera_port.py): the camera port's field starts, taken before
the overflow guard, cross into the core domain; LossWatch flags a camera whose starts stop."""
import pytest
from amaranth.hdl import ClockDomain, Module, ResetInserter, Signal
from amaranth.sim import Simulator

from golden.bt656 import decode_bt656, encode_bt656
from hdl.camera_port import CameraPort, LossWatch
from tests.camera_drive import camera_module, drive, make_fields

PRESCALE_BITS, LIMIT = 6, 20        # 1216..1280 core cycles: about two of these fields


class WatchModel:
    """LossWatch cycle by cycle, one camera: the prescaler ticks in the cycle its low bits
    wrap; the count saturates at the limit; a start or a reset clears it."""

    def __init__(self):
        self.pre = self.count = 0

    def lost(self):
        return int(self.count == LIMIT)

    def step(self, start, reset):
        tick = self.pre >> PRESCALE_BITS
        if reset:
            self.pre = self.count = 0
            return
        self.pre = (self.pre & ((1 << PRESCALE_BITS) - 1)) + 1
        if start:
            self.count = 0
        elif tick and self.count != LIMIT:
            self.count += 1


def run(segments, *, ready, reset_at=()):
    """Camera bytes (``bytes``) and pauses (``int``: camera cycles without a byte) in turn;
    the core reads the port when ``ready``. Returns per core cycle (start, lost, reset)."""
    port = CameraPort(domain="cam", lines=4, fifo_depth=16)
    watch = LossWatch(n=1, prescale_bits=PRESCALE_BITS, limit=LIMIT)
    rst = Signal()
    m = camera_module(port)
    m.submodules.watch = ResetInserter(rst)(watch)
    m.d.comb += [watch.start.eq(port.field_start), port.o.ready.eq(ready)]
    trace = []

    def core(ctx, n):
        r = n in reset_at
        ctx.set(rst, r)
        trace.append((ctx.get(port.field_start), ctx.get(watch.lost), r))

    drive(m, port, segments, each_cycle=core)
    return trace


def check_against_model(trace):
    model = WatchModel()
    for n, (start, lost, reset) in enumerate(trace):
        assert lost == model.lost(), f"cycle {n}"
        model.step(start, reset)


@pytest.mark.parametrize("ready", [1, 0])
def test_lost_after_the_limit_and_cleared_by_the_next_field_start(ready):
    # ready 0: the core never reads, the guard cuts every frame, the starts still count
    before = encode_bt656(make_fields(1, 3))
    after = encode_bt656(make_fields(2, 2), first_field=1)
    gap = 3000                                  # camera cycles: 5,556 core cycles
    trace = run([before, gap, after], ready=ready)
    check_against_model(trace)
    starts = [n for n, t in enumerate(trace) if t[0]]
    gold = decode_bt656(before + after, lines=4)
    assert len(starts) == sum(b[3] for b in gold.beats) == 5
    lost = [t[1] for t in trace]
    # never lost while the fields come, nor before the limit; lost within the gap; cleared by
    # the first start after it
    assert not any(lost[:starts[2] + 1])
    rise = lost.index(1)
    assert starts[2] + ((LIMIT - 1) << PRESCALE_BITS) <= rise
    assert rise <= starts[2] + 1 + (LIMIT << PRESCALE_BITS) < starts[3]
    assert all(lost[rise:starts[3] + 1]) and not any(lost[starts[3] + 1:])


def test_reset_clears_lost_and_a_silent_camera_is_lost_again():
    fields = encode_bt656(make_fields(3, 1))
    trace = run([fields, 8000], ready=1, reset_at=(6000,))
    check_against_model(trace)
    lost = [t[1] for t in trace]
    assert lost[5999] == 1 and lost[6001] == 0
    assert lost.index(1, 6001) - 6001 == (LIMIT << PRESCALE_BITS) + 1    # the first tick a full period after


def test_two_cameras_share_the_prescaler():
    m = Module()
    m.domains.sync = ClockDomain()
    m.submodules.watch = watch = LossWatch(n=2, prescale_bits=2, limit=3)
    sim = Simulator(m)
    sim.add_clock(1e-8)
    seen = []

    async def bench(ctx):
        for n in range(40):
            ctx.set(watch.start, 0b01 if n % 6 == 0 else 0)   # the left camera only
            seen.append(ctx.get(watch.lost))
            await ctx.tick()

    sim.add_testbench(bench)
    sim.run()
    assert all(s & 1 == 0 for s in seen)
    assert seen.index(0b10) == 13 and seen[13:] == [0b10] * 27   # ticks at 4, 8, 12


def test_bad_parameters():
    for kw in ({"n": 0}, {"prescale_bits": 17}, {"prescale_bits": 0}, {"limit": 1}):
        with pytest.raises(ValueError):
            LossWatch(**kw)


def test_soc_loss_parameters():
    from hdl.soc import LOSS_WATCH, SystemSoC
    from sim.designs import silenced
    assert silenced(SystemSoC())._loss == LOSS_WATCH
    assert silenced(SystemSoC(loss=dict(prescale_bits=4, limit=3)))._loss["limit"] == 3
    with pytest.raises(ValueError, match="limit"):
        SystemSoC(loss=dict(prescale_bits=4, limit=1))
