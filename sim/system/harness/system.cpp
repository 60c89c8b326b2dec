// Verilated SystemSoC (hdl/soc.py) as a shared library for sim/system/run.py (ctypes).
//
// Three clocks run on one picosecond time line: the core clock `clk` and the two camera
// clocks `cam0_clk`, `cam1_clk`, each with its own period and phase. On every rising edge of a
// camera clock the camera presents its next BT.656 byte (valid high; after its stream ends it
// sends blanking filler 0x80 0x10 for ever): a camera never waits. sys_camera_stop makes one
// lose its decoder for a while: valid low, the bytes of that time lost.
//
// The CPU side is the MicroBlaze I/O bus: sys_read32 / sys_write32 perform one transfer the way
// the MCS does (one-cycle strobe, then wait for IO_Ready, at most 64 core cycles) while the
// cameras keep running. Their signatures match the firmware HAL's bus hook (firmware/include/
// hal.h), so the firmware's host build drives this model directly: hal_set_bus_hook(sys_read32,
// sys_write32, sys_delay_us, NULL, NULL). sys_delay_us advances the time line by that many
// microseconds of core clock.
#include <cstdint>
#include <cstdio>
#include <memory>
#include <vector>

#include "verilated.h"
#include "Vsoc.h"

namespace {

struct Clock {
    int64_t half_ps;        // half period
    int64_t next_ps;        // time of the next edge
    bool level = false;
};

struct Camera {
    std::vector<uint8_t> bytes;
    size_t pos = 0;
    uint64_t filler = 0;
    int64_t stop_pos = -1;      // sys_camera_stop: the byte it stops at, for stop_ps
    int64_t stop_ps = 0;
    int64_t stop_until = -1;
};

std::unique_ptr<VerilatedContext> ctx;
std::unique_ptr<Vsoc> top;
Clock clocks[3];            // 0 core, 1 cam0, 2 cam1
Camera cams[2];
int64_t now_ps = 0;
uint64_t core_cycles = 0;
int bus_timeouts = 0;

void present(int k) {
    Camera& c = cams[k];
    uint8_t b;
    if (c.stop_pos >= 0 && (int64_t)c.pos == c.stop_pos) {
        c.stop_until = now_ps + c.stop_ps;
        c.stop_pos = -1;
    }
    if (now_ps < c.stop_until) {
        if (c.pos < c.bytes.size()) c.pos++;
        if (k == 0) top->cam0___05Fvalid = 0; else top->cam1___05Fvalid = 0;
        return;
    }
    if (c.pos < c.bytes.size()) {
        b = c.bytes[c.pos++];
    } else {
        b = (c.filler++ & 1) ? 0x10 : 0x80;
    }
    if (k == 0) {
        top->cam0___05Fvalid = 1;
        top->cam0___05Fpayload = b;
    } else {
        top->cam1___05Fvalid = 1;
        top->cam1___05Fpayload = b;
    }
}

// Advance to the next clock edge(s); returns true when the core clock rose.
bool step() {
    int64_t t = clocks[0].next_ps;
    for (auto& c : clocks) t = c.next_ps < t ? c.next_ps : t;
    now_ps = t;
    bool core_rose = false;
    for (int i = 0; i < 3; i++) {
        Clock& c = clocks[i];
        if (c.next_ps != t) continue;
        c.level = !c.level;
        c.next_ps += c.half_ps;
        if (i == 0) {
            top->clk = c.level;
            if (c.level) { core_rose = true; core_cycles++; }
        } else {
            if (c.level) present(i - 1);
            if (i == 1) top->cam0_clk = c.level; else top->cam1_clk = c.level;
        }
    }
    ctx->timeInc(1);
    top->eval();
    return core_rose;
}

void core_tick() {
    while (!step()) {}
}

}  // namespace

extern "C" {

// Load the camera streams and set up the clocks (periods and the first edges in ps).
int sys_init(const uint8_t* left, uint64_t left_len, const uint8_t* right, uint64_t right_len,
             int64_t core_ps, int64_t cam0_ps, int64_t cam1_ps, int64_t cam0_phase_ps,
             int64_t cam1_phase_ps) {
    ctx = std::make_unique<VerilatedContext>();
    top = std::make_unique<Vsoc>(ctx.get());
    cams[0] = Camera{std::vector<uint8_t>(left, left + left_len)};
    cams[1] = Camera{std::vector<uint8_t>(right, right + right_len)};
    clocks[0] = Clock{core_ps / 2, core_ps / 2};
    clocks[1] = Clock{cam0_ps / 2, cam0_phase_ps + cam0_ps / 2};
    clocks[2] = Clock{cam1_ps / 2, cam1_phase_ps + cam1_ps / 2};
    now_ps = 0;
    core_cycles = 0;
    bus_timeouts = 0;
    top->clk = 0;
    top->cam0_clk = 0;
    top->cam1_clk = 0;
    top->scl_i = 1;
    top->sda_i = 1;
    top->uart_rx = 1;
    top->rst = 1;
    top->eval();
    for (int i = 0; i < 4; i++) core_tick();
    top->rst = 0;
    return 0;
}

uint32_t sys_read32(void*, uint32_t addr) {
    top->bus___05Faddr_strobe = 1;
    top->bus___05Faddress = addr;
    top->bus___05Fread_strobe = 1;
    top->bus___05Fwrite_strobe = 0;
    top->bus___05Fbyte_enable = 0xF;
    core_tick();
    top->bus___05Faddr_strobe = 0;
    top->bus___05Fread_strobe = 0;
    for (int n = 0; n < 64; n++) {
        if (top->bus___05Fready) return top->bus___05Fread_data;
        core_tick();
    }
    bus_timeouts++;
    return 0xFFFFFFFFu;
}

void sys_write32(void*, uint32_t addr, uint32_t value) {
    top->bus___05Faddr_strobe = 1;
    top->bus___05Faddress = addr;
    top->bus___05Fwrite_strobe = 1;
    top->bus___05Fread_strobe = 0;
    top->bus___05Fwrite_data = value;
    top->bus___05Fbyte_enable = 0xF;
    core_tick();
    top->bus___05Faddr_strobe = 0;
    top->bus___05Fwrite_strobe = 0;
    for (int n = 0; n < 64; n++) {
        if (top->bus___05Fready) return;
        core_tick();
    }
    bus_timeouts++;
}

void sys_delay_us(void*, uint32_t us) {
    int64_t until = now_ps + (int64_t)us * 1000000;
    while (now_ps < until) step();
}

void sys_run_cycles(uint64_t n) {
    for (uint64_t i = 0; i < n; i++) core_tick();
}

uint64_t sys_core_cycles() { return core_cycles; }
int64_t sys_time_ps() { return now_ps; }
uint64_t sys_camera_pos(int k) { return cams[k].pos; }

// Camera k stops when its stream reaches byte `pos`, for `ps` picoseconds (the decoder loses
// its input: the bytes of that time are lost), then goes on.
void sys_camera_stop(int k, int64_t pos, int64_t ps) {
    cams[k].stop_pos = pos;
    cams[k].stop_ps = ps;
}
int sys_bus_timeouts() { return bus_timeouts; }

void sys_final() {
    if (top) top->final();
    top.reset();
    ctx.reset();
}

}  // extern "C"
