"""``skin bench drivers``, ``fuzz`` and ``clock``: the drivers' speed, robustness and timing.

Registered by `skin.commands.bench`; the work is done in `skin.bench.drivers` and
`skin.bench.fuzz` and `skin.bench.clock`, imported when the command runs.
"""

from __future__ import annotations

import argparse
import json
import time

from skin.errors import SkinError
from skin.progress import Progress


def add_parsers(kinds: argparse._SubParsersAction) -> None:
    """Register ``skin bench drivers`` and ``skin bench fuzz``."""
    drv = kinds.add_parser("drivers", help="decode throughput of each driver backend")
    drv.add_argument("--quick", action="store_true", help="few samples (a smoke run)")
    drv.add_argument("--taxels", default="64,1000", help="skin sizes (default 64,1000)")
    drv.add_argument("--json", action="store_true", help="print one JSON document")
    drv.set_defaults(func=main_drivers)
    fuzz = kinds.add_parser("fuzz", help="every decoder against damaged streams")
    fuzz.add_argument("--frames", type=int, default=4_000_000,
                      help="about how many frames to try in all (default 4000000)")
    fuzz.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    fuzz.add_argument("--json", action="store_true", help="print one JSON document")
    fuzz.set_defaults(func=main_fuzz)
    clock = kinds.add_parser("clock", help="device-to-host time mapping: error and cost")
    clock.add_argument("--seconds", type=float, default=300.0,
                       help="simulated seconds per scenario (default 300)")
    clock.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    clock.add_argument("--json", action="store_true", help="print one JSON document")
    clock.set_defaults(func=main_clock)
    fw = kinds.add_parser("firmware", help="the AVR firmware's cycles per sample in simavr, "
                                           "with and without its force inputs")
    fw.add_argument("--builds", default="uno,uno_force",
                    help="firmware/Makefile builds, the first the baseline "
                         "(default uno,uno_force; also mega)")
    fw.add_argument("--seconds", type=float, default=3.0,
                    help="emulated seconds per build (default 3)")
    fw.add_argument("--same-stream", metavar="ELF",
                    help="also check that the first build (without timing marks) sends byte "
                         "for byte what this ELF (the same board built from another commit) "
                         "sends")
    fw.add_argument("--json", action="store_true", help="print one JSON document")
    fw.set_defaults(func=main_firmware)


def _si(value: float) -> str:
    for unit, scale in (("G", 1e9), ("M", 1e6), ("k", 1e3)):
        if abs(value) >= scale:
            return f"{value / scale:.3g} {unit}"
    return f"{value:.3g} "


def _link(bus: str, bit_rate: int) -> str:
    rate = f"{bit_rate / 1e6:g}M" if bit_rate >= 1_000_000 else f"{bit_rate // 1000}k"
    return f"{bus} {rate}"


def main_firmware(args: argparse.Namespace) -> int:
    """Run ``skin bench firmware``."""
    from skin.bench import machine
    from skin.bench.firmware import measure, same_packets, stream_bytes
    from skin.drivers.avr_sim import firmware_elf

    builds = [b.strip() for b in args.builds.split(",") if b.strip()]
    if not builds:
        raise SkinError("--builds names no build")
    if not args.seconds > 0:
        raise SkinError("--seconds must be positive")
    rows = [measure(b, args.seconds) for b in builds]
    base = rows[0]
    out = []
    for r in rows:
        d = r.as_dict()
        d["work_ratio"] = round(r.work_per_sample / base.work_per_sample, 3)
        d["scan_ratio"] = round(r.scan_mean / base.scan_mean, 3)
        out.append(d)
    same = None
    if args.same_stream:
        ours = stream_bytes(str(firmware_elf(base.build)), base.build, args.seconds)
        theirs = stream_bytes(args.same_stream, base.build, args.seconds)
        same = {"elf": args.same_stream, "build": str(firmware_elf(base.build)),
                **same_packets(ours, theirs, int(200 * args.seconds))}
    if args.json:
        print(json.dumps({"machine": machine(), "seconds": args.seconds, "baseline": base.build,
                          "builds": out, "same_stream": same}, indent=2))
        return 0
    print(f"AVR firmware in simavr, {args.seconds:g} emulated s per build, cycles of the 16 MHz "
          f"MCU per sample (period {base.period_cycles:.0f}); ratios against {base.build}")
    print(f"{'build':>10} {'taxels':>6} {'force':>5} {'frames':>6} {'w/force':>7} "
          f"{'scan':>8} {'(max)':>7} {'%per':>5} {'work':>7} {'ratio':>6} {'wait':>6} "
          f"{'poll max':>8} {'B/sample':>8}")
    for d in out:
        print(f"{d['build']:>10} {d['taxels']:>6} {d['force_inputs']:>5} {d['frames']:>6} "
              f"{d['frames_with_force']:>7} {d['scan_mean']:>8.0f} {d['scan_max']:>7.0f} "
              f"{100 * d['scan_max'] / d['period_cycles']:>5.1f} {d['work_per_sample']:>7.0f} "
              f"{d['work_ratio']:>6.2f} {d['wait_per_sample']:>6.0f} {d['poll_max']:>8.0f} "
              f"{d['bytes_per_sample']:>8.1f}")
    if same is not None:
        verdict = ("identical" if same["identical"]
                   else f"DIFFERENT (first at packet {same['first_difference']})")
        print(f"stream of {same['build']} vs {same['elf']}: {same['packets']} packets, "
              f"{verdict}")
    return 0


def main_drivers(args: argparse.Namespace) -> int:
    """Run ``skin bench drivers``."""
    from skin.bench import drivers as driver_bench
    from skin.bench import machine

    try:
        sizes = tuple(int(v) for v in args.taxels.split(",") if v.strip())
    except ValueError:
        raise SkinError(f"--taxels wants integers, got {args.taxels!r}") from None
    if not sizes or min(sizes) < 1:
        raise SkinError("--taxels must be positive")
    progress = Progress()
    doc = driver_bench.run(quick=args.quick, sizes=sizes, progress=progress.status)
    progress.done()
    doc = {"machine": machine(), **doc}
    if args.json:
        print(json.dumps(doc))
        return 0
    rate = doc["rate_hz"]
    print(f"driver decode throughput on one core ({doc['machine']['cpus']} cores, Python "
          f"{doc['machine']['python']}, numpy {doc['machine']['numpy']}), skins cut into "
          f"boards that fit their link at {rate:g} Hz")
    print("frames/s: board samples decoded per second; physical/s: what all the links carry "
          "at 100 % with those samples (CAN: worst-case stuffing); skin Hz: frames/s / boards")
    print(f"{'backend':<29} {'link':<10} {'taxels':>6} {'layout':<28} {'frames/s':>9} "
          f"{'taxel-smp/s':>11} {'us/frame':>8} {'physical/s':>10} {'x phys':>7} "
          f"{'skin Hz':>8} {'x 200Hz':>7}")
    for r in doc["results"]:
        print(f"{r['backend']:<29} {_link(r['bus'], r['bit_rate']):<10} {r['taxels']:>6} "
              f"{r['layout']:<28} {r['frames_per_s']:>9} {r['taxel_samples_per_s']:>11} "
              f"{r['us_per_frame']:>8} {r['physical_frames_per_s']:>10.0f} "
              f"{r['margin_physical']:>7} {r['skin_hz']:>8.0f} {r['margin_200hz']:>7}")
    b = doc["baseline"]
    print(f"\nbaseline, same run, on the 64-taxel serial stream ({b['stream_bytes']} bytes): "
          f"memcpy {_si(b['memcpy_bytes_per_s'])}B/s; a Python loop cutting it into "
          f"{b['read_bytes']} B reads {_si(b['read_loop_bytes_per_s'])}B/s; np.frombuffer of a "
          f"packet's taxel words {b['frombuffer_us_per_frame']} us; StreamDecoder on random "
          f"bytes {_si(b['garbage_decode_bytes_per_s'])}B/s")
    for r in doc["results"]:
        if "bytes_per_s" in r:
            print(f"  {r['backend']}, {r['taxels']} taxels: {_si(r['bytes_per_s'])}B/s = "
                  f"{r['x_memcpy']:.2g} x memcpy, {r['x_garbage']:.2g} x random bytes; "
                  f"{r['us_per_frame']} us a frame = {r['x_frombuffer']} x np.frombuffer")
    serial = [r for r in doc["results"] if r["bus"] == "serial"]
    can = [r for r in doc["results"] if r["bus"] == "can"]
    slowest = min(doc["results"], key=lambda r: r["margin_200hz"])
    print(f"\nslowest: {slowest['backend']} ({_link(slowest['bus'], slowest['bit_rate'])}, "
          f"{slowest['taxels']} taxels): {slowest['skin_hz']:.0f} Hz for the whole skin on "
          f"one core, {slowest['margin_200hz']} x the {rate:g} Hz needed")
    if serial and can:
        print("a pty is not paced at the baud rate and python-can's virtual bus was filled "
              "beforehand: the end-to-end rows measure the host's side of the link")
    print(f"wall time {doc['wall_time']} s")
    return 0


def main_fuzz(args: argparse.Namespace) -> int:
    """Run ``skin bench fuzz``."""
    from skin.bench import fuzz, machine

    if args.frames < 128:
        raise SkinError("--frames must be at least 128")
    progress = Progress()
    started = time.monotonic()
    doc = fuzz.run(args.frames, args.seed,
                   progress=lambda d, n, part: progress.bar(d, n, part, started))
    progress.done()
    doc = {"machine": machine(), **doc}
    if args.json:
        print(json.dumps(doc))
        return 0
    print(f"fuzz campaign, seed {doc['seed']}: {doc['frames_tried']} frames tried, "
          f"{doc['crashes']} crashes ({doc['machine']['cpus']} cores, {doc['wall_time']} s)")
    for name, what in (("serial", "serial streams (COBS + CRC-16): bit flips, overwrites, "
                                  "insertions (garbage up to 3 packets long), deletions, "
                                  "truncations, spliced copies; reads of 1-4096 bytes"),
                       ("can", "CAN streams, no bus CRC in front: drops, duplicates, swaps, "
                               "foreign frames, bit flips, length changes; 1-3 nodes")):
        s = doc[name]["streams"]
        st = s["stats"]
        print(f"\n{what}")
        print(f"  {s['trials']} streams, {s['sent']} samples and replies sent, {s['out']} "
              f"decoded; {s['intact']} came through intact, {s['missed']} of them missed; "
              f"{s['corrupt']} corrupt accepted ({s['unexplained']} not accounted for by the "
              f"damage); crashes {s['crashes']}; statistics inconsistent in "
              f"{s['inconsistent']} streams")
        keys = (("crc_errors", "malformed", "resyncs", "lost_samples", "duplicates")
                if name == "serial" else
                ("malformed", "missing", "lost_groups", "orphans", "lost_samples",
                 "duplicates", "lost_replies"))
        print("  counted: " + ", ".join(f"{k} {st.get(k, 0)}" for k in keys))
        for e in s["examples"]:
            print(f"  ! {e}")
    print("\nserial, CRC-16/CCITT-FALSE: damaged SAMPLE packets of 16 taxels through "
          "StreamDecoder")
    print(f"  {'error pattern':<18} {'tried':>9} {'accepted':>8} {'rate':>9} "
          f"{'95 % CI (Clopper-Pearson)':>26}  theory")
    for r in doc["serial"]["crc"]:
        print(f"  {r['errors']:<18} {r['tried']:>9} {r['accepted']:>8} {r['rate']:>9.3g} "
              f"{_ci(r['ci95']):>26}  {r['theory']:.3g}: {r['note']}")
    print("\nCAN, frames of a 64-taxel node: the bus's CRC-15 (computed on identifier, data "
          "and CRC bits), then CanReassembler")
    print(f"  {'error pattern':<14} {'tried':>9} {'pass CRC':>8} {'rate':>9} "
          f"{'95 % CI':>22} {'theory':>9}  corrupt samples out: no bus CRC | behind it "
          f"(expected)")
    for r in doc["can"]["bus_crc"]:
        no, behind = r["reassembler"]["without_bus_crc"], r["reassembler"]["behind_bus_crc"]
        print(f"  {r['errors']:<14} {r['tried']:>9} {r['accepted']:>8} {r['rate']:>9.3g} "
              f"{_ci(r['ci95']):>22} {r['theory']:>9.3g}  {no['accepted']}/{no['tried']} = "
              f"{no['rate']:.3g} {_ci(no['ci95'])} | {behind['accepted']}/{behind['tried']} "
              f"{_ci(behind['ci95'])} ({behind['expected']:.2g})")
    print("  what protects a CAN sample: the bus CRC-15 (Hamming distance 6, 2^-15 for "
          "uniform patterns); behind it only structure: SYNC and STATUS lengths, STATUS's "
          "seq & 0xFF against the SYNC, the group count with every group present and full. "
          "These catch lost, repeated or misaddressed frames, not bits changed inside a DATA "
          "frame, nor a DATA frame of the next sample ahead of its STATUS (DATA has no seq).")
    p = doc["parsers"]
    print(f"\nparsers, damaged inputs: split_can_records {p['records']['tried']} (then "
          f"reassembled), parse_reply {p['replies']['tried']} (a reply returned encodes back "
          f"to its body), parse_command_packet {p['commands']['tried']} (never raises; a "
          f"command returned is the packet's body): "
          f"{sum(v['failures'] for v in p.values())} failures")
    for e in doc["parser_examples"]:
        print(f"  ! {e}")
    return 0


def _ci(ci: list[float]) -> str:
    return f"[{ci[0]:.2g}, {ci[1]:.2g}]"


def main_clock(args: argparse.Namespace) -> int:
    """Run ``skin bench clock``."""
    from skin.bench import clock as clock_bench
    from skin.bench import machine

    if args.seconds < 30:
        raise SkinError("--seconds must be at least 30 (10 s settle, then blocks to fit)")
    progress = Progress()
    t0 = time.perf_counter()
    doc = clock_bench.run(seconds=args.seconds, seed=args.seed, progress=progress.status)
    progress.done()
    doc = {"machine": machine(), **doc}
    if args.json:
        print(json.dumps(doc))
        return 0
    print(f"device -> host time: a board clock {doc['drift_ppm']:g} ppm fast, "
          f"{doc['seconds']:g} s at {doc['rate_hz']:g} Hz per scenario, errors after "
          f"{doc['settle_s']:g} s against the true sampling time plus the smallest delay "
          f"({doc['machine']['cpus']} cores, Python {doc['machine']['python']})")
    print(f"{'scenario':<14} {'method':<24} {'median ms':>9} {'p99 |e| ms':>10} "
          f"{'max |e| ms':>10} {'step sd ms':>10} {'drift ppm':>9} {'us/frame':>8}")
    base = {r["scenario"]: r for r in doc["rows"] if r["method"] == "arrival time"}
    for r in doc["rows"]:
        print(f"{r['scenario']:<14} {r['method']:<24} {r['median_error_ms']:>9.3f} "
              f"{r['p99_abs_error_ms']:>10.3f} {r['max_abs_error_ms']:>10.3f} "
              f"{r['step_jitter_ms']:>10.4f} {r['drift_error_ppm']:>9.2f} "
              f"{r['us_per_frame']:>8.2f}")
    print("p99 |error| against the arrival time, same run: " + "; ".join(
        f"{r['scenario']} {r['method']}: "
        f"{r['p99_abs_error_ms'] / max(base[r['scenario']]['p99_abs_error_ms'], 1e-9):.3f}x"
        for r in doc["rows"] if r["method"].startswith("ClockMap, 1")))
    print(f"wall time {time.perf_counter() - t0:.2f} s")
    return 0
