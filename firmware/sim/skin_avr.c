/*
 * skin_avr.c - run a compiled skin firmware (ELF) in simavr against a simulated scene.
 *
 * The board around the MCU (firmware/README.md) is emulated here:
 *   - M CD74HC4067 multiplexers on the select lines (PD4-PD7 on the ATmega328P, PA0-PA3 on the
 *     ATmega2560) feeding ADC0 .. ADC(M-1); with M = 0 taxel t is on ADC channel t;
 *   - each thermistor in the paper's divider (thermistor from V+ to the input, R_REF to ground),
 *     its temperature from the scene file plus its heater's first-order response;
 *   - the LM35 ambient sensor (10 mV per deg C) on ADC channel M (or N with M = 0);
 *   - with --force-inputs F, a force-sensing stage per taxel 0 .. F-1 (linear, --force-full-n
 *     at 1.1 V) on ceil(F / 16) more multiplexers on ADC channels M+1 .. (without multiplexers:
 *     input f on ADC channel N+1+f), its force from the scene (scene version 2);
 *   - the 74HC595 heater chain on SPI with the latch on PB0;
 *   - UART0 on a pseudo-terminal, with back-pressure both ways.
 *
 * simavr's ADC reads its input when the firmware reads ADCL/ADCH, not when the conversion
 * starts; the harness adds the sample-and-hold: the value of the channel being converted is
 * captured when the conversion starts, so firmware may move the multiplexer during a conversion.
 * simavr also times a UART byte with a parity bit that 8N1 does not have (11 bit times); the
 * harness retimes it from the configured frame format (10 bit times: 10 us at 1 Mbaud).
 *
 * Usage: skin_avr --mcu atmega328p|atmega2560 --freq 16000000 --elf FILE --scene FILE
 *                 --taxels N --muxes M [--swap I,J] [--realtime X] [--duration SECONDS]
 *                 [--wait-host 1]  (start on the first byte the host writes)
 *                 [--force-inputs F] [--force-full-n NEWTON]
 * The first line on stdout is "PTY <path>"; a one-line summary goes to stderr at exit, after
 * a "timing" line: the cycles of the firmware's GPIOR0 marks (bit 0: the main loop's work on a
 * sample; bit 1: a scan's conversions; bit 2: the serial sketch waiting for the previous packet
 * to leave), count, mean and max per mark.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <pty.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <sim_avr.h>
#include <sim_elf.h>
#include <sim_io.h>
#include <sim_irq.h>
#include <sim_cycle_timers.h>
#include <avr_adc.h>
#include <avr_ioport.h>
#include <avr_spi.h>
#include <avr_uart.h>

#define MAX_MUXES 8
#define MAX_TAXELS (16 * MAX_MUXES)
#define SIM_ADC_CHANNELS 8 /* simavr 1.6 keeps values for ADC0-ADC7 only */
#define ADCL_ADDR 0x78     /* data-space addresses, the same on the 328P and the 2560 */
#define ADCH_ADDR 0x79
#define UBRR0L_ADDR 0xC4   /* also the same on both */
#define SPDR_ADDR 0x4E     /* SPI data register, the same on both */
#define GPIOR0_ADDR 0x3E   /* the firmware's timing marks, the same on both */
#define OUT_HIGH_WATER 4096      /* pending UART output before the emulation waits */
#define IN_CAPACITY (64 * 1024)  /* host bytes buffered before the pty is no longer read */
#define EXIT_LINGER_S 0.25       /* at the end, wait while the host reads the rest */

typedef struct {
	/* options */
	const char *mcu, *elf_path, *scene_path;
	uint32_t freq;
	int n_taxels, n_muxes, swap_i, swap_j;
	double realtime, duration;
	int wait_host; /* start emulating on the first byte from the host */
	int n_force;   /* taxels 0 .. n_force-1 have a force input */
	double force_full_n; /* force at 1.1 V */
	double c0, c1, r_ref, v_plus;
	int verbose;

	/* scene */
	uint32_t n_samples;
	float rate_hz, nominal, rise, tau;
	float *temp; /* [n_samples][n_taxels] */
	float *ambient;
	float *force; /* [n_samples][n_taxels], N; NULL: version-1 scene (no force) */

	/* simulator */
	avr_t *avr;
	avr_irq_t *adc_irq; /* ADC_IRQ_ADC0 .. */
	int ambient_ch, n_channels, force_ch0, n_force_ch;
	uint8_t sel;                   /* multiplexer select lines S0-S3 */
	uint32_t live_mv[SIM_ADC_CHANNELS];
	int hold_ch;                   /* sample-and-hold: channel of the last conversion, -1 none */
	uint32_t hold_mv;
	avr_io_read_t adc_read_orig[2];
	void *adc_read_param[2];
	avr_io_write_t ubrr_write_orig;
	void *ubrr_write_param;

	/* heaters */
	int n_bytes;
	uint8_t shift[MAX_TAXELS / 8];
	uint8_t latch_prev;
	uint8_t on[MAX_TAXELS];
	double h0[MAX_TAXELS], t0[MAX_TAXELS]; /* heater rise h0 at time t0 */
	int heater_of[MAX_TAXELS];             /* thermistor t is warmed by heater heater_of[t] */
	uint64_t latches, spi_bytes;

	/* timing marks (GPIOR0 bits 0, 1) */
	uint8_t gpior;
	avr_cycle_count_t mark_t0[3], mark_max[3];
	uint64_t mark_sum[3], mark_n[3];

	/* serial */
	int master, slave;
	char pty_name[256];
	uint8_t *out;
	size_t out_len, out_cap;
	uint8_t in[IN_CAPACITY];
	size_t in_head, in_len;
	int rx_open; /* the UART takes input: XON seen and no XOFF since */
	uint64_t bytes_out, bytes_in;
	double waited_s; /* real seconds the emulation waited for the host to read */
} sim_t;

static sim_t S;
static volatile sig_atomic_t g_stop;

static void die(const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	fputs("skin_avr: ", stderr);
	vfprintf(stderr, fmt, ap);
	fputc('\n', stderr);
	va_end(ap);
	exit(2);
}

static double wall_now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static double emu_now(void)
{
	return (double)S.avr->cycle / S.freq;
}

/* ---------------------------------------------------------------- scene */

static uint32_t rd_u32(const uint8_t *p)
{
	return p[0] | (p[1] << 8) | (p[2] << 16) | ((uint32_t)p[3] << 24);
}

static float rd_f32(const uint8_t *p)
{
	uint32_t u = rd_u32(p);
	float f;
	memcpy(&f, &u, sizeof f);
	return f;
}

static void load_scene(const char *path)
{
	FILE *f = fopen(path, "rb");
	if (!f)
		die("cannot open scene %s: %s", path, strerror(errno));
	uint8_t h[32];
	if (fread(h, 1, sizeof h, f) != sizeof h)
		die("%s: shorter than the 32-byte header", path);
	if (memcmp(h, "SKSC", 4))
		die("%s: not a scene file (magic is not SKSC)", path);
	uint32_t version = rd_u32(h + 4);
	if (version != 1 && version != 2)
		die("%s: scene version %u, this harness reads versions 1 and 2", path, version);
	uint32_t n = rd_u32(h + 8);
	S.n_samples = rd_u32(h + 12);
	S.rate_hz = rd_f32(h + 16);
	S.nominal = rd_f32(h + 20);
	S.rise = rd_f32(h + 24);
	S.tau = rd_f32(h + 28);
	if ((int)n != S.n_taxels)
		die("%s: the scene has %u taxels, --taxels says %d", path, n, S.n_taxels);
	if (S.n_samples == 0 || !(S.rate_hz > 0))
		die("%s: no samples or a rate that is not positive", path);
	size_t count = (size_t)S.n_samples * n;
	S.temp = malloc(count * sizeof(float));
	S.ambient = malloc(S.n_samples * sizeof(float));
	uint8_t *raw = malloc((count + S.n_samples) * 4);
	if (!S.temp || !S.ambient || !raw)
		die("out of memory for the scene");
	if (fread(raw, 4, count + S.n_samples, f) != count + S.n_samples)
		die("%s: truncated: %u samples x %u taxels of data expected", path, S.n_samples, n);
	for (size_t i = 0; i < count; i++)
		S.temp[i] = rd_f32(raw + 4 * i);
	for (size_t i = 0; i < S.n_samples; i++)
		S.ambient[i] = rd_f32(raw + 4 * (count + i));
	free(raw);
	if (version == 2) { /* then the force of every taxel at every sample, N */
		S.force = malloc(count * sizeof(float));
		raw = malloc(count * 4);
		if (!S.force || !raw)
			die("out of memory for the scene's force");
		if (fread(raw, 4, count, f) != count)
			die("%s: truncated: %u samples x %u taxels of force expected", path, S.n_samples, n);
		for (size_t i = 0; i < count; i++)
			S.force[i] = rd_f32(raw + 4 * i);
		free(raw);
	}
	fclose(f);
}

static uint32_t sample_at(double t)
{
	double s = floor(t * S.rate_hz);
	if (s < 0)
		return 0;
	if (s >= S.n_samples)
		return S.n_samples - 1;
	return (uint32_t)s;
}

/* ---------------------------------------------------------------- heaters */

static double heater_rise(int i, double t)
{
	double target = S.rise * ((S.on[i] ? 1.0 : 0.0) - S.nominal);
	if (!(S.tau > 0))
		return target;
	return target + (S.h0[i] - target) * exp(-(t - S.t0[i]) / S.tau);
}

static double thermistor_temp(int taxel, double t)
{
	return S.temp[(size_t)sample_at(t) * S.n_taxels + taxel] + heater_rise(S.heater_of[taxel], t);
}

static uint32_t divider_mv(double temp_c)
{
	double r = exp((1.0 / (temp_c + 273.15) - S.c0) / S.c1);
	double v = S.v_plus * S.r_ref / (S.r_ref + r);
	return (uint32_t)lround(v * 1000.0);
}

static uint32_t force_mv(int taxel, double t)
{
	if (!S.force || taxel >= S.n_force || taxel >= S.n_taxels)
		return 0;
	double f = S.force[(size_t)sample_at(t) * S.n_taxels + taxel];
	double mv = f / S.force_full_n * 1100.0;
	if (!(mv > 0))
		return 0;
	return mv > 5000.0 ? 5000 : (uint32_t)lround(mv);
}

static uint32_t channel_mv(int ch, double t)
{
	if (S.n_force_ch && ch >= S.force_ch0)
		return force_mv(S.n_muxes ? 16 * (ch - S.force_ch0) + S.sel : ch - S.force_ch0, t);
	if (ch == S.ambient_ch) {
		double mv = S.ambient[sample_at(t)] * 10.0;
		return mv > 0 ? (uint32_t)lround(mv) : 0;
	}
	int taxel = S.n_muxes ? 16 * ch + S.sel : ch;
	if (taxel >= S.n_taxels)
		return 0; /* an unconnected multiplexer input */
	return divider_mv(thermistor_temp(taxel, t));
}

static void refresh_channel(int ch, double t)
{
	if (ch < 0 || ch >= S.n_channels)
		return;
	S.live_mv[ch] = channel_mv(ch, t);
	avr_raise_irq(S.adc_irq + ch, S.live_mv[ch]);
}

static void refresh_all(void)
{
	double t = emu_now();
	for (int ch = 0; ch < S.n_channels; ch++)
		refresh_channel(ch, t);
}

/* ---------------------------------------------------------------- IRQ hooks */

static void on_select(avr_irq_t *irq, uint32_t value, void *param)
{
	int bit = (int)(intptr_t)param;
	uint8_t sel = (S.sel & ~(1u << bit)) | ((value & 1) << bit);
	if (sel == S.sel)
		return;
	S.sel = sel;
	double t = emu_now();
	for (int ch = 0; ch < S.n_muxes; ch++)
		refresh_channel(ch, t);
	if (S.n_muxes)
		for (int ch = S.force_ch0; ch < S.force_ch0 + S.n_force_ch; ch++)
			refresh_channel(ch, t);
}

/* GPIOR0: the firmware's timing marks; time each bit from its rise to its fall */
static void gpior_write(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
	avr->data[addr] = v;
	for (int b = 0; b < 3; b++) {
		int was = (S.gpior >> b) & 1, now = (v >> b) & 1;
		if (now && !was)
			S.mark_t0[b] = avr->cycle;
		else if (!now && was) {
			avr_cycle_count_t d = avr->cycle - S.mark_t0[b];
			S.mark_sum[b] += d;
			S.mark_n[b]++;
			if (d > S.mark_max[b])
				S.mark_max[b] = d;
		}
	}
	S.gpior = v;
}

static void on_adc_trigger(avr_irq_t *irq, uint32_t value, void *param)
{
	union {
		avr_adc_mux_t mux;
		uint32_t v;
	} e = {.v = value};
	S.hold_ch = -1;
	if (e.mux.kind == ADC_MUX_SINGLE && e.mux.src < (unsigned)S.n_channels) {
		refresh_channel(e.mux.src, emu_now());
		S.hold_ch = e.mux.src;
		S.hold_mv = S.live_mv[e.mux.src];
	}
}

/* ADCL/ADCH reads: simavr computes the result here, from the input's value now; give it the
 * value held when the conversion started. */
static uint8_t adc_read_held(avr_t *avr, avr_io_addr_t addr, void *param)
{
	int k = addr == ADCH_ADDR;
	int ch = S.hold_ch;
	if (ch < 0)
		return S.adc_read_orig[k](avr, addr, S.adc_read_param[k]);
	avr_raise_irq(S.adc_irq + ch, S.hold_mv);
	uint8_t v = S.adc_read_orig[k](avr, addr, S.adc_read_param[k]);
	avr_raise_irq(S.adc_irq + ch, S.live_mv[ch]);
	return v;
}

/* simavr times a UART byte as start + data + parity + stop bits even without parity (11 bit
 * times for 8N1, 10 % slow); after the firmware sets the baud rate, time it from the frame format
 * actually configured. */
static void ubrr_write_fixed(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
	S.ubrr_write_orig(avr, addr, v, S.ubrr_write_param);
	avr_uart_t *p = S.ubrr_write_param;
	uint32_t ubrr = avr_regbit_get(avr, p->ubrrl) | (avr_regbit_get(avr, p->ubrrh) << 8);
	avr_cycle_count_t per_bit = (ubrr + 1) * (avr_regbit_get(avr, p->u2x) ? 8 : 16);
	static const int databits[8] = {5, 6, 7, 8, 8, 8, 8, 9};
	int data = databits[avr_regbit_get(avr, p->ucsz) | (avr_regbit_get(avr, p->ucsz2) << 2)];
	int parity = p->r_ucsrc && (avr->data[p->r_ucsrc] & 0x30) ? 1 : 0; /* UPMn1:0 */
	int stop = 1 + avr_regbit_get(avr, p->usbs);
	p->cycles_per_byte = per_bit * (1 + data + parity + stop);
}

/* simavr 1.6 takes 100 us for every SPI byte whatever the clock (8 bytes of heaters took 0.8 ms
 * of a 5 ms sample period); time it from SPCR/SPSR instead: 8 bits at F_CPU / divider. */
static avr_cycle_count_t spi_done(avr_t *avr, avr_cycle_count_t when, void *param)
{
	avr_spi_t *p = param;
	avr_raise_irq(p->io.irq + SPI_IRQ_OUTPUT, avr->data[p->r_spdr]);
	avr_raise_interrupt(avr, &p->spi);
	return 0;
}

static void spdr_write_timed(avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
	avr_spi_t *p = param;
	static const uint8_t div[4] = {4, 16, 64, 128};
	avr_clear_interrupt(avr, &p->spi);
	avr_core_watch_write(avr, addr, v);
	avr_cycle_count_t bit = div[avr->data[p->r_spcr] & 3];
	if (avr->data[p->r_spsr] & 1) /* SPI2X */
		bit /= 2;
	avr_cycle_timer_register(avr, 8 * bit, spi_done, p);
}

static avr_cycle_count_t on_sample_boundary(avr_t *avr, avr_cycle_count_t when, void *param)
{
	refresh_all();
	double t = (double)when / S.freq;
	double next_s = floor(t * S.rate_hz + 1e-9) + 1;
	avr_cycle_count_t next = (avr_cycle_count_t)ceil(next_s / S.rate_hz * S.freq);
	return next > when ? next : when + 1;
}

static void on_spi_out(avr_irq_t *irq, uint32_t value, void *param)
{
	/* a chain of n_bytes shift registers: the byte shifted last sits in the first one */
	memmove(S.shift + 1, S.shift, S.n_bytes - 1);
	S.shift[0] = value & 0xFF;
	S.spi_bytes++;
}

static void on_latch(avr_irq_t *irq, uint32_t value, void *param)
{
	uint8_t v = value & 1;
	if (v && !S.latch_prev) {
		double t = emu_now();
		for (int i = 0; i < S.n_taxels; i++) {
			S.h0[i] = heater_rise(i, t);
			S.t0[i] = t;
			S.on[i] = (S.shift[i / 8] >> (i % 8)) & 1;
		}
		S.latches++;
		refresh_all();
	}
	S.latch_prev = v;
}

static void uart_feed(void)
{
	avr_irq_t *in = avr_io_getirq(S.avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
	while (S.rx_open && S.in_len) {
		uint8_t b = S.in[S.in_head];
		S.in_head = (S.in_head + 1) % IN_CAPACITY;
		S.in_len--;
		S.bytes_in++;
		avr_raise_irq(in, b); /* may raise XOFF, which closes rx_open */
	}
}

static void on_uart_xon(avr_irq_t *irq, uint32_t value, void *param)
{
	S.rx_open = 1;
	if (S.in_len)
		uart_feed();
}

static void on_uart_xoff(avr_irq_t *irq, uint32_t value, void *param)
{
	if (value)
		S.rx_open = 0;
}

static void on_uart_out(avr_irq_t *irq, uint32_t value, void *param)
{
	if (S.out_len == S.out_cap) {
		S.out_cap = S.out_cap ? 2 * S.out_cap : 65536;
		S.out = realloc(S.out, S.out_cap);
		if (!S.out)
			die("out of memory for UART output");
	}
	S.out[S.out_len++] = value & 0xFF;
	S.bytes_out++;
}

static void quiet_sleep(avr_t *avr, avr_cycle_count_t how_long)
{
	/* simavr's default sleeps in real time while the MCU sleeps; pacing is done here */
}

static void logger(avr_t *avr, const int level, const char *fmt, va_list ap)
{
	if (!avr || avr->log >= level)
		vfprintf(stderr, fmt, ap);
}

/* ---------------------------------------------------------------- pty */

static void open_pty(void)
{
	if (openpty(&S.master, &S.slave, S.pty_name, NULL, NULL) < 0)
		die("openpty: %s", strerror(errno));
	struct termios tio;
	if (tcgetattr(S.slave, &tio) == 0) {
		cfmakeraw(&tio);
		tcsetattr(S.slave, TCSANOW, &tio);
	}
	fcntl(S.master, F_SETFL, fcntl(S.master, F_GETFL) | O_NONBLOCK);
}

/* Move bytes between the pty and the buffers; with `wait_out`, block until the pending output
 * drops to the high-water mark (or a signal stops us). */
static void service_pty(int wait_out)
{
	for (;;) {
		/* host -> board */
		while (S.in_len < IN_CAPACITY) {
			size_t tail = (S.in_head + S.in_len) % IN_CAPACITY;
			size_t room = tail >= S.in_head ? IN_CAPACITY - tail : S.in_head - tail;
			if (room > IN_CAPACITY - S.in_len)
				room = IN_CAPACITY - S.in_len;
			ssize_t r = read(S.master, S.in + tail, room);
			if (r <= 0)
				break;
			S.in_len += r;
		}
		/* board -> host */
		size_t done = 0;
		while (done < S.out_len) {
			ssize_t w = write(S.master, S.out + done, S.out_len - done);
			if (w <= 0)
				break;
			done += w;
		}
		if (done) {
			memmove(S.out, S.out + done, S.out_len - done);
			S.out_len -= done;
		}
		if (!wait_out || S.out_len <= OUT_HIGH_WATER || g_stop)
			return;
		struct pollfd p = {.fd = S.master, .events = POLLOUT};
		double w0 = wall_now();
		poll(&p, 1, 100);
		S.waited_s += wall_now() - w0;
	}
}

/* ---------------------------------------------------------------- main */

static void usage(void)
{
	fprintf(stderr,
		"usage: skin_avr --mcu atmega328p|atmega2560 --freq 16000000 --elf FILE --scene FILE\n"
		"                --taxels N --muxes M [--swap I,J] [--realtime X] [--duration SECONDS]\n"
		"                [--r-ref OHM] [--v-plus VOLT] [--c0 C0] [--c1 C1] [--wait-host 1] [--verbose]\n"
		"                [--force-inputs F] [--force-full-n NEWTON]\n");
	exit(2);
}

static void parse_args(int argc, char **argv)
{
	S.mcu = "atmega328p";
	S.freq = 16000000;
	S.n_taxels = -1;
	S.n_muxes = -1;
	S.swap_i = S.swap_j = -1;
	S.c0 = 9.5594e-4;
	S.c1 = 2.6181e-4;
	S.r_ref = 668.0;
	S.v_plus = 5.06;
	S.force_full_n = 20.0;
	for (int i = 1; i < argc; i++) {
		const char *a = argv[i];
		if (!strcmp(a, "--verbose")) {
			S.verbose = 1;
			continue;
		}
		if (!strcmp(a, "--help") || !strcmp(a, "-h"))
			usage();
		if (i + 1 >= argc)
			die("%s needs a value", a);
		const char *v = argv[++i];
		if (!strcmp(a, "--mcu"))
			S.mcu = v;
		else if (!strcmp(a, "--freq"))
			S.freq = strtoul(v, NULL, 10);
		else if (!strcmp(a, "--elf"))
			S.elf_path = v;
		else if (!strcmp(a, "--scene"))
			S.scene_path = v;
		else if (!strcmp(a, "--taxels"))
			S.n_taxels = atoi(v);
		else if (!strcmp(a, "--muxes"))
			S.n_muxes = atoi(v);
		else if (!strcmp(a, "--swap")) {
			if (sscanf(v, "%d,%d", &S.swap_i, &S.swap_j) != 2)
				die("--swap takes I,J");
		} else if (!strcmp(a, "--realtime"))
			S.realtime = atof(v);
		else if (!strcmp(a, "--duration"))
			S.duration = atof(v);
		else if (!strcmp(a, "--wait-host"))
			S.wait_host = atoi(v);
		else if (!strcmp(a, "--r-ref"))
			S.r_ref = atof(v);
		else if (!strcmp(a, "--v-plus"))
			S.v_plus = atof(v);
		else if (!strcmp(a, "--c0"))
			S.c0 = atof(v);
		else if (!strcmp(a, "--c1"))
			S.c1 = atof(v);
		else if (!strcmp(a, "--force-inputs"))
			S.n_force = atoi(v);
		else if (!strcmp(a, "--force-full-n"))
			S.force_full_n = atof(v);
		else
			die("unknown option %s (--help lists them)", a);
	}
	if (!S.elf_path || !S.scene_path || S.n_taxels < 0 || S.n_muxes < 0)
		usage();
	if (S.freq == 0)
		die("--freq must be positive");
	if (S.n_taxels < 1 || S.n_taxels > MAX_TAXELS)
		die("--taxels must be 1..%d", MAX_TAXELS);
	if (S.n_muxes > MAX_MUXES)
		die("--muxes must be 0..%d", MAX_MUXES);
	if (S.n_muxes && S.n_taxels > 16 * S.n_muxes)
		die("%d multiplexers carry at most %d taxels", S.n_muxes, 16 * S.n_muxes);
	if (S.swap_i >= S.n_taxels || S.swap_j >= S.n_taxels || (S.swap_i < 0) != (S.swap_j < 0))
		die("--swap %d,%d: heaters are 0..%d", S.swap_i, S.swap_j, S.n_taxels - 1);
	S.ambient_ch = S.n_muxes ? S.n_muxes : S.n_taxels;
	if (S.ambient_ch >= SIM_ADC_CHANNELS)
		die("the ambient sensor would be on ADC%d; simavr models ADC0-ADC%d only",
		    S.ambient_ch, SIM_ADC_CHANNELS - 1);
	if (S.n_force < 0 || S.n_force > S.n_taxels)
		die("--force-inputs must be 0..%d (the taxels)", S.n_taxels);
	if (!(S.force_full_n > 0))
		die("--force-full-n must be positive");
	S.force_ch0 = S.ambient_ch + 1;
	S.n_force_ch = S.n_muxes ? (S.n_force + 15) / 16 : S.n_force;
	S.n_channels = S.ambient_ch + 1 + S.n_force_ch;
	if (S.n_channels > SIM_ADC_CHANNELS)
		die("the force inputs would need ADC%d; simavr models ADC0-ADC%d only",
		    S.n_channels - 1, SIM_ADC_CHANNELS - 1);
}

static void on_signal(int sig)
{
	g_stop = 1;
}

int main(int argc, char **argv)
{
	/* simavr prints on stdout in places; keep stdout for the PTY line only */
	int out_fd = dup(STDOUT_FILENO);
	dup2(STDERR_FILENO, STDOUT_FILENO);
	FILE *out = fdopen(out_fd, "w");

	parse_args(argc, argv);
	load_scene(S.scene_path);
	avr_global_logger_set(logger);

	elf_firmware_t fw;
	memset(&fw, 0, sizeof fw);
	if (access(S.elf_path, R_OK) != 0)
		die("cannot read firmware %s: %s", S.elf_path, strerror(errno));
	if (elf_read_firmware(S.elf_path, &fw) != 0)
		die("%s: not a readable AVR ELF", S.elf_path);
	S.avr = avr_make_mcu_by_name(S.mcu);
	if (!S.avr)
		die("simavr does not know the MCU %s", S.mcu);
	avr_init(S.avr);
	avr_load_firmware(S.avr, &fw);
	S.avr->frequency = S.freq;
	S.avr->vcc = S.avr->avcc = S.avr->aref = 5000;
	S.avr->log = S.verbose ? LOG_TRACE : LOG_ERROR;
	S.avr->sleep = quiet_sleep;
	int mega = strstr(S.mcu, "2560") || strstr(S.mcu, "1280");

	/* ADC inputs and the sample-and-hold */
	S.adc_irq = avr_io_getirq(S.avr, AVR_IOCTL_ADC_GETIRQ, ADC_IRQ_ADC0);
	if (!S.adc_irq)
		die("%s has no ADC in simavr", S.mcu);
	avr_irq_register_notify(avr_io_getirq(S.avr, AVR_IOCTL_ADC_GETIRQ, ADC_IRQ_OUT_TRIGGER),
				on_adc_trigger, NULL);
	S.hold_ch = -1;
	avr_io_addr_t adc_regs[2] = {ADCL_ADDR, ADCH_ADDR};
	for (int k = 0; k < 2; k++) {
		int io = AVR_DATA_TO_IO(adc_regs[k]);
		S.adc_read_orig[k] = S.avr->io[io].r.c;
		S.adc_read_param[k] = S.avr->io[io].r.param;
		if (!S.adc_read_orig[k])
			die("simavr's ADC does not hook ADCL/ADCH at 0x%02x on %s", adc_regs[k], S.mcu);
		S.avr->io[io].r.c = adc_read_held;
	}

	/* multiplexer select lines, heater chain, latch */
	char sel_port = mega ? 'A' : 'D';
	int sel_pin0 = mega ? 0 : 4;
	for (int b = 0; b < 4; b++) {
		avr_irq_t *pin = avr_io_getirq(S.avr, AVR_IOCTL_IOPORT_GETIRQ(sel_port), sel_pin0 + b);
		if (!pin)
			die("%s has no port %c in simavr", S.mcu, sel_port);
		avr_irq_register_notify(pin, on_select, (void *)(intptr_t)b);
	}
	avr_irq_register_notify(avr_io_getirq(S.avr, AVR_IOCTL_SPI_GETIRQ(0), SPI_IRQ_OUTPUT),
				on_spi_out, NULL);
	avr_irq_register_notify(avr_io_getirq(S.avr, AVR_IOCTL_IOPORT_GETIRQ('B'), IOPORT_IRQ_PIN0),
				on_latch, NULL);
	S.n_bytes = (S.n_taxels + 7) / 8;
	for (int t = 0; t < S.n_taxels; t++)
		S.heater_of[t] = t;
	if (S.swap_i >= 0) {
		S.heater_of[S.swap_i] = S.swap_j;
		S.heater_of[S.swap_j] = S.swap_i;
	}

	int spdr_io = AVR_DATA_TO_IO(SPDR_ADDR);
	/* SPI: retime each byte (see spdr_write_timed) */
	if (!S.avr->io[spdr_io].w.c)
		die("simavr's SPI does not hook SPDR at 0x%02x on %s", SPDR_ADDR, S.mcu);
	S.avr->io[spdr_io].w.c = spdr_write_timed;
	avr_register_io_write(S.avr, GPIOR0_ADDR, gpior_write, NULL);

	/* UART0 */
	int ubrr_io = AVR_DATA_TO_IO(UBRR0L_ADDR);
	S.ubrr_write_orig = S.avr->io[ubrr_io].w.c;
	S.ubrr_write_param = S.avr->io[ubrr_io].w.param;
	if (!S.ubrr_write_orig)
		die("simavr's UART0 does not hook UBRR0L at 0x%02x on %s", UBRR0L_ADDR, S.mcu);
	S.avr->io[ubrr_io].w.c = ubrr_write_fixed;
	uint32_t flags = 0;
	avr_ioctl(S.avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
	flags &= ~(AVR_UART_FLAG_STDIO | AVR_UART_FLAG_POLL_SLEEP);
	avr_ioctl(S.avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
	avr_irq_register_notify(avr_io_getirq(S.avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
				on_uart_out, NULL);
	avr_irq_register_notify(avr_io_getirq(S.avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON),
				on_uart_xon, NULL);
	avr_irq_register_notify(avr_io_getirq(S.avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF),
				on_uart_xoff, NULL);

	refresh_all();
	avr_cycle_timer_register(S.avr, (avr_cycle_count_t)ceil(S.freq / S.rate_hz),
				 on_sample_boundary, NULL);

	open_pty();
	struct sigaction sa = {.sa_handler = on_signal};
	sigaction(SIGTERM, &sa, NULL);
	sigaction(SIGINT, &sa, NULL);
	signal(SIGPIPE, SIG_IGN);
	fprintf(out, "PTY %s\n", S.pty_name);
	fflush(out);

	/* --wait-host 1: the board powers up when the host first writes, so that a host which
	 * opens the port (and so empties its input) misses none of the board's output */
	while (S.wait_host && !g_stop) {
		struct pollfd p = {.fd = S.master, .events = POLLIN};
		if (poll(&p, 1, 100) > 0 && (p.revents & POLLIN))
			break;
	}
	double end_s = S.duration > 0 ? S.duration : S.n_samples / (double)S.rate_hz;
	avr_cycle_count_t end_cycle = (avr_cycle_count_t)ceil(end_s * S.freq);
	avr_cycle_count_t chunk = S.freq / 2000; /* 0.5 ms of emulated time between pty services */
	double wall0 = wall_now();
	int rc = 0;
	const char *why = "end of scene";
	if (S.duration > 0)
		why = "end of --duration";
	while (!g_stop) {
		avr_cycle_count_t target = S.avr->cycle + chunk;
		if (target > end_cycle)
			target = end_cycle;
		int state = cpu_Running;
		while (S.avr->cycle < target) {
			state = avr_run(S.avr);
			if (state == cpu_Done || state == cpu_Crashed)
				break;
		}
		service_pty(1);
		if (S.rx_open && S.in_len)
			uart_feed();
		if (state == cpu_Crashed) {
			why = "the firmware crashed";
			rc = 3;
			break;
		}
		if (state == cpu_Done) {
			why = "the firmware stopped (sleep with interrupts off)";
			break;
		}
		if (S.avr->cycle >= end_cycle)
			break;
		if (S.realtime > 0) {
			double ahead = emu_now() / S.realtime - (wall_now() - wall0);
			if (ahead > 0.001) {
				struct timespec ts = {(time_t)ahead, (long)((ahead - (time_t)ahead) * 1e9)};
				nanosleep(&ts, NULL);
			}
		}
	}
	if (g_stop)
		why = "signal";
	double real = wall_now() - wall0;
	double emu = emu_now();
	/* let the host read what is still pending, as long as it keeps reading */
	double idle_since = wall_now();
	int last_pending = -1;
	while (!g_stop && wall_now() - idle_since < EXIT_LINGER_S) {
		service_pty(0);
		int pending = 0;
		ioctl(S.slave, FIONREAD, &pending);
		pending += (int)S.out_len;
		if (!pending)
			break;
		if (pending != last_pending)
			idle_since = wall_now();
		last_pending = pending;
		usleep(2000);
	}
	fprintf(stderr,
		"skin_avr: timing: poll %llu marks, mean %.1f max %llu cycles; "
		"scan %llu marks, mean %.1f max %llu cycles; "
		"wait %llu marks, mean %.1f max %llu cycles\n",
		(unsigned long long)S.mark_n[0], S.mark_n[0] ? (double)S.mark_sum[0] / S.mark_n[0] : 0.0,
		(unsigned long long)S.mark_max[0], (unsigned long long)S.mark_n[1],
		S.mark_n[1] ? (double)S.mark_sum[1] / S.mark_n[1] : 0.0,
		(unsigned long long)S.mark_max[1], (unsigned long long)S.mark_n[2],
		S.mark_n[2] ? (double)S.mark_sum[2] / S.mark_n[2] : 0.0,
		(unsigned long long)S.mark_max[2]);
	fprintf(stderr,
		"skin_avr: %s: emulated %.3f s, %llu cycles, %llu bytes out, %llu bytes in, "
		"real %.3f s (%.2fx real time), waited %.3f s for the host, %llu latches\n",
		why, emu, (unsigned long long)S.avr->cycle, (unsigned long long)S.bytes_out,
		(unsigned long long)S.bytes_in, real, real > 0 ? emu / real : 0.0, S.waited_s,
		(unsigned long long)S.latches);
	close(S.master);
	close(S.slave);
	return rc;
}
