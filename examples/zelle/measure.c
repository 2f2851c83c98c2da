/* measure.c: the ZELLE cell measures by itself. Reads A/D channel 1 sixteen times, 10 ms
 * apart, driving the converter on port 1 as the OS does (P1.0 /CS, P1.1 CLK, P1.2 DI, P1.3 DO:
 * see docs/zelle.md), stores the readings in the data area from 0808h (after the 8 series
 * parameter bytes) and their count at 0800h, then says "D" on the line and waits there until
 * the host stops it with a 0 and reads the values back (command 18, or `buslab zelle dump`).
 *
 * Build (SDCC): sdcc -mmcs51 --code-loc 0x400 --code-size 0x400 --iram-size 128 measure.c
 * gives measure.ihx for `buslab zelle load`.
 */
#include <8051.h>

#define COUNT 16

__xdata __at(0x0800) unsigned char count;
__xdata __at(0x0808) unsigned char values[COUNT];

/* Sende (0030h) takes its byte in A; SDCC passes a char argument in DPL. */
static void sende(unsigned char c) __naked
{
    (void)c;
    __asm
        mov     a, dpl
        ljmp    0x0030
    __endasm;
}

/* One conversion of single-ended channel 1..4: start bit, SGL, ODD, SELECT on rising CLK
 * edges; the falling edge after SELECT samples (DO: a leading 0), then 8 bits MSB first. */
static unsigned char convert(unsigned char channel)
{
    unsigned char address = 0x0C | ((channel - 1) & 1) << 1 | ((channel - 1) >> 1 & 1);
    unsigned char i, value = 0;
    P1_3 = 1; /* DO is an input: its latch high */
    P1_1 = 0;
    P1_0 = 0; /* select */
    for (i = 0; i < 4; i++) {
        P1_2 = (address & 0x08) ? 1 : 0;
        address <<= 1;
        P1_1 = 1;
        P1_1 = 0; /* after SELECT: samples, DO gives the leading 0 */
    }
    for (i = 0; i < 8; i++) {
        P1_1 = 1;
        P1_1 = 0;
        value = value << 1 | P1_3;
    }
    P1_0 = 1; /* deselect (the LED goes off) */
    return value;
}

/* 10 ms on timer 0 (mode 1: 9216 machine cycles at 11.0592 MHz); timer 1 keeps the baud rate. */
static void wait_10ms(void)
{
    TMOD = (TMOD & 0xF0) | 0x01;
    TH0 = 0xDC;
    TL0 = 0x00;
    TF0 = 0;
    TR0 = 1;
    while (!TF0)
        ;
    TR0 = 0;
}

void main(void)
{
    unsigned char i;
    for (i = 0; i < COUNT; i++) {
        values[i] = convert(1);
        count = i + 1;
        wait_10ms();
    }
    sende('D');
    for (;;)
        ; /* until the host sends a 0 */
}
