"""A DBC file of protocol v1's CAN frames, for candump, cantools and bus analysers.

`dbc_text` writes one message per identifier the nodes 0-6 send (firmware/PROTOCOL.md, section
2): ``SYNC_N<node>`` (seq, device time in us), ``DATA_N<node>_G<g>`` (the 12-bit ADC count and
4 status bits of taxels 4g .. 4g+3), ``DUTY_N<node>_G<d>`` (heater duty of taxels 8d .. 8d+7),
``STATUS_N<node>`` (seq mod 256, flags, ambient in deg C, groups), ``FORCE_N<node>_G<g>`` (the
force of taxels 4g .. 4g+3, N; 65.535 = no reading; sent only by a board with a force channel,
between DUTY and STATUS) and the host's
``COMMAND_N<node>`` (version, type, token; node 7 is every node). REPLY segments carry a byte
stream and are not described. The shipped file is ``firmware/thermoskin.dbc``
(``python -m skin.drivers.dbc > firmware/thermoskin.dbc`` writes it again); a test decodes
frames of `skin.drivers.protocol.can_sample_frames` with cantools.
"""

from __future__ import annotations

import sys

from skin.drivers.protocol import CAN_BROADCAST, CAN_MAX_TAXELS, CanType, can_id

NODES = range(CAN_BROADCAST)  # 0-6


def _signal(name: str, start: int, length: int, signed: bool = False, scale: float = 1.0,
            unit: str = "") -> str:
    low, high = (-(1 << (length - 1)), (1 << (length - 1)) - 1) if signed else (
        0, (1 << length) - 1)
    return (f' SG_ {name} : {start}|{length}@1{"-" if signed else "+"} ({scale:g},0) '
            f'[{low * scale:g}|{high * scale:g}] "{unit}" Vector__XXX\n')


def _message(ident: int, name: str, size: int, signals: list[str], sender: str) -> str:
    return f"BO_ {ident} {name}: {size} {sender}\n" + "".join(signals) + "\n"


def dbc_text() -> str:
    """Return the DBC file of protocol v1's CAN frames (see the module docstring)."""
    nodes = " ".join(f"NODE{n}" for n in NODES)
    out = ['VERSION "thermoskin protocol v1"\n\n', "NS_ :\n\n", "BS_:\n\n",
           f"BU_: HOST {nodes}\n\n"]
    for n in NODES:
        sender = f"NODE{n}"
        out.append(_message(can_id(CanType.SYNC, n, 0), f"SYNC_N{n}", 8,
                            [_signal("seq", 0, 32), _signal("time_us", 32, 32, unit="us")],
                            sender))
        for g in range(CAN_MAX_TAXELS // 4):
            sig = []
            for i in range(4):
                k = 4 * g + i
                sig += [_signal(f"count_{k}", 16 * i, 12), _signal(f"status_{k}", 16 * i + 12, 4)]
            out.append(_message(can_id(CanType.DATA, n, g), f"DATA_N{n}_G{g}", 8, sig, sender))
        for d in range(CAN_MAX_TAXELS // 8):
            sig = [_signal(f"duty_{8 * d + i}", 8 * i, 8) for i in range(8)]
            out.append(_message(can_id(CanType.DUTY, n, d), f"DUTY_N{n}_G{d}", 8, sig, sender))
        for g in range(CAN_MAX_TAXELS // 4):
            sig = [_signal(f"force_{4 * g + i}", 16 * i, 16, scale=0.001, unit="N")
                   for i in range(4)]
            out.append(_message(can_id(CanType.FORCE, n, g), f"FORCE_N{n}_G{g}", 8, sig, sender))
        out.append(_message(can_id(CanType.STATUS, n, 0), f"STATUS_N{n}", 6, [
            _signal("seq8", 0, 8), _signal("flags", 8, 16),
            _signal("ambient", 24, 16, signed=True, scale=0.01, unit="degC"),
            _signal("groups", 40, 8)], sender))
    for n in range(CAN_BROADCAST + 1):
        out.append(_message(can_id(CanType.COMMAND, n, 0), f"COMMAND_N{n}", 3, [
            _signal("version", 0, 8), _signal("type", 8, 8), _signal("token", 16, 8)], "HOST"))
    out.append('CM_ "thermoskin protocol v1 (firmware/PROTOCOL.md): identifier = type << 8 | '
               'node << 5 | index; ambient 0x7FFF (327.67) = unknown; '
               'force 0xFFFF (65.535) = no reading";\n')
    return "".join(out)


if __name__ == "__main__":
    sys.stdout.write(dbc_text())
