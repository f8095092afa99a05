"""``skin sensors``: the sensor descriptions (presets, or those of a file).

For each sensor: its half-response time to a surface step, its reading noise at 35 C, its
heater control, sample rate, ADC bits and smoothing (`skin.models.sensors`). ``--file`` lists
the sensors of a user's file instead of the shipped presets.
"""

from __future__ import annotations

import argparse
import json


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin sensors``."""
    cmd = sub.add_parser("sensors", help="list the sensor descriptions (presets)",
                         description=__doc__)
    cmd.add_argument("--file", default=None, help="list the sensors of this TOML file")
    cmd.add_argument("--json", action="store_true",
                     help="print one JSON document on stdout and nothing else")
    cmd.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """List the sensors (see the module docstring)."""
    from skin.models.sensors import load_sensors

    sensors = load_sensors(args.file)
    if args.json:
        print(json.dumps({"source": args.file or "presets",
                          "sensors": [s.to_dict() for s in sensors.values()]}))
        return 0
    print(f"{'name':<12} {'t50 s':>7} {'noise K':>8} {'heater':<18} {'Hz':>6} {'bits':>4}  "
          f"smoothing")
    for s in sensors.values():
        smoothing = {"none": "none", "moving-average": f"moving average {s.smoothing_window}",
                     "low-pass": f"low-pass {s.smoothing_cutoff:g} Hz",
                     "savgol": f"Savitzky-Golay {s.smoothing_window}/{s.savgol_order}"}
        print(f"{s.name:<12} {s.response_time:7.3f} {s.noise_kelvin():8.4f} {s.heater:<18} "
              f"{s.sample_rate:6g} {s.adc_bits:4d}  {smoothing[s.smoothing]}")
        print(f"{'':<12} {s.summary}")
    return 0
