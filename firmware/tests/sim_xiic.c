/**
 * @file sim_xiic.c
 * Host model of the AXI IIC controller (dynamic mode) and its I2C devices; see sim_xiic.h.
 */
#include "sim_xiic.h"

#include <string.h>

#include "hal.h"
#include "stereo_regs.h"
#include "xiic_l.h"

void sim_init(sim_xiic_t *s, uint32_t base)
{
    memset(s, 0, sizeof *s);
    s->base = base;
    s->regfile[STEREO_GROUND_OFFSET / 4u] = STEREO_GROUND_RESET;
}

sim_dev_t *sim_add_dev(sim_xiic_t *s, uint8_t addr7)
{
    sim_dev_t *d = &s->devs[s->n_devs++];
    memset(d, 0, sizeof *d);
    d->addr7 = addr7;
    return d;
}

static void adv7180_defaults(sim_dev_t *d)
{
    memset(d->regs, 0, sizeof d->regs);
    d->regs[0x03] = 0x0C; /* OUTPUT_CONTROL reset value */
    d->regs[0x07] = 0x7F; /* AUTODETECT_ENABLE reset value */
    d->regs[0x10] = 0x05; /* STATUS1: in lock, FSC lock, NTSC-M */
    d->regs[0x11] = 0x18; /* IDENT: ADV7180 */
}

sim_dev_t *sim_add_adv7180(sim_xiic_t *s, uint8_t addr7)
{
    sim_dev_t *d = sim_add_dev(s, addr7);
    d->adv7180 = 1;
    d->busy_after_reset = 2;
    adv7180_defaults(d);
    return d;
}

static sim_dev_t *find_dev(sim_xiic_t *s, uint8_t addr7)
{
    int i;
    for (i = 0; i < s->n_devs; i++) {
        if (s->devs[i].addr7 == addr7) {
            return &s->devs[i];
        }
    }
    return NULL;
}

static void bus_stop(sim_xiic_t *s)
{
    s->bus_busy = 0;
    s->cur = NULL;
    s->reading = 0;
    s->need_count = 0;
}

static void dev_write(sim_dev_t *d, uint8_t byte)
{
    d->regs[d->ptr] = byte;
    d->written[d->ptr] = 1u;
    d->writes++;
    if (d->adv7180 && d->ptr == 0x0Fu && (byte & 0x80u) != 0u) {
        adv7180_defaults(d);            /* RES: every register back to its reset value */
        memset(d->written, 0, sizeof d->written);
        d->writes = 0u;
        d->busy = d->busy_after_reset;  /* and no answer for a while */
    }
    d->ptr++;
}

/* Process one TX FIFO word. */
static void step(sim_xiic_t *s)
{
    uint16_t w;
    uint8_t byte;
    if ((s->cr & XIIC_CR_ENABLE_DEVICE_MASK) == 0u || s->stuck || s->tx_n == 0u) {
        return;
    }
    w = s->tx[0];
    memmove(&s->tx[0], &s->tx[1], (s->tx_n - 1u) * sizeof s->tx[0]);
    s->tx_n--;
    byte = (uint8_t)(w & 0xFFu);
    if ((w & XIIC_TX_DYN_START_MASK) != 0u) {
        sim_dev_t *d = find_dev(s, (uint8_t)(byte >> 1));
        s->bus_busy = 1;
        if (d == NULL || d->nack || d->busy > 0 ||
            (d->fail_after > 0u && d->writes >= d->fail_after)) {
            if (d != NULL && d->busy > 0) {
                d->busy--;
            }
            s->isr |= XIIC_INTR_TX_ERROR_MASK;  /* NACK: flush, STOP */
            s->tx_n = 0u;
            bus_stop(s);
            return;
        }
        s->cur = d;
        if (d->hold_scl) {
            s->stuck = 1;                       /* SCL held low: nothing moves any more */
            return;
        }
        s->reading = (byte & 1u) != 0u;
        s->need_count = s->reading;
        s->first_byte = !s->reading;
    } else if (s->cur == NULL) {
        s->isr |= XIIC_INTR_TX_ERROR_MASK;      /* data without an addressed device */
        return;
    } else if (s->need_count) {
        uint32_t i;
        for (i = 0u; i < byte && s->rx_n < 16u; i++) {
            s->rx[s->rx_n++] = s->cur->regs[s->cur->ptr++];
        }
        s->need_count = 0;
    } else if (s->first_byte) {
        s->cur->ptr = byte;
        s->first_byte = 0;
    } else {
        dev_write(s->cur, byte);
    }
    if ((w & XIIC_TX_DYN_STOP_MASK) != 0u) {
        bus_stop(s);
    }
}

static void controller_reset(sim_xiic_t *s)
{
    s->cr = 0u;
    s->isr = 0u;
    s->rfd = 0u;
    s->tx_n = 0u;
    s->rx_n = 0u;
    if (!s->stuck) {
        bus_stop(s);
    }
}

static uint32_t regblock_read(sim_xiic_t *s, uint32_t off)
{
    switch (off) {
    case STEREO_ID_OFFSET:
        return STEREO_ID_RESET;
    case STEREO_CTRL_OFFSET:
        return 0u;
    case STEREO_RESULT_OFFSET:
        if (s->result_head < s->result_n) {
            s->result_ext_last = s->result_ext[s->result_head];
            return s->result_fifo[s->result_head++];
        }
        s->result_ext_last = 0u;
        return 0u;
    case STEREO_RESULT_EXT_OFFSET:
        return s->result_ext_last;
    case STEREO_RESULT_LEVEL_OFFSET:
        return s->result_n - s->result_head;
    default:
        return off < 0x100u ? s->regfile[off / 4u] : 0u;
    }
}

static void regblock_write(sim_xiic_t *s, uint32_t off, uint32_t v)
{
    if (off == STEREO_CTRL_OFFSET) {
        if ((v & STEREO_CTRL_FLUSH_RESULTS_MASK) != 0u) {
            s->result_head = s->result_n;
        }
    } else if ((off >= STEREO_GROUND_OFFSET && off < STEREO_FRAME_COUNT_OFFSET) ||
               off == STEREO_FLOOR_OFFSET || off == STEREO_FLOOR_LINE_OFFSET) {
        /* the parameter registers: everything between CTRL and the status block, and the
         * floor's */
        s->regfile[off / 4u] = v;
    }
}

static uint32_t sim_read(void *ctx, uint32_t addr)
{
    sim_xiic_t *s = ctx;
    uint32_t off = addr - s->base;
    uint32_t v = 0u;
    s->accesses++;
    if (addr >= STEREO_BASEADDR && addr < STEREO_BASEADDR + 0x100u) {
        return regblock_read(s, addr - STEREO_BASEADDR);
    }
    step(s);
    switch (off) {
    case XIIC_IISR_OFFSET: v = s->isr; break;
    case XIIC_CR_REG_OFFSET: v = s->cr; break;
    case XIIC_SR_REG_OFFSET:
        v = ((s->bus_busy || s->stuck) ? XIIC_SR_BUS_BUSY_MASK : 0u) |
            (s->reading ? XIIC_SR_MSTR_RDING_SLAVE_MASK : 0u) |
            (s->tx_n == 16u ? XIIC_SR_TX_FIFO_FULL_MASK : 0u) |
            (s->rx_n == 16u ? XIIC_SR_RX_FIFO_FULL_MASK : 0u) |
            (s->rx_n == 0u ? XIIC_SR_RX_FIFO_EMPTY_MASK : 0u) |
            (s->tx_n == 0u ? XIIC_SR_TX_FIFO_EMPTY_MASK : 0u);
        break;
    case XIIC_DRR_REG_OFFSET:
        if (s->rx_n > 0u) {
            v = s->rx[0];
            memmove(&s->rx[0], &s->rx[1], --s->rx_n);
        }
        break;
    case XIIC_TFO_REG_OFFSET: v = s->tx_n ? s->tx_n - 1u : 0u; break;
    case XIIC_RFO_REG_OFFSET: v = s->rx_n ? s->rx_n - 1u : 0u; break;
    case XIIC_RFD_REG_OFFSET: v = s->rfd; break;
    default: break;
    }
    return v;
}

static void sim_write(void *ctx, uint32_t addr, uint32_t v)
{
    sim_xiic_t *s = ctx;
    uint32_t off = addr - s->base;
    s->accesses++;
    if (addr >= STEREO_BASEADDR && addr < STEREO_BASEADDR + 0x100u) {
        regblock_write(s, addr - STEREO_BASEADDR, v);
        return;
    }
    switch (off) {
    case XIIC_RESETR_OFFSET:
        if (v == XIIC_RESET_MASK) {
            controller_reset(s);
        }
        break;
    case XIIC_IISR_OFFSET: s->isr ^= v & 0xFFu; break;
    case XIIC_CR_REG_OFFSET:
        s->cr = v & 0x7Fu;
        if ((v & XIIC_CR_TX_FIFO_RESET_MASK) != 0u) {
            s->tx_n = 0u;
        }
        break;
    case XIIC_DTR_REG_OFFSET:
        if (s->tx_n < 16u) {
            s->tx[s->tx_n++] = (uint16_t)(v & 0x3FFu);
        }
        break;
    case XIIC_RFD_REG_OFFSET: s->rfd = v & 0xFu; break;
    default: break;
    }
    step(s);
}

static void sim_delay(void *ctx, uint32_t us)
{
    sim_xiic_t *s = ctx;
    s->delays_us += us;
}

static void sim_uart(void *ctx, const uint8_t *data, uint32_t len)
{
    sim_xiic_t *s = ctx;
    uint32_t i;
    for (i = 0u; i < len && s->uart_n < sizeof s->uart; i++) {
        s->uart[s->uart_n++] = data[i];
    }
}

void sim_install(sim_xiic_t *s)
{
    hal_set_bus_hook(sim_read, sim_write, sim_delay, sim_uart, s);
    hal_set_ticks_hook(NULL, NULL);
}

void sim_uninstall(void)
{
    hal_set_bus_hook(NULL, NULL, NULL, NULL, NULL);
    hal_set_ticks_hook(NULL, NULL);
}

static uint32_t sim_ticks(void *ctx)
{
    sim_xiic_t *s = ctx;
    return s->ticks_base + s->accesses * s->ticks_per_access;
}

void sim_clock(sim_xiic_t *s, uint32_t ticks_per_access, uint32_t start)
{
    uint32_t delays;
    hal_set_ticks_hook(NULL, NULL);
    delays = hal_ticks();                    /* the delays' share of hal_ticks */
    s->ticks_per_access = ticks_per_access;
    s->ticks_base = start - delays - s->accesses * ticks_per_access;
    hal_set_ticks_hook(sim_ticks, s);
}
