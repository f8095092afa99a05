# The simavr harness and its test program.
#   make -C firmware -f sim/sim.mk harness    -> build/host/skin_avr
#   make -C firmware -f sim/sim.mk testprog   -> build/sim/testprog_atmega328p.elf, ..._atmega2560.elf
#                                               (TESTPROG_DIR=... puts them elsewhere)
# Paths are relative to firmware/ (make -C firmware).

CC ?= cc
AVR_CC ?= avr-gcc
PKG_CONFIG ?= pkg-config
SIMAVR_CFLAGS := $(shell $(PKG_CONFIG) --cflags simavr simavrparts 2>/dev/null || echo -I/usr/include/simavr)
SIMAVR_LIBS := $(shell $(PKG_CONFIG) --libs simavr simavrparts 2>/dev/null || echo -lsimavr) -lelf -lutil -lm

HOST_CFLAGS ?= -O2 -g -Wall -Wextra -Wno-unused-parameter -std=gnu11
AVR_CFLAGS ?= -Os -Wall -Wextra -std=gnu11 -DF_CPU=16000000UL

HARNESS := build/host/skin_avr
TESTPROG_MCUS := atmega328p atmega2560
TESTPROG_DIR ?= build/sim
TESTPROGS := $(TESTPROG_MCUS:%=$(TESTPROG_DIR)/testprog_%.elf)

.PHONY: harness testprog all clean-sim
all: harness testprog
harness: $(HARNESS)
testprog: $(TESTPROGS)

$(HARNESS): sim/skin_avr.c sim/sim.mk
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) $(SIMAVR_CFLAGS) -o $@ $< $(SIMAVR_LIBS)

$(TESTPROG_DIR)/testprog_%.elf: sim/testprog/testprog.c sim/sim.mk
	@mkdir -p $(@D)
	$(AVR_CC) -mmcu=$* $(AVR_CFLAGS) -o $@ $<

clean-sim:
	rm -f $(HARNESS) $(TESTPROGS)
