"""UART (8N1) for the radio on the MicroBlaze I/O bus, and the byte-level transmitter and
receiver it is made of (also used by the UART register bridge, ``hdl/bridge.py``).

Registers of :class:`UART` (window of 0x10 bytes at ``base``; :data:`UART_REGS`), latency 2
cycles, never stalls:

=======  ======  ==========================================================================
offset   name    meaning
=======  ======  ==========================================================================
0x0      DATA    write: send byte [7:0] (ignored while STATUS.tx_ready = 0); read: the
                 received byte [7:0] and bit 8 = 1, or 0 when nothing was received; a read
                 takes the byte
0x4      STATUS  bit 0 tx_ready (a byte may be written), bit 1 rx_valid, bit 2 tx_busy
                 (a byte is being shifted out), bit 3 rx_overrun (a byte arrived while one
                 was waiting; cleared by reading DATA)
0x8      BAUD    [15:0] core cycles per bit (>= 4; reset: the ``divisor`` parameter); the
                 firmware sets 5208 for the XBee's factory 9600 baud, 434 for 115200 at
                 50 MHz. Takes effect with the next byte; write it while STATUS.tx_busy = 0.
=======  ======  ==========================================================================

Frame: 1 start bit (0), 8 data bits LSB first, 1 stop bit (1); ``divisor`` core cycles per bit
(50 MHz / 115200 baud: 434; the transmitter and receiver take it as a port, so the UART can
change it at run time and the bridge leaves it constant). The receiver synchronises ``rx`` with two flip-flops, waits half a
bit after the falling edge and samples each bit in its middle; a missing stop bit drops the
byte.
"""
from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.cdc import FFSynchronizer
from amaranth.lib.wiring import In, Out

from .regs import BusWindow, IOBusSignature, check_window_base

__all__ = ["UART", "UART_REGS", "DIVISOR_BITS", "UartTx", "UartRx", "check_divisor"]

UART_REGS = {"DATA": 0x0, "STATUS": 0x4, "BAUD": 0x8}
#: Width of the run-time bit period (core cycles per bit): 9600 baud at 50 MHz is 5208.
DIVISOR_BITS = 16
UART_WINDOW = 0x10


def check_divisor(unit, divisor):
    if not isinstance(divisor, int) or divisor < 4:
        unit._MustUse__silence = True
        raise ValueError(f"divisor must be an integer >= 4, not {divisor!r}")


class UartTx(wiring.Component):
    """8N1 transmitter. ``i``: bytes (ready while idle; a byte is sent in 10 bit times);
    ``tx``: the line (idle high); ``busy``: a byte is being sent; ``divisor``: core cycles per
    bit (init: the parameter; change it only while idle)."""

    def __init__(self, *, divisor):
        check_divisor(self, divisor)
        self._divisor = divisor
        super().__init__({"i": In(stream.Signature(8)), "tx": Out(1, init=1), "busy": Out(1),
                          "divisor": In(DIVISOR_BITS, init=divisor)})

    def elaborate(self, platform):
        m = Module()
        shift = Signal(10)
        count = Signal(range(11))
        timer = Signal(DIVISOR_BITS)
        # divisor - 1, registered: no subtractor on the path
        last = Signal(DIVISOR_BITS, init=self._divisor - 1)
        m.d.sync += last.eq(self.divisor - 1)
        m.d.comb += [self.busy.eq(count != 0), self.i.ready.eq(count == 0)]
        with m.If(count != 0):
            with m.If(timer >= last):
                m.d.sync += [timer.eq(0), count.eq(count - 1), shift.eq(Cat(shift[1:], 1)),
                             self.tx.eq(shift[1])]
            with m.Else():
                m.d.sync += timer.eq(timer + 1)
        with m.Elif(self.i.valid):
            m.d.sync += [shift.eq(Cat(0, self.i.payload, 1)), count.eq(10), timer.eq(0),
                         self.tx.eq(0)]
        return m


class UartRx(wiring.Component):
    """8N1 receiver. ``rx``: the line (asynchronous, idle high); ``o``: received bytes, one-cycle
    ``valid`` pulses (no backpressure: the consumer must take them); ``divisor``: core cycles
    per bit (init: the parameter)."""

    def __init__(self, *, divisor):
        check_divisor(self, divisor)
        self._divisor = divisor
        super().__init__({"rx": In(1, init=1), "o": Out(stream.Signature(8)),
                          "divisor": In(DIVISOR_BITS, init=divisor)})

    def elaborate(self, platform):
        m = Module()
        rx = Signal(init=1)
        m.submodules.sync = FFSynchronizer(self.rx, rx, init=1)
        shift = Signal(9)
        count = Signal(range(11))
        timer = Signal(DIVISOR_BITS)
        last = Signal(DIVISOR_BITS, init=self._divisor - 1)     # divisor - 1, registered
        m.d.sync += last.eq(self.divisor - 1)
        m.d.sync += self.o.valid.eq(0)
        with m.If(count == 0):
            with m.If(~rx):
                m.d.sync += [count.eq(10), timer.eq(self.divisor[1:])]
        with m.Elif(timer >= last):
            m.d.sync += [timer.eq(0), count.eq(count - 1), shift.eq(Cat(shift[1:], rx))]
            with m.If((count == 10) & rx):              # a glitch, not a start bit
                m.d.sync += count.eq(0)
            with m.If((count == 1) & rx):               # the stop bit
                m.d.sync += [self.o.payload.eq(shift[1:]), self.o.valid.eq(1)]
        with m.Else():
            m.d.sync += timer.eq(timer + 1)
        return m


class UART(wiring.Component):
    """8N1 UART with a one-byte buffer each way, on the I/O bus.

    Parameters (keyword-only): ``divisor`` (core cycles per bit at reset, >= 4; BAUD changes it),
    ``base`` (bus address, aligned to 0x10).

    Ports: ``bus`` In(IOBusSignature) (answers in its window, latency 2); ``tx`` Out(1) (idle
    high); ``rx`` In(1) (idle high, asynchronous).
    """

    def __init__(self, *, divisor=434, base=0xC002_0000):
        check_divisor(self, divisor)
        check_window_base(self, base, UART_WINDOW)
        self._divisor = divisor
        self._base = base
        super().__init__({"bus": In(IOBusSignature()), "tx": Out(1, init=1), "rx": In(1, init=1)})

    def elaborate(self, platform):
        m = Module()
        bus = self.bus
        window = BusWindow(m, bus, self._base, UART_WINDOW)
        offset = window.offset
        m.submodules.tx = tx = UartTx(divisor=self._divisor)
        m.submodules.rx = rx = UartRx(divisor=self._divisor)
        baud = Signal(DIVISOR_BITS, init=self._divisor)
        m.d.comb += [self.tx.eq(tx.tx), rx.rx.eq(self.rx), tx.divisor.eq(baud),
                     rx.divisor.eq(baud)]
        with m.If(window.write & (offset == UART_REGS["BAUD"]) & (window.write_data[:DIVISOR_BITS] >= 4)):
            m.d.sync += baud.eq(window.write_data[:DIVISOR_BITS])

        tx_hold = Signal(8)
        tx_full = Signal()
        m.d.comb += [tx.i.valid.eq(tx_full), tx.i.payload.eq(tx_hold)]
        with m.If(tx.i.ready & tx_full):
            m.d.sync += tx_full.eq(0)

        rx_hold = Signal(8)
        rx_valid = Signal()
        rx_overrun = Signal()

        value = Signal(32)
        with m.If(offset == UART_REGS["DATA"]):
            m.d.comb += value.eq(Mux(rx_valid, Cat(rx_hold, 1), 0))
        with m.Elif(offset == UART_REGS["STATUS"]):
            m.d.comb += value.eq(Cat(~tx_full, rx_valid, tx.busy | tx_full, rx_overrun))
        with m.Elif(offset == UART_REGS["BAUD"]):
            m.d.comb += value.eq(baud)
        window.answer(value)
        with m.If(window.write & (offset == UART_REGS["DATA"]) & ~tx_full):
            m.d.sync += [tx_hold.eq(window.write_data[:8]), tx_full.eq(1)]
        with m.If(window.read & (offset == UART_REGS["DATA"])):
            m.d.sync += [rx_valid.eq(0), rx_overrun.eq(0)]
        # after the bus: a byte completing during a DATA read is kept
        with m.If(rx.o.valid):
            m.d.sync += [rx_hold.eq(rx.o.payload), rx_valid.eq(1),
                         rx_overrun.eq(rx_overrun | rx_valid)]
        return m
