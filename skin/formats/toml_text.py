"""Values as TOML text: the one writer behind layout, chain and skin files."""

from __future__ import annotations

import json
from typing import Any

import numpy as np


def toml_value(value: Any, digits: int | None = None) -> str:
    """Return ``value`` (str, bool, int, float, or a list of them, nested) as TOML text.

    Parameters
    ----------
    value : str, bool, int, float, numpy scalar, list or tuple
        The value; a numpy array is a list.
    digits : int, optional
        Significant digits of floats (12 writes 30.0 rather than 29.999999999999996);
        default: exact (``repr``, which round-trips). ``-0.0`` only when exact.

    Raises
    ------
    TypeError
        For a value TOML cannot hold (None, a dict...).
    """
    if isinstance(value, str):
        # a JSON string is a TOML basic string, once control characters are escaped (json does)
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        if digits is None:
            number = float(value)  # exact, -0.0 included
        else:
            number = float(f"{float(value):.{digits}g}") + 0.0  # + 0.0: no -0.0
        if not np.isfinite(number):
            return {np.inf: "inf", -np.inf: "-inf"}.get(number, "nan")
        return repr(number)
    if isinstance(value, list | tuple | np.ndarray):
        return "[" + ", ".join(toml_value(v, digits) for v in value) + "]"
    raise TypeError(f"no TOML form for {type(value).__name__}")
