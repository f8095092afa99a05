"""``skin bench delay-bound``: the delay an oracle detector reaches at the false-alarm target.

The measurement is `skin.bench.delay_bound.measure_delay_bound` (loaded only when run): for
every contact of ``skin evaluate-onset --sensor S --seed N``'s stream with a floor (when its
noise-free reading first moves 3 sigma), a window-limited GLR told the contact's exact
noise-free change, the sensor's raw noise (before smoothing) and no disturbances, with its
threshold set by simulation on pure noise for 0.1 false alarms per taxel-hour. That oracle is
near-optimal, not provably optimal: the GLR is asymptotically optimal for the mean delay
(Lai 1998), and its threshold is an extrapolation (checked by noise-only runs). Its median
delay / floor is what a detector that knows everything can reach: a median above 1.5 makes
issue 16's delay target very unlikely for that sensor, not provably impossible; a median
below it says the target is not ruled out.

The same oracle, at the same per-contact thresholds, also gives its detection of the contacts
evaluate-onset counts in ``detected_5sigma`` (> 5 sigma, >= 0.3 s): ``oracle_detected_5sigma``,
the mean over them of the share of ``--detection-repeats`` noise draws in which it alarms by
the end of the window in which evaluate-onset still credits an alarm to the contact. Below
0.99 the detection target is out of reach of that sensor (as near-optimal as the oracle is);
with ``--detector`` the real detector's ``detected_5sigma`` and each of its misses, with its
cause (evaluate-onset --why) and the oracle's detection of it, beside it.
"""

from __future__ import annotations

import argparse


def add_parsers(kinds: argparse._SubParsersAction) -> None:
    """Register ``skin bench delay-bound``."""
    p = kinds.add_parser("delay-bound", help="a near-optimal oracle detector's delay / floor "
                         "at the false-alarm target, per sensor",
                         description=__doc__)
    p.add_argument("--sensor", default="paper", metavar="PRESET|FILE",
                   help="the stream's sensor (default paper)")
    p.add_argument("--seed", type=int, default=0, help="seed of the stream (0)")
    p.add_argument("--minutes", type=float, default=15.0, help="simulated minutes (15)")
    p.add_argument("--taxels", type=int, default=16, help="simulated taxels (16)")
    p.add_argument("--false-alarms", type=float, default=0.1,
                   help="false alarms per taxel-hour allowed (0.1)")
    p.add_argument("--check-hours", type=float, default=None,
                   help="hours of pure noise to count the oracle's alarms at its threshold, "
                        "for each of the contacts of lowest, median and highest threshold "
                        "(default: about 10 s of work each, at least 1)")
    p.add_argument("--detector", action="store_true",
                   help="also run the real detector (as evaluate-onset --sensor) and give "
                        "its delay / floor on the same contacts (slow on fast-film)")
    p.add_argument("--detection-repeats", type=int, default=20,
                   help="noise draws per 5-sigma contact for the oracle's detection "
                        "probability (oracle_detected_5sigma; default 20)")
    p.add_argument("--disturbances", action="store_true",
                   help="also the disturbance-aware oracle (skin.bench.gust_oracle): each "
                        "5-sigma contact's exact template told from the best-fitting gust or "
                        "heater switch of the streams' own family, drift and flutter in its "
                        "noise, thresholds counted on disturbance-only streams; 200 draws "
                        "per contact whose threshold is found. A reference test, not a "
                        "bound: reaching 99 %% shows the disturbances do not rule the target "
                        "out; falling short rules nothing out")
    p.add_argument("--null-hours", type=float, default=40.0,
                   help="taxel-hours of disturbance-only streams for its thresholds (40; "
                        "rounded up to whole pieces of 16 taxels x 15 min)")
    p.add_argument("--grid-factor", type=float, default=1.0,
                   help="its null grid's density (2: twice the gust rises and holds, half "
                        "the start step; a check of the grid's resolution)")
    p.add_argument("--pre", type=float, default=2.0,
                   help="seconds before the onset in its windows, at least (2; more past "
                        "tells the oracle more: check that its figures have stopped moving)")
    p.add_argument("--free-contacts", action="store_true",
                   help="draw its contact-side noise free through the contact (as its "
                        "contact hypothesis assumes; noisier than the streams, whose generator "
                        "freezes the drift and flutter from onset to release)")
    p.add_argument("--json", action="store_true", help="print one JSON document")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Run `skin.bench.delay_bound.measure_delay_bound` and print its figures (or JSON)."""
    import json
    import time

    from skin.bench import machine
    from skin.bench.delay_bound import measure_delay_bound
    from skin.errors import SkinError
    from skin.models.sensors import load_sensor
    from skin.progress import Progress

    sensor = load_sensor(args.sensor)
    if args.minutes <= 0 or args.taxels < 1 or args.false_alarms <= 0:
        raise SkinError("--minutes, --taxels and --false-alarms must be positive")
    if args.check_hours is not None and args.check_hours <= 0:
        raise SkinError("--check-hours must be positive")
    if args.detection_repeats < 1:
        raise SkinError("--detection-repeats must be at least 1")
    if args.null_hours <= 0 or args.grid_factor <= 0 or args.pre <= 0:
        raise SkinError("--null-hours, --grid-factor and --pre must be positive")
    progress = Progress()
    started = time.monotonic()
    out = measure_delay_bound(sensor, args.seed, args.minutes, args.taxels, args.false_alarms,
                              args.check_hours, args.detector,
                              detection_repeats=args.detection_repeats,
                              disturbances=args.disturbances, null_hours=args.null_hours,
                              grid_factor=args.grid_factor, pre=args.pre,
                              freeze=not args.free_contacts,
                              progress=lambda d, n: progress.bar(d, n, "steps", started))
    progress.done()
    out = {"machine": machine(), **out, "wall_time": round(time.monotonic() - started, 2)}
    if args.json:
        print(json.dumps(out))
        return 0
    print(f"sensor {out['sensor']} seed {out['seed']}: {out['contacts_with_floor']} contacts "
          f"with a floor (median {out['floor_ms_median']} ms), {out['contacts_5sigma']} > 5 "
          f"sigma; raw noise {out['raw_noise_k']} K at {out['fs']:g} Hz")
    print(f"oracle (template, noise and onset window known, no disturbances) at "
          f"{out['false_alarms_target']:g} false alarms per taxel-hour: delay / floor median "
          f"{out['oracle_ratio_median']} (5-sigma contacts {out['oracle_ratio_median_5sigma']}; "
          f"p25-p75 {out['oracle_ratio_p25_p75']}; {out['oracle_not_detectable']} not "
          f"detectable; share > 1.5: {out['oracle_over_1_5']}); Lorden's bound "
          f"{out['lorden_ratio_median']}"
          + (f"; without the smoothing's look-ahead of {out['lookahead_samples']} samples "
             f"{out['oracle_ratio_median_no_lookahead']}" if out["lookahead_samples"] else ""))
    print(f"  with every threshold 1 nat higher (by the e^-h tail model, about 2.7 times "
          f"fewer false alarms): {out['oracle_ratio_median_threshold_plus_1']}")
    print(f"  5-sigma contacts' sigma {out['five_sigma_noise_k']} K: {out['five_sigma_noise']}")
    if out["oracle_detected_5sigma"] is not None:
        print(f"oracle detects {out['oracle_detected_5sigma']:.2%} of the "
              f"{out['contacts_5sigma']} 5-sigma contacts (mean over "
              f"{out['detection_repeats']} noise draws each; "
              f"{out['oracle_5sigma_detected_under_half']} detected in under half the draws, "
              f"{out['oracle_5sigma_detected_under_99']} in under 99 %)")
    print(f"thresholds {out['threshold_nats_median']} nats median "
          f"{out['threshold_nats_range']} (ln ARL {out['ln_arl_nats']}; tail h^b e^-h, b "
          f"{out['tail_exponent_b']}; {out['thresholds_at_ln_arl_bound']} at the ln ARL bound, "
          f"nothing to fit), window {out['window_lags_median']} lags")
    for check in out["false_alarm_check"]:
        for row in check["runs"]:
            print(f"  noise only, contact {check['contact']} ({check['threshold_rank']} "
                  f"threshold)'s test at {row['threshold']} nats: {row['alarms']} alarms in "
                  f"{row['hours']} h ({row['per_hour']} per hour; {row['expected']} expected "
                  f"by its fitted tail)")
    if "disturbance_oracle_detected_5sigma" in out and \
            out["disturbance_oracle_detected_5sigma"] is None:
        print("disturbance-aware oracle: no 5-sigma contacts")
    if out.get("disturbance_oracle_detected_5sigma") is not None:
        print(f"disturbance-aware oracle (exact template against the best-fitting gust or "
              f"heater switch; drift and flutter in its noise; a reference test, not a "
              f"bound) detects "
              f"{out['disturbance_oracle_detected_5sigma']:.2%} "
              f"(SE {out['disturbance_oracle_detected_5sigma_se']:.2%}) of the 5-sigma contacts "
              f"({out['disturbance_oracle_under_half']} in under half the draws, "
              f"{out['disturbance_oracle_under_99']} in under 99 %; "
              f"{out['disturbance_oracle_mimicked']} mimicked by the family without noise); "
              f"thresholds on {out['disturbance_oracle_null_taxel_hours']} taxel-hours of "
              f"disturbances: {out['disturbance_oracle_threshold_status']}, found in "
              f"{out['disturbance_oracle_threshold_found_range']} nats")
    if "detector_ratio_median" in out:
        print(f"detector delay / floor median {out['detector_ratio_median']} over its "
              f"{out['detector_contacts']} detected contacts; the oracle's on the same "
              f"{out['oracle_ratio_median_same_contacts']}; detector / oracle median "
              f"{out['detector_over_oracle_median']} over the "
              f"{out['detector_over_oracle_pairs']} the oracle too detected "
              f"({out['oracle_not_detectable_same_contacts']} not detectable by it)")
        if out["detector_detected_5sigma"] is not None:
            print(f"detector detects {out['detector_detected_5sigma']:.2%} of the 5-sigma "
                  "contacts; its misses by cause (the oracle detects how many of them): "
                  + (", ".join(f"{c} {v['missed']} ({v['oracle_detects']})" for c, v in
                               out["detector_misses_5sigma_by_cause"].items()) or "none")
                  + "; the test that came nearest to firing on them: "
                  + (", ".join(f"{t} {n}" for t, n in
                               out["detector_misses_5sigma_closest_test"].items()) or "none"))
        if "detector_misses_5sigma_disturbance_oracle" in out:
            d = out["detector_misses_5sigma_disturbance_oracle"]
            print(f"  of its {d['missed']} misses the disturbance-aware oracle detects "
                  f"{d['oracle_detects_half']} in half the draws or more, "
                  f"{d['oracle_detects_99']} in 99 %; {d['mimicked']} mimicked by the family")
    return 0
