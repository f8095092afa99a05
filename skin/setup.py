"""A setup: what `skin.Skin` runs, declared once, with where each value came from.

A `Setup` holds every choice of a run - sources, layout, calibration, classifier or model,
decision window, sinks, arm, recording, output folder - as plain values (strings, numbers,
lists). It is made from its defaults, then a skin file (``skin.toml``,
`skin.formats.skin_file`), then the command line or Python keywords, each later one
overriding the earlier; ``origin`` tells where each value came from (``skin config show``).

Adding an option to ``skin run`` is a field here (with its check in ``_CHECKS``), an
``add_argument`` line in `skin.commands.run` whose ``dest`` is the field's name, and its use in
`skin.runner.Skin`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any

from skin.errors import SkinError

SINKS = ("events", "terminal")
"""Sinks by name: ``events`` (``events.jsonl`` in the output folder), ``terminal`` (a line per
contact on stderr); any other entry ending in ``.jsonl`` is a JSON-lines file of that path."""


GROUPS: dict[str, tuple[str, ...]] = {
    "source": ("port", "reconnect", "first_frame_timeout", "firmware_sim", "scene", "seed",
               "duration", "speed", "contact"),
    "skin": ("layout", "calibration", "workers", "common_mode", "force_onsets",
             "response_check"),
    "classifier": ("model", "classifier", "threshold", "expect", "window", "provisional",
                   "object_temperature_range"),
    "output": ("out", "force", "sinks", "publish", "record", "map", "arm", "view", "video",
               "view_mode", "robot", "robot_pose"),
}
"""The tables of a skin file and the fields each holds (every field is in one table)."""

PATHS: dict[str, str] = {
    "layout": "name", "scene": "name", "calibration": "path", "model": "path", "record": "path",
    "out": "path", "arm": "name", "video": "path", "sinks": "jsonl", "port": "url",
}
"""Fields that hold files: ``path`` always a path; ``name`` a shipped name unless it has a
folder or a suffix; ``jsonl`` paths ending in ``.jsonl``; ``url`` the file of ``replay://``.
A skin file's relative paths are relative to its folder."""


class SetupError(SkinError):
    """A setup value of the wrong kind, or a skin file that cannot be read."""


@dataclass(frozen=True)
class Setup:
    """The resolved setup of a run (see the module docstring); every field has a default.

    Attributes
    ----------
    port : list of str
        Source URLs (``serial:///dev/ttyACM0``, ``can://socketcan/can0``, ``sim://default``,
        ``replay://run.mcap``); several make one skin of several boards or buses; empty: a
        simulated skin of ``scene`` served on a pseudo-terminal.
    reconnect : float
        Seconds a failed serial or CAN device is reopened before giving up.
    first_frame_timeout : float
        Seconds to wait for the first frame of a device before failing.
    firmware_sim : bool
        Play the scene to the compiled firmware in simavr (no ``port``).
    scene : str
        Simulation scene: a shipped name or a TOML file.
    seed : int or None
        The simulation's seed in place of the scene's own (None: the scene's): the same
        touches with other noise, starting temperatures and taxel units.
    layout : str or None
        Layout file or shipped name (default: the scene's, the recording's, or ``arm``).
    duration : float or None
        Seconds to run (default: the scene's; 20 for a device; a recording to its end).
    speed : float
        Simulation pace relative to real time; 0 as fast as possible.
    contact : str or None
        Simulated contact: ``perfect`` or ``finite``; None: the scene's (perfect unless the
        scene says ``contact = "finite"``).
    calibration : str or None
        Calibration file from ``skin calibrate``.
    model : str or None
        Model file from ``skin train``; without it, ``classifier``.
    classifier : str
        ``joint`` or ``histogram`` (without ``model``).
    threshold : float
        Probability needed to name a material (else its family, else "unknown").
    object_temperature_range : float
        K objects may be colder or warmer than a model file's training data: its confidence
        is bounded by the physics over that range (`skin.models.nuisance`); 0 trusts the
        training data's objects to be the world's. Default: a simulated scene's largest
        object offset from its ambient, else 0. Learned models only (the joint
        classifier has its own prior on the object's temperature).
    expect : list of str
        Materials the classifier must know (a simulation's scene adds its own).
    window : float
        Decision time after onset, s.
    provisional : list of float
        Anytime points: also classify open contacts at these seconds after onset.
    sinks : list of str
        Where results go (`SINKS`, or ``*.jsonl`` files).
    publish : list of str
        Live publishers by URL (``foxglove://HOST:PORT``, ``zenoh://PREFIX``;
        `skin.stream.publish`).
    record : str or None
        MCAP file to record to.
    out : str or None
        Output folder (None: write no files).
    force : bool
        Overwrite the outputs of an earlier run in ``out``.
    map : bool
        Render ``contact_map.png``.
    arm : str or None
        Arm file (TOML of meshes per link, or a URDF), or ``xarm7`` (the shipped example
        arm); default the procedural arm.
    view : bool
        Show the arm in a window.
    video : str or None
        Movie of the arm view (.gif, .mp4).
    view_mode : str
        ``material`` or ``temperature``.
    robot : str
        The robot's name: the key segment of its Zenoh topics (``zenoh://`` URLs' ``robot=``
        wins) and its name in a shared map (`skin.world.map_service`).
    robot_pose : list of float
        The robot's base in a shared map's frame, ``[x, y, z, roll, pitch, yaw]`` (m, rad),
        sent with each contact over Zenoh; empty: not given (the map's origin).
    workers : int
        1 runs the whole pipeline in this process. More: with at least as many serial ports
        (one board each) and no ``record``, each of that many worker processes opens its own
        boards' ports and decodes, assembles, calibrates and detects onsets
        (`skin.stream.board_workers`); otherwise onset detection alone is sharded across that
        many processes, this one included (`skin.stream.shards`). The same results.
    common_mode : bool or "auto"
        The onset detector's board common mode (`skin.stream.onset.OnsetDetector`'s
        ``common_mode``: the room's change, shared alike by nearly every free taxel of a
        board of 4 or more, taken off first). ``"auto"`` (default): on for sensors whose
        heater is not PID-held, off for PID-held ones (`skin.stream.onset.common_auto`);
        true / false: on / off for every sensor. With it, onset shards keep whole
        boards (fewer worker processes than ``workers`` on a skin of fewer boards).
    force_onsets : bool
        Date the contacts of taxels whose frames carry a force or contact reading by it
        (`skin.stream.force`; the onset detector where it has none); False: the onset
        detector dates every taxel. Default on.
    response_check : bool
        Test each contact the force alone dated for a thermal response and answer "unknown"
        (noted "no thermal response") where it shows none (`skin.stream.response`); False:
        classify it whatever it shows. Default on.
    origin : dict
        Field name -> where its value came from (``default`` when absent).
    """

    port: list[str] = field(default_factory=list)
    reconnect: float = 10.0
    first_frame_timeout: float = 5.0
    firmware_sim: bool = False
    scene: str = "default"
    seed: int | None = None
    layout: str | None = None
    duration: float | None = None
    speed: float = 1.0
    contact: str | None = None
    calibration: str | None = None
    model: str | None = None
    classifier: str = "joint"
    threshold: float = 0.5
    object_temperature_range: float = 0.0
    expect: list[str] = field(default_factory=list)
    window: float = 2.5
    provisional: list[float] = field(default_factory=list)
    sinks: list[str] = field(default_factory=lambda: list(SINKS))
    publish: list[str] = field(default_factory=list)
    record: str | None = None
    out: str | None = "out/run"
    force: bool = False
    map: bool = True
    arm: str | None = None
    view: bool = False
    video: str | None = None
    view_mode: str = "material"
    workers: int = 1
    common_mode: bool | str = "auto"
    force_onsets: bool = True
    response_check: bool = True
    robot: str = "skin"
    robot_pose: list[float] = field(default_factory=list)
    origin: dict[str, str] = field(default_factory=dict, compare=False)

    def updated(self, values: Mapping[str, Any], origin: str | Mapping[str, str]) -> Setup:
        """Return a copy with ``values`` checked and set, each noted as coming from ``origin``.

        Parameters
        ----------
        values : mapping
            Field name -> value (None for an optional field clears it).
        origin : str or mapping
            Where the values came from (``"command line"``), or per field (``"skin.toml:7"``).

        Raises
        ------
        SetupError
            Naming the field (and its origin) of an unknown name or a value of the wrong kind.
        """
        names = setup_fields()
        checked: dict[str, Any] = {}
        where = dict(self.origin)
        for name, value in values.items():
            at = origin if isinstance(origin, str) else origin.get(name, "?")
            if name not in names:
                raise SetupError(f"{at}: unknown setting {name!r} (settings: "
                                 f"{', '.join(sorted(names))})")
            try:
                checked[name] = _CHECKS[name](value)
            except (TypeError, ValueError) as exc:
                raise SetupError(f"{at}: {name}: {exc}") from None
            where[name] = at
        return replace(self, **checked, origin=where)

    def where(self, name: str) -> str:
        """Return where the value of field ``name`` came from."""
        return self.origin.get(name, "default")

    def as_dict(self) -> dict[str, Any]:
        """Return the values, field name -> value (JSON-ready)."""
        return {name: getattr(self, name) for name in setup_fields()}


def setup_fields() -> list[str]:
    """Names of the `Setup` fields that hold values (all but ``origin``)."""
    return [f.name for f in fields(Setup) if f.name != "origin"]


def _text(value: Any) -> str:
    if not isinstance(value, str) or not value:
        raise TypeError(f"must be a non-empty string, got {value!r}")
    return value


def _optional_text(value: Any) -> str | None:
    return None if value is None else _text(str(value) if hasattr(value, "__fspath__") else value)


def _texts(value: Any) -> list[str]:
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list | tuple):
        raise TypeError(f"must be a list of strings, got {value!r}")
    return [_text(str(v) if hasattr(v, "__fspath__") else v) for v in value]


def _number(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or math.isnan(value):
        raise TypeError(f"must be a number, got {value!r}")
    return float(value)


def _non_negative(value: Any) -> float:
    out = _number(value)
    if out < 0:
        raise ValueError(f"must be 0 or more, got {value!r}")
    return out


def _positive(value: Any) -> float:
    out = _number(value)
    if not out > 0:
        raise ValueError(f"must be more than 0, got {value!r}")
    return out


def _whole(value: Any, least: int) -> int:
    if isinstance(value, str):  # the command line's "2"
        try:
            value = int(value)
        except ValueError:
            raise ValueError(f"must be a whole number, got {value!r}") from None
    if isinstance(value, bool) or not isinstance(value, int) or value < least:
        raise ValueError(f"must be a whole number of at least {least}, got {value!r}")
    return value


def _count(value: Any) -> int:
    return _whole(value, 1)


def _probability(value: Any) -> float:
    out = _number(value)
    if not 0.0 <= out <= 1.0:
        raise ValueError(f"must be a probability in 0-1, got {value!r}")
    return out


def _optional_positive(value: Any) -> float | None:
    return None if value is None else _positive(value)


def _optional_seed(value: Any) -> int | None:
    return None if value is None else _whole(value, 0)


def _numbers(value: Any) -> list[float]:
    if isinstance(value, str):  # the command line's "0.5,1"
        try:
            value = [float(v) for v in value.split(",") if v.strip()]
        except ValueError:
            raise ValueError(f"must be numbers separated by commas, got {value!r}") from None
    if isinstance(value, int | float) and not isinstance(value, bool):
        value = [value]
    if not isinstance(value, list | tuple):
        raise TypeError(f"must be a list of numbers, got {value!r}")
    return [_positive(v) for v in value]


def _name(value: Any) -> str:
    if not isinstance(value, str) or not value or not all(c.isalnum() or c in "-_"
                                                          for c in value):
        raise ValueError(f"must be a name of letters, digits, - and _, got {value!r}")
    return value


def _pose(value: Any) -> list[float]:
    if isinstance(value, str):
        try:
            value = [float(v) for v in value.split(",") if v.strip()]
        except ValueError:
            raise ValueError(f"must be x,y,z,roll,pitch,yaw, got {value!r}") from None
    if not isinstance(value, list | tuple) or len(value) not in (0, 6):
        raise ValueError(f"must be 6 numbers [x, y, z, roll, pitch, yaw] (m, rad), got {value!r}")
    numbers = [_number(v) for v in value]
    if not all(math.isfinite(v) for v in numbers):
        raise ValueError(f"must be finite numbers, got {value!r}")
    return numbers


def _flag(value: Any) -> bool:
    if not isinstance(value, bool):
        raise TypeError(f"must be true or false, got {value!r}")
    return value


def _auto_flag(value: Any) -> bool | str:
    if value == "auto" or isinstance(value, bool):
        return value
    raise TypeError(f"must be true, false or \"auto\", got {value!r}")


def _choice(*options: str) -> Callable[[Any], str]:
    def check(value: Any) -> str:
        if value not in options:
            raise ValueError(f"must be one of {', '.join(options)}, got {value!r}")
        return value

    return check


_CHECKS: dict[str, Callable[[Any], Any]] = {
    "port": _texts,
    "reconnect": _non_negative,
    "first_frame_timeout": _positive,
    "firmware_sim": _flag,
    "scene": _text,
    "seed": _optional_seed,
    "layout": _optional_text,
    "duration": _optional_positive,
    "speed": _non_negative,
    "contact": _choice("perfect", "finite"),
    "calibration": _optional_text,
    "model": _optional_text,
    "classifier": _choice("joint", "histogram"),
    "threshold": _probability,
    "object_temperature_range": _non_negative,
    "expect": _texts,
    "window": _positive,
    "provisional": _numbers,
    "sinks": _texts,
    "publish": _texts,
    "record": _optional_text,
    "out": _optional_text,
    "force": _flag,
    "map": _flag,
    "arm": _optional_text,
    "view": _flag,
    "video": _optional_text,
    "view_mode": _choice("material", "temperature"),
    "workers": _count,
    "common_mode": _auto_flag,
    "force_onsets": _flag,
    "response_check": _flag,
    "robot": _name,
    "robot_pose": _pose,
}
