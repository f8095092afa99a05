"""Benchmarks, evaluations and fuzzers: tools that measure the runtime, never imported by it.

`skin bench ...`, `skin evaluate-onset` and `skin evaluate --ceiling` run them. Each module
prints figures (error or accuracy beside cost) rather than asserting them.
"""

from __future__ import annotations


def machine() -> dict:
    """Describe the machine the figures come from."""
    import os
    import platform

    import numpy as np

    return {"platform": platform.platform(), "python": platform.python_version(),
            "numpy": np.__version__, "cpus": os.cpu_count()}
