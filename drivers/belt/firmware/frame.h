/* Belt frame protocol (drivers/belt/PROTOCOL.md): constants, CRC, incremental parser.
 *
 * Portable C99 with no AVR headers, so the host test compiles exactly this code against
 * the byte-exact vectors in drivers/belt/vectors.json. drivers/belt/frames.py mirrors it.
 */
#ifndef BELT_FRAME_H
#define BELT_FRAME_H

#include <stdint.h>

#define FRAME_START 0xA5u
#define FRAME_VERSION 0x01u
#define FRAME_HEADER 6u /* start, version, type, len, seq (u16 LE) */
#define FRAME_MAX_PAYLOAD 24u
#define FRAME_CRC 2u
#define FRAME_MAX (FRAME_HEADER + FRAME_MAX_PAYLOAD + FRAME_CRC)

/* host -> belt */
#define TYPE_PATTERN 0x01u
#define TYPE_STOP 0x02u
#define TYPE_PING 0x03u
#define TYPE_INTENSITY 0x04u  /* the user's intensity, 0..100 */
#define TYPE_BUTTON_ACK 0x05u /* the host has a press: stop repeating it */
/* belt -> host */
#define TYPE_ACK 0x81u
#define TYPE_HEARTBEAT 0x82u
#define TYPE_BUTTON 0x83u /* a debounced press, repeated until acknowledged */
#define TYPE_STATUS 0x84u /* battery, intensity, presses: every second */

#define PATTERN_LEN 8u
#define ACK_LEN 3u
#define HEARTBEAT_LEN 23u
#define INTENSITY_LEN 1u
#define BUTTON_ACK_LEN 2u
#define BUTTON_LEN 4u
#define STATUS_LEN 8u

#define INTENSITY_MAX 100u
/* Intensity scales every motor level by FLOOR..100 %, never below the floor: a pattern's
 * shape (which motors, which period) is what tells events apart, and it stays felt. */
#define INTENSITY_FLOOR_PCT 40u

#define BUTTON_SHORT 1u
#define BUTTON_LONG 2u

#define TTL_MIN_MS 50u
#define TTL_MAX_MS 5000u
#define PERIOD_MAX_MS 5000u

/* ACK result codes */
#define ACK_APPLIED 0u
#define ACK_REFUSED 1u /* CRC fine but the content is not a valid command */

/* heartbeat states */
#define STATE_BOOT 0u     /* no valid frame since reset */
#define STATE_ACTIVE 1u   /* a pattern is running */
#define STATE_IDLE 2u     /* the pattern's own TTL ran out */
#define STATE_WATCHDOG 3u /* no valid frame for 500 ms: every motor off */
#define STATE_STOPPED 4u  /* a STOP frame: every motor off until the next pattern */

typedef struct {
    uint16_t rx_frames;  /* frames with a good CRC */
    uint16_t crc_errors;
    uint16_t oversized;  /* LEN above FRAME_MAX_PAYLOAD */
    uint16_t truncated;  /* a frame started, then the line went quiet */
    uint16_t malformed;  /* bad version, unknown type, wrong LEN for the type, bad values */
} frame_counters_t;

typedef struct {
    uint8_t buf[FRAME_MAX];
    uint8_t n;
    frame_counters_t count;
} frame_parser_t;

/* CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no final xor. */
uint16_t frame_crc16(const uint8_t *data, uint8_t len);

void frame_parser_init(frame_parser_t *p);

/* Feed one received byte. Returns the total length of a complete frame with a good CRC,
 * now at p->buf[0..len), or 0. Call frame_parser_consume(p, len) once it is handled. */
uint8_t frame_parser_feed(frame_parser_t *p, uint8_t byte);
void frame_parser_consume(frame_parser_t *p, uint8_t len);
/* After a consume: the next complete frame already buffered (behind a bad one), or 0. */
uint8_t frame_parser_poll(frame_parser_t *p);

/* The line was quiet past the inter-byte timeout: a partial frame is counted and dropped. */
void frame_parser_timeout(frame_parser_t *p);

/* A motor level as the firmware drives it at the user's intensity (0..100): scaled by
 * INTENSITY_FLOOR_PCT + (100 - INTENSITY_FLOOR_PCT) * intensity / 100 percent, rounded half
 * up. 0 stays 0 and any other level at least 1; a ratio between two motors (a GUIDE direction) is kept to rounding. */
uint8_t frame_scale_level(uint8_t level, uint8_t intensity);

/* Writes a whole frame into out (FRAME_MAX bytes); returns its length. */
uint8_t frame_encode(uint8_t *out, uint8_t type, uint16_t seq, const uint8_t *payload,
                     uint8_t len);

#endif
