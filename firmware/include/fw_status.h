/**
 * @file fw_status.h
 * Status codes returned by every firmware function that can fail.
 * 0 is success; errors are negative so that callers can test `if (st < 0)`.
 */
#ifndef FW_STATUS_H
#define FW_STATUS_H

#include <stdint.h>

typedef int32_t fw_status_t;

#define FW_OK               0   /**< success */
#define FW_ERR_NACK        (-1) /**< IIC: address or data byte not acknowledged */
#define FW_ERR_TIMEOUT     (-2) /**< a bounded wait ran out (stuck bus, held SCL, device busy) */
#define FW_ERR_BUS_BUSY    (-3) /**< IIC: bus still busy before a transfer could start */
#define FW_ERR_ARBITRATION (-4) /**< IIC: arbitration lost (another master or a stuck SDA) */
#define FW_ERR_PARAM       (-5) /**< argument out of range */
#define FW_ERR_ID          (-6) /**< wrong chip / bitstream identification */
#define FW_ERR_NO_LOCK     (-7) /**< video decoder not locked to an input */
#define FW_ERR_RX          (-8) /**< IIC: receive FIFO empty when data was expected */
#define FW_ERR_RECT_ABSENT (-9) /**< the build has no rectifier for a rig that needs one */
#define FW_ERR_RECT_WARP  (-10) /**< the rig's warp needs more rows than the rectifier holds */
#define FW_ERR_RECT_MAP   (-11) /**< the rectifier's map is not the calibration's */

/** Short name of a status code, for logs ("OK", "NACK", ...). */
const char *fw_status_str(fw_status_t st);

#endif /* FW_STATUS_H */
