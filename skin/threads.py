"""Thread limits for the numerical hot paths (classifiers, fits).

numpy's BLAS and scikit-learn's OpenMP start one thread per core. On a machine where other
work runs, those threads wait for each other and a classifier runs 10-30 times slower than on
one thread (110 trials: 41 s instead of 1.5 s on 2 busy cores). The hot paths therefore run
inside `limited_threads`, which caps BLAS and OpenMP at ``SKIN_THREADS`` threads (default 1;
``0`` or ``all`` leaves them alone) through threadpoolctl, when it is installed (it comes with
scikit-learn). The caller's own limits are restored on the way out.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager

from skin.errors import SkinError

#: Environment variable with the number of BLAS/OpenMP threads of the hot paths.
ENV = "SKIN_THREADS"

_controller = None


def thread_count() -> int | None:
    """Threads the hot paths may use: ``SKIN_THREADS`` (default 1), None for no limit."""
    raw = os.environ.get(ENV, "1").strip().lower()
    if raw in ("0", "all", ""):
        return None
    try:
        n = int(raw)
    except ValueError:
        n = -1
    if n < 1:
        raise SkinError(f"{ENV}={raw!r}: give a number of threads >= 1, or 0 / all for no limit")
    return n


@contextmanager
def limited_threads() -> Iterator[None]:
    """Run the block with BLAS and OpenMP limited to `thread_count` threads."""
    global _controller
    n = thread_count()
    if n is None:
        yield
        return
    if _controller is None:
        try:
            from threadpoolctl import ThreadpoolController
        except ImportError:  # without it numpy's BLAS cannot be told; nothing else to do
            yield
            return
        _controller = ThreadpoolController()  # inspecting the loaded libraries costs ms: once
    with _controller.limit(limits=n):
        yield
