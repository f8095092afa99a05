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
    progress = Progress()
    started = time.monotonic()
    out = measure_delay_bound(sensor, args.seed, args.minutes, args.taxels, args.false_alarms,
                              args.check_hours, args.detector,
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
    if "detector_ratio_median" in out:
        print(f"detector delay / floor median {out['detector_ratio_median']} over its "
              f"{out['detector_contacts']} detected contacts; the oracle's on the same "
              f"{out['oracle_ratio_median_same_contacts']}; detector / oracle median "
              f"{out['detector_over_oracle_median']} over the "
              f"{out['detector_over_oracle_pairs']} the oracle too detected "
              f"({out['oracle_not_detectable_same_contacts']} not detectable by it)")
    return 0
