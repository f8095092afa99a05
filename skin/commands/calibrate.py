"""``skin calibrate``: fit each taxel's constants and keep them in a calibration file.

- ``skin calibrate thermistors --data refs.csv -o cal.json``: Steinhart-Hart coefficients per
  taxel (the paper's two-term form, or ``--terms 3``) from ADC counts read with the skin at two
  or more reference temperatures. ``refs.csv`` has the columns ``taxel,reference_c,counts``
  (one row per taxel and reference; several readings of one reference are averaged), and
  optionally ``ambient_c``: the board's ambient sensor at that reference, from which the
  ambient offset is fitted (the mean of reference - reading over the rows that give it).
- ``skin calibrate thermal --data water.npz --reference water -o cal.json``: each taxel's
  diffusivity and conductivity from contacts with a reference material resting at ambient
  (a trial dataset with a ``taxel`` column; `skin.models.sensor_fit`).
- ``skin calibrate board --board 0 --divider-resistor 667.4 ... -o cal.json``: a board's
  measured divider constants and heater resistance (used from then on by the thermistor fit,
  by the counts-to-temperature conversion and by the sensor model).
- ``skin calibrate show cal.json``: what the file holds, and the layout's taxels it misses.

A calibration file that exists is updated, not replaced: the thermistor and thermal parts can
be fitted separately. `skin run --calibration cal.json` applies it.
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np

from skin.errors import SkinError

JSON_HELP = "print one JSON document (what was fitted, with its figures) and nothing else"


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin calibrate``."""
    cal = sub.add_parser("calibrate", help="fit per-taxel constants into a calibration file",
                         description=__doc__)
    kinds = cal.add_subparsers(dest="kind", required=True)
    th = kinds.add_parser("thermistors", help="Steinhart-Hart per taxel from reference temps")
    th.add_argument("--data", required=True, help="CSV with columns taxel,reference_c,counts")
    th.add_argument("--layout", default="arm", help="layout (default: arm)")
    th.add_argument("--terms", type=int, choices=(2, 3), default=2,
                    help="2: the paper's form (default); 3: the full form (3+ references)")
    th.add_argument("-o", "--out", required=True, help="calibration file to write or update")
    th.add_argument("--json", action="store_true", help=JSON_HELP)
    th.set_defaults(func=main_thermistors)
    tm = kinds.add_parser("thermal", help="sensor diffusivity and conductivity per taxel")
    tm.add_argument("--data", required=True, help="trial dataset (.npz) of reference contacts")
    tm.add_argument("--reference", default="water",
                    help="the reference material (water), or 'label': each contact's own "
                         "labelled material (a training set of known materials), whose "
                         "shape gives the taxel's time scale (its effusivity stays nominal)")
    tm.add_argument("--duration", type=float, default=1.5, help="seconds of contact used")
    tm.add_argument("-o", "--out", required=True, help="calibration file to write or update")
    tm.add_argument("--json", action="store_true", help=JSON_HELP)
    tm.set_defaults(func=main_thermal)
    bd = kinds.add_parser("board", help="a board's measured divider constants and heaters")
    bd.add_argument("--board", type=int, required=True, help="board id")
    bd.add_argument("--layout", default="arm", help="layout (default: arm)")
    for name, what in (("divider-resistor", "divider's reference resistor, ohm"),
                       ("supply-voltage", "divider's supply V+, V"),
                       ("adc-reference", "ADC reference voltage, V"),
                       ("heater-resistance", "heaters' resistance, ohm")):
        bd.add_argument(f"--{name}", type=float, help=f"measured {what}")
    bd.add_argument("-o", "--out", required=True, help="calibration file to write or update")
    bd.add_argument("--json", action="store_true", help=JSON_HELP)
    bd.set_defaults(func=main_board)
    show = kinds.add_parser("show", help="what a calibration file holds")
    show.add_argument("file", help="calibration file")
    show.add_argument("--layout", default="arm", help="layout to check it against")
    show.add_argument("--json", action="store_true", help="print one JSON document")
    show.set_defaults(func=main_show)


def _existing(path: str):
    from skin.formats.calibration_file import CalibrationFile, load_calibration

    return load_calibration(path) if Path(path).exists() else CalibrationFile()


def read_references(path: str) -> tuple[dict[int, tuple[np.ndarray, np.ndarray]], list[float]]:
    """Read ``taxel,reference_c,counts[,ambient_c]`` rows.

    Returns
    -------
    references : dict
        Taxel -> (reference temperatures, mean counts at each).
    ambient_errors : list of float
        Reference minus the ambient sensor's reading, for the rows that give ``ambient_c``.
    """
    rows: dict[int, dict[float, list[float]]] = {}
    ambient_errors: list[float] = []
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            need = {"taxel", "reference_c", "counts"}
            if not need <= set(reader.fieldnames or ()):
                raise SkinError(f"{path}, line 1: the header must name the columns "
                                f"taxel,reference_c,counts (got {reader.fieldnames})")
            for row in reader:
                line = reader.line_num
                try:
                    taxel, ref, counts = (int(row["taxel"]), float(row["reference_c"]),
                                          float(row["counts"]))
                except (TypeError, ValueError):
                    raise SkinError(f"{path}, line {line}: taxel must be an integer and "
                                    f"reference_c, counts numbers: {row}") from None
                if not (np.isfinite(ref) and np.isfinite(counts)):
                    raise SkinError(f"{path}, line {line}: taxel {taxel}: not a finite number")
                rows.setdefault(taxel, {}).setdefault(ref, []).append(counts)
                if (row.get("ambient_c") or "").strip():
                    try:
                        ambient = float(row["ambient_c"])
                    except ValueError:
                        ambient = float("nan")
                    if not np.isfinite(ambient):
                        raise SkinError(f"{path}, line {line}: taxel {taxel}: ambient_c must "
                                        f"be a finite number, got {row['ambient_c']!r}")
                    ambient_errors.append(ref - ambient)
    except FileNotFoundError:
        raise SkinError(f"{path}: no such file") from None
    refs = {k: (np.array(sorted(v)), np.array([np.mean(v[r]) for r in sorted(v)]))
            for k, v in rows.items()}
    return refs, ambient_errors


def main_thermistors(args: argparse.Namespace) -> int:
    """Fit the thermistors."""
    from skin.formats.layout import load_layout
    from skin.stream.calibration import fit_steinhart_hart, resistance_from_counts

    layout = load_layout(args.layout)
    refs, ambient_errors = read_references(args.data)
    out = _existing(args.out)
    flagged = []
    for taxel, (temps, counts) in sorted(refs.items()):
        if taxel not in layout:
            raise SkinError(f"{args.data}: taxel {taxel} is not in layout {layout.source}")
        board = out.board(layout, layout.taxels[layout.index(taxel)].board)
        adc_max = 2**board.adc_bits - 1
        if np.any(counts <= 0) or np.any(counts >= adc_max):
            flagged.append(taxel)  # open or saturated at a reference: no fit
            continue
        r = resistance_from_counts(counts, board.divider_resistor, board.supply_voltage,
                                   board.adc_reference, adc_max)
        try:
            coef = fit_steinhart_hart(r, temps, args.terms)
        except ValueError as exc:
            raise SkinError(f"{args.data}: taxel {taxel}: {exc}") from None
        fitted = 1.0 / (coef[0] + coef[1] * np.log(r) + coef[2] * np.log(r) ** 3) - 273.15
        out.taxels.setdefault(int(taxel), {}).update(
            thermistor=[float(c) for c in coef],
            thermistor_rms=round(float(np.sqrt(np.mean((fitted - temps) ** 2))), 5))
    all_refs = sorted({float(x) for v in refs.values() for x in v[0]})
    out.references["thermistor"] = (f"{args.data} ({', '.join(f'{x:g}' for x in all_refs)} C, "
                                    f"{args.terms}-term)")
    if ambient_errors:
        out.ambient_offset = round(float(np.mean(ambient_errors)), 4)
        out.references["ambient"] = f"{args.data} ({len(ambient_errors)} readings)"
    path = out.save(args.out)
    missing = out.missing(layout, "thermistor")
    if args.json:
        rms = {str(t): out.taxels[int(t)]["thermistor_rms"] for t in sorted(refs)
               if t not in flagged}
        print(json.dumps({"file": str(path), "terms": args.terms, "fitted": len(rms),
                          "thermistor_rms": rms, "rms_unit": "K", "flagged": flagged,
                          "missing": missing, "ambient_offset":
                          out.ambient_offset if ambient_errors else None}))
        return 0
    print(f"wrote {path}: thermistors of {len(refs) - len(flagged)} taxels "
          f"({args.terms}-term); {len(missing)} of the layout's {len(layout)} taxels without "
          f"a thermistor fit" + (f"; open or saturated at a reference: {flagged}"
                                 if flagged else "")
          + (f"; ambient offset {out.ambient_offset:+.3f} K" if ambient_errors else ""))
    return 0


def _time_scale_only(fit):
    """Keep a fit's diffusivity (the time scale depth^2 / alpha), the sensor's effusivity nominal.

    Contacts from a labelled set (a training protocol) meet objects warmed by earlier
    touches, which the reading's amplitude takes for a more effusive sensor (+25-50 % in the
    simulated protocol, seed 1), while its shape still gives the time scale (within 3 %).
    Measured (heated + passive, trained at ambient, tested at +-8 K by the same skin; the
    issue 17 notes): the joint fit with the fitted effusivity .41 / .39 at 0.5 / 1.5 s, with
    the nominal one .50 / .62.
    """
    import dataclasses

    from skin.models.physics import SensorConstants

    nominal = SensorConstants().effusivity
    sensor = dataclasses.replace(fit.sensor,
                                 conductivity=nominal * float(np.sqrt(fit.sensor.diffusivity)))
    return dataclasses.replace(fit, sensor=sensor)


def fit_thermal_taxels(data, reference: str, duration: float, source: str = "") -> dict:
    """Fit each taxel's thermal constants from its contacts (``skin calibrate thermal``).

    ``reference`` is a material of the table, or ``"label"`` (each contact's own label; the
    time scale alone is fitted, `_time_scale_only`). Returns taxel id -> the fit
    (`skin.models.sensor_fit.fit_sensor_constants`).
    """
    from skin.models import load_materials
    from skin.models.features import PRE
    from skin.models.sensor_fit import fit_sensor_constants

    table = load_materials()
    source = source or str(data.source)
    n = round(duration * data.fs)
    if np.any(data.onset + n > data.temperature.shape[-1]):
        raise SkinError(f"{source}: a {duration:g} s window does not fit the trials")
    t = np.arange(1, n + 1) / data.fs
    fits = {}
    for taxel in np.unique(data.taxel[:, 0]):
        rows = np.flatnonzero(data.taxel[:, 0] == taxel)
        t0 = np.array([data.primary[i, data.onset[i] - PRE:data.onset[i]].mean()
                       for i in rows])
        y = np.array([data.primary[i, data.onset[i] + 1:data.onset[i] + 1 + n]
                      for i in rows])
        ambient = data.ambient[rows] if data.ambient is not None else np.full(rows.size, 25.0)
        refs = [table[str(c)] for c in data.label[rows]] if reference == "label" else [
            table[reference]] * rows.size
        try:
            fit = fit_sensor_constants(
                t, y, t0, ambient, [m.effusivity for m in refs],
                conductance_range=tuple(np.array([m.conductance_range for m in refs]).T))
        except ValueError as exc:
            raise SkinError(f"{source}: taxel {int(taxel)}: {exc}") from None
        fits[int(taxel)] = _time_scale_only(fit) if reference == "label" else fit
    return fits


def main_thermal(args: argparse.Namespace) -> int:
    """Fit the thermal constants."""
    from skin.formats.dataset import load_trials
    from skin.models import load_materials
    from skin.models.features import PRE

    table = load_materials()
    if args.reference not in table and args.reference != "label":
        raise SkinError(f"unknown reference material {args.reference!r}")
    data = load_trials(args.data)
    if data.taxel is None:
        raise SkinError(f"{args.data}: a 'taxel' column is needed to know whose contact is whose")
    labelled = args.reference == "label"
    if labelled:
        bad = sorted({str(c) for c in data.classes
                      if c not in table or table[c].temperature is not None})
        if bad:
            raise SkinError(f"{args.data}: --reference label needs materials of the table at "
                            f"rest in the room; {', '.join(bad)} is not one")
    if not np.all(data.heated[:, 0]):
        raise SkinError(f"{args.data}: trial {int(np.argmin(data.heated[:, 0]))}: the primary "
                        f"channel is not heated (the fit models a heated taxel)")
    if np.any(data.onset < PRE):
        raise SkinError(f"{args.data}: every trial needs its onset and {PRE} samples before it")
    out = _existing(args.out)
    for taxel, fit in fit_thermal_taxels(data, args.reference, args.duration, args.data).items():
        rows = int(np.sum(data.taxel[:, 0] == taxel))
        out.taxels.setdefault(int(taxel), {}).update(
            diffusivity=fit.sensor.diffusivity, conductivity=fit.sensor.conductivity,
            depth=fit.sensor.depth, thermal_rms=round(fit.rms, 5),
            thermal_contacts=rows, thermal_converged=fit.converged)
    out.references["thermal"] = f"{args.reference} ({args.data})"
    path = out.save(args.out)
    if args.json:
        keys = ("diffusivity", "conductivity", "depth", "thermal_rms", "thermal_contacts",
                "thermal_converged")
        print(json.dumps({"file": str(path), "reference": args.reference,
                          "contacts": len(data), "taxels": {
                              str(int(t)): {k: np.asarray(out.taxels[int(t)][k]).item()
                                            for k in keys}
                              for t in np.unique(data.taxel[:, 0])}}))
        return 0
    print(f"wrote {path}: thermal constants of {len(np.unique(data.taxel[:, 0]))} taxels from "
          f"{len(data)} contacts with {args.reference}")
    return 0


def main_board(args: argparse.Namespace) -> int:
    """Keep a board's measured constants."""
    from skin.formats.calibration_file import BOARD
    from skin.formats.layout import load_layout

    layout = load_layout(args.layout)
    if args.board not in layout.boards:
        raise SkinError(f"board {args.board} is not in layout {layout.source} (boards "
                        f"{sorted(layout.boards)})")
    given = {k: getattr(args, k) for k in BOARD if getattr(args, k) is not None}
    if not given:
        raise SkinError("give at least one of --divider-resistor, --supply-voltage, "
                        "--adc-reference, --heater-resistance")
    bad = {k: v for k, v in given.items() if not (0 < v < np.inf)}
    if bad:
        raise SkinError(f"board {args.board}: constants must be positive: {bad}")
    out = _existing(args.out)
    out.boards.setdefault(args.board, {}).update(given)
    path = out.save(args.out)
    if args.json:
        print(json.dumps({"file": str(path), "board": args.board,
                          "constants": out.boards[args.board]}))
        return 0
    print(f"wrote {path}: board {args.board}: "
          + ", ".join(f"{k} {v:g}" for k, v in out.boards[args.board].items()))
    return 0


def main_show(args: argparse.Namespace) -> int:
    """Describe a calibration file against a layout."""
    from skin.formats.calibration_file import load_calibration
    from skin.formats.layout import load_layout

    cal = load_calibration(args.file)
    layout = load_layout(args.layout)
    doc = {"file": args.file, "created": cal.created, "references": cal.references,
           "ambient_offset": cal.ambient_offset, "taxels": len(cal.taxels),
           "boards": {str(k): v for k, v in cal.boards.items()},
           "missing_thermistor": cal.missing(layout, "thermistor"),
           "missing_thermal": cal.missing(layout, "thermal"),
           "unknown_taxels": sorted(k for k in cal.taxels if k not in layout)}
    if args.json:
        print(json.dumps(doc))
        return 0
    print(f"{args.file} ({cal.created}): {len(cal.taxels)} taxels; references "
          + ", ".join(f"{k}: {v}" for k, v in cal.references.items()))
    for part in ("thermistor", "thermal"):
        miss = doc[f"missing_{part}"]
        print(f"{part}: {len(layout) - len(miss)} of {len(layout)} taxels"
              + (f"; missing {miss[:12]}{' ...' if len(miss) > 12 else ''}" if miss else ""))
    for board, values in cal.boards.items():
        print(f"board {board}: " + ", ".join(f"{k} {v:g}" for k, v in values.items()))
    if doc["unknown_taxels"]:
        print(f"taxels not in the layout: {doc['unknown_taxels']}")
    return 0
