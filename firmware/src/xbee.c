/**
 * @file xbee.c
 * AT-command start-up of the XBee module (see xbee.h for the sequence and the bounds).
 */
#include "xbee.h"
#include "hal.h"
#include "radio.h"

#include <stddef.h>

/* Read one byte within XBEE_RESPONSE_US on the timer (hal_deadline_us), polling every
 * XBEE_POLL_US; XBEE_RESPONSE_POLLS polls end it too, the backstop for a clock that does not
 * advance (hal.h "Timeouts"). */
static int read_byte(const xbee_io_t *io, uint8_t *b)
{
    uint32_t deadline = hal_deadline_us(XBEE_RESPONSE_US);
    uint32_t polls;
    for (polls = 0u; polls < XBEE_RESPONSE_POLLS; polls++) {
        if (io->read(io->ctx, b) != 0) {
            return 1;
        }
        if (hal_expired(deadline)) {
            break;
        }
        io->delay_us(io->ctx, XBEE_POLL_US);
    }
    return 0;
}

static void drain(const xbee_io_t *io)
{
    uint8_t b;
    uint32_t n;
    for (n = 0u; n < 4096u && io->read(io->ctx, &b) != 0; n++) {
    }
}

static void write_str(const xbee_io_t *io, const char *s)
{
    uint32_t n = 0u;
    while (s[n] != '\0') {
        n++;
    }
    io->write(io->ctx, (const uint8_t *)s, n);
}

/* Command-mode response: characters up to '\r'; FW_OK only for exactly "OK". */
static fw_status_t expect_ok(const xbee_io_t *io)
{
    char line[8];
    uint32_t n = 0u;
    uint8_t b;
    for (;;) {
        if (!read_byte(io, &b)) {
            return FW_ERR_TIMEOUT;
        }
        if (b == '\r') {
            break;
        }
        if (n < sizeof line) {
            line[n] = (char)b;
        }
        n++;
    }
    return (n == 2u && line[0] == 'O' && line[1] == 'K') ? FW_OK : FW_ERR_RX;
}

/* Hexadecimal without leading zeros, as in the manual's examples (ATDL1F). Returns the
 * number of digits written (1..4). */
static uint32_t put_hex(char *p, uint16_t v)
{
    static const char digits[] = "0123456789ABCDEF";
    uint32_t n = 0u;
    int32_t shift;
    for (shift = 12; shift >= 0; shift -= 4) {
        uint32_t d = (v >> (uint32_t)shift) & 0xFu;
        if (d != 0u || n != 0u || shift == 0) {
            p[n++] = digits[d];
        }
    }
    return n;
}

/* "AT" + two letters + optional hex value + '\r', then "OK". */
static fw_status_t at_command(const xbee_io_t *io, const char *cmd, int has_value,
                              uint16_t value)
{
    char buf[10];
    uint32_t n = 0u;
    buf[n++] = 'A';
    buf[n++] = 'T';
    buf[n++] = cmd[0];
    buf[n++] = cmd[1];
    if (has_value) {
        n += put_hex(&buf[n], value);
    }
    buf[n++] = '\r';
    io->write(io->ctx, (const uint8_t *)buf, n);
    return expect_ok(io);
}

/* Receive one API frame (mode 2) into data (frame data, unescaped). Returns its length,
 * 0 on timeout or a bad frame. */
static uint32_t read_api_frame(const xbee_io_t *io, uint8_t *data, uint32_t cap)
{
    uint8_t b;
    uint8_t raw[3];
    uint32_t got = 0u;
    uint32_t len = 0u;
    uint32_t n = 0u;
    uint8_t sum = 0u;
    uint32_t skipped = 0u;
    do {                                     /* start delimiter */
        if (!read_byte(io, &b) || ++skipped > 64u) {
            return 0u;
        }
    } while (b != XBEE_START);
    for (;;) {
        if (!read_byte(io, &b) || b == XBEE_START) {
            return 0u;
        }
        if (b == XBEE_ESCAPE) {
            if (!read_byte(io, &b)) {
                return 0u;
            }
            b = (uint8_t)(b ^ XBEE_ESCAPE_XOR);
        }
        if (got < 2u) {
            raw[got++] = b;
            if (got == 2u) {
                len = ((uint32_t)raw[0] << 8) | raw[1];
                if (len == 0u || len > cap) {
                    return 0u;
                }
            }
        } else if (n < len) {
            data[n++] = b;
            sum = (uint8_t)(sum + b);
        } else {
            return (uint8_t)(sum + b) == 0xFFu ? len : 0u;
        }
    }
}

/* API-mode query of a 16-bit or 8-bit register; FW_OK and *value on a good answer. */
static fw_status_t api_query(const xbee_io_t *io, const char *cmd, uint16_t *value)
{
    uint8_t req[4];
    uint8_t frame[16];
    uint8_t resp[16];
    uint32_t n;
    uint32_t len;
    uint32_t tries;
    req[0] = XBEE_API_AT_COMMAND;
    req[1] = XBEE_AT_FRAME_ID;
    req[2] = (uint8_t)cmd[0];
    req[3] = (uint8_t)cmd[1];
    n = radio_encode_frame(req, 4u, frame, sizeof frame);
    io->write(io->ctx, frame, n);
    /* skip up to 4 other frames (a modem status after a reset, a late TX status) */
    for (tries = 0u; tries < 5u; tries++) {
        len = read_api_frame(io, resp, sizeof resp);
        if (len == 0u) {
            return FW_ERR_TIMEOUT;
        }
        if (resp[0] != XBEE_API_AT_RESPONSE) {
            continue;
        }
        if (len < 5u || len > 7u || resp[1] != XBEE_AT_FRAME_ID || resp[2] != req[2] ||
            resp[3] != req[3] || resp[4] != 0u) {
            return FW_ERR_RX;             /* not our answer, or status not OK */
        }
        *value = len == 5u ? 0u : (len == 6u ? resp[5] : (uint16_t)((resp[5] << 8) | resp[6]));
        return FW_OK;
    }
    return FW_ERR_RX;
}

static fw_status_t api_check(const xbee_io_t *io, const xbee_config_t *cfg)
{
    uint16_t v = 0u;
    fw_status_t st = api_query(io, "AP", &v);
    if (st != FW_OK) {
        return st;
    }
    if (v != 2u) {
        return FW_ERR_RX;
    }
    st = api_query(io, "MY", &v);
    if (st != FW_OK) {
        return st;
    }
    return v == cfg->my_addr ? FW_OK : FW_ERR_RX;
}

static fw_status_t enter_command_mode(const xbee_io_t *io, uint32_t baud)
{
    io->set_baud(io->ctx, baud);
    io->delay_us(io->ctx, XBEE_GUARD_US);   /* silence before "+++" */
    drain(io);
    write_str(io, "+++");
    io->delay_us(io->ctx, XBEE_GUARD_US);   /* silence after */
    return expect_ok(io);
}

fw_status_t xbee_configure(const xbee_io_t *io, const xbee_config_t *cfg,
                           xbee_result_t *result)
{
    static const uint32_t bauds[2] = { XBEE_FACTORY_BAUD, XBEE_LINK_BAUD };
    xbee_result_t local;
    fw_status_t st;
    uint32_t i;
    if (io == NULL || cfg == NULL || io->write == NULL || io->read == NULL ||
        io->set_baud == NULL || io->delay_us == NULL) {
        return FW_ERR_PARAM;
    }
    if (result == NULL) {
        result = &local;
    }
    result->was_configured = 0u;
    result->factory_baud = 0u;
    result->commands_ok = 0u;
    io->set_baud(io->ctx, XBEE_LINK_BAUD);
    drain(io);
    if (api_check(io, cfg) == FW_OK) {
        result->was_configured = 1u;
        return FW_OK;
    }
    st = FW_ERR_TIMEOUT;
    for (i = 0u; i < 2u && st != FW_OK; i++) {
        st = enter_command_mode(io, bauds[i]);
        if (st == FW_OK) {
            result->factory_baud = bauds[i];
        }
    }
    if (st != FW_OK) {
        return st;
    }
    {
        const struct { const char *cmd; int has_value; uint16_t value; } table[] = {
            { "AP", 1, 2u },                 /* API mode 2: escaped */
            { "BD", 1, XBEE_BD_LINK },       /* 115200 baud, applied at CN */
            { "MY", 1, cfg->my_addr },
            { "DL", 1, cfg->dest_addr },
            { "ID", 1, cfg->pan_id },
            { "WR", 0, 0u },                 /* keep it over a power cycle */
            { "CN", 0, 0u },                 /* leave command mode */
        };
        for (i = 0u; i < sizeof table / sizeof table[0]; i++) {
            st = at_command(io, table[i].cmd, table[i].has_value, table[i].value);
            if (st != FW_OK) {
                return st;
            }
            result->commands_ok++;
        }
    }
    io->set_baud(io->ctx, XBEE_LINK_BAUD);
    drain(io);
    return api_check(io, cfg);
}

/* The API frames of the probe: the AT query "AP" and the answer of a module in API mode 2
 * (AT Command Response, status OK, value 2). No byte needs escaping. */
static const uint8_t probe_query[XBEE_PROBE_QUERY_LEN] = {
    XBEE_START, 0x00u, 0x04u, XBEE_API_AT_COMMAND, XBEE_AT_FRAME_ID, 'A', 'P', 0x14u
};
static const uint8_t probe_answer[10] = {
    XBEE_START, 0x00u, 0x06u, XBEE_API_AT_RESPONSE, XBEE_AT_FRAME_ID, 'A', 'P', 0x00u, 0x02u,
    0x92u
};

void xbee_probe_query(uint8_t buf[XBEE_PROBE_QUERY_LEN])
{
    uint32_t i;
    for (i = 0u; i < XBEE_PROBE_QUERY_LEN; i++) {
        buf[i] = probe_query[i];
    }
}

int xbee_probe_feed(xbee_probe_t *probe, uint8_t byte)
{
    /* the start delimiter occurs only first: a mismatch starts over, at it if it is one */
    if (byte == probe_answer[probe->matched]) {
        probe->matched++;
    } else {
        probe->matched = (uint8_t)(byte == XBEE_START);
    }
    if (probe->matched == sizeof probe_answer) {
        probe->matched = 0u;
        return 1;
    }
    return 0;
}
