"""Material classifiers shared by all taxels, on scikit-learn's estimator contract.

Every method takes rows laid out by `skin.models.features.trial_matrix`
(``[ambient, T0, T(onset) ... T(onset + n - 1)]``) and is built by `make_method`:

- ``svm-pca``: the paper's PCA (10 components) + linear SVM on the raw window;
- ``knn-pca``: the paper's PCA (10 components) + 3-nearest neighbours;
- ``hmm``: the paper's left-right Gaussian HMMs, one per material, 25 states, trained by
  Baum-Welch (hmmlearn) and compared by their Viterbi scores;
- ``model``: the paper's model-based method (the effusivity histogram, eqs. 9-11, against
  the materials table); it learns nothing;

each with ``:raw`` (default), ``:slope`` or ``:both`` features, e.g. ``svm-pca:both``;

- ``default``: the library's recommendation, `skin.models.contact.ContactClassifier`: the
  joint physics fit of all a contact's channels (one object temperature shared) and their
  traces into calibrated gradient-boosted trees. It alone reads every channel of a contact
  (rows of `skin.models.features.contact_matrix`); the others read the primary channel;
- ``fit-trees``: the previous default, `PhysicsFeatures` (one channel's contact fit and its
  normalised trace) into gradient-boosted trees.
"""

from __future__ import annotations

import itertools

import numpy as np

from skin._optional import require

require("sklearn", "ml")  # importing this module is using the classifiers

from sklearn.base import BaseEstimator, ClassifierMixin, TransformerMixin  # noqa: E402
from sklearn.utils.validation import check_is_fitted, validate_data  # noqa: E402

from skin.errors import SkinError  # noqa: E402
from skin.models.features import KINDS, split_rows, trace_features  # noqa: E402

PAPER_METHODS = ("svm-pca", "knn-pca", "hmm", "model")
UNKNOWN = "unknown"


def parse_method(name: str) -> tuple[str, str]:
    """Split ``"svm-pca:both"`` into ``("svm-pca", "both")``; validate both parts."""
    base, _, kind = name.partition(":")
    kind = kind or "raw"
    if base not in METHODS:
        raise SkinError(f"unknown method {base!r}; choose from {', '.join(METHODS)}")
    if kind not in KINDS:
        raise SkinError(f"unknown features {kind!r} in {name!r}; choose from {', '.join(KINDS)}")
    return base, kind


def make_method(name: str, fs: float = 200.0, channels: int = 1):
    """Return a fresh, unfitted estimator for a method name such as ``"knn-pca:both"``.

    ``channels`` is the number of channel blocks of the rows of a method that reads every
    channel (`reads_channels`); the others ignore it.
    """
    base, kind = parse_method(name)
    if base in CHANNEL_METHODS:
        return METHODS[base](kind, fs, channels)
    return METHODS[base](kind, fs)


def reads_channels(name: str) -> bool:
    """Whether a method reads every channel of a contact (else the primary one)."""
    return parse_method(name)[0] in CHANNEL_METHODS


def method_matrix(data, name: str, duration: float) -> np.ndarray:
    """Return the rows a method reads: `contact_matrix` or `trial_matrix` of ``data``."""
    from skin.models.features import contact_matrix, trial_matrix

    return contact_matrix(data, duration) if reads_channels(name) else trial_matrix(data,
                                                                                    duration)


def _svm_pca(kind: str, fs: float):
    from sklearn.decomposition import PCA
    from sklearn.pipeline import make_pipeline
    from sklearn.svm import SVC

    # seeded: on large windows scikit-learn picks its randomized solver, and an unseeded one
    # moved the accuracy by up to 0.7 points between identical runs
    return make_pipeline(TraceFeatures(kind=kind, fs=fs), PCA(n_components=10, random_state=0),
                         SVC(kernel="linear"))


def _knn_pca(kind: str, fs: float):
    from sklearn.decomposition import PCA
    from sklearn.neighbors import KNeighborsClassifier
    from sklearn.pipeline import make_pipeline

    return make_pipeline(TraceFeatures(kind=kind, fs=fs), PCA(n_components=10, random_state=0),
                         KNeighborsClassifier(n_neighbors=3))


def _hmm(kind: str, fs: float):
    return HMMClassifier(features=kind, fs=fs)


def _model(kind: str, fs: float):
    return ModelBasedClassifier(fs=fs)


def _default(kind: str, fs: float, channels: int = 1):
    from skin.models.contact import ContactClassifier

    return ContactClassifier(channels=channels, fs=fs)


def _fit_trees(kind: str, fs: float):
    from sklearn.ensemble import HistGradientBoostingClassifier
    from sklearn.pipeline import make_pipeline

    # early stopping, a slower rate and an L2 penalty keep the trees' probabilities honest
    # (expected calibration error 0.33 -> 0.10 at 0.5 s, 0.19 -> 0.06 at 2.5 s, same accuracy)
    return make_pipeline(PhysicsFeatures(fs=fs),
                         HistGradientBoostingClassifier(max_iter=300, learning_rate=0.05,
                                                        l2_regularization=1.0,
                                                        early_stopping=True, random_state=0))


METHODS = {"svm-pca": _svm_pca, "knn-pca": _knn_pca, "hmm": _hmm, "model": _model,
           "default": _default, "fit-trees": _fit_trees}
CHANNEL_METHODS = frozenset({"default"})



def _check_targets(y: np.ndarray) -> None:
    """Raise ValueError for a continuous target or a single class (sklearn's wording)."""
    from sklearn.utils.multiclass import check_classification_targets

    check_classification_targets(y)
    if np.unique(y).size < 2:
        raise ValueError("a classifier needs at least two classes; got 1 class")


class TraceFeatures(TransformerMixin, BaseEstimator):
    """The paper's features of `trial_matrix` rows: raw window, slope, or both.

    Parameters
    ----------
    kind : str
        ``"raw"``, ``"slope"`` or ``"both"``.
    fs : float
        Sampling rate, Hz.
    """

    def __init__(self, kind: str = "raw", fs: float = 200.0) -> None:
        self.kind = kind
        self.fs = fs

    def fit(self, X: np.ndarray, y: np.ndarray | None = None) -> TraceFeatures:
        """Check the rows; nothing is learned."""
        validate_data(self, X, reset=True)
        if self.kind not in KINDS:
            raise ValueError(f"unknown feature kind {self.kind!r}")
        return self

    def transform(self, X: np.ndarray) -> np.ndarray:
        """Return the feature vectors."""
        check_is_fitted(self, "n_features_in_")
        x = validate_data(self, X, reset=False)
        return trace_features(x, self.kind, self.fs)


def _sequences(x: np.ndarray, kind: str, fs: float, decimate: int) -> np.ndarray:
    """Observation sequences (n_trials, n_samples // decimate, n_dims) for the HMMs.

    Each observation is the mean of ``decimate`` consecutive samples (the slope is computed
    at the full rate first).
    """
    w = split_rows(x)[2]
    n = w.shape[1]
    if kind == "raw":
        seq = w[:, :, None]
    else:
        s = trace_features(x, "both", fs)[:, n:]
        seq = s[:, :, None] if kind == "slope" else np.stack([w, s], axis=2)
    m = max(n // decimate, 1)
    return seq[:, : m * decimate].reshape(seq.shape[0], m, -1, seq.shape[2]).mean(axis=2)


class _quiet_hmmlearn:
    """Silence hmmlearn's logged warnings about degenerate states during a fit."""

    def __enter__(self) -> None:
        import logging

        self._logger = logging.getLogger("hmmlearn")
        self._level = self._logger.level
        self._logger.setLevel(logging.ERROR)

    def __exit__(self, *exc: object) -> None:
        self._logger.setLevel(self._level)


class HMMClassifier(ClassifierMixin, BaseEstimator):
    """The paper's classifier: one left-right Gaussian HMM per material, best Viterbi score.

    Parameters
    ----------
    n_states : int
        Hidden states per model (the paper: 25).
    features : str
        Emissions: ``"raw"`` (1-D), ``"slope"`` (1-D) or ``"both"`` (2-D).
    n_iter : int
        Baum-Welch iterations.
    fs : float
        Sampling rate, Hz.
    decimate : int
        Observations are means of this many samples (5: 40 Hz, still 20 observations in
        0.5 s); training time falls by the same factor. 1 is the paper's full rate.
    random_state : int
        Seed of hmmlearn.
    """

    def __init__(self, n_states: int = 25, features: str = "raw", n_iter: int = 10,
                 fs: float = 200.0, decimate: int = 5, random_state: int = 0) -> None:
        self.n_states = n_states
        self.features = features
        self.n_iter = n_iter
        self.fs = fs
        self.decimate = decimate
        self.random_state = random_state

    def fit(self, X: np.ndarray, y: np.ndarray) -> HMMClassifier:
        """Train one HMM per class by Baum-Welch."""
        require("hmmlearn", "ml")
        from hmmlearn.hmm import GaussianHMM

        x, y = validate_data(self, X, y, reset=True)
        _check_targets(y)
        self.classes_ = np.unique(y)
        seqs = _sequences(x, self.features, self.fs, self.decimate)
        _, length, dims = seqs.shape
        k = max(1, min(self.n_states, length // 2))  # at least two observations per state
        self.models_ = []
        for c in self.classes_:
            obs = seqs[y == c]
            # left-right: start in state 0, stay or move one state on; zeros stay zero under
            # Baum-Welch. Means and variances start from equal slices of the trials in time.
            trans = np.zeros((k, k))
            for i in range(k):
                trans[i, i] = 0.5 if i < k - 1 else 1.0
                if i < k - 1:
                    trans[i, i + 1] = 0.5
            edges = np.linspace(0, length, k + 1).astype(int)
            means = np.array([obs[:, a:max(b, a + 1)].reshape(-1, dims).mean(axis=0)
                              for a, b in itertools.pairwise(edges)])
            var = np.array([obs[:, a:max(b, a + 1)].reshape(-1, dims).var(axis=0)
                            for a, b in itertools.pairwise(edges)])
            model = GaussianHMM(n_components=k, covariance_type="diag", n_iter=self.n_iter,
                                init_params="", params="tmc", random_state=self.random_state,
                                min_covar=1e-4)
            model.startprob_ = np.eye(k)[0]
            model.transmat_ = trans
            model.means_ = means
            model.covars_ = np.maximum(var, 1e-4)
            with _quiet_hmmlearn():
                model.fit(obs.reshape(-1, dims), lengths=[length] * obs.shape[0])
            # a state no training trial left keeps its self-loop (rows must sum to 1)
            dead = model.transmat_.sum(axis=1) == 0
            if dead.any():
                t = model.transmat_.copy()
                t[dead, dead] = 1.0
                model.transmat_ = t
            self.models_.append(model)
        return self

    def decision_function(self, X: np.ndarray) -> np.ndarray:
        """Viterbi log-probability of each trial under each class's HMM, (n, n_classes)."""
        check_is_fitted(self, "models_")
        x = validate_data(self, X, reset=False)
        seqs = _sequences(x, self.features, self.fs, self.decimate)
        out = np.empty((seqs.shape[0], len(self.models_)))
        for j, model in enumerate(self.models_):
            for i, seq in enumerate(seqs):
                out[i, j] = model.decode(seq, algorithm="viterbi")[0]
        return out

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Label of the HMM with the best Viterbi score."""
        check_is_fitted(self, "models_")
        return self.classes_[np.argmax(self.decision_function(X), axis=1)]


class ModelBasedClassifier(ClassifierMixin, BaseEstimator):
    """The paper's model-based method: histogram of pointwise effusivity against the table.

    It learns nothing from the data: `fit` only records which classes the table should
    choose among (those of ``y`` that the materials table knows). Trials whose estimates do
    not allow a decision are labelled ``"unknown"``.

    Parameters
    ----------
    fs : float
        Sampling rate, Hz.
    bins : int
        Histogram bins (the paper: 10).
    """

    def __init__(self, fs: float = 200.0, bins: int = 10) -> None:
        self.fs = fs
        self.bins = bins

    def fit(self, X: np.ndarray, y: np.ndarray) -> ModelBasedClassifier:
        """Restrict the table to the classes of ``y``."""
        from skin.models.materials import load_materials

        validate_data(self, X, y, reset=True)
        _check_targets(y)
        table = load_materials()
        self.classes_ = np.unique(y)
        unknown = [c for c in self.classes_ if c not in table]
        if unknown:
            raise SkinError(f"the model-based method needs every class in the materials "
                            f"table; not there: {', '.join(map(str, unknown))}")
        self.candidates_ = [str(c) for c in self.classes_]  # names: model files hold no objects
        return self

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Label each trial (or ``"unknown"``)."""
        from skin.models.effusivity import classify_log_effusivity
        from skin.models.materials import load_materials
        from skin.models.physics import SensorConstants, effusivity_estimates

        check_is_fitted(self, "candidates_")
        table = load_materials()
        candidates = [table[c] for c in self.candidates_]
        amb, t0, w = split_rows(validate_data(self, X, reset=False))
        t = np.arange(w.shape[1]) / self.fs
        sensor = SensorConstants()
        out = []
        for i in range(w.shape[0]):
            _, e = effusivity_estimates(t, w[i], float(t0[i]), float(amb[i]), sensor)
            est = classify_log_effusivity(np.log10(e), candidates, bins=self.bins)
            out.append(est.label)
        return np.array(out, dtype=object)


class PhysicsFeatures(TransformerMixin, BaseEstimator):
    """Features that do not depend on how warm the room or the taxel was.

    Per trial: the contact fit (`skin.models.inverse.fit_contact` with an onset shift):
    log10 effusivity, object temperature above ambient, log10 contact conductance, the
    effusivity's posterior std, the residual and the onset shift; the sensor's excess over
    ambient T0 - T_amb; and the reading and its slope at ``points`` log-spaced instants,
    normalised by that excess: (T(t) - T0) / (T0 - T_amb), which for an object at ambient
    depends on the material alone.

    Parameters
    ----------
    points : int
        Log-spaced instants of the normalised trace and slope.
    fs : float
        Sampling rate, Hz.
    """

    def __init__(self, points: int = 12, fs: float = 200.0) -> None:
        self.points = points
        self.fs = fs

    def fit(self, X: np.ndarray, y: np.ndarray | None = None) -> PhysicsFeatures:
        """Check the rows; nothing is learned."""
        validate_data(self, X, reset=True)
        return self

    def transform(self, X: np.ndarray) -> np.ndarray:
        """Return the feature vectors, (n_trials, 7 + 2 points)."""
        from skin.models.inverse import fit_contact

        check_is_fitted(self, "n_features_in_")
        x = validate_data(self, X, reset=False)
        amb, t0, w = split_rows(x)
        n = w.shape[1]
        t = np.arange(n) / self.fs
        fit = fit_contact(t[1:], w[:, 1:], t0, amb, fit_onset=True)
        excess = t0 - amb
        scale = np.where(np.abs(excess) < 0.1, np.copysign(0.1, excess + 1e-12), excess)
        k = np.unique(np.round(np.geomspace(1, n - 1, self.points)).astype(int))
        k = np.pad(k, (0, self.points - k.size), mode="edge")  # short windows repeat
        s = trace_features(x, "slope", self.fs)
        return np.column_stack([
            np.log10(fit.effusivity), fit.object_temperature - amb, np.log10(fit.conductance),
            fit.log10_effusivity_std, fit.rms, fit.onset_shift, excess,
            (w[:, k] - t0[:, None]) / scale[:, None], s[:, k] / scale[:, None]])


def fuse_probabilities(probabilities: np.ndarray) -> np.ndarray:
    """Fuse the class probabilities of several taxels touching one object.

    The taxels' evidence is treated as independent given the material (naive Bayes with a
    flat prior): the fused probability is the normalised product, computed in log space so
    that many confident taxels do not underflow.

    Parameters
    ----------
    probabilities : numpy.ndarray
        (n_taxels, n_classes), each row a distribution.

    Returns
    -------
    numpy.ndarray
        (n_classes,), summing to 1.
    """
    p = np.asarray(probabilities, dtype=float)
    if p.ndim != 2 or p.shape[0] == 0:
        raise ValueError(f"expected (n_taxels, n_classes) probabilities, got shape {p.shape}")
    log = np.log(np.clip(p, 1e-300, 1.0)).sum(axis=0)
    log -= log.max()
    out = np.exp(log)
    return out / out.sum()


def truncate_rows(x: np.ndarray, channels: int, samples: int) -> np.ndarray:
    """Cut rows of ``channels`` blocks ``[T0, window...]`` (after ambient) to ``samples``."""
    x = np.asarray(x, dtype=float)
    block = (x.shape[1] - 1) // channels
    b = x[:, 1:].reshape(x.shape[0], channels, block)[:, :, : 1 + samples]
    return np.column_stack([x[:, 0], b.reshape(x.shape[0], -1)])


def fit_grouped(model, X: np.ndarray, y: np.ndarray, groups: np.ndarray | None = None):
    """Fit ``model``, passing ``groups`` when its ``fit`` takes them; return the model."""
    import inspect

    if groups is not None and "groups" in inspect.signature(model.fit).parameters:
        return model.fit(X, y, groups=groups)
    return model.fit(X, y)


class AnytimeClassifier(ClassifierMixin, BaseEstimator):
    """A label and a confidence at any moment after onset, "unknown" until it is sure.

    One model per duration of ``durations`` (all of the same ``method``); for a window of a
    given length the model of the longest duration that fits is used, and its most probable
    class is returned when its probability reaches ``threshold``, else ``"unknown"``.

    Parameters
    ----------
    method : str
        A method with probabilities (``"default"``).
    durations : tuple of float
        Window lengths with a model, s.
    threshold : float
        Probability needed to name a material.
    fs : float
        Sampling rate, Hz.
    channels : int
        Channel blocks per row (a method that reads every channel; else 1).
    """

    def __init__(self, method: str = "default", durations: tuple = (0.25, 0.5, 1.0, 2.5),
                 threshold: float = 0.8, fs: float = 200.0, channels: int = 1) -> None:
        self.method = method
        self.durations = durations
        self.threshold = threshold
        self.fs = fs
        self.channels = channels

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.allow_nan = reads_channels(self.method)
        return tags

    def _samples(self, x: np.ndarray) -> int:
        return (x.shape[1] - 1) // self.channels - 1

    def fit(self, X: np.ndarray, y: np.ndarray, groups: np.ndarray | None = None
            ) -> AnytimeClassifier:
        """Fit one model per duration on the rows truncated to it.

        ``groups`` (one per row: trials that share a taxel or recording unit share a group)
        go to each model whose ``fit`` takes them (the default's calibration folds keep each
        group on one side); the others ignore them.
        """
        nan = "allow-nan" if reads_channels(self.method) else True
        x, y = validate_data(self, X, y, reset=True, ensure_all_finite=nan)
        _check_targets(y)
        if not hasattr(make_method(self.method, self.fs), "predict_proba"):
            raise ValueError(f"method {self.method!r} gives no probabilities, so it cannot say "
                             f"how sure it is; anytime needs default, knn-pca or hmm")
        n = self._samples(x)
        self.samples_ = [round(d * self.fs) for d in self.durations if round(d * self.fs) <= n]
        if not self.samples_:
            raise ValueError(f"windows of {n} samples are shorter than every duration")
        self.models_ = [fit_grouped(make_method(self.method, self.fs, self.channels),
                                    truncate_rows(x, self.channels, k), y, groups)
                        for k in self.samples_]
        self.classes_ = self.models_[0].classes_
        return self

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """Class probabilities from the model of the longest duration the rows cover."""
        check_is_fitted(self, "models_")
        x = np.asarray(X, dtype=float)
        n = self._samples(x)
        usable = [i for i, k in enumerate(self.samples_) if k <= n]
        if not usable:
            return np.full((x.shape[0], len(self.classes_)), 1.0 / len(self.classes_))
        i = usable[-1]
        return self.models_[i].predict_proba(truncate_rows(x, self.channels, self.samples_[i]))

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Most probable class where sure enough, else ``"unknown"``."""
        p = self.predict_proba(X)
        best = np.argmax(p, axis=1)
        labels = self.classes_[best].astype(object)
        labels[p[np.arange(len(best)), best] < self.threshold] = UNKNOWN
        return labels


#: Why scikit-learn's generic checks fail on these estimators, by reason (see
#: `expected_failed_checks`); every other check of `check_estimator` passes (a test runs them).
LAYOUT = ("its rows are [ambient, T0, window...] blocks (trial_matrix / contact_matrix) and a "
          "window needs a few samples; the generic check feeds 1-3 columns")
TABLE = ("the model-based method chooses among materials-table names, so its classes must be "
         "material names; the generic check uses 0, 1, 2 or 'one', 'two'")
#: The generic checks the model-based and anytime classifiers fail (for different reasons).
_TABLE_OR_LAYOUT_CHECKS = (
    "check_classifier_data_not_an_array",
    "check_classifiers_classes",
    "check_classifiers_train",
    "check_dict_unchanged",
    "check_dont_overwrite_parameters",
    "check_dtype_object",
    "check_estimators_dtypes",
    "check_estimators_fit_returns_self",
    "check_estimators_nan_inf",
    "check_estimators_overwrite_params",
    "check_estimators_pickle",
    "check_f_contiguous_array_estimator",
    "check_fit2d_1feature",
    "check_fit2d_predict1d",
    "check_fit_check_is_fitted",
    "check_fit_idempotent",
    "check_fit_score_takes_y",
    "check_methods_sample_order_invariance",
    "check_methods_subset_invariance",
    "check_n_features_in",
    "check_n_features_in_after_fitting",
    "check_pipeline_consistency",
    "check_positive_only_tag_during_fit",
    "check_readonly_memmap_input",
    "check_supervised_y_2d",
)
EXPECTED_FAILED_CHECKS: dict[str, dict[str, str]] = {
    "ContactFeatures": {
        **dict.fromkeys((
            "check_dict_unchanged",
            "check_dont_overwrite_parameters",
            "check_estimators_fit_returns_self",
            "check_estimators_overwrite_params",
            "check_estimators_pickle",
            "check_f_contiguous_array_estimator",
            "check_fit2d_1feature",
            "check_fit2d_predict1d",
            "check_fit_check_is_fitted",
            "check_fit_idempotent",
            "check_fit_score_takes_y",
            "check_methods_sample_order_invariance",
            "check_methods_subset_invariance",
            "check_n_features_in",
            "check_n_features_in_after_fitting",
            "check_pipeline_consistency",
            "check_positive_only_tag_during_fit",
            "check_readonly_memmap_input",
            "check_transformer_data_not_an_array",
            "check_transformer_general",
            "check_transformer_preserve_dtypes",
        ), LAYOUT),
    },
    "ContactClassifier": {
        **dict.fromkeys((
            "check_classifier_data_not_an_array",
            "check_classifiers_classes",
            "check_classifiers_train",
            "check_dict_unchanged",
            "check_dont_overwrite_parameters",
            "check_estimators_fit_returns_self",
            "check_estimators_overwrite_params",
            "check_estimators_pickle",
            "check_f_contiguous_array_estimator",
            "check_fit2d_1feature",
            "check_fit2d_1sample",
            "check_fit2d_predict1d",
            "check_fit_check_is_fitted",
            "check_fit_idempotent",
            "check_fit_score_takes_y",
            "check_methods_sample_order_invariance",
            "check_methods_subset_invariance",
            "check_n_features_in",
            "check_n_features_in_after_fitting",
            "check_pipeline_consistency",
            "check_positive_only_tag_during_fit",
            "check_readonly_memmap_input",
            "check_supervised_y_2d",
        ), LAYOUT),
    },
    "TraceFeatures": {
        **dict.fromkeys((
            "check_dict_unchanged",
            "check_estimators_pickle",
            "check_f_contiguous_array_estimator",
            "check_fit_idempotent",
            "check_fit_score_takes_y",
            "check_methods_sample_order_invariance",
            "check_methods_subset_invariance",
            "check_pipeline_consistency",
            "check_transformer_data_not_an_array",
            "check_transformer_general",
            "check_transformer_preserve_dtypes",
        ), LAYOUT),
    },
    "PhysicsFeatures": {
        **dict.fromkeys((
            "check_dict_unchanged",
            "check_estimators_dtypes",
            "check_estimators_pickle",
            "check_f_contiguous_array_estimator",
            "check_fit_idempotent",
            "check_fit_score_takes_y",
            "check_methods_sample_order_invariance",
            "check_methods_subset_invariance",
            "check_pipeline_consistency",
            "check_transformer_data_not_an_array",
            "check_transformer_general",
            "check_transformer_preserve_dtypes",
        ), LAYOUT),
    },
    "ModelBasedClassifier": dict.fromkeys(_TABLE_OR_LAYOUT_CHECKS, TABLE),
    "AnytimeClassifier": dict.fromkeys(_TABLE_OR_LAYOUT_CHECKS, LAYOUT),
    "HMMClassifier": {
        **dict.fromkeys((
            "check_classifier_data_not_an_array",
            "check_classifiers_classes",
            "check_classifiers_train",
            "check_dict_unchanged",
            "check_dont_overwrite_parameters",
            "check_estimators_fit_returns_self",
            "check_estimators_nan_inf",
            "check_estimators_overwrite_params",
            "check_estimators_pickle",
            "check_f_contiguous_array_estimator",
            "check_fit2d_1feature",
            "check_fit2d_predict1d",
            "check_fit_check_is_fitted",
            "check_fit_idempotent",
            "check_fit_score_takes_y",
            "check_methods_sample_order_invariance",
            "check_methods_subset_invariance",
            "check_n_features_in",
            "check_pipeline_consistency",
            "check_readonly_memmap_input",
            "check_supervised_y_2d",
        ), LAYOUT),
    },
}


def expected_failed_checks(estimator: object) -> dict[str, str]:
    """Return the generic scikit-learn checks an estimator is expected to fail, with why.

    Pass it to `sklearn.utils.estimator_checks.check_estimator` (``expected_failed_checks=``).
    """
    return dict(EXPECTED_FAILED_CHECKS.get(type(estimator).__name__, {}))
