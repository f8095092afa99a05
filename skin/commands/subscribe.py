"""``skin subscribe zenoh://[PREFIX]``: print or record what a skin publishes over Zenoh.

Subscribes to ``PREFIX/ROBOT/{temperature,contacts,health}`` (every robot unless ``robot=``
says which) and prints a line per contact and per health message; ``--record FILE.jsonl``
keeps every message, decoded (`skin.stream.publish.decode_payload`; temperatures as nested
lists), one JSON object per line, flushed at once. Query options as for publishing:
``listen=``/``connect=`` endpoints (comma separated), ``mode=``. It stops after ``--duration``
seconds, after ``--idle`` seconds without a message once one came, or at Ctrl-C.
"""

from __future__ import annotations

import argparse
import json
import queue
import sys
import time
from typing import Any
from urllib.parse import parse_qs, urlsplit

from skin.errors import SkinError


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``skin subscribe``."""
    p = sub.add_parser("subscribe", help="print or record what a skin publishes over Zenoh",
                       description=__doc__)
    p.add_argument("url", help="zenoh://[PREFIX][?robot=NAME&listen=...&connect=...&mode=...]")
    p.add_argument("--record", metavar="FILE.jsonl", help="keep every message, decoded")
    p.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    p.add_argument("--idle", type=float, default=None,
                   help="stop after this many seconds without a message, once one came")
    p.add_argument("--json", action="store_true",
                   help="print one JSON summary on stdout at the end and nothing else")
    p.set_defaults(func=main)


def _record(msg: dict[str, Any], key: str) -> dict[str, Any]:
    out = {"key": key, **msg}
    if "temperature" in out:
        out["temperature"] = [[None if v != v else v for v in row]
                              for row in out["temperature"].tolist()]
    return out


def main(args: argparse.Namespace) -> int:
    """Subscribe (see the module docstring)."""
    from skin.stream.publish import decode_payload
    from skin.stream.publish_zenoh import TOPICS, open_session
    from skin.stream.sinks import contact_line

    parts = urlsplit(args.url)
    if parts.scheme != "zenoh":
        raise SkinError(f"{args.url}: skin subscribe reads zenoh:// URLs")
    query = {k: v[-1] for k, v in parse_qs(parts.query).items()}
    unknown = set(query) - {"robot", "listen", "connect", "mode"}
    if unknown:
        raise SkinError(f"{args.url}: unknown option(s) {sorted(unknown)}")
    prefix = (parts.netloc + parts.path).strip("/") or "thermoskin"
    robot = query.get("robot", "*")

    def endpoints(key: str) -> list[str]:
        return [e for e in query.get(key, "").split(",") if e]

    session = open_session(endpoints("listen"), endpoints("connect"), query.get("mode"))
    inbox: queue.SimpleQueue = queue.SimpleQueue()
    subs = [session.declare_subscriber(
        f"{prefix}/{robot}/{topic}",
        lambda s: inbox.put((str(s.key_expr), s.payload.to_bytes(), time.time())))
        for topic in TOPICS]
    out = open(args.record, "w", encoding="utf-8") if args.record else None
    counts: dict[str, int] = dict.fromkeys(TOPICS, 0)
    samples = 0
    errors = 0
    latency: list[float] = []
    say = (lambda line: None) if args.json else (lambda line: print(line, flush=True))
    say(f"subscribed to {prefix}/{robot}/{{{','.join(TOPICS)}}}")
    print("ready", file=sys.stderr, flush=True)  # for scripts waiting on the subscription
    def take(key: str, data: bytes, arrived: float) -> None:
        """Count, print and record one message."""
        nonlocal samples, errors
        topic = key.rsplit("/", 1)[-1]
        try:
            msg = decode_payload(data)
        except ValueError as exc:
            errors += 1
            say(f"{key}: {exc}")
            return
        counts[topic] = counts.get(topic, 0) + 1
        if topic == "temperature":
            samples += msg["samples"]
            if msg["host_time"]:
                latency.append(arrived - msg["host_time"][-1])
        elif topic == "contacts":
            say(f"{msg['robot']}: {contact_line(msg)}")
        elif topic == "health":
            say(f"{msg['robot']}: health: frames {msg['frames']}  gaps {msg['gaps']}  "
                f"late {msg.get('late', 0)}  "
                f"contacts {msg['contacts']}  in contact {msg['in_contact']}")
        if out is not None:
            out.write(json.dumps(_record(msg, key)) + "\n")
            out.flush()

    started = last = time.monotonic()
    try:
        while True:
            now = time.monotonic()
            if args.duration is not None and now - started >= args.duration:
                break
            if args.idle is not None and sum(counts.values()) and now - last >= args.idle:
                break
            try:
                key, data, arrived = inbox.get(timeout=0.05)
            except queue.Empty:
                continue
            last = time.monotonic()
            take(key, data, arrived)
    except KeyboardInterrupt:
        pass
    finally:
        for s in subs:
            s.undeclare()
        # what arrived before the subscribers closed is kept, not dropped with the inbox
        while True:
            try:
                take(*inbox.get_nowait())
            except queue.Empty:
                break
        session.close()
        if out is not None:
            out.close()
    latency.sort()
    summary = {"url": args.url, "messages": counts, "samples": samples, "errors": errors,
               "p50_latency_ms": round(latency[len(latency) // 2] * 1e3, 3) if latency else None,
               "p99_latency_ms": round(latency[int(0.99 * (len(latency) - 1))] * 1e3, 3)
               if latency else None}
    if args.json:
        print(json.dumps(summary))
    else:
        say(f"received {counts} ({samples} samples, {errors} undecodable)")
    return 0
