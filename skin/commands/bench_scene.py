"""``skin bench scene``: one scene over many seeds, as `skin run` names its touches.

The measurement is `skin.bench.scene_seeds.run` (loaded only when run).
"""

from __future__ import annotations

import argparse
from pathlib import Path

_COLUMNS = ("touches", "detected", "material", "family", "unknown", "wrong", "sure_wrong",
            "false_contacts")


def add_parsers(kinds: argparse._SubParsersAction) -> None:
    """Register ``skin bench scene``."""
    scene = kinds.add_parser("scene", help="a scene run once per seed (skin run --seed N): "
                             "touches named right, and every miss grouped by what it was")
    scene.add_argument("--scene", default="default",
                       help="a shipped scene name or a TOML file (default)")
    scene.add_argument("--seeds", default="0-9",
                       help="seeds: a range 0-9 or a list 3,7,11 (0-9)")
    scene.add_argument("--duration", type=float, default=None,
                       help="seconds of each run (default: the scene's)")
    scene.add_argument("--ceiling", action="store_true",
                       help="also the known-nuisance ceiling of each touch (the best classifier "
                            "told all but the material) and the gap from the run to it, in "
                            "steps (skin.bench.scene_ceiling)")
    scene.add_argument("--common-mode", action=argparse.BooleanOptionalAction, default=None,
                       help="the onset detector's board common mode on / off (skin run "
                            "--[no-]common-mode; default: skin run's, on where the heater is "
                            "not PID-held)")
    scene.add_argument("--force-channel", choices=("force", "contact"), default=None,
                       help="give the scene's taxels a force sensor or a contact switch (the "
                            "scene's field force; the scene must not set it)")
    scene.add_argument("--force-inverted", action="store_true",
                       help="wire that force channel inverted: high at rest, dropping when "
                            "pressed (an active-low switch; the scene's field force_inverted)")
    scene.add_argument("--sensor", default=None,
                       help="put this sensor preset or file on every board (the scene's field "
                            "sensor; the scene must not set it)")
    scene.add_argument("--force-onsets", action=argparse.BooleanOptionalAction, default=True,
                       help="date contacts by the scene's force channel where it has one "
                            "(skin run --force-onsets; default on); --no-force-onsets: the "
                            "onset detector alone")
    scene.add_argument("--response-check", action=argparse.BooleanOptionalAction, default=True,
                       help="answer \"unknown\" for force-dated contacts whose temperature "
                            "shows no contact (skin run --response-check; default on)")
    scene.add_argument("--phantoms", type=int, default=0, metavar="N",
                       help="add N force glitches (2 N for 1 s on two neighbouring taxels no "
                            "touch comes near, nothing thermal behind them: "
                            "skin.bench.phantoms) to the scene; needs a force channel "
                            "(--force-channel)")
    scene.add_argument("--json", action="store_true", help="print one JSON document")
    scene.set_defaults(func=main)
    fit = kinds.add_parser("fit-calibration", help="fit the joint classifier's calibration "
                           "(the temperature of its evidence) by the least log-loss over a "
                           "scene's contacts (skin.bench.calibration_fit)")
    fit.add_argument("--scene", action="append", default=None,
                     help="a shipped scene name or a TOML file; give it again to pool scenes "
                          "into one fit (default: default, default-fast-film and cold-warm)")
    fit.add_argument("--seeds", default="0-9",
                     help="training seeds: a range 0-9 or a list 3,7,11 (0-9)")
    fit.add_argument("--write", action="store_true",
                     help="store the fit where the classifier reads it "
                          "(skin.models.joint.CALIBRATION_FILE)")
    fit.add_argument("--json", action="store_true", help="print one JSON document")
    fit.set_defaults(func=fit_calibration)


def parse_seeds(text: str) -> list[int]:
    """Seeds from ``"0-9"`` (inclusive) or ``"3,7,11"``; SkinError naming the text otherwise."""
    from skin.errors import SkinError

    seeds: list[int] = []
    try:
        for part in (p.strip() for p in text.split(",")):
            if not part:
                continue
            lo, sep, hi = part.partition("-")
            seeds += list(range(int(lo), int(hi) + 1)) if sep else [int(lo)]
    except ValueError:
        raise SkinError(f"--seeds must be a range like 0-9 or integers like 3,7,11, got "
                        f"{text!r}") from None
    if not seeds or min(seeds) < 0:
        raise SkinError(f"--seeds {text!r}: give at least one seed, none negative")
    return seeds


def _with_fields(scene: str, fields: dict[str, str | bool | None], tail: str = "") -> str:
    """Write ``scene`` with top-level ``fields`` added (None: left) to a temporary file; its path.

    ``tail`` is appended to the file (tables such as ``[[phantoms]]``).

    The scene's ``layout`` must be a shipped layout name (the copy lives elsewhere). The
    caller removes the file (`main` does, when the bench is done).
    """
    import tempfile
    import tomllib

    from skin.formats.datafiles import read_data_file
    from skin.formats.scene import SceneError

    text, source, _ = read_data_file(scene, "scenes", "scene", SceneError)
    data = tomllib.loads(text)
    head = ""
    for key, value in fields.items():
        if value is None:
            continue
        if key in data:
            raise SceneError(f"{source}: sets '{key}' already; drop --{key.replace('_', '-')} "
                             "or the field")
        text_value = str(value).lower() if isinstance(value, bool) else repr(value)
        head += f"{key} = {text_value}\n".replace("'", '"')
    out = tempfile.NamedTemporaryFile("w", suffix=".toml", prefix="bench_scene_", delete=False)
    with out:
        out.write(head + text + tail)
    return out.name


def main(args: argparse.Namespace) -> int:
    """Run `skin.bench.scene_seeds.run` and print its figures (or JSON)."""
    import json
    import time

    from skin.bench import machine
    from skin.bench.scene_seeds import SURE, run
    from skin.errors import SkinError
    from skin.formats.scene import load_scene
    from skin.progress import Progress

    seeds = parse_seeds(args.seeds)
    if args.duration is not None and args.duration <= 0:
        raise SkinError(f"--duration must be positive, got {args.duration}")
    scene = args.scene
    temporary = None
    if args.force_inverted and not args.force_channel:
        raise SkinError("--force-inverted needs --force-channel force|contact")
    if args.phantoms < 0:
        raise SkinError(f"--phantoms must be >= 0, got {args.phantoms}")
    tail = ""
    if args.phantoms:
        from skin.bench.phantoms import place, tables

        loaded = load_scene(scene)
        if not (args.force_channel or loaded.force):
            raise SkinError("--phantoms presses the force channel: the scene has none; give "
                            "--force-channel force or contact")
        try:
            tail = tables(place(loaded, args.phantoms, duration=args.duration))
        except ValueError as exc:
            raise SkinError(f"--phantoms {args.phantoms}: {exc}") from None
    if args.force_channel or args.sensor or tail:
        scene = temporary = _with_fields(scene, {"force": args.force_channel,
                                                 "force_inverted": args.force_inverted or None,
                                                 "sensor": args.sensor}, tail)
    try:
        load_scene(scene)  # a missing or bad scene is named before the work
        progress = Progress()
        started = time.monotonic()
        out = run(scene, seeds, args.duration,
                  progress=lambda d, n: progress.bar(d, n, "runs", started),
                  ceiling=args.ceiling,
                  common_mode="auto" if args.common_mode is None else args.common_mode,
                  force_onsets=args.force_onsets, response_check=args.response_check)
        progress.done()
    finally:
        if temporary is not None:
            Path(temporary).unlink(missing_ok=True)
    if args.json:
        print(json.dumps({"machine": machine(), **out,
                          "wall_time": round(time.monotonic() - started, 2)}))
        return 0
    print(f"scene {args.scene}, {len(seeds)} seeds; sure_wrong = wrong at p >= {SURE:g}")
    columns = _COLUMNS + (("ceiling", "ceiling_family") if args.ceiling else ())
    print(f"{'seed':>5} " + " ".join(f"{c:>{len(c)}}" for c in columns) + "  cpu_s")
    for r in out["runs"]:
        print(f"{r['seed']:>5} " + " ".join(f"{r[c]:>{len(c)}}" for c in columns)
              + f"  {r['cpu_s']:>5.1f}")
    t = out["totals"]
    print(f"{'all':>5} " + " ".join(f"{t[c]:>{len(c)}}" for c in columns))
    m, f = t["material_per_run"], t["family_per_run"]
    print(f"\nnamed right per run: material {m['mean']} (min {m['min']}, max {m['max']}), "
          f"family {f['mean']} (min {f['min']}, max {f['max']}) of {t['touches'] // t['runs']}")
    print("runs with at least k right at material level: "
          + ", ".join(f"{k}: {n}" for k, n in t["runs_material_at_least"].items()))
    ph = t["phantoms"]
    if ph["phantoms"]:
        print(f"phantom presses (force glitches of two taxels): {ph['phantoms']}, contacts "
              f"they started {ph['contacts']}: unknown {ph['unknown']} (no thermal response "
              f"{ph['no_response']}), named {ph['named']}")
    print(f"classify stage: {t['classify_ms_per_contact']} ms per contact")
    _print_reliability(t["reliability"])
    if args.ceiling:
        _print_ceiling(t, len(seeds))
    if out["pairs"]:
        print(f"\n{'truth':<12} {'called':<12} {'count':>5} {'median p':>8} {'best':<12} "
              f"{'e ratio':>7} {'family ok':>9} {'median s':>8} {'1 taxel':>7}")
        for p in out["pairs"]:
            ratio = "-" if p["effusivity_ratio"] is None else f"{p['effusivity_ratio']:.3f}"
            dur = "-" if p["median_duration"] is None else f"{p['median_duration']:.2f}"
            print(f"{p['truth']:<12} {p['label']:<12} {p['count']:>5} "
                  f"{p['median_confidence']:>8.2f} {p['best']:<12} {ratio:>7} "
                  f"{p['family_right']:>9} {dur:>8} {p['one_taxel']:>7}")
    return 0


def fit_calibration(args: argparse.Namespace) -> int:
    """Run `skin.bench.calibration_fit.fit` on the scene's seeds; print it, store with --write."""
    import json
    import time

    from skin.bench import machine
    from skin.bench.calibration_fit import FIT_SCENES, collect_scenes, fit
    from skin.errors import SkinError
    from skin.formats.scene import load_scene
    from skin.models.joint import CALIBRATION_FILE, EvidenceTemperature
    from skin.progress import Progress

    seeds = parse_seeds(args.seeds)
    scenes = args.scene or list(FIT_SCENES)
    for scene in scenes:
        load_scene(scene)  # a missing or bad scene is named before the work
    progress = Progress()
    started = time.monotonic()
    answers = collect_scenes(scenes, seeds,
                             lambda d, n: progress.bar(d, n, "runs", started))
    progress.done()
    out = fit(answers)
    best = next(r for r in out["table"] if r["temperature"] == out["best"])
    calibration = EvidenceTemperature(out["best"], (
        "skin bench fit-calibration " + "".join(f"--scene {s} " for s in scenes)
        + f"--seeds {args.seeds.replace(' ', '')}"
        f" --write: least log-loss of the true material "
        + ("with no touch named wrong at p >= 0.9" if not best["sure_wrong_count"] else
           f"with the fewest touches named wrong at p >= 0.9 ({best['sure_wrong_count']})")
        + f", {best['material']['log_loss']:.3f} over {best['material']['n']} contacts "
        f"(untempered {out['table'][0]['material']['log_loss']:.3f})"))
    if args.write:
        try:
            CALIBRATION_FILE.write_text(calibration.dump(), encoding="utf-8")
        except OSError as exc:
            raise SkinError(f"{CALIBRATION_FILE}: cannot store the calibration ({exc}); "
                            f"--write needs an editable install (pip install -e .)") from None
    if args.json:
        print(json.dumps({"machine": machine(), "scenes": scenes, "seeds": seeds, **out,
                          "written": str(CALIBRATION_FILE) if args.write else None,
                          "wall_time": round(time.monotonic() - started, 2)}))
        return 0
    n = sum(len(r) for r in answers["runs"])
    print(f"scenes {', '.join(scenes)}, {len(seeds)} seeds each, {n} contacts; per run: "
          f"named right "
          f"(material, family), unknown, wrong at p >= 0.9")
    print(f"{'temperature':>11} {'log-loss':>8} {'ECE':>6} {'Brier':>6} {'family LL':>9} "
          f"{'named':>6} {'family':>6} {'unknown':>7} {'sure_wrong':>10}")
    for r in out["table"]:
        m = r["material"]
        print(f"{r['temperature']:>11.4g} {m['log_loss']:>8.3f} {m['ece']:>6.3f} "
              f"{m['brier']:>6.3f} {r['family']['log_loss']:>9.3f} {r['named']:>6.2f} "
              f"{r['family_named']:>6.2f} {r['unknown']:>7.2f} {r['sure_wrong']:>10.2f}")
    print(f"\nleast log-loss: temperature {out['least_log_loss']:g}; least with no touch "
          f"named wrong at p >= 0.9 (the fit): {out['best']:g}"
          + (f"; written to {CALIBRATION_FILE}" if args.write else " (--write stores it)"))
    return 0


def _print_reliability(figures: dict) -> None:
    """Print how calibrated the answers are (`skin.bench.reliability`), material and family."""
    from skin.bench.reliability import SURE

    print("\nreliability of the answers' probabilities over every detected touch:")
    for level in ("material", "family"):
        r = figures[level]
        if not r["n"]:
            continue
        s = r["sure"]
        share = "-" if s["share_right"] is None else f"{100 * s['share_right']:.1f} %"
        print(f"{level}: n {r['n']}, log-loss {r['log_loss']:.3f}, Brier {r['brier']:.3f}, "
              f"ECE {r['ece']:.3f}, most probable right {100 * r['accuracy']:.1f} %; "
              f"at p >= {SURE:g}: {s['count']}, {share} right")
        print("  max p bin     count  mean p  accuracy")
        for b in r["bins"]:
            if b["count"]:
                print(f"  {b['lo']:.1f}-{b['hi']:.1f}     {b['count']:>7} {b['confidence']:>7.3f}"
                      f" {b['accuracy']:>9.3f}")


def _print_ceiling(totals: dict, runs: int) -> None:
    """Print the ceiling over the runs and the gap's steps (`skin.bench.scene_ceiling`)."""
    c = totals["ceiling_per_run"]
    n = totals["touches"] // totals["runs"]
    print(f"\nceiling (told all but the material) per run: {c['mean']} of {n} "
          f"(min {c['min']}, max {c['max']}); family {totals['ceiling_family'] / runs:.2f}")
    print(f"\n{'step':<12} {'named right':>11} {'best right':>10} {'family':>6} "
          f"{'best family':>11} {'sure_wrong':>10}   (per run)")
    for step, v in totals["steps"].items():
        print(f"{step:<12} {v['label'] / runs:>11.2f} {v['best'] / runs:>10.2f} "
              f"{v['family'] / runs:>6.2f} {v['best_family'] / runs:>11.2f} "
              f"{v['sure_wrong'] / runs:>10.2f}")
    print(f"{'ceiling':<12} {'':>11} {totals['ceiling'] / runs:>10.2f} {'':>6} "
          f"{totals['ceiling_family'] / runs:>11.2f}")
    for name, what in (("all", "every touch"), ("short", "touches <= 0.6 s")):
        d = totals["dating"][name]
        print(f"dating, {what}: " + "; ".join(
            f"{k} {v['median']:+.1f} ms ({v['p5']:+.1f} to {v['p95']:+.1f}, {v['n']} windows)"
            for k, v in (("onset", d["onset"]), ("release", d["end"])) if v is not None))
