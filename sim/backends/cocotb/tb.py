"""Generic cocotb testbench for a stream component (runs inside the simulator process).

:class:`StreamTB` owns the clock and the reset, one :class:`StreamDriver` per input stream and
one :class:`StreamMonitor` per output stream, all built from the component's payload layouts
(:func:`sim.designs.ports`). Words are packed integers exactly as :class:`sim.streams.Packer`
packs them, so the golden model's frames become words and back.

Timing discipline (the same on Verilator, Icarus and GHDL): every coroutine changes its inputs
just after a falling edge and samples ``valid``/``ready`` in the ``ReadOnly`` phase of that
time step. The design only changes state on rising edges, so what is sampled there is what the
next rising edge sees: a transfer happens exactly when both were high.
"""
import random

from cocotb.clock import Clock
from cocotb.triggers import FallingEdge, ReadOnly, RisingEdge, Timer
from cocotb.utils import get_sim_time

__all__ = ["handle", "StreamTB", "StreamDriver", "StreamMonitor", "Deadlock", "PERIOD_NS"]

PERIOD_NS = 10


class Deadlock(AssertionError):
    pass


def handle(dut, name, lang="verilog"):
    """The handle of port ``name`` (a Verilog name such as ``i__valid``); in the VHDL made by
    sim.flows.vhdl (``lang="vhdl"``), ``__`` became ``_``. (Do not look the Verilog name up in
    VHDL: GHDL's VHDL-93 mode returns an undriven object for ``i__valid``.)"""
    vhdl_name = "_".join(p for p in name.split("_") if p)
    candidates = [vhdl_name] if lang == "vhdl" else [name]
    for n in candidates:
        try:
            return dut[n]
        except (AttributeError, KeyError, IndexError):
            continue
    raise AttributeError(f"{dut._name} has no port {' or '.join(candidates)}")


class _Cycles:
    """Cycle numbers from simulation time (the same in every coroutine)."""

    def __init__(self, period_ns):
        self.period = period_ns

    def now(self):
        return int(get_sim_time("ns") // self.period)


class StreamDriver:
    """Offers words on an input stream; before each word, idle (valid low) cycles with
    probability ``idle`` each."""

    def __init__(self, dut, port, clock, lang="verilog"):
        self.valid = handle(dut, port.valid, lang)
        self.ready = handle(dut, port.ready, lang)
        self.payload = handle(dut, port.payload, lang)
        self.port = port
        self.clock = clock
        self.taken = 0
        self.first_offer = None

    def idle(self):
        self.valid.value = 0

    async def send(self, words, *, rng, idle=0.0, cycles=None):
        offering = False
        i = 0
        while i < len(words):
            await FallingEdge(self.clock)
            if not offering and not (idle and rng.random() < idle):
                offering = True
                self.payload.value = int(words[i])
                if self.first_offer is None:
                    self.first_offer = cycles.now()
            self.valid.value = int(offering)
            await ReadOnly()
            if offering and int(self.ready.value):
                offering = False
                i += 1
                self.taken = i
        await FallingEdge(self.clock)
        self.valid.value = 0


class StreamMonitor:
    """Takes words from an output stream with ``ready`` low in a cycle with probability
    ``stall``; stops after ``count`` words, or after ``frames`` words with the ``eof`` flag;
    raises :class:`Deadlock` when nothing moves for ``timeout`` cycles."""

    def __init__(self, dut, port, clock, lang="verilog"):
        self.valid = handle(dut, port.valid, lang)
        self.ready = handle(dut, port.ready, lang)
        self.payload = handle(dut, port.payload, lang)
        self.port = port
        self.clock = clock
        self.words = []
        self.last_take = None

    def idle(self):
        self.ready.value = 0

    async def receive(self, count=None, *, frames=None, rng, stall=0.0, timeout=10000, cycles=None):
        quiet, seen = 0, 0
        eof = self.port.eof_bit
        if frames is not None and eof is None:
            raise ValueError(f"{self.port.name} has no eof flag: count words")

        def done():
            return len(self.words) >= count if count is not None else seen >= frames

        while not done():
            await FallingEdge(self.clock)
            ready = not (stall and rng.random() < stall)
            self.ready.value = int(ready)
            await ReadOnly()
            if ready and int(self.valid.value):
                word = int(self.payload.value)
                self.words.append(word)
                if eof is not None:
                    seen += (word >> eof) & 1
                self.last_take = cycles.now()
                quiet = 0
            else:
                quiet += 1
                if quiet > timeout:
                    raise Deadlock(f"{self.port.name}: no output for {timeout} cycles after "
                                   f"{len(self.words)} words ({seen} frames)")
        await FallingEdge(self.clock)
        self.ready.value = 0
        return self.words


class StreamTB:
    """Clock, reset and stream ports of one component under test."""

    def __init__(self, dut, ports, period_ns=PERIOD_NS, lang="verilog"):
        self.dut = dut
        self.ports = ports
        self.lang = lang
        self.clk = handle(dut, "clk", lang)
        self.rst = handle(dut, "rst", lang)
        self.cycles = _Cycles(period_ns)
        self.period_ns = period_ns
        self.drivers = {p.name: StreamDriver(dut, p, self.clk, lang) for p in ports.inputs}
        self.monitors = {p.name: StreamMonitor(dut, p, self.clk, lang) for p in ports.outputs}
        self._clock = None

    def start_clock(self):
        if self._clock is None:
            self._clock = Clock(self.clk, self.period_ns, unit="ns")
            self._clock.start(start_high=False)

    async def reset(self, runtime=None, cycles=4):
        """Hold reset for ``cycles`` cycles with every stream idle and the run-time parameter
        ports set from ``runtime`` (``{port: value}``; unspecified ones are 0)."""
        self.start_clock()
        # Leave time 0 to the design's own start-up (see sim.backends.cocotb.icarus_fixup).
        await Timer(1, "ns")
        values = dict(runtime or {})
        for p in self.ports.params:
            handle(self.dut, p.name, self.lang).value = int(values.pop(p.name, 0))
        if values:
            raise ValueError(f"no parameter ports {sorted(values)}")
        for d in self.drivers.values():
            d.idle()
            d.taken, d.first_offer = 0, None
        for m in self.monitors.values():
            m.idle()
            m.words, m.last_take = [], None
        self.rst.value = 1
        for _ in range(cycles):
            await RisingEdge(self.clk)
        await FallingEdge(self.clk)
        self.rst.value = 0

    def status(self):
        return {p.name: int(handle(self.dut, p.name, self.lang).value) for p in self.ports.status}

    async def run(self, inputs, out_frames=None, out_words=None, *, seed=0, idle=0.0, stall=0.0,
                  timeout=10000):
        """Drive ``inputs`` (``{port: words}``) and collect ``out_frames`` (``{port: n}``) frames
        or ``out_words`` words per output. Returns ``({port: words}, cycles)`` with cycles from
        the first word offered to the last word taken."""
        wanted = {**{k: ("frames", n) for k, n in (out_frames or {}).items()},
                  **{k: ("words", n) for k, n in (out_words or {}).items()}}
        import cocotb
        tasks = []
        for k, (name, words) in enumerate(sorted(inputs.items())):
            rng = random.Random(seed * 64 + 1 + k)
            tasks.append(cocotb.start_soon(self.drivers[name].send(words, rng=rng, idle=idle,
                                                                   cycles=self.cycles)))
        takers = {}
        for k, (name, (kind, n)) in enumerate(sorted(wanted.items())):
            rng = random.Random(seed * 64 + 33 + k)
            takers[name] = cocotb.start_soon(self.monitors[name].receive(
                n if kind == "words" else None, frames=n if kind == "frames" else None, rng=rng,
                stall=stall, timeout=timeout, cycles=self.cycles))
        results = {name: await task for name, task in takers.items()}
        for t in tasks:
            t.cancel()
        for d in self.drivers.values():
            d.idle()
        first = min((d.first_offer for d in self.drivers.values() if d.first_offer is not None),
                    default=0)
        last = max((m.last_take for m in self.monitors.values() if m.last_take is not None),
                   default=first - 1)
        return results, last - first + 1
