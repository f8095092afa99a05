"""Confidence bounded by what the training data did not vary: the object's temperature.

A learned model trained on objects at room temperature has never seen a cold or warm object,
and with one heated channel it cannot learn to: after contact a heated taxel reads
``T0 + (T_obj - T0) phi_e,h(t)``, so a cold object of low effusivity and a conductive object
at room temperature give nearly the same trace. Its probabilities say how sure it would be
*if the object were at the training data's temperature*. When the setup declares that objects
may be up to ``object_temperature_range`` K off that temperature, the honest answer is the
set of materials that explain the trace for *some* object temperature in the range: a
family, or unknown.

`class_misfits` measures that with the physics (the joint grid of
`skin.models.contact_fit`: effusivity, contact conductance, onset shift; the object's
temperature enters linearly, so its best value within a box is closed form): for each class
(the materials table's effusivity range) the least sum of squares over the grid, once with
the object at the training temperature and once anywhere in the declared range.

`bound_probabilities` turns a model's probabilities into bounded ones. A class is an *alias*
of the model's answer when it explains the trace only thanks to the range: either it fits
within two standard deviations (4 chi^2, the noise from the best fit's residual) of the best
fit with the object anywhere in the range but not of the best at the training temperature,
or it fits, within the range, as well as the answer fits at the training temperature (25 %)
while the range improves its own fit by more than that. Classes that already fit at the
training temperature are left to the model: it was trained to tell them apart (and so a
range of 0, or one tending to 0, changes nothing). The answer and its aliases share their
summed probability (0.9 of the mean, 0.1 of their own: the model's ranking, so its answer,
stays, its confidence goes): the physics cannot rank them, and the model's ranking assumed
what the setup says may be false. A family named by
`skin.models.materials.hierarchical_answer` keeps its summed probability when its aliases all
belong to it. A model that only votes shares its vote with every class that fits within the
range (a vote says nothing among the classes that fit at the training temperature).

`NuisanceBounded` wraps any scikit-learn classifier (``predict_proba`` or only ``predict``)
with this bound; `LearnedClassifier` applies it to a model file at run time.
"""

from __future__ import annotations

import functools

import numpy as np

from skin._optional import require
from skin.models.contact_fit import LOG_E, _cached_responses
from skin.models.physics import SensorConstants

require("sklearn", "ml")

from sklearn.base import BaseEstimator, ClassifierMixin  # noqa: E402

#: Chi-square within which a class "explains the trace as well" as the best (4: two standard
#: deviations of one parameter), with the reading noise taken from the best fit's residual.
SLACK = 4.0
#: K: the least reading noise assumed (a noise-free trace would make every fit distinct).
NOISE_FLOOR = 0.02
#: Relative slack of the second test: a class whose best sum of squares within the range is
#: within this fraction of the answer's at the training temperature (and which the range
#: improves by more than it) is an alias however noisy the reading.
TOLERANCE = 0.25
#: Weight of the model's own probabilities within a group of aliases: it keeps the model's
#: ranking (so its answer and accuracy), not its confidence.
RANKING = 0.1


@functools.lru_cache(maxsize=16)
def _class_table(classes: tuple[str, ...]) -> tuple[np.ndarray, tuple]:
    """Log10 effusivity spans and own temperatures of ``classes`` (the table read once)."""
    from skin.models.materials import load_materials

    table = load_materials()
    spans = np.array([table[c].log_effusivity_range if c in table else (LOG_E[0], LOG_E[-1])
                      for c in classes])
    own = tuple(table[c].temperature if c in table else None for c in classes)
    return spans, own


def class_log_e(classes: list[str]) -> np.ndarray:
    """Each class's (min, max) log10 effusivity from the materials table, (n_classes, 2).

    A class the table does not know spans the whole grid (it cannot be ruled out).
    """
    return _class_table(tuple(classes))[0].copy()


def class_offsets(classes: list[str], ambient: np.ndarray, low: float, high: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Object temperature above ambient each class may have, (n, n_classes) low and high.

    ``low``/``high`` bound an ordinary object; a heat-generating material (skin) holds its own
    temperature range whatever the room.
    """
    amb = np.asarray(ambient, dtype=float)[:, None]
    lo = np.full((amb.shape[0], len(classes)), float(low))
    hi = np.full_like(lo, float(high))
    for i, own in enumerate(_class_table(tuple(classes))[1]):
        if own is not None:
            lo[:, i] = own[0] - amb[:, 0]
            hi[:, i] = own[1] - amb[:, 0]
    return lo, hi


def class_misfits(x: np.ndarray, classes: list[str], channels: int = 1, fs: float = 200.0,
                  sensor: SensorConstants | None = None, object_range: float = 0.0,
                  training: tuple[float, float] = (0.0, 0.0)
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least sum of squares of each class's physics fit, trained and declared conditions.

    Parameters
    ----------
    x : numpy.ndarray
        Contact rows (`skin.models.features.contact_matrix`), (n, 1 + channels (1 + m)).
    classes : list of str
        Class names (materials of the table; others span the whole grid).
    channels : int
        Channel blocks per row.
    fs : float
        Sampling rate, Hz.
    sensor : SensorConstants or None
        The taxels' thermal constants (default: the paper's). A sensor's lag, loop,
        smoothing and heater mode are not modelled (filtering the responses with the low-cost
        preset's lag and low-pass made the bound worse: 0.003 -> 0.075 confidently wrong).
    object_range : float
        K: the object may be this much colder or warmer than the training range.
    training : (float, float)
        The object's temperature above ambient in the training data, K (low, high).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        ``trained`` and ``declared`` (n, n_classes): the least sum of squares, K^2, with the
        object within the training range and within it widened by ``object_range``; and the
        number of samples each row's fit used, (n,).
    """
    from skin.models.contact import split_contact_rows

    amb, t0, w = split_contact_rows(x, channels)
    n, _, m = w.shape
    sensor = SensorConstants() if sensor is None else sensor
    phi = _cached_responses(m, fs, sensor)  # (g, m), g = (log e, log h, shift)
    present = np.all(np.isfinite(w), axis=2) & np.isfinite(t0)
    d = np.where(present[:, :, None], w - np.nan_to_num(t0)[:, :, None], 0.0)
    a = np.where(present, t0 - amb[:, None], 0.0)
    pp = np.einsum("gm,gm->g", phi, phi)
    dp = np.einsum("ncm,gm->ncg", d, phi)
    k = present.sum(axis=1).astype(float)
    # each channel reads z_i = d_i + a_i phi = delta phi + noise, delta = T_obj - T_amb
    big_a = k[:, None] * pp[None, :]
    big_b = (dp + a[:, :, None] * pp[None, None, :]).sum(axis=1)
    zz = ((d**2).sum(axis=(1, 2))[:, None] + 2.0 * (a[:, :, None] * dp).sum(axis=1)
          + (a**2).sum(axis=1)[:, None] * pp[None, :])
    free = big_b / np.maximum(big_a, 1e-300)  # the unconstrained best delta per grid point
    log_e = LOG_E.repeat(phi.shape[0] // LOG_E.size)
    half = 0.5 * (LOG_E[1] - LOG_E[0])
    spans = class_log_e(classes)
    out = []
    for lo_t, hi_t in ((training[0], training[1]),
                       (training[0] - object_range, training[1] + object_range)):
        lo, hi = class_offsets(classes, amb, lo_t, hi_t)
        ss = np.empty((n, len(classes)))
        for i, (e_lo, e_hi) in enumerate(spans):
            cols = (log_e >= e_lo - half) & (log_e <= e_hi + half)
            if not cols.any():  # narrower than the grid: its nearest point
                cols = np.abs(log_e - 0.5 * (e_lo + e_hi)) <= np.abs(
                    log_e - 0.5 * (e_lo + e_hi)).min() + 1e-12
            delta = np.clip(free[:, cols], lo[:, i:i + 1], hi[:, i:i + 1])
            s = zz[:, cols] - 2.0 * delta * big_b[:, cols] + delta**2 * big_a[:, cols]
            ss[:, i] = np.maximum(s.min(axis=1), 0.0)
        out.append(ss)
    return out[0], out[1], np.maximum(k * m, 1.0)


def bound_probabilities(p: np.ndarray, trained: np.ndarray, declared: np.ndarray,
                        samples: np.ndarray, slack: float = SLACK,
                        noise: float = NOISE_FLOOR, voted: bool = False) -> np.ndarray:
    """Share the answer's probability with its aliases (module docstring).

    Parameters
    ----------
    p : numpy.ndarray
        The model's probabilities, (n, n_classes).
    trained, declared, samples : numpy.ndarray
        `class_misfits`'s output for the same rows and classes.
    slack : float
        Chi-square above the best fit within which a class explains the trace as well.
    noise : float
        K: the least reading noise assumed (the fit's own residual RMS is used above it).
    voted : bool
        ``p`` are votes, not probabilities (a model without ``predict_proba``): a vote says
        nothing of how sure the model was among the classes that fit at the training
        temperature, so every class that fits within the range is an alias.

    Returns
    -------
    numpy.ndarray
        The bounded probabilities (rows still sum to 1; unchanged where no class is an
        alias of the answer).
    """
    p = np.array(p, dtype=float, copy=True)
    if p.shape[0] == 0:
        return p
    best = declared.min(axis=1)
    var = np.maximum(best / samples, noise**2)  # the reading noise, from the best fit
    margin = (slack * var)[:, None]
    fits = declared <= best[:, None] + margin
    as_trained = trained <= trained.min(axis=1, keepdims=True) + margin
    group = fits if voted else fits & ~as_trained  # explained only thanks to the range
    top = np.argmax(p, axis=1)
    rows = np.arange(p.shape[0])
    # as well as the answer explains it at the training temperature, only thanks to the range
    limit = (trained[rows, top] * (1.0 + TOLERANCE) + samples * noise**2)[:, None]
    group |= (declared <= limit) & (declared * (1.0 + TOLERANCE) + samples[:, None] * noise**2
                                    < trained)
    for r in np.flatnonzero(group.any(axis=1)):
        g = group[r].copy()
        g[top[r]] = True
        if g.sum() < 2:
            continue
        share = p[r, g].sum() / g.sum()
        p[r, g] = (1.0 - RANKING) * share + RANKING * p[r, g]
    return p


def votes(pred: np.ndarray, classes: np.ndarray) -> np.ndarray:
    """Probabilities of a model that only votes: its class at 1 (the bound then shares it)."""
    return (np.asarray(pred)[:, None] == np.asarray(classes)[None, :]).astype(float)


def object_spread(data) -> float | None:
    """K the training data's objects varied about ambient (None: not recorded).

    From the dataset's ``object_temperature`` column (a measurement); simulated truth
    (``true_object_temperature``) is not read, as a classifier never reads truth.
    """
    t = getattr(data, "object_temperature", None)
    amb = getattr(data, "ambient", None)
    if t is None or amb is None:
        return None
    off = np.asarray(t, dtype=float) - np.asarray(amb, dtype=float)
    off = off[np.isfinite(off)]
    return float(np.max(np.abs(off))) if off.size else None


def uncovered(object_range: float, trained_spread: float | None) -> str | None:
    """Return a warning when the training data did not vary the declared range, else None."""
    if object_range <= 0:
        return None
    if trained_spread is None:
        return (f"objects may be {object_range:g} K off ambient (object_temperature_range), "
                f"but the training data did not record its objects' temperature: assumed at "
                f"ambient, so the confidence is bounded by the physics over +-{object_range:g} K")
    if trained_spread + 0.5 < object_range:
        return (f"objects may be {object_range:g} K off ambient (object_temperature_range), "
                f"but the training data's varied only {trained_spread:.1f} K: the confidence is "
                f"bounded by the physics over the rest")
    return None


def scene_object_range(scene, materials: dict) -> float:
    """K the scene's objects sit off its ambient (0 when all are at it).

    Objects of a heat-generating material hold their own temperature and do not count (the
    bound keeps their table range whatever the setting).
    """
    off = [abs(o.temperature - scene.ambient) for o in scene.objects.values()
           if o.temperature is not None
           and getattr(materials.get(o.material), "temperature", None) is None]
    return float(max(off, default=0.0))


def other_sensors(trained: str | None, used: list[str]) -> str | None:
    """Return a warning when a run's sensors are not the one the model was trained with.

    ``trained``: the model file's training sensor (None: not recorded); ``used``: the
    layout's boards' sensor names (``""`` or ``"paper"``: the paper's).
    """
    names = sorted({u or "paper" for u in used})
    if trained is None:
        if names == ["paper"]:
            return None
        return (f"the layout's boards use sensor(s) {', '.join(names)}, and the model file "
                f"does not record the sensor its training data came from (skin train "
                f"--sensor): its confidence does not account for another sensor")
    other = [n for n in names if n != trained]
    if not other:
        return None
    return (f"the model was trained on sensor {trained!r}, the layout's boards use "
            f"{', '.join(other)}: its confidence does not account for another sensor")


class NuisanceBounded(ClassifierMixin, BaseEstimator):
    """Any classifier with its confidence bounded over a declared object temperature range.

    Parameters
    ----------
    estimator : estimator
        A scikit-learn classifier reading `contact_matrix` rows (with ``predict_proba``, or
        only ``predict``: its votes are then the probabilities the bound shares).
    object_temperature_range : float
        K the objects met may be colder or warmer than the training data's (0: unchanged).
    channels : int
        Channel blocks per row.
    fs : float
        Sampling rate, Hz.
    sensor : SensorConstants or None
        The taxels' thermal constants for the physics (default: the paper's).
    """

    def __init__(self, estimator=None, object_temperature_range: float = 0.0,
                 channels: int = 1, fs: float = 200.0,
                 sensor: SensorConstants | None = None) -> None:
        self.estimator = estimator
        self.object_temperature_range = object_temperature_range
        self.channels = channels
        self.fs = fs
        self.sensor = sensor

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.allow_nan = True
        return tags

    def fit(self, X: np.ndarray, y: np.ndarray) -> NuisanceBounded:
        """Fit a clone of the estimator."""
        from sklearn.base import clone

        if not (np.isfinite(self.object_temperature_range)
                and self.object_temperature_range >= 0):
            raise ValueError(f"object_temperature_range must be a finite K >= 0, got "
                             f"{self.object_temperature_range!r}")
        self.estimator_ = clone(self.estimator).fit(X, y)
        self.classes_ = self.estimator_.classes_
        return self

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """Return the estimator's probabilities, bounded (module docstring)."""
        from sklearn.utils.validation import check_is_fitted

        check_is_fitted(self, "estimator_")
        x = np.asarray(X, dtype=float)
        voted = not hasattr(self.estimator_, "predict_proba")
        if voted:
            p = votes(self.estimator_.predict(x), self.classes_)
        else:
            p = self.estimator_.predict_proba(x)
        return bound(p, x, [str(c) for c in self.classes_], self.object_temperature_range,
                     self.channels, self.fs, self.sensor, voted=voted)

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Most probable class after the bound."""
        return self.classes_[np.argmax(self.predict_proba(X), axis=1)]


def bound(p: np.ndarray, x: np.ndarray, classes: list[str], object_range: float,
          channels: int = 1, fs: float = 200.0, sensor: SensorConstants | None = None,
          voted: bool = False) -> np.ndarray:
    """`bound_probabilities` of rows ``x`` for a declared range (``p`` itself for 0)."""
    if object_range <= 0 or len(p) == 0:
        return np.asarray(p, dtype=float)
    trained, declared, samples = class_misfits(x, classes, channels, fs, sensor, object_range)
    return bound_probabilities(p, trained, declared, samples, voted=voted)
