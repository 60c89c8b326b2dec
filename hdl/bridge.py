"""UART register bridge: a host computer in the soft CPU's place on the I/O bus (protocol and
framing rules: ``golden/bridge.py``)."""
from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from golden.bridge import (BUS_TIMEOUT, CMD_READ, CMD_WRITE, GAP_CYCLES, ST_CHECKSUM, ST_OK,
                           ST_TIMEOUT, SYNC_REQ, SYNC_RESP)
from .regs import IOBusSignature
from .uart import UartRx, UartTx, check_divisor

__all__ = ["UartBridge"]


class UartBridge(wiring.Component):
    """Requests in on ``rx``, one I/O bus transfer each on ``bus``, responses out on ``tx``.

    Parameters (keyword-only): ``divisor`` (core cycles per bit).

    Ports: ``rx`` In(1), ``tx`` Out(1) (8N1 lines); ``bus`` Out(IOBusSignature) (the initiator's
    side: connect it to the SoC's bus port); ``requests``, ``errors`` Out(16) (transfers done,
    requests dropped for a bad checksum, wrapping).
    """

    def __init__(self, *, divisor=434):
        check_divisor(self, divisor)
        self._divisor = divisor
        super().__init__({"rx": In(1, init=1), "tx": Out(1, init=1), "bus": Out(IOBusSignature()),
                          "requests": Out(16), "errors": Out(16)})

    def elaborate(self, platform):
        m = Module()
        m.submodules.rx = rx = UartRx(divisor=self._divisor)
        m.submodules.tx = tx = UartTx(divisor=self._divisor)
        m.d.comb += [rx.rx.eq(self.rx), self.tx.eq(tx.tx)]
        byte = rx.o.payload
        got = rx.o.valid

        write = Signal()
        addr = Signal(32)
        data = Signal(32)
        total = Signal(8)           # byte sum from CMD on
        count = Signal(3)
        gap = Signal(range(GAP_CYCLES + 1))
        wait = Signal(range(BUS_TIMEOUT + 1))
        status = Signal(8)
        resp = Signal(48)           # ST D3 D2 D1 D0 CK, sent from the top byte
        bus = self.bus

        with m.FSM():
            with m.State("SYNC"):
                with m.If(got & (byte == SYNC_REQ)):
                    m.d.sync += [total.eq(0), count.eq(0), gap.eq(0)]
                    m.next = "CMD"
            # inside a request: a gap drops it
            with m.State("CMD"):
                with m.If(got):
                    m.d.sync += [total.eq(byte), write.eq(byte == CMD_WRITE), gap.eq(0)]
                    with m.If((byte == CMD_READ) | (byte == CMD_WRITE)):
                        m.next = "ADDR"
                    with m.Else():
                        m.next = "SYNC"
                with m.Elif(gap == GAP_CYCLES):
                    m.next = "SYNC"
                with m.Else():
                    m.d.sync += gap.eq(gap + 1)
            for state, reg, after in (("ADDR", addr, "ADDR_NEXT"), ("DATA", data, "CK")):
                with m.State(state):
                    with m.If(got):
                        m.d.sync += [reg.eq((reg << 8) | byte), total.eq(total + byte),
                                     count.eq(count + 1), gap.eq(0)]
                        with m.If(count == 3):
                            m.d.sync += count.eq(0)
                            m.next = after
                    with m.Elif(gap == GAP_CYCLES):
                        m.next = "SYNC"
                    with m.Else():
                        m.d.sync += gap.eq(gap + 1)
            with m.State("ADDR_NEXT"):
                with m.If(write):
                    m.next = "DATA"
                with m.Else():
                    m.d.sync += data.eq(0)
                    m.next = "CK"
            with m.State("CK"):
                with m.If(got):
                    m.d.sync += gap.eq(0)
                    with m.If(((total + byte) & 0xFF) == 0):
                        m.next = "STROBE"
                    with m.Else():
                        m.d.sync += [status.eq(ST_CHECKSUM), data.eq(0),
                                     self.errors.eq(self.errors + 1)]
                        m.next = "RESPOND"
                with m.Elif(gap == GAP_CYCLES):
                    m.next = "SYNC"
                with m.Else():
                    m.d.sync += gap.eq(gap + 1)
            with m.State("STROBE"):
                m.d.comb += [bus.addr_strobe.eq(1), bus.address.eq(addr),
                             bus.read_strobe.eq(~write), bus.write_strobe.eq(write),
                             bus.write_data.eq(data), bus.byte_enable.eq(0xF)]
                m.d.sync += wait.eq(0)
                m.next = "WAIT"
            with m.State("WAIT"):
                with m.If(bus.ready):
                    m.d.sync += [status.eq(ST_OK), data.eq(Mux(write, 0, bus.read_data)),
                                 self.requests.eq(self.requests + 1)]
                    m.next = "RESPOND"
                with m.Elif(wait == BUS_TIMEOUT):
                    m.d.sync += [status.eq(ST_TIMEOUT), data.eq(0)]
                    m.next = "RESPOND"
                with m.Else():
                    m.d.sync += wait.eq(wait + 1)
            with m.State("RESPOND"):
                ck = -(status + data[24:32] + data[16:24] + data[8:16] + data[0:8])
                m.d.sync += [resp.eq((status << 40) | (data << 8) | ck[:8]), count.eq(0)]
                m.next = "SEND_SYNC"
            with m.State("SEND_SYNC"):
                m.d.comb += [tx.i.valid.eq(1), tx.i.payload.eq(SYNC_RESP)]
                with m.If(tx.i.ready):
                    m.next = "SEND"
            with m.State("SEND"):
                m.d.comb += [tx.i.valid.eq(1), tx.i.payload.eq(resp[40:48])]
                with m.If(tx.i.ready):
                    m.d.sync += [resp.eq(resp << 8), count.eq(count + 1)]
                    with m.If(count == 5):
                        m.next = "SYNC"
        return m
