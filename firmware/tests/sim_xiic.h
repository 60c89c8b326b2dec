/**
 * @file sim_xiic.h
 * Host model of the AXI IIC controller in dynamic mode (the register subset of xiic_l.h)
 * with I2C devices on its bus, installed as the HAL bus hook. Transaction level: each bus
 * access lets the controller process one TX FIFO word, so the firmware sees the FIFO drain
 * and the bus busy flag as on hardware. Devices can NACK, hold SCL low (the controller then
 * stalls for good, as a real one waiting for SCL), or be busy (NACK) for a number of
 * addressings after a soft reset. A small register-block model answers at STEREO_BASEADDR.
 */
#ifndef SIM_XIIC_H
#define SIM_XIIC_H

#include <stdint.h>

#define SIM_MAX_DEVS 4

typedef struct {
    uint8_t addr7;
    uint8_t regs[256];
    uint8_t written[256];     /**< 1 where the master wrote */
    uint8_t ptr;
    int nack;                 /**< 1: never acknowledge */
    int hold_scl;             /**< 1: hold SCL low once addressed */
    int adv7180;              /**< 1: PWR_MAN bit 7 resets the register file */
    int busy_after_reset;     /**< addressings to NACK after a reset */
    int busy;                 /**< remaining NACKs */
    uint32_t writes;          /**< data bytes written since the last reset */
    uint32_t fail_after;      /**< >0: NACK every addressing once `writes` reaches it */
} sim_dev_t;

typedef struct {
    uint32_t base;
    uint32_t cr, isr, rfd;
    uint16_t tx[16];
    uint32_t tx_n;
    uint8_t rx[16];
    uint32_t rx_n;
    int bus_busy;
    int stuck;                /**< a device holds SCL low */
    sim_dev_t *cur;           /**< addressed device */
    int reading;              /**< addressed for read */
    int need_count;           /**< next TX word is a read byte count */
    int first_byte;           /**< next written byte is the register pointer */
    sim_dev_t devs[SIM_MAX_DEVS];
    int n_devs;
    uint32_t accesses;
    uint32_t delays_us;
    uint32_t ticks_per_access;   /**< sim_clock: core cycles a bus access costs */
    uint32_t ticks_base;         /**< sim_clock: the ticks hook's count at 0 accesses */
    uint32_t regfile[64];     /**< register block model (RW, no side effects) */
    uint32_t result_fifo[256];   /**< RESULT words of the queued records */
    uint32_t result_ext[256];    /**< their RESULT_EXT words */
    uint32_t result_n, result_head;
    uint32_t result_ext_last;    /**< RESULT_EXT: of the record the last RESULT read popped */
    uint8_t uart[512];
    uint32_t uart_n;
} sim_xiic_t;

void sim_init(sim_xiic_t *s, uint32_t base);
sim_dev_t *sim_add_dev(sim_xiic_t *s, uint8_t addr7);
sim_dev_t *sim_add_adv7180(sim_xiic_t *s, uint8_t addr7);
/** Install s as the HAL bus hook (and no ticks hook: polls take no time). */
void sim_install(sim_xiic_t *s);
void sim_uninstall(void);
/** From now on every bus access costs ticks_per_access core cycles on the HAL's clock
 *  (hal_set_ticks_hook), which reads `start` now: a modelled poll cost, so that a wait's
 *  deadline passes while it polls. */
void sim_clock(sim_xiic_t *s, uint32_t ticks_per_access, uint32_t start);

#endif /* SIM_XIIC_H */
