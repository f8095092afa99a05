"""The error hierarchy: every error the library raises on purpose is a `SkinError`."""

from __future__ import annotations


class SkinError(Exception):
    """Base class of every error raised by thermoskin."""


class LayoutError(SkinError):
    """A layout file is malformed; the message names the file, the taxel and the field."""


class SceneError(SkinError):
    """A simulation scene file is malformed; the message names the file and the entry."""


class CalibrationError(SkinError):
    """Calibration data is missing or inconsistent with the layout."""


class ProtocolError(SkinError):
    """A board refused a command or did not answer it (readers count bad bytes, never raise)."""


class DeviceError(SkinError):
    """A device URL cannot be opened or the device stopped answering."""


class MaterialsError(SkinError):
    """The materials table is malformed or a material is unknown."""


class MissingDependencyError(SkinError, ImportError):
    """An optional dependency is needed for the feature that was used."""


class ViewError(SkinError):
    """A view cannot be made or shown: an arm file or mesh, a pose, or no display to show it on."""


class SensorError(SkinError):
    """A sensor description is malformed or unknown; the message names the file and line."""
