"""thermoskin: material recognition from heat transfer across a skin of heated taxels.

``import skin`` loads numpy alone; the drivers (``skin.drivers``), models (``skin.models``) and
views (``skin.viz``) load their own dependencies when used.
"""

from skin.contact import UNKNOWN, Contact, MaterialEstimate, TaxelWindow
from skin.errors import (
    CalibrationError,
    DeviceError,
    LayoutError,
    MaterialsError,
    MissingDependencyError,
    ProtocolError,
    SceneError,
    SkinError,
)
from skin.formats.layout import Board, Layout, Taxel, load_layout, parse_layout
from skin.frame import Frame
from skin.runner import Skin
from skin.setup import Setup
from skin.stream.calibration import Calibration
from skin.stream.onset import DetectorState, OnsetDetector, OnsetEvent
from skin.stream.onset_refine import refine_onset
from skin.stream.pipeline import ContactResult, Pipeline
from skin.stream.tracking import ContactTracker

__version__ = "0.1.0"

__all__ = [
    "UNKNOWN",
    "Board",
    "Calibration",
    "CalibrationError",
    "Contact",
    "ContactResult",
    "ContactTracker",
    "DetectorState",
    "DeviceError",
    "Frame",
    "Layout",
    "LayoutError",
    "MaterialEstimate",
    "MaterialsError",
    "MissingDependencyError",
    "OnsetDetector",
    "OnsetEvent",
    "Pipeline",
    "ProtocolError",
    "SceneError",
    "Setup",
    "Skin",
    "SkinError",
    "Taxel",
    "TaxelWindow",
    "load_layout",
    "parse_layout",
    "refine_onset",
]
