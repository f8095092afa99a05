"""``skin bench delay-bound``: the delay an oracle detector reaches at the false-alarm target.

The measurement is `skin.bench.delay_bound.delay_bound` (loaded only when run): for every
contact of ``skin evaluate-onset --sensor S --seed N``'s stream with a floor (when its
noise-free reading first moves 3 sigma), a window-limited GLR told the contact's exact
noise-free change, the sensor's raw noise (before smoothing) and no disturbances, with its
threshold set by simulation on pure noise for 0.1 false alarms per taxel-hour. Its median
delay / floor is a lower bound on any real detector's: above 1.5, issue 16's delay target is
out of reach for that sensor by physics.
"""

from __future__ import annotations

import argparse


def add_parsers(kinds: argparse._SubParsersAction) -> None:
    """Register ``skin bench delay-bound``."""
    p = kinds.add_parser("delay-bound", help="an oracle detector's delay / floor at the "
                         "false-alarm target (a lower bound, per sensor)",
                         description=__doc__)
    p.add_argument("--sensor", default="paper", metavar="PRESET|FILE",
                   help="the stream's sensor (default paper)")
    p.add_argument("--seed", type=int, default=0, help="seed of the stream (0)")
    p.add_argument("--minutes", type=float, default=15.0, help="simulated minutes (15)")
    p.add_argument("--taxels", type=int, default=16, help="simulated taxels (16)")
    p.add_argument("--false-alarms", type=float, default=0.1,
                   help="false alarms per taxel-hour allowed (0.1)")
    p.add_argument("--check-hours", type=float, default=None,
                   help="hours of pure noise to count the oracle's alarms at its threshold "
                        "(default: about 30 s of work, at least 1)")
    p.add_argument("--detector", action="store_true",
                   help="also run the real detector (as evaluate-onset --sensor) and give "
                        "its delay / floor on the same contacts (slow on fast-film)")
    p.add_argument("--json", action="store_true", help="print one JSON document")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Run `skin.bench.delay_bound.delay_bound` and print its figures (or JSON)."""
    import json
    import time

    from skin.bench import machine
    from skin.bench.delay_bound import delay_bound
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
    out = delay_bound(sensor, args.seed, args.minutes, args.taxels, args.false_alarms,
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
    print(f"  with every threshold 1 nat higher (2.7 times fewer false alarms): "
          f"{out['oracle_ratio_median_threshold_plus_1']}")
    print(f"thresholds {out['threshold_nats_median']} nats median "
          f"{out['threshold_nats_range']} (ln ARL {out['ln_arl_nats']}; tail h^b e^-h, b "
          f"{out['tail_exponent_b']}), window {out['window_lags_median']} lags")
    check = out["false_alarm_check"]
    if check:
        for row in check["runs"]:
            print(f"  noise only, contact {check['contact']}'s test at {row['threshold']} nats: "
                  f"{row['alarms']} alarms in {row['hours']} h ({row['per_hour']} per hour; "
                  f"{row['expected']} expected)")
    if "detector_ratio_median" in out:
        print(f"detector delay / floor median {out['detector_ratio_median']} over its "
              f"{out['detector_contacts']} detected contacts; the oracle's on the same "
              f"{out['oracle_ratio_median_same_contacts']}; detector / oracle median "
              f"{out['detector_over_oracle_median']}")
    return 0
