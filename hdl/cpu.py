"""The SoC's soft CPU: a PicoRV32 RISC-V core (Verilog from the ``pythondata-cpu-picorv32``
package, as an :class:`~amaranth.hdl.Instance`) with its block RAM, a timer, and a bridge from
the core's memory interface to the SoC's MicroBlaze-style I/O bus (:class:`hdl.regs.IOBusSignature`).

Core: no multiplier or divider, barrel shifter, 32-bit cycle and instruction counters
(``rdcycle``, ``rdinstret``), illegal instructions trap (``trap`` port), misaligned accesses
are not checked. The core starts at address 0 a cycle after the reset ends (its reset goes
through a register placed with the core). Two configurations (:data:`CORES`, the ``core``
parameter), each with the instruction set its firmware is built for (``firmware/Makefile``
``rv32 RV_MARCH=...``) and its RAM:

* ``"compact"`` (the chip's): RV32IC, compressed instructions, which keep the firmware inside
  8 KB (four RAMB16 on a Spartan-3, whose 24 the chip uses all of); the ALU result and the
  branch decision in the cycle of the operands.
* ``"fast"`` (the builds for a larger ECP5, the rectifying chip on the 45F): RV32I, no
  compressed instructions (the half-word realignment of the fetch and its decode, the core's
  deepest and most spread-out paths, are gone), the ALU result and the branch compare each
  through a register (``TWO_CYCLE_ALU``, ``TWO_CYCLE_COMPARE``: a cycle more for every ALU
  instruction and every branch); the firmware is about a third larger, so 16 KB of RAM.

Address map (the core's byte addresses; the decode looks at few bits, so the RAM and the
timer repeat through their halves of the map):

===========================  ======================================================
0x0000_0000 (bit 31 = 0)     block RAM, ``ram_bytes`` (code, data, bss and stack)
0xC003_0000 (bits 19:16 = 3) timer: COUNT (0x0, read: core cycles since reset, 32 bits,
                             wrapping), WAIT (0x4, write n: the write completes n core
                             cycles later, the core stalled meanwhile)
other addresses, bit 31 = 1  the I/O bus: the register block, the IIC master, the UART
                             and whatever else the SoC's user hangs on it (0xC004_0000:
                             the pose block); an address nobody answers within
                             ``io_timeout`` cycles reads 0xFFFF_FFFF (writes are lost)
===========================  ======================================================

Timing of one access: RAM one wait state (the read starts from the core's look-ahead address,
a cycle before the access, and its data go through a register: ``ram_register``; without it
no wait state); timer 2 cycles, WAIT n more; I/O bus the strobe from a register in the
access's second cycle, ``ready`` from the slave (two cycles later for every slave of this SoC:
each registers the bus before it decodes, :class:`hdl.regs.BusWindow`), then the core's
``mem_ready`` a cycle after that, from a register (the read data go through a register, not
from the bus's OR into the core's decoder): 5 cycles. The core itself takes 3 to 6 cycles an
instruction without memory waits (the ``fast`` core one more for an ALU instruction or a
branch).

The RAM is ``ram_bytes`` / 4 words of 32 bits with byte writes, initialised with ``image``
(the little-endian words of ``build/firmware/firmware.bin``, :func:`sim.system.firmware.image_words`);
without an image it starts empty (zeros: the core traps at once). On a Spartan-3 each RAMB16
holds 2 KB (2K x 8, one byte lane of 2K words, or 512 x 32): 8 KB take four; on an ECP5 each
DP16KD holds 2 KB as well.

Ports
-----
bus : Out(IOBusSignature)
    The I/O bus, as its initiator.
idle : Out(1)
    The core is stalled in a timer WAIT (the firmware sleeps): busy cycles are the others.
trap : Out(1)
    The core stopped on an illegal instruction (stays until reset).

Conversion: :func:`verilog_text` is the core's Verilog, which every flow that converts a design
with this component must read beside Amaranth's output; a platform build (``platform.build``:
the ECP5 bitstream, the ISE tree) gets it as the file ``picorv32.v`` from :meth:`elaborate`. The core's instruction
counter is ``count_instr`` inside the ``picorv32`` instance (a simulator may expose it).
"""
from dataclasses import dataclass, field
from pathlib import Path

from amaranth.hdl import Cat, ClockSignal, Const, Instance, Module, Mux, ResetSignal, Signal
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import Out

from .regs import IOBusSignature

__all__ = ["RiscvCPU", "TIMER_BASEADDR", "TIMER_REGS", "verilog_text", "CoreConfig", "CORES"]

#: Bus address of the timer (firmware/include/hal.h HAL_TIMER_BASEADDR).
TIMER_BASEADDR = 0xC003_0000
TIMER_REGS = {"COUNT": 0x0, "WAIT": 0x4}

#: PicoRV32 parameters both configurations share: barrel shifter, 32-bit counters, no IRQ,
#: PCPI, MUL or DIV.
_COMMON_PARAMETERS = {
    "ENABLE_COUNTERS": 1, "ENABLE_COUNTERS64": 0, "ENABLE_REGS_16_31": 1,
    "ENABLE_REGS_DUALPORT": 1, "LATCHED_MEM_RDATA": 0, "TWO_STAGE_SHIFT": 1,
    "BARREL_SHIFTER": 1, "CATCH_MISALIGN": 0, "CATCH_ILLINSN": 1, "ENABLE_PCPI": 0,
    "ENABLE_MUL": 0, "ENABLE_FAST_MUL": 0, "ENABLE_DIV": 0, "ENABLE_IRQ": 0,
    "ENABLE_TRACE": 0, "REGS_INIT_ZERO": 0, "PROGADDR_RESET": 0,
}


@dataclass(frozen=True)
class CoreConfig:
    """A configuration of the core: ``march`` (the instruction set the firmware is built for,
    gcc's ``-march``), ``ram_bytes`` (the RAM its firmware needs) and ``parameters``
    (PicoRV32's, :data:`_COMMON_PARAMETERS` and these)."""
    march: str
    ram_bytes: int
    parameters: dict = field(default_factory=dict)

    def core_parameters(self):
        """Every PicoRV32 parameter of this configuration."""
        return {**_COMMON_PARAMETERS, **self.parameters}


#: The core's configurations (module docstring).
CORES = {
    "compact": CoreConfig("rv32ic", 8192, {"COMPRESSED_ISA": 1, "TWO_CYCLE_COMPARE": 0,
                                           "TWO_CYCLE_ALU": 0}),
    "fast": CoreConfig("rv32i", 16384, {"COMPRESSED_ISA": 0, "TWO_CYCLE_COMPARE": 1,
                                        "TWO_CYCLE_ALU": 1}),
}


#: The core's register file (32 x 32 bits, two reads and a write a cycle) goes to distributed
#: RAM, not to two block RAMs: the chip's block RAMs are taken (the CPU's four hold its 8 KB).
_REGFILE = "reg [31:0] cpuregs [0:regfile_size-1];"


def verilog_text():
    """The core's Verilog (``picorv32.v`` of the ``pythondata-cpu-picorv32`` package), its
    register file marked ``ram_style = "distributed"``: every flow that converts a design with
    this component reads it beside Amaranth's output."""
    import pythondata_cpu_picorv32
    text = (Path(pythondata_cpu_picorv32.data_location) / "picorv32.v").read_text()
    if text.count(_REGFILE) != 1:
        raise RuntimeError("picorv32.v: the register file declaration was not found")
    return text.replace(_REGFILE, f'(* ram_style = "distributed" *) {_REGFILE}')


def _split_counter(m, name, *, load=None, value=None, down=False):
    """A 32-bit counter as two 16-bit halves, the high half stepping in the same cycle as the
    low half wraps (its enable decoded from the registered low half), so no carry chain is
    longer than 16 bits and a read of both halves is always consistent. ``load``/``value``:
    load a new count; ``down``: count down and stop at 0. Returns (count, zero)."""
    lo = Signal(16, name=f"{name}_lo")
    hi = Signal(16, name=f"{name}_hi")
    count = Signal(32, name=name)
    m.d.comb += count.eq(Cat(lo, hi))
    lo_edge = Signal(name=f"{name}_lo_edge")
    zero = Signal(name=f"{name}_zero")
    if down:
        m.d.comb += [lo_edge.eq(lo == 0), zero.eq(lo_edge & (hi == 0))]
        with m.If(load):
            m.d.sync += [lo.eq(value[:16]), hi.eq(value[16:])]
        with m.Elif(~zero):
            m.d.sync += lo.eq(lo - 1)
            with m.If(lo_edge):
                m.d.sync += hi.eq(hi - 1)
    else:
        m.d.comb += lo_edge.eq(lo == 0xFFFF)
        m.d.sync += lo.eq(lo + 1)
        with m.If(lo_edge):
            m.d.sync += hi.eq(hi + 1)
    return count, zero


class RiscvCPU(wiring.Component):
    """PicoRV32 with its memory, a timer and an I/O bus bridge (module docstring).

    Parameters: ``core`` (a name in :data:`CORES`: ``"compact"``, the default, or
    ``"fast"``), ``image`` (a list of 32-bit words, the RAM's initial contents, built for the
    core's ``march``; at most ``ram_bytes`` / 4; None: zeros), ``ram_bytes`` (a power of two,
    1 KB..64 KB; None: the core's), ``io_timeout`` (cycles an I/O access waits for
    ``ready``), ``ram_register`` (default: a register between the RAM and the core, one wait
    state a RAM access, for a faster clock; False: none, the RAM answers at once)."""

    def __init__(self, *, core="compact", image=None, ram_bytes=None, io_timeout=64,
                 ram_register=True):
        if core not in CORES:
            self._MustUse__silence = True
            raise ValueError(f"core must be one of {', '.join(CORES)}, not {core!r}")
        self._core = CORES[core]
        if ram_bytes is None:
            ram_bytes = self._core.ram_bytes
        if not isinstance(ram_bytes, int) or ram_bytes < 1024 or ram_bytes > 65536 or \
                ram_bytes & (ram_bytes - 1):
            self._MustUse__silence = True
            raise ValueError(f"ram_bytes must be a power of two, 1024..65536, not {ram_bytes!r}")
        words = ram_bytes // 4
        image = list(image or [])
        if len(image) > words:
            self._MustUse__silence = True
            raise ValueError(f"the image has {len(image)} words; the RAM holds {words}")
        self._image = image
        self._ram_bytes = ram_bytes
        self._io_timeout = io_timeout
        self._ram_register = bool(ram_register)
        super().__init__({"bus": Out(IOBusSignature()), "idle": Out(1), "trap": Out(1)})

    def elaborate(self, platform):
        m = Module()
        if platform is not None:        # a vendor build reads the core's Verilog beside ours
            platform.add_file("picorv32.v", verilog_text())
        words = self._ram_bytes // 4
        abits = (words - 1).bit_length()

        valid, instr, ready = Signal(), Signal(), Signal()
        addr, wdata, rdata = Signal(32), Signal(32), Signal(32)
        wstrb = Signal(4)
        la_read, la_addr = Signal(), Signal(32)
        # The core's reset from a register of its own, placed with the core: the core uses its
        # reset in its combinational logic too (the look-ahead read, the prefetch state), and
        # the domain's reset comes from far across the chip; the core leaves reset a cycle late.
        core_rst = Signal(init=1, reset_less=True)
        m.d.sync += core_rst.eq(ResetSignal())
        m.submodules.core = Instance(
            "picorv32",
            **{f"p_{k}": Const(v, 32) if k == "PROGADDR_RESET" else Const(v, 1)
               for k, v in self._core.core_parameters().items()},
            i_clk=ClockSignal(), i_resetn=~core_rst,
            o_trap=self.trap,
            o_mem_valid=valid, o_mem_instr=instr, i_mem_ready=ready,
            o_mem_addr=addr, o_mem_wdata=wdata, o_mem_wstrb=wstrb, i_mem_rdata=rdata,
            o_mem_la_read=la_read, o_mem_la_addr=la_addr,
            i_pcpi_wr=0, i_pcpi_rd=Const(0, 32), i_pcpi_wait=0, i_pcpi_ready=0,
            i_irq=Const(0, 32),
        )

        # Address decode: the core's address is a register.
        is_io = Signal()
        is_timer = Signal()
        m.d.comb += [is_io.eq(addr[31] & (addr[16:20] != 3)),
                     is_timer.eq(addr[31] & (addr[16:20] == 3))]
        write = wstrb.any()

        # RAM, no wait state: a read is started by the core's look-ahead address (mem_la_read,
        # the cycle before mem_valid) and its data are there with mem_valid; a write happens
        # in the cycle of mem_valid. Either way ready comes at once.
        m.submodules.ram = ram = Memory(shape=32, depth=words, init=self._image)
        rp = ram.read_port()
        wp = ram.write_port(granularity=8)
        ram_ready = Signal()
        ram_data = Signal(32)
        if self._ram_register:
            # a register after the memory: one wait state, and the core's read path starts
            # from a flip-flop, not from the memory's output
            m.d.sync += [ram_ready.eq(valid & ~addr[31] & ~ram_ready), ram_data.eq(rp.data)]
        else:
            m.d.comb += [ram_ready.eq(valid & ~addr[31]), ram_data.eq(rp.data)]
        m.d.comb += [rp.addr.eq(la_addr[2:2 + abits]), rp.en.eq(la_read),
                     wp.addr.eq(addr[2:2 + abits]), wp.data.eq(wdata),
                     wp.en.eq(Mux(ram_ready, wstrb, 0))]

        # Registered answers of the timer and the I/O bus.
        reg_ready = Signal()
        reg_data = Signal(32)
        m.d.sync += reg_ready.eq(0)

        # Timer.
        count, _ = _split_counter(m, "timer_count")
        load = Signal()
        remaining, done = _split_counter(m, "timer_wait", load=load, value=wdata, down=True)
        waiting = Signal()
        timer_go = valid & is_timer & ~reg_ready & ~waiting
        m.d.comb += load.eq(timer_go & write & (addr[2:4] == TIMER_REGS["WAIT"] >> 2))
        with m.If(waiting):
            with m.If(done):
                m.d.sync += [waiting.eq(0), reg_ready.eq(1)]
        with m.Elif(load):
            m.d.sync += waiting.eq(1)
        with m.Elif(timer_go):
            m.d.sync += [reg_ready.eq(1), reg_data.eq(count)]
        m.d.comb += self.idle.eq(waiting)

        # I/O bus: the strobe from a register, the cycle after the access begins (the bus's
        # slaves decode it with the depth of logic they had behind an external CPU's
        # registered pins), then wait for ready (or time out).
        bus = self.bus
        io_busy = Signal()
        io_wait = Signal(range(self._io_timeout + 1))
        io_go = valid & is_io & ~io_busy & ~reg_ready
        m.d.sync += [
            bus.addr_strobe.eq(io_go),
            bus.read_strobe.eq(io_go & ~write),
            bus.write_strobe.eq(io_go & write),
            bus.address.eq(addr),
            bus.write_data.eq(wdata),
            bus.byte_enable.eq(Mux(write, wstrb, 0b1111)),
        ]
        with m.If(io_go):
            m.d.sync += [io_busy.eq(1), io_wait.eq(0)]
        with m.Elif(io_busy & ~bus.addr_strobe):
            m.d.sync += io_wait.eq(io_wait + 1)
            with m.If(bus.ready):
                m.d.sync += [io_busy.eq(0), reg_ready.eq(1), reg_data.eq(bus.read_data)]
            with m.Elif(io_wait == self._io_timeout):
                m.d.sync += [io_busy.eq(0), reg_ready.eq(1), reg_data.eq(0xFFFF_FFFF)]

        m.d.comb += [ready.eq(ram_ready | reg_ready),
                     rdata.eq(Mux(ram_ready, ram_data, reg_data))]
        return m
