/* The CPU196 kernel API for user programs compiled to WebAssembly (docs/cpu196.md, "User
 * programs"). Every service is an import from the module "kernel"; a hook is an exported
 * function under the seed's name. Build with Debian's clang and lld:
 *   clang --target=wasm32 -O2 -nostdlib -Wl,--no-entry -o prog.wasm prog.c
 */
#ifndef CPU196_KERNEL_H
#define CPU196_KERNEL_H

#define KERNEL(name) __attribute__((import_module("kernel"), import_name(#name)))
/* Marks a hook: init_prog, user_prog, RS_prog, pic_prog, pas_prog1, pas_prog2, AD_prog,
 * fin_prog, Main_Fread. */
#define HOOK(name) __attribute__((export_name(#name)))

/* What a hook returns: bits 0..15 a START word (_NoStart_ 8000h: none), bit 16 _StopExec_. */
#define NoStart 0x8000
#define ContExec 0x8000
#define StopExec 0x18000
/* A START word (the seed's sefm thhh pabb bnnn, here for a set with or without the 80C196
 * A/D): returned by a hook, it ends this run (fin_prog) and starts that set. */
#define START(bank, config, ad) ((((ad) ? 0x40 : 0) | ((bank) << 3) | (config)) & 0xFFFF)

/* affiche formats (THREAD sub-codes); add NEWLINE to end the line. */
#define TEXT 0
#define HEX8 2
#define HEX16 3
#define UNSIGNED8 4
#define UNSIGNED16 5
#define SIGNED8 6
#define SIGNED16 7
#define NEWLINE 8

/* fopen modes */
#define READ 0
#define WRITE 1

KERNEL(affiche) void affiche(int n, int format, const void *tab);
KERNEL(fopen) int fopen(int n, const char *name, int mode);
KERNEL(fwrite) void fwrite(int f, int n, const void *tab);
KERNEL(fread) void fread(int f, int n);
KERNEL(fclose) void fclose(int f);
KERNEL(emission_canal_virtuel_16bits) void emission_canal_virtuel_16bits(int n, int d);
KERNEL(emission_canal_virtuel_12bits) void emission_canal_virtuel_12bits(int n, int d);
KERNEL(emission_canal_virtuel_8bits) void emission_canal_virtuel_8bits(int n, int d);
KERNEL(pwm) void pwm(int n, int c);
KERNEL(alerte) void alerte(int n);
KERNEL(ad_voie) int ad_voie(int n);
KERNEL(ad_pic) int ad_pic(int n);
KERNEL(arg) int arg(int i);
KERNEL(now_us) long long now_us(void);
KERNEL(wr_pic_pwm) void wr_pic_pwm(int value);
KERNEL(wr_pic_reference) void wr_pic_reference(int value);
KERNEL(wr_pic_sci) void wr_pic_sci(int byte);
KERNEL(wr_pic_user) void wr_pic_user(int byte);
KERNEL(user_command) void user_command(int cmd, int n);
KERNEL(event_data) int event_data(void *buf, int max);

#define pwm0(c) pwm(0, (c))
#define pwm1(c) pwm(1, (c))
#define pwm2(c) pwm(2, (c))

#endif
