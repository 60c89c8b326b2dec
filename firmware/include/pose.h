/**
 * @file pose.h
 * The robot's pose, read from the register block the motion controller writes.
 *
 * Why a register block and not odometry in the FPGA: the seed's robot has wheel encoders, a
 * GPS and a compass, and its motion controller already fuses them to steer; the vision
 * module only needs the result, stamped with the time it was taken. A mailbox of six 32-bit
 * words that the motion controller writes (over whatever bus bridges it to the MCS I/O bus)
 * keeps the pose in one place, costs the FPGA no encoder pins or odometry logic, and gives
 * the radio packet the fused pose (GPS and compass included) rather than raw wheel odometry.
 *
 * Consistency: the writer increments SEQ before (SEQ becomes odd) and after (even) each
 * update. pose_read() takes a snapshot only when SEQ is even and unchanged across the read
 * (a sequence lock), retrying at most POSE_MAX_TRIES times.
 *
 *   offset  register  contents
 *   0x00    SEQ       update counter (odd while the writer is updating)
 *   0x04    X_MM      x in millimetres (int32)
 *   0x08    Y_MM      y in millimetres (int32)
 *   0x0C    THETA     heading, bits 15:0, 65536 units per turn (0 = +x, counter-clockwise)
 *   0x10    T_MS      motion controller's clock when the pose was taken (ms, wraps)
 *   0x14    STATUS    bit 0 pose valid, bit 1 GPS fix, bit 2 compass valid
 */
#ifndef POSE_H
#define POSE_H

#include <stdint.h>
#include "fw_status.h"

#define POSE_BASEADDR        0xC0040000u  /**< the motion controller's mailbox: outside the SoC's 0xC0000000-0xC003FFFF window (registers, IIC, UART) */
#define POSE_SEQ_OFFSET      0x00u
#define POSE_X_MM_OFFSET     0x04u
#define POSE_Y_MM_OFFSET     0x08u
#define POSE_THETA_OFFSET    0x0Cu
#define POSE_T_MS_OFFSET     0x10u
#define POSE_STATUS_OFFSET   0x14u
#define POSE_STATUS_VALID    0x01u
#define POSE_STATUS_GPS      0x02u
#define POSE_STATUS_COMPASS  0x04u
#define POSE_MAX_TRIES       8u

typedef struct {
    int16_t x_mm;        /**< saturated to the radio's int16 range */
    int16_t y_mm;
    uint16_t theta;
    uint32_t t_ms;
    uint32_t status;
} pose_t;

/** Consistent snapshot of the pose block at base. FW_OK; FW_ERR_TIMEOUT if the writer kept
 *  it changing for POSE_MAX_TRIES reads; FW_ERR_NO_LOCK if the pose is not valid yet. *pose
 *  is written only on FW_OK. */
fw_status_t pose_read(uint32_t base, pose_t *pose);

#endif /* POSE_H */
