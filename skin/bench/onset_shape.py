"""Can a contact be told from a gust by its shape? A GLRT on templates, measured.

A contact is a step of the sensor's surface temperature: at the thermistor it arrives through
the sensor body (eq. 5's ``erfc(x / (2 sqrt(alpha t)))``, or slower through a closing contact
conductance), then through the sensor's own dynamics (a PID loop's high-pass, the
thermistor's lag, the logger's smoothing). An air current or a draft changes the face's
temperature gradually, over seconds (`DISTURBANCE_RISE`), through the same dynamics. On a
window of the reading both are fitted over a free straight baseline, each with its onset free
on a grid; the generalised likelihood ratio of the best contact fit against the best
disturbance fit (and against the baseline alone) decides.

Everything follows from the sensor description (`skin.models.sensors`): the templates are its
response, the window spans its response time, the readings are box-averaged down to about
`ROWS` rows per window. The statistics are in units of the window's own residual variance
(what is left after the contact fit), so the flutter of air and the sensor's noise set them,
not an absolute temperature.

`shape_separability` measures, on a simulated stream of a sensor (`skin.bench.streams`),
what such a test could detect: each statistic's threshold is set so that the stream's
contact-free windows (gusts, flutter, heater steps, drift; no contact or recovery within the
window) raise at most a target number of alarms per taxel-hour (falls only, as for the
contacts: through a PID loop a gust's recovery fits the contact template turned over), and
the share of the contacts that move the reading more than 5 sigma whose windows pass it
with a fall within 1, 2 and 4 s of their onset (and no later than
`skin.bench.onset_eval.release_window` after their release) is reported
(``skin bench onset-shape``; ``--common-mode``: on the detector's reading with its board's
common mode taken off). It is the measurement behind
running the test in the streaming detector or not (issue 16): where it detects no more than
the detector's level test at the same false-alarm rate, shape cannot separate them either.
"""

from __future__ import annotations

import numpy as np

#: Rise times of what air currents and drafts do to a heated face, s (a first-order change of
#: the face temperature; the simulated streams' gusts rise over 1-4 s).
DISTURBANCE_RISE = (0.5, 1.0, 2.0, 4.0)
#: Contact closing rates of the contact templates, s^-0.5 (inf: perfect contact).
CONTACT_RATES = (np.inf, 30.0, 3.0)
#: Rows of a window after box-averaging (the test's resolution).
ROWS = 96
#: Least window, s, and most, s.
WINDOW_RANGE = (0.4, 8.0)


def _box(x: np.ndarray, m: int) -> np.ndarray:
    """Mean of consecutive blocks of ``m`` samples along axis 0 (the tail dropped)."""
    n = (x.shape[0] // m) * m
    return x[:n].reshape(n // m, m, *x.shape[1:]).mean(axis=1)


class ShapeTest:
    """Contact-versus-disturbance templates of one sensor, and the test over windows.

    Parameters
    ----------
    sensor : skin.models.sensors.SensorDescription
        The taxels' sensor.
    window : float, optional
        Window length, s (default: twice the sensor's response time within `WINDOW_RANGE`).
    """

    def __init__(self, sensor: object, window: float | None = None) -> None:
        from skin.models.physics import contact_response
        from skin.models.sensors import apply_dynamics, smooth

        fs = float(sensor.sample_rate)
        if window is None:
            window = min(max(2.0 * sensor.response_time, WINDOW_RANGE[0]), WINDOW_RANGE[1])
        self.decimation = m = max(1, round(window * fs / ROWS))
        self.rows = rows = max(8, round(window * fs / m))
        self.row_time = m / fs
        self.window = rows * self.row_time
        # templates at the sample rate, with a row of zeros before the onset (a non-causal
        # smoothing spreads a step backwards), through the sensor's dynamics and smoothing
        pre = rows * m
        lag = (np.arange(pre + rows * m) - pre) / fs + 0.5 / fs
        shapes = [contact_response(np.maximum(lag, 0.0), rate, sensor) for rate in CONTACT_RATES]
        n_contact = len(shapes)
        shapes += [np.where(lag > 0, -np.expm1(-np.maximum(lag, 0.0) / r), 0.0)
                   for r in DISTURBANCE_RISE]
        raw = np.stack(shapes, axis=1)
        raw = smooth(apply_dynamics(raw, sensor, fs, axis=0), sensor, axis=0, fs=fs)
        table = _box(raw, m)  # (2 rows, families): row `rows` is the onset's
        # onsets on the row grid, from a quarter window in (a baseline to fit) to two rows
        # before the window's end
        self.onsets = np.arange(rows // 4, rows - 2)
        i = np.arange(rows)
        t = (i - rows / 2) / rows
        base = np.stack([np.ones(rows), t], axis=1)
        q0, _ = np.linalg.qr(base)
        self._q0 = q0  # (rows, 2)
        # per family and onset: the template's part orthogonal to the baseline, normalised
        idx = i[None, :] - self.onsets[:, None] + rows  # (onsets, rows) into `table`
        cols = table[idx]  # (onsets, rows, families)
        cols = cols - np.einsum("rk,okf->orf", q0, np.einsum("rk,orf->okf", q0, cols))
        norm = np.sqrt((cols**2).sum(axis=1, keepdims=True))
        self._q = np.divide(cols, norm, out=np.zeros_like(cols), where=norm > 1e-12)
        self._n_contact = n_contact
        self.dof = rows - 3

    def test(self, window: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Fit the contact and the disturbance templates to windows of readings.

        Parameters
        ----------
        window : numpy.ndarray, shape (rows, k)
            Box-averaged readings of ``k`` taxels, oldest row first (no NaN).

        Returns
        -------
        contact : numpy.ndarray, shape (k,)
            Energy the best contact template explains beyond the baseline, in units of the
            residual variance per row after that fit.
        versus : numpy.ndarray, shape (k,)
            The same, minus what the best disturbance template explains: the log-likelihood
            ratio of contact against disturbance (x2).
        sign : numpy.ndarray, shape (k,)
            Direction of the best contact fit: -1 the reading fell, +1 it rose.
        onset : numpy.ndarray, shape (k,)
            Its onset, in rows from the window's start (the row where it begins).
        """
        y = window - self._q0 @ (self._q0.T @ window)  # the baseline removed
        proj = np.einsum("orf,rk->ofk", self._q, y)  # (onsets, families, k)
        energy = proj**2
        nc = self._n_contact
        ce = energy[:, :nc].reshape(-1, y.shape[1])
        best = np.argmax(ce, axis=0)
        e_contact = ce[best, np.arange(y.shape[1])]
        e_dist = energy[:, nc:].reshape(-1, y.shape[1]).max(axis=0)
        sign = np.sign(proj[:, :nc].reshape(-1, y.shape[1])[best, np.arange(y.shape[1])])
        resid = np.maximum((y**2).sum(axis=0) - e_contact, 1e-30) / self.dof
        onset = self.onsets[best // nc]
        return e_contact / resid, (e_contact - e_dist) / resid, sign, onset


def rows_needed(sensor: object) -> int:
    """Rows of box-averaged readings a detector keeps per taxel for `ShapeTest` (cheap)."""
    return ShapeTest(sensor).rows


def shape_separability(sensor: object, seed: int = 0, minutes: float = 15.0,
                       n_taxels: int = 16, window: float | None = None,
                       false_alarms: float = 0.1, delays: tuple[float, ...] = (1.0, 2.0, 4.0),
                       progress: object | None = None, common_mode: bool = False) -> dict:
    """Measure how many 5-sigma contacts a template test finds at a false-alarm target.

    Parameters
    ----------
    sensor : skin.models.sensors.SensorDescription
        The stream's sensor.
    seed, minutes, n_taxels : int, float, int
        The simulated stream (`skin.bench.streams.simulate_stream`, the materials of
        ``skin evaluate-onset``, one contact per taxel-minute, disturbances on).
    window : float, optional
        Window of the test, s (default: `ShapeTest`'s).
    false_alarms : float
        Alarms per contact-free taxel-hour allowed (a run of windows above the threshold is
        one alarm); with fewer free taxel-hours than 1 / this, no free window may pass.
    delays : tuple of float
        A contact counts as found when a window ending within this long of its onset (and
        no later than `skin.bench.onset_eval.release_window` after its release, as
        ``skin evaluate-onset`` credits an alarm) passes with a fall, s.
    progress : callable, optional
        Called as ``progress(done, total)`` with rows tested.
    common_mode : bool
        Test the reading the onset detector itself looks at with its board's common mode
        taken off (`skin.stream.onset.OnsetDetector`'s ``common_mode``: its smoothed reading,
        causal, ``smooth_tau`` 0.03 s) instead of the raw reading: on a PID-held board the
        room's drift through the loop (pid-logger: 0.03 K sd) is most of what a free window
        holds.

    Only falls count on either side: a free window's statistic is an alarm only when its
    best contact fit is a fall, as a contact's must be (a gust's recovery, a rise, fits the
    contact template with the other sign and is no falling alarm).

    Returns
    -------
    dict
        ``window_s``, ``free_taxel_hours``, ``contacts_5sigma``, ``noise_sigma_k`` and per
        statistic (``energy``: the contact fit over the baseline, a matched filter;
        ``versus``: the contact fit over the best disturbance fit, shape alone) its
        ``threshold`` and ``detected_within_s`` (delay -> share of the 5-sigma contacts).
    """
    from skin.bench.onset_eval import release_window
    from skin.bench.streams import simulate_stream
    from skin.commands.evaluate_onset import MATERIALS
    from skin.models import load_materials
    from skin.stream.onset import COMMON_MIN, OnsetDetector

    if common_mode and n_taxels < COMMON_MIN:
        raise ValueError(f"common_mode needs a board of at least {COMMON_MIN} taxels, got "
                         f"{n_taxels}: with fewer the detector has no common mode")
    table = load_materials()
    stream = simulate_stream([table[n] for n in MATERIALS.split(",")], n_taxels=n_taxels,
                             duration=60.0 * minutes, seed=seed, sensor=sensor)
    test = ShapeTest(sensor, window)
    reading = stream.temperature
    if common_mode:
        reading = OnsetDetector(n_taxels, sensor=sensor, common_mode=True).trace(
            stream.times, reading).smooth
    after = release_window(sensor)
    rows = _box(reading, test.decimation)
    times = _box(stream.times[:, None], test.decimation)[:, 0]
    n_rows = rows.shape[0]
    busy = np.zeros((n_rows, n_taxels), dtype=bool)  # a contact or its recovery in the window
    for c in stream.contacts:
        lo, hi = np.searchsorted(times, [c.onset - 0.1, c.release + 20.0 + test.window])
        busy[lo:hi, c.taxel] = True
    stats = np.full((n_rows, n_taxels, 2), -np.inf)
    for e in range(test.rows, n_rows):
        free = ~busy[e - 1]
        if free.any():
            energy, versus, sign, _ = test.test(rows[e - test.rows:e][:, free])
            fall = sign < 0
            stats[e - 1, free, 0] = np.where(fall, energy, -np.inf)
            stats[e - 1, free, 1] = np.where(fall, versus, -np.inf)
        if progress is not None and e % 2000 == 0:
            progress(e, n_rows)
    free_hours = float((~busy).sum() * test.row_time / 3600.0)
    sigma = float(np.median(OnsetDetector(n_taxels, sensor=sensor).sigma))
    contacts = [c for c in stream.contacts if c.duration >= 0.3 and c.peak_change > 5 * sigma]
    # each contact's best statistics (with a fall) over the windows ending within each delay
    best = np.full((len(contacts), len(delays), 2), -np.inf)
    for i, c in enumerate(contacts):
        k0 = int(np.searchsorted(times, c.onset))
        for j, d in enumerate(delays):
            k1 = int(np.searchsorted(times, min(c.onset + d, c.release + after)))
            ends = [e for e in range(max(k0 + 1, test.rows), k1 + 1)]
            if not ends:
                continue
            w = np.stack([rows[e - test.rows:e, c.taxel] for e in ends], axis=1)
            energy, versus, sign, _ = test.test(w)
            fall = sign < 0
            if fall.any():
                best[i, j] = energy[fall].max(), versus[fall].max()
    out = {"sensor": sensor.name, "seed": seed, "window_s": round(test.window, 3),
           "free_taxel_hours": round(free_hours, 3), "contacts_5sigma": len(contacts),
           "noise_sigma_k": round(sigma, 5), "false_alarms_target": false_alarms,
           "common_mode": common_mode}
    for s, name in enumerate(("energy", "versus")):
        score = stats[..., s]
        above = lambda thr, score=score: int(((score[1:] > thr) & ~(score[:-1] > thr)).sum())  # noqa: E731
        finite = np.unique(score[np.isfinite(score)])
        # the lowest of the free windows' own values that keeps within the target (bisection;
        # the count of alarms falls as the threshold rises)
        lo, hi = 0, max(finite.size - 1, 0)
        while lo < hi:
            mid = (lo + hi) // 2
            if above(finite[mid]) <= false_alarms * free_hours:
                hi = mid
            else:
                lo = mid + 1
        thr = float(finite[lo]) if finite.size else 0.0
        out[name] = {"threshold": round(thr, 2),
                     "free_alarms_per_taxel_hour": round(above(thr) / max(free_hours, 1e-9), 3),
                     "detected_within_s": {f"{d:g}": round(float(np.mean(best[:, j, s] > thr))
                                                           if contacts else 0.0, 4)
                                           for j, d in enumerate(delays)}}
    return out

