/* The PowerPC 403 core's speed benchmark (bench/ppc403_speed.sh): CPU-bound integer work
 * with no library, the same static ELF run by buslab's core and by qemu-ppc.
 *
 * CRC-32 (table-driven, reflected, polynomial 0xEDB88320) over a 64 KiB buffer ROUNDS times,
 * then a sieve of Eratosthenes to 1,000,000 SIEVES times; prints both results and exits
 * through `sc` (Linux's numbers: r0 = 4 write, r0 = 1 exit), which the board's firmware
 * serves the same way.
 *
 *   powerpc-linux-gnu-gcc -O2 -mcpu=403 -static -nostdlib -ffreestanding -fno-stack-protector \
 *       -fno-pie -no-pie -Wl,-Ttext=0x30000 -o crc_sieve crc_sieve.c
 */
#ifndef ROUNDS
#define ROUNDS 64
#endif
#ifndef SIEVES
#define SIEVES 16
#endif

typedef unsigned int u32;

#define BUF_LEN (64 * 1024)
#define SIEVE_LEN 1000000

static unsigned char buf[BUF_LEN];
static unsigned char composite[SIEVE_LEN];
static u32 crc_table[256];

/* Entry: a frame for main's link register save, main, exit(main's value). */
__asm__(".section .text\n"
        ".globl _start\n"
        "_start:\n"
        "    stwu 1, -16(1)\n"
        "    bl main\n"
        "    li 0, 1\n"
        "    sc\n"
        "    b .\n");

static long sys_write(long fd, const void *data, long len)
{
    register long r0 __asm__("r0") = 4;
    register long r3 __asm__("r3") = fd;
    register long r4 __asm__("r4") = (long)data;
    register long r5 __asm__("r5") = len;
    __asm__ volatile("sc"
                     : "+r"(r0), "+r"(r3), "+r"(r4), "+r"(r5)
                     :
                     : "r6", "r7", "r8", "r9", "r10", "r11", "r12", "cr0", "ctr", "xer", "memory");
    return r3;
}

/* gcc may turn a clearing loop into a call. */
void *memset(void *dst, int c, unsigned long n)
{
    unsigned char *p = dst;
    while (n--)
        *p++ = (unsigned char)c;
    return dst;
}

static u32 crc32(u32 crc, const unsigned char *p, u32 n)
{
    crc = ~crc;
    while (n--)
        crc = crc_table[(crc ^ *p++) & 0xFF] ^ (crc >> 8);
    return ~crc;
}

static u32 count_primes(void)
{
    u32 i, j, count = 0;
    for (i = 0; i < SIEVE_LEN; i++)
        composite[i] = 0;
    for (i = 2; i < SIEVE_LEN; i++) {
        if (composite[i])
            continue;
        count++;
        for (j = i + i; j < SIEVE_LEN; j += i)
            composite[j] = 1;
    }
    return count;
}

static char *put_hex(char *out, u32 v)
{
    int k;
    for (k = 28; k >= 0; k -= 4)
        *out++ = "0123456789abcdef"[(v >> k) & 0xF];
    return out;
}

static char *put_dec(char *out, u32 v)
{
    char digits[10];
    int n = 0;
    do {
        digits[n++] = (char)('0' + v % 10);
        v /= 10;
    } while (v);
    while (n)
        *out++ = digits[--n];
    return out;
}

static char *put_str(char *out, const char *s)
{
    while (*s)
        *out++ = *s++;
    return out;
}

int main(void)
{
    u32 i, k, c, x = 2463534242u, crc = 0, primes = 0;
    char line[80], *p = line;

    for (i = 0; i < 256; i++) {
        c = i;
        for (k = 0; k < 8; k++)
            c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
        crc_table[i] = c;
    }
    for (i = 0; i < BUF_LEN; i++) {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        buf[i] = (unsigned char)x;
    }
    for (i = 0; i < ROUNDS; i++) {
        crc = crc32(crc, buf, BUF_LEN);
        buf[(i * 4099) % BUF_LEN] ^= (unsigned char)crc;
    }
    for (i = 0; i < SIEVES; i++)
        primes += count_primes();

    p = put_str(p, "crc32 ");
    p = put_hex(p, crc);
    p = put_str(p, " primes ");
    p = put_dec(p, primes);
    *p++ = '\n';
    return sys_write(1, line, p - line) == p - line ? 0 : 1;
}
