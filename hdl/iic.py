"""IIC (I2C) master with the register layout of the Xilinx AXI IIC Bus Interface.

Specification followed: NXP UM10204 (I2C-bus specification) for the bus; Xilinx PG090 (AXI
IIC Bus Interface v2.1, "Register Space" and "Dynamic Controller Logic Flow") for the
registers. Only the subset the firmware (``firmware/src/iic.c``) uses is implemented, on the
MicroBlaze MCS I/O bus (:class:`hdl.regs.IOBusSignature`) instead of AXI4-Lite:

======  ==========  ====================================================================
offset  register    implemented behaviour
======  ==========  ====================================================================
0x020   IISR        bit 0 arbitration lost, 1 TX error (NACK), 2 TX FIFO empty, 3 RX FIFO
                    occupancy = RFD + 1, 4 bus not busy. Toggle on write (write back the
                    bits read to clear them). Bits 2-4 are re-set while their condition holds.
0x040   SOFTR       writing 0xA resets the whole controller (registers, FIFOs, state) one
                    cycle later and releases both lines; other values are ignored.
0x100   CR          bit 0 EN, bit 1 TX_FIFO_RESET (held in reset while 1); bits 2-6 are stored
                    but unused: only dynamic mode is implemented.
0x104   SR          bit 2 BB (bus busy: a START seen and no STOP yet, or a transfer of ours in
                    progress), 3 SRW (master reading), 4 TX_FIFO_FULL, 5 RX_FIFO_FULL,
                    6 RX_FIFO_EMPTY, 7 TX_FIFO_EMPTY.
0x108   TX_FIFO     16 x 10 bits. Dynamic mode: bit 8 START before this byte (a repeated
                    START if the bus is ours), bit 9 STOP after it. After an address with the
                    read bit, the next word is the number of bytes to read.
0x10C   RX_FIFO     16 x 8 bits, a read pops (an empty FIFO reads 0).
0x114   TX_FIFO_OCY entries - 1 (0 when empty).
0x118   RX_FIFO_OCY entries - 1 (0 when empty).
0x120   RX_FIFO_PIRQ 4 bits: IISR bit 3 is set when RX occupancy = value + 1.
======  ==========  ====================================================================

Bus behaviour:

- Each bit is four quarter periods of ``clk_div`` cycles (``clk_div`` >= 4): with SCL low,
  a data hold quarter then a set-up quarter (SDA changes between them); SCL released, and
  two quarters high (SDA sampled between them); SCL pulled low. The rising edge is seen
  3 cycles late (output register + 2-flip-flop synchroniser), so the SCL period is
  4 x clk_div + 3 cycles: clk_div = 125 gives 503 cycles, 99.4 kHz at 50 MHz (measured in
  tests/test_iic.py with clk_div = 4: 19 cycles).
- Clock stretching: after releasing SCL the controller waits, without limit, until SCL reads
  high; the quarter-period timer only runs while it is high. Bounding this wait is the
  firmware's job (it gives up and writes SOFTR).
- A NACK of an address or data byte sets IISR bit 1, empties the TX FIFO and sends STOP.
- Arbitration: reading SDA low while sending a 1 (or before a START) sets IISR bit 0,
  releases both lines and empties the TX FIFO.
- While a transfer is ours and the TX FIFO runs empty without a STOP, SCL is held low.
- When reading, the last byte of a count is NACKed (as the protocol requires), the others
  ACKed; if the RX FIFO is full the controller waits (SCL held low) before the ACK bit.

Pads are open drain: ``scl_o``/``sda_o`` are always 0, ``*_oe`` = 1 pulls the line low, 0
releases it; ``*_i`` is the line as seen at the pad (synchronised here with two flip-flops).
"""

from amaranth.hdl import Cat, Const, Module, Mux, ResetInserter, Signal
from amaranth.lib import wiring
from amaranth.lib.cdc import FFSynchronizer
from amaranth.lib.fifo import SyncFIFOBuffered
from amaranth.lib.wiring import In, Out

from . import regmap
from .regs import BusWindow, IOBusSignature, check_window_base

__all__ = ["IICMaster", "XIIC"]


class XIIC:
    """Register offsets and bits (the same names as firmware/include/xiic_l.h)."""
    IISR_OFFSET = 0x20
    RESETR_OFFSET = 0x40
    CR_REG_OFFSET = 0x100
    SR_REG_OFFSET = 0x104
    DTR_REG_OFFSET = 0x108
    DRR_REG_OFFSET = 0x10C
    TFO_REG_OFFSET = 0x114
    RFO_REG_OFFSET = 0x118
    RFD_REG_OFFSET = 0x120
    RESET_MASK = 0xA
    CR_ENABLE_DEVICE_MASK = 0x01
    CR_TX_FIFO_RESET_MASK = 0x02
    SR_BUS_BUSY_MASK = 0x04
    SR_MSTR_RDING_SLAVE_MASK = 0x08
    SR_TX_FIFO_FULL_MASK = 0x10
    SR_RX_FIFO_FULL_MASK = 0x20
    SR_RX_FIFO_EMPTY_MASK = 0x40
    SR_TX_FIFO_EMPTY_MASK = 0x80
    INTR_ARB_LOST_MASK = 0x01
    INTR_TX_ERROR_MASK = 0x02
    INTR_TX_EMPTY_MASK = 0x04
    INTR_RX_FULL_MASK = 0x08
    INTR_BNB_MASK = 0x10
    TX_DYN_START_MASK = 0x100
    TX_DYN_STOP_MASK = 0x200
    FIFO_DEPTH = 16


class _Core(wiring.Component):
    """Everything SOFTR resets: registers, FIFOs, the bus engine."""

    def __init__(self, clk_div):
        self._clk_div = clk_div
        super().__init__({
            # register accesses from the bus front end (one-cycle strobes)
            "wr_isr": In(1), "wr_cr": In(1), "wr_tx": In(1), "wr_rfd": In(1), "rd_rx": In(1),
            "wdata": In(32),
            "isr": Out(8), "cr": Out(8), "sr": Out(8), "rx_data": Out(8),
            "tfo": Out(8), "rfo": Out(8), "rfd": Out(4),
            "scl_oe": Out(1), "sda_oe": Out(1), "scl_i": In(1), "sda_i": In(1),
        })

    def elaborate(self, platform):
        m = Module()
        depth = XIIC.FIFO_DEPTH
        flush_tx = Signal()
        engine_flush = Signal()
        tx = m.submodules.tx = ResetInserter(flush_tx)(SyncFIFOBuffered(width=10, depth=depth))
        rx = m.submodules.rx = SyncFIFOBuffered(width=8, depth=depth)

        cr = Signal(7)
        rfd = Signal(4)
        isr = Signal(5)
        with m.If(self.wr_cr):
            m.d.sync += cr.eq(self.wdata[:7])
        with m.If(self.wr_rfd):
            m.d.sync += rfd.eq(self.wdata[:4])
        enabled = cr[0]

        # TX FIFO: firmware writes
        m.d.comb += [tx.w_data.eq(self.wdata[:10]), tx.w_en.eq(self.wr_tx)]
        # RX FIFO: firmware reads
        m.d.comb += [rx.r_en.eq(self.rd_rx), self.rx_data.eq(Mux(rx.r_rdy, rx.r_data, 0))]

        # bus monitor (START/STOP seen on the lines)
        scl = Signal(init=1)
        sda = Signal(init=1)
        m.submodules.scl_sync = FFSynchronizer(self.scl_i, scl, init=1)
        m.submodules.sda_sync = FFSynchronizer(self.sda_i, sda, init=1)
        sda_prev = Signal(init=1)
        scl_prev = Signal(init=1)
        busy_seen = Signal()
        m.d.sync += [sda_prev.eq(sda), scl_prev.eq(scl)]
        with m.If(scl & scl_prev & sda_prev & ~sda):
            m.d.sync += busy_seen.eq(1)
        with m.Elif(scl & scl_prev & ~sda_prev & sda):
            m.d.sync += busy_seen.eq(0)

        # line drivers, registered
        scl_low = Signal()
        sda_low = Signal()
        m.d.comb += [self.scl_oe.eq(scl_low), self.sda_oe.eq(sda_low)]

        word = Signal(10)
        shift = Signal(8)
        bits = Signal(4)
        count = Signal(8)
        active = Signal()      # the bus is ours (between our START and STOP)
        reading = Signal()
        need_count = Signal()
        is_addr = Signal()
        timer = Signal(range(self._clk_div + 1))
        set_arb = Signal()
        set_nack = Signal()

        # One quarter-period timer for every state that times a quarter (the state says so
        # through `timed`, and `wait_high` if the quarter runs only while SCL reads high)
        timed = Signal()
        wait_high = Signal()
        running = Signal()
        quarter_done = Signal()
        m.d.comb += [running.eq(~wait_high | scl),
                     quarter_done.eq(timed & running & (timer == 0))]
        with m.If(timed):
            with m.If(quarter_done | ~running):     # ~running: stretched, restart the quarter
                m.d.sync += timer.eq(self._clk_div - 1)
            with m.Else():
                m.d.sync += timer.eq(timer - 1)

        def quarter(wait_scl_high=False):
            """Condition that ends a quarter period (and reloads the timer)."""
            m.d.comb += timed.eq(1)
            if wait_scl_high:
                m.d.comb += wait_high.eq(1)
            return quarter_done

        with m.FSM(name="engine") as fsm:
            with m.State("IDLE"):
                with m.If(enabled & tx.r_rdy):
                    m.d.comb += tx.r_en.eq(1)
                    m.d.sync += [word.eq(tx.r_data), timer.eq(self._clk_div - 1)]
                    m.next = "DISPATCH"
            with m.State("DISPATCH"):
                with m.If(word[8]):
                    m.next = "START_RELEASE_SDA"
                with m.Elif(~active):
                    m.next = "IDLE"                       # data without START: dropped
                with m.Elif(need_count):
                    m.d.sync += [count.eq(word[:8]), need_count.eq(0)]
                    with m.If(word[:8] == 0):
                        m.next = "AFTER_BYTE"
                    with m.Else():
                        m.d.sync += bits.eq(8)
                        m.next = "RX_BIT_HOLD"
                with m.Else():
                    m.d.sync += [shift.eq(word[:8]), bits.eq(8), is_addr.eq(0)]
                    m.next = "TX_BIT_HOLD"

            # (repeated) START: SDA released with SCL low, SCL up, SDA down, SCL down
            with m.State("START_RELEASE_SDA"):
                with m.If(quarter()):
                    m.d.sync += sda_low.eq(0)
                    m.next = "START_SDA_HIGH"
            with m.State("START_SDA_HIGH"):
                with m.If(quarter()):
                    m.d.sync += scl_low.eq(0)
                    m.next = "START_SCL_HIGH"
            with m.State("START_SCL_HIGH"):
                with m.If(quarter(wait_scl_high=True)):
                    with m.If(~sda):
                        m.d.comb += set_arb.eq(1)         # somebody holds SDA low
                        m.next = "LOST"
                    with m.Else():
                        m.d.sync += sda_low.eq(1)
                        m.next = "START_HOLD"
            with m.State("START_HOLD"):
                with m.If(quarter()):
                    m.d.sync += scl_low.eq(1)
                    m.next = "START_DONE"
            with m.State("START_DONE"):
                with m.If(quarter()):
                    m.d.sync += [active.eq(1), reading.eq(0), need_count.eq(0),
                                 shift.eq(word[:8]), bits.eq(8), is_addr.eq(1)]
                    m.next = "TX_BIT_HOLD"

            # one byte out, MSB first, then the acknowledge bit in
            with m.State("TX_BIT_HOLD"):                  # SCL low: data hold time
                with m.If(quarter()):
                    m.d.sync += sda_low.eq(~shift[7])
                    m.next = "TX_BIT_LOW"
            with m.State("TX_BIT_LOW"):                   # data set-up time
                with m.If(quarter()):
                    m.d.sync += scl_low.eq(0)
                    m.next = "TX_BIT_HIGH"
            with m.State("TX_BIT_HIGH"):
                with m.If(quarter(wait_scl_high=True)):
                    with m.If(shift[7] & ~sda):
                        m.d.comb += set_arb.eq(1)
                        m.next = "LOST"
                    with m.Else():
                        m.next = "TX_BIT_HIGH2"
            with m.State("TX_BIT_HIGH2"):
                with m.If(quarter()):
                    m.d.sync += [scl_low.eq(1), shift.eq(shift << 1), bits.eq(bits - 1)]
                    with m.If(bits == 1):
                        m.next = "ACK_IN_LOW"
                    with m.Else():
                        m.next = "TX_BIT_HOLD"
            with m.State("ACK_IN_LOW"):
                with m.If(quarter()):
                    m.d.sync += sda_low.eq(0)
                    m.next = "ACK_IN_LOW2"
            with m.State("ACK_IN_LOW2"):
                with m.If(quarter()):
                    m.d.sync += scl_low.eq(0)
                    m.next = "ACK_IN_HIGH"
            with m.State("ACK_IN_HIGH"):
                with m.If(quarter(wait_scl_high=True)):
                    with m.If(sda):
                        m.d.comb += set_nack.eq(1)
                        m.next = "NACK_HIGH2"
                    with m.Else():
                        m.next = "ACK_IN_HIGH2"
            with m.State("ACK_IN_HIGH2"):
                with m.If(quarter()):
                    m.d.sync += scl_low.eq(1)
                    with m.If(is_addr & word[0]):
                        m.d.sync += [reading.eq(1), need_count.eq(1)]
                    m.next = "AFTER_BYTE"
            with m.State("NACK_HIGH2"):
                m.d.comb += engine_flush.eq(1)
                with m.If(quarter()):
                    m.d.sync += scl_low.eq(1)
                    m.next = "STOP_HOLD"

            # one byte in, then our acknowledge (NACK for the last byte of the count)
            with m.State("RX_BIT_HOLD"):
                with m.If(quarter()):
                    m.d.sync += sda_low.eq(0)
                    m.next = "RX_BIT_LOW"
            with m.State("RX_BIT_LOW"):
                with m.If(quarter()):
                    m.d.sync += scl_low.eq(0)
                    m.next = "RX_BIT_HIGH"
            with m.State("RX_BIT_HIGH"):
                with m.If(quarter(wait_scl_high=True)):
                    m.d.sync += shift.eq(Cat(sda, shift[:7]))
                    m.next = "RX_BIT_HIGH2"
            with m.State("RX_BIT_HIGH2"):
                with m.If(quarter()):
                    m.d.sync += [scl_low.eq(1), bits.eq(bits - 1)]
                    with m.If(bits == 1):
                        m.next = "RX_PUSH"
                    with m.Else():
                        m.next = "RX_BIT_HOLD"
            with m.State("RX_PUSH"):
                with m.If(rx.w_rdy):                      # else wait, SCL held low
                    m.d.comb += [rx.w_en.eq(1), rx.w_data.eq(shift)]
                    m.d.sync += timer.eq(self._clk_div - 1)
                    m.next = "ACK_OUT_HOLD"
            with m.State("ACK_OUT_HOLD"):
                with m.If(quarter()):
                    m.d.sync += sda_low.eq(count != 1)
                    m.next = "ACK_OUT_LOW"
            with m.State("ACK_OUT_LOW"):
                with m.If(quarter()):
                    m.d.sync += scl_low.eq(0)
                    m.next = "ACK_OUT_HIGH"
            with m.State("ACK_OUT_HIGH"):
                with m.If(quarter(wait_scl_high=True)):
                    m.next = "ACK_OUT_HIGH2"
            with m.State("ACK_OUT_HIGH2"):
                with m.If(quarter()):
                    m.d.sync += [scl_low.eq(1), count.eq(count - 1), bits.eq(8)]
                    with m.If(count == 1):
                        m.next = "AFTER_BYTE"
                    with m.Else():
                        m.next = "RX_BIT_HOLD"

            with m.State("AFTER_BYTE"):
                with m.If(word[9] & ~need_count):
                    m.next = "STOP_HOLD"
                with m.Else():
                    m.d.sync += sda_low.eq(0)
                    m.next = "IDLE"                       # bus kept: SCL stays low

            # STOP: SDA low with SCL low, SCL up, SDA up
            with m.State("STOP_HOLD"):
                with m.If(quarter()):
                    m.d.sync += sda_low.eq(1)
                    m.next = "STOP_LOW"
            with m.State("STOP_LOW"):
                with m.If(quarter()):
                    m.d.sync += scl_low.eq(0)
                    m.next = "STOP_SCL_HIGH"
            with m.State("STOP_SCL_HIGH"):
                with m.If(quarter(wait_scl_high=True)):
                    m.d.sync += sda_low.eq(0)
                    m.next = "STOP_BUS_FREE"
            with m.State("STOP_BUS_FREE"):
                with m.If(quarter()):
                    m.d.sync += [active.eq(0), reading.eq(0), need_count.eq(0)]
                    m.next = "STOP_BUS_FREE2"
            with m.State("STOP_BUS_FREE2"):                # bus free time before a new START
                with m.If(quarter()):
                    m.next = "IDLE"

            with m.State("LOST"):
                m.d.comb += engine_flush.eq(1)
                m.d.sync += [scl_low.eq(0), sda_low.eq(0), active.eq(0), reading.eq(0),
                             need_count.eq(0)]
                m.next = "IDLE"

        m.d.comb += flush_tx.eq(cr[1] | engine_flush)

        bus_busy = Signal()
        m.d.comb += bus_busy.eq(busy_seen | active | ~fsm.ongoing("IDLE"))
        isr_set = Cat(set_arb, set_nack, ~tx.r_rdy, rx.level == rfd + 1, ~bus_busy)
        toggle = Mux(self.wr_isr, self.wdata[:5], 0)
        m.d.sync += isr.eq((isr ^ toggle) | isr_set)

        m.d.comb += [
            self.isr.eq(isr),
            self.cr.eq(cr),
            self.rfd.eq(rfd),
            self.sr.eq(Cat(Const(0, 2), bus_busy, reading, tx.level == depth, rx.level == depth,
                           ~rx.r_rdy, tx.level == 0)),
            self.tfo.eq(Mux(tx.level != 0, tx.level - 1, 0)),
            self.rfo.eq(Mux(rx.level != 0, rx.level - 1, 0)),
        ]
        return m


class IICMaster(wiring.Component):
    """IIC master with AXI IIC-compatible registers on the MCS I/O bus.

    Parameters (keyword-only)
    -------------------------
    clk_div : int
        Clock cycles per quarter SCL period (>= 4). 125 gives 100 kHz at 50 MHz.
    base : int
        Byte address of the 0x200-byte register window.

    Ports
    -----
    bus : In(IOBusSignature)
        Register access; ``ready`` one cycle after the strobe, never stalls.
    scl_o, scl_oe, scl_i, sda_o, sda_oe, sda_i
        Open-drain pads: ``*_o`` is always 0, ``*_oe`` pulls the line low.
    """

    def __init__(self, *, clk_div=125, base=regmap.IIC_BASEADDR):
        if not isinstance(clk_div, int) or clk_div < 4:
            self._MustUse__silence = True
            raise ValueError(f"clk_div must be an integer >= 4, not {clk_div!r}")
        check_window_base(self, base, regmap.IIC_WINDOW)
        self._clk_div = clk_div
        self._base = base
        super().__init__({
            "bus": In(IOBusSignature()),
            "scl_o": Out(1), "scl_oe": Out(1), "scl_i": In(1, init=1),
            "sda_o": Out(1), "sda_oe": Out(1), "sda_i": In(1, init=1),
        })

    @property
    def clk_div(self):
        return self._clk_div

    def elaborate(self, platform):
        m = Module()
        bus = self.bus
        window = BusWindow(m, bus, self._base, regmap.IIC_WINDOW)
        offset, do_read = window.offset, window.read
        do_write = window.write & (bus.byte_enable == 0xF)

        soft_reset = Signal()
        m.d.sync += soft_reset.eq(do_write & (offset == XIIC.RESETR_OFFSET)
                                  & (bus.write_data == XIIC.RESET_MASK))
        core = m.submodules.core = ResetInserter(soft_reset)(_Core(self._clk_div))

        m.d.comb += [
            core.wdata.eq(bus.write_data),
            core.wr_isr.eq(do_write & (offset == XIIC.IISR_OFFSET)),
            core.wr_cr.eq(do_write & (offset == XIIC.CR_REG_OFFSET)),
            core.wr_tx.eq(do_write & (offset == XIIC.DTR_REG_OFFSET)),
            core.wr_rfd.eq(do_write & (offset == XIIC.RFD_REG_OFFSET)),
            core.rd_rx.eq(do_read & (offset == XIIC.DRR_REG_OFFSET)),
            core.scl_i.eq(self.scl_i),
            core.sda_i.eq(self.sda_i),
            self.scl_oe.eq(core.scl_oe),
            self.sda_oe.eq(core.sda_oe),
            self.scl_o.eq(0),
            self.sda_o.eq(0),
        ]

        value = Signal(32)
        with m.Switch(offset):
            for off, sig in ((XIIC.IISR_OFFSET, core.isr), (XIIC.CR_REG_OFFSET, core.cr),
                             (XIIC.SR_REG_OFFSET, core.sr), (XIIC.DRR_REG_OFFSET, core.rx_data),
                             (XIIC.TFO_REG_OFFSET, core.tfo), (XIIC.RFO_REG_OFFSET, core.rfo),
                             (XIIC.RFD_REG_OFFSET, core.rfd)):
                with m.Case(off):
                    m.d.comb += value.eq(sig)

        window.answer(value)
        return m
