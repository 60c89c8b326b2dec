// Verilated SystemSoC with its CPU inside (hdl/soc.py, cpu="picorv32", monitor=True) as a
// shared library for sim/system/cpu_run.py (ctypes). The firmware runs on the Verilated core;
// nothing here drives the CPU's bus.
//
// Three clocks on one picosecond time line, as in system.cpp: the core clock and the two
// camera clocks, each camera presenting its next BT.656 byte on every rising edge of its
// clock (blanking filler after its stream ends).
//
// Around the SoC, once per core cycle (after the rising edge):
//   - two ADV7180 decoders on the IIC pins (7-bit addresses 0x20, 0x21): the register
//     behaviour of golden/iic.py ADV7180Model (IDENT 0x18, STATUS1 locked, a soft reset that
//     leaves the chip deaf for two addressings); either may be set never to answer;
//   - the radio UART's TX pin decoded into bytes (8N1 at `uart_divisor` core cycles a bit),
//     each with the core cycle of its start bit; bytes queued by the host are sent on the RX
//     pin at the same rate (the XBee's answers);
//   - the cameras send blanking filler until the firmware enables the video path (the first
//     write of VIDEO with video_enable = 1 seen on the bus), then their streams;
//   - the records and end-of-frame markers the SoC hands its band summary unit (ports
//     record_valid, record_word, as RESULT shows them) are logged with their cycle;
//   - the CPU's idle cycles (cpu_idle: asleep in a timer wait) and traps are counted;
//   - the loss watch's bits (HEALTH_STATUS left_lost, right_lost) are logged with the cycle of
//     each change: what a report's health must tell, independent of the firmware's reads.
// The model is built with an empty RAM; sys_load_ram writes the firmware image into it (the
// memory, the core's instruction counter and the loss bits are public through a Verilator
// configuration file, their names given as RAM, INSTRET, LOST_LEFT and LOST_RIGHT).
#include <cstdint>
#include <cstring>
#include <deque>
#include <memory>
#include <vector>

#include "verilated.h"
#include "Vsoc.h"
#include "Vsoc___024root.h"

namespace {

struct Clock {
    int64_t half_ps;
    int64_t next_ps;
    bool level = false;
};

struct Camera {
    std::vector<uint8_t> bytes;
    size_t pos = 0;
    uint64_t filler = 0;
};

// I2C target with a register file: golden/iic.py I2CDevice / ADV7180Model without stretching.
struct Adv7180 {
    int addr7;
    bool nack = false;
    uint8_t regs[256];
    int busy = 0;
    int resets = 0;
    enum State { IDLE, ADDR, ACK, WRITE, READ, READ_ACK, IGNORE } state = IDLE;
    int scl = 1, sda = 1, bits = 0, shift = 0, ptr = 0, out = 0;
    bool first = false, reading = false, master_nacked = true;
    int sda_low = 0;
    uint64_t addressed = 0;

    void defaults() {
        std::memset(regs, 0, sizeof regs);
        regs[0x03] = 0x0C; regs[0x07] = 0x7F; regs[0x10] = 0x05; regs[0x11] = 0x18;
    }
    bool ack_address() {
        if (busy > 0) { busy--; return false; }
        return !nack;
    }
    void on_write(int reg, int val) {
        if (reg == 0x0F && (val & 0x80)) { resets++; defaults(); busy = 2; return; }
        regs[reg] = (uint8_t)val;
    }
    void load_read_byte() {
        out = regs[ptr];
        ptr = (ptr + 1) & 0xFF;
        bits = 0;
        state = READ;
        sda_low = (out & 0x80) ? 0 : 1;
    }
    void on_fall() {
        if ((state == ADDR || state == WRITE) && bits == 8) {
            if (state == ADDR) {
                if ((shift >> 1) == addr7) {
                    addressed++;
                    if (ack_address()) {
                        sda_low = 1;
                        reading = shift & 1;
                        first = !reading;
                        state = ACK;
                    } else {
                        state = IGNORE;
                    }
                } else {
                    state = IGNORE;
                }
            } else {
                if (first) { ptr = shift; first = false; }
                else { on_write(ptr, shift); ptr = (ptr + 1) & 0xFF; }
                sda_low = 1;
                state = ACK;
            }
        } else if (state == ACK) {
            sda_low = 0;
            if (reading) load_read_byte();
            else { state = WRITE; bits = 0; shift = 0; }
        } else if (state == READ) {
            bits++;
            if (bits == 8) { sda_low = 0; state = READ_ACK; }
            else sda_low = ((out << bits) & 0x80) ? 0 : 1;
        } else if (state == READ_ACK) {
            if (master_nacked) state = IGNORE;
            else load_read_byte();
        }
    }
    int step(int nscl, int nsda) {     // returns sda_low for the next cycle
        bool rise = nscl && !scl, fall = !nscl && scl;
        if (nscl && scl && sda != nsda) {
            if (!nsda) { state = ADDR; bits = 0; shift = 0; sda_low = 0; }
            else { state = IDLE; sda_low = 0; }
        } else if (rise) {
            if (state == ADDR || state == WRITE) { shift = ((shift << 1) | nsda) & 0xFF; bits++; }
            else if (state == READ_ACK) master_nacked = nsda != 0;
        } else if (fall) {
            on_fall();
        }
        scl = nscl;
        sda = nsda;
        return sda_low;
    }
};

std::unique_ptr<VerilatedContext> ctx;
std::unique_ptr<Vsoc> top;
Clock clocks[3];
Camera cams[2];
Adv7180 decoders[2] = {Adv7180{0x20}, Adv7180{0x21}};
int dev_sda_low = 0;
int64_t now_ps = 0;
uint64_t core_cycles = 0, idle_cycles = 0, trap_cycles = 0;
uint32_t video_addr = 0;
bool video_on = false;
int64_t video_on_ps = -1;
uint64_t video_on_cycles = 0, video_on_idle = 0;
std::vector<uint64_t> rec_cycle;
std::vector<uint32_t> rec_word;
int divisor = 434;
// TX decoder
int tx_state = -1;              // -1 idle, 0 start bit, 1..8 data bits, 9 stop bit
int tx_count = 0, tx_byte = 0;
uint64_t tx_start = 0;
std::vector<uint8_t> tx_bytes;
std::vector<uint64_t> tx_cycle;
// RX driver
std::deque<uint8_t> rx_queue;
int rx_bit = -1, rx_count = 0, rx_byte = 0;
bool cam_live[2] = {false, false};
// loss watch: its bits (bit 0 left, bit 1 right) and each change with its core cycle
int lost_now = 0;
std::vector<uint64_t> lost_cycle;
std::vector<uint8_t> lost_bits;
int64_t cam_stop_pos[2] = {-1, -1}, cam_stop_ps[2] = {0, 0}, cam_stop_until[2] = {-1, -1};

void present(int k) {
    Camera& c = cams[k];
    uint8_t b;
    if (!cam_live[k]) {
        // the cameras' streams start when the firmware enables the video path (at a filler
        // pair's boundary)
        if (video_on && (c.filler & 1) == 0) {
            cam_live[k] = true;
        } else {
            b = (c.filler++ & 1) ? 0x10 : 0x80;
            if (k == 0) { top->cam0___05Fvalid = 1; top->cam0___05Fpayload = b; }
            else { top->cam1___05Fvalid = 1; top->cam1___05Fpayload = b; }
            return;
        }
    }
    if (cam_stop_pos[k] >= 0 && (int64_t)c.pos == cam_stop_pos[k]) {
        cam_stop_until[k] = now_ps + cam_stop_ps[k];
        cam_stop_pos[k] = -1;
    }
    if (now_ps < cam_stop_until[k]) {
        // the decoder has lost its camera: no byte comes (valid low) until it returns, and
        // the fields of that time are lost (the stream goes on without it)
        if (c.pos < c.bytes.size()) c.pos++;
        if (k == 0) top->cam0___05Fvalid = 0; else top->cam1___05Fvalid = 0;
        return;
    }
    if (c.pos < c.bytes.size()) b = c.bytes[c.pos++];
    else b = (c.filler++ & 1) ? 0x10 : 0x80;
    if (k == 0) { top->cam0___05Fvalid = 1; top->cam0___05Fpayload = b; }
    else { top->cam1___05Fvalid = 1; top->cam1___05Fpayload = b; }
}

void core_cycle() {
    core_cycles++;
    if (top->cpu_idle) idle_cycles++;
    if (top->cpu_trap) trap_cycles++;
    // the records into the band summary unit
    if (top->record_valid) {
        rec_cycle.push_back(core_cycles);
        rec_word.push_back(top->record_word);
    }
#if defined(LOST_LEFT) && defined(LOST_RIGHT)
    int lost = (top->rootp->LOST_LEFT & 1) | (top->rootp->LOST_RIGHT & 1) << 1;
    if (lost != lost_now) {
        lost_now = lost;
        lost_cycle.push_back(core_cycles);
        lost_bits.push_back((uint8_t)lost);
    }
#endif
    if (!video_on && top->monitor___05Faddr_strobe && top->monitor___05Fwrite_strobe &&
        top->monitor___05Faddress == video_addr && (top->monitor___05Fwrite_data & 1)) {
        video_on = true;
        video_on_ps = now_ps;
        video_on_cycles = core_cycles;
        video_on_idle = idle_cycles;
    }
    // IIC: resolve the open-drain lines, the devices answer from the next cycle
    int scl = top->scl_oe ? 0 : 1;
    int sda = (top->sda_oe || dev_sda_low) ? 0 : 1;
    top->scl_i = scl;
    top->sda_i = sda;
    int low = 0;
    for (auto& d : decoders) low |= d.step(scl, sda);
    dev_sda_low = low;
    // UART TX decode
    int tx = top->uart_tx;
    if (tx_state < 0) {
        if (!tx) { tx_state = 0; tx_count = divisor / 2; tx_start = core_cycles; tx_byte = 0; }
    } else if (--tx_count <= 0) {
        tx_count = divisor;
        if (tx_state == 0) {
            tx_state = tx ? -1 : 1;                 // a glitch, not a start bit
        } else if (tx_state <= 8) {
            tx_byte |= tx << (tx_state - 1);
            tx_state++;
        } else {
            if (tx) { tx_bytes.push_back((uint8_t)tx_byte); tx_cycle.push_back(tx_start); }
            tx_state = -1;
        }
    }
    // UART RX drive
    if (rx_bit < 0 && !rx_queue.empty()) {
        rx_byte = rx_queue.front();
        rx_queue.pop_front();
        rx_bit = 0;
        rx_count = divisor;
    }
    if (rx_bit >= 0) {
        top->uart_rx = rx_bit == 0 ? 0 : (rx_bit <= 8 ? (rx_byte >> (rx_bit - 1)) & 1 : 1);
        if (--rx_count <= 0) {
            rx_count = divisor;
            if (++rx_bit > 9) rx_bit = -1;
        }
    } else {
        top->uart_rx = 1;
    }
}

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
            core_rose = c.level;
        } else {
            if (c.level) present(i - 1);
            if (i == 1) top->cam0_clk = c.level; else top->cam1_clk = c.level;
        }
    }
    ctx->timeInc(1);
    top->eval();
    if (core_rose) core_cycle();
    return core_rose;
}

}  // namespace

// Move up to `max` logged pairs (a, b) into the buffers; returns how many.
template <typename A, typename B>
static uint64_t take(std::vector<A>& a, std::vector<B>& b, A* out_a, B* out_b, uint64_t max) {
    uint64_t n = b.size() < max ? b.size() : max;
    for (uint64_t i = 0; i < n; i++) { out_a[i] = a[i]; out_b[i] = b[i]; }
    a.erase(a.begin(), a.begin() + n);
    b.erase(b.begin(), b.begin() + n);
    return n;
}

extern "C" {

int sys_init(const uint8_t* left, uint64_t left_len, const uint8_t* right, uint64_t right_len,
             int64_t core_ps, int64_t cam0_ps, int64_t cam1_ps, int64_t cam0_phase_ps,
             int64_t cam1_phase_ps, uint32_t video_address,
             int uart_divisor, int nack_mask) {
    ctx = std::make_unique<VerilatedContext>();
    top = std::make_unique<Vsoc>(ctx.get());
    cams[0] = Camera{std::vector<uint8_t>(left, left + left_len)};
    cams[1] = Camera{std::vector<uint8_t>(right, right + right_len)};
    clocks[0] = Clock{core_ps / 2, core_ps / 2};
    clocks[1] = Clock{cam0_ps / 2, cam0_phase_ps + cam0_ps / 2};
    clocks[2] = Clock{cam1_ps / 2, cam1_phase_ps + cam1_ps / 2};
    for (int k = 0; k < 2; k++) {
        decoders[k] = Adv7180{0x20 + k};
        decoders[k].defaults();
        decoders[k].nack = (nack_mask >> k) & 1;
        cam_stop_pos[k] = cam_stop_until[k] = -1;
        cam_live[k] = false;
    }
    dev_sda_low = 0;
    now_ps = 0;
    core_cycles = idle_cycles = trap_cycles = 0;
    video_addr = video_address;
    video_on = false;
    video_on_ps = -1;
    rec_cycle.clear(); rec_word.clear();
    lost_now = 0; lost_cycle.clear(); lost_bits.clear();
    divisor = uart_divisor;
    tx_state = -1; tx_bytes.clear(); tx_cycle.clear();
    rx_queue.clear(); rx_bit = -1;
    top->clk = 0; top->cam0_clk = 0; top->cam1_clk = 0;
    top->scl_i = 1; top->sda_i = 1; top->uart_rx = 1;
    top->rst = 1;
    top->eval();
    for (int i = 0; i < 8; i++) { while (!step()) {} }
    return 0;
}

// Release the reset (after sys_init and sys_load_ram).
void sys_start() {
    top->rst = 0;
}

// Camera k stops when its stream reaches byte `pos`, for `ps` picoseconds (the decoder loses
// its input: the bytes of that time are lost), then goes on.
void sys_camera_stop(int k, int64_t pos, int64_t ps) {
    cam_stop_pos[k] = pos;
    cam_stop_ps[k] = ps;
}

void sys_run_until(int64_t until_ps) {
    while (now_ps < until_ps) step();
}

// Move up to `max` logged records into the buffers; returns how many.
uint64_t sys_take_records(uint64_t* cycles, uint32_t* words, uint64_t max) {
    return take(rec_cycle, rec_word, cycles, words, max);
}

// Move up to `max` bytes received from the TX pin into the buffers; returns how many.
uint64_t sys_take_tx(uint64_t* cycles, uint8_t* bytes, uint64_t max) {
    return take(tx_cycle, tx_bytes, cycles, bytes, max);
}

// Move up to `max` changes of the loss watch's bits into the buffers (the core cycle of each
// and the bits from then on: bit 0 left lost, bit 1 right lost); returns how many.
uint64_t sys_take_lost(uint64_t* cycles, uint8_t* bits, uint64_t max) {
    return take(lost_cycle, lost_bits, cycles, bits, max);
}

void sys_send_rx(const uint8_t* bytes, uint64_t n) {
    for (uint64_t i = 0; i < n; i++) rx_queue.push_back(bytes[i]);
}

uint64_t sys_core_cycles() { return core_cycles; }
uint64_t sys_idle_cycles() { return idle_cycles; }
uint64_t sys_trap_cycles() { return trap_cycles; }
int64_t sys_time_ps() { return now_ps; }
int64_t sys_video_on_ps() { return video_on_ps; }
uint64_t sys_video_on_cycles() { return video_on_cycles; }
uint64_t sys_video_on_idle() { return video_on_idle; }
uint64_t sys_decoder_addressed(int k) { return decoders[k].addressed; }
uint64_t sys_decoder_resets(int k) { return decoders[k].resets; }

// Load the CPU's RAM (the firmware image, little-endian words) before the core starts: the
// Verilated model is built with an empty RAM, so one build runs any image.
int sys_load_ram(const uint32_t* words, uint64_t n) {
#ifdef RAM
    auto& ram = top->rootp->RAM;
    if (n > ram.size()) return -1;
    for (uint64_t i = 0; i < ram.size(); i++) ram[i] = i < n ? words[i] : 0;
    return 0;
#else
    return -1;
#endif
}

uint64_t sys_instructions() {
#ifdef INSTRET
    return (uint32_t)top->rootp->INSTRET;
#else
    return 0;
#endif
}

void sys_final() {
    if (top) top->final();
    top.reset();
    ctx.reset();
}

}  // extern "C"
