"""Host side of the UART register bridge (protocol: ``golden/bridge.py``): the firmware's host
build drives a board through its HAL bus hook, exactly as in the co-simulation.

    python -m sim.system.bridge_host /dev/ttyUSB0 [--baud 115200]   # ID check and health of a board

:class:`BridgeHost` turns 32-bit reads and writes into bridge requests over a *transport*
(anything with ``write(bytes)`` and ``read(n) -> bytes``: a serial port from :func:`open_serial`,
or a simulated line in the tests); :meth:`BridgeHost.install` points the firmware's HAL at it
(``hal_set_bus_hook``), so every ``Xil_In32``/``Xil_Out32`` of the firmware becomes one request.
"""
from __future__ import annotations

import argparse
import ctypes as C
import os
import sys
import time

from golden.bridge import ST_OK, decode_response, encode_request

__all__ = ["BridgeError", "BridgeHost", "open_serial", "main"]


class BridgeError(RuntimeError):
    pass


class BridgeHost:
    def __init__(self, transport, *, retries=2):
        self.transport = transport
        self.retries = retries
        self.transfers = 0
        self._hooks = None

    def _transfer(self, write, addr, value=0):
        for _ in range(self.retries + 1):
            self.transport.write(encode_request(write, addr, value))
            frame = self.transport.read(7)
            try:
                status, data = decode_response(frame)
            except ValueError:
                continue                    # a damaged answer: ask again
            if status == ST_OK:
                self.transfers += 1
                return data
            if status != 0x01:              # bus time-out: no device there
                raise BridgeError(f"bus time-out at 0x{addr:08X}")
        raise BridgeError(f"no valid answer for 0x{addr:08X} after {self.retries + 1} tries")

    def read32(self, addr):
        return self._transfer(False, addr)

    def write32(self, addr, value):
        self._transfer(True, addr, value)

    def install(self, lib):
        """Point the firmware library's HAL bus hook at this bridge; returns the hooks (keep
        them alive while the firmware runs)."""
        from sim.system.cosim import fwlib
        rd = fwlib.READ32(lambda _ctx, a: self.read32(a))
        wr = fwlib.WRITE32(lambda _ctx, a, v: self.write32(a, v))
        dl = fwlib.DELAY(lambda _ctx, us: time.sleep(us / 1e6))
        self._hooks = (rd, wr, dl, fwlib.UART())
        lib.hal_set_bus_hook(*self._hooks, None)
        return self._hooks


class _Serial:
    """A raw 8N1 serial port (termios), blocking reads with a time-out."""

    def __init__(self, path, baud, timeout=0.5):
        import termios
        import tty
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd)
        attrs = termios.tcgetattr(self.fd)
        speed = getattr(termios, f"B{baud}")
        attrs[4] = attrs[5] = speed
        termios.tcsetattr(self.fd, termios.TCSANOW, attrs)
        self.timeout = timeout

    def write(self, data):
        os.write(self.fd, data)

    def read(self, n):
        import select
        out = b""
        end = time.monotonic() + self.timeout
        while len(out) < n and time.monotonic() < end:
            r, _, _ = select.select([self.fd], [], [], max(0.0, end - time.monotonic()))
            if r:
                out += os.read(self.fd, n - len(out))
        return out


def open_serial(path, baud=115200):
    return _Serial(path, baud)


def main(argv=None):
    from hdl import regmap
    from sim.system.cosim import fwlib
    ap = argparse.ArgumentParser(prog="python -m sim.system.bridge_host", description=__doc__.split("\n")[0])
    ap.add_argument("port")
    ap.add_argument("--baud", type=int, default=115200)
    args = ap.parse_args(argv)
    try:
        host = BridgeHost(open_serial(args.port, args.baud))
        lib = fwlib.load()
        host.install(lib)
        app = fwlib.AppC()
        st = lib.app_init_pipeline(C.byref(app), regmap.REGS_BASEADDR)
        print(f"app_init_pipeline: {fwlib.STATUS_NAMES.get(st, st)} ({host.transfers} transfers)")
    except (OSError, BridgeError, AttributeError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0 if st == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
