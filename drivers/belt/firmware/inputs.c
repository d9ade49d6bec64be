/* The belt's inputs: three push buttons and the battery (drivers/belt/PROTOCOL.md).
 *
 * Buttons to ground (internal pull-ups): D4 = PD4, D7 = PD7, D8 = PB0, sampled every
 * millisecond, debounced (20 ms), reported as short (at release) or long (at 800 ms, while
 * still held) presses, each repeated every 100 ms until the host acknowledges it, for at most
 * 2 s. The battery through a 1:2 divider on A0 (ADC0, AVcc = 5 V reference), read every
 * 100 ms into a running mean.
 */
#include "inputs.h"

#include <avr/io.h>

#include "frame.h"

#define DEBOUNCE_MS 20u
#define LONG_PRESS_MS 800u
#define BUTTON_RESEND_MS 100u
#define BUTTON_EXPIRE_MS 2000u /* a press older than this means nothing any more */
#define BUTTON_QUEUE 4u
#define NBUTTONS 3u
#define BATTERY_MS 100u
#define AVCC_MV 5000u
#define DIVIDER 2u /* battery -> 2 x 10 kOhm -> A0 */

/* ---- buttons: debounced in the millisecond tick ---- */
typedef struct {
    uint8_t raw, stable, long_sent;
    uint32_t changed_at, pressed_at;
} button_t;

typedef struct {
    uint16_t press;
    uint8_t button, kind;
    uint32_t at, sent;
} press_t;

static button_t buttons[NBUTTONS];
static press_t pending[BUTTON_QUEUE];
static uint8_t npending;
static uint16_t presses, presses_dropped;
static uint16_t battery_mv;
static uint32_t next_battery;

void inputs_status(uint8_t *p, uint8_t intensity)
{
    put16(p, battery_mv);
    p[2] = intensity;
    p[3] = npending;
    put16(p + 4, presses);
    put16(p + 6, presses_dropped);
}

static void send_press(press_t *q, uint32_t now)
{
    uint8_t p[BUTTON_LEN];
    put16(p, q->press);
    p[2] = q->button;
    p[3] = q->kind;
    send(TYPE_BUTTON, p, BUTTON_LEN);
    q->sent = now;
}

static void drop_pending(uint8_t i)
{
    for (; i + 1u < npending; i++)
        pending[i] = pending[i + 1u];
    npending--;
}

static void queue_press(uint8_t button, uint8_t kind, uint32_t now)
{
    if (++presses == 0) /* 0 is never a press number */
        presses = 1;
    if (npending == BUTTON_QUEUE) { /* the host hears none of them: this one is lost */
        presses_dropped++;
        return;
    }
    press_t *q = &pending[npending++];
    q->press = presses;
    q->button = button;
    q->kind = kind;
    q->at = now;
    send_press(q, now);
}

void inputs_ack(uint16_t press)
{
    for (uint8_t i = 0; i < npending; i++)
        if (pending[i].press == press) {
            drop_pending(i);
            return;
        }
}

static void buttons_init(void)
{
    DDRD &= (uint8_t)~(_BV(PD4) | _BV(PD7));
    PORTD |= _BV(PD4) | _BV(PD7); /* pull-ups: a button pulls its pin to ground */
    DDRB &= (uint8_t)~_BV(PB0);
    PORTB |= _BV(PB0);
}

static uint8_t button_down(uint8_t i)
{
    switch (i) {
    case 0:
        return !(PIND & _BV(PD4));
    case 1:
        return !(PIND & _BV(PD7));
    default:
        return !(PINB & _BV(PB0));
    }
}

static void buttons_tick(uint32_t now)
{
    for (uint8_t i = 0; i < NBUTTONS; i++) {
        button_t *b = &buttons[i];
        uint8_t raw = button_down(i);
        if (raw != b->raw) {
            b->raw = raw;
            b->changed_at = now;
        }
        if (raw != b->stable && reached(now, b->changed_at + DEBOUNCE_MS)) {
            b->stable = raw;
            if (raw) {
                b->pressed_at = now;
                b->long_sent = 0;
            } else if (!b->long_sent) {
                queue_press(i, BUTTON_SHORT, now);
            }
        }
        if (b->stable && !b->long_sent && reached(now, b->pressed_at + LONG_PRESS_MS)) {
            b->long_sent = 1;
            queue_press(i, BUTTON_LONG, now);
        }
    }
    for (uint8_t i = 0; i < npending;) {
        if (reached(now, pending[i].at + BUTTON_EXPIRE_MS)) {
            presses_dropped++;
            drop_pending(i);
            continue;
        }
        if (reached(now, pending[i].sent + BUTTON_RESEND_MS))
            send_press(&pending[i], now);
        i++;
    }
}

/* ---- battery on ADC0 ---- */
static void adc_init(void)
{
    ADMUX = _BV(REFS0);                                     /* AVcc reference, ADC0 */
    ADCSRA = _BV(ADEN) | _BV(ADPS2) | _BV(ADPS1) | _BV(ADPS0); /* 125 kHz ADC clock */
    DIDR0 = _BV(ADC0D);
    ADCSRA |= _BV(ADSC);
}

static void battery_tick(uint32_t now)
{
    if (!reached(now, next_battery) || (ADCSRA & _BV(ADSC)))
        return;
    next_battery = now + BATTERY_MS;
    uint16_t mv = (uint16_t)((uint32_t)ADC * AVCC_MV * DIVIDER / 1024u);
    /* A running mean over about four readings: a motor's current dip is not a low battery. */
    battery_mv = battery_mv ? (uint16_t)((3u * (uint32_t)battery_mv + mv) / 4u) : mv;
    ADCSRA |= _BV(ADSC);
}

void inputs_init(void)
{
    buttons_init();
    adc_init();
}

void inputs_tick(uint32_t now)
{
    buttons_tick(now);
    battery_tick(now);
}
