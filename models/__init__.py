"""Heat-transfer physics, the materials table, and the classifiers all taxels share."""

from skin.models.effusivity import HistogramClassifier
from skin.models.joint import JointClassifier, JointContactModel
from skin.models.materials import Material, load_materials
from skin.models.physics import (
    SensorConstants,
    contact_temperature,
    depth_response,
    effusivity,
    effusivity_estimates,
    heated_temperature,
    thermistor_temperature,
)

__all__ = [
    "HistogramClassifier",
    "JointClassifier",
    "JointContactModel",
    "Material",
    "SensorConstants",
    "contact_temperature",
    "depth_response",
    "effusivity",
    "effusivity_estimates",
    "heated_temperature",
    "load_materials",
    "thermistor_temperature",
]
