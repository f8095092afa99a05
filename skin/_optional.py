"""Import optional dependencies at the point of use, with an install hint when they are missing."""

from __future__ import annotations

import importlib
from types import ModuleType

from skin.errors import MissingDependencyError

# import name -> (distribution name, extra of thermoskin that brings it)
_HINTS: dict[str, tuple[str, str]] = {
    "serial": ("pyserial", "serial"),
    "cobs": ("cobs", "serial"),
    "can": ("python-can", "can"),
    "sklearn": ("scikit-learn", "ml"),
    "hmmlearn": ("hmmlearn", "ml"),
    "skops": ("skops", "ml"),
    "pyvista": ("pyvista", "viz"),
    "matplotlib": ("matplotlib", "viz"),
    "imageio": ("imageio", "viz"),
    "mcap": ("mcap", "record"),
    "zstandard": ("zstandard", "record"),
    "foxglove": ("foxglove-sdk", "foxglove"),
    "zenoh": ("eclipse-zenoh", "zenoh"),
    "yourdfpy": ("yourdfpy", "urdf"),
    "rosbags": ("rosbags", "urdf"),
    "cantools": ("cantools", "dbc"),
}


def require(name: str, feature: str) -> ModuleType:
    """Import an optional module or fail with a hint naming the extra to install.

    Parameters
    ----------
    name : str
        Import name, such as ``"serial"`` or ``"pyvista"``.
    feature : str
        What the caller was doing, for the message (``"the serial driver"``).

    Returns
    -------
    module
        The imported module.

    Raises
    ------
    MissingDependencyError
        When the module cannot be imported.
    """
    try:
        return importlib.import_module(name)
    except ImportError as exc:
        dist, extra = _HINTS.get(name.split(".")[0], (name, "all"))
        raise MissingDependencyError(
            f"{feature} needs the package {dist!r}, which is not installed: "
            f"pip install 'thermoskin[{extra}]'"
        ) from exc
