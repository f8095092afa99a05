# Builds one sketch with Debian's arduino-mk; called by firmware/Makefile with BOARD_TAG, OBJDIR
# and SKIN_DEFS set. Debian's gcc-avr 5.4 needs gnu++11 and DECIMAL_DIG for the 1.8.7 core.
ARDUINO_DIR = /usr/share/arduino
ARDMK_DIR = /usr/share/arduino
AVR_TOOLS_DIR = /usr
ARDUINO_SKETCHBOOK = $(realpath ..)
USER_LIB_PATH = $(realpath ../lib)
ARDUINO_LIBS = skinproto skincontrol skinboard
CFLAGS_STD = -std=gnu11
CXXFLAGS_STD = -std=gnu++11
CPPFLAGS += -DDECIMAL_DIG=17 -Wall -Wextra $(SKIN_DEFS)
include /usr/share/arduino/Arduino.mk
