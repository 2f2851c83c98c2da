/* hello: greets on the THREAD display, writes channel 0 to hello.txt on the PC at each A/D
 * interrupt and puts it on PWM 0 (top 8 bits), counts on PWM 1; after arg(0) lines (default
 * 3) it closes the file and says how many lines it wrote, then STARTs the set whose START word
 * is arg(1) (0: none, the lower loop just stops). */
#include "kernel.h"

static int file;
static int lines;

static int length(const char *s) {
    int n = 0;
    while (s[n]) n++;
    return n;
}

static void say(const char *s) { affiche(length(s), TEXT | NEWLINE, s); }

/* Decimal digits of v at p; returns the count. */
static int decimal(char *p, unsigned v) {
    char tmp[10];
    int n = 0, i = 0;
    do {
        tmp[n++] = (char)('0' + v % 10);
        v /= 10;
    } while (v);
    while (n) p[i++] = tmp[--n];
    return i;
}

static int wanted(void) { return arg(0) ? arg(0) : 3; }

HOOK(init_prog) int init_prog(void) {
    say("hello from C");
    file = fopen(9, "hello.txt", WRITE);
    lines = 0;
    return ContExec;
}

HOOK(AD_prog) int AD_prog(void) {
    int ch0 = ad_voie(0);
    char line[32] = "line ";
    int n = 5;
    pwm0(ch0 >> 8);
    lines++;
    pwm1(lines);
    n += decimal(line + n, (unsigned)lines);
    line[n++] = ':';
    line[n++] = ' ';
    n += decimal(line + n, (unsigned)ch0 >> 6); /* 10-bit */
    line[n++] = '\n';
    fwrite(file, n, line);
    if (lines < wanted()) return ContExec;
    /* A START word alone ends this run (fin_prog) and starts that set. */
    return arg(1) ? arg(1) : StopExec;
}

HOOK(fin_prog) void fin_prog(void) {
    unsigned short count = (unsigned short)lines;
    fclose(file);
    affiche(length("hello: lines written "), TEXT, "hello: lines written ");
    affiche(1, UNSIGNED16 | NEWLINE, &count);
}
