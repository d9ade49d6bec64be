/* Host-side check of frame.c against drivers/belt/vectors.json (driven by tests/belt).
 *
 * Reads commands on stdin, one per line, and answers on stdout:
 *   C HEX             -> "crc XXXX"                       CRC-16 of the bytes
 *   E TYPE SEQ HEX    -> "frame HEX"                      frame_encode()
 *   S LEVEL INTENSITY -> "level N"                        frame_scale_level()
 *   P HEX TIMEOUT     -> "frame TYPE SEQ HEX" per frame, then
 *                        "counters RX CRC OVERSIZED TRUNCATED MALFORMED"
 * HEX may be "-" for no bytes. Built with the host compiler: cc -o frame_check frame_check.c frame.c
 */
#include <stdio.h>
#include <string.h>

#include "frame.h"

static int unhex(const char *s, uint8_t *out, int max)
{
    if (strcmp(s, "-") == 0)
        return 0;
    int n = 0;
    unsigned v;
    while (s[0] && s[1] && n < max && sscanf(s, "%2x", &v) == 1) {
        out[n++] = (uint8_t)v;
        s += 2;
    }
    return n;
}

static void puthex(const uint8_t *b, int n)
{
    if (!n)
        fputs("-", stdout);
    for (int i = 0; i < n; i++)
        printf("%02x", b[i]);
}

int main(void)
{
    char line[4096], hex[4000];
    uint8_t data[2000];
    while (fgets(line, sizeof(line), stdin)) {
        unsigned type, seq, level, intensity;
        int timeout;
        if (sscanf(line, "C %3999s", hex) == 1) {
            int n = unhex(hex, data, sizeof(data));
            printf("crc %04x\n", frame_crc16(data, (uint8_t)n));
        } else if (sscanf(line, "S %u %u", &level, &intensity) == 2) {
            printf("level %u\n", frame_scale_level((uint8_t)level, (uint8_t)intensity));
        } else if (sscanf(line, "E %u %u %3999s", &type, &seq, hex) == 3) {
            uint8_t out[FRAME_MAX];
            int n = unhex(hex, data, FRAME_MAX_PAYLOAD);
            printf("frame ");
            puthex(out, frame_encode(out, (uint8_t)type, (uint16_t)seq, data, (uint8_t)n));
            printf("\n");
        } else if (sscanf(line, "P %3999s %d", hex, &timeout) == 2) {
            frame_parser_t p;
            frame_parser_init(&p);
            int n = unhex(hex, data, sizeof(data));
            for (int i = 0; i < n; i++) {
                uint8_t len = frame_parser_feed(&p, data[i]);
                while (len) {
                    printf("frame %u %u ", p.buf[2], (unsigned)(p.buf[4] | (p.buf[5] << 8)));
                    puthex(p.buf + FRAME_HEADER, p.buf[3]);
                    printf("\n");
                    frame_parser_consume(&p, len);
                    len = frame_parser_poll(&p);
                }
            }
            if (timeout)
                frame_parser_timeout(&p);
            printf("counters %u %u %u %u %u\n", p.count.rx_frames, p.count.crc_errors,
                   p.count.oversized, p.count.truncated, p.count.malformed);
        }
        fflush(stdout);
    }
    return 0;
}
