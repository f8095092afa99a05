/*
 * testprog.c - a small AVR program that exercises the skin board wiring
 * (firmware/README.md) so the simavr harness (firmware/sim/skin_avr.c) can be
 * tested without the real sketch.
 *
 * Commands from the host on UART0 (1 Mbaud), replies on UART0:
 *   'P'                     -> "P"                        ping
 *   'A' sel ch              -> 'A' u16 count              select mux channel sel (S0-S3), convert
 *                                                          ADC channel ch (internal 1.1 V reference)
 *   'Q' sel ch next         -> 'Q' u16 count              as 'A', but the select lines move to
 *                                                          `next` while the conversion runs (the
 *                                                          ADC's sample-and-hold keeps `sel`)
 *   'H' k byte*k            -> "H"                        shift k bytes over SPI, pulse the latch PB0
 *   'W' u16 ms              -> "W"                        busy-wait ms milliseconds
 *   'B' u16 kib             -> "B" 1024*kib bytes "E"     burst: byte i = (i + (i >> 8)) & 0xFF
 *   'U' u16 n               -> n x 0x55, 'U' u16 ticks    the time the n bytes took to queue,
 *                                                          in 4 us ticks of Timer1 (F_CPU / 64)
 * On reset it sends "READY\n".
 */
#include <avr/io.h>
#include <stdint.h>
#include <util/delay.h>

#if defined(__AVR_ATmega2560__)
#define SEL_PORT PORTA
#define SEL_DDR DDRA
#define SEL_SHIFT 0
#define SPI_DDR_BITS (_BV(PB2) | _BV(PB1) | _BV(PB0)) /* MOSI, SCK, latch (= SS) */
#define REF_INTERNAL _BV(REFS1)                         /* 10: internal 1.1 V */
#else
#define SEL_PORT PORTD
#define SEL_DDR DDRD
#define SEL_SHIFT 4
#define SPI_DDR_BITS (_BV(PB3) | _BV(PB5) | _BV(PB0) | _BV(PB2)) /* MOSI, SCK, latch, SS */
#define REF_INTERNAL (_BV(REFS1) | _BV(REFS0))                    /* 11: internal 1.1 V */
#endif
#define SEL_MASK (0x0F << SEL_SHIFT)

static void uart_put(uint8_t b)
{
	while (!(UCSR0A & _BV(UDRE0)))
		;
	UDR0 = b;
}

static uint8_t uart_get(void)
{
	while (!(UCSR0A & _BV(RXC0)))
		;
	return UDR0;
}

static void put_u16(uint16_t v)
{
	uart_put(v & 0xFF);
	uart_put(v >> 8);
}

static void select_mux(uint8_t sel)
{
	SEL_PORT = (SEL_PORT & ~SEL_MASK) | ((sel & 0x0F) << SEL_SHIFT);
}

static void adc_start(uint8_t ch)
{
	ADMUX = REF_INTERNAL | (ch & 0x07);
	ADCSRA |= _BV(ADSC);
}

static uint16_t adc_finish(void)
{
	while (ADCSRA & _BV(ADSC))
		;
	return ADC;
}

static void spi_byte(uint8_t b)
{
	SPDR = b;
	while (!(SPSR & _BV(SPIF)))
		;
}

int main(void)
{
	UCSR0A = _BV(U2X0);
	UBRR0 = 1; /* 16 MHz / (8 * (1 + 1)) = 1 Mbaud */
	UCSR0B = _BV(RXEN0) | _BV(TXEN0);
	UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);

	SEL_DDR |= SEL_MASK;
	DDRB |= SPI_DDR_BITS;
	PORTB &= ~_BV(PB0);
	SPCR = _BV(SPE) | _BV(MSTR); /* fosc / 4 */

	ADCSRA = _BV(ADEN) | _BV(ADPS2) | _BV(ADPS1) | _BV(ADPS0); /* 125 kHz */

	for (const char *s = "READY\n"; *s; s++)
		uart_put(*s);

	for (;;) {
		uint8_t cmd = uart_get();
		switch (cmd) {
		case 'P':
			uart_put('P');
			break;
		case 'A':
		case 'Q': {
			uint8_t sel = uart_get();
			uint8_t ch = uart_get();
			uint8_t next = cmd == 'Q' ? uart_get() : sel;
			select_mux(sel);
			_delay_us(5); /* settling */
			adc_start(ch);
			select_mux(next);
			uint16_t v = adc_finish();
			uart_put(cmd);
			put_u16(v);
			break;
		}
		case 'H': {
			uint8_t k = uart_get();
			uint8_t buf[16];
			for (uint8_t i = 0; i < k && i < sizeof buf; i++)
				buf[i] = uart_get();
			for (uint8_t i = 0; i < k && i < sizeof buf; i++)
				spi_byte(buf[i]);
			PORTB |= _BV(PB0);
			PORTB &= ~_BV(PB0);
			uart_put('H');
			break;
		}
		case 'W': {
			uint16_t ms = uart_get();
			ms |= (uint16_t)uart_get() << 8;
			while (ms--)
				_delay_ms(1);
			uart_put('W');
			break;
		}
		case 'B': {
			uint16_t kib = uart_get();
			kib |= (uint16_t)uart_get() << 8;
			uint32_t n = (uint32_t)kib * 1024;
			uart_put('B');
			for (uint32_t i = 0; i < n; i++)
				uart_put((uint8_t)(i + (i >> 8)));
			uart_put('E');
			break;
		}
		case 'U': {
			uint16_t n = uart_get();
			n |= (uint16_t)uart_get() << 8;
			TCCR1A = 0;
			TCCR1B = _BV(CS11) | _BV(CS10);
			TCNT1 = 0;
			while (n--)
				uart_put(0x55);
			uint16_t ticks = TCNT1;
			uart_put('U');
			put_u16(ticks);
			break;
		}
		default:
			uart_put('?');
			break;
		}
	}
}
