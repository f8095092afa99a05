"""`Frame`: one sample of every taxel on one board, as a driver delivers it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Board flags carried in Frame.flags (wire protocol v1, firmware/PROTOCOL.md). Bits 0-3 are the
# OR of every taxel's status bits (Frame.status), which use the same four bits.
FLAG_ADC_SATURATED = 1 << 0
FLAG_THERMISTOR_FAULT = 1 << 1
FLAG_HEATER_FAULT = 1 << 2
FLAG_OVER_TEMPERATURE = 1 << 3
FLAG_AMBIENT_FAULT = 1 << 4
FLAG_POWER_LIMITED = 1 << 5
FLAG_TX_OVERRUN = 1 << 6
FLAG_SAMPLE_OVERRUN = 1 << 7
FLAG_SELFTEST = 1 << 8
FLAG_STREAMING = 1 << 9
#: The bits a taxel's status can hold.
TAXEL_STATUS_BITS = 0xF


@dataclass(frozen=True)
class Frame:
    """One sample of all taxels of a board.

    Attributes
    ----------
    seq : int
        Sequence number as sent by the device (wraps at 2**32).
    device_time : float
        Device clock at sampling, in seconds (a decoder gives the board's u32 microsecond
        clock, which wraps every 71.6 min; a driver's ``recv`` gives it unwrapped).
    host_time : float
        Host clock (``time.monotonic``), s: a decoder gives the arrival time; a driver's
        ``recv`` gives the host time at sampling, mapped from the device time by the board's
        clock map (`skin.drivers.clock`), the time base several boards and buses share.
    counts : numpy.ndarray
        Raw ADC counts, one per channel of the board (uint16).
    ambient : float
        Ambient temperature from the board's ambient sensor, in deg C (NaN when the board
        does not know it).
    duty : numpy.ndarray
        Heater duty per channel, 0-255 (uint8).
    flags : int
        Board status flags (``FLAG_*``).
    board : int
        Board id, to merge several boards into one skin.
    status : numpy.ndarray or None
        The 4 status bits of each channel (uint8, the ``FLAG_*`` bits 0-3), when the source
        reports them.
    force : numpy.ndarray or None
        Normal force on each channel, N (float64, one per channel like ``counts``), when the
        board has a force or contact sensor (wire: a FORCE message after the SAMPLE,
        firmware/PROTOCOL.md): NaN where that channel has no reading (no sensor under the
        taxel, or the board's FORCE message for this sample was lost). A contact switch
        reports 0 (free) or 1 (touched) in the same field. None: the source has no force
        channel at all (most boards; every frame before this field existed). Per channel, not
        per board, because touches are dated per taxel (`skin.models.commission`).
    duty_known : numpy.ndarray or None
        Which channels' ``duty`` the source has heard (bool, one per channel), where it has
        not heard them all yet: a CAN node sends each group of 8 duties in its own message,
        and until a group's first arrives its duties read 0 in ``duty`` without being known
        (`skin.stream.assembly` gives them as NaN). None: every duty known.
    """

    seq: int
    device_time: float
    host_time: float
    counts: np.ndarray
    ambient: float
    duty: np.ndarray
    flags: int = 0
    board: int = 0
    status: np.ndarray | None = None
    force: np.ndarray | None = None
    duty_known: np.ndarray | None = None
