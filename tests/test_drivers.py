import numpy as np
import pytest

import skin.drivers
from skin.drivers.sim import PtySerialDevice, SimDriver, SkinSimulator
from skin.errors import DeviceError
from skin.formats.scene import load_scene


@pytest.fixture(scope="module")
def sim() -> SkinSimulator:
    return SkinSimulator(load_scene("default"), duration=3.0)


def test_serial_driver_reads_simulated_board_over_a_real_pty(sim):
    expected = list(sim.frames())
    with PtySerialDevice(sim, speed=0) as device, skin.drivers.open(
        f"serial://{device.port}"
    ) as driver:
        device.start()
        got = []
        while len(got) < len(expected):
            frame = driver.recv(timeout=2.0)
            assert frame is not None, f"stalled after {len(got)} frames"
            got.append(frame)
        assert driver.stats.crc_errors == 0 and driver.stats.malformed == 0
    assert [f.seq for f in got] == [f.seq for f in expected]
    for a, b in zip(got, expected, strict=True):
        assert np.array_equal(a.counts, b.counts)
        assert a.device_time == pytest.approx(b.device_time, abs=1e-6)
        assert a.ambient == pytest.approx(b.ambient, abs=0.006)


def test_sim_driver_ends_and_close_is_idempotent(sim):
    driver = SimDriver(sim, speed=0)
    frames = list(driver)
    assert len(frames) == sim.n_samples and driver.finished
    driver.close()
    driver.close()
    with pytest.raises(DeviceError, match="closed"):
        driver.recv(timeout=0.1)


def test_sim_url_and_loop_url():
    with skin.drivers.open("sim://default?speed=0&duration=0.5") as d:
        assert sum(1 for _ in d) == 100
    with skin.drivers.open("serial+loop://") as d:  # pyserial's loopback: nothing to read
        assert d.recv(timeout=0.05) is None


@pytest.mark.parametrize("url, message", [
    ("bogus://x", "unknown scheme"),
    ("serial://", "no port"),
    ("sim://default?speed=fast", "must be a number"),
    ("sim://default?colour=red", "unknown option"),
    ("serial:///dev/does-not-exist", "cannot open"),
])
def test_bad_urls_give_clear_errors(url, message):
    with pytest.raises(DeviceError, match=message):
        skin.drivers.open(url)


def test_simulator_follows_the_paper_during_contact(sim):
    # a touch from the scene: taxels 0, 1, 10 against aluminium from 1.0 s for 1.5 s
    from skin.models.physics import contact_temperature, thermistor_temperature

    temps = sim.temperatures()
    k = sim.layout.index(0)
    fs = sim.sample_rate
    i0 = int(1.0 * fs)
    t0 = temps[i0 - 1, k]
    e_al = sim._touches[0][4]
    ts = contact_temperature(t0, 25.0, sim.sensor.effusivity, e_al)
    expected = thermistor_temperature(np.arange(0, 300) / fs, t0, ts, sim.sensor)
    assert np.allclose(temps[i0 : i0 + 300, k], expected, atol=0.01)
    assert np.all(np.isfinite(temps))
    # free taxels reheat towards the heated steady state, never above it
    assert temps.max() <= sim.heated + 1e-9
