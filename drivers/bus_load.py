"""What protocol v1 costs on each bus: frame sizes, bytes per second, bus load, taxel limits.

Plain arithmetic from ``firmware/PROTOCOL.md``; ``skin bench bus`` prints it. A serial byte takes
10 bit times (8N1). A classic CAN data frame with an 11-bit identifier and d data bytes takes
47 + 8d bits (interframe space included) plus stuff bits: none at best, (34 + 8d - 1) // 4 at
worst.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

#: Bytes of a SAMPLE body (version .. flags) besides its 3 bytes per taxel, plus the CRC.
_SAMPLE_FIXED = 16 + 2
#: Taxels one CAN node carries (32 DATA groups of 4).
CAN_MAX_TAXELS = 128


def serial_sample_bytes(n: int) -> int:
    """Bytes of one SAMPLE of ``n`` taxels on the wire: body, CRC, COBS overhead, delimiter."""
    packet = _SAMPLE_FIXED + 3 * n
    return packet + math.ceil(packet / 254) + 1


def serial_force_bytes(n: int) -> int:
    """Bytes of one FORCE of ``n`` taxels on the wire (a board with a force channel)."""
    packet = 8 + 2 * n + 2
    return packet + math.ceil(packet / 254) + 1


def can_sample_dlcs(n: int, force: bool = False) -> list[int]:
    """Return the data lengths of one sample's CAN frames: SYNC, DATA groups, DUTY, STATUS.

    With ``force``, the FORCE groups (as many and as long as the DATA groups) before STATUS.
    """
    data = [8] * (n // 4) + ([2 * (n % 4)] if n % 4 else [])
    duty = 8 if n >= 8 else n
    return [8, *data, duty, *(data if force else []), 6]


def can_frame_bits(dlc: int, worst: bool = True) -> int:
    """Bits of a classic CAN data frame with an 11-bit identifier, with worst-case stuffing."""
    return 47 + 8 * dlc + ((34 + 8 * dlc - 1) // 4 if worst else 0)


@dataclass(frozen=True)
class BusLoad:
    """One sample stream on one bus.

    Attributes
    ----------
    bus : str
        ``"serial"`` or ``"can"``.
    bit_rate : int
        Baud rate or CAN bit rate, bit/s.
    taxels : int
        Taxels per board (per CAN node).
    rate_hz : float
        Sample rate.
    frame_bytes : int
        Serial: bytes per sample on the wire. CAN: data bytes of the sample's frames.
    frames : int
        Frames per sample (serial: packets, 1, or 2 with the force channel).
    bits_per_sample : int
        Bus bits per sample (serial: 10 per byte; CAN: worst-case stuffing).
    bytes_per_s : float
        ``frame_bytes`` x rate.
    load : float
        Fraction of the bus the stream takes (CAN: worst case).
    load_best : float
        CAN without stuff bits (serial: same as ``load``).
    max_taxels : int
        Most taxels one board streams at ``rate_hz`` in at most 95 % of the bus (5 % kept for
        replies), worst-case stuffing; a CAN node also stops at 128.
    """

    bus: str
    bit_rate: int
    taxels: int
    rate_hz: float
    frame_bytes: int
    frames: int
    bits_per_sample: int
    bytes_per_s: float
    load: float
    load_best: float
    max_taxels: int

    def as_dict(self) -> dict:
        """Plain values, for JSON."""
        return asdict(self)


def _fits(bus: str, n: int, bit_rate: int, rate_hz: float, force: bool = False) -> bool:
    if bus == "serial":
        size = serial_sample_bytes(n) + (serial_force_bytes(n) if force else 0)
        return size * 10 * rate_hz <= 0.95 * bit_rate
    bits = sum(can_frame_bits(d) for d in can_sample_dlcs(n, force))
    return n <= CAN_MAX_TAXELS and bits * rate_hz <= 0.95 * bit_rate


def bus_load(bus: str, bit_rate: int, taxels: int, rate_hz: float = 200.0,
             force: bool = False) -> BusLoad:
    """Load of one board's sample stream on a bus.

    Parameters
    ----------
    bus : str
        ``"serial"`` or ``"can"``.
    bit_rate : int
        Baud rate or CAN bit rate, bit/s.
    taxels : int
        Taxels on the board.
    rate_hz : float
        Sample rate.
    force : bool
        The board also sends its force channel (serial FORCE, CAN FORCE frames).
    """
    if bus not in ("serial", "can"):
        raise ValueError(f"bus must be 'serial' or 'can', got {bus!r}")
    if taxels < 0 or bit_rate <= 0 or rate_hz <= 0:
        raise ValueError("taxels must be >= 0, bit_rate and rate_hz > 0")
    if bus == "serial":
        size = serial_sample_bytes(taxels) + (serial_force_bytes(taxels) if force else 0)
        frames = 2 if force else 1
        bits, best = 10 * size, 10 * size
    else:
        dlcs = can_sample_dlcs(taxels, force)
        size, frames = sum(dlcs), len(dlcs)
        bits = sum(can_frame_bits(d) for d in dlcs)
        best = sum(can_frame_bits(d, worst=False) for d in dlcs)
    limit = 0
    while _fits(bus, limit + 1, bit_rate, rate_hz, force) and limit < 100_000:
        limit += 1
    return BusLoad(bus, bit_rate, taxels, rate_hz, size, frames, bits, size * rate_hz,
                   bits * rate_hz / bit_rate, best * rate_hz / bit_rate, limit)


#: The buses and board sizes of the firmware issue's closing note.
STANDARD_BUSES = (("serial", 115_200), ("serial", 1_000_000), ("can", 500_000), ("can", 1_000_000))


def bus_table(taxels: tuple[int, ...] = (16, 64), rate_hz: float = 200.0,
              force: bool = False) -> list[BusLoad]:
    """`bus_load` for every standard bus and board size (with the force channel: ``force``)."""
    return [bus_load(bus, rate, n, rate_hz, force) for bus, rate in STANDARD_BUSES
            for n in taxels]


#: The firmware's cycle costs per sample (firmware/lib/skinboard/skin_config.h, fitted to
#: `skin bench firmware`'s emulated measurements): a conversion's interrupt, a channel switch,
#: a force conversion's extra, and the main loop (fixed, per taxel, per force input).
CONV_CYCLES, SWITCH_CYCLES, FORCE_EXTRA_CYCLES = 88, 112, 240
LOOP_CYCLES, LOOP_TAXEL_CYCLES, LOOP_FORCE_CYCLES = 7000, 850, 1100
F_CPU = 16_000_000


def sample_cycles(taxels: int, oversampling: int = 1, force_inputs: int = 0,
                  prescaler: int = 64, force_prescaler: int = 16) -> int:
    """Return the CPU cycles one AVR board needs per sample (the firmware's max-rate formula).

    The larger of the scan (each of the ``taxels + 1`` channels, the ambient sensor included:
    ``oversampling`` conversions of 13 ADC clocks plus `CONV_CYCLES`, and `SWITCH_CYCLES`; each
    force input one conversion at ``force_prescaler`` plus `FORCE_EXTRA_CYCLES`) and the main
    loop's work (`LOOP_CYCLES` + per taxel + per force input).

    Parameters
    ----------
    taxels, oversampling, force_inputs : int
        The build's SKIN_TAXELS, SKIN_OVERSAMPLING and SKIN_FORCE_INPUTS.
    prescaler, force_prescaler : int
        SKIN_ADC_PRESCALER and SKIN_FORCE_PRESCALER.

    Returns
    -------
    int
        Cycles of the 16 MHz MCU.
    """
    scan = ((taxels + 1) * oversampling * (13 * prescaler + CONV_CYCLES)
            + (taxels + 1) * SWITCH_CYCLES + force_inputs * (13 * force_prescaler
                                                             + FORCE_EXTRA_CYCLES))
    loop = LOOP_CYCLES + taxels * LOOP_TAXEL_CYCLES + force_inputs * LOOP_FORCE_CYCLES
    return max(scan, loop)


def adc_max_rate(taxels: int, oversampling: int = 1, force_inputs: int = 0) -> int:
    """Return the board's highest rate, Hz: IDENTITY's ``max_rate_hz`` before the link's limit.

    95 % of the period holds `sample_cycles` (the firmware's SKIN_MAX_RATE_ADC).
    """
    return F_CPU // 100 * 95 // sample_cycles(taxels, oversampling, force_inputs)


def adc_max_taxels(rate_hz: float = 200.0, oversampling: int = 1, force: bool = False) -> int:
    """Return the most taxels one AVR board converts and handles per sample at ``rate_hz``.

    With ``force`` every taxel has a force input (one more conversion each). Counts as the
    firmware's max-rate formula does (`sample_cycles`: 95 % of the period).
    """
    n = 0
    while n < 255 and adc_max_rate(n + 1, oversampling, n + 1 if force else 0) >= rate_hz:
        n += 1
    return n
