"""UART register bridge (hdl/bridge.py) against its protocol (golden/bridge.py): requests sent
as 8N1 bytes reach the register block over the I/O bus; bad checksums, unknown commands, gaps
and addresses nobody answers are handled as specified."""
from amaranth.hdl import Module
from amaranth.lib import wiring
from amaranth.sim import Simulator

from golden.bridge import (ST_CHECKSUM, ST_OK, ST_TIMEOUT, decode_response, encode_request)
from hdl import regmap
from hdl.bridge import UartBridge
from hdl.regs import RegisterBlock

DIV = 4
BASE = regmap.REGS_BASEADDR


def bridge_and_registers():
    """The UART bridge driving a register block's bus, and their simulator."""
    bridge = UartBridge(divisor=DIV)
    regs = RegisterBlock(fifo_depth=4)
    m = Module()
    m.submodules.bridge = bridge
    m.submodules.regs = regs
    wiring.connect(m, bridge.bus, regs.bus)
    sim = Simulator(m)
    sim.add_clock(1e-8)
    return bridge, regs, sim


def run(chunks):
    """Send each chunk of bytes (None: a gap longer than the bridge's limit); collect the
    response frames."""
    bridge, regs, sim = bridge_and_registers()
    line = []
    state = {}

    async def host(ctx):
        for chunk in chunks:
            if chunk is None:
                await ctx.tick().repeat(70000)
                continue
            for b in chunk:
                for bit in [0] + [(b >> k) & 1 for k in range(8)] + [1]:
                    ctx.set(bridge.rx, bit)
                    await ctx.tick().repeat(DIV)
            await ctx.tick().repeat(20 * DIV * 10)      # time for a response
        state["done"] = True
        state["requests"] = ctx.get(bridge.requests)
        state["errors"] = ctx.get(bridge.errors)

    async def probe(ctx):
        async for _c, _r, tx in ctx.tick().sample(bridge.tx):
            line.append(tx)

    sim.add_testbench(host)
    sim.add_testbench(probe, background=True)
    sim.run()
    # decode the 8N1 line
    out, i = [], 0
    while i < len(line):
        if line[i] == 0:
            bits = [line[i + DIV // 2 + k * DIV] for k in range(1, 9)]
            out.append(sum(b << k for k, b in enumerate(bits)))
            i += 10 * DIV - DIV // 2
        else:
            i += 1
    frames = [bytes(out[k:k + 7]) for k in range(0, len(out), 7)]
    return [decode_response(f) for f in frames], state


def test_read_write_and_errors():
    match = BASE + regmap.register("MATCH").offset
    ident = BASE + regmap.register("ID").offset
    bad = bytearray(encode_request(True, match, 0x1234))
    bad[-1] ^= 1
    answers, st = run([
        b"\x00\x13",                                  # noise before a request: ignored
        encode_request(False, ident),
        encode_request(True, match, 0x00150F00),
        encode_request(False, match),
        bytes(bad),                                   # checksum error, nothing written
        encode_request(False, match),
        b"\x5A\x41",                                  # unknown command: dropped, no answer
        encode_request(False, 0x1000_0000),           # nobody answers: time-out
        encode_request(False, match)[:4], None,       # a request cut by a gap: dropped
        encode_request(False, match),
    ])
    reset_id = regmap.register("ID").reset
    assert answers == [(ST_OK, reset_id), (ST_OK, 0), (ST_OK, 0x00150F00), (ST_CHECKSUM, 0),
                       (ST_OK, 0x00150F00), (ST_TIMEOUT, 0), (ST_OK, 0x00150F00)]
    assert st["requests"] == 5 and st["errors"] == 1


def test_firmware_drives_the_register_block_through_the_bridge():
    """The firmware's host build (app_init_pipeline: ID check, configuration with read-back)
    over sim.system.bridge_host and the bridge RTL, as on the ECP5 board."""
    import ctypes as C
    from sim.system.bridge_host import BridgeHost
    from sim.system.cosim import fwlib

    bridge, regs, sim = bridge_and_registers()
    mailbox = {"send": b"", "recv": b""}

    async def line(ctx):
        bits = []
        while True:
            if mailbox["send"]:
                b, mailbox["send"] = mailbox["send"][0], mailbox["send"][1:]
                bits = [0] + [(b >> k) & 1 for k in range(8)] + [1]
            for bit in bits:
                ctx.set(bridge.rx, bit)
                await ctx.tick().repeat(DIV)
            bits = []
            if not mailbox["send"]:
                await ctx.tick()

    async def listen(ctx):
        while True:
            await ctx.tick()
            if ctx.get(bridge.tx) == 0:             # start bit: sample the byte
                byte = 0
                await ctx.tick().repeat(DIV // 2 + DIV)
                for n in range(8):
                    byte |= ctx.get(bridge.tx) << n
                    await ctx.tick().repeat(DIV)
                mailbox["recv"] += bytes([byte])

    class Line:
        def write(self, data):
            mailbox["send"] += data

        def read(self, n):
            for _ in range(200000):
                if len(mailbox["recv"]) >= n:
                    break
                sim.advance()
            out, mailbox["recv"] = mailbox["recv"][:n], mailbox["recv"][n:]
            return out

    sim.add_testbench(line, background=True)
    sim.add_testbench(listen, background=True)
    lib = fwlib.load()
    host = BridgeHost(Line())
    host.install(lib)
    try:
        app = fwlib.AppC()
        assert lib.app_init_pipeline(C.byref(app), regmap.REGS_BASEADDR) == 0
    finally:
        lib.hal_set_bus_hook(fwlib.READ32(), fwlib.WRITE32(), fwlib.DELAY(), fwlib.UART(), None)
    assert host.transfers > 10
