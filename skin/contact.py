"""The plain types passed from contact tracking to classification and on to the views."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

UNKNOWN = "unknown"


@dataclass(frozen=True)
class TaxelWindow:
    """The temperature of one taxel from the onset of a contact on.

    Attributes
    ----------
    taxel : int
        Taxel id.
    onset : float
        Refined onset of this taxel, s (device time).
    initial : float
        Sensor temperature just before contact, deg C.
    time : numpy.ndarray
        Time since ``onset`` of each sample, s (all >= 0).
    temperature : numpy.ndarray
        Readings, deg C.
    released : bool
        Whether the taxel was released within the window (else the window was cut).
    dated_by : str
        What dated its onset: ``"thermal"`` (the onset detector, refined) or ``"force"``
        (the taxel's force channel, `skin.stream.force`).
    """

    taxel: int
    onset: float
    initial: float
    time: np.ndarray
    temperature: np.ndarray
    released: bool
    dated_by: str = "thermal"


@dataclass
class Contact:
    """One contact: neighbouring taxels that touched one object at about the same time.

    Attributes
    ----------
    id : int
        Running number.
    taxels : list of int
        Taxel ids.
    onset : float
        Onset of the contact (median of its taxels' onsets), s.
    release : float or None
        When the last taxel was released, s; None if still touching when it was decided.
    ambient : float
        Mean ambient temperature over the contact, deg C.
    windows : list of TaxelWindow
        One per taxel.
    decided_at : float
        Device time at which the contact was handed on for classification, s.
    final : bool
        False for a provisional snapshot of a contact still open (an anytime answer; the final
        one follows with the same ``id``).
    """

    id: int
    taxels: list[int]
    onset: float
    release: float | None
    ambient: float
    windows: list[TaxelWindow] = field(repr=False)
    decided_at: float = 0.0
    final: bool = True

    @property
    def duration(self) -> float | None:
        """Length of the contact, s; None while it has not been released."""
        return None if self.release is None else max(0.0, self.release - self.onset)


@dataclass(frozen=True)
class MaterialEstimate:
    """What a classifier says about a contact.

    Attributes
    ----------
    label : str
        Material name, or ``"unknown"``.
    probabilities : dict
        Material name -> probability (sums to 1 over the candidates, or empty when unknown).
    confidence : float
        Confidence in ``label``, 0-1.
    effusivity : float or None
        Effusivity estimate, W s^0.5 / (m^2 K), where the method gives one.
    method : str
        Name of the method.
    family : str or None
        The material's family (``"wood_paper"``), named when the material is not
        resolvable but its family is, ``"unknown"`` when neither is; None: not given.
    family_confidence : float
        Probability of the most probable family.
    note : str
        Why the answer is what it is, when it is not the classifier's own ("no thermal
        response: ..." for a force-dated contact whose temperature shows no contact,
        `skin.stream.response`); "" otherwise.
    """

    label: str
    probabilities: dict[str, float]
    confidence: float
    effusivity: float | None
    method: str
    family: str | None = None
    family_confidence: float = 0.0
    note: str = ""
