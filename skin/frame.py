"""`Frame`: one sample of every taxel on one board, as a driver delivers it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Status flags carried in Frame.flags (protocol v0). Later protocol versions keep these bits.
FLAG_ADC_SATURATED = 1 << 0
FLAG_THERMISTOR_OPEN = 1 << 1
FLAG_HEATER_FAULT = 1 << 2
FLAG_OVER_TEMPERATURE = 1 << 3


@dataclass(frozen=True)
class Frame:
    """One sample of all taxels of a board.

    Attributes
    ----------
    seq : int
        Sequence number as sent by the device (wraps at 2**32).
    device_time : float
        Device clock at sampling, in seconds.
    host_time : float
        Host clock (``time.monotonic``) when the frame was decoded, in seconds.
    counts : numpy.ndarray
        Raw ADC counts, one per channel of the board (uint16).
    ambient : float
        Ambient temperature from the board's ambient sensor, in deg C.
    duty : numpy.ndarray
        Heater duty per channel, 0-255 (uint8).
    flags : int
        Board status flags (``FLAG_*``).
    board : int
        Board id, to merge several boards into one skin.
    """

    seq: int
    device_time: float
    host_time: float
    counts: np.ndarray
    ambient: float
    duty: np.ndarray
    flags: int = 0
    board: int = 0
