"""``skin evaluate-onset``: how well the streaming detector finds and dates contacts.

By default it simulates a skin's stream (`skin.bench.streams`): minutes of mostly
contact-free time per taxel with heater switching, ambient drift and air currents (``--quiet``
leaves them out), and contacts of 0.1-5 s with the table's materials; ``--warm FRACTION`` makes
that fraction of them warm objects, hotter than the heated taxel by 2-25 K (the reading rises
instead of falling), and the figures are then also given for cool and warm contacts apart.
``--data trials.npz``
runs the detector over each trial's whole recording instead (one taxel per trial; the
dataset's onsets are the truth). It reports the detection rate of contacts longer than
``--min-duration``, false alarms per taxel-hour, the detection delay, the error of the refined
onset (median and p95), the floor of the delay (when each contact's reading first stood out
of the noise, on simulated streams), and the cost per taxel-sample.

With ``--sensor`` it adds issue 16's figures over the contacts whose noise-free reading moves
more than 5 sigma: ``detected_5sigma``; ``detectable_5sigma``, the share of them that any
detector held to 0.1 false alarms per taxel-hour could see by the end of the window after
their release in which an alarm still counts as theirs (Lorden's bound on their own change,
`skin.bench.streams.StreamContact.detectable_after`; ``detectable_in_contact_5sigma``: before
the release); ``detected_of_detectable``, the detector's rate among those; and
``detected_not_detectable``, how many it found all the same (the bound holds on average).
Beside the refined onset's error median it gives issue 16's target for it,
``refined_onset_target_ms``: max(15 ms, 10 % of the median floor of every contact with one,
detected or not; `skin.bench.onset_eval.onset_error_target`). The rates come with exact
95 % intervals (``false_alarms_per_taxel_hour_ci95``, Garwood's; ``detected_5sigma_ci95``,
Clopper-Pearson's): one false alarm in 4 taxel-hours reads 0.25 per taxel-hour, and holds 0.1.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from skin.errors import SkinError
from skin.progress import Progress

MATERIALS = "aluminium,brick,cardboard,glass,human_skin,neoprene,pine"


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin evaluate-onset``."""
    ev = sub.add_parser("evaluate-onset", help="detection rate, false alarms and onset error "
                        "of the streaming detector", description=__doc__)
    ev.add_argument("--data", help="trial dataset (.npz) whose onsets are the truth "
                                   "(default: a simulated stream)")
    ev.add_argument("--taxels", type=int, default=16, help="simulated taxels (default 16)")
    ev.add_argument("--minutes", type=float, default=15.0,
                    help="simulated minutes (default 15)")
    ev.add_argument("--rate", type=float, default=1.0,
                    help="contacts per taxel per minute (default 1)")
    ev.add_argument("--materials", default=MATERIALS, help="comma-separated materials touched")
    ev.add_argument("--object-offset", type=float, default=0.0,
                    help="objects within +-OFFSET K of their resting temperature")
    ev.add_argument("--warm", type=float, default=0.0, metavar="FRACTION",
                    help="fraction of contacts with objects hotter than the taxel by 2-25 K "
                         "(default 0; skin keeps its own temperature)")
    ev.add_argument("--quiet", action="store_true",
                    help="no heater switching, ambient drift or air currents")
    ev.add_argument("--min-duration", type=float, default=0.3,
                    help="contacts at least this long count for the detection rate (0.3 s)")
    ev.add_argument("--seed", type=int, default=0, help="seed of the simulated stream")
    ev.add_argument("--sensor", default=None, metavar="PRESET|FILE",
                    help="simulate this sensor's stream and set the detector by it (`skin "
                         "sensors`); adds detected_5sigma, delay_floor_ratio_median and "
                         "detectable_5sigma (Lorden's bound). With --data: the sensor that "
                         "recorded the trials (default the paper's), re-rated to their "
                         "sample rate when it has no smoothing (a smoothed one at another "
                         "rate is refused: describe it at the recording's rate)")
    ev.add_argument("--commissioned", action="store_true",
                    help="set the detector by noise commissioned (`skin commission`'s quiet "
                         "figures) on a quiet minute of another simulated unit (seed + 1000), "
                         "not the one measured")
    ev.add_argument("--calibration", default=None, metavar="FILE",
                    help="a calibration file from `skin commission`: each taxel's measured "
                         "noise sets the detector (taxel ids = stream columns)")
    ev.add_argument("--why", action="store_true",
                    help="give every missed contact (the 5-sigma ones with --sensor) and every "
                         "false alarm its cause (`skin.bench.onset_why`; simulated streams)")
    ev.add_argument("--common-mode", action=argparse.BooleanOptionalAction, default=None,
                    help="take a change shared alike by nearly every taxel (the room) off the "
                         "readings first (the detector's common_mode; every column is one "
                         "board, of at least 4 taxels: refused with fewer). A PID-held "
                         "heater's: the median of the free taxels' departures, taken off on "
                         "every sample. Default: on for a simulated stream (--sensor) whose "
                         "heater is not PID-held (with 4 taxels or more), off for a PID-held "
                         "one and for --data (its trials are no board); --no-common-mode: off")
    ev.add_argument("--envelope-sigmas", type=float, default=None, metavar="Z",
                    help="the detector's gust-envelope noise margin, sigmas: the z of the "
                         "fall's noise table (default the false-alarm target's Gaussian "
                         "quantile per sample, 4.7-5.4; with --envelope-tau's faster reading, "
                         "of half the target: fast-film 5.55); where Z x the table exceeds "
                         "the flat 8 sigmas the flat margin applies (and before the filters "
                         "settle), so a larger Z brings the margin closer to --flat-envelope's. "
                         "With --flat-envelope: the flat margin's sigmas (default 8). "
                         "Diagnosis: what sets the delay")
    ev.add_argument("--flat-envelope", action="store_true",
                    help="the gust-envelope margin flat, 8 sigmas of the reading (the "
                         "detector's envelope_noise=False; the default is the fall's noise "
                         "table, capped at the flat margin)")
    ev.add_argument("--duty", action=argparse.BooleanOptionalAction, default=None,
                    help="tell the detector each taxel's simulated heater duty, as the frames "
                         "carry it and the pipeline tells it (OnsetDetector.process's duty): a "
                         "fall is allowed the heater's own fall only where the duty lies below "
                         "its lag through the body's slowest mode. Default: on for a simulated "
                         "stream; --no-duty allows every fall the steepest heater step's "
                         "(as a detector told no duty does); a trial dataset (--data) has none")
    ev.add_argument("--smooth-tau", type=float, default=None, metavar="S",
                    help="the detector's smoothing time constant, s (default max(0.03 s, one "
                         "sample); diagnosis)")
    ev.add_argument("--envelope-tau", type=float, default=None, metavar="S",
                    help="the gust-envelope test's second, faster reading's smoothing, s; 0: "
                         "none (default: the smoothing shortened with the sensor's response "
                         "time where that is at most half of it: fast-film 2.9 ms; else none). "
                         "Diagnosis: --envelope-tau 0 gives the detector without it")
    ev.add_argument("--json", action="store_true", help="print one JSON document")
    ev.set_defaults(func=main)


def _from_trials(path: str) -> tuple[np.ndarray, np.ndarray, list, float, str]:
    from skin.formats.dataset import load_trials

    data = load_trials(path)
    if np.any(data.onset < 0):
        raise SkinError(f"{path}: every trial needs its onset (the truth) to be judged")
    times = np.arange(data.temperature.shape[-1]) / data.fs
    truth = [(i, float(times[o]), float(times[-1])) for i, o in enumerate(data.onset)]
    return times, data.primary.T.copy(), truth, data.fs, data.source


def _commissioned_noise(path: str, n_taxels: int) -> np.ndarray:
    """Each stream column's ``noise_sigma`` from a calibration file (column k: taxel id k)."""
    from skin.formats.calibration_file import load_calibration

    cal = load_calibration(path)
    missing = [k for k in range(n_taxels) if "noise_sigma" not in cal.taxels.get(k, {})]
    if missing:
        raise SkinError(f"{path}: taxels {missing[:10]} have no commissioned noise_sigma; run "
                        f"`skin commission` on a quiet stretch of this skin first")
    return np.array([cal.taxels[k]["noise_sigma"] for k in range(n_taxels)], dtype=float)


def _commissioned_elsewhere(table: dict, names: list, n_taxels: int, seed: int,
                           sensor: object) -> np.ndarray:
    """Each taxel's noise from a quiet minute of another simulated unit (`quiet_figures`)."""
    from skin.bench.streams import simulate_stream
    from skin.models.commission import quiet_figures

    quiet = simulate_stream([table[n] for n in names], n_taxels=n_taxels, duration=60.0,
                            contacts_per_minute=0.0, disturbances=False, seed=seed,
                            sensor=sensor)
    return quiet_figures(quiet.times, quiet.temperature).noise_sigma


def _sensor_figures(contacts: list, flags: list, delays: list, errors: list, detector: object,
                    min_duration: float, described: bool = True) -> dict:
    """Return issue 16's figures: 5-sigma detection, delay against the floor, onset error.

    ``described``: the stream is a described sensor's (`simulate_stream`'s ``sensor``), whose
    contacts carry Lorden's bound; else the ``detectable`` figures are None (unknown).
    """
    from skin.bench.intervals import clopper_pearson
    from skin.bench.onset_eval import five_sigma, onset_error_target

    sigma = float(np.median(detector.sigma))
    big = [k for k, five in enumerate(five_sigma(contacts, detector, min_duration)) if five]
    ratio = [delays[k] / contacts[k].visible_after for k in range(len(contacts))
             if flags[k] and np.isfinite(contacts[k].visible_after)
             and contacts[k].visible_after > 0]
    # Lorden's bound at the false-alarm target against the floor, and the delay against the
    # bound, over the same detected contacts as the delay against the floor
    both = [k for k, c in enumerate(contacts) if flags[k] and np.isfinite(c.visible_after)
            and c.visible_after > 0 and np.isfinite(c.bound_after) and c.bound_after > 0]
    bound = [contacts[k].bound_after / contacts[k].visible_after for k in both]
    over = [delays[k] / contacts[k].bound_after for k in both]
    err = np.abs([errors[k] for k in range(len(contacts)) if flags[k]])
    # the Cramer-Rao bound on each detected contact's onset spread, and its error in units of
    # it (an efficient unbiased estimate: |error| / bound has median 0.6745); contacts differ
    # in spread by orders of magnitude, so the bound is compared contact by contact
    dated = [k for k in range(len(contacts))
             if flags[k] and np.isfinite(contacts[k].onset_sd_bound)]
    sd_bound = np.array([contacts[k].onset_sd_bound for k in dated])
    over_bound = np.abs([errors[k] for k in dated]) / sd_bound if dated else np.zeros(0)
    floor = np.array([c.visible_after for c in contacts if np.isfinite(c.visible_after)])
    # what physics allows: the 5-sigma contacts whose own change gives ln ARL nats by the
    # end of the window an alarm still counts in (`StreamContact.detectable_after`)
    reach = [k for k in big if np.isfinite(contacts[k].detectable_after)]
    physics = {
        "detectable_5sigma": round(len(reach) / len(big), 4) if big else None,
        "detectable_in_contact_5sigma": round(
            sum(np.isfinite(contacts[k].bound_after) for k in big) / len(big), 4)
        if big else None,
        "detected_of_detectable": (round(sum(flags[k] for k in reach) / len(reach), 4)
                                   if reach else None),
        "detected_not_detectable": int(sum(flags[k] for k in big)
                                       - sum(flags[k] for k in reach))}
    if not described:
        physics = dict.fromkeys(physics)
    return {"sensor": detector.sensor.name, "noise_sigma_k": round(sigma, 5),
            "contacts_5sigma": len(big),
            "detected_5sigma": round(sum(flags[k] for k in big) / max(len(big), 1), 4),
            # exact 95 % interval (none where no contact counts)
            "detected_5sigma_ci95": ([round(v, 4) for v in clopper_pearson(
                sum(flags[k] for k in big), len(big))] if big else None),
            **physics,
            "delay_floor_ratio_median": round(float(np.median(ratio)), 3) if ratio else None,
            "floor_ms_median": round(1e3 * float(np.median(floor)), 1) if floor.size else None,
            "bound_floor_ratio_median": round(float(np.median(bound)), 3) if bound else None,
            "delay_bound_ratio_median": round(float(np.median(over)), 3) if over else None,
            "refined_onset_error_ms_median": (round(1e3 * float(np.median(err)), 1)
                                              if err.size else None),
            # issue 16's target for it: max(15 ms, 10 % of the median floor of every
            # contact with one, detected or not)
            "refined_onset_target_ms": onset_error_target(floor),
            "refined_onset_sd_bound_ms_median": (round(1e3 * float(np.median(sd_bound)), 1)
                                                 if sd_bound.size else None),
            "refined_onset_error_bound_ratio_median": (
                round(float(np.median(over_bound)), 2) if over_bound.size else None)}


def _why(events: list, contacts: list, stream: object, detector: object, sensor: object,
         min_duration: float) -> dict:
    """Return `skin.bench.onset_why.explain_outcomes` (the 5-sigma contacts with a sensor)."""
    from skin.bench.onset_eval import five_sigma, release_window
    from skin.bench.onset_why import explain_outcomes
    from skin.bench.streams import GUST_DEPTH
    from skin.stream.onset import OnsetDetector

    detector = OnsetDetector(1) if detector is None else detector
    scale = 1.0
    if sensor is not None:
        from skin.models.sensors import load_sensor

        scale = sensor.heated_rise / load_sensor("paper").heated_rise
        counted = five_sigma(contacts, detector, min_duration)
        which = "5-sigma contacts"
    else:
        counted = [c.duration >= min_duration for c in contacts]
        which = f"contacts >= {min_duration:g} s"
    out = explain_outcomes(events, contacts, counted, stream.gusts, stream.switches,
                           warmup=detector.warmup, gust_size=GUST_DEPTH[1] * scale,
                           after=release_window(sensor),
                           settle=detector.slow_tau)
    return {"counted": which, "contacts": int(sum(counted)), **out}


def main(args: argparse.Namespace) -> int:
    """Run the evaluation and print the figures (or JSON)."""
    from skin.bench import machine
    from skin.bench.onset_eval import evaluate_onsets, release_window
    from skin.bench.streams import GUST_DEPTH

    if args.duty is None:
        args.duty = not args.data
    if args.duty and args.data:
        raise SkinError("--duty tells the detector a simulated stream's heater duty: a trial "
                        "dataset (--data) carries none")
    if args.commissioned and (args.data or args.calibration):
        raise SkinError("--commissioned simulates its own quiet stretch: not with --data or "
                        "--calibration")
    from skin.stream.onset import COMMON_MIN

    if args.common_mode and not args.data and args.taxels < COMMON_MIN:
        raise SkinError(f"--common-mode needs a board of at least {COMMON_MIN} taxels (every "
                        f"column is one board) and --taxels is {args.taxels}: with fewer the "
                        f"detector has no common mode; give --taxels {COMMON_MIN} or more, or "
                        f"leave --common-mode out")
    progress = Progress()
    started = time.monotonic()
    by_material = None
    sensor = None
    stream = None
    if args.sensor is not None:
        from skin.models.sensors import load_sensor

        sensor = load_sensor(args.sensor)  # a bad file fails before the work starts
    from skin.stream.onset import OnsetDetector

    knobs = {k: v for k, v in (("envelope_sigmas", args.envelope_sigmas),
                               ("smooth_tau", args.smooth_tau),
                               ("envelope_tau", args.envelope_tau)) if v is not None}
    if args.flat_envelope:
        knobs["envelope_noise"] = False
    try:  # knobs the detector refuses (not positive; --envelope-tau on a PID-held sensor)
        OnsetDetector(1, sensor=sensor, **knobs)  # fail now, before any simulation
    except ValueError as e:
        raise SkinError(f"the detector's options (--envelope-sigmas, --smooth-tau, "
                        f"--envelope-tau, --flat-envelope): {e}") from None
    if args.data:
        times, temperature, truth, fs, source = _from_trials(args.data)
        contacts = duty = None
        if args.common_mode and temperature.shape[1] < COMMON_MIN:
            raise SkinError(f"--common-mode needs a board of at least {COMMON_MIN} taxels "
                            f"(one per trial, all one board) and {args.data} has "
                            f"{temperature.shape[1]} trials: with fewer the detector has no "
                            f"common mode; leave --common-mode out")
    else:
        from skin.bench.streams import simulate_stream
        from skin.models import load_materials

        table = load_materials()
        names = [n.strip() for n in args.materials.split(",") if n.strip()]
        unknown = [n for n in names if n not in table]
        if unknown or not names:
            raise SkinError(f"unknown material(s) {', '.join(unknown) or '(none given)'}")
        if args.taxels < 1 or args.minutes <= 0:
            raise SkinError("--taxels and --minutes must be positive")
        if not 0.0 <= args.warm <= 1.0:
            raise SkinError("--warm must lie between 0 and 1")
        progress.message(f"simulating {args.taxels} taxels x {args.minutes:g} min")
        stream = simulate_stream([table[n] for n in names], n_taxels=args.taxels,
                                 duration=60.0 * args.minutes, contacts_per_minute=args.rate,
                                 object_offset=(-args.object_offset, args.object_offset),
                                 disturbances=not args.quiet, seed=args.seed, warm=args.warm,
                                 sensor=sensor)
        times, temperature, fs = stream.times, stream.temperature, stream.fs
        duty = stream.duty() if args.duty else None
        contacts = stream.contacts
        truth = [(c.taxel, c.onset, c.release, c.visible_after) for c in contacts]
        directions = [c.direction for c in contacts]
        source = (f"simulated stream ({args.taxels} taxels, {args.minutes:g} min, "
                  f"{'quiet' if args.quiet else 'with disturbances'}, "
                  + (f"{args.warm:g} warm, " if args.warm else "") + f"seed {args.seed})")
    sigma = None
    if args.calibration is not None:
        sigma = _commissioned_noise(args.calibration, temperature.shape[1])
        source += f", noise from {args.calibration}"
    if args.commissioned:
        sigma = _commissioned_elsewhere(table, names, args.taxels, args.seed + 1000, sensor)
        source += f", noise commissioned on unit seed {args.seed + 1000}"
    from skin.models.sensors import load_sensor

    # the detector's smoothing, CUSUM thresholds and hole test are per sample: a recording is
    # judged at its own rate whatever the description's (default: the paper's sensor)
    judged = load_sensor(sensor)
    if judged.sample_rate != fs:
        judged = judged.at_rate(fs, f"{args.data}")
        source += f", sensor {judged.name} at the recording's {fs:g} Hz"
    elif sensor is not None:
        source += f", sensor {sensor.name}"
    detector = OnsetDetector(temperature.shape[1], sensor=judged, sigma=sigma,
                             common_mode=(False if args.data and args.common_mode is None
                                          else args.common_mode), **knobs)
    source += "".join(f", {k.replace('_', ' ')} {v:g}" for k, v in knobs.items()
                      if k != "envelope_noise")
    if detector.envelope_tau is not None:
        source += f", envelope's faster reading {1e3 * detector.envelope_tau:.1f} ms"
    source += ", common mode" if detector.common_active else ", no common mode"
    if duty is not None:
        source += (", heater duty told" if detector.envelope is None
                   else ", heater duty told (no effect: a loop-held heater's envelope)")
    source += (", flat envelope margin" if not detector.envelope_noise
               else ", noise-table envelope margin")
    result = evaluate_onsets(times, temperature, truth, fs, min_duration=args.min_duration,
                             progress=lambda d, n: progress.bar(d, n, "samples", started),
                             directions=None if args.data else directions, detector=detector,
                             depth=judged.depth, diffusivity=judged.diffusivity,
                             sensor=judged, duty=duty)
    progress.done()
    events = result.pop("events")
    flags = result.pop("detected_flags")
    delays, errors = result.pop("delay_s"), result.pop("onset_error_s")
    if (sensor is not None or sigma is not None) and contacts is not None:
        result.update(_sensor_figures(contacts, flags, delays, errors, detector,
                                      args.min_duration, described=sensor is not None))
    if contacts is not None:
        by_material = {}
        for name in sorted({c.material for c in contacts}):
            counted = [k for k, c in enumerate(contacts)
                       if c.material == name and c.duration >= args.min_duration]
            by_material[name] = {"contacts": len(counted),
                                 "detected": int(sum(flags[k] for k in counted))}
    doc = {"machine": machine(), "source": source, "common_mode": detector.common_active,
           "duty": duty is not None, "envelope_tau": detector.envelope_tau,
           **result,
           "wall_time": round(time.monotonic() - started, 2)}
    if by_material is not None:
        doc["by_material"] = by_material
        # contacts whose reading moved more than any gust: the ones size alone can tell (a
        # described sensor's gusts scale with its heated rise, as the stream makes them)
        gust = GUST_DEPTH[1]
        if sensor is not None:
            from skin.models.sensors import load_sensor

            gust *= sensor.heated_rise / load_sensor("paper").heated_rise
        big = [k for k, c in enumerate(contacts)
               if c.duration >= args.min_duration and c.peak_change > gust]
        doc["beyond_gusts"] = {"threshold_k": round(gust, 4), "contacts": len(big),
                               "detection_rate": round(sum(flags[k] for k in big)
                                                       / max(len(big), 1), 4)}
    if args.why and contacts is not None:
        doc["why"] = _why(events, contacts, stream, detector, sensor, args.min_duration)
    if args.json:
        print(json.dumps(doc))
        return 0
    print(f"{source}: {doc['contacts']} contacts, {doc['taxel_hours']} taxel-hours "
          f"({doc['machine']['cpus']} cores)")
    d, e, v = doc["delay_ms"], doc["onset_error_ms"], doc.get("visible_ms")
    fa = doc["false_alarms_by_direction"]
    print(f"detected {doc['detection_rate']:.2%} of contacts >= {args.min_duration:g} s "
          f"({doc['detection_rate_all']:.2%} of all); false alarms "
          f"{doc['false_alarms_per_taxel_hour']:g} per taxel-hour (95 % "
          f"{doc['false_alarms_per_taxel_hour_ci95'][0]:g}-"
          f"{doc['false_alarms_per_taxel_hour_ci95'][1]:g}; {doc['false_alarms']}: "
          f"{fa['fall']} falls, {fa['rise']} rises); {doc['onsets']} onsets, "
          f"{doc['releases']} releases")
    if "detected_5sigma" in doc:
        print(f"sensor {doc['sensor']} (noise {doc['noise_sigma_k']:g} K): detected "
              f"{doc['detected_5sigma']:.2%} of the {doc['contacts_5sigma']} contacts that move "
              f"the reading > 5 sigma{_interval(doc['detected_5sigma_ci95'])}; delay / floor "
              f"median {doc['delay_floor_ratio_median']} "
              f"(floor median {doc['floor_ms_median']} ms); refined onset error median "
              f"{doc['refined_onset_error_ms_median']} ms (target "
              f"{doc['refined_onset_target_ms']} ms; its Cramer-Rao bound: sd median "
              f"{doc['refined_onset_sd_bound_ms_median']} ms; |error| / bound median "
              f"{doc['refined_onset_error_bound_ratio_median']}, 0.67 for an efficient "
              "unbiased estimate)")
        from skin.bench.streams import BOUND_FALSE_ALARMS

        print(f"  the earliest any detector can react at {BOUND_FALSE_ALARMS:g} false alarms per "
              f"taxel-hour (Lorden's bound) / floor median {doc['bound_floor_ratio_median']}; "
              f"delay / that bound median {doc['delay_bound_ratio_median']}")
        of = doc["detected_of_detectable"]
        if doc["detectable_5sigma"] is not None:
            print(f"  detectable by that bound: {doc['detectable_5sigma']:.2%} of the 5-sigma "
                  f"contacts by {release_window(sensor):.2g} s after their release "
                  f"({doc['detectable_in_contact_5sigma']:.2%} before it); detected "
                  + ("n/a" if of is None else f"{of:.2%}") + " of those, and "
                  f"{doc['detected_not_detectable']} beyond the bound")
    if "beyond_gusts" in doc:
        b = doc["beyond_gusts"]
        print(f"of the {b['contacts']} contacts >= {args.min_duration:g} s that move the reading "
              f"more than a gust can ({b['threshold_k']:g} K): detected {b['detection_rate']:.2%}")
    print(f"delay median {d['median']} ms, p95 {d['p95']} ms"
          + (f" (the reading first stands out of the noise after {v['median']} ms, median)"
             if v and v["median"] is not None else ""))
    print(f"onset error median {e['median']} ms, p95 {e['p95']} ms, signed median "
          f"{e['signed_median']} ms")
    print(f"cost: detector {doc['detector_us_per_taxel_sample']} us per taxel-sample, "
          f"refinement {doc['refine_ms_per_onset']} ms per onset")
    for name, g in doc.get("by_direction", {}).items():
        if g["contacts"]:
            right = g["right_direction"]
            print(f"{name} contacts: detected {g['detection_rate']:.2%} of "
                  f"{g['contacts_counted']} >= {args.min_duration:g} s "
                  f"({g['detection_rate_all']:.2%} of {g['contacts']})"
                  + (f", {right:.2%} with the right direction" if right is not None else "")
                  + f"; delay median {g['delay_ms']['median']} ms; onset error median "
                  f"{g['onset_error_ms']['median']} ms, p95 {g['onset_error_ms']['p95']} ms")
    if "why" in doc:
        w = doc["why"]
        print(f"why missed ({w['counted']}: {w['missed']} of {w['contacts']}): "
              + ", ".join(f"{k} {v}" for k, v in w["misses"].items() if v))
        print(f"why false alarms ({w['false_alarm_total']}): "
              + ", ".join(f"{k} {v}" for k, v in w["false_alarms"].items() if v))
    if by_material:
        print("detected by material: " + ", ".join(
            f"{k} {v['detected']}/{v['contacts']}" for k, v in by_material.items()))
    return 0


def _interval(ci: list | None) -> str:
    """`` (95 % a-b)`` for a rate's interval, in percent; nothing where there is none."""
    return "" if ci is None else f" (95 % {ci[0]:.1%}-{ci[1]:.1%})"
