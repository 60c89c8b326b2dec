"""UART for the radio (XBee, 8N1) on the MicroBlaze I/O bus.

Registers (window of 0x10 bytes at ``base``; :data:`UART_REGS`), latency 1 cycle, never stalls:

=======  ======  ==========================================================================
offset   name    meaning
=======  ======  ==========================================================================
0x0      DATA    write: send byte [7:0] (ignored while STATUS.tx_ready = 0); read: the
                 received byte [7:0] and bit 8 = 1, or 0 when nothing was received; a read
                 takes the byte
0x4      STATUS  bit 0 tx_ready (a byte may be written), bit 1 rx_valid, bit 2 tx_busy
                 (a byte is being shifted out), bit 3 rx_overrun (a byte arrived while one
                 was waiting; cleared by reading DATA)
=======  ======  ==========================================================================

Frame: 1 start bit (0), 8 data bits LSB first, 1 stop bit (1); ``divisor`` core cycles per bit
(50 MHz / 115200 baud: 434). The receiver synchronises ``rx`` with two flip-flops, waits half a
bit after the falling edge and samples each bit in its middle; a missing stop bit drops the
byte.
"""
from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.cdc import FFSynchronizer
from amaranth.lib.wiring import In, Out

from .regs import IOBusSignature

__all__ = ["UART", "UART_REGS"]

UART_REGS = {"DATA": 0x0, "STATUS": 0x4}
UART_WINDOW = 0x10


class UART(wiring.Component):
    """8N1 UART with a one-byte buffer each way.

    Parameters (keyword-only): ``divisor`` (core cycles per bit, >= 4), ``base`` (bus address,
    aligned to 0x10).

    Ports: ``bus`` In(IOBusSignature) (answers in its window, latency 1); ``tx`` Out(1) (idle
    high); ``rx`` In(1) (idle high, asynchronous).
    """

    def __init__(self, *, divisor=434, base=0xC002_0000):
        if not isinstance(divisor, int) or divisor < 4:
            self._MustUse__silence = True
            raise ValueError(f"divisor must be an integer >= 4, not {divisor!r}")
        if not isinstance(base, int) or base % UART_WINDOW:
            self._MustUse__silence = True
            raise ValueError(f"base must be aligned to 0x{UART_WINDOW:X}, not {base!r}")
        self._divisor = divisor
        self._base = base
        super().__init__({"bus": In(IOBusSignature()), "tx": Out(1, init=1), "rx": In(1, init=1)})

    def elaborate(self, platform):
        m = Module()
        bus = self.bus
        bits = (UART_WINDOW - 1).bit_length()
        hit = bus.addr_strobe & (bus.address[bits:] == self._base >> bits)
        offset = bus.address[:bits] & ~0b11
        div = self._divisor

        # transmitter
        tx_hold = Signal(8)
        tx_full = Signal()
        tx_shift = Signal(10)
        tx_count = Signal(range(11))
        tx_timer = Signal(range(div))
        tx_busy = tx_count != 0
        with m.If(tx_busy):
            with m.If(tx_timer == div - 1):
                m.d.sync += [tx_timer.eq(0), tx_count.eq(tx_count - 1),
                             tx_shift.eq(Cat(tx_shift[1:], 1)), self.tx.eq(tx_shift[1])]
            with m.Else():
                m.d.sync += tx_timer.eq(tx_timer + 1)
        with m.Elif(tx_full):
            m.d.sync += [tx_shift.eq(Cat(0, tx_hold, 1)), tx_count.eq(10), tx_timer.eq(0),
                         self.tx.eq(0), tx_full.eq(0)]

        # receiver
        rx = Signal(init=1)
        m.submodules.rx_sync = FFSynchronizer(self.rx, rx, init=1)
        rx_hold = Signal(8)
        rx_valid = Signal()
        rx_overrun = Signal()
        rx_shift = Signal(9)
        rx_count = Signal(range(11))
        rx_timer = Signal(range(div))
        # bus
        m.d.sync += [bus.ready.eq(hit & (bus.read_strobe | bus.write_strobe)), bus.read_data.eq(0)]
        with m.If(hit & bus.write_strobe & (offset == UART_REGS["DATA"]) & ~tx_full):
            m.d.sync += [tx_hold.eq(bus.write_data[:8]), tx_full.eq(1)]
        with m.If(hit & bus.read_strobe):
            with m.If(offset == UART_REGS["DATA"]):
                m.d.sync += bus.read_data.eq(Mux(rx_valid, Cat(rx_hold, 1), 0))
                m.d.sync += [rx_valid.eq(0), rx_overrun.eq(0)]
            with m.Elif(offset == UART_REGS["STATUS"]):
                m.d.sync += bus.read_data.eq(Cat(~tx_full, rx_valid, tx_busy | tx_full, rx_overrun))
        # receiver (after the bus: a byte completing during a DATA read is kept)
        with m.If(rx_count == 0):
            with m.If(~rx):
                m.d.sync += [rx_count.eq(10), rx_timer.eq(div // 2)]
        with m.Elif(rx_timer == div - 1):
            m.d.sync += [rx_timer.eq(0), rx_count.eq(rx_count - 1), rx_shift.eq(Cat(rx_shift[1:], rx))]
            with m.If(rx_count == 10):                # middle of the start bit
                with m.If(rx):
                    m.d.sync += rx_count.eq(0)        # a glitch, not a start bit
            with m.If(rx_count == 1):                 # middle of the stop bit
                with m.If(rx):
                    m.d.sync += [rx_hold.eq(rx_shift[1:]), rx_valid.eq(1),
                                 rx_overrun.eq(rx_overrun | rx_valid)]
        with m.Else():
            m.d.sync += rx_timer.eq(rx_timer + 1)

        return m
