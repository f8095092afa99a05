"""Simulation scenes: which objects touch which taxels, when, and for how long.

A scene is a TOML file that users copy and edit; ``skin/data/scenes/default.toml`` ships.
It names a layout, the ambient conditions, the objects with their materials and temperatures,
and the touches.  It is validated on load (materials are checked by the simulator, which owns
the materials table).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from skin.errors import SceneError
from skin.formats.datafiles import header_lines, is_number, read_data_file
from skin.formats.layout import Layout, load_layout


@dataclass(frozen=True)
class SceneObject:
    """An object the arm touches.

    Attributes
    ----------
    name : str
        Unique name.
    material : str
        Key in the materials table.
    temperature : float or None
        Object temperature, deg C; None: the material's own (heat-generating) or ambient.
    line : int
        Line of its ``[[objects]]`` header in the scene file (0: unknown), for messages.
    """

    name: str
    material: str
    temperature: float | None
    line: int = 0


@dataclass(frozen=True)
class Touch:
    """One object touching a set of taxels.

    Attributes
    ----------
    object : str
        Name of the object.
    taxels : tuple of int
        Taxel ids.
    start, duration : float
        When the touch begins and how long it lasts, s.
    line : int
        Line of the ``[[touches]]`` table in the scene file.
    force : float
        Normal force on each of its taxels, N (field ``force``, 2 N by default): what a scene
        whose taxels have a force sensor (`Scene.force`) reads during the touch.
    """

    object: str
    taxels: tuple[int, ...]
    start: float
    duration: float
    line: int = 0
    force: float = 2.0

    @property
    def end(self) -> float:
        """When the touch ends, s."""
        return self.start + self.duration


@dataclass(frozen=True)
class Phantom:
    """A press the force channel reads with nothing thermal behind it (a glitch, a test).

    The taxels' force sensors read ``force`` from ``start`` for ``duration`` s (a contact
    switch reads 1) while no object touches them: no heat flows. A scene's ``[[phantoms]]``
    tables (fields ``taxels``, ``start``, ``duration``, ``force``, 2 N by default); only a
    scene with a force channel (``force``) reads them. `skin bench scene --phantoms N` adds
    them to measure what `skin run` makes of force glitches.
    """

    taxels: tuple[int, ...]
    start: float
    duration: float
    force: float = 2.0
    line: int = 0

    @property
    def end(self) -> float:
        """When the press ends, s."""
        return self.start + self.duration


@dataclass(frozen=True)
class Scene:
    """A validated simulation scene.

    ``noise`` is the white noise of the thermistor temperatures, K, when the scene sets it
    (it then replaces the sensor's noise model); None: each board's sensor description says.
    ``sensor`` is the sensor the scene puts on every board ("": the layout's own).
    ``taxel_spread`` spreads each taxel's thermistor depth, diffusivity and conductivity
    uniformly within +- that fraction of its board's (seeded: units differ, as real ones do;
    what commissioning and ``skin run --calibration`` correct). 0: every taxel is nominal.
    ``contact`` is how the touches meet the skin when the simulation is not told otherwise
    (``skin run --contact``): ``"perfect"`` (the paper's eq. 5) or ``"finite"`` (through each
    material's air gap, a conductance drawn from its range, as real contacts are).
    ``initial_temperature`` is the range each free taxel starts in; a PID-held sensor
    (``heater = "pid"``) ignores it and starts at its setpoint (ambient + heated rise).
    ``force`` says whether the taxels carry a force channel (``Frame.force``, the wire's
    FORCE message): ``""`` none (default), ``"force"`` a force sensor (each touch's
    ``force``, N, with noise), ``"contact"`` a contact switch (1 while touched, else 0).
    ``phantoms`` are presses of the force channel alone (`Phantom`: nothing touches).
    ``force_inverted`` (default false) wires that channel inverted, as a miswired sensor or an
    active-low switch reads: the force sensor reads its full scale
    (`skin.drivers.sim.FORCE_FULL_SCALE`, 20 N) less what it would read (high at rest,
    dropping when pressed; 0 beyond full scale), the switch 0 while touched, else 1.
    """

    name: str
    source: str
    layout: Layout
    duration: float
    ambient: float
    noise: float | None
    seed: int
    initial_temperature: tuple[float, float]
    objects: dict[str, SceneObject]
    touches: tuple[Touch, ...]
    sensor: str = ""
    taxel_spread: float = 0.0
    contact: str = "perfect"
    force: str = ""
    phantoms: tuple[Phantom, ...] = ()
    force_inverted: bool = False

    def material_of(self, touch: Touch) -> str:
        """Material of the object of a touch."""
        return self.objects[touch.object].material


def _press(raw: dict, where: str, what: str, layout: Layout, duration: float
           ) -> tuple[list, float, float, float]:
    """Check a touch's or phantom's taxels, start, duration and force; return them."""
    taxels = raw.get("taxels")
    if not isinstance(taxels, list) or not taxels:
        raise SceneError(f"{where}: field 'taxels' must be a non-empty list of taxel ids")
    for tid in taxels:
        if not isinstance(tid, int) or isinstance(tid, bool) or tid not in layout._index:
            raise SceneError(f"{where}: field 'taxels': no taxel {tid!r} in {layout.source}")
    start = _number(raw, "start", where)
    length = _number(raw, "duration", where, positive=True)
    if not 0 <= start <= duration - length:
        raise SceneError(f"{where}: the {what} ({start} s + {length} s) does not fit in the "
                         f"scene's {duration} s")
    newtons = _number(raw, "force", where, 2.0)
    if not 0 < newtons <= 65.0:
        raise SceneError(f"{where}: field 'force' must be within (0, 65] N, got {newtons!r}")
    return taxels, start, length, newtons


def _tables(data: dict, key: str, source: str) -> list[dict]:
    items = data.get(key, [])
    if not isinstance(items, list) or not all(isinstance(x, dict) for x in items):
        raise SceneError(f"{source}: {key!r} must be an array of tables ([[{key}]])")
    return items


def _number(raw: dict, key: str, where: str, default: Any = None, positive: bool = False) -> float:
    value = raw.get(key, default)
    if value is None:
        raise SceneError(f"{where}: missing field {key!r}")
    if not is_number(value):
        raise SceneError(f"{where}: field {key!r} must be a finite number, got {value!r}")
    if positive and not value > 0:
        raise SceneError(f"{where}: field {key!r} must be positive, got {value!r}")
    return float(value)


def _with_sensor(layout: Layout, ref: object, source: str, base: Path | None) -> Layout:
    """Return the layout with every board carrying the sensor ``ref`` (a preset or a file)."""
    from dataclasses import replace

    from skin.errors import SensorError
    from skin.models.sensors import load_sensor_field

    try:
        sensor, ref = load_sensor_field(ref, base)
    except SensorError as exc:
        raise SceneError(f"{source}: field 'sensor': {exc}") from None
    boards = [replace(b, **sensor.board_fields(), sensor=ref) for b in layout.boards.values()]
    return Layout(layout.taxels, boards, name=layout.name, source=layout.source)


def parse_scene(text: str, source: str = "<string>", base: Path | None = None) -> Scene:
    """Parse and validate scene TOML text.

    Parameters
    ----------
    text : str
        TOML text.
    source : str
        File name for messages.
    base : Path, optional
        Folder that a relative ``layout`` path is resolved against.
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{source}: not valid TOML: {exc}") from None
    layout_ref = data.get("layout", "arm")
    if not isinstance(layout_ref, str):
        raise SceneError(f"{source}: field 'layout' must be a layout name or path")
    ref = Path(layout_ref)
    if base is not None and ref.suffix and not ref.is_absolute():
        ref = base / ref
    layout = load_layout(ref)
    sensor = data.get("sensor", "")
    if sensor:
        layout = _with_sensor(layout, sensor, source, base)
    duration = _number(data, "duration", source, 20.0, positive=True)
    ambient = _number(data, "ambient", source, 25.0)
    noise = _number(data, "noise", source) if "noise" in data else None
    if noise is not None and noise < 0:
        raise SceneError(f"{source}: field 'noise' must be >= 0, got {noise!r}")
    seed = int(_number(data, "seed", source, 0))
    spread = _number(data, "taxel_spread", source, 0.0)
    if not 0 <= spread < 1:
        raise SceneError(f"{source}: field 'taxel_spread' must be within [0, 1), got {spread!r}")
    contact = data.get("contact", "perfect")
    if contact not in ("perfect", "finite"):
        raise SceneError(f"{source}: field 'contact' must be \"perfect\" or \"finite\", got "
                         f"{contact!r}")
    force = data.get("force", "")
    if force not in ("", "force", "contact"):
        raise SceneError(f"{source}: field 'force' must be \"force\", \"contact\" or \"\" "
                         f"(no force channel), got {force!r}")
    inverted = data.get("force_inverted", False)
    if not isinstance(inverted, bool):
        raise SceneError(f"{source}: field 'force_inverted' must be true or false, got "
                         f"{inverted!r}")
    if inverted and not force:
        raise SceneError(f"{source}: field 'force_inverted' needs a force channel (field "
                         "'force' = \"force\" or \"contact\")")
    init = data.get("initial_temperature", [ambient + 6.0, ambient + 14.0])
    if not (
        isinstance(init, list)
        and len(init) == 2
        and all(map(is_number, init))
        and init[0] <= init[1]
    ):
        raise SceneError(f"{source}: field 'initial_temperature' must be [low, high]")
    objects: dict[str, SceneObject] = {}
    object_lines = header_lines(text, "objects")
    for k, raw in enumerate(_tables(data, "objects", source)):
        line = object_lines[k] if k < len(object_lines) else 0
        where = f"{source}:{line}: object #{k}"
        name = raw.get("name")
        if not isinstance(name, str) or not name:
            raise SceneError(f"{where}: missing field 'name'")
        if name in objects:
            raise SceneError(f"{where}: duplicate object name {name!r}")
        material = raw.get("material")
        if not isinstance(material, str):
            raise SceneError(f"{where} ({name}): missing field 'material'")
        temp = raw.get("temperature")
        if temp is not None:
            temp = _number(raw, "temperature", f"{where} ({name})")
        objects[name] = SceneObject(name, material, temp, line)
    touches: list[Touch] = []
    touch_lines = header_lines(text, "touches")
    for k, raw in enumerate(_tables(data, "touches", source)):
        line = touch_lines[k] if k < len(touch_lines) else 0
        where = f"{source}:{line}: touch #{k}"
        obj = raw.get("object")
        if not isinstance(obj, str) or obj not in objects:
            raise SceneError(f"{where}: field 'object' names {obj!r}, which is not in [[objects]]")
        taxels, start, length, newtons = _press(raw, where, "touch", layout, duration)
        touches.append(Touch(obj, tuple(taxels), start, length, line, newtons))
    touches.sort(key=lambda t: t.start)
    phantoms: list[Phantom] = []
    phantom_lines = header_lines(text, "phantoms")
    for k, raw in enumerate(_tables(data, "phantoms", source)):
        line = phantom_lines[k] if k < len(phantom_lines) else 0
        where = f"{source}:{line}: phantom #{k}"
        taxels, start, length, newtons = _press(raw, where, "press", layout, duration)
        phantoms.append(Phantom(tuple(taxels), start, length, newtons, line))
    for i, a in enumerate(touches):
        for b in touches[i + 1 :]:
            if b.start >= a.end:
                break
            common = set(a.taxels) & set(b.taxels)
            if common:
                raise SceneError(f"{source}:{b.line}: touch overlaps the touch on line {a.line} "
                                 f"at taxel {min(common)}")
    return Scene(
        name=str(data.get("name", Path(source).stem)),
        source=source,
        layout=layout,
        duration=duration,
        ambient=ambient,
        noise=noise,
        seed=seed,
        initial_temperature=(float(init[0]), float(init[1])),
        objects=objects,
        touches=tuple(touches),
        sensor=sensor,
        taxel_spread=spread,
        contact=contact,
        force=force,
        phantoms=tuple(sorted(phantoms, key=lambda p: p.start)),
        force_inverted=inverted,
    )


def load_scene(path: str | Path) -> Scene:
    """Load a scene file, or a shipped scene by name (``"default"``)."""
    text, source, base = read_data_file(path, "scenes", "scene", SceneError)
    return parse_scene(text, source=source, base=base)


@dataclass(frozen=True)
class Match:
    """A scene touch and the detected contact that matches it (if any)."""

    touch: Touch
    material: str
    contact_index: int | None


def match_touches(
    scene: Scene, taxels: list[list[int]], onsets: list[float], tolerance: float = 0.5
) -> tuple[list[Match], list[int]]:
    """Match detected contacts to the scene's touches.

    A contact matches a touch when they share a taxel and the contact's onset lies within
    ``tolerance`` seconds of the touch's start; each contact matches at most one touch.

    Parameters
    ----------
    scene : Scene
        The scene with the truth.
    taxels : list of list of int
        Taxel ids of each detected contact.
    onsets : list of float
        Onset of each detected contact, s.
    tolerance : float
        Largest onset error accepted, s.

    Returns
    -------
    matches : list of Match
        One per touch, in time order.
    unmatched : list of int
        Indices of detected contacts that match no touch (false contacts).
    """
    used: set[int] = set()
    matches = []
    for touch in scene.touches:
        best, best_err = None, tolerance
        for i, (tx, t0) in enumerate(zip(taxels, onsets, strict=True)):
            err = abs(t0 - touch.start)
            if i not in used and set(tx) & set(touch.taxels) and err <= best_err:
                best, best_err = i, err
        if best is not None:
            used.add(best)
        matches.append(Match(touch, scene.material_of(touch), best))
    return matches, [i for i in range(len(taxels)) if i not in used]
