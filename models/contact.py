"""The default classifier of a contact seen by one or more channels (taxels) of one object.

Rows are laid out by `skin.models.features.contact_matrix`::

    [ambient, T0_0, T_0(onset) ... T_0(onset + n - 1), T0_1, T_1(onset) ..., ...]

one block per channel (its temperature before contact, then its window), NaN for a channel
the contact did not reach; with one channel this is `trial_matrix`'s row.

`ContactFeatures` computes, per contact and vectorised over contacts, the joint physics fit of
all its channels (`skin.models.contact_fit.grid_fit`: one object temperature shared by the
channels, on a plain log e grid, so the features do not depend on the class names), twice:
with a broad prior on the object's temperature (10 K about ambient) and with a narrow one
(1 K, an object near ambient). The features: the posterior over log e (its profile on the
grid, mean and standard deviation), the object temperature above ambient and its standard
deviation, the posterior mean of log h, the residual RMS, each channel's excess over ambient,
whether each other channel is present, and each channel's trace at log-spaced instants
(relative to its T0; the primary one also normalised by its excess, which for an object at
ambient depends on the material alone).

`ContactClassifier` (the method ``default``) feeds them to a multinomial logistic regression
whose probabilities are temperature-scaled on held-out folds.
Training data recorded with objects at room temperature does not show the classifier what a
cold or warm object does; where the training contacts have a second channel that pins the
object's temperature, ``object_spread`` adds, for each training contact, copies with the
object ``delta`` K colder or warmer (uniform in +-``object_spread``), made with the physics:
the readings move by ``delta phi(t)``, and ``phi`` is the primary heated channel's own
normalised response ``(T_0(t) - T0_0) / (T_amb - T0_0)``. A single heated channel cannot tell a
cold object from a more conductive one, so with one channel no copies are made (they cost
11-15 points at ambient and bought nothing on cold objects); a passive channel, or heaters at
other setpoints, pin the object's temperature, and with them the copies teach the model to
read it.
"""

from __future__ import annotations

import numpy as np

from skin._optional import require

require("sklearn", "ml")

from sklearn.base import BaseEstimator, ClassifierMixin, TransformerMixin  # noqa: E402
from sklearn.utils.validation import check_is_fitted, validate_data  # noqa: E402

from skin.models.contact_fit import grid_basis, grid_fit, grid_fits, grid_responses  # noqa: E402

AMBIENT_STD = 1.0  # K: the second fit's prior, an object near ambient
PRIMARY_SCALE_FLOOR = 0.1  # K: the primary channel's excess is at least this in a normalisation
RAW_COMPONENTS = 10  # the raw-window expert's principal components (the paper's, svm-pca's)


def split_contact_rows(x: np.ndarray, channels: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split `contact_matrix` rows into ambient (n,), T0 (n, channels), windows (n, channels, m).

    Raises
    ------
    ValueError
        If the row length does not hold ``channels`` blocks of at least three samples.
    """
    x = np.asarray(x, dtype=float)
    if x.ndim != 2 or channels < 1 or (x.shape[1] - 1) % channels:
        raise ValueError(f"rows of shape {x.shape} do not hold {channels} channel block(s) "
                         f"[T0, window...] after the ambient column")
    block = (x.shape[1] - 1) // channels
    if block < 4:
        raise ValueError(f"each channel needs T0 and at least 3 samples, got {block - 1}")
    b = x[:, 1:].reshape(x.shape[0], channels, block)
    return x[:, 0], b[:, :, 0], b[:, :, 1:]


class ContactFeatures(TransformerMixin, BaseEstimator):
    """Joint physics fit of a contact's channels plus their traces (see the module docstring).

    Parameters
    ----------
    channels : int
        Channel blocks per row.
    fs : float
        Sampling rate, Hz.
    points : int
        Log-spaced instants of each channel's trace.
    noise : float
        Reading noise of the fit, K.
    object_std : float
        Prior standard deviation of the object's temperature about ambient, K (a second fit
        with 1 K, an object near ambient, is also given).
    excess : bool
        Whether each channel's excess over ambient before contact is a feature.
    depth, diffusivity, conductivity : float
        The taxels' thermistor depth (m), diffusivity (m^2/s) and conductivity (W/(m K))
        (default: the paper's sensor).
    """

    def __init__(self, channels: int = 1, fs: float = 200.0, points: int = 4,
                 noise: float = 0.1, object_std: float = 10.0, excess: bool = True,
                 depth: float = 8e-5, diffusivity: float = 2.796e-9,
                 conductivity: float = 0.0349) -> None:
        self.excess = excess
        self.channels = channels
        self.fs = fs
        self.points = points
        self.noise = noise
        self.object_std = object_std
        self.depth = depth
        self.diffusivity = diffusivity
        self.conductivity = conductivity

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.allow_nan = True  # an absent channel is NaN
        return tags

    def fit(self, X: np.ndarray, y: np.ndarray | None = None) -> ContactFeatures:
        """Check the rows and tabulate the grid's responses for their window length."""
        x = validate_data(self, X, reset=True, ensure_all_finite="allow-nan")
        _, _, w = split_contact_rows(x, self.channels)
        self.samples_ = w.shape[2]
        self.responses_ = self._responses(self.samples_)
        self.basis_ = grid_basis(self.responses_)  # the same fit, ~20x fewer operations
        return self

    def _responses(self, m: int) -> np.ndarray:
        from skin.models.physics import SensorConstants

        sensor = SensorConstants(depth=self.depth, diffusivity=self.diffusivity,
                                 conductivity=self.conductivity)
        return grid_responses(m, self.fs, sensor)

    def physics(self, X: np.ndarray, object_std: float | None = None) -> dict[str, np.ndarray]:
        """Return the joint fit of each row (`skin.models.contact_fit.grid_fit`).

        ``object_std`` overrides the prior's standard deviation of the object's temperature.
        """
        check_is_fitted(self, "responses_")
        amb, t0, w = split_contact_rows(np.asarray(X, dtype=float), self.channels)
        return grid_fit(amb, t0, w, self.responses_, self.noise,
                        self.object_std if object_std is None else object_std,
                        getattr(self, "basis_", None))

    def transform(self, X: np.ndarray) -> np.ndarray:
        """Return the feature vectors (see the module docstring)."""
        check_is_fitted(self, "responses_")
        return self._features(validate_data(self, X, reset=False, ensure_all_finite="allow-nan"))

    def _features(self, x: np.ndarray) -> np.ndarray:
        """`transform` of rows already checked (the classifier's predict checks them once)."""
        amb, t0, w = split_contact_rows(x, self.channels)
        fit, near = grid_fits(amb, t0, w, self.responses_, self.noise,
                              (self.object_std, AMBIENT_STD), getattr(self, "basis_", None))
        m = w.shape[2]
        k = np.unique(np.round(np.geomspace(1, m - 1, self.points)).astype(int))
        k = np.pad(k, (0, self.points - k.size), mode="edge")
        rel = w[:, :, k] - t0[:, :, None]  # (n, c, points), NaN where absent
        excess = t0 - amb[:, None]
        e0 = excess[:, 0]
        scale = np.where(np.abs(e0) < PRIMARY_SCALE_FLOOR,
                         np.copysign(PRIMARY_SCALE_FLOOR, e0 + 1e-12), e0)
        return np.column_stack([
            fit["log_e_profile"], fit["log_e"], fit["log_e_std"], fit["object"],
            fit["object_std"], fit["log_h"], fit["rms"],
            near["log_e_profile"], near["log_e"], near["log_e_std"], near["rms"],
            np.nan_to_num(excess) if self.excess else np.zeros((x.shape[0], 0)),
            np.isfinite(t0[:, 1:]).astype(float),  # which other channels the contact reached
            rel[:, 0] / scale[:, None], np.nan_to_num(rel.reshape(rel.shape[0], -1))])


def _softmax(z: np.ndarray) -> np.ndarray:
    z = z - z.max(axis=1, keepdims=True)
    e = np.exp(z)
    return e / e.sum(axis=1, keepdims=True)


def _log_proba(model, x: np.ndarray, n_classes: int) -> np.ndarray:
    """Log-probabilities of a model fitted on class indices, over all ``n_classes``."""
    out = np.full((x.shape[0], n_classes), np.log(1e-300))
    out[:, model.classes_] = np.log(np.maximum(model.predict_proba(x), 1e-300))
    return out


def _relative_window(x: np.ndarray, channels: int) -> np.ndarray:
    """Return the primary channel's window above ambient (a warmer room moves neither)."""
    amb, _, w = split_contact_rows(x, channels)
    return w[:, 0] - amb[:, None]


def _raw_expert(w: np.ndarray):
    """Return the raw-window expert for windows ``w``: svm-pca's PCA and linear SVM.

    A logistic regression on the same components fell 5-7 points below the SVM on the
    low-cost sensor (.35 against .41 alone, with or without standardised components, C 1-100)
    and was level on the paper's; its scores become log-probabilities through the weights
    `fit_expert_weights` fits on held-out rows.
    """
    from sklearn.decomposition import PCA
    from sklearn.pipeline import make_pipeline
    from sklearn.svm import SVC

    return make_pipeline(PCA(min(RAW_COMPONENTS, *w.shape), random_state=0),
                         SVC(kernel="linear", decision_function_shape="ovr"))


def _raw_scores(model, x: np.ndarray, n_classes: int) -> np.ndarray:
    """Return the raw expert's one-vs-rest scores over ``n_classes`` (absent ones lowest)."""
    d = np.asarray(model.decision_function(x), dtype=float)
    if d.ndim == 1:  # two classes: one signed score
        d = np.column_stack([-d, d]) * 0.5
    out = np.full((x.shape[0], n_classes), d.min() - 10.0 if d.size else 0.0)
    out[:, model.classes_] = d
    return out


def fit_expert_weights(physics: np.ndarray, raw: np.ndarray, y: np.ndarray,
                       ) -> tuple[float, float]:
    """Return the weights (a, b) that minimise the held-out log loss of ``a L_p + b S_r``.

    ``physics`` holds the physics model's held-out log-probabilities, ``raw`` the raw
    expert's held-out scores, ``y`` class indices. A temperature per expert: the product
    stays calibrated, and an expert that misleads on the data (a sensor the physics does not
    describe) gets less say.
    """
    from scipy.optimize import minimize

    rows = np.arange(y.size)
    physics = np.maximum(physics, -700.0)

    def loss(w: np.ndarray) -> float:
        z = np.exp(w[0]) * physics + np.exp(w[1]) * raw
        z = z - z.max(axis=1, keepdims=True)
        return float(-np.mean(z[rows, y] - np.log(np.exp(z).sum(axis=1))))

    w = minimize(loss, np.zeros(2), method="Nelder-Mead",
                 options={"xatol": 1e-4, "fatol": 1e-8}).x
    return float(np.exp(w[0])), float(np.exp(w[1]))


def fit_temperature(logits: np.ndarray, y: np.ndarray) -> float:
    """Return the T that minimises the log loss of ``softmax(logits / T)`` on held-out rows.

    ``y`` holds class indices. Temperature scaling keeps the ranking of the classes (and so the
    accuracy) and only makes the probabilities as sure as the held-out rows say.
    """
    from scipy.optimize import minimize_scalar

    rows = np.arange(y.size)

    def loss(log_t: float) -> float:
        p = _softmax(logits / np.exp(log_t))
        return float(-np.mean(np.log(np.maximum(p[rows, y], 1e-300))))

    return float(np.exp(minimize_scalar(loss, bounds=(-3.0, 5.0), method="bounded").x))


class ContactClassifier(ClassifierMixin, BaseEstimator):
    """The default method: `ContactFeatures` into a calibrated learned model.

    Parameters
    ----------
    channels : int
        Channel blocks per row (`skin.models.features.contact_matrix`).
    fs : float
        Sampling rate, Hz.
    object_spread : float
        Training copies move the object up to this many K from the recorded one (module
        docstring); 0 trusts the training data's object temperatures to be the world's.
    copies : int
        Shifted copies per training contact (with ``object_spread`` > 0).
    learner : str
        ``"linear"`` (standardised multinomial logistic regression) or ``"trees"``
        (gradient-boosted trees).
    C : float or None
        Inverse L2 penalty of the linear learner; None: 0.1 when copies are made (many
        near-duplicate rows), else 1 (measured: without copies C = 0.1 / 1 / 10 gives .748 /
        .767 / .765 on seed 7 and .715 / .761 / .772 on seed 8, 1.5 s).
    calibration : str or None
        ``"temperature"`` (default): one temperature that rescales the learner's logits,
        fitted by the held-out log loss of a ``cv``-fold split of the (augmented) training
        rows; ``"isotonic"`` or ``"sigmoid"``: `CalibratedClassifierCV` (one-vs-rest, which
        with many classes and few trials costs accuracy: 0.67 -> 0.57 at 0.5 s on the
        synthetic benchmark); None: the learner's own probabilities.
    cv : int
        Folds of the calibration.
    points : int
        Trace instants per channel in the features.
    excess : bool
        Whether the channels' excess over ambient before contact is a feature.
    warp : float
        In a copy, each channel other than the primary sees the object's shift through the
        primary's response with time rescaled by ``exp(U(-warp, warp))``: another taxel,
        whose depth and diffusivity the training data did not pin.
    sensor_spread : float
        In a copy, the primary taxel starts up to this fraction of its excess over ambient
        (less 1 K) cooler, as after touches of cold or conductive objects; its reading moves
        by ``eps (1 - phi)``. 0: the training data's sensor temperatures are the world's.
    unpinned_copies : bool
        Whether to make the copies when no training contact has a second channel. By default
        they are made only when one has: a single heated channel cannot tell a cold object
        from a more conductive one, so copies teach it only to blur the answer. Measured
        (synthetic, 11 materials, 1.5 s, 3-fold): with the copies one heated channel is 11-15
        points below svm-pca at ambient (.678 against .787, seed 7) and on +-8 K objects no
        better (.06 material, its p >= 0.9 answers 6 % right); without them it is level with
        svm-pca at ambient. With a second channel (heated + passive) the copies turn chance
        into .56 material / .93 family on +-8 K objects, so there they stay.
    raw_expert : bool
        Where no copies are made (the training data cannot pin the object's temperature),
        combine the probabilities with a raw-window expert (svm-pca itself: PCA of the primary
        window above ambient into a linear SVM), which reads what ambient data shows (the
        object at ambient, the protocol's sensor history): ``softmax(a log p + b s)`` with the
        SVM's scores ``s`` and one weight per expert fitted on held-out rows (a temperature
        each; on the low-cost sensor the physics gets a ~ 0.1, on the paper's ~ 0.6-0.75).
        Measured (3-fold, seeds 7 / 8, 0.5, 1.5, 2.5 s): physics model alone .640 .767 .775 /
        .563 .761 .800; with the former logistic-regression expert .670 .785 .789 / .595 .762
        .787; svm-pca .648 .794 .799 / .567 .762 .772 (this expert: the notes of issue 17).
    random_state : int
        Seed of the copies, the folds and the trees.
    """

    def __init__(self, channels: int = 1, fs: float = 200.0, object_spread: float = 10.0,
                 copies: int = 2, learner: str = "linear", C: float | None = None,
                 calibration: str | None = "temperature", cv: int = 3, points: int = 4,
                 excess: bool = True, warp: float = 0.25, sensor_spread: float = 0.5,
                 unpinned_copies: bool = False, raw_expert: bool = True,
                 random_state: int = 0) -> None:
        self.raw_expert = raw_expert
        self.unpinned_copies = unpinned_copies
        self.warp = warp
        self.sensor_spread = sensor_spread
        self.channels = channels
        self.fs = fs
        self.object_spread = object_spread
        self.copies = copies
        self.learner = learner
        self.C = C
        self.calibration = calibration
        self.cv = cv
        self.points = points
        self.excess = excess
        self.random_state = random_state

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.allow_nan = True  # an absent channel is NaN
        return tags

    def augment(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Add the shifted-object copies of the training rows (module docstring).

        The object's recorded temperature is the joint fit's where the row has a second
        channel to pin it, else ambient.
        """
        if self.object_spread <= 0 or self.copies < 1:
            return x, y
        amb, t0, w = split_contact_rows(x, self.channels)
        obj = np.zeros(x.shape[0])
        pinned = np.isfinite(t0[:, 1:]).any(axis=1) if self.channels > 1 else obj > 0
        if not (pinned.any() or self.unpinned_copies):
            return x, y  # one heated channel: the copies would only blur (class docstring)
        if pinned.any():
            from skin.models.physics import SensorConstants

            resp = grid_responses(w.shape[2], self.fs, SensorConstants())
            obj[pinned] = grid_fit(amb[pinned], t0[pinned], w[pinned], resp)["object"]
        gap = amb + obj - t0[:, 0]  # the object minus the primary channel
        usable = np.abs(gap) >= 2.0  # phi is read from the primary channel's excursion
        phi = (w[:, 0] - t0[:, :1]) / np.where(usable, gap, 1.0)[:, None]
        rng = np.random.default_rng(self.random_state)
        xs, ys = [x], [y]
        t0_recorded = t0
        m = w.shape[2]
        k = np.arange(m, dtype=float)
        for _ in range(self.copies):
            delta = rng.uniform(-self.object_spread, self.object_spread, x.shape[0])
            # each other channel is another taxel: its response runs faster or slower (depth
            # and diffusivity within +-10 % rescale time by up to ~+-25 %)
            warp = np.exp(rng.uniform(-self.warp, self.warp, (x.shape[0], self.channels)))
            warp[:, 0] = 1.0
            idx = np.minimum(k[None, None, :] * warp[:, :, None], m - 1)
            lo = np.floor(idx).astype(int)
            hi = np.minimum(lo + 1, m - 1)
            frac = idx - lo
            ph = phi[:, None, :]
            ph = np.broadcast_to(ph, (x.shape[0], self.channels, m))
            moved = (np.take_along_axis(ph, lo, axis=2) * (1 - frac)
                     + np.take_along_axis(ph, hi, axis=2) * frac)
            shifted = w + delta[:, None, None] * moved
            if self.sensor_spread:
                # the primary taxel starts at another temperature (a history of other
                # touches): T0 + eps, and its reading moves by eps (1 - phi)
                room = np.maximum(t0[:, 0] - amb - 1.0, 0.0)
                eps = -rng.uniform(0.0, 1.0, x.shape[0]) * room * self.sensor_spread
                shifted[:, 0] += eps[:, None] * (1.0 - phi)
                t0 = t0.copy()
                t0[:, 0] += eps
            block = np.concatenate([t0[:, :, None], shifted], axis=2)
            t0 = t0_recorded
            rows = np.column_stack([amb, block.reshape(x.shape[0], -1)])
            xs.append(rows[usable])
            ys.append(y[usable])
        return np.vstack(xs), np.concatenate(ys)

    def _learner(self):
        from sklearn.ensemble import HistGradientBoostingClassifier
        from sklearn.linear_model import LogisticRegression
        from sklearn.pipeline import make_pipeline
        from sklearn.preprocessing import StandardScaler

        if self.learner == "trees":
            return HistGradientBoostingClassifier(max_iter=200, learning_rate=0.1,
                                                  l2_regularization=1.0, early_stopping=False,
                                                  random_state=self.random_state)
        if self.learner == "linear":
            return make_pipeline(StandardScaler(), LogisticRegression(C=self.C_, max_iter=5000))
        raise ValueError(f"unknown learner {self.learner!r}; linear or trees")

    def fit(self, X: np.ndarray, y: np.ndarray, groups: np.ndarray | None = None
            ) -> ContactClassifier:
        """Fit the features' grid, then the calibrated learner on the (augmented) rows.

        ``groups`` (one per row, e.g. the taxel unit that recorded it): the held-out folds
        that fit the calibration keep each group on one side, so the probabilities are as
        sure as they are on taxels the model has not seen (None: stratified folds).
        """
        from sklearn.calibration import CalibratedClassifierCV
        from sklearn.model_selection import StratifiedKFold
        from sklearn.utils.multiclass import check_classification_targets

        x, y = validate_data(self, X, y, reset=True, ensure_all_finite="allow-nan")
        check_classification_targets(y)
        self.classes_, counts = np.unique(y, return_counts=True)
        if self.classes_.size < 2:
            raise ValueError("ContactClassifier needs at least two classes")
        if self.calibration not in (None, "temperature", "isotonic", "sigmoid"):
            raise ValueError(f"unknown calibration {self.calibration!r}")
        if self.calibration is not None and counts.min() < self.cv:
            raise ValueError(f"class {str(self.classes_[np.argmin(counts)])!r} has "
                             f"{counts.min()} trial(s); calibrating by {self.cv}-fold "
                             f"cross-validation needs at least {self.cv} per class")
        xa, source = self.augment(x, np.arange(y.size))  # each row's training contact
        ya = y[source]
        if groups is not None:
            groups = np.asarray(groups)
            if groups.shape != y.shape:
                raise ValueError(f"groups of shape {groups.shape}, one per row of y "
                                 f"{y.shape} expected")
            groups = groups[source]
        self.copied_ = ya.size > y.size
        self.C_ = self.C if self.C is not None else (0.1 if self.copied_ else 1.0)
        self.features_ = ContactFeatures(self.channels, self.fs, points=self.points,
                                         excess=self.excess).fit(xa)
        f = self.features_.transform(xa)
        self.temperature_ = 1.0
        if self.calibration in ("isotonic", "sigmoid"):
            self.model_ = CalibratedClassifierCV(self._learner(), method=self.calibration,
                                                 cv=self.cv).fit(f, ya)
            return self
        # the raw-window expert reads what ambient data shows; with copies (an object whose
        # temperature the model must read) it would teach the opposite, so only without them
        w0 = _relative_window(x, self.channels) if self.raw_expert else None
        use_raw = self.raw_expert and not self.copied_
        index = np.searchsorted(self.classes_, ya)
        self.expert_weights_ = (1.0, 1.0)
        if self.calibration == "temperature":
            logits = np.zeros((f.shape[0], self.classes_.size))
            raw = np.zeros_like(logits)
            if groups is not None and np.unique(groups).size >= self.cv:
                from sklearn.model_selection import StratifiedGroupKFold

                split = StratifiedGroupKFold(self.cv, shuffle=True,
                                             random_state=self.random_state).split(f, index,
                                                                                   groups)
            else:
                split = StratifiedKFold(self.cv, shuffle=True,
                                        random_state=self.random_state).split(f, index)
            for tr, te in split:
                logits[te] = _log_proba(self._learner().fit(f[tr], index[tr]), f[te],
                                        self.classes_.size)
                if use_raw:
                    raw[te] = _raw_scores(_raw_expert(w0[tr]).fit(w0[tr], index[tr]), w0[te],
                                          self.classes_.size)
            if use_raw:  # one temperature per expert
                self.expert_weights_ = fit_expert_weights(logits, raw, index)
            else:
                self.temperature_ = fit_temperature(logits, index)
        self.model_ = self._learner().fit(f, ya)
        self.raw_ = _raw_expert(w0).fit(w0, index) if use_raw else None
        return self

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """Calibrated class probabilities, (n, n_classes)."""
        check_is_fitted(self, "model_")
        x = validate_data(self, X, reset=False, ensure_all_finite="allow-nan")
        p = self.model_.predict_proba(self.features_._features(x))
        if self.temperature_ == 1.0 and getattr(self, "raw_", None) is None:
            return p
        logits = np.log(np.maximum(p, 1e-300))
        if getattr(self, "raw_", None) is not None:
            a, b = self.expert_weights_
            logits = a * np.maximum(logits, -700.0) + b * _raw_scores(
                self.raw_, _relative_window(x, self.channels), self.classes_.size)
        return _softmax(logits / self.temperature_)

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Most probable class."""
        check_is_fitted(self, "model_")
        return self.classes_[np.argmax(self.predict_proba(X), axis=1)]
