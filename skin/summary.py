"""Median and 95th percentile: how every benchmark summarises a spread of figures."""

from __future__ import annotations

import numpy as np


def median_p95(values, scale: float = 1.0, digits: int = 4) -> dict:
    """Return ``{"median": ..., "p95": ...}`` of ``values`` times ``scale``, rounded.

    Both are None when there are no values.
    """
    v = np.asarray(values, dtype=float) * scale
    if v.size == 0:
        return {"median": None, "p95": None}
    return {"median": round(float(np.median(v)), digits),
            "p95": round(float(np.percentile(v, 95)), digits)}
