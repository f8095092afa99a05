"""BLAS/OpenMP thread limits in the classifiers' hot paths (issue 20 item 10)."""

import json
import os
import subprocess
import sys

import pytest

pytest.importorskip("threadpoolctl")

PROBE = """
import json
import numpy as np
from threadpoolctl import threadpool_info
from skin.models.learned import LearnedClassifier

def threads():
    return max([i["num_threads"] for i in threadpool_info()] or [0])

class Recorder:
    classes_ = np.array(["a", "b"])
    def predict_proba(self, x):
        self.seen = threads()
        return np.full((len(x), 2), 0.5)

rec = Recorder()
clf = LearnedClassifier({"estimator": rec, "features": {"fs": 200.0, "duration": 0.05},
                         "method": "probe"})
clf._predict(np.zeros((3, 12)))
print(json.dumps({"outside": threads(), "inside": rec.seen}))
"""


def probe(**env):
    clean = {k: v for k, v in os.environ.items()
             if k not in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                          "SKIN_THREADS")}
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True,
                         env={**clean, **env}, check=True)
    return json.loads(out.stdout)


def test_a_learned_model_predicts_on_one_blas_thread_unless_told_otherwise():
    free = probe()
    if free["outside"] < 2:
        pytest.skip("one core: BLAS starts one thread anyway")
    # before: the model's predict ran on every core's thread (10-30x slower on busy cores)
    assert free["inside"] == 1
    assert probe(SKIN_THREADS="2")["inside"] == 2
    assert probe(SKIN_THREADS="all")["inside"] == free["outside"]


@pytest.mark.parametrize("value", ["-1", "two", "1.5"])
def test_a_bad_thread_setting_is_a_clear_error(monkeypatch, value):
    from skin.errors import SkinError
    from skin.threads import thread_count

    monkeypatch.setenv("SKIN_THREADS", value)
    with pytest.raises(SkinError, match="SKIN_THREADS"):
        thread_count()
