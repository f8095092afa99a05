"""The contact-versus-disturbance template test and its measurement (skin bench onset-shape)."""

from __future__ import annotations

import numpy as np
import pytest

from skin.bench.onset_shape import ShapeTest, _box, shape_separability
from skin.models.physics import contact_response
from skin.models.sensors import apply_dynamics, load_sensor, smooth


def _reading(sensor: object, shape: str, t_on: float, seconds: float) -> np.ndarray:
    fs = sensor.sample_rate
    t = np.arange(0.0, seconds, 1.0 / fs)
    since = np.maximum(t - t_on, 0.0)
    if shape == "contact":
        step = contact_response(since, np.inf, sensor)
    else:  # a gust: the face cools over 2 s
        step = -np.expm1(-since / 2.0)
    y = 35.0 - 2.0 * np.where(t > t_on, step, 0.0)
    rng = np.random.default_rng(1)
    y = smooth(apply_dynamics(y, sensor, fs), sensor, fs=fs)
    return y + 0.002 * rng.standard_normal(y.size)


def test_a_contact_fits_the_contact_template_and_a_gust_the_disturbance_one() -> None:
    sensor = load_sensor("paper")
    test = ShapeTest(sensor, 1.0)
    n = test.rows * test.decimation
    contact = _box(_reading(sensor, "contact", 0.6, n / sensor.sample_rate)[:, None],
                   test.decimation)
    gust = _box(_reading(sensor, "gust", 0.6, n / sensor.sample_rate)[:, None],
                test.decimation)
    energy, versus, sign, onset = test.test(np.hstack([contact, gust]))
    assert sign[0] == -1 and energy[0] > 100
    assert versus[0] > 10 > versus[1]
    assert abs(onset[0] * test.row_time - 0.6) < 3 * test.row_time


def test_the_templates_follow_the_sensor() -> None:
    slow, fast = ShapeTest(load_sensor("pid-logger")), ShapeTest(load_sensor("fast-film"))
    assert slow.window > 5 * fast.window
    assert slow.rows <= 100 and fast.rows <= 100


def test_shape_separability_reports_its_figures() -> None:
    out = shape_separability(load_sensor("paper"), seed=0, minutes=1.0, n_taxels=2, window=1.0)
    assert out["free_taxel_hours"] > 0
    for name in ("energy", "versus"):
        assert out[name]["free_alarms_per_taxel_hour"] <= 0.1 + 1e-9
        assert set(out[name]["detected_within_s"]) == {"1", "2", "4"}


def test_skin_bench_onset_shape_prints_one_json_document(capsys) -> None:
    import json

    from skin.cli import main

    assert main(["bench", "onset-shape", "--sensor", "fast-film", "--minutes", "0.5",
                 "--taxels", "2", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["sensor"] == "fast-film" and "energy" in doc and "versus" in doc


def test_a_gusts_recovery_fits_the_contact_template_as_a_rise() -> None:
    # through a PID loop a gust's recovery (the face warming back, overshooting) looks like a
    # contact turned over: it fits the contact template well, with the sign of a rise, which
    # is why shape_separability counts only falls in the contact-free windows too
    sensor = load_sensor("pid-logger")
    test = ShapeTest(sensor, 2.0)
    fs = sensor.sample_rate
    t = np.arange(0.0, 12.0, 1.0 / fs)
    s = np.maximum(t - 5.0, 0.0)
    shape = np.where(s < 2.0, -np.expm1(-s), -np.expm1(-2.0) * np.exp(-(s - 2.0)))
    y = smooth(apply_dynamics(35.0 - 0.3 * np.where(t > 5.0, shape, 0.0), sensor, fs), sensor,
               fs=fs)
    y = y + 0.001 * np.random.default_rng(1).standard_normal(y.size)
    rows = _box(y[:, None], test.decimation)
    end = int(7.5 / test.row_time)  # the window ends half a second into the recovery
    energy, versus, sign, _ = test.test(rows[end - test.rows:end])
    assert sign[0] == 1 and energy[0] > 100 and versus[0] > 10


def test_shape_separability_on_the_common_mode_free_reading() -> None:
    sensor = load_sensor("pid-logger")
    kw = {"seed": 0, "minutes": 1.0, "n_taxels": 4, "window": 2.0}
    raw = shape_separability(sensor, **kw)
    free = shape_separability(sensor, common_mode=True, **kw)
    assert raw["common_mode"] is False and free["common_mode"] is True
    assert raw["contacts_5sigma"] == free["contacts_5sigma"]  # the same stream
    for name in ("energy", "versus"):
        assert free[name]["free_alarms_per_taxel_hour"] <= 0.1 + 1e-9
        # a different reading: the room's drift through the loop is gone from it
        assert free[name]["threshold"] != raw[name]["threshold"]


def test_skin_bench_onset_shape_takes_the_common_mode_off(capsys) -> None:
    import json

    from skin.cli import main

    assert main(["bench", "onset-shape", "--sensor", "pid-logger", "--minutes", "0.5",
                 "--taxels", "4", "--window", "2", "--common-mode", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["common_mode"] is True


def test_onset_shape_refuses_a_common_mode_it_cannot_take(capsys) -> None:
    """With fewer than COMMON_MIN taxels the detector has no common mode: refused before the
    stream is simulated, not reported as taken off."""
    from skin.cli import main
    from skin.stream.onset import COMMON_MIN

    code = main(["bench", "onset-shape", "--sensor", "pid-logger", "--minutes", "0.5",
                 "--taxels", str(COMMON_MIN - 1), "--window", "2", "--common-mode", "--json"])
    err = capsys.readouterr().err
    assert code != 0 and f"at least {COMMON_MIN} taxels" in err and "--taxels is 3" in err
    with pytest.raises(ValueError, match="common_mode needs a board"):
        shape_separability(load_sensor("pid-logger"), seed=0, minutes=0.5, n_taxels=2,
                           window=2.0, common_mode=True)
