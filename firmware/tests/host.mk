# Host tests and AVR size of the protocol library (firmware/lib/skinproto).
#
#   make -C firmware -f tests/host.mk host-test   build build/host/test_proto with g++ and run it
#                                                 against test_vectors/ (also checks that
#                                                 skin_proto.c compiles warning-free as C and C++)
#                                                 and build/host/test_control (the heater
#                                                 control on a simulated thermal plant)
#   make -C firmware -f tests/host.mk avr-size    compile skin_proto.c with -Os for the ATmega328P
#                                                 and the ATmega2560 and print its size
#
# Paths are relative to firmware/ (the directory make runs in).

ifeq ($(origin CC),default)
CC := gcc
endif
ifeq ($(origin CXX),default)
CXX := g++
endif
AVR_CC ?= avr-gcc
AVR_SIZE ?= avr-size

PROTO_DIR := lib/skinproto
PROTO_SRC := $(PROTO_DIR)/skin_proto.c
PROTO_HDR := $(PROTO_DIR)/skin_proto.h
TEST_SRC := tests/test_proto.cpp
VECTOR_DIR := $(CURDIR)/test_vectors
HOST_DIR := build/host
AVR_DIR := build/avr
AVR_MCUS := atmega328p atmega2560

WARN := -Wall -Wextra -Werror
SANITIZE := -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=all
HOST_CFLAGS := -std=c99 -pedantic $(WARN) -O2 $(SANITIZE) -I$(PROTO_DIR)
HOST_CXXFLAGS := -std=c++17 $(WARN) -O2 $(SANITIZE) -I$(PROTO_DIR) \
	-DSKIN_VECTOR_DIR='"$(VECTOR_DIR)"'
AVR_CFLAGS := -Os -std=gnu99 $(WARN) -ffunction-sections -fdata-sections -I$(PROTO_DIR)

.PHONY: host-test host-build avr-size clean-host

host-test: $(HOST_DIR)/test_proto $(HOST_DIR)/test_control
	$(HOST_DIR)/test_proto $(VECTOR_DIR)
	$(HOST_DIR)/test_control

host-build: $(HOST_DIR)/test_proto

$(HOST_DIR)/skin_proto.o: $(PROTO_SRC) $(PROTO_HDR)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) -c $< -o $@

# The library compiled as C++ too (the firmware's sketches include it from C++); not linked.
$(HOST_DIR)/skin_proto_cxx.o: $(PROTO_SRC) $(PROTO_HDR)
	@mkdir -p $(@D)
	$(CXX) -x c++ -std=c++17 $(WARN) -O2 -I$(PROTO_DIR) -c $< -o $@

$(HOST_DIR)/test_proto.o: $(TEST_SRC) $(PROTO_HDR)
	@mkdir -p $(@D)
	$(CXX) $(HOST_CXXFLAGS) -c $< -o $@

$(HOST_DIR)/test_proto: $(HOST_DIR)/test_proto.o $(HOST_DIR)/skin_proto.o $(HOST_DIR)/skin_proto_cxx.o
	$(CXX) $(SANITIZE) -o $@ $(HOST_DIR)/test_proto.o $(HOST_DIR)/skin_proto.o

# The heater control (lib/skincontrol) against a simulated thermal plant.
CONTROL_DIR := lib/skincontrol
$(HOST_DIR)/skin_control.o: $(CONTROL_DIR)/skin_control.c $(CONTROL_DIR)/skin_control.h $(PROTO_HDR)
	@mkdir -p $(@D)
	$(CC) $(HOST_CFLAGS) -I$(CONTROL_DIR) -c $< -o $@

$(HOST_DIR)/test_control: tests/test_control.cpp $(HOST_DIR)/skin_control.o $(HOST_DIR)/skin_proto.o
	$(CXX) -std=c++17 $(WARN) -O2 $(SANITIZE) -I$(PROTO_DIR) -I$(CONTROL_DIR) -o $@ $^

$(AVR_DIR)/%/skin_proto.o: $(PROTO_SRC) $(PROTO_HDR)
	@mkdir -p $(@D)
	$(AVR_CC) -mmcu=$* $(AVR_CFLAGS) -c $< -o $@

avr-size: $(foreach m,$(AVR_MCUS),$(AVR_DIR)/$(m)/skin_proto.o)
	$(AVR_SIZE) $^

clean-host:
	rm -rf $(HOST_DIR) $(AVR_DIR)
