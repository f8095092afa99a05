"""One object, several taxels: the material's evidence with the object's temperature shared.

A single heated taxel cannot tell a cold object from one of higher effusivity. After contact
its reading is ``T0 + (T_obj - T0) r R(t)``, with ``r = e_o / (e_s + e_o)`` and ``R`` the
thermistor's response (`skin.models.physics.contact_response`): the object's temperature and
its effusivity enter through one amplitude, and with the contact conductance unknown the
shape of ``R`` cannot separate them either. Cold pine looks like warm glass.

Taxels that touch the same object at *different* initial temperatures break the tie: each
sees ``(T_obj - T0_i) r``, two unknowns that two distinct ``T0_i`` pin down. Per-taxel
classifiers fused as independent evidence (`skin.models.classifiers.fuse_probabilities`)
cannot use this, because each marginalises the object's temperature on its own.
`JointContactModel` shares it: for each candidate material and each contact conductance of
the material's range, the reading is linear in ``T_obj``, so with a Gaussian prior on
``T_obj`` (around ambient) its marginal likelihood is closed form (Bayesian regression with
one coefficient); the conductance is marginalised on a log grid, and the materials are
compared by that evidence.

A sensor other than the paper's (`skin.models.sensors.SensorDescription`: a heater switched
off or left on at contact, a PID loop, a thermistor lag, smoothing) reads
``T0 + (T_obj - T0) P + (T_amb - T0) Q + A`` (`skin.models.sensors.contact_basis`): its
filters are linear and time-invariant, so the reading stays linear in ``T_obj``, and the
heater's terms ``Q`` and ``A`` do not depend on it; they are subtracted as an offset per
material and conductance, and the evidence keeps its closed form.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from skin.contact import UNKNOWN, MaterialEstimate
from skin.models.materials import Material
from skin.models.physics import SensorConstants, conductance_rate, contact_response
from skin.models.sensors import SensorDescription, contact_basis, has_dynamics

#: How many (sensor, lags) bases of foreign sensors a model keeps (about 1 MB each).
BASIS_CACHE = 32


class JointContactModel:
    """Material evidence of one contact from all its taxels, the object's temperature shared.

    Parameters
    ----------
    materials : sequence of Material
        The candidates.
    sensor : SensorConstants, optional
        The taxels' constants (default: the paper's).
    noise : float or sequence of float
        Standard deviation of a reading about the model, K: the ADC's noise and what the
        model leaves out (taxel spread, onset error). Larger is softer. A sequence is a grid
        the noise is integrated over (each material its own): a contact
        the model explains down to the reading's noise is then judged at that noise, one it
        explains badly (a misdated onset or release) at the grid's largest. Each of the grid's
        noises weighs the same: a log-uniform prior when the grid is geometric. ``noise`` is
        then the grid's largest, ``noises`` the grid.
    object_std : float
        Prior standard deviation of the object's temperature about ambient, K.
    h_points : int
        Contact conductances per material (log-spaced over its range).
    onset_shifts : sequence of float
        How much earlier than the given onset the contact may have begun, s; the evidence is
        averaged over them (default: the onset is right).
    conductance_range : (float, float), optional
        One contact conductance range (W/(m^2 K)) for every material. By default each
        material's own (`Material.conductance_range`, from its surface's air gap), which
        makes the contact's sharpness evidence for the material: a touch firmer or softer
        than the table's gaps (a pressed or a perfect contact) is then taken for another
        material of like effusivity (pine for mdf at p = 0.98 in the default scene).

    Notes
    -----
    Each taxel's own constants (depth, diffusivity, conductivity), when calibrated, are
    passed as ``sensors``: a +-10 % spread left to the nominal constants costs more accuracy
    than ADC noise and onset error together (`skin bench fusion`).
    """

    def __init__(self, materials: Sequence[Material], sensor: SensorConstants | None = None,
                 noise: float | Sequence[float] = 0.1, object_std: float = 10.0, h_points: int = 7,
                 onset_shifts: Sequence[float] = (0.0,),
                 conductance_range: tuple[float, float] | None = None) -> None:
        if not materials:
            raise ValueError("JointContactModel needs at least one candidate material")
        noises = np.atleast_1d(np.asarray(noise, dtype=float))
        if noises.ndim != 1 or noises.size == 0:
            raise ValueError(f"noise must be a number or a non-empty sequence of numbers, "
                             f"not {noise!r}")
        if not (np.all(noises > 0) and object_std > 0 and h_points >= 1):
            raise ValueError("noise and object_std must be positive and h_points at least 1")
        self.materials = list(materials)
        self.classes = [m.name for m in self.materials]
        self.sensor = SensorConstants() if sensor is None else sensor
        self.noises = noises
        self.noise = float(self.noises.max())
        self.object_std = float(object_std)
        self.onset_shifts = np.asarray(onset_shifts, dtype=float)
        if self.onset_shifts.ndim != 1 or self.onset_shifts.size == 0:
            raise ValueError("onset_shifts must be a non-empty sequence of seconds")
        self.effusivity = np.array([m.effusivity for m in self.materials])
        #: prior std of a heat-generating material's temperature about its centre, K (0: none)
        self.own_std = np.array([0.0 if m.temperature is None
                                 else max(0.5 * (m.temperature[1] - m.temperature[0]), 0.5)
                                 for m in self.materials])
        lo_hi = np.log10([m.conductance_range if conductance_range is None
                          else conductance_range for m in self.materials])
        # (n_classes, h_points): each material's contact conductances, log-spaced
        self.conductance = 10.0 ** np.linspace(lo_hi[:, 0], lo_hi[:, 1], h_points, axis=1)
        self._basis_cache: dict = {}  # (sensor, lags) -> contact_basis, oldest first

    def log_evidence(self, t: np.ndarray, temperature: np.ndarray, t_sensor: np.ndarray,
                     ambient: float, sensors: Sequence[SensorConstants] | None = None,
                     ) -> np.ndarray:
        """Log marginal likelihood of each material (up to a shared constant).

        Parameters
        ----------
        t : numpy.ndarray
            Time since contact of each sample, s, (n_samples,); samples at t <= 0 are ignored.
        temperature : numpy.ndarray
            Readings of the taxels touching the object, (n_taxels, n_samples), deg C.
        t_sensor : numpy.ndarray
            Each taxel's temperature just before contact, (n_taxels,), deg C.
        ambient : float
            Room temperature, deg C (the centre of the object-temperature prior).
        sensors : sequence of SensorConstants, optional
            Each taxel's calibrated constants (default: ``sensor`` for all).

        Returns
        -------
        numpy.ndarray
            (n_classes,) log evidence.
        """
        return self.log_evidence_by_std(t, temperature, t_sensor, ambient, sensors,
                                        [self.object_std])[0]

    def log_evidence_by_std(self, t: np.ndarray, temperature: np.ndarray,
                            t_sensor: np.ndarray, ambient: float,
                            sensors: Sequence[SensorConstants] | None,
                            stds: Sequence[float], own: bool = False) -> np.ndarray:
        """Log evidence of each material for each prior std of the object's temperature.

        The arguments are those of `log_evidence`; ``stds`` (K) replace ``object_std``
        (heat-generating materials keep their own prior, unless ``own``: then the stds apply
        to them too, about their own resting temperature). Returns (len(stds), n_classes),
        up to one constant shared by all entries.
        """
        log_ev, _ = self._posterior(t, temperature, t_sensor, ambient, sensors, stds, own)
        top = log_ev.max(axis=-1, keepdims=True)  # log-mean-exp over the h grid
        return top[..., 0] + np.log(np.mean(np.exp(log_ev - top), axis=-1))

    def probabilities(self, t: np.ndarray, temperature: np.ndarray, t_sensor: np.ndarray,
                      ambient: float, sensors: Sequence[SensorConstants] | None = None,
                      ) -> np.ndarray:
        """Posterior probability of each material (flat prior), (n_classes,).

        The arguments are those of `log_evidence`.
        """
        log_ev = self.log_evidence(t, temperature, t_sensor, ambient, sensors)
        p = np.exp(log_ev - log_ev.max())
        return p / p.sum()

    def object_temperature(self, t: np.ndarray, temperature: np.ndarray,
                           t_sensor: np.ndarray, ambient: float, material: str,
                           sensors: Sequence[SensorConstants] | None = None) -> float:
        """Posterior mean of the object's temperature if it is ``material``, deg C.

        Taken at the material's most probable contact conductance of the grid; the other
        arguments are those of `log_evidence`.
        """
        log_ev, mean = self._posterior(t, temperature, t_sensor, ambient, sensors)
        i = self.classes.index(material)
        return float(mean[i, np.argmax(log_ev[i])])

    def _basis(self, lags: np.ndarray, sensor: SensorDescription,
               ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """`contact_basis` of every material and conductance at ``lags``, the last few kept.

        A skin's contacts come back to the same taxels with windows of the same length, and a
        foreign sensor's basis costs some ms (filters over its own sample grid).
        """
        key = (sensor, lags.tobytes())
        hit = self._basis_cache.pop(key, None)
        if hit is None:
            hit = contact_basis(lags, self.effusivity[:, None], self.conductance, sensor)
            if len(self._basis_cache) >= BASIS_CACHE:
                self._basis_cache.pop(next(iter(self._basis_cache)))
        self._basis_cache[key] = hit  # most recent last
        return hit

    def _posterior(self, t: np.ndarray, temperature: np.ndarray, t_sensor: np.ndarray,
                   ambient: float, sensors: Sequence[SensorConstants] | None,
                   stds: Sequence[float] | None = None,
                   own_stds: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Log evidence and posterior mean of T_obj, both (classes, h x onset shifts).

        With ``stds`` (prior stds of the object's temperature, K) both get a leading axis, one
        entry per std.
        """
        t = np.asarray(t, dtype=float)
        y = np.atleast_2d(np.asarray(temperature, dtype=float))
        t0 = np.atleast_1d(np.asarray(t_sensor, dtype=float))
        if y.shape != (t0.size, t.size):
            raise ValueError(f"temperature must be (n_taxels, n_samples) = ({t0.size}, "
                             f"{t.size}), got {y.shape}")
        sensors = [self.sensor] * t0.size if sensors is None else list(sensors)
        if len(sensors) != t0.size:
            raise ValueError(f"{len(sensors)} sensors given for {t0.size} taxels")
        keep = (t > 0) & np.all(np.isfinite(y), axis=0)
        if not keep.any():
            raise ValueError("no finite reading after contact")
        # measured from ambient, so that the sums below stay small (no cancellation)
        t, d, t0 = t[keep], y[:, keep] - t0[:, None], t0 - ambient
        e_o = self.effusivity[:, None, None]
        # phi_i: (classes, h, shifts, samples), taxel i's fraction of (T_obj - T0_i), enters
        # only through pp = sum phi_i^2 and dp = sum d_i phi_i. Shifted sample times mostly
        # coincide (shifts of whole samples): each distinct lag's response R is computed once,
        # taxels with the same constants share it, and when every shift reads a contiguous run
        # of lags (a uniform grid) the sums are running sums and matrix products over R
        n_c, n_h = self.conductance.shape
        n_s, n = self.onset_shifts.size, t.size
        since = (t[None, :] + self.onset_shifts[:, None]).ravel()
        lags, where = np.unique(np.round(since, 9), return_inverse=True)
        where = where.reshape(n_s, n)
        first = where[:, 0]
        contiguous = bool(np.all(where == first[:, None] + np.arange(n)))
        pp = np.empty((n_c, n_h, n_s, t0.size))
        dp = np.empty((n_c, n_h, n_s, t0.size))
        # a sensor with a heater term, dynamics or smoothing (`has_dynamics`) reads
        # d_i = (T_obj - T0_i) P + (T_amb - T0_i) Q + A (`contact_basis`): its offset-corrected
        # e_i = d_i + T0_i Q - A stands in for d_i, and ee (n_c, n_h, n_s) collects
        # sum_i (|e_i|^2 - |d_i|^2) for the quadratic term
        ee = None

        def cross(x: np.ndarray, z: np.ndarray) -> np.ndarray:
            """Sum over the samples of x z at each shift's lags, (classes, h, shifts)."""
            if contiguous:
                run = np.concatenate([np.zeros((*x.shape[:-1], 1)), np.cumsum(x * z, axis=-1)],
                                     -1)
                return run[..., first + n] - run[..., first]
            return np.einsum("chsn,chsn->chs", x[..., where], z[..., where])

        def with_data(x: np.ndarray, dg: np.ndarray) -> np.ndarray:
            """Sum over the samples of x against each taxel's dg (n, taxels): (c, h, s, taxels)."""
            if contiguous:
                return np.stack([x[..., o:o + n] @ dg for o in first], axis=2)
            return np.einsum("in,chsn->chsi", dg.T, x[..., where])

        for sensor in set(sensors):
            group = [i for i, s in enumerate(sensors) if s == sensor]
            dg = d[group].T  # (n, taxels of the group)
            if not has_dynamics(sensor):
                r = (e_o / (sensor.effusivity + e_o) * contact_response(
                    lags[None, None, :], conductance_rate(self.conductance[:, :, None],
                                                          sensor.effusivity, e_o), sensor))
                pp[..., group] = cross(r, r)[..., None]
                dp[..., group] = with_data(r, dg)
                continue
            r, q, a = self._basis(lags, sensor)
            g0 = t0[group]  # from ambient
            pp[..., group] = cross(r, r)[..., None]
            ep = with_data(r, dg)
            extra = np.zeros((n_c, n_h, n_s, len(group)))
            if q is not None:  # e_i += T0_i Q
                ep = ep + g0 * cross(q, r)[..., None]
                extra += (2.0 * g0 * with_data(q, dg)
                          + g0**2 * cross(q, q)[..., None])
            if a is not None:  # e_i -= A
                a = np.broadcast_to(a, r.shape)
                ep = ep - cross(a, r)[..., None]
                extra += -2.0 * with_data(a, dg) + cross(a, a)[..., None]
                if q is not None:
                    extra += -2.0 * g0 * cross(q, a)[..., None]
            dp[..., group] = ep
            ee = extra.sum(axis=-1) if ee is None else ee + extra.sum(axis=-1)
        pp = pp.reshape(n_c, n_h * n_s, t0.size)
        dp = dp.reshape(n_c, n_h * n_s, t0.size)
        # z_i = y_i - T0_i + T0_i phi_i = T_obj phi_i + noise (all from ambient)
        # the object's prior: about ambient, or a heat-generating material's own temperature
        mu = np.array([0.0 if m.temperature is None else m.resting_temperature(ambient) - ambient
                       for m in self.materials])[:, None]
        own = np.array([m.temperature is not None for m in self.materials])[:, None]
        own_std = self.own_std[:, None]
        tau = np.asarray([self.object_std] if stds is None else stds, dtype=float)
        tau2 = np.where(own[None] & (stds is None or not own_stds), own_std[None],
                        tau[:, None, None]) ** 2  # (K, classes, 1)
        a = pp.sum(axis=-1)
        b = dp.sum(axis=-1) + pp @ t0
        zz = np.sum(d**2) + 2.0 * dp @ t0 + pp @ t0**2
        if ee is not None:
            zz = zz + ee.reshape(n_c, n_h * n_s)
        noises = np.atleast_1d(np.asarray(self.noises, dtype=float))
        s2 = (noises**2)[:, None, None, None]  # (noises, 1, 1, 1) against (K, classes, h x s)
        precision = a / s2 + 1.0 / tau2
        rhs = b / s2 + mu / tau2
        mean = rhs / precision
        quad = zz / s2 + mu**2 / tau2 - rhs**2 / precision
        log_ev = -0.5 * quad - 0.5 * np.log(tau2 * precision)
        if noises.size == 1:
            log_ev, mean = log_ev[0], mean[0]
        else:  # the noise integrated over its grid (equal weights): each material its own
            log_ev = log_ev - d.size * np.log(noises)[:, None, None, None]
            top = log_ev.max(axis=0)
            w = np.exp(log_ev - top)
            mean = np.sum(w * mean, axis=0) / np.sum(w, axis=0)
            log_ev = top + np.log(np.mean(w, axis=0))
        if stds is None:
            return log_ev[0], mean[0] + ambient
        return log_ev, mean + ambient



def with_constants(description: SensorDescription, constants: SensorConstants,
                   ) -> SensorDescription:
    """Return ``description`` with the thermal constants of ``constants``.

    A calibration file holds a taxel's fitted depth, diffusivity and conductivity (as
    `SensorConstants`); its heater, layer, dynamics and smoothing are its board's
    (as `skin.models.commission.described`).
    """
    return dataclasses.replace(description, depth=constants.depth,
                               diffusivity=constants.diffusivity,
                               conductivity=constants.conductivity)


#: The pipeline's contact conductance range for every material, W/(m^2 K): air gaps of 150 um
#: down to 0.1 um (the materials table's extremes), so that how firmly a contact was made is
#: not taken for evidence of the material.
CONDUCTANCE_RANGE = (0.026 / 150e-6, 0.026 / 0.1e-6)
#: How much earlier than the detected onset a contact may have begun, s (the pipeline's).
ONSET_SHIFTS = tuple(np.round(np.arange(0.0, 0.081, 0.01), 3))


#: Where the pipeline's fitted calibration of the joint classifier is stored
#: (`EvidenceTemperature.load`); `skin bench fit-calibration --write` refits it.
CALIBRATION_FILE = Path(__file__).parent / "data" / "joint_calibration.toml"


@dataclasses.dataclass(frozen=True)
class EvidenceTemperature:
    """The temperature of the joint classifier's evidence: how far its probabilities are tempered.

    The joint model's evidence (fixed noise 0.1 K, the conductance and the onset shift
    averaged over their grids) ranks the materials well on the pipeline's contacts but is
    too cautious about them: its model noise stands for what the model leaves out (misdated
    onsets and releases, taxel spread) and, taken as white noise, also blurs the contacts it
    explains well (main's `skin bench scene`: the answers given at p 0.3-0.5 were right 90 %
    of the time). The posterior is tempered, ``p ~ exp(log_evidence / temperature)``: the
    ranking is kept, and the confidence follows how often such answers are right. This is a
    tempered (generalised-Bayes) posterior; the temperature is fitted by the least log-loss
    of the true material, among the temperatures that make no confident mistake, over
    simulated pipeline contacts of training seeds (`skin bench fit-calibration`), with the
    model's other settings at their defaults; it is stored in `CALIBRATION_FILE` with how it
    was fitted.

    Parameters
    ----------
    temperature : float
        Divides the log evidence (1: the model as it is; below 1 sharper), 0.01 to 10.
    fitted : str
        How the value was obtained (the command, scene, seeds and the log-loss).
    """

    temperature: float
    fitted: str = ""

    def __post_init__(self) -> None:
        value = self.temperature
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value) or not 0.01 <= value <= 10.0:
            raise ValueError(f"temperature must be a number from 0.01 to 10, got {value!r}")

    @classmethod
    def load(cls, path: str | Path = CALIBRATION_FILE) -> EvidenceTemperature:
        """Read a calibration from its TOML file (``temperature``, ``fitted``).

        Raises
        ------
        ValueError
            Naming the file, when it is missing, not TOML, or holds a bad or unknown field.
        """
        import tomllib

        path = Path(path)
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
            raise ValueError(f"{path}: cannot read the joint classifier's calibration: "
                             f"{exc}") from None
        if set(data) - {"temperature", "fitted"} or "temperature" not in data:
            raise ValueError(f"{path}: the calibration needs 'temperature' and may hold "
                             f"'fitted'; got {sorted(data)}")
        try:
            return cls(data["temperature"], str(data.get("fitted", "")))
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None

    def dump(self) -> str:
        """Return the calibration as the TOML text `load` reads."""
        fitted = self.fitted.replace("\\", "\\\\").replace('"', '\\"')
        return ("# The joint classifier's calibration (skin.models.joint.EvidenceTemperature).\n"
                "# Refit with the command in 'fitted'; do not edit by hand.\n"
                f"temperature = {self.temperature!r}\n"
                f'fitted = "{fitted}"\n')

    def probabilities(self, log_evidence: np.ndarray) -> np.ndarray:
        """Return the tempered posterior of a log evidence (flat prior), summing to 1."""
        z = (np.asarray(log_evidence, dtype=float) - np.max(log_evidence)) / self.temperature
        p = np.exp(z)
        return p / p.sum()


#: Prior stds of an object's temperature about ambient that `ObjectTemperaturePrior` weighs,
#: K: log-spaced from objects long at rest in the room to a 10 K spread (the model's default).
OBJECT_STDS = tuple(float(v) for v in np.geomspace(0.1, 10.0, 9))


class ObjectTemperaturePrior:
    """How far from ambient the objects a skin touches sit, learned from its own contacts.

    One heated taxel cannot tell a cold object from a more conductive one: its answer rests on
    the prior on the object's temperature, and a broad prior (10 K) leaves it "unknown". A
    contact seen by several taxels at different starting temperatures pins the object's
    temperature, so the skin's multi-taxel contacts show how far objects sit from ambient
    where it works. The prior is hierarchical: the object's temperature about ambient is
    Gaussian with a std from ``stds`` (log-uniform hyperprior), whose posterior each pinned
    contact updates by its evidence (the material marginalised with equal weights, so a
    contact that does not pin the temperature leaves it as it was); and the next object may be
    unlike every one seen so far, with probability 1 / (n + 1) after n (a Dirichlet process
    with concentration 1), in which case the broadest std applies. With no contact seen it is
    the broad prior.

    Parameters
    ----------
    stds : sequence of float
        Candidate stds, K (default `OBJECT_STDS`); the largest is the new object's.
    """

    def __init__(self, stds: Sequence[float] = OBJECT_STDS) -> None:
        self.stds = np.asarray(stds, dtype=float)
        if self.stds.ndim != 1 or self.stds.size == 0 or np.any(self.stds <= 0):
            raise ValueError("stds must be a non-empty sequence of positive K")
        self.log_posterior = np.zeros(self.stds.size)  # log-uniform hyperprior
        self.contacts = 0.0

    def weights(self) -> np.ndarray:
        """Weight of each std in the prior of the next contact (they sum to 1)."""
        post = np.exp(self.log_posterior - self.log_posterior.max())
        new = 1.0 / (self.contacts + 1.0)
        w = (1.0 - new) * post / post.sum()
        w[np.argmax(self.stds)] += new
        return w

    def std(self) -> float:
        """Return the prior's standard deviation, K (of the mixture)."""
        return float(np.sqrt(self.weights() @ self.stds**2))

    def update(self, log_evidence_by_std: np.ndarray, weight: float = 1.0) -> None:
        """Add a pinned contact's evidence, (len(stds), n_classes) (`log_evidence_by_std`).

        ``weight`` (0-1) is how surely it is an object at rest in the room (not one that holds
        its own temperature).
        """
        ev = np.asarray(log_evidence_by_std, dtype=float)
        marginal = np.logaddexp.reduce(ev, axis=1) - np.log(ev.shape[1])
        self.log_posterior = self.log_posterior + weight * marginal
        self.log_posterior -= self.log_posterior.max()
        self.contacts += weight


class JointClassifier:
    """The pipeline's classifier that weighs all of a contact's taxels with one object.

    Each taxel's window is resampled onto a common grid after its own onset, as long as the
    shortest usable window (at most ``max_duration``); taxels with less than ``min_duration``
    of contact are left out. Each taxel's constants come from its board in the layout.

    Parameters
    ----------
    layout : Layout
        Gives each taxel's sensor constants.
    materials : dict of Material, optional
        Candidates; the shipped table's ``classify = true`` materials by default.
    threshold : float
        Posterior probability needed to name a material, else ``"unknown"``.
    min_duration, max_duration : float
        Shortest window a taxel must give, and the longest used, s.
    fs : float
        Sampling rate of the common grid, Hz.
    sensors : dict, optional
        Taxel id -> calibrated `SensorConstants` (`skin.formats.calibration_file`); taxels not in it
        use their board's constants. Each taxel is read as its board's sensor description
        reads (`skin.models.sensors.SensorDescription.from_board`: heater mode, PID loop, lag,
        smoothing), with the calibrated depth, diffusivity and conductivity.
    object_prior : str
        ``"learned"`` (default): the prior on the object's temperature is learned from this
        run's contacts of two or more taxels (`ObjectTemperaturePrior`), so that one-taxel
        contacts are named as far as the objects seen so far justify; ``"fixed"``: always
        ``object_std`` (10 K), which leaves most one-taxel contacts "unknown". The learned
        prior trusts the objects seen: a cold object touched by one taxel after many at
        ambient is taken for a more conductive one at ambient (one heated trace cannot tell
        them apart); a second taxel on it pins its temperature either way. A
        heat-generating material's temperature about its table centre is learned the same
        way from its pinned contacts (weighed by its probability), its table spread being
        the new one's prior: a forearm met once at 32 C is not outweighed, on the next
        contact that cannot pin it, by cardboard at ambient whose learned prior is merely
        narrower (scene seed 8: cardboard at p = 0.92 became 0.76, and a one-taxel forearm
        touch, "unknown" before, is named). The other side of it: a short one-taxel pine
        touch that skin at 32 C explains as well is named skin at 0.54 on scene seeds 9 and
        11 ("unknown" at 0.31-0.33 before); seeds 7 and 10 and forearms at 30.5 or 33.5 C
        are unchanged. (These probabilities are the model's, before the calibration tempers
        them.)
    calibration : EvidenceTemperature, "stored" or None
        How the posterior is tempered (`EvidenceTemperature`): ``"stored"`` (default) reads
        the fit in `CALIBRATION_FILE` when the classifier keeps the settings it was fitted
        with (no ``model_options``, the shipped materials table, the learned object prior),
        else none; None: the posterior as the model gives it. The stored temperature is one
        for every sensor: fitted on the paper and fast-film presets (`skin bench
        fit-calibration`), it is applied unchecked to the others (low-cost, pid-logger) and
        to commissioned constants.
    **model_options
        Passed to `JointContactModel` (``noise``, ``object_std``, ``h_points``,
        ``onset_shifts``; by default the contact may have begun up to 80 ms before the
        detected onset, which the streaming detector dates late when the contact is not
        perfect).
    """

    method = "joint"

    def __init__(self, layout, materials: dict[str, Material] | None = None,
                 threshold: float = 0.5, min_duration: float = 0.1, max_duration: float = 2.5,
                 fs: float = 200.0, sensors: dict | None = None, object_prior: str = "learned",
                 calibration: EvidenceTemperature | str | None = "stored",
                 **model_options) -> None:
        from skin.models.materials import load_materials

        if calibration == "stored":  # fitted for the default settings and table only
            default = (not model_options and object_prior == "learned"
                       and (materials is None or materials == load_materials()))
            calibration = EvidenceTemperature.load() if default else None
        elif calibration is not None and not isinstance(calibration, EvidenceTemperature):
            raise ValueError(f"calibration must be an EvidenceTemperature, 'stored' or None, "
                             f"got {calibration!r}")
        self.calibration = calibration

        table = materials if materials is not None else load_materials()
        self.table = table
        model_options.setdefault("onset_shifts", ONSET_SHIFTS)
        model_options.setdefault("conductance_range", CONDUCTANCE_RANGE)
        model_options.setdefault("h_points", 9)
        self.model = JointContactModel([m for m in table.values() if m.classify],
                                       **model_options)
        if object_prior not in ("learned", "fixed"):
            raise ValueError(f"object_prior must be 'learned' or 'fixed', got {object_prior!r}")
        self.object_prior = object_prior
        # the candidates below the model's own (broad) std, which a new kind of object gets
        broad = self.model.object_std
        self.prior = ObjectTemperaturePrior([*(v for v in OBJECT_STDS if v < broad), broad])
        # a heat-generating material (skin) holds its own temperature: how far the ones this
        # skin meets sit from the table's centre is learned the same way, its table spread
        # being the broad prior of a new one (a new person, another spot)
        self.own_priors = {}
        for i, m in enumerate(self.model.materials):
            if m.temperature is not None:
                own = float(self.model.own_std[i])
                self.own_priors[i] = ObjectTemperaturePrior(
                    [*(v for v in OBJECT_STDS if v < own), own])
        self.threshold = threshold
        self.min_duration = min_duration
        self.max_duration = max_duration
        self.fs = fs
        # each taxel's board's sensor description (heater mode, dynamics, smoothing): the
        # model reads a foreign preset's contacts as that sensor does (`contact_basis`)
        boards = {int(t.id): SensorDescription.from_board(layout.boards[t.board])
                  for t in layout.taxels}
        self._sensors = dict(boards)
        for i, s in (sensors or {}).items():
            self._sensors[int(i)] = (s if isinstance(s, SensorDescription) or int(i) not in boards
                                     else with_constants(boards[int(i)], s))

    def classify(self, contact):
        """Label a contact from all its taxels at once (its family, or ``"unknown"``, when unsure).

        The effusivity reported is measured (`skin.models.contact_fit.fitted_effusivity`).
        """
        from skin.models.contact_fit import fitted_effusivity
        from skin.models.materials import hierarchical_answer

        usable = []
        for w in contact.windows:
            ok = np.isfinite(w.temperature)
            if ok.sum() >= 2 and w.time[ok][-1] >= self.min_duration:
                usable.append((w, ok))
        if not usable:
            return MaterialEstimate(UNKNOWN, {}, 0.0, None, self.method, UNKNOWN, 0.0)
        span = min(min(w.time[ok][-1] for w, ok in usable), self.max_duration)
        grid = np.arange(1, int(np.floor(span * self.fs + 1e-9)) + 1) / self.fs
        y = np.array([np.interp(grid, w.time[ok], w.temperature[ok]) for w, ok in usable])
        t0 = np.array([w.initial for w, _ in usable])
        sensors = [self._sensors[w.taxel] for w, _ in usable]
        if self.object_prior == "fixed":
            log_ev = self.model.log_evidence(grid, y, t0, contact.ambient, sensors)
        else:
            stds = np.unique(np.concatenate([self.prior.stds,
                                             *(q.stds for q in self.own_priors.values())]))
            by_all = self.model.log_evidence_by_std(grid, y, t0, contact.ambient, sensors,
                                                    stds, own=True)
            by_std = by_all[np.searchsorted(stds, self.prior.stds)]
            own_by_std = {i: by_all[np.searchsorted(stds, q.stds), i]
                          for i, q in self.own_priors.items()}
            for i, ev in own_by_std.items():  # at the material's own (table) std
                by_std[:, i] = ev[-1]
            log_w = np.log(np.maximum(self.prior.weights(), 1e-300))
            log_ev = np.logaddexp.reduce(log_w[:, None] + by_std, axis=0)
            for i, q in self.own_priors.items():
                log_ev[i] = np.logaddexp.reduce(
                    np.log(np.maximum(q.weights(), 1e-300)) + own_by_std[i])
        p = np.exp(log_ev - log_ev.max())
        p /= p.sum()
        if self.object_prior == "learned" and len(usable) >= 2 and contact.final:
            # the taxels pin the object's temperature: what it says about the next objects,
            # weighed by how surely this object sits in the room (not one of its own warmth)
            at_rest = sum(float(v) for m, v in zip(self.model.materials, p, strict=True)
                          if m.temperature is None)
            self.prior.update(by_std, at_rest)
            for i, q in self.own_priors.items():  # and what it says of skin, if skin
                q.update(own_by_std[i][:, None], float(p[i]))
        if self.calibration is not None:  # the answer is tempered; what is learned is not
            p = self.calibration.probabilities(log_ev)
        probs = {c: float(v) for c, v in zip(self.model.classes, p, strict=True)}
        label, confidence, family, family_confidence = hierarchical_answer(
            probs, self.threshold, self.table)
        # the effusivity the contact shows (not the chosen material's table value)
        measured = fitted_effusivity(contact, self.fs, self.min_duration, self.max_duration,
                                     sensors[0])
        return MaterialEstimate(label, probs, confidence,
                                None if measured is None else measured[0], self.method,
                                family, family_confidence)
