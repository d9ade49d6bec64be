/* Belt frame protocol: CRC, encoder and the resynchronising parser (see frame.h). */
#include "frame.h"

#include <string.h>

uint16_t frame_crc16(const uint8_t *data, uint8_t len)
{
    uint16_t crc = 0xFFFFu;
    while (len--) {
        crc ^= (uint16_t)(*data++) << 8;
        for (uint8_t bit = 0; bit < 8; bit++)
            crc = (crc & 0x8000u) ? (uint16_t)((crc << 1) ^ 0x1021u) : (uint16_t)(crc << 1);
    }
    return crc;
}

void frame_parser_init(frame_parser_t *p)
{
    memset(p, 0, sizeof(*p));
}

void frame_parser_consume(frame_parser_t *p, uint8_t len)
{
    if (len >= p->n) {
        p->n = 0;
        return;
    }
    memmove(p->buf, p->buf + len, p->n - len);
    p->n -= len;
}

/* Scan the buffer for the next complete frame. A frame that fails a check loses only
 * its start byte, so a real frame hidden behind garbage is still found. */
uint8_t frame_parser_poll(frame_parser_t *p)
{
    for (;;) {
        uint8_t skip = 0;
        while (skip < p->n && p->buf[skip] != FRAME_START)
            skip++;
        frame_parser_consume(p, skip);
        if (p->n < 2)
            return 0;
        if (p->buf[1] != FRAME_VERSION) {
            p->count.malformed++;
            frame_parser_consume(p, 1);
            continue;
        }
        if (p->n < 4)
            return 0;
        if (p->buf[3] > FRAME_MAX_PAYLOAD) {
            p->count.oversized++;
            frame_parser_consume(p, 1);
            continue;
        }
        uint8_t need = (uint8_t)(FRAME_HEADER + p->buf[3] + FRAME_CRC);
        if (p->n < need)
            return 0;
        uint16_t got = (uint16_t)((p->buf[need - 2] << 8) | p->buf[need - 1]);
        if (frame_crc16(p->buf + 1, (uint8_t)(need - 3)) != got) {
            p->count.crc_errors++;
            frame_parser_consume(p, 1);
            continue;
        }
        p->count.rx_frames++;
        return need;
    }
}

uint8_t frame_parser_feed(frame_parser_t *p, uint8_t byte)
{
    if (p->n == 0 && byte != FRAME_START)
        return 0; /* noise between frames */
    p->buf[p->n++] = byte; /* scan keeps n below FRAME_MAX between calls */
    return frame_parser_poll(p);
}

void frame_parser_timeout(frame_parser_t *p)
{
    if (p->n) {
        p->count.truncated++;
        p->n = 0;
    }
}

uint8_t frame_encode(uint8_t *out, uint8_t type, uint16_t seq, const uint8_t *payload,
                     uint8_t len)
{
    out[0] = FRAME_START;
    out[1] = FRAME_VERSION;
    out[2] = type;
    out[3] = len;
    out[4] = (uint8_t)(seq & 0xFF);
    out[5] = (uint8_t)(seq >> 8);
    if (len)
        memcpy(out + FRAME_HEADER, payload, len);
    uint8_t n = (uint8_t)(FRAME_HEADER + len);
    uint16_t crc = frame_crc16(out + 1, (uint8_t)(n - 1));
    out[n] = (uint8_t)(crc >> 8);
    out[n + 1] = (uint8_t)(crc & 0xFF);
    return (uint8_t)(n + FRAME_CRC);
}

uint8_t frame_scale_level(uint8_t level, uint8_t intensity)
{
    if (intensity > INTENSITY_MAX)
        intensity = INTENSITY_MAX;
    uint16_t pct = (uint16_t)(INTENSITY_FLOOR_PCT +
                              (INTENSITY_MAX - INTENSITY_FLOOR_PCT) * intensity / INTENSITY_MAX);
    uint8_t out = (uint8_t)(((uint16_t)level * pct + 50u) / 100u);
    return (level && !out) ? 1u : out; /* a motor that is on stays on */
}
