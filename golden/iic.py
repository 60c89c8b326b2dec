"""Transaction-level model and checker of an I2C bus (NXP UM10204).

Everything here works on the two wired-AND lines sampled once per clock cycle, so it can be
attached to any simulation of ``hdl/iic.py`` (Amaranth's simulator, cocotb...):

- :class:`I2CMonitor` decodes the SCL/SDA waveform into :class:`Transaction` objects (START,
  address + R/W + ACK, data bytes + ACK, repeated START, STOP) and records protocol
  violations (SDA changing while SCL is high outside START/STOP) and SCL timing;
- :class:`I2CDevice` is a target with a 256-byte register file (first written byte = register
  pointer, auto-increment), able to NACK, to stretch the clock for a while after each byte,
  or to hold SCL low for good;
- :class:`ADV7180Model` adds the ADV7180's identity, reset values and soft reset (PWR_MAN bit
  7: registers back to reset values, no acknowledge for ``busy_after_reset`` addressings);
- :class:`WiredBus` resolves the lines from every driver;
- :func:`expected_write_reg8` / :func:`expected_read_reg8` give the transaction the firmware's
  ``iic_write_reg8`` / ``iic_read_reg8`` must produce.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["Transaction", "I2CMonitor", "I2CDevice", "ADV7180Model", "WiredBus",
           "expected_write_reg8", "expected_read_reg8"]


@dataclass
class Transaction:
    """One START ... STOP exchange. ``segments`` holds one entry per (repeated) START:
    (addr7, is_read, addr_acked, [(byte, acked), ...])."""
    segments: list = field(default_factory=list)
    stopped: bool = False

    def simple(self):
        """A comparable form: tuple of (addr7, 'R'/'W', ack, ((byte, ack), ...))."""
        return tuple((a, "R" if r else "W", ack, tuple(d)) for a, r, ack, d in self.segments)


def expected_write_reg8(addr7, reg, val):
    return ((addr7, "W", True, ((reg, True), (val, True))),)


def expected_read_reg8(addr7, reg, val):
    # the master NACKs the last byte it reads
    return ((addr7, "W", True, ((reg, True),)), (addr7, "R", True, ((val, False),)))


class I2CMonitor:
    """Decode a sampled SCL/SDA waveform. Call :meth:`step` once per clock cycle."""

    def __init__(self):
        self.transactions: list[Transaction] = []
        self.errors: list[str] = []
        self.cycle = 0
        self._scl = 1
        self._sda = 1
        self._cur: Transaction | None = None
        self._bits = []
        self._seg = None
        self._rise_cycles = []
        self._high_start = None
        self.min_high = math.inf   #: shortest SCL high time seen, cycles
        self.min_low = math.inf    #: shortest SCL low time seen (inside a transaction), cycles
        self._low_start = None

    @property
    def busy(self):
        return self._cur is not None

    def step(self, scl: int, sda: int):
        self.cycle += 1
        if scl and self._scl:
            if self._sda and not sda:
                self._start()
            elif not self._sda and sda:
                self._stop()
        elif scl and not self._scl:                  # rising edge: sample
            self._rise_cycles.append(self.cycle)
            self._high_start = self.cycle
            if self._low_start is not None and self._cur is not None:
                self.min_low = min(self.min_low, self.cycle - self._low_start)
            if self._cur is not None:
                self._bit(sda)
        elif not scl and self._scl:                  # falling edge
            self._low_start = self.cycle
            if self._high_start is not None and self._cur is not None:
                self.min_high = min(self.min_high, self.cycle - self._high_start)
        self._scl, self._sda = scl, sda

    def scl_period(self):
        """Median cycles between SCL rising edges inside bytes (None if too few edges)."""
        d = sorted(b - a for a, b in zip(self._rise_cycles, self._rise_cycles[1:]))
        return d[len(d) // 2] if d else None

    def _start(self):
        if self._cur is None:
            self._cur = Transaction()
        self._bits = []
        self._seg = None

    def _stop(self):
        if self._cur is None:
            self.errors.append(f"cycle {self.cycle}: STOP without START")
            return
        # the SCL rise of the STOP condition itself was sampled as one bit
        if len(self._bits) > 1:
            self.errors.append(f"cycle {self.cycle}: STOP after {len(self._bits) - 1} bits of a byte")
        self._cur.stopped = True
        self.transactions.append(self._cur)
        self._cur = None
        self._seg = None
        self._bits = []

    def _bit(self, sda):
        self._bits.append(sda)
        if len(self._bits) < 9:
            return
        byte = 0
        for b in self._bits[:8]:
            byte = byte << 1 | b
        ack = self._bits[8] == 0
        self._bits = []
        if self._seg is None:
            self._seg = [byte >> 1, bool(byte & 1), ack, []]
            self._cur.segments.append(self._seg)
        else:
            self._seg[3].append((byte, ack))


class I2CDevice:
    """An I2C target with a register file.

    ``nack``: never acknowledge its address. ``stretch``: cycles to hold SCL low after each
    byte's acknowledge (0: none; ``math.inf``: hold it for good, a stuck device).
    Call :meth:`step` once per cycle with the resolved lines; it returns the lines it pulls
    low as (scl_low, sda_low), applied from the next cycle.
    """

    def __init__(self, addr7: int, *, regs=None, nack=False, stretch=0):
        self.addr7 = addr7
        self.regs = bytearray(256) if regs is None else bytearray(regs)
        self.written = {}            #: register -> last value written since reset
        self.write_log = []          #: (register, value) in order
        self.nack = nack
        self.stretch = stretch
        self.ptr = 0
        self._state = "IDLE"
        self._scl = 1
        self._sda = 1
        self._bits = 0
        self._shift = 0
        self._first = False
        self._reading = False
        self._sda_low = 0
        self._scl_low = 0
        self._hold = 0
        self.addressed = 0           #: times our address was seen

    # hooks for subclasses
    def ack_address(self) -> bool:
        return not self.nack

    def on_write(self, reg: int, val: int):
        self.regs[reg] = val
        self.written[reg] = val
        self.write_log.append((reg, val))

    def on_read(self, reg: int) -> int:
        return self.regs[reg]

    def step(self, scl: int, sda: int):
        rise = scl and not self._scl
        fall = not scl and self._scl
        if scl and self._scl and self._sda != sda:
            if not sda:                               # START / repeated START
                self._state, self._bits, self._shift = "ADDR", 0, 0
                self._sda_low = 0
            else:                                     # STOP
                self._state = "IDLE"
                self._sda_low = 0
        elif rise:
            if self._state in ("ADDR", "WRITE"):
                self._shift = (self._shift << 1 | sda) & 0xFF
                self._bits += 1
            elif self._state == "READ_ACK":
                self._master_nacked = bool(sda)
        elif fall:
            self._on_fall()
        if self._hold > 0:
            self._hold -= 1
            if self._hold == 0:
                self._scl_low = 0
        self._scl, self._sda = scl, sda
        return self._scl_low, self._sda_low

    def _stretch(self):
        if self.stretch:
            self._scl_low = 1
            self._hold = self.stretch if self.stretch != math.inf else -1

    def _on_fall(self):
        st = self._state
        if st in ("ADDR", "WRITE") and self._bits == 8:
            if st == "ADDR":
                if self._shift >> 1 == self.addr7:
                    self.addressed += 1
                    if self.ack_address():
                        self._sda_low = 1
                        self._reading = bool(self._shift & 1)
                        self._first = not self._reading
                        self._state = "ACK"
                    else:
                        self._state = "IGNORE"
                else:
                    self._state = "IGNORE"
            else:
                if self._first:
                    self.ptr = self._shift
                    self._first = False
                else:
                    self.on_write(self.ptr, self._shift)
                    self.ptr = (self.ptr + 1) & 0xFF
                self._sda_low = 1
                self._state = "ACK"
        elif st == "ACK":                             # end of our ACK bit
            self._sda_low = 0
            self._stretch()
            if self._reading:
                self._load_read_byte()
            else:
                self._state, self._bits, self._shift = "WRITE", 0, 0
        elif st == "READ":
            self._bits += 1
            if self._bits == 8:
                self._sda_low = 0                     # release for the master's ACK
                self._state = "READ_ACK"
            else:
                self._sda_low = 0 if (self._out << self._bits) & 0x80 else 1
        elif st == "READ_ACK":
            if getattr(self, "_master_nacked", True):
                self._state = "IGNORE"                # wait for STOP / repeated START
            else:
                self._stretch()
                self._load_read_byte()

    def _load_read_byte(self):
        self._out = self.on_read(self.ptr)
        self.ptr = (self.ptr + 1) & 0xFF
        self._bits = 0
        self._state = "READ"
        self._sda_low = 0 if self._out & 0x80 else 1


class ADV7180Model(I2CDevice):
    """ADV7180 register behaviour the firmware relies on (datasheet / Linux adv7180.c)."""

    IDENT = 0x11
    PWR_MAN = 0x0F
    RESET_VALUES = {0x03: 0x0C, 0x07: 0x7F, 0x10: 0x05, 0x11: 0x18}

    def __init__(self, addr7: int, *, busy_after_reset=2, ident=0x18, **kw):
        super().__init__(addr7, **kw)
        self.busy_after_reset = busy_after_reset
        self.ident = ident
        self.busy = 0
        self.resets = 0
        self._defaults()

    def _defaults(self):
        self.regs[:] = bytes(256)
        for r, v in self.RESET_VALUES.items():
            self.regs[r] = v
        self.regs[self.IDENT] = self.ident
        self.written = {}

    def ack_address(self):
        if self.busy > 0:
            self.busy -= 1
            return False
        return super().ack_address()

    def on_write(self, reg, val):
        if reg == self.PWR_MAN and val & 0x80:
            self.resets += 1
            self._defaults()
            self.busy = self.busy_after_reset
            self.write_log.append((reg, val))
            return
        super().on_write(reg, val)


class WiredBus:
    """Resolve SCL/SDA from the master's output enables and the devices' pull-downs."""

    def __init__(self, devices=(), monitor=None):
        self.devices = list(devices)
        self.monitor = monitor
        self._dev_scl = 0
        self._dev_sda = 0

    def step(self, master_scl_oe: int, master_sda_oe: int):
        """One cycle: returns the (scl, sda) levels the master sees this cycle."""
        scl = 0 if (master_scl_oe or self._dev_scl) else 1
        sda = 0 if (master_sda_oe or self._dev_sda) else 1
        if self.monitor is not None:
            self.monitor.step(scl, sda)
        dscl = dsda = 0
        for d in self.devices:
            a, b = d.step(scl, sda)
            dscl |= a
            dsda |= b
        self._dev_scl, self._dev_sda = dscl, dsda
        return scl, sda
