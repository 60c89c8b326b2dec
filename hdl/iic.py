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

from types import SimpleNamespace

from amaranth.hdl import Cat, Const, Module, Mux, ResetInserter, Signal
from amaranth.lib import wiring
from amaranth.lib.cdc import FFSynchronizer
from amaranth.lib.fifo import SyncFIFOBuffered
from amaranth.lib.wiring import In, Out

from . import regmap
from .regs import BusWindow, IOBusSignature, check_window_base

__all__ = ["IICMaster", "IICBusMonitor", "IICQuarterTimer", "IICBusEngine", "XIIC"]


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


class IICBusMonitor(wiring.Component):
    """The bus lines as the controller sees them, and whether the bus is busy.

    ``scl_i``/``sda_i`` (the pads) pass through a two-flip-flop synchroniser each to ``scl`` and
    ``sda``. ``busy`` is set by a START (SDA falling while SCL is high, on two successive
    synchronised samples) and cleared by a STOP (SDA rising while SCL is high), whoever sent
    them, so another master's transfer is seen too.

    Ports
    -----
    scl_i, sda_i : In(1)
        The lines at the pads (1: released), asynchronous.
    scl, sda : Out(1)
        The lines, synchronised: 2 cycles after the pads (1 after reset).
    busy : Out(1)
        Registered: one cycle after the synchronised sample that completes the START or STOP.
    """
    scl_i: In(1, init=1)
    sda_i: In(1, init=1)
    scl: Out(1, init=1)
    sda: Out(1, init=1)
    busy: Out(1)

    def elaborate(self, platform):
        m = Module()
        scl, sda = self.scl, self.sda
        m.submodules.scl_sync = FFSynchronizer(self.scl_i, scl, init=1)
        m.submodules.sda_sync = FFSynchronizer(self.sda_i, sda, init=1)
        sda_prev = Signal(init=1)
        scl_prev = Signal(init=1)
        m.d.sync += [sda_prev.eq(sda), scl_prev.eq(scl)]
        with m.If(scl & scl_prev & sda_prev & ~sda):
            m.d.sync += self.busy.eq(1)
        with m.Elif(scl & scl_prev & ~sda_prev & sda):
            m.d.sync += self.busy.eq(0)
        return m


class IICQuarterTimer(wiring.Component):
    """The quarter-period timer of the bus engine: one for every state that times a quarter.

    A state that times a quarter holds ``timed`` high, and ``wait_high`` too if its quarter runs
    only while SCL reads high (after releasing SCL: clock stretching by a slave waits here, and
    the quarter starts again from its beginning while ``scl`` is low). ``done`` is high in the
    last cycle of the quarter, ``clk_div`` cycles after the quarter started (or after SCL was
    last seen low), and the timer reloads for the next one in that cycle. ``restart`` reloads
    it: for a state that starts timing in the next cycle after a wait of its own.

    Parameters
    ----------
    clk_div : int
        Cycles per quarter period (>= 4).

    Ports
    -----
    timed, wait_high, restart : In(1)
        Set by the engine's state, combinationally.
    scl : In(1)
        The synchronised SCL line (:class:`IICBusMonitor`).
    done : Out(1)
        Combinational, from the timer register and the inputs.
    """
    timed: In(1)
    wait_high: In(1)
    restart: In(1)
    scl: In(1)
    done: Out(1)

    def __init__(self, clk_div):
        self._clk_div = clk_div
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        timer = Signal(range(self._clk_div + 1))
        running = Signal()
        m.d.comb += [running.eq(~self.wait_high | self.scl),
                     self.done.eq(self.timed & running & (timer == 0))]
        with m.If(self.timed):
            with m.If(self.done | ~running):        # ~running: stretched, restart the quarter
                m.d.sync += timer.eq(self._clk_div - 1)
            with m.Else():
                m.d.sync += timer.eq(timer - 1)
        with m.If(self.restart):
            m.d.sync += timer.eq(self._clk_div - 1)
        return m


class IICBusEngine(wiring.Component):
    """The bus engine in dynamic mode: takes the TX FIFO's words one at a time and turns them
    into START, address and data bytes, read counts and STOP on the lines.

    A word (10 bits, the TX_FIFO register's) with bit 8 sends a (repeated) START and then its
    low byte as the address; without it, the low byte is a data byte, or after an address with
    the read bit the number of bytes to read (each received byte pushed into the RX FIFO, the
    last of the count NACKed). Bit 9 sends a STOP after the byte (or after the count's last
    byte). Each bit takes four quarter periods (:class:`IICQuarterTimer`): SCL low for a hold
    and a set-up quarter, SDA changed between them; SCL released and two quarters high, SDA
    sampled between them. A NACK of ours sets ``nack`` and sends STOP; a line read low where it
    should be high (arbitration) sets ``lost`` and releases both lines. Both also empty the TX
    FIFO (``flush``).

    Parameters
    ----------
    clk_div : int
        Cycles per quarter period (>= 4).

    Ports
    -----
    enabled : In(1)
        CR bit 0: words are taken only while it is set.
    tx_ready, tx_word : In(1), In(10)
        The TX FIFO's read side; ``tx_take`` (Out) pops it, in the cycle the word is taken.
    rx_room : In(1)
        The RX FIFO can take a byte; ``rx_push`` and ``rx_byte`` (Out) write it. Without room
        the engine waits with SCL held low before the acknowledge bit.
    scl, sda : In(1)
        The synchronised lines (:class:`IICBusMonitor`).
    scl_oe, sda_oe : Out(1)
        Registered line drivers: 1 pulls the line low.
    lost, nack : Out(1)
        One-cycle strobes for IISR bits 0 and 1.
    flush : Out(1)
        Empty the TX FIFO (after a NACK or a lost arbitration).
    ours : Out(1)
        The bus is ours (between our START and STOP) or a word is being handled.
    reading : Out(1)
        The master is reading (SR bit 3).

    Latency: a word is taken in the cycle ``tx_ready`` is seen in the idle state; the lines
    change on quarter boundaries only, through their output registers.
    """
    enabled: In(1)
    tx_ready: In(1)
    tx_word: In(10)
    tx_take: Out(1)
    rx_room: In(1)
    rx_push: Out(1)
    rx_byte: Out(8)
    scl: In(1, init=1)
    sda: In(1, init=1)
    scl_oe: Out(1)
    sda_oe: Out(1)
    lost: Out(1)
    nack: Out(1)
    flush: Out(1)
    ours: Out(1)
    reading: Out(1)

    def __init__(self, clk_div):
        self._clk_div = clk_div
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        m.submodules.timer = timer = IICQuarterTimer(self._clk_div)
        m.d.comb += timer.scl.eq(self.scl)
        # the engine's registers, shared by the methods that make its states
        r = SimpleNamespace(
            word=Signal(10, name="word"), shift=Signal(8, name="shift"),
            bits=Signal(4, name="bits"), count=Signal(8, name="count"),
            active=Signal(name="active"),   # the bus is ours (between our START and STOP)
            reading=self.reading, need_count=Signal(name="need_count"),
            is_addr=Signal(name="is_addr"), scl_low=self.scl_oe, sda_low=self.sda_oe)

        def quarter(wait_scl_high=False):
            """Condition that ends a quarter period (and reloads the timer)."""
            m.d.comb += timer.timed.eq(1)
            if wait_scl_high:
                m.d.comb += timer.wait_high.eq(1)
            return timer.done

        # the states in the order of the bus: the FSM numbers them in order of appearance
        with m.FSM(name="engine") as fsm:
            self._word_states(m, r, timer)
            self._start_states(m, r, quarter)
            self._transmit_states(m, r, quarter)
            self._receive_states(m, r, quarter, timer)
            self._stop_states(m, r, quarter)
        m.d.comb += self.ours.eq(r.active | ~fsm.ongoing("IDLE"))
        return m

    def _word_states(self, m, r, timer):
        """Take a word from the TX FIFO and decide what it is."""
        with m.State("IDLE"):
            with m.If(self.enabled & self.tx_ready):
                m.d.comb += [self.tx_take.eq(1), timer.restart.eq(1)]
                m.d.sync += r.word.eq(self.tx_word)
                m.next = "DISPATCH"
        with m.State("DISPATCH"):
            with m.If(r.word[8]):
                m.next = "START_RELEASE_SDA"
            with m.Elif(~r.active):
                m.next = "IDLE"                       # data without START: dropped
            with m.Elif(r.need_count):
                m.d.sync += [r.count.eq(r.word[:8]), r.need_count.eq(0)]
                with m.If(r.word[:8] == 0):
                    m.next = "AFTER_BYTE"
                with m.Else():
                    m.d.sync += r.bits.eq(8)
                    m.next = "RX_BIT_HOLD"
            with m.Else():
                m.d.sync += [r.shift.eq(r.word[:8]), r.bits.eq(8), r.is_addr.eq(0)]
                m.next = "TX_BIT_HOLD"

    def _start_states(self, m, r, quarter):
        """(Repeated) START: SDA released with SCL low, SCL up, SDA down, SCL down."""
        with m.State("START_RELEASE_SDA"):
            with m.If(quarter()):
                m.d.sync += r.sda_low.eq(0)
                m.next = "START_SDA_HIGH"
        with m.State("START_SDA_HIGH"):
            with m.If(quarter()):
                m.d.sync += r.scl_low.eq(0)
                m.next = "START_SCL_HIGH"
        with m.State("START_SCL_HIGH"):
            with m.If(quarter(wait_scl_high=True)):
                with m.If(~self.sda):
                    m.d.comb += self.lost.eq(1)           # somebody holds SDA low
                    m.next = "LOST"
                with m.Else():
                    m.d.sync += r.sda_low.eq(1)
                    m.next = "START_HOLD"
        with m.State("START_HOLD"):
            with m.If(quarter()):
                m.d.sync += r.scl_low.eq(1)
                m.next = "START_DONE"
        with m.State("START_DONE"):
            with m.If(quarter()):
                m.d.sync += [r.active.eq(1), r.reading.eq(0), r.need_count.eq(0),
                             r.shift.eq(r.word[:8]), r.bits.eq(8), r.is_addr.eq(1)]
                m.next = "TX_BIT_HOLD"

    def _transmit_states(self, m, r, quarter):
        """One byte out, MSB first, then the acknowledge bit in."""
        with m.State("TX_BIT_HOLD"):                  # SCL low: data hold time
            with m.If(quarter()):
                m.d.sync += r.sda_low.eq(~r.shift[7])
                m.next = "TX_BIT_LOW"
        with m.State("TX_BIT_LOW"):                   # data set-up time
            with m.If(quarter()):
                m.d.sync += r.scl_low.eq(0)
                m.next = "TX_BIT_HIGH"
        with m.State("TX_BIT_HIGH"):
            with m.If(quarter(wait_scl_high=True)):
                with m.If(r.shift[7] & ~self.sda):
                    m.d.comb += self.lost.eq(1)
                    m.next = "LOST"
                with m.Else():
                    m.next = "TX_BIT_HIGH2"
        with m.State("TX_BIT_HIGH2"):
            with m.If(quarter()):
                m.d.sync += [r.scl_low.eq(1), r.shift.eq(r.shift << 1), r.bits.eq(r.bits - 1)]
                with m.If(r.bits == 1):
                    m.next = "ACK_IN_LOW"
                with m.Else():
                    m.next = "TX_BIT_HOLD"
        with m.State("ACK_IN_LOW"):
            with m.If(quarter()):
                m.d.sync += r.sda_low.eq(0)
                m.next = "ACK_IN_LOW2"
        with m.State("ACK_IN_LOW2"):
            with m.If(quarter()):
                m.d.sync += r.scl_low.eq(0)
                m.next = "ACK_IN_HIGH"
        with m.State("ACK_IN_HIGH"):
            with m.If(quarter(wait_scl_high=True)):
                with m.If(self.sda):
                    m.d.comb += self.nack.eq(1)
                    m.next = "NACK_HIGH2"
                with m.Else():
                    m.next = "ACK_IN_HIGH2"
        with m.State("ACK_IN_HIGH2"):
            with m.If(quarter()):
                m.d.sync += r.scl_low.eq(1)
                with m.If(r.is_addr & r.word[0]):
                    m.d.sync += [r.reading.eq(1), r.need_count.eq(1)]
                m.next = "AFTER_BYTE"
        with m.State("NACK_HIGH2"):
            m.d.comb += self.flush.eq(1)
            with m.If(quarter()):
                m.d.sync += r.scl_low.eq(1)
                m.next = "STOP_HOLD"

    def _receive_states(self, m, r, quarter, timer):
        """One byte in, then our acknowledge (NACK for the last byte of the count)."""
        with m.State("RX_BIT_HOLD"):
            with m.If(quarter()):
                m.d.sync += r.sda_low.eq(0)
                m.next = "RX_BIT_LOW"
        with m.State("RX_BIT_LOW"):
            with m.If(quarter()):
                m.d.sync += r.scl_low.eq(0)
                m.next = "RX_BIT_HIGH"
        with m.State("RX_BIT_HIGH"):
            with m.If(quarter(wait_scl_high=True)):
                m.d.sync += r.shift.eq(Cat(self.sda, r.shift[:7]))
                m.next = "RX_BIT_HIGH2"
        with m.State("RX_BIT_HIGH2"):
            with m.If(quarter()):
                m.d.sync += [r.scl_low.eq(1), r.bits.eq(r.bits - 1)]
                with m.If(r.bits == 1):
                    m.next = "RX_PUSH"
                with m.Else():
                    m.next = "RX_BIT_HOLD"
        with m.State("RX_PUSH"):
            with m.If(self.rx_room):                  # else wait, SCL held low
                m.d.comb += [self.rx_push.eq(1), self.rx_byte.eq(r.shift), timer.restart.eq(1)]
                m.next = "ACK_OUT_HOLD"
        with m.State("ACK_OUT_HOLD"):
            with m.If(quarter()):
                m.d.sync += r.sda_low.eq(r.count != 1)
                m.next = "ACK_OUT_LOW"
        with m.State("ACK_OUT_LOW"):
            with m.If(quarter()):
                m.d.sync += r.scl_low.eq(0)
                m.next = "ACK_OUT_HIGH"
        with m.State("ACK_OUT_HIGH"):
            with m.If(quarter(wait_scl_high=True)):
                m.next = "ACK_OUT_HIGH2"
        with m.State("ACK_OUT_HIGH2"):
            with m.If(quarter()):
                m.d.sync += [r.scl_low.eq(1), r.count.eq(r.count - 1), r.bits.eq(8)]
                with m.If(r.count == 1):
                    m.next = "AFTER_BYTE"
                with m.Else():
                    m.next = "RX_BIT_HOLD"

    def _stop_states(self, m, r, quarter):
        """After a byte: STOP (SDA low with SCL low, SCL up, SDA up) or keep the bus; and
        the release after a lost arbitration."""
        with m.State("AFTER_BYTE"):
            with m.If(r.word[9] & ~r.need_count):
                m.next = "STOP_HOLD"
            with m.Else():
                m.d.sync += r.sda_low.eq(0)
                m.next = "IDLE"                       # bus kept: SCL stays low
        with m.State("STOP_HOLD"):
            with m.If(quarter()):
                m.d.sync += r.sda_low.eq(1)
                m.next = "STOP_LOW"
        with m.State("STOP_LOW"):
            with m.If(quarter()):
                m.d.sync += r.scl_low.eq(0)
                m.next = "STOP_SCL_HIGH"
        with m.State("STOP_SCL_HIGH"):
            with m.If(quarter(wait_scl_high=True)):
                m.d.sync += r.sda_low.eq(0)
                m.next = "STOP_BUS_FREE"
        with m.State("STOP_BUS_FREE"):
            with m.If(quarter()):
                m.d.sync += [r.active.eq(0), r.reading.eq(0), r.need_count.eq(0)]
                m.next = "STOP_BUS_FREE2"
        with m.State("STOP_BUS_FREE2"):                # bus free time before a new START
            with m.If(quarter()):
                m.next = "IDLE"
        with m.State("LOST"):
            m.d.comb += self.flush.eq(1)
            m.d.sync += [r.scl_low.eq(0), r.sda_low.eq(0), r.active.eq(0), r.reading.eq(0),
                         r.need_count.eq(0)]
            m.next = "IDLE"


class _Core(wiring.Component):
    """Everything SOFTR resets: registers, FIFOs, the bus monitor and engine."""

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
        tx = m.submodules.tx = ResetInserter(flush_tx)(SyncFIFOBuffered(width=10, depth=depth))
        rx = m.submodules.rx = SyncFIFOBuffered(width=8, depth=depth)
        m.submodules.monitor = monitor = IICBusMonitor()
        m.submodules.engine = engine = IICBusEngine(self._clk_div)

        cr = Signal(7)
        rfd = Signal(4)
        isr = Signal(5)
        with m.If(self.wr_cr):
            m.d.sync += cr.eq(self.wdata[:7])
        with m.If(self.wr_rfd):
            m.d.sync += rfd.eq(self.wdata[:4])

        m.d.comb += [
            # TX FIFO: firmware writes, the engine reads
            tx.w_data.eq(self.wdata[:10]), tx.w_en.eq(self.wr_tx),
            engine.tx_ready.eq(tx.r_rdy), engine.tx_word.eq(tx.r_data), tx.r_en.eq(engine.tx_take),
            # RX FIFO: the engine writes, firmware reads
            rx.w_en.eq(engine.rx_push), rx.w_data.eq(engine.rx_byte), engine.rx_room.eq(rx.w_rdy),
            rx.r_en.eq(self.rd_rx), self.rx_data.eq(Mux(rx.r_rdy, rx.r_data, 0)),
            # lines
            monitor.scl_i.eq(self.scl_i), monitor.sda_i.eq(self.sda_i),
            engine.scl.eq(monitor.scl), engine.sda.eq(monitor.sda),
            self.scl_oe.eq(engine.scl_oe), self.sda_oe.eq(engine.sda_oe),
            engine.enabled.eq(cr[0]),
            flush_tx.eq(cr[1] | engine.flush),
        ]

        bus_busy = Signal()
        m.d.comb += bus_busy.eq(monitor.busy | engine.ours)
        isr_set = Cat(engine.lost, engine.nack, ~tx.r_rdy, rx.level == rfd + 1, ~bus_busy)
        toggle = Mux(self.wr_isr, self.wdata[:5], 0)
        m.d.sync += isr.eq((isr ^ toggle) | isr_set)

        m.d.comb += [
            self.isr.eq(isr),
            self.cr.eq(cr),
            self.rfd.eq(rfd),
            self.sr.eq(Cat(Const(0, 2), bus_busy, engine.reading, tx.level == depth,
                           rx.level == depth, ~rx.r_rdy, tx.level == 0)),
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
        Register access; ``ready`` two cycles after the strobe, never stalls.
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
        do_write = window.write & (window.byte_enable == 0xF)

        soft_reset = Signal()
        m.d.sync += soft_reset.eq(do_write & (offset == XIIC.RESETR_OFFSET)
                                  & (window.write_data == XIIC.RESET_MASK))
        core = m.submodules.core = ResetInserter(soft_reset)(_Core(self._clk_div))

        m.d.comb += [
            core.wdata.eq(window.write_data),
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
