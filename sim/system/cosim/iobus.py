"""MicroBlaze MCS I/O bus transfers for Amaranth testbenches (``hdl.regs.IOBusSignature``).

``await io_write(ctx, bus, addr, value)`` and ``await io_read(ctx, bus, addr)`` drive one
transfer the way the MCS does: a one-cycle strobe, then wait for ``ready``. They return the
read value (and record the latency in cycles in ``last_latency``).
"""

__all__ = ["io_read", "io_write", "last_latency", "BusTimeout"]

last_latency = [0]


class BusTimeout(Exception):
    pass


async def _transfer(ctx, bus, addr, *, write, value=0, byte_enable=0xF, timeout=64):
    ctx.set(bus.addr_strobe, 1)
    ctx.set(bus.address, addr)
    ctx.set(bus.read_strobe, 0 if write else 1)
    ctx.set(bus.write_strobe, 1 if write else 0)
    ctx.set(bus.write_data, value if write else 0)
    ctx.set(bus.byte_enable, byte_enable if write else 0xF)
    await ctx.tick()
    ctx.set(bus.addr_strobe, 0)
    ctx.set(bus.read_strobe, 0)
    ctx.set(bus.write_strobe, 0)
    cycles = 1
    while not ctx.get(bus.ready):
        if cycles >= timeout:
            raise BusTimeout(f"no IO_Ready within {timeout} cycles at 0x{addr:08X}")
        await ctx.tick()
        cycles += 1
    last_latency[0] = cycles
    return ctx.get(bus.read_data)


async def io_write(ctx, bus, addr, value, byte_enable=0xF, timeout=64):
    await _transfer(ctx, bus, addr, write=True, value=value, byte_enable=byte_enable,
                    timeout=timeout)


async def io_read(ctx, bus, addr, timeout=64):
    return await _transfer(ctx, bus, addr, write=False, timeout=timeout)
