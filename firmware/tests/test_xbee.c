/* XBee AT-command start-up against a simulated module (command mode with guard times,
 * AT commands applied at CN, API mode 2 AT queries, a baud rate that must match). */
#include "fwtest.h"
#include "hal.h"
#include "radio.h"
#include "xbee.h"

#include <string.h>

#define GT_US 1000000u   /* the module's guard time (factory GT = 1 s) */

typedef struct {
    int present;
    uint32_t now_us;
    uint32_t host_baud;
    uint32_t baud;
    uint8_t ap;
    uint8_t cmd_mode;
    uint16_t my, dl, id;
    uint16_t new_ap, new_bd, new_my, new_dl, new_id;
    uint32_t last_rx_us;
    uint32_t plus_count;
    uint32_t plus_done_us;
    int plus_armed;
    char line[32];
    uint32_t line_n;
    uint8_t api[64];
    uint32_t api_n;
    int api_in, api_esc;
    uint8_t out[512];
    uint32_t out_baud[512];  /* the module's baud when it sent each byte */
    uint32_t out_head, out_tail;
    const char *error_cmd;   /* answer ERROR to this command */
    uint32_t nv_writes;
    uint32_t commands;
    uint32_t read_cost_us;   /* time a read of the UART takes */
} sim_xbee_t;

static void out_put(sim_xbee_t *m, const uint8_t *d, uint32_t n)
{
    uint32_t i;
    for (i = 0; i < n && m->out_tail < sizeof m->out; i++) {
        m->out_baud[m->out_tail] = m->baud;
        m->out[m->out_tail++] = d[i];
    }
}

static void out_str(sim_xbee_t *m, const char *s)
{
    out_put(m, (const uint8_t *)s, (uint32_t)strlen(s));
}

static uint32_t bd_baud(uint16_t bd)
{
    static const uint32_t rates[8] = { 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200 };
    return bd < 8 ? rates[bd] : 0;
}

static uint16_t hex_value(const char *s, uint32_t n)
{
    uint16_t v = 0;
    uint32_t i;
    for (i = 0; i < n; i++) {
        char c = s[i];
        v = (uint16_t)(v * 16 + (c <= '9' ? c - '0' : c - 'A' + 10));
    }
    return v;
}

static void run_command(sim_xbee_t *m)
{
    const char *c = m->line;
    uint32_t n = m->line_n;
    uint16_t v;
    m->commands++;
    if (n < 4 || c[0] != 'A' || c[1] != 'T' || (m->error_cmd && !strncmp(c + 2, m->error_cmd, 2))) {
        out_str(m, "ERROR\r");
        return;
    }
    v = hex_value(c + 4, n - 4);
    if (!strncmp(c + 2, "AP", 2)) { m->new_ap = v; }
    else if (!strncmp(c + 2, "BD", 2)) { m->new_bd = v; }
    else if (!strncmp(c + 2, "MY", 2)) { m->new_my = v; }
    else if (!strncmp(c + 2, "DL", 2)) { m->new_dl = v; }
    else if (!strncmp(c + 2, "ID", 2)) { m->new_id = v; }
    else if (!strncmp(c + 2, "WR", 2)) { m->nv_writes++; }
    else if (!strncmp(c + 2, "CN", 2)) {
        out_str(m, "OK\r");
        m->cmd_mode = 0;
        m->ap = (uint8_t)m->new_ap; m->my = m->new_my; m->dl = m->new_dl; m->id = m->new_id;
        m->baud = bd_baud(m->new_bd);
        return;
    } else {
        out_str(m, "ERROR\r");
        return;
    }
    out_str(m, "OK\r");
}

static void api_frame(sim_xbee_t *m)
{
    uint8_t resp[8];
    uint8_t frame[24];
    uint32_t n = 5, len;
    if (m->api_n < 4 || m->api[0] != XBEE_API_AT_COMMAND) {
        return;
    }
    resp[0] = XBEE_API_AT_RESPONSE; resp[1] = m->api[1]; resp[2] = m->api[2];
    resp[3] = m->api[3]; resp[4] = 0;
    if (m->api[2] == 'A' && m->api[3] == 'P') {
        resp[n++] = m->ap;
    } else if (m->api[2] == 'M' && m->api[3] == 'Y') {
        resp[n++] = (uint8_t)(m->my >> 8); resp[n++] = (uint8_t)m->my;
    } else {
        resp[4] = 2;     /* invalid command */
    }
    len = radio_encode_frame(resp, n, frame, sizeof frame);
    out_put(m, frame, len);
}

static void api_byte(sim_xbee_t *m, uint8_t b)
{
    uint32_t len;
    uint32_t i;
    uint8_t sum = 0;
    if (b == 0x7E) {
        m->api_in = 1; m->api_n = 0; m->api_esc = 0;
        return;
    }
    if (!m->api_in) {
        return;
    }
    if (b == 0x7D) {
        m->api_esc = 1;
        return;
    }
    if (m->api_esc) {
        b ^= 0x20; m->api_esc = 0;
    }
    if (m->api_n < sizeof m->api) {
        m->api[m->api_n++] = b;
    }
    if (m->api_n < 2) {
        return;
    }
    len = ((uint32_t)m->api[0] << 8) | m->api[1];
    if (m->api_n == len + 3) {
        for (i = 2; i < len + 3; i++) {
            sum = (uint8_t)(sum + m->api[i]);
        }
        m->api_in = 0;
        if (sum == 0xFF) {
            memmove(m->api, m->api + 2, len);
            m->api_n = len;
            api_frame(m);
        }
    }
}

static void sim_write(void *ctx, const uint8_t *d, uint32_t n)
{
    sim_xbee_t *m = ctx;
    uint32_t i;
    if (!m->present) {
        return;
    }
    for (i = 0; i < n; i++) {
        uint8_t b = d[i];
        uint32_t silence = m->now_us - m->last_rx_us;
        m->last_rx_us = m->now_us;
        m->plus_armed = 0;
        if (m->host_baud != m->baud) {
            m->plus_count = 0;          /* framing errors: the module sees garbage */
            continue;
        }
        if (m->cmd_mode) {
            if (b == '\r') {
                run_command(m);
                m->line_n = 0;
            } else if (m->line_n < sizeof m->line) {
                m->line[m->line_n++] = (char)b;
            }
            continue;
        }
        if (b == '+' && (m->plus_count > 0 || silence >= GT_US)) {
            if (++m->plus_count == 3) {
                m->plus_armed = 1;
                m->plus_done_us = m->now_us;
                m->plus_count = 0;
            }
            continue;
        }
        m->plus_count = 0;
        if (m->ap == 2) {
            api_byte(m, b);
        }
    }
}

static int sim_read(void *ctx, uint8_t *b)
{
    sim_xbee_t *m = ctx;
    m->now_us += m->read_cost_us;
    if (m->out_head == m->out_tail) {
        return 0;
    }
    *b = m->out[m->out_head];
    if (m->host_baud != m->out_baud[m->out_head++]) {
        *b ^= 0x5A;                     /* read at the wrong baud: garbage */
    }
    return 1;
}

static void sim_set_baud(void *ctx, uint32_t baud)
{
    ((sim_xbee_t *)ctx)->host_baud = baud;
}

static void sim_delay(void *ctx, uint32_t us)
{
    sim_xbee_t *m = ctx;
    m->now_us += us;
    if (m->plus_armed && m->now_us - m->plus_done_us >= GT_US) {
        m->plus_armed = 0;
        m->cmd_mode = 1;
        m->line_n = 0;
        m->new_ap = m->ap; m->new_my = m->my; m->new_dl = m->dl; m->new_id = m->id;
        m->new_bd = m->baud == 9600 ? 3 : 7;
        out_str(m, "OK\r");
    }
}

static void factory(sim_xbee_t *m)
{
    memset(m, 0, sizeof *m);
    m->present = 1;
    m->baud = 9600;
    m->ap = 0;
    m->my = 0;
    m->id = 0x3332;
    m->host_baud = 9600;
}

static const xbee_config_t cfg = { 0x0002, 0x0001, 0x1234 };

/* The HAL's clock (the firmware's deadlines) is the module's time. */
static uint32_t sim_ticks(void *ctx)
{
    return ((sim_xbee_t *)ctx)->now_us * HAL_TICKS_PER_US;
}

static void io_of(xbee_io_t *io, sim_xbee_t *m)
{
    io->write = sim_write; io->read = sim_read; io->set_baud = sim_set_baud;
    io->delay_us = sim_delay; io->ctx = m;
    hal_set_ticks_hook(sim_ticks, m);
}

static void test_factory_module_is_configured(void)
{
    static sim_xbee_t m;
    xbee_io_t io;
    xbee_result_t r;
    factory(&m);
    io_of(&io, &m);
    FWT_CHECK_EQ(xbee_configure(&io, &cfg, &r), FW_OK);
    FWT_CHECK_EQ(r.was_configured, 0);
    FWT_CHECK_EQ(r.factory_baud, 9600);
    FWT_CHECK_EQ(r.commands_ok, 7);
    FWT_CHECK(m.ap == 2 && m.baud == 115200 && m.my == 2 && m.dl == 1 && m.id == 0x1234);
    FWT_CHECK_EQ(m.nv_writes, 1);
    FWT_CHECK_EQ(m.host_baud, 115200);
}

static void test_configured_module_is_left_alone(void)
{
    static sim_xbee_t m;
    xbee_io_t io;
    xbee_result_t r;
    factory(&m);
    m.baud = 115200; m.ap = 2; m.my = 2;
    io_of(&io, &m);
    FWT_CHECK_EQ(xbee_configure(&io, &cfg, &r), FW_OK);
    FWT_CHECK_EQ(r.was_configured, 1);
    FWT_CHECK_EQ(m.commands, 0);
    FWT_CHECK_EQ(m.nv_writes, 0);
    FWT_CHECK(m.now_us < XBEE_RESPONSE_US);
}

static void test_transparent_module_at_115200(void)
{
    /* the 9600-baud "+++" is garbage to it: bounded wait, then 115200 */
    static sim_xbee_t m;
    xbee_io_t io;
    xbee_result_t r;
    factory(&m);
    m.baud = 115200;
    io_of(&io, &m);
    FWT_CHECK_EQ(xbee_configure(&io, &cfg, &r), FW_OK);
    FWT_CHECK_EQ(r.factory_baud, 115200);
    FWT_CHECK(m.ap == 2 && m.baud == 115200 && m.my == 2);
}

static void test_wrong_address_is_rewritten(void)
{
    static sim_xbee_t m;
    xbee_io_t io;
    xbee_result_t r;
    factory(&m);
    m.baud = 115200; m.ap = 2; m.my = 7;
    io_of(&io, &m);
    FWT_CHECK_EQ(xbee_configure(&io, &cfg, &r), FW_OK);
    FWT_CHECK_EQ(r.was_configured, 0);
    FWT_CHECK_EQ(m.my, 2);
}

static void test_no_module_times_out_in_bounds(void)
{
    static sim_xbee_t m;
    xbee_io_t io;
    factory(&m);
    m.present = 0;
    io_of(&io, &m);
    FWT_CHECK_EQ(xbee_configure(&io, &cfg, NULL), FW_ERR_TIMEOUT);
    FWT_CHECK(m.now_us <= 2u * (2u * XBEE_GUARD_US + XBEE_RESPONSE_US) + 3u * XBEE_RESPONSE_US
              + 10000u);
}

/* With no module, the time xbee_configure takes: the first API query's wait, then command
 * mode at both bauds (a guard time either side of "+++" and the wait for "OK"). */
#define NO_MODULE_US (XBEE_RESPONSE_US + 2u * (2u * XBEE_GUARD_US + XBEE_RESPONSE_US))

static void test_response_waits_end_at_their_deadlines(void)
{
    static sim_xbee_t m;
    xbee_io_t io;
    factory(&m);
    m.present = 0;
    io_of(&io, &m);
    FWT_CHECK_EQ(xbee_configure(&io, &cfg, NULL), FW_ERR_TIMEOUT);
    FWT_CHECK(m.now_us >= NO_MODULE_US);
    FWT_CHECK(m.now_us <= NO_MODULE_US + 3u * XBEE_POLL_US);
}

static void test_slow_reads_count_against_the_deadline(void)
{
    /* every read of the UART takes longer than the pause between polls: the waits still end
     * at their deadlines, after fewer polls */
    static sim_xbee_t m;
    xbee_io_t io;
    factory(&m);
    m.present = 0;
    m.read_cost_us = 3u * XBEE_POLL_US;
    io_of(&io, &m);
    FWT_CHECK_EQ(xbee_configure(&io, &cfg, NULL), FW_ERR_TIMEOUT);
    FWT_CHECK(m.now_us >= NO_MODULE_US);
    /* past each of the three deadlines by at most a poll, and a read to drain the UART
     * before each */
    FWT_CHECK(m.now_us <= NO_MODULE_US + 3u * (XBEE_POLL_US + 2u * m.read_cost_us));
}

static void test_error_answer_stops_before_writing(void)
{
    static sim_xbee_t m;
    xbee_io_t io;
    xbee_result_t r;
    factory(&m);
    m.error_cmd = "BD";
    io_of(&io, &m);
    FWT_CHECK_EQ(xbee_configure(&io, &cfg, &r), FW_ERR_RX);
    FWT_CHECK_EQ(r.commands_ok, 1);
    FWT_CHECK_EQ(m.nv_writes, 0);
    FWT_CHECK_EQ(xbee_configure(NULL, &cfg, NULL), FW_ERR_PARAM);
}

/* Feed every byte the module sent; the number of completed answers, and the index of the
 * byte that completed the last one in *last. */
static uint32_t probe_all(sim_xbee_t *m, xbee_probe_t *p, uint32_t *last)
{
    uint8_t b;
    uint32_t i = 0, hits = 0;
    while (sim_read(m, &b)) {
        if (xbee_probe_feed(p, b)) {
            hits++;
            *last = i;
        }
        i++;
    }
    return hits;
}

static void test_probe_finds_a_module_that_comes_later(void)
{
    static sim_xbee_t m;
    static const uint8_t req[4] = { XBEE_API_AT_COMMAND, XBEE_AT_FRAME_ID, 'A', 'P' };
    static const uint8_t noise[] = { 0x7E, 0x00, 0x7E, 0x7E, 0x00, 0x06, 0x88, 0x52, 0x41 };
    uint8_t q[XBEE_PROBE_QUERY_LEN];
    uint8_t want[16];
    xbee_io_t io;
    xbee_probe_t p = { 0 };
    uint32_t last = 0, i;
    factory(&m);
    m.present = 0;
    io_of(&io, &m);
    FWT_CHECK_EQ(xbee_configure(&io, &cfg, NULL), FW_ERR_TIMEOUT);
    xbee_probe_query(q);
    FWT_CHECK_EQ(radio_encode_frame(req, 4, want, sizeof want), XBEE_PROBE_QUERY_LEN);
    FWT_CHECK(memcmp(q, want, sizeof q) == 0);
    io.write(io.ctx, q, sizeof q);                   /* nobody there: no answer */
    FWT_CHECK_EQ(probe_all(&m, &p, &last), 0);
    m.present = 1; m.baud = 115200; m.ap = 2;        /* a configured module plugged in */
    io.set_baud(io.ctx, XBEE_LINK_BAUD);
    out_put(&m, noise, sizeof noise);                /* a cut-off frame first */
    io.write(io.ctx, q, sizeof q);
    FWT_CHECK_EQ(probe_all(&m, &p, &last), 1);
    FWT_CHECK_EQ(last, sizeof noise + 9);            /* at the answer's checksum */
    for (i = 0; i < 2; i++) {                        /* and again for the next query */
        io.write(io.ctx, q, sizeof q);
        FWT_CHECK_EQ(probe_all(&m, &p, &last), 1);
    }
    m.ap = 0;                                        /* transparent mode: no answer */
    io.write(io.ctx, q, sizeof q);
    FWT_CHECK_EQ(probe_all(&m, &p, &last), 0);
    m.ap = 2; m.baud = 9600;                         /* at another baud: garbage */
    io.write(io.ctx, q, sizeof q);
    FWT_CHECK_EQ(probe_all(&m, &p, &last), 0);
}

void suite_xbee(void)
{
    FWT_RUN(test_probe_finds_a_module_that_comes_later);
    FWT_RUN(test_factory_module_is_configured);
    FWT_RUN(test_configured_module_is_left_alone);
    FWT_RUN(test_transparent_module_at_115200);
    FWT_RUN(test_wrong_address_is_rewritten);
    FWT_RUN(test_no_module_times_out_in_bounds);
    FWT_RUN(test_error_answer_stops_before_writing);
    FWT_RUN(test_response_waits_end_at_their_deadlines);
    FWT_RUN(test_slow_reads_count_against_the_deadline);
    hal_set_ticks_hook(NULL, NULL);
}
