/* The belt's inputs (inputs.c): buttons and battery; main.c provides send() and put16(). */
#ifndef BELT_INPUTS_H
#define BELT_INPUTS_H

#include <stdint.h>

void send(uint8_t type, const uint8_t *payload, uint8_t len); /* one frame to the host */
void put16(uint8_t *p, uint16_t v);                           /* little-endian */

static inline uint8_t reached(uint32_t now, uint32_t deadline)
{
    return (int32_t)(now - deadline) >= 0;
}

void inputs_init(void);
/* Every millisecond: debounce, press kinds, repeats and expiry, the battery's ADC. */
void inputs_tick(uint32_t now);
/* BUTTON_ACK: that press is no longer repeated (unknown numbers are ignored). */
void inputs_ack(uint16_t press);
/* The STATUS payload (STATUS_LEN bytes) with the intensity main.c applies. */
void inputs_status(uint8_t *p, uint8_t intensity);

#endif
