"""``skin commission``: measure a skin's own noise from a quiet stretch, into the calibration file.

Record up to a minute with nothing touching the skin (heaters on, as in use), for example
``skin record serial:///dev/ttyACM0 quiet.mcap --duration 60``, then::

    skin commission --port replay://quiet.mcap?speed=0 -o cal.json

Per taxel it writes ``noise_sigma`` (noise per sample, K), ``noise_lowfreq`` (white-equivalent
noise of sums over many samples: larger when the readings were smoothed) and ``drift`` (K/s)
into the calibration file (updated if it exists; `skin.models.commission`), and prints the
sample jitter and a spectrum summary. `skin run --calibration` and `skin evaluate-onset
--calibration` then set the onset detector's thresholds from each taxel's own noise. A stretch
that is too short or not quiet is refused with what to record instead.

With ``--touches water,neoprene`` it fits each taxel's sensor response (diffusivity and
conductivity; the depth too when the heater is switched off or left on at contact, else it
is kept: a semi-infinite body shows depth^2 / diffusivity and the effusivity) from touches
of those references at room temperature, at least 3 of each held 2.5 s on the paper's
sensor, longer on a slower one (`skin.models.commission.touch_seconds`; a recording that
falls short is refused with how long to hold and rest): touches found by the pipeline's
detector (or given by ``--labels``), named by the
reference they fit best, each touch's onset, baseline and contact conductance fitted with
the constants. A taxel with too few touches gets its board's pooled fit.

Touch references that conform: water (in a thin bag), neoprene or rubber. Through a hard
object's air gap (aluminium, wood) the contact conductance and the response time trade
against each other (both slow the reading's approach by a 1/sqrt(t) tail), and every real
contact has that gap; a note on stderr (and ``air_gap_note`` in ``--json``) names
references whose gap slows the contact by more than 1 % of the sensor's half-response time
(`GAP_TIME_FRACTION`) and says what to record instead. Measured in simulation (`skin bench
commission --references aluminium,pine [--classify]`, finite contacts, 8 taxels, seeds 3, 7
and 11): aluminium and pine through their gaps leave the response time 8.5-10 % off on the
paper's sensor and 20-25 % on fast-film, and a classifier told those constants 5.7-9.1
points below one told the true ones at 1 and 2.5 s on paper (not met at seed 7, unresolved
at seed 11), 13-27 on fast-film (not met). Water and neoprene (`skin bench commission`, its
defaults): response time 0.19-0.45 % off on paper (gaps -0.3 to +0.8 points on 1,320
contacts: met), 0.73-0.96 % on fast-film (-0.4 to +1.5 on 1,320: met but seed 11 at 1 s,
unresolved), 0.21 % on pid-logger and 6.5 % on low-cost (labelled touches; both classify
near chance with the true constants).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from skin.errors import SkinError
from skin.progress import Progress


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin commission``."""
    cmd = sub.add_parser("commission", help="each taxel's noise from a quiet stretch, into the "
                                            "calibration file", description=__doc__)
    source = cmd.add_mutually_exclusive_group(required=True)
    source.add_argument("--data", metavar="NPZ", default=None,
                        help="fit each taxel's sensor response from a trial dataset (version 2, "
                             "README 'Trial datasets') of labelled reference contacts with "
                             "their onsets (an unknown one, -1, dated by the trial's force "
                             "channel, else left out), taxel ids and 0.4 s before each onset")
    source.add_argument("--port", metavar="URL",
                     help="where the quiet stretch comes from: replay://quiet.mcap?speed=0, a "
                          "device URL, or sim://SCENE?speed=0")
    cmd.add_argument("--seconds", type=float, default=60.0,
                     help="seconds of the stretch to use (default 60, at least 10)")
    cmd.add_argument("--layout", default=None,
                     help="layout (default: the recording's, else arm)")
    cmd.add_argument("--touches", metavar="MATERIALS", default=None,
                     help="instead of the noise, fit each taxel's sensor response from touches "
                          "of these reference materials at room temperature in the recording, "
                          "e.g. water,neoprene (at least 3 touches of each "
                          "of 2, held 2.5 s, "
                          "longer on a slower sensor, with 0.4 s of quiet before each); each "
                          "touch's onset is fitted with "
                          "the constants")
    cmd.add_argument("--labels", metavar="CSV", default=None,
                     help="the reference touches' times instead of detecting them: a label "
                          "file time,material[,taxels][,group] (taxel ids separated by spaces "
                          "or ';', 'all' or empty: every taxel); the materials are the file's")
    cmd.add_argument("--room", type=float, default=None, metavar="C",
                     help="room temperature of the references, deg C (default: the "
                          "recording's ambient sensor)")
    cmd.add_argument("-o", "--out", required=True, help="calibration file to write or update")
    cmd.add_argument("--json", action="store_true",
                     help="print one JSON document on stdout and nothing else")
    cmd.set_defaults(func=main)


def read_stretch(url: str, layout: object, seconds: float, calibration: object = None,
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """Read ``seconds`` of a source as (times, temperatures, ambient, force).

    Temperatures and force (N, `skin.frame.Frame.force`) in layout order; force is None when
    no frame carried a force channel, NaN where a sample or taxel had no reading.
    """
    from skin import drivers
    from skin.stream.assembly import FrameAssembler
    from skin.stream.calibration import Calibration

    cal = calibration or Calibration.from_layout(layout)
    assembler = FrameAssembler(layout)
    times, temps, ambient, force = [], [], [], []
    first = None
    with drivers.open(url) as driver:
        while True:
            frame = driver.recv(timeout=2.0)
            if frame is None:
                break
            first = frame.device_time if first is None else first
            block = assembler.push([frame])
            if len(block):
                times.append(block.times)
                temps.append(cal.temperature(block.counts)[0])
                ambient.append(block.ambient)
                force.append(block.force)
            if frame.device_time - first >= seconds:
                break
    block = assembler.flush()
    if len(block):
        times.append(block.times)
        temps.append(cal.temperature(block.counts)[0])
        ambient.append(block.ambient)
        force.append(block.force)
    if not times:
        raise SkinError(f"{url}: no frame arrived: check the port, then record again")
    channel = None
    if any(f is not None for f in force):  # blocks without one: no reading
        channel = np.concatenate([np.full((len(t), len(layout)), np.nan) if f is None else f
                                  for t, f in zip(times, force, strict=True)])
    return np.concatenate(times), np.concatenate(temps), np.concatenate(ambient), channel


def main(args: argparse.Namespace) -> int:
    """Commission from a quiet stretch (see the module docstring)."""
    from pathlib import Path

    from skin.formats.calibration_file import CalibrationFile, load_calibration
    from skin.formats.layout import load_layout
    from skin.models.commission import QUIET_SECONDS, quiet_figures

    if not QUIET_SECONDS[0] <= args.seconds <= QUIET_SECONDS[1]:
        raise SkinError(f"--seconds must lie within {QUIET_SECONDS[0]:g}-{QUIET_SECONDS[1]:g}")
    if args.touches:
        from skin.models import load_materials

        _reference_names(args.touches, load_materials())
    if args.data:
        return _dataset(args, load_layout(args.layout or "arm"), Progress())
    layout = _layout(args.port, args.layout, load_layout)
    if args.labels:  # checked before the recording is read
        from skin.formats.touch_labels import read_touch_labels

        args.label_list = read_touch_labels(args.labels, layout=layout)
        names = list(dict.fromkeys(lab.material for lab in args.label_list))
        given = {m.strip() for m in (args.touches or "").split(",") if m.strip()}
        if given and set(names) - given:
            raise SkinError(f"{args.labels}: material {sorted(set(names) - given)[0]} is not "
                            f"in --touches {args.touches}")
        args.touches = ",".join(names)
    out = Path(args.out)
    cal_file = load_calibration(out) if out.exists() else CalibrationFile()
    progress = Progress()
    started = time.monotonic()
    progress.message(f"reading {args.seconds:g} s of {args.port}")
    calibration, _ = cal_file.apply(layout)
    times, temps, ambient, force = read_stretch(args.port, layout, args.seconds, calibration)
    if args.touches:
        return _touches(args, layout, cal_file, out, times, temps, ambient, started, progress,
                        force)
    q = quiet_figures(times, temps, layout.ids)
    for i, t in enumerate(layout.ids):
        entry = cal_file.taxels.setdefault(int(t), {})
        entry.update(noise_sigma=float(q.noise_sigma[i]), noise_lowfreq=float(q.noise_lowfreq[i]),
                     drift=float(q.drift[i]))
    cal_file.references["noise"] = (f"quiet stretch of {args.port} ({q.seconds:.1f} s at "
                                    f"{q.fs:.4g} Hz, sample jitter {1e3 * q.jitter:.3g} ms rms)")
    cal_file.save(out)
    progress.done()
    factor = q.noise_sigma / q.noise_lowfreq
    doc = {"out": str(out), "taxels": len(layout), "seconds": round(q.seconds, 2),
           "fs": round(q.fs, 3), "jitter_ms": round(1e3 * q.jitter, 4),
           "noise_sigma_k": _stats(q.noise_sigma), "noise_lowfreq_k": _stats(q.noise_lowfreq),
           "smoothing_factor": _stats(factor), "drift_k_per_min": _stats(60.0 * q.drift),
           "wall_time": round(time.monotonic() - started, 2)}
    if args.json:
        print(json.dumps(doc))
        return 0
    print(f"wrote {out}: noise of {len(layout)} taxels from {q.seconds:.1f} s at {q.fs:.4g} Hz "
          f"(jitter {doc['jitter_ms']} ms rms)")
    for key, unit in (("noise_sigma_k", "K"), ("noise_lowfreq_k", "K"),
                      ("smoothing_factor", ""), ("drift_k_per_min", "K/min")):
        s = doc[key]
        print(f"  {key:<18} median {s['median']:.4g} {unit} (min {s['min']:.4g}, "
              f"max {s['max']:.4g})")
    return 0


def _touches(args: argparse.Namespace, layout: object, cal_file: object, out: object,
             times: np.ndarray, temps: np.ndarray, ambient: np.ndarray, started: float,
             progress: Progress, force: np.ndarray | None = None) -> int:
    """Fit the sensor response from reference touches (`skin.models.commission`).

    A recording with a force channel dates the touches of the taxels it reads by it.
    """
    from skin.formats.calibration_file import noise_sigma
    from skin.models import load_materials
    from skin.models.commission import commission_response, described

    table = load_materials()
    names = _reference_names(args.touches, table)
    room = args.room if args.room is not None else float(np.nanmean(ambient))
    if not np.isfinite(room):
        raise SkinError("the recording has no ambient reading: give --room C")
    _, sensors = cal_file.apply(layout)
    note = air_gap_note(names, table, described(layout, sensors))
    if note:
        progress.message(note)
    progress.message(f"fitting the response from touches of {', '.join(names)}")
    labels = getattr(args, "label_list", None)
    if force is not None and labels is None:
        progress.message(f"dating the touches of {int(np.isfinite(force).any(axis=0).sum())} "
                         f"taxels by the recording's force channel")
    fits, counts = commission_response(times, temps, layout, {m: table[m] for m in names},
                                       sensors, room, noise=noise_sigma(cal_file, layout),
                                       labels=labels, force=force)
    return _write_response(args, layout, cal_file, out, fits, counts,
                           f"touches of {', '.join(names)} at {room:.2f} C in {args.port}"
                           + (" (dated by its force channel)" if counts.get("force_dated")
                              else ""),
                           room, started, progress, note)


def _dataset(args: argparse.Namespace, layout: object, progress: Progress) -> int:
    """Fit the sensor response from a trial dataset's labelled reference contacts."""
    from pathlib import Path

    from skin.formats.calibration_file import CalibrationFile, load_calibration
    from skin.formats.dataset import load_trials
    from skin.models import load_materials
    from skin.models.commission import (
        dataset_touches,
        described,
        fit_responses,
        touches_wanted,
    )

    if args.labels or args.touches:
        raise SkinError("--data names its touches' materials and onsets: no --labels or "
                        "--touches with it")
    started = time.monotonic()
    trials = load_trials(args.data)
    table = load_materials()
    names = list(dict.fromkeys(str(m) for m in trials.label))
    _reference_names(",".join(names), table, option=f"{args.data}'s reference contacts")
    out = Path(args.out)
    cal_file = load_calibration(out) if out.exists() else CalibrationFile()
    _, sensors = cal_file.apply(layout)
    note = air_gap_note(names, table, described(layout, sensors), dataset=True)
    if note:
        progress.message(note)
    progress.message(f"fitting the response from {len(trials)} trials of {', '.join(names)}")
    touches, short = dataset_touches(trials, layout)
    room = float(np.nanmedian(trials.ambient))
    fits = fit_responses(touches, layout, {m: table[m] for m in names},
                         described(layout, sensors), room)
    counts = {"detected": len(touches) + short, "left_out": short, "ambiguous": 0,
              "wanted": touches_wanted(fits, touches, layout, {m: table[m] for m in names})}
    return _write_response(args, layout, cal_file, out, fits, counts,
                           f"{len(touches)} contacts of {', '.join(names)} in {args.data}",
                           room, started, progress, note)


def _write_response(args: argparse.Namespace, layout: object, cal_file: object, out: object,
                    fits: list, counts: dict, reference: str, room: float, started: float,
                    progress: Progress, note: str | None = None) -> int:
    """Write the fitted responses into the calibration file and report them.

    ``note``: the air-gap note (`air_gap_note`), in ``--json`` as ``air_gap_note``. A
    board's pooled fit does not replace a taxel's own fit already in the file (an earlier
    recording's touches of that taxel beat its board's spread): those taxels are counted in
    ``kept_own`` and left out of ``wanted``.
    """
    kept = []
    for f in fits:
        for k in f.columns:
            entry = cal_file.taxels.setdefault(int(layout.ids[k]), {})
            if f.scope == "board" and entry.get("thermal_scope") == "taxel":
                kept.append(int(layout.ids[k]))
                continue
            entry.update(
                diffusivity=f.fit.sensor.diffusivity, conductivity=f.fit.sensor.conductivity,
                depth=f.fit.sensor.depth, thermal_rms=round(f.fit.rms, 5),
                thermal_contacts=f.touches, thermal_converged=f.fit.converged,
                thermal_scope=f.scope)
    cal_file.references["thermal"] = reference
    cal_file.save(out)
    progress.done()
    counts = {**counts, "wanted": {k: w for k, w in counts.get("wanted", {}).items()
                                   if k not in kept}}
    per_board = sum(len(f.columns) for f in fits if f.scope == "board") - len(kept)
    per_taxel = sum(len(f.columns) for f in fits if f.scope == "taxel")
    fitted = per_taxel + per_board
    doc = {"out": str(out), "taxels": len(layout), "fitted": fitted,
           "per_taxel": per_taxel, "per_board": per_board, "kept_own": len(kept),
           "room_c": round(room, 3), **counts,
           "thermal_rms_k": _stats(np.array([f.fit.rms for f in fits])),
           "wall_time": round(time.monotonic() - started, 2)}
    if note:
        doc["air_gap_note"] = note
    if args.json:
        print(json.dumps(doc))
        return 0
    print(f"wrote {out}: sensor response of {fitted} of {len(layout)} taxels "
          f"({doc['per_taxel']} per taxel, {doc['per_board']} per board) from "
          f"{counts['detected']} touches at {room:.2f} C ({counts['left_out']} too short or "
          f"warm, {counts['ambiguous']} ambiguous); fit rms median "
          f"{doc['thermal_rms_k']['median']:.3g} K")
    if counts.get("force_taxels"):
        print(f"{counts['force_dated']} touches dated by the recording's force channel "
              f"({counts['force_taxels']} taxels read it; the others' by the onset detector)")
        for note in counts.get("force_notes", []):
            print(note)
    if kept:
        print(f"kept the own fits already in {out} of {len(kept)} taxels this recording "
              "gave only their board's pooled fit")
    if counts.get("wanted"):
        from skin.models.commission import wanted_said

        print(wanted_said(counts["wanted"]))
    return 0


#: Flag a reference whose air gap slows the contact for more than this fraction of the
#: sensor's half-response time (`gap_seconds`). Where it comes from (simulation,
#: `skin bench commission --contact finite`): the conforming pair water + neoprene, at most
#: 0.24 % (neoprene on fast-film), left the response time 0.45-0.96 % off on paper and
#: fast-film; the pair aluminium + pine, from 2.3 % (aluminium on paper; pine 7.2 %, on
#: fast-film 24 and 73 %), left it 8.5-25 % off. 1 % lies between; materials between the two
#: pairs (acrylic, glass, porcelain, foam on paper) were not measured.
GAP_TIME_FRACTION = 0.01


def gap_seconds(material: object, sensor_effusivity: float) -> float:
    """Rough time an air gap slows a contact, s: (e / h)^2 at the material's widest gap.

    ``e`` is the sensor's and the material's effusivities in series (the contact's own
    effusivity, e_s e_m / (e_s + e_m)), ``h`` the lowest conductance of the material's
    range (`Material.conductance_range`, from its widest gap); a finite contact reaches the
    perfect contact's surface temperature on this time scale. Aluminium, steel and copper
    about 0.06 s against the paper's sensor, pine 0.18 s, acrylic 0.0035 s, water 0.0001 s.
    """
    e = sensor_effusivity * material.effusivity / (sensor_effusivity + material.effusivity)
    return float((e / material.conductance_range[0]) ** 2)


def air_gap_note(names: list[str], table: dict, sensors: list,
                 dataset: bool = False) -> str | None:
    """Name the references whose air gap slows the contact on the sensor's own time scale.

    A reference is named when `gap_seconds` (with the taxels' median effusivity) exceeds
    `GAP_TIME_FRACTION` of the fastest taxel's half-response time (``sensors``: each taxel's
    `SensorDescription`): its contact conductance then trades against the response time
    (`skin.bench.commission`). None when no reference is. The note says what to record
    instead: touches given with ``--touches water,neoprene``, or with ``dataset`` (the
    ``--data`` path, which takes no ``--touches``) a dataset of such contacts.
    """
    e_s = float(np.median([s.effusivity for s in sensors]))
    tau = float(min(s.response_time for s in sensors))
    slow = {m: gap_seconds(table[m], e_s) for m in names}
    slow = {m: t for m, t in slow.items() if t > GAP_TIME_FRACTION * tau}
    if not slow:
        return None
    said = ", ".join(f"{m} {t:.2g} s" for m, t in slow.items())
    conform = ("references that conform, at least 3 each of a thin bag of water and a "
               "neoprene or rubber pad at room temperature")
    instead = (f"log a dataset of water and neoprene contacts instead ({conform}) and give "
               f"it with --data" if dataset else
               f"record the touches again with {conform}, and give --touches water,neoprene")
    return (f"note: the air gap of {', '.join(slow)} slows the contact ({said}) by more than "
            f"{100 * GAP_TIME_FRACTION:g} % of the sensor's half-response time "
            f"({tau:.3g} s), so its conductance trades against the response time and the "
            f"fitted response time may be off (in simulation aluminium and pine through "
            f"their gaps left it 8.5-10 % off on the paper's sensor and 20-25 % on "
            f"fast-film). On real hardware every contact has such a gap: " + instead)


def _reference_names(touches: str, table: dict, option: str = "--touches") -> list[str]:
    """Return the ``option``'s materials, checked: at least 2, all in the materials table."""
    names = list(dict.fromkeys(m.strip() for m in touches.split(",") if m.strip()))
    unknown = [m for m in names if m not in table]
    if unknown or len(names) < 2:
        raise SkinError(f"{option} needs at least 2 known reference materials; "
                        f"{'unknown: ' + ', '.join(unknown) if unknown else 'got ' + touches}"
                        f" (known: {', '.join(sorted(table))})")
    return names


def _stats(values: np.ndarray) -> dict:
    return {"median": float(np.median(values)), "min": float(np.min(values)),
            "max": float(np.max(values))}


def _layout(port: str, given: str | None, load_layout: object) -> object:
    if given:
        return load_layout(given)
    if port.startswith("replay://"):
        from skin.drivers.recording import RecordingReader

        path = port[len("replay://"):].partition("?")[0]
        recorded = RecordingReader(path).layout()
        if recorded is not None:
            return recorded
    if port.startswith("sim://"):
        from skin.formats.scene import load_scene

        return load_scene(port[len("sim://"):].partition("?")[0] or "default").layout
    return load_layout("arm")
