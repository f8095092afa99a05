"""Fuzzing the protocol decoders: valid streams, damaged at random, fed in random chunks.

Two halves share this module: the tools a property test (``tests/test_fuzz_decoders.py``,
hypothesis) and the campaign (`run`, ``skin bench fuzz``, numpy's RNG, reproducible from a
seed) both use.

**Damage with origin tracking.** `damage_bytes` applies `Damage` steps (bit flips, overwrites,
insertions, deletions, truncations, spliced copies) to a serial stream and `damage_frames`
(drops, duplicates, swaps, foreign frames, bit flips, length changes) to a list of CAN frames;
both also return, per byte or frame, where it came from in the clean stream (-1: changed or
new). From that an oracle knows which packets (samples) came through intact and so *must* be
decoded: a serial packet whose bytes and whose preceding 0x00 are untouched (the decoder
resynchronises at the delimiter after any damage), a CAN sample whose SYNC, DATA and STATUS
frames reach its node unchanged and with nothing of that node's in between.

**Verdicts.** `check_serial` and `check_can` feed the damaged stream in random chunk sizes and
return a `Verdict`: items out, intact items missed (resync failures, must be 0), items out that
were never sent (corrupt accepted), the exception that escaped (must be None: decoders of bus
data never raise) and the statistics that disagree with what came out.

**Rates.** For an error pattern drawn uniformly, CRC-16/CCITT-FALSE lets 2**-16 through; no
pattern of 1-3 bits (Hamming distance 4 at these lengths) and no burst of 16 bits or less. CAN
has no CRC of ours: the bus's CRC-15 (Hamming distance 6, 2**-15 for uniform patterns) drops a
damaged frame before the host sees it, and what protects a sample beyond that are the
reassembler's checks: SYNC and STATUS lengths, STATUS's ``seq & 0xFF`` against the open SYNC,
the group count and every group present, 8 bytes in all but the last group. They catch frames
lost, repeated or moved to another identifier, not bits changed inside a DATA frame, nor a DATA
frame of the next sample put before the STATUS of its own (DATA carries no seq; a node sends
from one transmit buffer, so its frames stay in order on a sound bus). The campaign
measures both: what passes the bus CRC (computed exactly on each frame's identifier, data and
CRC bits, `can_crc15_syndromes`; stuffing and DLC errors are not modelled) and what the
reassembler accepts with and without it.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from skin._optional import require
from skin.bench.intervals import clopper_pearson
from skin.drivers.protocol import (
    DUPLICATE_WINDOW,
    MAX_PACKET,
    MAX_TAXELS,
    Ack,
    CanFrame,
    CanReassembler,
    CanType,
    Command,
    ErrorReply,
    Identity,
    LinkStats,
    MsgType,
    Reply,
    SelftestResult,
    StreamDecoder,
    can_record,
    can_reply_frames,
    can_sample_frames,
    cobs_decode,
    crc16,
    encode_sample,
    parse_command_packet,
    parse_reply,
    sample_body,
    split_can_records,
)
from skin.errors import ProtocolError
from skin.frame import Frame

#: Kinds of damage to a serial byte stream.
BYTE_DAMAGE = ("flip", "overwrite", "insert", "delete", "truncate", "splice")
#: Kinds of damage to a list of CAN frames.
FRAME_DAMAGE = ("drop", "duplicate", "swap", "insert", "flip", "resize")
#: CRC-15 of CAN (x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1), initial value 0.
CAN_CRC15_POLY = 0x4599


@dataclass(frozen=True)
class Damage:
    """One step of damage; positions are taken modulo the current length.

    Bytes (`damage_bytes`): ``flip`` bit ``size % 8`` of byte ``at``; ``overwrite`` from
    ``at`` with ``data``; ``insert`` ``data`` before ``at``; ``delete`` ``size`` bytes from
    ``at``; ``truncate`` from ``at`` to the next 0x00 (a packet cut short); ``splice`` a copy
    of ``size`` bytes from ``at`` before ``to`` (a repeated stretch).

    CAN frames (`damage_frames`): ``drop`` frame ``at``; ``duplicate`` it (received twice);
    ``swap`` it with the next; ``insert`` a frame with identifier ``to & 0x7FF`` and data
    ``data[:8]`` before ``at``; ``flip`` bit ``size`` of frame ``at``'s identifier and data
    (modulo their bits); ``resize`` frame ``at`` to ``size % 9`` bytes (cut, or padded with
    ``data``).
    """

    kind: str
    at: int
    size: int = 1
    data: bytes = b""
    to: int = 0


def damage_bytes(stream: bytes, damages: Sequence[Damage]) -> tuple[bytes, list[int]]:
    """Apply byte damage to a serial stream.

    Returns
    -------
    bytes, list of int
        The damaged stream, and per byte its index in ``stream`` (-1: changed or inserted).
    """
    data = bytearray(stream)
    origin = list(range(len(stream)))
    for d in damages:
        n = len(data)
        if d.kind == "insert":
            at = d.at % (n + 1)
            data[at:at] = d.data
            origin[at:at] = [-1] * len(d.data)
        elif n == 0:
            continue
        elif d.kind == "flip":
            at = d.at % n
            data[at] ^= 1 << (d.size % 8)
            origin[at] = -1
        elif d.kind == "overwrite":
            at = d.at % n
            part = d.data[: n - at]
            data[at : at + len(part)] = part
            origin[at : at + len(part)] = [-1] * len(part)
        elif d.kind == "delete":
            at = d.at % n
            del data[at : at + d.size], origin[at : at + d.size]
        elif d.kind == "truncate":
            at = d.at % n
            end = data.find(0, at)
            end = n if end < 0 else end
            del data[at:end], origin[at:end]
        elif d.kind == "splice":
            at = d.at % n
            part, where = data[at : at + d.size], origin[at : at + d.size]
            to = d.to % (n + 1)
            data[to:to] = part
            origin[to:to] = where
        else:
            raise ValueError(f"unknown byte damage {d.kind!r}")
    return bytes(data), origin


def damage_frames(frames: Sequence[CanFrame],
                  damages: Sequence[Damage]) -> tuple[list[CanFrame], list[int]]:
    """Apply frame damage to a list of CAN frames.

    Returns
    -------
    list of (int, bytes), list of int
        The damaged frames, and per frame its index in ``frames`` (-1: changed or inserted).
    """
    out = list(frames)
    origin = list(range(len(frames)))
    for d in damages:
        n = len(out)
        if d.kind == "insert":
            at = d.at % (n + 1)
            out.insert(at, (d.to & 0x7FF, bytes(d.data[:8])))
            origin.insert(at, -1)
        elif n == 0:
            continue
        elif d.kind == "drop":
            at = d.at % n
            del out[at], origin[at]
        elif d.kind == "duplicate":
            at = d.at % n
            out.insert(at, out[at])
            origin.insert(at, origin[at])
        elif d.kind == "swap":
            at = d.at % n
            if at + 1 < n:
                out[at], out[at + 1] = out[at + 1], out[at]
                origin[at], origin[at + 1] = origin[at + 1], origin[at]
        elif d.kind == "flip":
            at = d.at % n
            ident, payload = out[at]
            bit = d.size % (11 + 8 * len(payload))
            if bit < 11:
                ident ^= 1 << bit
            else:
                raw = bytearray(payload)
                raw[(bit - 11) // 8] ^= 1 << ((bit - 11) % 8)
                payload = bytes(raw)
            out[at] = (ident, payload)
            origin[at] = -1
        elif d.kind == "resize":
            at = d.at % n
            ident, payload = out[at]
            size = d.size % 9
            new = (payload + bytes(d.data) + bytes(8))[:size]
            if new != payload:
                out[at] = (ident, new)
                origin[at] = -1
        else:
            raise ValueError(f"unknown frame damage {d.kind!r}")
    return out, origin


# ---- clean streams ----

@dataclass(frozen=True)
class SentSample:
    """What a sample carried, to compare decoded frames with."""

    board: int
    seq: int
    time_us: int
    counts: np.ndarray
    status: np.ndarray
    duty: np.ndarray
    ambient: float
    flags: int

    def matches(self, frame: Frame, duty_known_only: bool = False) -> bool:
        """Tell whether ``frame`` carries exactly this sample.

        ``duty_known_only``: a duty of 0 also matches (CAN: not received yet).
        """
        duty_ok = (np.array_equal(frame.duty, self.duty) if not duty_known_only else
                   frame.duty.shape == self.duty.shape
                   and bool(np.all((frame.duty == self.duty) | (frame.duty == 0))))
        same_ambient = (frame.ambient == self.ambient
                        or (math.isnan(frame.ambient) and math.isnan(self.ambient)))
        return (frame.board == self.board and frame.seq == self.seq
                and frame.device_time == self.time_us * 1e-6 and frame.flags == self.flags
                and same_ambient and np.array_equal(frame.counts, self.counts)
                and frame.status is not None and np.array_equal(frame.status, self.status)
                and duty_ok)


def random_sample(rng: np.random.Generator, board: int, seq: int, n: int,
                  duty: np.ndarray | None = None) -> SentSample:
    """Draw one sample of ``n`` taxels (any counts, status bits, ambient and flags)."""
    raw = int(rng.integers(-4000, 8000))
    ambient = math.nan if rng.random() < 0.1 else raw / 100.0
    return SentSample(board, seq % (1 << 32), int(seq * 5000) % (1 << 32),
                      rng.integers(0, 4096, n).astype(np.uint16),
                      rng.integers(0, 16, n).astype(np.uint8),
                      rng.integers(0, 256, n).astype(np.uint8) if duty is None else duty,
                      ambient, int(rng.integers(0, 1 << 16)))


def encode(sample: SentSample) -> bytes:
    """Return the serial packet of a `SentSample`."""
    return encode_sample(sample.seq, sample.time_us, sample.counts, sample.ambient, sample.duty,
                         sample.flags, sample.status)


def random_reply(rng: np.random.Generator, token: int) -> Reply:
    """Draw one reply of each kind in turn (ACK, ERROR, IDENTITY, SELFTEST_RESULT)."""
    u8, u16 = (lambda: int(rng.integers(0, 256))), (lambda: int(rng.integers(0, 1 << 16)))
    kind = int(rng.integers(0, 4))
    if kind == 0:
        return Ack(token, u8())
    if kind == 1:
        return ErrorReply(token, u8(), u8(), u16())
    if kind == 2:
        return Identity(token, u8(), u8(), u8(), u8(), u8(), u8(), u8(), u16(), u8(), u8(),
                        u16(), u16(), int(rng.integers(0, 1 << 32)), u16())
    n = int(rng.integers(0, 20))
    return SelftestResult(token, tuple(int(v) for v in rng.integers(-0x8000, 0x8000, n)),
                          tuple(int(v) for v in rng.integers(0, 1 << 16, n)))


@dataclass
class SerialCase:
    """A clean serial stream: a 0x00, then packets; ``bounds[i]`` = (delimiter before, after)."""

    stream: bytes
    items: list[SentSample | Reply]
    bounds: list[tuple[int, int]]


def serial_case(rng: np.random.Generator, packets: int = 8, board: int = 0,
                sizes: Sequence[int] = (0, 1, 4, 16, 64, MAX_TAXELS)) -> SerialCase:
    """Draw a clean stream of samples (consecutive seq) with a reply now and then."""
    seq = int(rng.integers(0, 1 << 32)) if rng.random() < 0.2 else int(rng.integers(0, 1000))
    items: list[SentSample | Reply] = []
    for k in range(packets):
        if rng.random() < 0.2:
            items.append(random_reply(rng, k + 1))
        else:
            items.append(random_sample(rng, board, seq, int(rng.choice(sizes))))
            seq += 1
    chunks = [b"\x00"]
    bounds = []
    pos = 0
    for item in items:
        packet = encode(item) if isinstance(item, SentSample) else item.encode()
        chunks.append(packet)
        bounds.append((pos, pos + len(packet)))
        pos += len(packet)
    return SerialCase(b"".join(chunks), items, bounds)


@dataclass
class CanCase:
    """A clean CAN stream of several nodes: frames, and per frame what it belongs to.

    ``owner[i]`` is the index in ``items`` of the sample or reply frame i is part of.
    """

    frames: list[CanFrame]
    items: list[tuple[int, SentSample | Reply]]
    owner: list[int]


def can_case(rng: np.random.Generator, samples: int = 3, nodes: int = 2,
             sizes: Sequence[int] = (1, 3, 4, 8, 13, 64, 128)) -> CanCase:
    """Draw ``samples`` samples (consecutive seq) per node, a reply now and then.

    The nodes' frames are interleaved as on a shared bus: each node's stay in order.
    """
    ids = [int(v) for v in rng.choice(7, size=nodes, replace=False)]
    items: list[tuple[int, SentSample | Reply]] = []
    per_node: list[list[tuple[CanFrame, int]]] = []
    for node in ids:
        n = int(rng.choice(sizes))
        duty = rng.integers(0, 256, n).astype(np.uint8)  # duties change slowly: fixed here
        seq = int(rng.integers(0, 1 << 32))
        frames: list[tuple[CanFrame, int]] = []
        for _ in range(samples):
            if rng.random() < 0.2:
                reply = random_reply(rng, int(rng.integers(1, 256)))
                items.append((node, reply))
                frames += [(f, len(items) - 1) for f in can_reply_frames(node, reply.body())]
            s = random_sample(rng, node, seq, n, duty)
            seq += 1
            items.append((node, s))
            frames += [(f, len(items) - 1) for f in can_sample_frames(
                node, s.seq, s.time_us, s.counts, s.ambient, s.duty, s.flags, s.status)]
        per_node.append(frames)
    order = np.concatenate([np.full(len(f), k) for k, f in enumerate(per_node)])
    rng.shuffle(order)
    cursor = [0] * len(per_node)
    out, owner = [], []
    for k in order:
        frame, item = per_node[k][cursor[k]]
        cursor[k] += 1
        out.append(frame)
        owner.append(item)
    return CanCase(out, items, owner)


# ---- verdicts ----

@dataclass
class Verdict:
    """What a decoder made of one damaged stream.

    Attributes
    ----------
    sent : int
        Samples and replies in the clean stream.
    out : int
        Samples and replies decoded.
    intact : int
        Items sent that came through undamaged (and so must be decoded).
    missed : int
        Intact items that were not decoded: resync failures, must be 0.
    corrupt : int
        Items decoded that were never sent: corrupt frames accepted.
    unexplained : int
        Corrupt items no damage accounts for (must be 0). Serial: more corrupt items than
        packets in the damaged stream that pass the CRC and are not one of the packets sent.
        CAN: a corrupt item from a node none of whose frames was changed, inserted or put out
        of order (DATA frames carry no seq: one moved into the previous sample goes unseen).
    crash : str or None
        The exception that escaped the decoder, if one did (must be None).
    inconsistent : list of str
        Statistics that disagree with what came out (must be empty).
    stats : LinkStats
        The decoder's statistics.
    """

    sent: int = 0
    out: int = 0
    intact: int = 0
    missed: int = 0
    corrupt: int = 0
    unexplained: int = 0
    crash: str | None = None
    inconsistent: list[str] = field(default_factory=list)
    stats: LinkStats = field(default_factory=LinkStats)


def chunk_sizes(rng: np.random.Generator, total: int) -> list[int]:
    """Random chunk sizes (log-uniform, 1 - 4096 bytes) that add up to ``total``."""
    sizes = []
    while total > 0:
        k = min(total, int(np.exp(rng.uniform(0, np.log(4096)))))
        sizes.append(k)
        total -= k
    return sizes


def sequence_stats(seqs: Sequence[int], window: int = DUPLICATE_WINDOW) -> tuple[int, int]:
    """Lost samples and duplicates of one board's seq sequence, as `LinkStats` defines them."""
    lost = dups = 0
    newest = None
    for s in seqs:
        if newest is None:
            newest = s
            continue
        behind = (newest - s) % (1 << 32)
        if behind < window:  # equal to the newest, or a little behind it
            dups += 1
        else:
            ahead = (s - newest) % (1 << 32)
            if ahead < 1 << 31:
                lost += ahead - 1
            newest = s
    return lost, dups


def _intact_serial(case: SerialCase, origin: list[int]) -> Counter[int]:
    """How many times each packet appears undamaged, its preceding 0x00 included."""
    at = np.asarray(origin)
    found: Counter[int] = Counter()
    for i, (start, end) in enumerate(case.bounds):
        want = np.arange(start, end + 1)
        for j in np.flatnonzero(at == start):
            if np.array_equal(at[j : j + want.size], want):
                found[i] += 1
    return found


def check_serial(case: SerialCase, damaged: bytes, origin: list[int],
                 chunks: Sequence[int]) -> Verdict:
    """Decode a damaged serial stream in ``chunks`` and judge the result (see `Verdict`)."""
    v = Verdict(sent=len(case.items))
    dec = StreamDecoder(board=0)
    v.stats = dec.stats
    frames: list[Frame] = []
    pos = 0
    try:
        for size in chunks:
            frames += dec.feed(damaged[pos : pos + size])
            pos += size
        frames += dec.flush()  # a sample held for a FORCE (an IDENTITY may announce one)
    except Exception as exc:  # the finding, not an error of the campaign
        v.crash = f"{type(exc).__name__}: {exc}"
        return v
    replies = list(dec.replies)
    v.out = len(frames) + len(replies)
    # match what came out with what was sent
    samples = {item.seq: i for i, item in enumerate(case.items) if isinstance(item, SentSample)}
    sent_replies: dict[Reply, list[int]] = {}
    for i, item in enumerate(case.items):
        if not isinstance(item, SentSample):
            sent_replies.setdefault(item, []).append(i)
    got: Counter[int] = Counter()
    for f in frames:
        i = samples.get(f.seq)
        if i is not None and case.items[i].matches(f):  # type: ignore[union-attr]
            got[i] += 1
        else:
            v.corrupt += 1
    for r in replies:
        if r in sent_replies:
            for i in sent_replies[r]:
                got[i] += 1
        else:
            v.corrupt += 1
    intact = _intact_serial(case, origin)
    v.intact = sum(intact.values())
    v.missed = sum(max(0, k - got[i]) for i, k in intact.items())
    v.unexplained = max(0, v.corrupt - _novel_packets(case, damaged))
    # statistics against what came out
    s = dec.stats
    bad = v.inconsistent
    if s.frames != len(frames) or s.replies != len(replies):
        bad.append(f"frames/replies {s.frames}/{s.replies} != {len(frames)}/{len(replies)} out")
    if s.bytes != len(damaged):
        bad.append(f"bytes {s.bytes} != {len(damaged)}")
    segments = damaged.split(b"\x00")
    packets = sum(1 for p in segments[:-1] if p)
    handled = s.frames + s.replies + s.crc_errors + s.malformed + s.forces + s.force_orphans
    long = any(len(p) > 2 * MAX_PACKET for p in segments)  # may be dropped unterminated
    if handled > packets or (not long and handled != packets):
        bad.append(f"{handled} packets counted, {packets} delimited")
    if s.resyncs < s.crc_errors + s.malformed or (
            not long and s.resyncs != s.crc_errors + s.malformed):
        bad.append(f"resyncs {s.resyncs} vs crc {s.crc_errors} + malformed {s.malformed}")
    lost, dups = sequence_stats([f.seq for f in frames])
    if (s.lost_samples, s.duplicates) != (lost, dups):
        bad.append(f"lost/duplicates {s.lost_samples}/{s.duplicates} != {lost}/{dups}")
    return v


def _valid_bodies(stream: bytes) -> list[bytes]:
    """Return the bodies of the packets in ``stream`` that pass the CRC."""
    cobs = require("cobs.cobs", "the serial wire protocol")
    out = []
    for packet in stream.split(b"\x00"):
        try:
            raw = cobs.decode(packet)
        except cobs.DecodeError:
            continue
        if len(raw) >= 4 and crc16(raw[:-2]) == int.from_bytes(raw[-2:], "little"):
            out.append(raw[:-2])
    return out


def _novel_packets(case: SerialCase, damaged: bytes) -> int:
    """Count the packets of ``damaged`` that pass the CRC and were never sent."""
    sent = set(_valid_bodies(case.stream))
    return sum(body not in sent for body in _valid_bodies(damaged))


def _node_of(ident: int) -> int:
    return ident >> 5 & 7


def _intact_can(case: CanCase, frames: list[CanFrame], origin: list[int]) -> Counter[int]:
    """How many times each sample reaches its node undamaged (SYNC, DATA, STATUS)."""
    state = (CanType.SYNC, CanType.DATA, CanType.STATUS)
    # per node, the damaged frames that change a sample's state, with their origin
    lanes: dict[int, list[int]] = {}
    for (ident, _), o in zip(frames, origin, strict=True):
        if 0 <= ident < 0x800 and ident >> 8 in state:
            lanes.setdefault(_node_of(ident), []).append(o)
    clean: dict[int, list[int]] = {}
    for i, ((ident, _), item) in enumerate(zip(case.frames, case.owner, strict=True)):
        if ident >> 8 in state and isinstance(case.items[item][1], SentSample):
            clean.setdefault(item, []).append(i)
    found: Counter[int] = Counter()
    for item, want in clean.items():
        lane = lanes.get(case.items[item][0], [])
        for j, o in enumerate(lane):
            if o == want[0] and lane[j : j + len(want)] == want:
                found[item] += 1
    return found


def check_can(case: CanCase, frames: list[CanFrame], origin: list[int] | None,
              rng: np.random.Generator | None = None) -> Verdict:
    """Reassemble damaged CAN frames (in random batches) and judge the result.

    ``origin`` None: no intact-sample check (only corrupt acceptance, crashes and statistics).
    """
    v = Verdict(sent=sum(isinstance(item, SentSample) for _, item in case.items))
    can = CanReassembler()
    v.stats = can.stats
    out: list[Frame] = []
    try:
        pos = 0
        while pos < len(frames):
            k = len(frames) if rng is None else int(rng.integers(1, 40))
            out += can.feed(frames[pos : pos + k])
            pos += k
    except Exception as exc:  # the finding, not an error of the campaign
        v.crash = f"{type(exc).__name__}: {exc}"
        return v
    v.out = len(out)
    sent = {(item.board, item.seq): i for i, (_, item) in enumerate(case.items)
            if isinstance(item, SentSample)}
    got: Counter[int] = Counter()
    bad_nodes = []
    for f in out:
        i = sent.get((f.board, f.seq))
        if i is not None and case.items[i][1].matches(f, duty_known_only=True):  # type: ignore
            got[i] += 1
            continue
        if i is not None and _same_but_duty(case.items[i][1], f):  # type: ignore[arg-type]
            got[i] += 1  # its own frames were intact; a damaged DUTY frame came before
        bad_nodes.append(f.board)
    sent_replies = {(node, r) for node, r in case.items if not isinstance(r, SentSample)}
    bad_nodes += [node for node, r in can.replies if (node, r) not in sent_replies]
    v.corrupt = len(bad_nodes)
    if origin is not None:
        changed = set()
        newest: dict[int, int] = {}
        for (ident, _), o in zip(frames, origin, strict=True):
            node = _node_of(ident)
            if o < 0 or o < newest.get(node, -1):
                changed.add(node)
            newest[node] = max(o, newest.get(node, -1))
        v.unexplained = sum(node not in changed for node in bad_nodes)
    if origin is not None:
        intact = _intact_can(case, frames, origin)
        v.intact = sum(intact.values())
        v.missed = sum(max(0, k - got[i]) for i, k in intact.items())
    s = can.stats
    bad = v.inconsistent
    if s.frames != len(out) or s.replies != len(can.replies):
        bad.append(f"frames/replies {s.frames}/{s.replies} != {len(out)}/{len(can.replies)}")
    syncs = sum(1 for ident, data in frames
                if 0 <= ident < 0x800 and ident >> 8 == CanType.SYNC and ident & 31 == 0
                and len(data) == 8)
    still_open = sum(node.seq is not None for node in can._nodes.values())
    if s.frames + s.missing + still_open != syncs:
        bad.append(f"frames {s.frames} + missing {s.missing} + open {still_open} "
                   f"!= {syncs} SYNCs")
    lost = dups = genuine_lost = 0
    genuine = [f for f in out if (f.board, f.seq) in sent]  # seqs that were really sent
    for node in {f.board for f in out}:
        lo, du = sequence_stats([f.seq for f in out if f.board == node])
        lost, dups = lost + lo, dups + du
        genuine_lost += sequence_stats([f.seq for f in genuine if f.board == node])[0]
    # a gap counts once the next sample confirms it (a damaged SYNC seq would count up to
    # 2^31): at most the gaps between all the samples out, at least those between the
    # genuine ones less the samples dropped incomplete, those that came out damaged (a gap
    # between genuine ones, not lost) and the gaps still waiting
    waiting = sum(n.pending[2] for n in can._nodes.values() if n.pending is not None)
    floor = genuine_lost - s.missing - v.corrupt - waiting
    # a damaged seq that is taken back also moves what counts as a repeat: by one at most
    if abs(s.duplicates - dups) > v.corrupt or not floor <= s.lost_samples <= lost:
        bad.append(f"lost/duplicates {s.lost_samples}/{s.duplicates}: gaps {lost} "
                   f"(between genuine samples {genuine_lost}, missing {s.missing}, waiting "
                   f"{waiting}), {dups} repeats")
    return v


def _same_but_duty(sample: SentSample, frame: Frame) -> bool:
    return sample.matches(Frame(frame.seq, frame.device_time, frame.host_time, frame.counts,
                                frame.ambient, sample.duty, frame.flags, frame.board,
                                frame.status))


def check_records(raw: bytes) -> str | None:
    """Split damaged CAN records and reassemble them; return the exception that escaped.

    `split_can_records` may raise `ProtocolError` (documented); nothing else may escape, and
    the reassembler takes whatever the records hold.
    """
    try:
        try:
            records = split_can_records(raw)
        except ProtocolError:
            return None
        CanReassembler().feed((ident, data) for ident, data, _ in records)
    except Exception as exc:  # the finding
        return f"raised {type(exc).__name__}: {exc}"
    return None


def check_reply_body(body: bytes) -> str | None:
    """`parse_reply` raises ValueError only, and what it returns encodes back to ``body``."""
    try:
        reply = parse_reply(body)
    except ValueError:
        return None
    except Exception as exc:  # the finding
        return f"raised {type(exc).__name__}: {exc}"
    if reply.body() != body:
        return f"{reply!r} encodes to {reply.body().hex()}, not {body.hex()}"
    return None


def check_command_packet(packet: bytes, n_taxels: int = 64,
                         max_rate_hz: int = 400) -> str | None:
    """`parse_command_packet` never raises, and a command it returns is the packet's body."""
    try:
        result = parse_command_packet(packet, n_taxels, max_rate_hz)
    except Exception as exc:  # the finding
        return f"raised {type(exc).__name__}: {exc}"
    if isinstance(result, Command) and result.body() != cobs_decode(packet)[:-2]:
        return f"{result!r} is not the body of the packet {packet.hex()}"
    if not isinstance(result, Command | ErrorReply):
        return f"returned {result!r}"
    return None


# ---- the campaign ----

def _draw_byte_damage(rng: np.random.Generator, length: int) -> Damage:
    kind = BYTE_DAMAGE[int(rng.integers(len(BYTE_DAMAGE)))]
    at = int(rng.integers(0, max(1, length)))
    if kind in ("overwrite", "insert"):
        big = rng.random() < 0.1  # garbage: long enough to overflow the buffer at times
        size = int(rng.integers(1, 3 * MAX_PACKET if big else 16))
        data = rng.integers(0, 256, size, dtype=np.uint8)
        if rng.random() < 0.5:  # runs without 0x00 (no delimiter to resync on)
            data[data == 0] = 0x55
        return Damage(kind, at, size, data.tobytes())
    if kind == "splice":
        return Damage(kind, at, int(rng.integers(1, 600)), to=int(rng.integers(0, length + 1)))
    return Damage(kind, at, int(rng.integers(1, 40)) if kind == "delete" else
                  int(rng.integers(0, 8)))


def _draw_frame_damage(rng: np.random.Generator, length: int) -> Damage:
    kind = FRAME_DAMAGE[int(rng.integers(len(FRAME_DAMAGE)))]
    at = int(rng.integers(0, max(1, length)))
    return Damage(kind, at, int(rng.integers(0, 75)),
                  rng.integers(0, 256, 8, dtype=np.uint8).tobytes(), int(rng.integers(0, 0x800)))


@dataclass
class _Tally:
    """Sums of verdicts over a campaign part."""

    trials: int = 0
    sent: int = 0
    out: int = 0
    intact: int = 0
    missed: int = 0
    corrupt: int = 0
    unexplained: int = 0
    crashes: int = 0
    inconsistent: int = 0
    examples: list[str] = field(default_factory=list)
    stats: Counter[str] = field(default_factory=Counter)

    def add(self, v: Verdict, trial: int) -> None:
        self.trials += 1
        self.sent += v.sent
        self.out += v.out
        self.intact += v.intact
        self.missed += v.missed
        self.corrupt += v.corrupt
        self.unexplained += v.unexplained
        self.crashes += v.crash is not None
        self.inconsistent += bool(v.inconsistent)
        for problem in ([v.crash] if v.crash else []) + v.inconsistent + (
                [f"{v.missed} intact items missed"] if v.missed else []) + (
                [f"{v.unexplained} corrupt items unexplained"] if v.unexplained else []):
            if len(self.examples) < 5:
                self.examples.append(f"trial {trial}: {problem}")
        for key, value in vars(v.stats).items():
            self.stats[key] += value

    def as_dict(self) -> dict:
        out = {k: getattr(self, k) for k in ("trials", "sent", "out", "intact", "missed",
                                             "corrupt", "unexplained", "crashes",
                                             "inconsistent", "examples")}
        out["stats"] = dict(self.stats)
        return out


def _rate(name: str, accepted: int, tried: int, theory: float | None, note: str) -> dict:
    lo, hi = clopper_pearson(accepted, tried)
    return {"errors": name, "tried": tried, "accepted": accepted,
            "rate": accepted / tried if tried else None, "ci95": [lo, hi], "theory": theory,
            "theory_in_ci": None if theory is None else lo <= theory <= hi, "note": note}


def serial_crc_rates(rng: np.random.Generator, packets: int, taxels: int = 16,
                     tick: Callable[[int], None] | None = None) -> list[dict]:
    """Count the damaged SAMPLE packets `StreamDecoder` accepts, per kind of error pattern.

    The kinds: 1-3 bit flips anywhere; a burst of at most 16 bits in the body; uniform (every
    byte random but version, type and n, so the packet still parses as a sample).
    """
    clean = rng.integers(0, 4096, taxels)
    body = bytearray(sample_body(7, 35000, clean, 21.5, np.full(taxels, 100), 0x200))
    raw = np.frombuffer(bytes(body) + crc16(bytes(body)).to_bytes(2, "little"), np.uint8)
    size = raw.size
    keep = np.zeros(size, bool)
    keep[[0, 1, 10, 11]] = True  # version, type, n: the packet still parses as a sample
    rows = []
    encode = require("cobs.cobs", "the serial wire protocol").encode
    per_class = [packets // 8, packets // 8, packets - 2 * (packets // 8)]
    for cls, total in zip(("1-3 bits", "burst <= 16 bits", "uniform"), per_class, strict=True):
        accepted = tried = 0
        dec = StreamDecoder()
        batch = 1 << 14
        for start in range(0, total, batch):
            m = min(batch, total - start)
            pkt = np.tile(raw, (m, 1))
            if cls == "1-3 bits":
                bits = rng.integers(0, 8 * size, (m, 3))
                w = rng.integers(1, 4, m)
                for c in range(3):
                    on = w > c
                    bit = bits[on, c]
                    pkt[np.flatnonzero(on), bit // 8] ^= (1 << (bit % 8)).astype(np.uint8)
            elif cls == "burst <= 16 bits":
                # within the body, bits numbered in the CRC's order (each byte MSB first)
                length = rng.integers(1, 17, m)
                first = rng.integers(0, 8 * (size - 2) - length + 1)
                inner = rng.integers(0, 1 << 16, m) & ((1 << np.maximum(length - 2, 0)) - 1)
                pattern = np.where(length == 1, 1, (1 << (length - 1)) | (inner << 1) | 1)
                for k in range(16):  # bit k of the pattern lands on stream bit first + k
                    on = (k < length) & ((pattern >> k) & 1).astype(bool)
                    bit = first[on] + k
                    pkt[np.flatnonzero(on), bit // 8] ^= (0x80 >> (bit % 8)).astype(np.uint8)
            else:
                noise = rng.integers(0, 256, (m, size), dtype=np.uint8)
                pkt = np.where(keep, pkt, noise)
            changed = (pkt != raw).any(axis=1)
            stream = b"\x00".join(encode(p.tobytes()) for p in pkt[changed]) + b"\x00"
            accepted += len(dec.feed(stream))
            tried += int(changed.sum())
            if tick:
                tick(m)
        theory = 0.0 if cls != "uniform" else 2.0**-16
        note = {"1-3 bits": "CRC-16/CCITT: Hamming distance 4 below 32751 bits, none pass",
                "burst <= 16 bits": "every burst of 16 bits or less is detected",
                "uniform": "an error pattern drawn uniformly passes with probability 2^-16"}[cls]
        rows.append(_rate(cls, accepted, tried, theory, note))
    return rows


def can_crc15(bits: Sequence[int]) -> int:
    """CRC-15 of CAN over a bit sequence (most significant first), initial value 0."""
    crc = 0
    for b in bits:
        top = b ^ (crc >> 14 & 1)
        crc = (crc << 1) & 0x7FFF
        if top:
            crc ^= CAN_CRC15_POLY
    return crc


def can_frame_bits(ident: int, data: bytes) -> list[int]:
    """Return the bits CAN's CRC covers: SOF, identifier, RTR, IDE, r0, DLC, data (MSB first)."""
    bits = [0, *((ident >> (10 - k)) & 1 for k in range(11)), 0, 0, 0,
            *((len(data) >> (3 - k)) & 1 for k in range(4))]
    for byte in data:
        bits += [(byte >> (7 - k)) & 1 for k in range(8)]
    return bits


def can_crc15_syndromes(dlc: int) -> np.ndarray:
    """Per error bit of a frame with ``dlc`` data bytes, what it does to the CRC check.

    Error bits are numbered: identifier bits 0-10 (bit k of the identifier), then data bit
    8 j + k (bit k of byte j), then CRC bits 0-14 (bit k of the CRC). The CRC is linear with
    initial value 0, so a receiver misses an error pattern exactly when the XOR of its bits'
    syndromes is 0.
    """
    length = 19 + 8 * dlc
    out = []
    for k in range(11):
        bits = [0] * length
        bits[1 + 10 - k] = 1
        out.append(can_crc15(bits))
    for j in range(dlc):
        for k in range(8):
            bits = [0] * length
            bits[19 + 8 * j + 7 - k] = 1
            out.append(can_crc15(bits))
    out += [1 << k for k in range(15)]
    return np.array(out, dtype=np.uint16)


def _apply_bits(ident: int, data: bytes, bits: np.ndarray) -> CanFrame:
    """Flip the error bits (numbered as in `can_crc15_syndromes`, CRC bits ignored)."""
    raw = bytearray(data)
    for b in bits.tolist():
        if b < 11:
            ident ^= 1 << b
        elif b < 11 + 8 * len(raw):
            raw[(b - 11) // 8] ^= 1 << ((b - 11) % 8)
    return ident, bytes(raw)


def can_bus_rates(rng: np.random.Generator, frames: int, taxels: int = 64,
                  direct: int = 4000, tick: Callable[[int], None] | None = None) -> list[dict]:
    """CAN frames of a node's samples hit by (a) 1-5 bit errors, (b) uniform error patterns.

    Every frame is checked against the bus CRC-15 exactly; the samples whose damaged frame
    passes it go through `CanReassembler` (behind the bus CRC), and ``direct`` damaged samples
    of each class go through it with no bus CRC at all (a link with no check of its own).
    """
    tables = {d: can_crc15_syndromes(d) for d in range(9)}
    rows = []
    for cls, total in (("1-5 bits", frames // 4), ("uniform", frames - frames // 4)):
        state = _CanSource(rng, taxels)
        passed = accepted_behind = 0
        batch = 1 << 15
        for start in range(0, total, batch):
            m = min(batch, total - start)
            picks = state.pick(m)
            for dlc in np.unique(picks["dlc"]):
                rows_d = np.flatnonzero(picks["dlc"] == dlc)
                nbits = 11 + 8 * int(dlc) + 15
                err = _error_bits(rng, cls, rows_d.size, nbits)
                synd = np.bitwise_xor.reduce(np.where(err, tables[int(dlc)], 0), axis=1)
                for r in np.flatnonzero(synd == 0):
                    passed += 1
                    sample, index = picks["sample"][rows_d[r]], picks["index"][rows_d[r]]
                    accepted_behind += state.accepts(int(sample), int(index),
                                                     np.flatnonzero(err[r]))
            if tick:
                tick(m)
        theory = 0.0 if cls == "1-5 bits" else 2.0**-15
        note = ("CRC-15: Hamming distance 6, none pass" if cls == "1-5 bits" else
                "a uniform error pattern passes the CRC-15 with probability 2^-15")
        row = _rate(cls, passed, total, theory, note)
        # the same damage with no bus CRC: straight into the reassembler
        direct_acc = 0
        picks = state.pick(direct)
        for k in range(direct):
            dlc = int(picks["dlc"][k])
            err = _error_bits(rng, cls, 1, 11 + 8 * dlc + 15)[0]
            direct_acc += state.accepts(int(picks["sample"][k]), int(picks["index"][k]),
                                        np.flatnonzero(err))
        if tick:
            tick(direct)
        no_crc = _rate(cls, direct_acc, direct, None, "")
        lo, hi = clopper_pearson(accepted_behind, total)
        row["reassembler"] = {
            "without_bus_crc": {"accepted": direct_acc, "tried": direct, "rate": no_crc["rate"],
                                "ci95": no_crc["ci95"]},
            "behind_bus_crc": {"accepted": accepted_behind, "tried": total,
                               "rate": accepted_behind / total, "ci95": [lo, hi],
                               "expected": theory * (no_crc["rate"] or 0.0)},
        }
        rows.append(row)
    return rows


def _error_bits(rng: np.random.Generator, cls: str, m: int, nbits: int) -> np.ndarray:
    """``m`` nonzero error patterns over ``nbits`` bits, as a boolean array."""
    if cls == "uniform":
        err = rng.random((m, nbits)) < 0.5
        while (bad := ~err.any(axis=1)).any():
            err[bad] = rng.random((int(bad.sum()), nbits)) < 0.5
        return err
    err = np.zeros((m, nbits), bool)
    weight = rng.integers(1, 6, m)
    todo = np.arange(m)
    while todo.size:  # distinct positions: redraw the rows that picked one twice
        pos = rng.integers(0, nbits, (todo.size, 5))
        pos = np.where(np.arange(5) < weight[todo, None], pos, -1)
        srt = np.sort(pos, axis=1)
        dup = ((srt[:, 1:] == srt[:, :-1]) & (srt[:, 1:] >= 0)).any(axis=1)
        ok = todo[~dup]
        for c in range(5):
            on = pos[~dup, c] >= 0
            err[ok[on], pos[~dup, c][on]] = True
        todo = todo[dup]
    return err


class _CanSource:
    """A node's clean samples, and whether one damaged frame gets a corrupt sample through."""

    def __init__(self, rng: np.random.Generator, taxels: int, samples: int = 64) -> None:
        self.rng = rng
        duty = rng.integers(0, 256, taxels).astype(np.uint8)
        self.samples = [random_sample(rng, 0, 1000 + s, taxels, duty) for s in range(samples)]
        self.frames = [can_sample_frames(0, s.seq, s.time_us, s.counts, s.ambient, s.duty,
                                         s.flags, s.status) for s in self.samples]
        per = len(self.frames[0])
        self.per = per
        self.dlc = np.array([len(d) for _, d in self.frames[0]])

    def pick(self, m: int) -> dict[str, np.ndarray]:
        """Draw ``m`` frames uniformly: their sample (never the first) and index in it."""
        sample = self.rng.integers(1, len(self.samples) - 1, m)
        index = self.rng.integers(0, self.per, m)
        dlc = np.array([len(self.frames[s][i][1]) for s, i in zip(sample, index, strict=True)])
        return {"sample": sample, "index": index, "dlc": dlc}

    def accepts(self, sample: int, index: int, bits: np.ndarray) -> int:
        """Return 1 if a corrupt frame comes out when frame ``index`` of ``sample`` is damaged.

        ``bits``: the error (numbered as in `can_crc15_syndromes`); the damaged sample goes
        through `CanReassembler` between the clean samples before and after it.
        """
        frames = [f for s in (sample - 1, sample) for f in self.frames[s]]
        at = len(self.frames[sample - 1]) + index
        frames[at] = _apply_bits(*frames[at], bits)
        frames += self.frames[sample + 1]
        can = CanReassembler()
        out = can.feed(frames)
        clean = {s.seq: s for s in self.samples[sample - 1 : sample + 2]}
        bad = sum(1 for f in out if f.seq not in clean
                  or not clean[f.seq].matches(f, duty_known_only=True))
        return int(bad > 0)


def run(frames: int = 4_000_000, seed: int = 0,
        progress: Callable[[int, int, str], None] | None = None) -> dict:
    """Run the fuzz campaign: every decoder, damaged streams, reproducible from ``seed``.

    Parameters
    ----------
    frames : int
        About how many frames (packets, CAN frames, parser inputs) to try in all. Half go to
        the serial CRC rates (1/8 each for 1-3 bit errors and short bursts, 3/4 uniform), half
        to the CAN bus CRC rates (1/4 for 1-5 bit errors, 3/4 uniform); besides, the stream
        runs (mixed damage, random chunks, the intact-frame and statistics checks) take
        ``frames // 128`` packets (samples) each, the record, reply and command parsers
        ``frames // 128`` inputs each, and ``frames // 512`` damaged CAN samples of each
        class go straight into the reassembler.
    seed : int
        Seed of numpy's random generator.
    progress : callable, optional
        Called as ``progress(done, total, part)`` as the campaign goes on.

    Returns
    -------
    dict
        ``frames_tried`` and ``crashes`` over every part, then per part its counts: see
        ``skin bench fuzz``.
    """
    if frames < 128:
        raise ValueError("frames must be at least 128")
    rng = np.random.default_rng(seed)
    started = time.monotonic()
    small = frames // 128
    rate_serial = frames // 2
    rate_can = frames - rate_serial
    direct = max(1, small // 4)
    total = 2 * small + rate_serial + rate_can + 2 * direct + 3 * small
    done = 0
    part = ""

    def tick(k: int) -> None:
        nonlocal done
        done += k
        if progress:
            progress(done, total, part)

    # serial streams: mixed damage, random chunks
    part = "serial streams"
    serial = _Tally()
    sent = 0
    trial = 0
    while sent < small:
        case = serial_case(rng)
        dmg = [_draw_byte_damage(rng, len(case.stream)) for _ in range(rng.integers(1, 4))]
        damaged, origin = damage_bytes(case.stream, dmg)
        serial.add(check_serial(case, damaged, origin, chunk_sizes(rng, len(damaged))), trial)
        sent += len(case.items)
        trial += 1
        tick(len(case.items))
    # CAN streams: frame faults (no bus CRC in front: flips and resizes reach the host)
    part = "CAN streams"
    can = _Tally()
    sent = 0
    trial = 0
    while sent < small:
        ccase = can_case(rng, samples=3, nodes=int(rng.integers(1, 4)), sizes=(1, 4, 13, 64))
        dmg = [_draw_frame_damage(rng, len(ccase.frames)) for _ in range(rng.integers(1, 4))]
        damaged_frames, forigin = damage_frames(ccase.frames, dmg)
        can.add(check_can(ccase, damaged_frames, forigin, rng), trial)
        n = sum(isinstance(item, SentSample) for _, item in ccase.items)
        sent += n
        trial += 1
        tick(n)
    part = "serial CRC"
    serial_rates = serial_crc_rates(rng, rate_serial, tick=tick)
    part = "CAN bus CRC"
    can_rates = can_bus_rates(rng, rate_can, direct=direct, tick=tick)
    # the other parsers: CAN records, reply bodies, command packets
    part = "parsers"
    parsers = {"records": [0, 0, 0], "replies": [0, 0, 0], "commands": [0, 0, 0]}
    examples: list[str] = []
    for k in range(small):
        ccase = can_case(rng, samples=1, nodes=1, sizes=(4, 13))
        raw = b"".join(can_record(i, d) for i, d in ccase.frames)
        damaged, _ = damage_bytes(raw, [_draw_byte_damage(rng, len(raw))])
        reply = random_reply(rng, int(rng.integers(0, 256))).body()
        body, _ = damage_bytes(reply, [_draw_byte_damage(rng, len(reply))])
        kinds = [t for t in MsgType if t >= MsgType.START]  # the commands
        cmd = Command(int(rng.choice(kinds)), int(rng.integers(0, 256)),
                      int(rng.integers(0, 1 << 16)), int(rng.integers(0, 256)),
                      int(rng.integers(0, 1 << 16)), int(rng.integers(0, 1 << 16)),
                      int(rng.integers(0, 1 << 16))).encode()[:-1]
        packet, _ = damage_bytes(cmd, [_draw_byte_damage(rng, len(cmd))])
        packet = packet.replace(b"\x00", b"")  # the reader splits at 0x00
        for key, problem in (("records", check_records(damaged)),
                             ("replies", check_reply_body(body)),
                             ("commands", check_command_packet(packet))):
            parsers[key][0] += 1
            if problem:
                parsers[key][1] += 1
                parsers[key][2] += problem.startswith("raised ")
                if len(examples) < 5:
                    examples.append(f"{key} {k}: {problem}")
        tick(3)
    crashes = serial.crashes + can.crashes + sum(v[2] for v in parsers.values())
    tried = (serial.sent + can.sent + sum(r["tried"] for r in serial_rates)
             + sum(r["tried"] + r["reassembler"]["without_bus_crc"]["tried"] for r in can_rates)
             + sum(v[0] for v in parsers.values()))
    return {
        "seed": seed, "frames": frames, "frames_tried": tried, "crashes": crashes,
        "wall_time": round(time.monotonic() - started, 2),
        "serial": {"streams": serial.as_dict(), "crc": serial_rates},
        "can": {"streams": can.as_dict(), "bus_crc": can_rates},
        "parsers": {k: {"tried": v[0], "failures": v[1], "crashes": v[2]}
                    for k, v in parsers.items()},
        "parser_examples": examples,
    }
