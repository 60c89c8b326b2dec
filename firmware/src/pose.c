/**
 * @file pose.c
 * Sequence-locked read of the motion controller's pose block (pose.h).
 */
#include "pose.h"
#include "hal.h"

static int16_t sat16(uint32_t raw)
{
    int32_t v = (int32_t)raw;
    if (v > 32767) {
        return 32767;
    }
    if (v < -32768) {
        return -32768;
    }
    return (int16_t)v;
}

fw_status_t pose_read(uint32_t base, pose_t *pose)
{
    uint32_t tries;
    if (pose == NULL) {
        return FW_ERR_PARAM;
    }
    for (tries = 0u; tries < POSE_MAX_TRIES; tries++) {
        uint32_t s1 = Xil_In32(base + POSE_SEQ_OFFSET);
        uint32_t x;
        uint32_t y;
        uint32_t th;
        uint32_t t;
        uint32_t st;
        if ((s1 & 1u) != 0u) {
            continue;                   /* the writer is in the middle of an update */
        }
        x = Xil_In32(base + POSE_X_MM_OFFSET);
        y = Xil_In32(base + POSE_Y_MM_OFFSET);
        th = Xil_In32(base + POSE_THETA_OFFSET);
        t = Xil_In32(base + POSE_T_MS_OFFSET);
        st = Xil_In32(base + POSE_STATUS_OFFSET);
        if (Xil_In32(base + POSE_SEQ_OFFSET) != s1) {
            continue;                   /* updated while we read: torn */
        }
        if ((st & POSE_STATUS_VALID) == 0u) {
            return FW_ERR_NO_LOCK;
        }
        pose->x_mm = sat16(x);
        pose->y_mm = sat16(y);
        pose->theta = (uint16_t)(th & 0xFFFFu);
        pose->t_ms = t;
        pose->status = st;
        return FW_OK;
    }
    return FW_ERR_TIMEOUT;
}
