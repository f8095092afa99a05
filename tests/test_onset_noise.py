"""The onset detector set by each taxel's measured noise and its sensor, not by kelvin constants."""

import dataclasses

import numpy as np
import pytest

from skin.formats.layout import parse_layout
from skin.formats.scene import parse_scene
from skin.models.sensors import load_sensor
from skin.stream.onset import OnsetDetector, arl_threshold
from skin.stream.pipeline import Pipeline


def test_arl_threshold_inverts_siegmunds_approximation():
    for k in (0.25, 0.5, 1.0, 2.0):
        for arl in (1e2, 1e4, 1e7):
            h = float(arl_threshold(arl, k))
            b = h + 1.166
            run = (np.exp(2 * k * b) - 2 * k * b - 1) / (2 * k**2)
            assert run == pytest.approx(arl, rel=1e-6)
    # a rarer false alarm needs a higher threshold; vectorised over taxels
    h = arl_threshold(np.array([1e3, 1e5, 1e7]), 0.5)
    assert np.all(np.diff(h) > 0)
    assert float(arl_threshold(1.0, 1.0)) == 0.0  # never negative


def test_the_paper_sensor_gives_the_former_thresholds():
    d = OnsetDetector(3)
    assert d.threshold == pytest.approx(0.4)
    assert d.rise_threshold == pytest.approx(0.6)
    assert d.release_rise == pytest.approx(0.12)
    assert d.slow_threshold == pytest.approx(0.6)
    assert d.slow_begin == pytest.approx(0.1)
    assert d.drift == pytest.approx(0.03) and d.noise_floor == pytest.approx(0.003)


def test_thresholds_follow_each_taxels_noise():
    d = OnsetDetector(3, sigma=[0.01, 0.2, 1.0], false_alarm_rate=0.1)
    assert np.all(np.diff(d.threshold) >= 0) and d.threshold[2] > d.threshold[0]
    assert np.all(np.diff(d.drift) > 0)
    rare = OnsetDetector(3, sigma=[0.01, 0.2, 1.0], false_alarm_rate=1e-4)
    assert np.all(rare.noise_threshold > d.noise_threshold)
    with pytest.raises(ValueError, match="sigma"):
        OnsetDetector(2, sigma=[0.1, 0.0])
    with pytest.raises(ValueError, match="sigma"):
        OnsetDetector(2, sigma=np.nan)


def _contact_stream(scale=1.0, n=6, seed=0):
    """Free taxels with noise and a slow drift; two contacts (a fall, a rise) of ``scale`` K."""
    from scipy.special import erfc

    rng = np.random.default_rng(seed)
    fs = 200.0
    t = np.arange(int(20 * fs)) / fs
    y = 38.0 + 0.01 * scale * t[:, None] + rng.normal(0, 0.035 * scale, (t.size, n))
    for k, (t0, amp) in enumerate(((6.0, -3.0), (12.0, 2.0))):
        since = np.clip(t - t0, 1e-9, None)
        shape = np.where(t > t0, erfc(8e-5 / (2 * np.sqrt(2.796e-9 * since))), 0.0)
        y[:, k] += scale * amp * shape
    return t, y


def test_no_absolute_kelvin_constant_scaling_everything_keeps_the_events():
    """Readings, noise and heater rise scaled together give the same onsets at the same times."""
    base = load_sensor("paper")
    c = 5.0
    hot = dataclasses.replace(base, heater_voltage=base.heater_voltage * np.sqrt(c))
    assert hot.heated_rise == pytest.approx(c * base.heated_rise)
    t, y = _contact_stream(1.0)
    _, y5 = _contact_stream(c)
    d1 = OnsetDetector(y.shape[1], sensor=base, sigma=0.035)
    d5 = OnsetDetector(y.shape[1], sensor=hot, sigma=0.035 * c)
    e1, _ = d1.process(t, y, d1.initial_state())
    e5, _ = d5.process(t, y5, d5.initial_state())
    assert [(e.kind, e.taxel, e.direction) for e in e1] == [
        (e.kind, e.taxel, e.direction) for e in e5]
    assert [e.time for e in e1] == pytest.approx([e.time for e in e5], abs=1e-9)
    assert sum(e.kind == "onset" for e in e1) == 2


def test_noise_alone_raises_fewer_false_alarms_than_the_target():
    """With the heater's disturbance floor out of the way, only the ARL threshold is left."""
    s = dataclasses.replace(load_sensor("paper"), heater_voltage=0.01)  # rise ~ 0
    n, fs, secs = 32, 200.0, 60.0
    rng = np.random.default_rng(3)
    t = np.arange(int(secs * fs)) / fs
    y = 38 + rng.normal(0, 0.035, (t.size, n))
    target = 3600.0  # per taxel-hour: about 16 alarms expected if the bound were tight
    d = OnsetDetector(n, sensor=s, sigma=0.035, false_alarm_rate=target)
    assert np.all(d.threshold == d.noise_threshold)
    events, _ = d.process(t, y, d.initial_state())
    onsets = sum(e.kind == "onset" for e in events)
    assert onsets / (n * secs / 3600) <= target


def test_chunks_of_any_size_give_the_same_events_on_a_foreign_sensor():
    from skin.drivers.sim import SkinSimulator

    src = ('layout = "arm"\nsensor = "fast-film"\nduration = 6.0\nseed = 2\n'
           '[[objects]]\nname = "o"\nmaterial = "aluminium"\n'
           '[[touches]]\nobject = "o"\ntaxels = [0, 1]\nstart = 2.0\nduration = 2.0\n')
    sim = SkinSimulator(parse_scene(src, "s.toml"))
    frames = list(sim.frames())
    temp, _ = sim.calibration.temperature(np.array([f.counts for f in frames])[:, sim._addr])
    temp = temp[:, :8]
    times = np.array([f.device_time for f in frames])
    d = OnsetDetector(8, sensor=load_sensor("fast-film"),
                      sigma=np.linspace(0.03, 0.05, 8))
    whole, _ = d.process(times, temp, d.initial_state())
    assert any(e.kind == "onset" and e.taxel == 0 for e in whole)
    rng = np.random.default_rng(0)
    state, parts, k = d.initial_state(), [], 0
    while k < len(times):
        m = int(rng.integers(1, 700))
        ev, state = d.process(times[k:k + m], temp[k:k + m], state)
        parts += ev
        k += m
    assert parts == whole


def test_a_heater_switched_off_at_contact_holds_the_touch_until_it_reheats():
    """Its reading settles at the contact's temperature within 0.3 s: that is no release (it
    was one, 0.3 s into a touch, and commissioning then found no touch long enough)."""
    from skin.drivers.sim import SkinSimulator

    src = ('layout = "arm"\nsensor = "fast-film"\nduration = 7.5\nseed = 3\n'
           'initial_temperature = [34.0, 36.0]\n'
           '[[objects]]\nname = "a"\nmaterial = "aluminium"\n'
           '[[objects]]\nname = "p"\nmaterial = "pine"\n'
           '[[touches]]\nobject = "a"\ntaxels = [0, 1]\nstart = 1.0\nduration = 2.0\n'
           '[[touches]]\nobject = "p"\ntaxels = [0, 1]\nstart = 4.5\nduration = 2.0\n')
    sim = SkinSimulator(parse_scene(src, "s.toml"))
    temp = sim.temperatures()[:, :2]
    d = OnsetDetector(2, sensor=load_sensor("fast-film"))
    assert not d.ends_when_stopped and OnsetDetector(3).ends_when_stopped
    times = np.arange(len(temp)) / d.sensor.sample_rate
    events, _ = d.process(times, temp, d.initial_state())
    for k in range(2):
        mine = [(e.kind, e.time) for e in events if e.taxel == k]
        assert [kind for kind, _ in mine] == ["onset", "release"] * 2
        for (_, on), (_, off), start in zip(mine[::2], mine[1::2], (1.0, 4.5), strict=True):
            assert abs(on - start) < 0.05 and abs(off - (start + 2.0)) < 0.1


def test_the_pipeline_sets_its_detector_by_the_boards_sensor():
    text = ('[[boards]]\nid = 0\nsensor = "low-cost"\n\n[[taxels]]\nid = 0\nboard = 0\n'
            'address = 0\nlink = "l"\nposition = [0, 0, 0]\nnormal = [0, 0, 1]\n')
    layout = parse_layout(text, "x.toml")
    pipe = Pipeline(layout, classifier=None)
    s = load_sensor("low-cost")
    assert pipe.detector.sensor == s
    assert pipe.detector.sigma[0] == pytest.approx(
        s.noise_kelvin(25.0 + s.heated_rise) * s.smoothing_noise_factor())
    assert pipe.detector.slow_tau > 3.0  # a slower sensor than the paper's: longer windows


def test_streams_of_a_sensor_scale_their_truth_to_it():
    from skin.bench.streams import simulate_stream
    from skin.models import load_materials

    mats = [load_materials()[m] for m in ("aluminium", "pine")]
    plain = simulate_stream(mats, n_taxels=2, duration=60.0, seed=1)
    again = simulate_stream(mats, n_taxels=2, duration=60.0, seed=1)
    assert np.array_equal(plain.temperature, again.temperature)
    slow = simulate_stream(mats, n_taxels=6, duration=120.0, seed=1, sensor="pid-logger",
                           contacts_per_minute=3.0)
    assert slow.fs == 50.0 and slow.temperature.shape == (6000, 6)
    fast = simulate_stream(mats, n_taxels=6, duration=120.0, seed=1, sensor="fast-film",
                           contacts_per_minute=3.0)
    assert fast.fs == 1000.0
    floor = {}
    for name, st in (("slow", slow), ("fast", fast)):
        seen = [c.visible_after for c in st.contacts if np.isfinite(c.visible_after)]
        assert len(seen) >= 3
        floor[name] = np.median(seen)
    assert floor["slow"] > 2 * floor["fast"]  # the slower thermistor shows a touch later


def test_evaluate_onset_per_sensor_reports_the_issue_figures(capsys):
    import json

    from skin.cli import main

    assert main(["evaluate-onset", "--sensor", "fast-film", "--taxels", "4", "--minutes", "1",
                 "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    for key in ("detected_5sigma", "false_alarms_per_taxel_hour", "delay_floor_ratio_median",
                "refined_onset_error_ms_median", "contacts_5sigma", "bound_floor_ratio_median",
                "delay_bound_ratio_median", "refined_onset_sd_bound_ms_median",
                "refined_onset_error_bound_ratio_median", "detectable_5sigma",
                "detected_of_detectable", "detectable_in_contact_5sigma",
                "detected_not_detectable"):
        assert key in doc
    assert doc["refined_onset_sd_bound_ms_median"] > 0
    assert doc["refined_onset_error_bound_ratio_median"] > 0
    assert doc["detectable_in_contact_5sigma"] <= doc["detectable_5sigma"] <= 1.0
    # no detector reacts before the information bound: the delay is at least the bound
    assert doc["delay_bound_ratio_median"] >= 1.0
    assert doc["sensor"] == "fast-film" and 0 <= doc["detected_5sigma"] <= 1
    assert "delay_s" not in doc and "detected_flags" not in doc
    assert main(["evaluate-onset", "--sensor", "nonesuch", "--minutes", "1"]) == 2
    # the diagnosis knobs: named in the source (without --sensor, on the paper's detector), and
    # refused when not positive
    assert main(["evaluate-onset", "--sensor", "fast-film", "--taxels", "2", "--minutes", "0.5",
                 "--envelope-sigmas", "5", "--smooth-tau", "0.01", "--json"]) == 0
    knobbed = json.loads(capsys.readouterr().out)
    assert "envelope sigmas 5, smooth tau 0.01" in knobbed["source"]
    assert "noise-table envelope margin" in knobbed["source"]
    # fast-film's faster envelope reading follows the smoothing: 0.01 s x 0.098, one sample
    assert knobbed["envelope_tau"] == pytest.approx(0.001)
    assert "envelope's faster reading 1.0 ms" in knobbed["source"]
    assert main(["evaluate-onset", "--sensor", "fast-film", "--taxels", "2", "--minutes", "0.5",
                 "--envelope-tau", "0", "--json"]) == 0
    off = json.loads(capsys.readouterr().out)
    assert off["envelope_tau"] is None and "envelope tau 0," in off["source"]
    assert main(["evaluate-onset", "--sensor", "fast-film", "--envelope-tau", "-1"]) == 2
    assert main(["evaluate-onset", "--sensor", "fast-film", "--envelope-tau", "0.003",
                 "--flat-envelope"]) == 2
    assert main(["evaluate-onset", "--flat-envelope", "--taxels", "2", "--minutes", "0.5",
                 "--json"]) == 0
    assert "flat envelope margin" in json.loads(capsys.readouterr().out)["source"]
    assert main(["evaluate-onset", "--sensor", "paper", "--taxels", "2", "--minutes", "0.5",
                 "--flat-envelope", "--json"]) == 0
    assert "flat envelope margin" in json.loads(capsys.readouterr().out)["source"]
    assert main(["evaluate-onset", "--sensor", "paper", "--smooth-tau", "0", "--minutes",
                 "0.5"]) == 2


def test_a_faster_sensor_body_raises_the_disturbance_floors():
    """Heater steps reach a thin body's thermistor faster: its floors grow, a PID's do not."""
    from skin.stream.onset import DISTURBANCE

    paper = load_sensor("paper")
    thin = dataclasses.replace(paper, thickness=paper.thickness / 2)  # l^2 / alpha / 4
    d_paper, d_thin = OnsetDetector(1, sensor=paper), OnsetDetector(1, sensor=thin)
    rise = thin.heated_rise
    assert d_thin.threshold[0] == pytest.approx(DISTURBANCE["threshold"] * rise * 4.0)
    assert d_thin.slow_threshold[0] > 3.0 * DISTURBANCE["slow_threshold"] * rise
    assert d_paper.threshold == pytest.approx(0.4)
    held = dataclasses.replace(thin, heater="pid", setpoint=rise)
    assert OnsetDetector(1, sensor=held).threshold[0] == pytest.approx(
        max(DISTURBANCE["threshold"] * rise, OnsetDetector(1, sensor=held).noise_threshold[0]))
    thick = dataclasses.replace(paper, thickness=paper.thickness * 2)  # slower: never lower
    assert OnsetDetector(1, sensor=thick).threshold[0] >= DISTURBANCE["threshold"] * \
        thick.heated_rise


def test_the_delay_bound_is_lordens_for_a_step_and_later_for_less_noise_never():
    """ln ARL nats of information: for a step of A in noise sigma, 2 sigma^2 ln ARL / A^2."""
    from skin.bench.streams import delay_bound

    fs, sigma, a = 200.0, 0.03, 0.05
    when = np.arange(1, 2001) / fs
    need = np.log(fs * 3600.0 / 0.1) * 2.0 * sigma**2 / a**2  # samples
    assert delay_bound(np.full(when.size, a), when, sigma, fs) == pytest.approx(
        np.ceil(need) / fs)
    # a fewer false alarms allowed wait longer; less noise or a larger step, sooner
    base = delay_bound(np.full(when.size, a), when, sigma, fs)
    assert delay_bound(np.full(when.size, a), when, sigma, fs, false_alarms=0.01) > base
    assert delay_bound(np.full(when.size, a), when, sigma / 2, fs) < base
    ramp = a * when / when[-1]  # a ramp gives its information later than the step
    assert delay_bound(ramp, when, sigma, fs) > base
    assert delay_bound(np.full(5, a), when[:5], sigma, fs) == np.inf  # too short: never
    assert delay_bound(np.zeros(when.size), when, sigma, fs) == np.inf  # no change
    with pytest.raises(ValueError):
        delay_bound(ramp, when, 0.0, fs)


def test_detectability_is_lordens_bound_for_a_step_held_and_released():
    """A step of A held n samples in noise sigma gives n A^2 / (2 sigma^2) nats; it is
    detectable (its bound finite) when that reaches ln ARL, within the samples given."""
    from skin.bench.streams import BOUND_FALSE_ALARMS, detectability

    paper = load_sensor("paper")  # no loop, no lag: the change is the reading's
    fs, sigma, a = 200.0, 0.03, 0.02
    h = np.log(fs * 3600.0 / BOUND_FALSE_ALARMS)
    need = int(np.ceil(h * 2.0 * sigma**2 / a**2))  # samples of the step to reach ln ARL
    for held, after in ((need - 1, 0), (need - 1, 50), (need + 10, 50)):
        change = np.concatenate([[0.0], np.full(held, a), np.zeros(after)])
        when = np.arange(1, change.size) / fs
        bound, information = detectability(change, when, paper, sigma, fs)
        assert information == pytest.approx(held * a**2 / (2 * sigma**2), rel=1e-12)
        # released (0 after): nothing more comes; held long enough: at the need-th sample
        assert bound == (np.inf if held < need else pytest.approx(need / fs))
    # a change that goes on after the release (as the reading recovers) is seen after it
    change = np.concatenate([[0.0], np.full(need - 1, a), np.full(5, a)])
    bound, _ = detectability(change, np.arange(1, change.size) / fs, paper, sigma, fs)
    assert bound == pytest.approx(need / fs)
    # through a first-order lag of time constant L (q = exp(-1 / (fs L))) the k-th sample
    # reads A (1 - q^k): sum_k A^2 (1 - q^k)^2 = A^2 (n - 2 q (1 - q^n) / (1 - q)
    # + q^2 (1 - q^2n) / (1 - q^2))
    lagged = dataclasses.replace(paper, lag=0.5)
    q, n = np.exp(-1.0 / (fs * 0.5)), 3 * need
    change = np.concatenate([[0.0], np.full(n, a)])
    _, information = detectability(change, np.arange(1, n + 1) / fs, lagged, sigma, fs)
    closed = a**2 * (n - 2 * q * (1 - q**n) / (1 - q) + q**2 * (1 - q ** (2 * n)) / (1 - q**2))
    assert information == pytest.approx(closed / (2 * sigma**2), rel=1e-9)


def test_a_contact_detectable_in_contact_stays_so_and_the_window_only_adds():
    """``detectable_after`` is the bound over the contact and the window after its release:
    where ``bound_after`` (the contact alone) is finite it is the same; elsewhere it comes
    after the release, within the window, or never."""
    from skin.bench.onset_eval import release_window
    from skin.bench.streams import simulate_stream
    from skin.models import load_materials

    for preset in ("paper", "low-cost"):
        st = simulate_stream(list(load_materials().values())[:6], n_taxels=4, duration=180.0,
                             seed=3, sensor=preset, contacts_per_minute=3.0)
        window = release_window(load_sensor(preset))
        assert any(np.isfinite(c.detectable_after) for c in st.contacts)
        for c in st.contacts:
            assert c.information >= 0.0
            if np.isfinite(c.bound_after):
                assert c.detectable_after == c.bound_after
            elif np.isfinite(c.detectable_after):
                assert c.duration - 1.0 / st.fs <= c.detectable_after <= \
                    c.duration + window + 1.0 / st.fs


def test_the_onset_bound_is_the_cramer_rao_bound_and_a_fit_reaches_it():
    """Closed form for a ramp; a least-squares fit of onset and size reaches it."""
    from scipy.optimize import least_squares

    from skin.bench.streams import onset_bound

    fs, sigma, r = 100.0, 0.01, 0.5
    t = np.arange(0, 101) / fs
    ramp = r * t  # m' = r everywhere: information r^2 (N - S(t)^2 / S(t^2)) / sigma^2
    expected = sigma / (r * np.sqrt(t.size - t.sum() ** 2 / (t @ t)))
    assert onset_bound(ramp, t, sigma) == pytest.approx(expected, rel=1e-12)
    assert onset_bound(2 * ramp, t, sigma) == pytest.approx(expected / 2, rel=1e-12)
    assert onset_bound(ramp, t, 2 * sigma) == pytest.approx(2 * expected, rel=1e-12)
    assert onset_bound(np.zeros(t.size), t, sigma) == np.inf
    assert onset_bound(ramp[:1], t[:1], sigma) == np.inf
    with pytest.raises(ValueError):
        onset_bound(ramp, t, 0.0)

    # a response that starts with a kink: fitted (onset, size) in noise spread as the bound says
    tau, t0, grid = 0.2, 0.0123, np.arange(-10, 100) / fs

    def shape(onset: float) -> np.ndarray:
        return -np.expm1(-np.maximum(grid - onset, 0.0) / tau)

    after = grid >= 0
    bound = onset_bound(np.r_[0.0, shape(t0)[grid > t0]], np.r_[0.0, grid[grid > t0] - t0],
                        sigma)
    rng = np.random.default_rng(3)
    fits = []
    for _ in range(300):
        y = shape(t0) + rng.normal(0.0, sigma, grid.size)
        fit = least_squares(lambda p, y=y: (p[1] * shape(p[0]) - y)[after | (grid < 0)],
                            [t0, 1.0], x_scale=[1e-3, 1.0])
        fits.append(fit.x[0])
    assert np.std(fits) == pytest.approx(bound, rel=0.15)
    assert abs(np.mean(fits) - t0) < 3 * bound / np.sqrt(len(fits)) + 1e-4


def test_every_sensor_contact_has_a_delay_bound_from_its_onset_on():
    from skin.bench.streams import simulate_stream
    from skin.models import load_materials

    for preset in ("paper", "fast-film"):
        st = simulate_stream(list(load_materials().values())[:4], n_taxels=4, duration=120.0,
                             seed=2, sensor=preset, contacts_per_minute=3.0)
        assert any(np.isfinite(c.bound_after) for c in st.contacts)
        for c in st.contacts:
            assert c.bound_after >= 0.0


@pytest.mark.parametrize("seed", [1, 2])
def test_the_noise_estimate_starts_from_the_readings_not_the_floor(seed):
    # pid-logger's residual is mostly the room's drift through its loop (3 mK against a floor
    # of 0.26 mK): started at the floor, the estimate stayed too small past the 2 s warm-up
    # and the CUSUM raised 4 onsets in 64 quiet taxels' first 12 s; a running mean at start
    from skin.models.sensors import apply_dynamics, smooth
    from skin.stream.onset import AMBIENT_DRIFT

    sensor = load_sensor("pid-logger")
    fs = sensor.sample_rate
    rng = np.random.default_rng(seed)
    t = np.arange(round(12.0 * fs)) / fs
    room = np.cumsum(rng.normal(0.0, np.sqrt(AMBIENT_DRIFT / fs), (t.size, 64)), axis=0)
    y = (35.0 + smooth(apply_dynamics(room, sensor, axis=0), sensor, axis=0)
         + smooth(rng.normal(0.0, sensor.noise_kelvin(35.0), (t.size, 64)), sensor, axis=0))
    det = OnsetDetector(64, sensor=sensor)
    events, state = det.process(t, y, det.initial_state())
    assert len([e for e in events if e.kind == "onset"]) <= 1
    assert np.median(np.sqrt(state.var)) > 10 * float(np.median(det.noise_floor))


@pytest.mark.xfail(strict=True, reason=(
    "known: the running noise estimate starts at the floor (a third of the smoothed reading's "
    "noise on paper), so the CUSUM's allowance stays under the design its threshold is set for "
    "in a stream's first seconds, and a dip of the room raises onsets on many taxels at once "
    "(paper seed 4: 11 of 64 quiet taxels, raised 2.0-2.3 s in). Started at the residual's "
    "nominal noise none are raised (paper seed 4, 64 taxels x 30 min: false alarms 12 -> 1), "
    "but weak early "
    "touches are then missed where the hotter start found them (scene seed 8: the forearm at "
    "4.5 s split into two contacts, and the run's skin prior then lost): see the CHANGELOG's "
    "known limitations"))
def test_a_heated_taxels_first_seconds_raise_no_onset_from_the_rooms_drift():
    from skin.bench.streams import simulate_stream
    from skin.models import load_materials

    sensor = load_sensor("paper")
    det = OnsetDetector(64, sensor=sensor, boards=np.repeat(np.arange(4), 16),
                        common_mode=True)
    glass = load_materials()["glass"]
    raised = {}
    for seed in (1, 3, 4):  # contact-free, with the room's drift, the air and heater switches
        st = simulate_stream([glass], n_taxels=64, duration=10.0, contacts_per_minute=1e-6,
                             disturbances=True, seed=seed, sensor=sensor)
        assert st.contacts == []
        events = det.trace(st.times, st.temperature, duty=st.duty()).events
        raised[seed] = [e for e in events if e.kind == "onset"]
    assert raised == {1: [], 3: [], 4: []}
