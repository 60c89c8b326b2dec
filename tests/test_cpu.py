"""The soft CPU (hdl/cpu.py) boots the cross-compiled firmware under Verilator: on a tiny SoC
of the core (its "compact" configuration with the RAM with and without the register after it,
and its "fast" one with its own image), the timer and the radio UART, the firmware's first act is the XBee
query "AP" in API mode, and it must come out of the TX pin as a correct API frame; the core
never traps, and it sleeps in the timer (idle cycles) while it waits for the answer."""
import shutil
import subprocess

import pytest
from amaranth.hdl import Module
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from hdl.cpu import CORES, RiscvCPU, TIMER_BASEADDR, verilog_text
from hdl.soc import UART_BASEADDR
from hdl.uart import UART
from sim.backends.verilator import VERILATOR_FLAGS, verilator_env
from sim.flows.verilog import verilog_source
from sim.paths import BUILD
from sim.system import firmware

MAIN = r"""
#include <cstdio>
#include <cstdlib>
#include "verilated.h"
#include "Vtiny.h"
int main(int argc, char** argv) {
    long cycles = atol(argv[1]);
    int divisor = 434;
    VerilatedContext ctx;
    Vtiny top(&ctx);
    long idle = 0, trap = 0;
    int state = -1, count = 0, byte = 0;
    top.clk = 0; top.rst = 1; top.uart_rx = 1; top.eval();
    for (long c = 0; c < cycles; c++) {
        if (c == 4) top.rst = 0;
        top.clk = 1; top.eval(); top.clk = 0; top.eval();
        idle += top.idle; trap += top.trap;
        int tx = top.uart_tx;
        if (state < 0) { if (!tx) { state = 0; count = divisor / 2; byte = 0; } }
        else if (--count <= 0) {
            count = divisor;
            if (state == 0) state = tx ? -1 : 1;
            else if (state <= 8) { byte |= tx << (state - 1); state++; }
            else { if (tx) printf("byte %ld %d\n", c, byte); state = -1; }
        }
    }
    printf("idle %ld\ntrap %ld\n", idle, trap);
    return 0;
}
"""


class TinySoC(wiring.Component):
    """The CPU and the radio UART on its I/O bus."""

    def __init__(self, image, ram_register=False, core="compact"):
        self._image = image
        self._ram_register = ram_register
        self._core = core
        super().__init__({"uart_tx": Out(1, init=1), "uart_rx": In(1, init=1), "idle": Out(1),
                          "trap": Out(1)})

    def elaborate(self, platform):
        m = Module()
        m.submodules.cpu = cpu = RiscvCPU(core=self._core, image=self._image,
                                          ram_register=self._ram_register)
        m.submodules.uart = uart = UART(divisor=434, base=UART_BASEADDR)
        for name in ("addr_strobe", "address", "read_strobe", "write_strobe", "write_data",
                     "byte_enable"):
            m.d.comb += getattr(uart.bus, name).eq(getattr(cpu.bus, name))
        m.d.comb += [cpu.bus.read_data.eq(uart.bus.read_data), cpu.bus.ready.eq(uart.bus.ready),
                     self.uart_tx.eq(uart.tx), uart.rx.eq(self.uart_rx),
                     self.idle.eq(cpu.idle), self.trap.eq(cpu.trap)]
        return m


@pytest.fixture(scope="module", params=[("compact", False), ("compact", True), ("fast", True)],
                ids=["ram", "ram_register", "fast"])
def boot(request):
    core, ram_register = request.param
    image = firmware.image_words(firmware.build_image(core=core))
    out = BUILD / f"test_cpu_{core}_{ram_register}"
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    top = TinySoC(image, ram_register=ram_register, core=core)
    (out / "tiny.v").write_text(verilog_source("tiny", top, {}))
    (out / "main.cpp").write_text(MAIN)
    (out / "picorv32.v").write_text(verilog_text())
    cmd = ["verilator", "--cc", "--exe", "--build", *VERILATOR_FLAGS, "-Wno-TIMESCALEMOD",
           "--top-module", "tiny", "-Mdir", "obj", "-o", "tiny", "-j", "2", "tiny.v",
           "picorv32.v", "main.cpp"]
    r = subprocess.run(cmd, cwd=out, env=verilator_env(), capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    # 3 ms: start-up, the UART's baud setting, the query's 8 bytes at 115200 baud
    r = subprocess.run([str(out / "obj" / "tiny"), "150000"], capture_output=True, text=True,
                       check=True)
    lines = r.stdout.split("\n")
    tx = [int(line.split()[2]) for line in lines if line.startswith("byte")]
    stats = dict(line.split() for line in lines if line.startswith(("idle", "trap")))
    return tx, {k: int(v) for k, v in stats.items()}


def test_firmware_boots_and_sends_the_ap_query(boot):
    tx, stats = boot
    frame = bytes([0x08, 0x52, ord("A"), ord("P")])      # AT Command, frame id 0x52, "AP"
    checksum = 0xFF - sum(frame) & 0xFF
    assert bytes(tx[:8]) == bytes([0x7E, 0x00, 0x04]) + frame + bytes([checksum])
    assert stats["trap"] == 0


def test_core_sleeps_in_the_timer_while_waiting(boot):
    """Waiting for the XBee's answer, the firmware polls the UART every XBEE_POLL_US with the
    timer's WAIT: most of the cycles after the query are idle."""
    _tx, stats = boot
    assert stats["idle"] > 150000 // 4


def test_timer_and_bus_addresses_agree_with_the_firmware():
    hal = (firmware.ROOT / "firmware" / "include" / "hal.h").read_text()
    assert f"#define HAL_TIMER_BASEADDR 0x{TIMER_BASEADDR:08X}u" in hal
    assert f"#define HAL_UART_BASEADDR 0x{UART_BASEADDR:08X}u" in hal


def test_image_must_fit_ram():
    with pytest.raises(ValueError):
        RiscvCPU(image=[0] * 2049, ram_bytes=8192)
    with pytest.raises(ValueError):
        RiscvCPU(image=[0] * 2049)                      # the compact core's 8 KB
    RiscvCPU(core="fast", image=[0] * 2049)             # the fast core's 16 KB
    with pytest.raises(ValueError):
        RiscvCPU(ram_bytes=3000)
    with pytest.raises(ValueError, match="core must be one of compact, fast"):
        RiscvCPU(core="tiny")


def test_core_configurations():
    """The fast core: no compressed instructions, the ALU and the branch compare registered;
    its firmware is built for rv32i, the compact core's for rv32ic."""
    compact, fast = CORES["compact"], CORES["fast"]
    assert (compact.march, fast.march) == ("rv32ic", "rv32i")
    assert compact.core_parameters()["COMPRESSED_ISA"] == 1
    assert {k: fast.core_parameters()[k] for k in ("COMPRESSED_ISA", "TWO_CYCLE_COMPARE",
                                                   "TWO_CYCLE_ALU")} == \
        {"COMPRESSED_ISA": 0, "TWO_CYCLE_COMPARE": 1, "TWO_CYCLE_ALU": 1}
    assert fast.ram_bytes == 2 * compact.ram_bytes
