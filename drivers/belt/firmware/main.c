/* guidebelt haptic belt firmware: ATmega328P (Arduino Nano) at 16 MHz, avr-libc only.
 *
 * Four vibration motors on the hardware PWM pins, driven through transistors:
 *   front OC0A = PD6 (D6), right OC0B = PD5 (D5), back OC1A = PB1 (D9), left OC1B = PB2 (D10).
 * Timer0 and Timer1 (8-bit fast PWM) make the PWM; Timer2's OC2B pin PD3 is also INT1, and
 * simavr polls a low INT1 pin every cycle, so Timer2 keeps the clock instead.
 * UART 115200 8N1, interrupt-driven ring buffers both ways. Timer2 ticks every millisecond:
 * patterns (steady or pulsed), the frame's TTL, the 500 ms link watchdog and heartbeats.
 * The hardware watchdog resets the chip (motors off: pins float to inputs) if the main loop
 * ever hangs. Protocol: drivers/belt/PROTOCOL.md.
 * The buttons and the battery: inputs.c.
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <avr/wdt.h>
#include <util/atomic.h>

#include "frame.h"
#include "inputs.h"

#ifndef BAUD
#define BAUD 115200
#endif
#define BAUD_TOL 3
#include <util/setbaud.h>

#define LINK_WATCHDOG_MS 500u
#define BYTE_TIMEOUT_MS 50u
#define HEARTBEAT_MS 200u
#define STATUS_MS 1000u

/* ---- UART ring buffers (sizes are powers of two) ---- */
#define RX_SIZE 64u
#define TX_SIZE 128u
static volatile uint8_t rx_buf[RX_SIZE], rx_head, rx_tail;
static volatile uint8_t tx_buf[TX_SIZE], tx_head, tx_tail;

ISR(USART_RX_vect)
{
    uint8_t b = UDR0;
    uint8_t next = (uint8_t)((rx_head + 1) & (RX_SIZE - 1));
    if (next != rx_tail) { /* full: drop; the frame's CRC or timeout catches it */
        rx_buf[rx_head] = b;
        rx_head = next;
    }
}

ISR(USART_UDRE_vect)
{
    if (tx_tail == tx_head) {
        UCSR0B &= (uint8_t)~_BV(UDRIE0);
        return;
    }
    UDR0 = tx_buf[tx_tail];
    tx_tail = (uint8_t)((tx_tail + 1) & (TX_SIZE - 1));
}

static void uart_init(void)
{
    UBRR0H = UBRRH_VALUE;
    UBRR0L = UBRRL_VALUE;
#if USE_2X
    UCSR0A = _BV(U2X0);
#else
    UCSR0A = 0;
#endif
    UCSR0C = _BV(UCSZ01) | _BV(UCSZ00); /* 8N1 */
    UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
}

static void uart_write(const uint8_t *data, uint8_t len)
{
    while (len--) {
        uint8_t next = (uint8_t)((tx_head + 1) & (TX_SIZE - 1));
        while (next == tx_tail) /* full: wait for the UDRE interrupt to drain it */
            ;
        tx_buf[tx_head] = *data++;
        tx_head = next;
        UCSR0B |= _BV(UDRIE0);
    }
}

static int uart_read(void)
{
    if (rx_tail == rx_head)
        return -1;
    uint8_t b = rx_buf[rx_tail];
    rx_tail = (uint8_t)((rx_tail + 1) & (RX_SIZE - 1));
    return b;
}

/* ---- millisecond clock ---- */
static volatile uint32_t clock_ms;
static volatile uint8_t tick_pending;

ISR(TIMER2_COMPA_vect)
{
    clock_ms++;
    tick_pending = 1;
}

static uint32_t now_ms(void)
{
    uint32_t t;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { t = clock_ms; }
    return t;
}

/* ---- motors: 8-bit fast PWM on Timer0 and Timer1, clk/64 = 976 Hz ---- */
static void pwm_init(void)
{
    DDRD |= _BV(PD6) | _BV(PD5);
    DDRB |= _BV(PB1) | _BV(PB2);
    PORTD &= (uint8_t)~(_BV(PD6) | _BV(PD5));
    PORTB &= (uint8_t)~(_BV(PB1) | _BV(PB2));
    TCCR0A = _BV(WGM01) | _BV(WGM00);
    TCCR0B = _BV(CS01) | _BV(CS00);
    TCCR1A = _BV(WGM10);
    TCCR1B = _BV(WGM12) | _BV(CS11) | _BV(CS10);
}

/* Level 0 disconnects the pin from the timer (fast PWM would still give a 1/256 spike). */
static void motor_set(uint8_t motor, uint8_t level)
{
    switch (motor) {
    case 0:
        OCR0A = level;
        TCCR0A = level ? (TCCR0A | _BV(COM0A1)) : (TCCR0A & (uint8_t)~_BV(COM0A1));
        break;
    case 1:
        OCR0B = level;
        TCCR0A = level ? (TCCR0A | _BV(COM0B1)) : (TCCR0A & (uint8_t)~_BV(COM0B1));
        break;
    case 2:
        OCR1A = level;
        TCCR1A = level ? (TCCR1A | _BV(COM1A1)) : (TCCR1A & (uint8_t)~_BV(COM1A1));
        break;
    default:
        OCR1B = level;
        TCCR1A = level ? (TCCR1A | _BV(COM1B1)) : (TCCR1A & (uint8_t)~_BV(COM1B1));
        break;
    }
}

/* ---- belt state ---- */
static frame_parser_t parser;
static uint8_t state = STATE_BOOT;
static uint8_t pattern[4], output[4];
static uint16_t period_ms, last_seq, tx_seq, watchdog_trips;
static uint32_t pattern_start, ttl_deadline, last_valid, last_byte, next_heartbeat;
static uint32_t next_status;
static uint8_t intensity = INTENSITY_MAX;

void send(uint8_t type, const uint8_t *payload, uint8_t len)
{
    uint8_t out[FRAME_MAX];
    uint8_t n = frame_encode(out, type, tx_seq++, payload, len);
    uart_write(out, n);
}

void put16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)(v & 0xFF);
    p[1] = (uint8_t)(v >> 8);
}

static void send_heartbeat(uint32_t now)
{
    uint8_t p[HEARTBEAT_LEN];
    const frame_counters_t *c = &parser.count;
    p[0] = state;
    put16(p + 1, last_seq);
    for (uint8_t i = 0; i < 4; i++)
        p[3 + i] = output[i];
    put16(p + 7, c->rx_frames);
    put16(p + 9, c->crc_errors);
    put16(p + 11, c->oversized);
    put16(p + 13, c->truncated);
    put16(p + 15, c->malformed);
    put16(p + 17, watchdog_trips);
    put16(p + 19, (uint16_t)(now & 0xFFFF));
    put16(p + 21, (uint16_t)(now >> 16));
    send(TYPE_HEARTBEAT, p, HEARTBEAT_LEN);
}

static void send_status(void)
{
    uint8_t p[STATUS_LEN];
    inputs_status(p, intensity);
    send(TYPE_STATUS, p, STATUS_LEN);
}

static void ack(uint16_t seq, uint8_t result)
{
    uint8_t p[ACK_LEN] = {(uint8_t)(seq & 0xFF), (uint8_t)(seq >> 8), result};
    send(TYPE_ACK, p, ACK_LEN);
}

static uint8_t apply_pattern(const uint8_t *pl, uint32_t now)
{
    uint16_t period = (uint16_t)(pl[4] | (pl[5] << 8));
    uint16_t ttl = (uint16_t)(pl[6] | (pl[7] << 8));
    if (ttl < TTL_MIN_MS || ttl > TTL_MAX_MS || period > PERIOD_MAX_MS ||
        (period != 0 && period < 20))
        return 0;
    uint8_t same = state == STATE_ACTIVE && period == period_ms;
    for (uint8_t i = 0; i < 4; i++)
        same = same && pattern[i] == pl[i];
    if (!same) /* a repeat only refreshes the TTL: the pulse keeps its phase */
        pattern_start = now;
    for (uint8_t i = 0; i < 4; i++)
        pattern[i] = pl[i];
    period_ms = period;
    ttl_deadline = now + ttl;
    state = STATE_ACTIVE;
    return 1;
}

static void update_outputs(uint32_t now);

static void handle_frame(const uint8_t *f, uint32_t now)
{
    uint8_t type = f[2], len = f[3];
    uint16_t seq = (uint16_t)(f[4] | (f[5] << 8));
    uint8_t ok = 0;
    if (type == TYPE_PATTERN && len == PATTERN_LEN)
        ok = apply_pattern(f + FRAME_HEADER, now);
    else if (type == TYPE_STOP && len == 0) {
        state = STATE_STOPPED;
        ok = 1;
    } else if (type == TYPE_PING && len == 0)
        ok = 1;
    else if (type == TYPE_INTENSITY && len == INTENSITY_LEN && f[FRAME_HEADER] <= INTENSITY_MAX) {
        ok = 1;
        if (intensity != f[FRAME_HEADER]) {
            intensity = f[FRAME_HEADER];
            next_status = now; /* tell the host at the next tick */
        }
    } else if (type == TYPE_BUTTON_ACK && len == BUTTON_ACK_LEN) {
        inputs_ack((uint16_t)(f[FRAME_HEADER] | (f[FRAME_HEADER + 1] << 8)));
        ok = 1; /* a repeated ack, for a press already gone, is no error */
    }
    if (!ok) {
        parser.count.malformed++;
        ack(seq, ACK_REFUSED);
        return;
    }
    last_valid = now;
    last_seq = seq;
    update_outputs(now); /* at once, not at the next tick */
    ack(seq, ACK_APPLIED);
}

static void update_outputs(uint32_t now)
{
    if (state == STATE_ACTIVE && reached(now, ttl_deadline))
        state = STATE_IDLE;
    uint8_t on = state == STATE_ACTIVE;
    if (on && period_ms)
        on = ((now - pattern_start) % period_ms) < (uint16_t)(period_ms / 2);
    for (uint8_t i = 0; i < 4; i++) {
        uint8_t level = on ? frame_scale_level(pattern[i], intensity) : 0;
        if (level != output[i]) {
            output[i] = level;
            motor_set(i, level);
        }
    }
}

static void tick(uint32_t now)
{
    if (parser.n && reached(now, last_byte + BYTE_TIMEOUT_MS))
        frame_parser_timeout(&parser);
    if (state != STATE_BOOT && state != STATE_WATCHDOG &&
        reached(now, last_valid + LINK_WATCHDOG_MS)) {
        state = STATE_WATCHDOG;
        watchdog_trips++;
    }
    update_outputs(now);
    inputs_tick(now);
    if (reached(now, next_heartbeat)) {
        next_heartbeat = now + HEARTBEAT_MS;
        send_heartbeat(now);
    }
    if (reached(now, next_status)) {
        next_status = now + STATUS_MS;
        send_status();
    }
}

static void clock_init(void)
{
    TCCR2A = _BV(WGM21);                       /* CTC */
    TCCR2B = _BV(CS22);                        /* clk/64 */
    OCR2A = (uint8_t)(F_CPU / 64 / 1000 - 1); /* 1 kHz */
    TIMSK2 = _BV(OCIE2A);
}

int main(void)
{
    MCUSR = 0;
    wdt_enable(WDTO_500MS);
    pwm_init();
    inputs_init();
    uart_init();
    clock_init();
    frame_parser_init(&parser);
    set_sleep_mode(SLEEP_MODE_IDLE);
    sei();
    for (;;) {
        wdt_reset();
        int b;
        while ((b = uart_read()) >= 0) {
            uint32_t now = now_ms();
            last_byte = now;
            uint8_t len = frame_parser_feed(&parser, (uint8_t)b);
            while (len) {
                handle_frame(parser.buf, now);
                frame_parser_consume(&parser, len);
                len = frame_parser_poll(&parser);
            }
        }
        if (tick_pending) {
            tick_pending = 0;
            tick(now_ms());
        }
        cli();
        if (rx_tail == rx_head && !tick_pending) {
            sleep_enable();
            sei(); /* the instruction after sei runs before any interrupt: no lost wake-up */
            sleep_cpu();
            sleep_disable();
        }
        sei();
    }
}
