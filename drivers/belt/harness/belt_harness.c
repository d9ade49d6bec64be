/* Hardware in the loop without the hardware: the belt firmware on a simulated ATmega328P.
 *
 *   belt-harness FIRMWARE.elf [--link PATH]
 *
 * libsimavr runs the ELF at 16 MHz, paced to the wall clock; simavr's uart_pty part bridges
 * UART0 to a pseudo-terminal that the driver opens exactly like /dev/ttyUSB0. Lines on
 * stdout (one event each, flushed at once):
 *   pty PATH                  the pseudo-terminal (and `link PATH` when --link made one)
 *   ready                     the simulation is running
 *   pwm T_US MONO_US MOTOR LEVEL
 *                             a motor's output level changed: simulated time, host
 *                             CLOCK_MONOTONIC (same clock as Python's time.monotonic) when
 *                             the AVR wrote the register, motor 0..3 (front, right, back,
 *                             left), level 0..255 from the OCR and COM bits
 *   rx T_US MONO_US           the first byte from the host after 100 ms of quiet
 *   stats SIM_S WALL_S MAX_LAG_MS SLIPS SLEEP_PCT   at exit: how closely the simulation
 *                             kept real time, and the share of cycles the AVR slept
 *   button T_US MONO_US ID DOWN   a stdin command below took effect on the pin
 *   battery T_US MONO_US MV       the battery voltage now on the divider
 * Commands on stdin, one a line, applied within a simulated millisecond:
 *   button ID DOWN            push button ID (0 = D4, 1 = D7, 2 = D8) down (1) or up (0)
 *   battery MV                the battery's voltage in millivolts; A0 sees half of it
 *                             through the 1:2 divider (4000 mV at start)
 * Other lines (simavr's own messages) are noise to readers.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <time.h>
#include <unistd.h>

#include "avr_adc.h"
#include "avr_ioport.h"
#include "avr_uart.h"
#include "sim_avr.h"
#include "sim_elf.h"
#include "sim_io.h"
#include "sim_irq.h"
#include "uart_pty.h"

#define F_CPU 16000000u
/* Behind the wall clock by more than this (host overloaded, process stopped), the
 * simulation forgets the debt instead of racing to catch up. */
#define MAX_LAG_NS 100000000ull
/* The simulation may run this far ahead of the wall clock before it sleeps: one sleep per
 * couple of milliseconds instead of one per timer event (thousands a second) keeps the
 * harness's own CPU use small, at the price of events up to 2 ms early. */
#define AHEAD_NS 2000000ull

/* ATmega328P data-space addresses of the PWM registers. */
enum { PORTB_ = 0x25, PORTD_ = 0x2B, TCCR0A_ = 0x44, OCR0A_ = 0x47, OCR0B_ = 0x48,
       TCCR1A_ = 0x80, OCR1AL_ = 0x88, OCR1BL_ = 0x8A };

typedef struct {
    uint16_t tccr, ocr, port;
    uint8_t com_shift, pin;
    int level;
} motor_t;

/* front OC0A/PD6, right OC0B/PD5, back OC1A/PB1, left OC1B/PB2 (Timer1 in 8-bit mode) */
static motor_t motors[4] = {
    {TCCR0A_, OCR0A_, PORTD_, 6, 6, -1},
    {TCCR0A_, OCR0B_, PORTD_, 4, 5, -1},
    {TCCR1A_, OCR1AL_, PORTB_, 6, 1, -1},
    {TCCR1A_, OCR1BL_, PORTB_, 4, 2, -1},
};

static avr_t *avr;
static uart_pty_t uart;
static volatile sig_atomic_t stop;
static uint64_t anchor_ns, max_lag_ns, slips, start_ns, slept_cycles;

static uint64_t mono_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
}

static uint64_t cycles_ns(avr_cycle_count_t c)
{
    return (c / F_CPU) * 1000000000ull + (c % F_CPU) * 1000000000ull / F_CPU;
}

/* Sleep until the wall clock reaches simulated cycle `target` (absolute, so no drift). */
static void pace(avr_cycle_count_t target)
{
    uint64_t due = anchor_ns + cycles_ns(target);
    uint64_t now = mono_ns();
    if (due > now) {
        if (due - now < AHEAD_NS)
            return;
        struct timespec ts = {(time_t)(due / 1000000000ull), (long)(due % 1000000000ull)};
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR && !stop)
            ;
        return;
    }
    uint64_t lag = now - due;
    if (lag > max_lag_ns)
        max_lag_ns = lag;
    if (lag > MAX_LAG_NS) {
        anchor_ns += lag;
        slips++;
    }
}

/* simavr calls this while the AVR sleeps, for the cycles until its next timer event. */
static void sleep_paced(avr_t *a, avr_cycle_count_t how_long)
{
    slept_cycles += how_long;
    pace(a->cycle + how_long);
}

static int level_of(const motor_t *m)
{
    uint8_t com = (avr->data[m->tccr] >> m->com_shift) & 3;
    if (com == 2)
        return avr->data[m->ocr];
    if (com == 3)
        return 255 - avr->data[m->ocr];
    return (avr->data[m->port] >> m->pin) & 1 ? 255 : 0; /* pin driven by PORT */
}

/* Any write to a PWM-related register: report motors whose level changed. */
static void register_written(struct avr_irq_t *irq, uint32_t value, void *param)
{
    for (int i = 0; i < 4; i++) {
        int level = level_of(&motors[i]);
        if (level == motors[i].level)
            continue;
        motors[i].level = level;
        if (printf("pwm %llu %llu %d %d\n",
                   (unsigned long long)(cycles_ns(avr->cycle) / 1000),
                   (unsigned long long)(mono_ns() / 1000), i, level) < 0)
            stop = 1;
    }
}

/* Remove a symlink to our pty, not one a successor harness has pointed elsewhere. */
static void unlink_if_ours(const char *path)
{
    char target[256];
    ssize_t len = readlink(path, target, sizeof(target) - 1);
    if (len > 0) {
        target[len] = 0;
        if (strcmp(target, uart.pty.slavename) == 0)
            unlink(path);
    }
}

/* A byte entered the AVR's UART: report the start of each burst from the host. */
static void byte_received(struct avr_irq_t *irq, uint32_t value, void *param)
{
    static avr_cycle_count_t last;
    static int seen;
    if (!seen || avr->cycle - last > F_CPU / 10)
        printf("rx %llu %llu\n", (unsigned long long)(cycles_ns(avr->cycle) / 1000),
               (unsigned long long)(mono_ns() / 1000));
    seen = 1;
    last = avr->cycle;
}

/* The buttons' pins: a pressed button pulls its pin low (the firmware enables pull-ups). */
static const struct {
    char port;
    int pin;
} button_pins[] = {{'D', 4}, {'D', 7}, {'B', 0}};
#define NBUTTONS (int)(sizeof(button_pins) / sizeof(button_pins[0]))
#define BATTERY_START_MV 4000u

static void set_button(int id, int down)
{
    avr_raise_irq(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(button_pins[id].port),
                                button_pins[id].pin),
                  down ? 0 : 1);
}

static void set_battery(unsigned mv)
{
    avr_raise_irq(avr_io_getirq(avr, AVR_IOCTL_ADC_GETIRQ, ADC_IRQ_ADC0), mv / 2u);
}

/* Read whatever stdin holds (non-blocking) and apply each whole line. */
static void poll_commands(void)
{
    static char line[256];
    static size_t len;
    char buf[256];
    ssize_t n;
    while ((n = read(STDIN_FILENO, buf, sizeof(buf))) > 0) {
        for (ssize_t i = 0; i < n; i++) {
            if (buf[i] != '\n') {
                if (len < sizeof(line) - 1)
                    line[len++] = buf[i];
                continue;
            }
            line[len] = 0;
            len = 0;
            int id, down;
            unsigned mv;
            unsigned long long t_us = cycles_ns(avr->cycle) / 1000, mono_us = mono_ns() / 1000;
            if (sscanf(line, "button %d %d", &id, &down) == 2 && id >= 0 && id < NBUTTONS) {
                set_button(id, down);
                printf("button %llu %llu %d %d\n", t_us, mono_us, id, down ? 1 : 0);
            } else if (sscanf(line, "battery %u", &mv) == 1) {
                set_battery(mv);
                printf("battery %llu %llu %u\n", t_us, mono_us, mv);
            }
        }
    }
}

static void on_signal(int sig)
{
    stop = 1;
}

int main(int argc, char **argv)
{
    const char *link_path = NULL;
    static const struct option opts[] = {{"link", required_argument, 0, 'l'}, {0, 0, 0, 0}};
    int c;
    while ((c = getopt_long(argc, argv, "l:", opts, NULL)) != -1) {
        if (c == 'l')
            link_path = optarg;
        else
            return 2;
    }
    if (optind != argc - 1) {
        fprintf(stderr, "usage: %s FIRMWARE.elf [--link PATH]\n", argv[0]);
        return 2;
    }
    setvbuf(stdout, NULL, _IOLBF, 0);
    prctl(PR_SET_PDEATHSIG, SIGTERM); /* never outlive the test or demo that started us */
    /* No SA_RESTART: uart_pty_stop() interrupts its thread's select() with SIGINT. */
    struct sigaction sa = {0};
    sa.sa_handler = on_signal;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGHUP, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);
    unsetenv("SIMAVR_UART_TAP");
    unsetenv("SIMAVR_UART_XTERM");

    elf_firmware_t fw;
    memset(&fw, 0, sizeof(fw));
    if (elf_read_firmware(argv[optind], &fw) != 0) {
        fprintf(stderr, "cannot read %s\n", argv[optind]);
        return 1;
    }
    avr = avr_make_mcu_by_name("atmega328p");
    if (!avr) {
        fprintf(stderr, "simavr has no atmega328p core\n");
        return 1;
    }
    avr_init(avr);
    fw.frequency = F_CPU; /* the real firmware carries no .mmcu section */
    strcpy(fw.mmcu, "atmega328p");
    avr_load_firmware(avr, &fw);
    avr->frequency = F_CPU;
    avr->sleep = sleep_paced;
    avr->log = 1; /* errors only */
    avr->vcc = avr->avcc = avr->aref = 5000; /* mV: the Nano's 5 V, the ADC's reference */

    uart_pty_init(avr, &uart);
    uart_pty_connect(&uart, '0');
    printf("pty %s\n", uart.pty.slavename);
    if (link_path) {
        char tmp[4096];
        snprintf(tmp, sizeof(tmp), "%s.%d", link_path, (int)getpid());
        /* rename() swaps the link atomically: a driver never sees it missing. */
        if (symlink(uart.pty.slavename, tmp) != 0 || rename(tmp, link_path) != 0) {
            fprintf(stderr, "cannot link %s: %s\n", link_path, strerror(errno));
            unlink(tmp);
            return 1;
        }
        printf("link %s\n", link_path);
    }

    const uint16_t watched[] = {TCCR0A_, OCR0A_, OCR0B_, TCCR1A_, OCR1AL_, OCR1BL_, PORTB_, PORTD_};
    for (size_t i = 0; i < sizeof(watched) / sizeof(watched[0]); i++)
        avr_irq_register_notify(avr_iomem_getirq(avr, watched[i], NULL, AVR_IOMEM_IRQ_ALL),
                                register_written, NULL);

    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT),
                            byte_received, NULL);

    for (int i = 0; i < NBUTTONS; i++)
        set_button(i, 0); /* released: the pins read high */
    set_battery(BATTERY_START_MV);
    fcntl(STDIN_FILENO, F_SETFL, fcntl(STDIN_FILENO, F_GETFL) | O_NONBLOCK);

    start_ns = anchor_ns = mono_ns();
    printf("ready\n");
    int state = cpu_Running;
    unsigned long n = 0;
    avr_cycle_count_t polled = 0;
    while (!stop && state != cpu_Done && state != cpu_Crashed) {
        state = avr_run(avr);
        if ((++n & 0xFFF) == 0) /* running flat out: stay behind the wall clock too */
            pace(avr->cycle);
        if (avr->cycle - polled >= F_CPU / 1000) { /* commands once a simulated ms */
            polled = avr->cycle;
            poll_commands();
        }
    }
    double wall_s = (double)(mono_ns() - start_ns) / 1e9;
    printf("stats %.3f %.3f %.3f %llu %.1f\n", (double)cycles_ns(avr->cycle) / 1e9, wall_s,
           (double)max_lag_ns / 1e6, (unsigned long long)slips,
           avr->cycle ? 100.0 * (double)slept_cycles / (double)avr->cycle : 0.0);
    if (link_path)
        unlink_if_ours(link_path);
    unlink_if_ours("/tmp/simavr-uart0"); /* uart_pty_connect() always makes this one */
    /* Not uart_pty_stop(): in simavr 1.6 its thread can miss the SIGINT it is sent and
     * then spin in select() forever, so pthread_join() never returns. exit() ends it. */
    fflush(stdout);
    return state == cpu_Crashed ? 3 : 0;
}
