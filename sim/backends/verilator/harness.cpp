// Full-frame stream harness for a Verilated Amaranth component (see sim/backends/verilator/__init__.py).
//
// The design-specific part is the generated header design_ports.h: it names the Verilated
// class (Top) and gives accessors for K input streams, M output streams, run-time parameter
// inputs and status outputs. This file is the same for every design.
//
// Protocol (amaranth.lib.stream): a word moves on a rising clock edge when valid and ready are
// both high. Inputs: before each word the harness idles (valid low) with probability --idle per
// cycle; once valid is high it holds the word until it is taken. Outputs: ready is low with
// probability --stall in each cycle, independently of valid. Every port has its own seeded
// generator, so a run is reproducible from --seed.
//
// With REGISTERED_INPUTS (design_ports.h) the Verilated model is a wrapper that feeds every
// input of the design but the clock through a register (sim/backends/verilator input_register_wrapper):
// the harness sets the inputs of each cycle in the cycle before, and the design's logic is
// evaluated once per cycle, after the rising edge. The ports move the same words in the same
// cycles as without the wrapper.
//
// Usage:
//   harness [--in NAME FILE]... [--out NAME FILE EOF_BIT COUNT]... [--param NAME HEX]...
//           [--seed N] [--idle P] [--stall P] [--timeout CYCLES] [--max-cycles CYCLES]
//           [--reset-cycles N]
// FILEs hold uint64 little-endian words. An output stops after COUNT words with bit EOF_BIT set
// (frames), or after COUNT words when EOF_BIT is -1. The run ends when every output is done.
// Prints one JSON line on stdout. Exit status: 0 done, 2 usage or I/O error, 3 deadlock (no
// transfer on any port for --timeout cycles), 4 --max-cycles reached.
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "verilated.h"
#include "design_ports.h"

namespace {

struct Rng {  // splitmix64
    uint64_t s;
    explicit Rng(uint64_t seed) : s(seed) {}
    uint64_t next() {
        uint64_t z = (s += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }
    // true with probability p (threshold precomputed as p * 2^64)
    bool chance(uint64_t threshold) { return threshold && next() < threshold; }
};

uint64_t threshold(double p) {
    if (p <= 0) return 0;
    if (p >= 1) return UINT64_MAX;
    return (uint64_t)(p * 18446744073709551616.0);
}

struct InStream {
    std::string file;
    std::vector<uint64_t> words;
    size_t pos = 0;
    bool offering = false;
};

struct OutStream {
    std::string file;
    int eof_bit = -1;
    uint64_t count = 0;
    std::vector<uint64_t> words;
    uint64_t frames = 0;
    bool done() const { return (eof_bit < 0 ? words.size() : frames) >= count; }
};

[[noreturn]] void die(const std::string& msg) {
    std::fprintf(stderr, "harness: %s\n", msg.c_str());
    std::exit(2);
}

int find(const char* const* names, int n, const char* name) {
    for (int k = 0; k < n; k++)
        if (!std::strcmp(names[k], name)) return k;
    return -1;
}

// A hexadecimal number (optional 0x) as 32-bit words, least significant first, at least 8 of
// them (parameter ports up to 256 bits).
std::vector<uint32_t> hex_words(std::string s) {
    if (s.rfind("0x", 0) == 0 || s.rfind("0X", 0) == 0) s = s.substr(2);
    std::vector<uint32_t> w;
    for (size_t end = s.size(); end > 0; end = end >= 8 ? end - 8 : 0) {
        size_t start = end >= 8 ? end - 8 : 0;
        std::string chunk = s.substr(start, end - start);
        char* stop = nullptr;
        w.push_back((uint32_t)std::strtoul(chunk.c_str(), &stop, 16));
        if (chunk.empty() || *stop) die("bad hexadecimal parameter value " + s);
        if (start == 0) break;
    }
    while (w.size() < 8) w.push_back(0);
    return w;
}

std::vector<uint64_t> read_words(const std::string& path) {
    FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) die("cannot read " + path);
    std::fseek(f, 0, SEEK_END);
    long size = std::ftell(f);
    std::fseek(f, 0, SEEK_SET);
    if (size % 8) die(path + ": size is not a multiple of 8 bytes");
    std::vector<uint64_t> w(size / 8);
    if (size && std::fread(w.data(), 8, w.size(), f) != w.size()) die("short read on " + path);
    std::fclose(f);
    return w;
}

void write_words(const std::string& path, const std::vector<uint64_t>& w) {
    FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) die("cannot write " + path);
    if (!w.empty() && std::fwrite(w.data(), 8, w.size(), f) != w.size()) die("short write on " + path);
    std::fclose(f);
}

}  // namespace

int main(int argc, char** argv) {
    InStream ins[N_IN > 0 ? N_IN : 1];
    OutStream outs[N_OUT > 0 ? N_OUT : 1];
    bool out_given[N_OUT > 0 ? N_OUT : 1] = {};
    std::vector<std::pair<int, std::vector<uint32_t>>> params;
    uint64_t seed = 0, timeout = 10000, max_cycles = UINT64_MAX, reset_cycles = 4;
    double idle = 0, stall = 0;

    auto need = [&](int i, int n) { if (i + n >= argc) die(std::string("missing value after ") + argv[i]); };
    for (int i = 1; i < argc; i++) {
        std::string a = argv[i];
        if (a == "--in") {
            need(i, 2);
            int k = find(IN_NAMES, N_IN, argv[i + 1]);
            if (k < 0) die(std::string("no input stream ") + argv[i + 1]);
            ins[k].file = argv[i + 2];
            i += 2;
        } else if (a == "--out") {
            need(i, 4);
            int k = find(OUT_NAMES, N_OUT, argv[i + 1]);
            if (k < 0) die(std::string("no output stream ") + argv[i + 1]);
            outs[k].file = argv[i + 2];
            outs[k].eof_bit = std::atoi(argv[i + 3]);
            outs[k].count = std::strtoull(argv[i + 4], nullptr, 0);
            out_given[k] = true;
            i += 4;
        } else if (a == "--param") {
            need(i, 2);
            int k = find(PARAM_NAMES, N_PARAM, argv[i + 1]);
            if (k < 0) die(std::string("no parameter input ") + argv[i + 1]);
            params.emplace_back(k, hex_words(argv[i + 2]));
            i += 2;
        } else if (a == "--seed") { need(i, 1); seed = std::strtoull(argv[++i], nullptr, 0); }
        else if (a == "--idle") { need(i, 1); idle = std::atof(argv[++i]); }
        else if (a == "--stall") { need(i, 1); stall = std::atof(argv[++i]); }
        else if (a == "--timeout") { need(i, 1); timeout = std::strtoull(argv[++i], nullptr, 0); }
        else if (a == "--max-cycles") { need(i, 1); max_cycles = std::strtoull(argv[++i], nullptr, 0); }
        else if (a == "--reset-cycles") { need(i, 1); reset_cycles = std::strtoull(argv[++i], nullptr, 0); }
        else die("unknown argument " + a);
    }
    for (int k = 0; k < N_IN; k++) {
        if (ins[k].file.empty()) die(std::string("no --in for stream ") + IN_NAMES[k]);
        ins[k].words = read_words(ins[k].file);
    }
    for (int k = 0; k < N_OUT; k++)
        if (!out_given[k]) die(std::string("no --out for stream ") + OUT_NAMES[k]);

    // One generator per port: inputs get seed*64+1+k, outputs seed*64+33+k.
    std::vector<Rng> in_rng, out_rng;
    for (int k = 0; k < N_IN; k++) in_rng.emplace_back(seed * 64 + 1 + k);
    for (int k = 0; k < N_OUT; k++) out_rng.emplace_back(seed * 64 + 33 + k);
    const uint64_t idle_t = threshold(idle), stall_t = threshold(stall);

    auto ctx = std::make_unique<VerilatedContext>();
    auto top = std::make_unique<Top>(ctx.get());
    if (REGISTERED_INPUTS && reset_cycles < 1) die("--reset-cycles must be at least 1");

    uint64_t cycle = 0, quiet = 0;
    int64_t first_offer = -1, last_take = -1;
    bool oready[N_OUT > 0 ? N_OUT : 1] = {};
    // The input and output ready lines of cycle c.
    auto drive = [&](uint64_t c) {
        for (int k = 0; k < N_IN; k++) {
            InStream& s = ins[k];
            if (!s.offering && s.pos < s.words.size() && !in_rng[k].chance(idle_t)) s.offering = true;
            in_drive(top.get(), k, s.offering, s.offering ? s.words[s.pos] : 0);
            if (s.offering && first_offer < 0) first_offer = (int64_t)c;
        }
        for (int k = 0; k < N_OUT; k++) {
            oready[k] = !out_rng[k].chance(stall_t);
            out_ready(top.get(), k, oready[k]);
        }
    };
    // The transfers that the rising edge ending cycle c makes (the design's outputs settled
    // for that cycle); whether anything moved.
    auto sample = [&](uint64_t c) {
        bool moved = false;
        for (int k = 0; k < N_IN; k++) {
            InStream& s = ins[k];
            if (s.offering && in_ready(top.get(), k)) {
                s.pos++;
                s.offering = false;
                moved = true;
            }
        }
        for (int k = 0; k < N_OUT; k++) {
            OutStream& s = outs[k];
            if (oready[k] && out_valid(top.get(), k) && !s.done()) {
                uint64_t w = out_payload(top.get(), k);
                s.words.push_back(w);
                if (s.eof_bit >= 0 && ((w >> s.eof_bit) & 1)) s.frames++;
                last_take = (int64_t)c;
                moved = true;
            }
        }
        return moved;
    };
    auto edge = [&]() {
        set_clk(top.get(), 1); top->eval();
        set_clk(top.get(), 0); top->eval();
    };

    // Parameters are set before and held through reset.
    for (auto& [k, v] : params) param_set(top.get(), k, v.data());
    set_clk(top.get(), 0);
    set_rst(top.get(), 1);
    for (int k = 0; k < N_IN; k++) in_drive(top.get(), k, false, 0);
    for (int k = 0; k < N_OUT; k++) out_ready(top.get(), k, false);
    top->eval();
    for (uint64_t c = 0; c < reset_cycles; c++) {
        if (REGISTERED_INPUTS && c + 1 == reset_cycles) {
            // The design sees its inputs through registers (sim/backends/verilator
            // input_register_wrapper): what it is to see in a cycle is set in the one before.
            set_rst(top.get(), 0);
            drive(0);
        }
        edge();
    }
    set_rst(top.get(), 0);

    auto t0 = std::chrono::steady_clock::now();
    int status = 0;
    std::string message;
    while (true) {
        bool all_done = true;
        for (int k = 0; k < N_OUT; k++) all_done &= outs[k].done();
        if (all_done) break;
        if (cycle >= max_cycles) {
            status = 4;
            message = "max cycles reached";
            break;
        }
        bool moved;
        if (REGISTERED_INPUTS) {
            // The rising edge that began this cycle settled every output: one evaluation of
            // the design per cycle (the falling edge's evaluation has no logic to run).
            moved = sample(cycle);
            drive(cycle + 1);
            edge();
        } else {
            // Plain inputs: settle the outputs on this cycle's inputs, then the rising edge.
            drive(cycle);
            top->eval();
            moved = sample(cycle);
            set_clk(top.get(), 1); top->eval();
            set_clk(top.get(), 0);
        }
        cycle++;
        quiet = moved ? 0 : quiet + 1;
        if (quiet >= timeout) {
            status = 3;
            message = "deadlock: no transfer for " + std::to_string(timeout) + " cycles";
            break;
        }
    }
    double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    top->final();

    for (int k = 0; k < N_OUT; k++) write_words(outs[k].file, outs[k].words);
    uint64_t cycles = (first_offer >= 0 && last_take >= first_offer) ? (uint64_t)(last_take - first_offer + 1) : 0;
    std::printf("{\"status\": %d, \"message\": \"%s\", \"cycles\": %llu, \"total_cycles\": %llu, "
                "\"seconds\": %.6f, \"inputs\": {", status, message.c_str(),
                (unsigned long long)cycles, (unsigned long long)cycle, seconds);
    for (int k = 0; k < N_IN; k++)
        std::printf("%s\"%s\": [%llu, %llu]", k ? ", " : "", IN_NAMES[k],
                    (unsigned long long)ins[k].pos, (unsigned long long)ins[k].words.size());
    std::printf("}, \"outputs\": {");
    for (int k = 0; k < N_OUT; k++)
        std::printf("%s\"%s\": [%llu, %llu]", k ? ", " : "", OUT_NAMES[k],
                    (unsigned long long)outs[k].words.size(), (unsigned long long)outs[k].frames);
    std::printf("}, \"status_ports\": {");
    for (int k = 0; k < N_STATUS; k++)
        std::printf("%s\"%s\": %llu", k ? ", " : "", STATUS_NAMES[k],
                    (unsigned long long)status_get(top.get(), k));
    std::printf("}}\n");
    if (status) {
        std::fprintf(stderr, "harness: %s at cycle %llu\n", message.c_str(), (unsigned long long)cycle);
    }
    return status;
}
