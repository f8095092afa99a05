"""Synthetic trial datasets that follow the paper's data-collection protocol.

The paper (section III-B/C) touched each material 500 times with a heated taxel, holding the
contact until the reading settled (at most 35 s), reheating for a random 2-60 s between
contacts and resting 10 minutes every 10 trials; initial sensor temperatures spread over
26-40 C (mean 30 C) in a 25 C room, and the samples had not fully cooled between touches.
`simulate_trials` reproduces that protocol, then records each trial as the paper's rig did:

- **Sensor history** (lumped): after a contact the taxel reheats towards its free steady
  state with the multilayer column's slowest time constant (about 63 s); a rest restores it.
  This gives initial temperatures of 26-41 C with a mean near 34.5 C in a 25 C room; the
  paper reports 26-40 C with a mean of 30 C, so its rig reheated more slowly than this
  column (the difference is reported, not tuned away).
- **Object history**: a touch warms the object's surface; after release the excess decays as
  ``sqrt(D / (D + t))`` (diffusion of a layer warmed for D seconds), and the next touch meets
  an object above its resting temperature by half that excess (the mean over the depth the
  next touch probes). Objects rest at ambient unless ``object_offset`` draws a cold or warm
  object per recording run; heat-generating materials (skin) hold their own temperature
  (30-34 C).
- **Contact** (``model``): ``"contact"`` (default) uses the closed form with a finite contact
  conductance h per trial, k_air / gap with the gap log-uniform in the material's range
  (`Material.gap`: smooth glass 1-5 um, machined metal 2-10 um, wood 10-50 um, brick
  30-150 um, conforming rubber 0.5-2 um; see the materials table); ``"semi-infinite"`` is
  the paper's perfect contact (h = inf); ``"multilayer"`` runs the finite-volume column
  through the whole protocol (heater on throughout, non-uniform profiles, slower).
- **Taxels**: ``n_taxels`` taxels whose thermistor depth, diffusivity and conductivity are
  drawn within +-10 % of the paper's. A contact is seen by a *unit*: one taxel, or with
  several channels a fixed set of that many taxels (the pool split into disjoint sets). Each
  recording run uses one unit, and a material's runs take the units in turn (from a random
  one), so by default (``run_length`` None: a material's trials split into one run per unit)
  every unit touches every material. ``group`` is the unit: trials of one group share their
  taxels and no other group's, so grouped cross-validation tests on taxels the model never
  saw. (Before, each 50-trial run drew its taxel at random: a taxel's constants marked the
  run and so the material, and folds that shared taxels read them.)
- **Readout**: the 0.5 s before onset, then ``duration`` s of contact at 200 Hz, through the
  paper's divider and 10-bit ADC: Gaussian noise of 0.5 LSB before rounding (the ADC's
  specified noise), then quantisation (about 0.07 C per count at 39 C).
- **Onset jitter**: the recorded onset sample lies within +-10 ms of the true contact (the
  paper's limit switch, read at 200 Hz).
- **Sensor** (``sensor``, a `skin.models.sensors.SensorDescription`; default the paper's):
  its thermal body is the centre of the taxels' spread, its heater mode shapes the contact
  (`skin.models.sensors.contact_reading`; a PID-held sensor meets every touch settled at its
  setpoint above the room of that touch, so the setpoint follows the room touch by touch; the
  transient after the last release is not modelled, though it need not be over by the next
  touch: the scene simulator, `skin.drivers.sim`, still reads +0.77 K above the setpoint 2 s
  after a 5 s aluminium hold), its PID loop and lag act on the whole trace, its sample rate
  and ADC noise replace the protocol's, its temperature noise and ADC bits apply before
  rounding, and its smoothing after (a logger's). The paper's sensor gives exactly the
  datasets made before sensor descriptions existed.
- **Channels** (``Protocol.channels``): each contact is seen by one or more taxels touching
  the same object: ``"heated"`` (the paper's constant-power heater, with the protocol's
  reheat history; further heated channels start within +-0.3 K of the first),
  ``"heated@+D"`` (a heater held D K above ambient by its setpoint) and ``"passive"`` (an
  unheated thermistor, 0-1 K above ambient from its heated neighbours). Every channel is a
  different taxel of the pool, with its own contact conductance (the trial's, times a
  log-normal factor of 0.1 decades). Channel 0 is the primary one and must be heated. The
  extra channels draw from their own random stream, so one heated channel gives the same
  dataset as before channels existed.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from skin.formats.dataset import TrialSet
from skin.formats.layout import Board
from skin.models.materials import Material
from skin.models.physics import contact_trace, heated_temperature
from skin.models.sensors import (
    SensorDescription,
    apply_dynamics,
    contact_reading,
    load_sensor,
    smooth,
)
from skin.stream.calibration import Calibration

MODELS = ("contact", "semi-infinite", "multilayer")
PAPER_MATERIALS = ("acrylic", "aluminium", "brick", "cardboard", "glass", "mdf", "neoprene",
                   "porcelain", "pine", "rubber", "steel")


@dataclass(frozen=True)
class Protocol:
    """The data-collection protocol and the recording chain (defaults: the paper's).

    Attributes
    ----------
    trials : int
        Trials per material.
    ambient : float
        Room temperature, deg C.
    duration : float
        Seconds of contact recorded after onset.
    pre : float
        Seconds recorded before onset.
    reheat : tuple of float
        Range of the random reheat time between contacts, s.
    rest_every, rest : int, float
        A rest of ``rest`` s after every ``rest_every`` trials.
    hold : tuple of float
        Range of how long a contact is held before release, s (until it settles, <= 35 s).
    conductance : tuple of float or None
        Range of log10 contact conductance, W/(m^2 K), log-uniform, for every material; None
        (default): each material's own range from its air gap (`Material.conductance_range`).
    run_length : int or None
        Trials per recording run (one unit of taxels); None (default): a material's trials
        split evenly into one run per unit, so that every unit touches every material.
    n_taxels : int
        Number of distinct taxels (with several channels, split into units of that many).
    taxel_spread : float
        Relative spread of each taxel's depth, diffusivity and conductivity (uniform +-).
    adc_noise : float
        Reading noise before quantisation, ADC counts (std).
    onset_jitter : float
        Half-width of the uniform onset error, s.
    fs : float
        Sampling rate, Hz.
    reheat_time_constant : float
        Lumped reheat time constant of the free taxel, s (the multilayer column's slowest mode).
    object_offset : tuple of float
        Range of a resting object's temperature above ambient, K, drawn uniformly per
        recording run (default (0, 0): objects rest at ambient; ``(-8, 8)`` gives cold and
        warm objects, a piece of wood from outdoors or from a sunny window sill).
        Heat-generating materials keep their own temperature.
    object_memory : float
        Share of a touch's surface warming that the next touch of the object meets (after its
        diffusive decay); 0: every touch meets the object at its resting temperature.
    """

    trials: int = 500
    ambient: float = 25.0
    duration: float = 3.0
    pre: float = 0.5
    reheat: tuple[float, float] = (2.0, 60.0)
    rest_every: int = 10
    rest: float = 600.0
    hold: tuple[float, float] = (5.0, 35.0)
    conductance: tuple[float, float] | None = None
    run_length: int | None = None
    n_taxels: int = 8
    taxel_spread: float = 0.10
    adc_noise: float = 0.5
    onset_jitter: float = 0.010
    fs: float = 200.0
    reheat_time_constant: float = 62.5
    object_offset: tuple[float, float] | float = (0.0, 0.0)
    channels: tuple[str, ...] = ("heated",)
    object_memory: float = 0.5


def parse_channel(spec: str) -> tuple[bool, float | None]:
    """Parse a channel name: ``"heated"``, ``"passive"`` or ``"heated@+D"`` (D in K).

    Returns
    -------
    (bool, float or None)
        Whether it is heated, and its setpoint above ambient (None: not held).
    """
    name = spec.strip()
    if name == "heated":
        return True, None
    if name == "passive":
        return False, None
    if name.startswith("heated@"):
        try:
            offset = float(name[len("heated@"):])
        except ValueError:
            offset = float("nan")
        if np.isfinite(offset) and offset > 0:
            return True, offset
    raise ValueError(f"unknown channel {spec!r}: use heated, passive or heated@+D (a setpoint "
                     f"D > 0 K above ambient)")


def _offsets(spec: tuple[float, float] | float, shape: tuple[int, int],
             rng: np.random.Generator) -> np.ndarray:
    """Resting objects' temperature above ambient: uniform in (low, high), or +-K exactly."""
    if np.ndim(spec) == 0:
        k = float(spec)  # type: ignore[arg-type]
        if not (np.isfinite(k) and k >= 0):
            raise ValueError(f"object_offset {spec} must be a finite K >= 0")
        return k * rng.choice([-1.0, 1.0], shape)
    low, high = spec  # type: ignore[misc]
    if low > high:
        raise ValueError(f"object_offset {spec} must be (low, high)")
    return rng.uniform(low, high, shape)


def adc_readings(temperature: np.ndarray, rng: np.random.Generator,
                 noise: float = 0.5, adc_bits: int = 10) -> np.ndarray:
    """Pass readings through the paper's divider and ADC (noise, then rounding)."""
    b = Board(adc_bits=adc_bits)
    one = np.ones(1)
    cal = Calibration(c0=b.thermistor_c0 * one, c1=b.thermistor_c1 * one,
                      divider_resistor=b.divider_resistor * one,
                      supply_voltage=b.supply_voltage * one, adc_reference=b.adc_reference * one,
                      adc_max=b.adc_max * one, source="paper board constants")
    counts = cal.counts(temperature) + rng.normal(0.0, noise, temperature.shape)
    counts = np.clip(np.rint(counts), 1, cal.adc_max[0] - 1)
    return cal.temperature(counts)[0]


def spread_sensors(n: int, spread: float, rng: np.random.Generator,
                   base: SensorDescription | None = None) -> list[SensorDescription]:
    """Return ``n`` taxels whose constants lie within +-``spread`` of ``base``'s (the paper's).

    Depth, diffusivity and conductivity are drawn uniformly, in that order for each taxel.
    """
    base = load_sensor(base)
    out = []
    for _ in range(n):
        f = 1.0 + rng.uniform(-spread, spread, 3)
        out.append(replace(base, depth=base.depth * f[0], diffusivity=base.diffusivity * f[1],
                           conductivity=base.conductivity * f[2]))
    return out


def simulate_trials(
    materials: Sequence[Material],
    protocol: Protocol | None = None,
    model: str = "contact",
    seed: int = 0,
    progress: Callable[[int, int], None] | None = None,
    sensor: SensorDescription | str | None = None,
    skin_seed: int | Sequence[int] | None = None,
) -> TrialSet:
    """Simulate the paper's protocol for each material; return a trial dataset.

    Parameters
    ----------
    materials : sequence of Material
        The classes (e.g. the paper's 11, plus human skin).
    protocol : Protocol, optional
        Protocol and recording chain (default: the paper's).
    model : str
        ``"contact"``, ``"semi-infinite"`` or ``"multilayer"`` (see the module docstring).
    seed : int
        Seed: the same seed gives the same dataset.
    progress : callable, optional
        Called as ``progress(done, total)`` with trials done so far.
    sensor : SensorDescription or str, optional
        The sensor (a description, preset name or file; default the paper's). Its sample
        rate and ADC noise replace the protocol's ``fs`` and ``adc_noise``.
    skin_seed : int or sequence of int, optional
        Seed of the taxels' constants alone: datasets with one ``skin_seed`` are recorded by
        the same skin (a model trained on one and tested on another meets the taxels it was
        trained with, as on a robot). Default: drawn from ``seed`` like everything else.
        ``[scene_seed, 11]`` gives the taxels `skin.drivers.sim.SkinSimulator` draws for a
        scene of that seed (its first ``n_taxels``, in layout order).

    Returns
    -------
    TrialSet
        With the truth in ``true_`` extra keys.
    """
    if model not in MODELS:
        raise ValueError(f"unknown model {model!r}; choose one of {', '.join(MODELS)}")
    p = Protocol() if protocol is None else protocol
    if sensor is not None:
        sensor = load_sensor(sensor)
        p = replace(p, fs=sensor.sample_rate, adc_noise=sensor.adc_noise)
    base = load_sensor(sensor)
    p = replace(p, reheat_time_constant=_reheat_time_constant(p, base))
    if model == "multilayer" and base.heater != "constant":
        raise ValueError(f"the multilayer model runs a constant-power heater; sensor "
                         f"{base.name!r} has heater {base.heater!r} (use 'contact' or "
                         f"'semi-infinite')")
    kinds = [parse_channel(c) for c in p.channels]
    if not kinds or not kinds[0][0]:
        raise ValueError(f"channels {p.channels}: the first (primary) channel must be heated")
    if model == "multilayer" and len(kinds) > 1:
        raise ValueError("several channels need a closed-form model ('contact' or "
                         "'semi-infinite')")
    if model == "multilayer" and np.any(np.asarray(p.object_offset) != 0.0):
        raise ValueError("object_offset needs a closed-form model ('contact' or "
                         "'semi-infinite'): the multilayer slab's back is held at ambient")
    if p.trials < 1 or (p.run_length is not None and p.run_length < 1) or p.n_taxels < 1 \
            or p.rest_every < 1:
        raise ValueError("trials, run_length, n_taxels and rest_every must be at least 1")
    n_units = p.n_taxels // len(kinds)
    if n_units < 1:
        raise ValueError(f"{len(kinds)} channels need at least {len(kinds)} taxels, "
                         f"n_taxels is {p.n_taxels}")
    if not materials:
        raise ValueError("simulate_trials needs at least one material")
    rng = np.random.default_rng(seed)
    taxels = spread_sensors(p.n_taxels, p.taxel_spread, rng, base)
    if skin_seed is not None:  # the same draws from rng either way: only the taxels change
        taxels = spread_sensors(p.n_taxels, p.taxel_spread, np.random.default_rng(skin_seed),
                                base)
    n_mat, n = len(materials), p.trials
    total = n_mat * n
    # the protocol's schedule: per trial, the hold before release and the reheat after it
    hold = rng.uniform(*p.hold, (n_mat, n))
    reheat = rng.uniform(*p.reheat, (n_mat, n))
    rest = (np.arange(n) + 1) % p.rest_every == 0
    after = np.where(rest[None, :], p.rest, reheat)  # time from release to the next contact
    run_length = p.run_length or -(-n // n_units)
    run = np.arange(n) // run_length
    # a material's runs take the units in turn from a random one: no unit marks a material
    run_unit = (rng.integers(0, n_units, (n_mat, 1)) + np.arange(run.max() + 1)) % n_units
    run_taxel = run_unit * len(kinds)  # the unit's primary taxel
    if p.conductance is None:
        lo_hi = np.log10([m.conductance_range for m in materials])  # (n_mat, 2)
    else:
        lo_hi = np.tile(np.asarray(p.conductance, dtype=float), (n_mat, 1))
    h = 10.0 ** rng.uniform(lo_hi[:, :1], lo_hi[:, 1:], (n_mat, n))
    jitter = rng.uniform(-p.onset_jitter, p.onset_jitter, (n_mat, n))
    amb = p.ambient + rng.normal(0.0, 0.1, (n_mat, n))  # the room drifts a little
    offset = _offsets(p.object_offset, (n_mat, run.max() + 1), rng)[:, run]  # per run
    n_ch = len(kinds)
    ch_rng = np.random.default_rng([seed, 1])  # extra channels: their own stream
    # channel c of a run is the c-th taxel of its unit
    ch_taxel = run_taxel[:, :, None] + np.arange(n_ch)  # (n_mat, runs, ch)

    n_pre = round(p.pre * p.fs)
    n_post = round(p.duration * p.fs)
    t = (np.arange(n_pre + n_post) - n_pre) / p.fs  # relative to the recorded onset
    temp = np.empty((n_mat, n, n_ch, t.size))
    t_sensor = np.empty((n_mat, n, n_ch))
    t_object = np.empty((n_mat, n))
    h_channel = np.empty((n_mat, n, n_ch))  # each channel's contact conductance
    h_channel[:, :, 0] = np.inf if model == "semi-infinite" else h
    if model == "multilayer":
        _multilayer_protocol(materials, p, taxels, run_taxel, run, hold, after, h, jitter, amb,
                             t, temp[:, :, 0], t_sensor[:, :, 0], t_object, progress)
    else:
        for i, mat in enumerate(materials):
            _closed_form_protocol(mat, p, taxels, ch_taxel[i], run, hold[i], after[i],
                                  np.inf if model == "semi-infinite" else h[i], jitter[i],
                                  amb[i], offset[i], t, temp[i], t_sensor[i], t_object[i], rng,
                                  kinds, ch_rng, h_channel[i])
            if progress is not None:
                progress((i + 1) * n, total)
    temp = apply_dynamics(temp, base, p.fs, axis=-1)  # the PID loop and the lag, if any
    if base.noise > 0:
        temp = temp + rng.normal(0.0, base.noise, temp.shape)
    if n_ch == 1:  # the stream of the one-channel datasets made before channels existed
        readings = adc_readings(temp.reshape(total, -1), rng, p.adc_noise,
                                base.adc_bits)[:, None, :]
    else:
        readings = adc_readings(temp.reshape(total * n_ch, -1), rng, p.adc_noise,
                                base.adc_bits).reshape(total, n_ch, -1)
    readings = smooth(readings, base, axis=-1, fs=p.fs)
    label = np.repeat([m.name for m in materials], n)
    if model == "multilayer":  # it may have changed the runs' taxels
        ch_taxel = run_taxel[:, :, None]
    groups = (ch_taxel[:, run, 0] // n_ch).ravel()  # the unit: a physical set of taxels
    taxels_of = ch_taxel[:, run].reshape(total, n_ch)
    taxel = taxels_of[:, 0]
    eff = np.repeat([m.effusivity for m in materials], n)
    constants = np.array([[s.depth, s.diffusivity, s.conductivity] for s in taxels])[taxel]
    heated = np.tile([k[0] for k in kinds], (total, 1))
    held = np.array([np.nan if k[1] is None else k[1] for k in kinds])
    setpoint = amb.ravel()[:, None] + held[None, :]
    extra_truth = {} if n_ch == 1 else {
        "true_channel_sensor_temperature": t_sensor.reshape(total, n_ch),
        # each channel's own taxel constants and contact conductance (the ceilings use them)
        **{f"true_channel_sensor_{name}": np.array([getattr(s, name) for s in taxels])[taxels_of]
           for name in ("depth", "diffusivity", "conductivity")},
        "true_channel_conductance": h_channel.reshape(total, n_ch)}
    return TrialSet(
        temperature=readings, fs=p.fs, label=label, heated=heated,
        setpoint=None if np.isnan(held).all() else setpoint,
        onset=np.full(total, n_pre, dtype=np.int64), ambient=amb.ravel(), group=groups,
        taxel=taxels_of.astype(np.int64),
        extra={"true_onset_time": (p.pre + jitter).ravel(),
               "true_sensor_temperature": t_sensor[:, :, 0].ravel(),
               "true_object_temperature": t_object.ravel(),
               "true_effusivity": eff,
               "true_conductance": (np.full_like(h, np.inf) if model == "semi-infinite"
                                    else h).ravel(),
               "true_sensor_depth": constants[:, 0],
               "true_sensor_diffusivity": constants[:, 1],
               "true_sensor_conductivity": constants[:, 2],
               # whether a reading is the closed form of the taxel's constants (the paper's
               # chain: constant heater, no lag, no smoothing), which the ceiling assumes
               "true_closed_form": np.full(total, base.heater == "constant" and base.lag == 0
                                           and base.smoothing == "none"),
               **extra_truth},
        source=f"simulated ({model}, seed {seed}"
               + ("" if sensor is None else f", sensor {base.name}") + ")",
    )


def _object_temperature(mat: Material, ambient: float, offset: float,
                        rng: np.random.Generator) -> float:
    if mat.temperature is not None:  # heat-generating: holds its own temperature
        return float(rng.uniform(*mat.temperature))
    return ambient + offset


def _closed_form_protocol(mat: Material, p: Protocol, taxels: list[SensorDescription],
                          run_taxel: np.ndarray, run: np.ndarray, hold: np.ndarray,
                          after: np.ndarray, h: np.ndarray | float, jitter: np.ndarray,
                          amb: np.ndarray, offset: np.ndarray, t: np.ndarray, out: np.ndarray,
                          t_sensor: np.ndarray, t_object: np.ndarray,
                          rng: np.random.Generator, kinds: list[tuple[bool, float | None]],
                          ch_rng: np.random.Generator, h_channel: np.ndarray) -> None:
    """Walk one material's protocol with the closed forms; fill ``out`` (n, channels, samples).

    ``run_taxel`` is (runs, channels): each channel's taxel in each run; ``h_channel``
    (n, channels) receives the other channels' contact conductances.
    """
    e_o = mat.effusivity
    h = np.broadcast_to(np.asarray(h, dtype=float), hold.shape)
    tau = p.reheat_time_constant
    sensor_now = None
    excess = 0.0  # object surface temperature above ambient at the next contact
    heat = np.empty(hold.size)
    for j in range(hold.size):
        s = taxels[run_taxel[run[j], 0]]
        full = float(amb[j] + s.heated_rise if s.heater == "pid"
                     else heated_temperature(amb[j], s))
        if j == 0 or run[j] != run[j - 1]:  # a run starts rested, with a cool object
            sensor_now, excess = full, 0.0
        if kinds[0][1] is not None:
            t0 = amb[j] + kinds[0][1]
        elif s.heater == "pid":
            # the loop holds its setpoint (this touch's room + its rise: each trace's loop
            # high-pass starts settled there) and the touch meets it settled; the transient
            # after the last release is not modelled (not assumed over). Not the last
            # touch's setpoint reheated towards this one's: that left a ramp of (room drift)
            # / control_time (0.1 K/s) stopped at contact, which the loop's high-pass
            # (`apply_dynamics`) then counted a second time
            t0 = full
        else:
            t0 = sensor_now
        base = _object_temperature(mat, amb[j], offset[j], rng)
        tobj = base + (excess if mat.temperature is None else 0.0)
        t_sensor[j, 0], t_object[j] = t0, tobj
        heat[j] = full
        # the trace: flat (still reheating slowly) before contact, then the contact response
        since = t - jitter[j]
        pre_slope = (full - t0) / tau if kinds[0][1] is None else 0.0
        pre = t0 + pre_slope * np.minimum(since, 0.0)
        out[j, 0] = np.where(since > 0, contact_reading(since, t0, tobj, e_o, s, h[j], amb[j]),
                             pre)
        for c in range(1, len(kinds)):  # the other taxels on the same object
            heated, held = kinds[c]
            if held is not None:
                t0_c = amb[j] + held
            elif heated:
                t0_c = t0 + ch_rng.uniform(-0.3, 0.3)
            else:
                t0_c = amb[j] + ch_rng.uniform(0.0, 1.0)
            h_c = h[j] * 10.0 ** ch_rng.normal(0.0, 0.1)
            h_channel[j, c] = h_c
            s_c = taxels[run_taxel[run[j], c]]
            t_sensor[j, c] = t0_c
            after_contact = (contact_reading(since, t0_c, tobj, e_o, s_c, h_c, amb[j]) if heated
                             else contact_trace(since, t0_c, tobj, e_o, s_c, h_c))
            out[j, c] = np.where(since > 0, after_contact, t0_c)
        # release after the hold, then reheat; the object keeps some of the heat it took
        end = float(contact_reading(hold[j], t0, tobj, e_o, s, h[j], amb[j]))
        surf = float((s.effusivity * t0 + e_o * tobj) / (s.effusivity + e_o))
        warm = (surf - base) * np.sqrt(hold[j] / (hold[j] + after[j])) * p.object_memory
        excess = max(warm, 0.0)
        sensor_now = full - (full - end) * np.exp(-after[j] / tau)


def _reheat_time_constant(p: Protocol, sensor: SensorDescription) -> float:
    """Return the protocol's reheat time constant, scaled to the sensor's l^2 / alpha.

    A PID-held sensor reheats with its loop (``control_time``); its primary channel meets each
    touch at its setpoint (`_closed_form_protocol`), so this serves no reading of it.
    """
    if sensor.heater == "pid":
        return sensor.control_time
    paper = SensorDescription().reheat_time_constant
    if sensor.reheat_time_constant == paper:
        return p.reheat_time_constant
    return p.reheat_time_constant * sensor.reheat_time_constant / paper


def _multilayer_protocol(materials: Sequence[Material], p: Protocol,
                         taxels: list[SensorDescription], run_taxel: np.ndarray, run: np.ndarray,
                         hold: np.ndarray, after: np.ndarray, h: np.ndarray, jitter: np.ndarray,
                         amb: np.ndarray, t: np.ndarray, out: np.ndarray, t_sensor: np.ndarray,
                         t_object: np.ndarray,
                         progress: Callable[[int, int], None] | None) -> None:
    """Run the protocol through the finite-volume column, all materials in lockstep.

    The materials share one schedule (the first material's hold and reheat times, ambient and
    taxel of each run) so that one batched model steps them together. ``amb`` and
    ``run_taxel`` are overwritten with what was simulated. The object is a slab held at
    ambient at the depth pi a / 4 (a: the radius of the taxel's area), where a 1-D slab has
    the steady spreading conductance 4 k / (pi a) of a disc on a half-space: the 3-D block
    carries heat away sideways, which a 1-D column of the taxel's width cannot.
    """
    from skin.models.multilayer import MultilayerModel, ObjectBody, Phase, SensorStack

    n_mat, n = hold.shape
    k = np.array([m.nominal["k"] for m in materials], dtype=float)
    rho_c = np.array([m.nominal["rho"] * m.nominal["c"] for m in materials], dtype=float)
    own = [m.temperature for m in materials]
    radius = np.sqrt(taxels[0].heater_area / np.pi)
    body = ObjectBody(k, k / rho_c, thickness=np.pi * radius / 4, cells=30, grading=20.0,
                      back="ambient")
    total, done = n_mat * n, 0
    run_taxel[:] = run_taxel[:1]
    for r in range(run.max() + 1):
        idx = np.flatnonzero(run == r)
        s = taxels[run_taxel[0, r]]
        amb[:, idx] = amb[0, idx[0]]
        model = MultilayerModel(SensorStack.paper(s), body, ambient=amb[0, idx[0]],
                                dt=1.0 / p.fs)
        heated = model.steady_state(1.0)
        obj_t = np.array([m.resting_temperature(amb[0, idx[0]]) for m in materials])
        state = model.state(lambda d, st=heated, s0=model.surface: st.u[s0:], obj_t)
        for j in idx:
            shift = p.pre + jitter[0, j]  # true contact after the recorded onset's start
            recorded = p.duration + p.pre - shift
            phases = [Phase(shift, False), Phase(recorded, True, conductance=h[:, j]),
                      Phase(max(hold[0, j] - recorded, 0.0), True, conductance=h[:, j],
                            record=False),
                      # the next trial's pre-contact phase is part of this reheat
                      Phase(max(after[0, j] - p.pre, 0.0), False, record=False)]
            res = model.run(state, phases, fs=p.fs)
            out[:, j] = res.thermistor[:, : t.size]
            # the free sensor is smooth up to the contact: read it there
            tt = np.arange(t.size) / p.fs
            t_sensor[:, j] = [np.interp(shift, tt, row) for row in out[:, j]]
            t_object[:, j] = state.u[model.surface - 1]
            state = res.state
            for i in range(n_mat):  # heat-generating objects hold their temperature
                if own[i] is not None:
                    state.u[: model.surface, i] = obj_t[i]
            done += n_mat
            if progress is not None:
                progress(done, total)
