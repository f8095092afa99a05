"""A simulated skin: the paper's semi-infinite contact model behind the paper's ADC.

`SkinSimulator` turns a `Scene` into frames.  Each taxel's sensor body, when free, relaxes
towards the heated steady state (eq. 2) with the lumped time constant l^2 / alpha_s; when an
object touches it, the thermistor follows the contact response from the temperature it had at
that moment, so initial conditions vary with each taxel's recent contacts. The contact has a
perfect conductance (eq. 5), or with ``contact="finite"`` a conductance h per taxel and
touch, drawn log-uniformly from the material's range (a light touch through the material's
air gap, `skin.models.materials.Material.gap`). A PID-held sensor (``heater = "pid"``) sits at
its setpoint from the start, its contacts swing from it, and its loop acts on the whole stream
(`skin.models.sensors.StreamingDynamics`). Setpoint convention: a scene's room is constant,
so the setpoint is the scene's ambient plus the sensor's heated rise (``initial_temperature``
is ignored). Its lift-off is not a release model: the un-looped deficit recovers with
``control_time`` and the loop's high-pass acts on it again, so the reading overshoots the
setpoint with the right sign but a magnitude that is not modelled and grows with the hold
(pid-logger on aluminium, noise-free, perfect contact: a -0.99 K dip, then a peak 2.1-2.5 s
after lift-off of +0.83 K after a 5 s hold, +1.82 K after 15 s, +2.24 K after 30 s), where
lifting off removes the object's flux, which falls as ~1/sqrt(t): at most about the dip,
smaller after a longer hold (the stream simulator, `skin.bench.streams`: +0.22 K after a
-0.93 K aluminium release). Readings get Gaussian noise and pass through the thermistor
divider and the 10-bit ADC.

A scene with ``force = "force"`` or ``"contact"`` also gives every frame its taxels' force
channel (`SkinSimulator.forces`, ``Frame.force``), which the wire carries as FORCE messages.

`SimDriver` hands those frames over directly (``sim://``); `PtySerialDevice` writes them, as
wire-protocol bytes, into a real pseudo-terminal, so that the serial driver reads them exactly
as it reads a board, and answers the commands the driver sends.
"""

from __future__ import annotations

import itertools
import os
import select
import threading
import time
import tty
from collections.abc import Iterator

import numpy as np

from skin.drivers.base import Driver
from skin.drivers.protocol import (
    ALL_TAXELS,
    OPTION_FORCE,
    Ack,
    Command,
    ErrorReply,
    Identity,
    MsgType,
    SelftestResult,
    encode_force,
    encode_sample,
    layout_hash,
    parse_command_packet,
)
from skin.errors import SceneError
from skin.formats.calibration_file import CalibrationFile
from skin.formats.scene import Scene
from skin.frame import FLAG_ADC_SATURATED, FLAG_STREAMING, Frame
from skin.stream.calibration import Calibration

#: Samples `SkinSimulator` computes at a time (5 s at 200 Hz).
CHUNK = 1000
#: A simulated force sensor: white noise, N, and the rise time of a touch's force, s (linear).
FORCE_NOISE = 0.005
FORCE_RISE = 0.02
#: An inverted force sensor (scene ``force_inverted``) reads this less its force, N (the AVR
#: firmware's default full scale, ``SKIN_FORCE_FULL_MN``).
FORCE_FULL_SCALE = 20.0
#: Key of the scene seed's stream the force noise is drawn from (``[seed + 1, FORCE_STREAM]``).
FORCE_STREAM = 3


#: Key of the scene seed's stream each taxel's spread is drawn from (``[seed, SPREAD_STREAM]``):
#: `skin.models.trials.simulate_trials` given ``skin_seed=[seed, SPREAD_STREAM]`` draws the
#: same taxels.
SPREAD_STREAM = 11

class SkinSimulator:
    """Simulate every taxel of a scene's layout, in bounded chunks as the frames are taken.

    Parameters
    ----------
    scene : Scene
        What touches what, when.
    duration : float, optional
        Simulated time, s; the scene's duration by default.
    contact : str, optional
        ``"perfect"``: the paper's eq. 5 (h = infinity); ``"finite"``: each taxel's contact
        conductance drawn from the material's range; None (default): the scene's
        (`Scene.contact`, perfect unless the scene says finite).
    """

    def __init__(self, scene: Scene, duration: float | None = None,
                 contact: str | None = None) -> None:
        import scipy.signal  # noqa: F401  (the frames' filters: loaded here, not at the first frame)

        from skin.models.materials import load_materials
        from skin.models.physics import heated_temperature
        from skin.models.sensors import SensorDescription

        contact = scene.contact if contact is None else contact
        if contact not in ("finite", "perfect"):
            raise ValueError(f"contact must be 'finite' or 'perfect', got {contact!r}")
        self.scene = scene
        self.contact = contact
        self.layout = scene.layout
        if len(self.layout.boards) != 1:
            raise SceneError(f"{scene.source}: the simulator drives one board for now")
        self.board = next(iter(self.layout.boards.values()))
        self.sample_rate = self.board.sample_rate
        self.duration = scene.duration if duration is None else float(duration)
        self.n_samples = round(self.duration * self.sample_rate)
        self.sensor = SensorDescription.from_board(self.board)
        self.calibration = Calibration.from_layout(self.layout)
        materials = load_materials()
        if self.sensor.heater == "pid":
            self.heated = scene.ambient + self.sensor.heated_rise
        else:
            self.heated = float(heated_temperature(scene.ambient, self.sensor))
        self.taxel_sensor = self._spread(len(self.layout))
        if self.taxel_sensor is self.sensor or self.sensor.heater == "pid":
            self._heated_each: np.ndarray | float = self.heated
        else:
            self._heated_each = heated_temperature(scene.ambient, self.taxel_sensor)
        self._touches = []
        for touch in scene.touches:
            obj = scene.objects[touch.object]
            if obj.material not in materials:
                where = f"{scene.source}:{obj.line}" if obj.line else str(scene.source)
                raise SceneError(f"{where}: object {obj.name!r}: unknown material "
                                 f"{obj.material!r} (known: {', '.join(sorted(materials))})")
            mat = materials[obj.material]
            t_obj = (mat.resting_temperature(scene.ambient) if obj.temperature is None
                     else obj.temperature)
            idx = np.array([self.layout.index(t) for t in touch.taxels])
            k0 = round(touch.start * self.sample_rate)
            k1 = round(touch.end * self.sample_rate)
            self._touches.append((k0, k1, idx, t_obj, mat.effusivity,
                                  np.log10(mat.conductance_range)))
        self._force_touches = [(touch.start, touch.end, t[2], touch.force)
                               for touch, t in zip(scene.touches, self._touches, strict=True)]
        # presses of the force alone (`skin.formats.scene.Phantom`): no heat flows
        self._force_touches += [(p.start, p.end, np.array([self.layout.index(t) for t in p.taxels]),
                                 p.force) for p in scene.phantoms]
        self._idx, self._addr = self.layout.channel_map(self.board.id)
        self._channels = int(self._addr.max()) + 1

    def _spread(self, n: int):
        """Each taxel's sensor: the board's, its body constants spread by the scene.

        Depth, diffusivity and conductivity are drawn uniformly within +-``taxel_spread`` of
        the board's (in that order per taxel, as the trial generator does), from their own
        stream of the scene's seed. No spread: the board's sensor itself.
        """
        from dataclasses import replace

        spread = self.scene.taxel_spread
        if spread == 0:
            return self.sensor
        rng = np.random.default_rng([self.scene.seed, SPREAD_STREAM])
        f = 1.0 + rng.uniform(-spread, spread, (n, 3))
        s = self.sensor
        return replace(s, depth=s.depth * f[:, 0], diffusivity=s.diffusivity * f[:, 1],
                       conductivity=s.conductivity * f[:, 2])

    def _sensor_of(self, select: np.ndarray):
        """Return the sensor of the selected taxels (arrays of constants when they differ)."""
        from dataclasses import replace

        s = self.taxel_sensor
        if s is self.sensor:
            return s
        return replace(s, depth=s.depth[select], diffusivity=s.diffusivity[select],
                       conductivity=s.conductivity[select])

    def true_calibration(self) -> CalibrationFile:
        """Return a calibration file of each taxel's true thermal constants (the simulation's).

        What a perfect commissioning would fit: the ceiling of what calibration can give.
        """
        from skin.formats.calibration_file import CalibrationFile

        s = self.taxel_sensor
        n = len(self.layout)
        depth, alpha, k = (np.broadcast_to(np.asarray(v, dtype=float), n)
                           for v in (s.depth, s.diffusivity, s.conductivity))
        taxels = {int(t): {"depth": float(depth[i]), "diffusivity": float(alpha[i]),
                           "conductivity": float(k[i])}
                  for i, t in enumerate(self.layout.ids)}
        return CalibrationFile(taxels=taxels, references={
            "thermal": f"simulation truth ({self.scene.source}, seed {self.scene.seed})"})

    @property
    def noise(self) -> float:
        """White noise of the thermistor temperatures, K: the scene's, else the sensor's."""
        return self.sensor.noise if self.scene.noise is None else self.scene.noise

    def temperatures(self) -> np.ndarray:
        """Noise-free thermistor temperatures, shape (n_samples, n_taxels), deg C.

        The whole run at once: `temperature_chunks` joined.
        """
        parts = list(self.temperature_chunks())
        return np.concatenate(parts) if parts else np.empty((0, len(self.layout)))

    def temperature_chunks(self, chunk: int = CHUNK) -> Iterator[np.ndarray]:
        """Yield the noise-free thermistor temperatures, ``chunk`` samples at a time.

        With the board's sensor description: its heater mode, PID loop and thermistor lag.
        The chunks joined are the same whatever ``chunk``, bit for bit; memory holds one.
        """
        from skin.models.physics import conductance_rate, contact_response, contact_temperature
        from skin.models.sensors import StreamingDynamics, heater_term

        if chunk < 1:
            raise ValueError(f"chunk must be at least 1 sample, got {chunk}")
        n = len(self.layout)
        rng = np.random.default_rng(self.scene.seed)
        lo, hi = self.scene.initial_temperature
        heated = self._heated_each
        free = np.minimum(rng.uniform(lo, hi, n), heated)
        h_rng = np.random.default_rng([self.scene.seed, 7])  # the free start stays as it was
        sensor = self.sensor
        each = self.taxel_sensor
        e_s = np.broadcast_to(np.asarray(each.effusivity, dtype=float), n)
        # A PID loop acts in `dynamics` (the reading is the loop's high-pass of the un-looped
        # temperature): it holds its setpoint from the start (the series' first sample is its
        # settled level: a free start below it read that far under the setpoint for good),
        # and a contact's swing starts from the setpoint the loop holds (added to the
        # un-looped value, which may still be recovering from the last touch). After a
        # release the un-looped drain recovers fast (near the thermistor; ``control_time`` as
        # before), and the loop's high-pass acts on that recovery again: the reading
        # overshoots the setpoint at lift-off (the sign is right; the magnitude is not
        # modelled and grows with the hold, past the onset dip after ~5 s: see the module
        # docstring), the lift-off that `skin.models.commission` finds a PID touch's end by.
        # Holding the un-looped value instead made lift-off invisible (commissioning fitted
        # 0 of 8 taxels, pidscene): a faithful release needs a release model
        pid = sensor.heater == "pid"
        if pid:
            free = np.full(n, heated)
        relax = sensor.control_time if pid else each.reheat_time_constant
        decay = np.exp(-1.0 / (self.sample_rate * relax))
        e_obj_now = np.zeros(n)
        touching = np.zeros(n, dtype=bool)
        t0 = np.zeros(n)
        ts = np.zeros(n)
        rate = np.full(n, np.inf)  # conductance_rate of each taxel's current contact
        start = np.zeros(n)
        starts: dict[int, list] = {}
        ends: dict[int, list] = {}
        for touch in self._touches:
            starts.setdefault(touch[0], []).append(touch)
            ends.setdefault(touch[1], []).append(touch)
        reading = free.copy()
        dynamics = StreamingDynamics(sensor, self.sample_rate)
        for first in range(0, self.n_samples, chunk):
            out = np.empty((min(chunk, self.n_samples - first), n))
            for k in range(first, first + out.shape[0]):
                t = k / self.sample_rate
                for _, _, idx, *_ in ends.get(k, ()):
                    touching[idx] = False
                    free[idx] = reading[idx]
                for _, _, idx, t_obj, e_obj, log_h in starts.get(k, ()):
                    touching[idx] = True
                    t0[idx] = free[idx]
                    if pid:  # the swing from the setpoint, added to the un-looped value
                        ts[idx] = free[idx] + (contact_temperature(heated, t_obj, e_s[idx],
                                                                   e_obj) - heated)
                    else:
                        ts[idx] = contact_temperature(free[idx], t_obj, e_s[idx], e_obj)
                    start[idx] = t
                    e_obj_now[idx] = e_obj
                    if self.contact == "finite":
                        h = 10.0 ** h_rng.uniform(log_h[0], log_h[1], idx.size)
                        rate[idx] = conductance_rate(h, e_s[idx], e_obj)
                free = np.where(touching, free, heated + (free - heated) * decay)
                if touching.any():
                    here = self._sensor_of(touching)
                    resp = contact_response(t - start[touching], rate[touching], here)
                    reading = free.copy()
                    reading[touching] = t0[touching] + (ts[touching] - t0[touching]) * resp
                    if sensor.heater in ("off-at-contact", "on-during-contact"):
                        # the body's drain reaches the thermistor by what the object's pull
                        # leaves of it (`heater_term`'s response)
                        e_o = e_obj_now[touching]
                        share = e_o / (e_s[touching] + e_o) * resp
                        reading[touching] += heater_term(t - start[touching], t0[touching],
                                                         e_obj_now[touching], here,
                                                         self.scene.ambient, response=share)
                else:
                    reading = free
                out[k - first] = reading
            yield dynamics.push(out)

    def frames(self, chunk: int = CHUNK) -> Iterator[Frame]:
        """Yield the frames of the whole simulation, with noise and ADC quantisation.

        A reading at either rail of the ADC has its taxel's ``FLAG_ADC_SATURATED`` status bit
        set, and the frame's flag with it. The simulation runs ``chunk`` samples at a time as
        the frames are taken, so memory does not grow with the duration; the frames are the
        same whatever ``chunk``. The temperature noise is drawn from the scene's seed + 1 as
        it always was; the sensor's ADC noise and the ambient reading's noise come from
        streams of their own (``[seed + 1, 1]`` and ``[seed + 1, 2]``), so that no chunk
        needs the draws of the whole run before it.
        """
        from skin.models.sensors import StreamingSmoother

        rng = np.random.default_rng(self.scene.seed + 1)
        adc_rng = np.random.default_rng([self.scene.seed + 1, 1])
        amb_rng = np.random.default_rng([self.scene.seed + 1, 2])
        force_rng = np.random.default_rng([self.scene.seed + 1, FORCE_STREAM])
        smoother = StreamingSmoother(self.sensor, self.sample_rate)  # the firmware's smoothing
        adc_noise = self.scene.noise is None and self.sensor.adc_noise > 0  # the sensor's
        k = 0
        for temps in self.temperature_chunks(chunk):
            noisy = temps + rng.normal(0.0, self.noise, temps.shape)
            raw = self.calibration.counts(noisy)
            if adc_noise:
                raw = raw + adc_rng.normal(0.0, self.sensor.adc_noise, raw.shape)
            raw = smoother.push(raw)
            yield from self._frames_of(raw, k, amb_rng, force_rng)
            k += raw.shape[0]
        rest = smoother.finish()
        if rest is not None:
            yield from self._frames_of(rest, k, amb_rng, force_rng)

    def forces(self, k0: int, m: int, rng: np.random.Generator | None = None) -> np.ndarray:
        """Return the force channel of samples ``k0`` .. ``k0 + m - 1``, N, (m, n_taxels).

        A force sensor (scene ``force = "force"``) reads each touch's force (and each phantom
        press's, `skin.formats.scene.Phantom`: no object behind it), reached linearly
        over `FORCE_RISE` from the touch's start and gone at its end, plus white noise of
        `FORCE_NOISE` from ``rng`` (none without), never below 0; a contact switch
        (``"contact"``) reads 1 while touched, else 0. Rounded to the wire's 1 mN, so that
        the frames equal what a serial link or a recording gives back. A scene with
        ``force_inverted`` reads `FORCE_FULL_SCALE` less that (never below 0), a switch 1 less.
        """
        t = (k0 + np.arange(m))[:, None] / self.sample_rate
        out = np.zeros((m, len(self.layout)))
        switch = self.scene.force == "contact"
        for start, end, idx, newtons in self._force_touches:
            if end * self.sample_rate < k0 or start * self.sample_rate > k0 + m:
                continue
            on = (t >= start) & (t < end)
            level = 1.0 if switch else newtons * np.clip((t - start) / FORCE_RISE, 0.0, 1.0)
            out[:, idx] = np.where(on, level, out[:, idx])
        if not switch and rng is not None:
            out = np.maximum(out + rng.normal(0.0, FORCE_NOISE, out.shape), 0.0)
        if self.scene.force_inverted:
            out = np.maximum((1.0 if switch else FORCE_FULL_SCALE) - out, 0.0)
        return np.rint(out * 1000.0) / 1000.0

    def _frames_of(self, raw: np.ndarray, k0: int, amb_rng: np.random.Generator,
                   force_rng: np.random.Generator | None = None) -> Iterator[Frame]:
        """Frames of consecutive raw readings (n, n_taxels) from sample ``k0``."""
        m = raw.shape[0]
        counts = np.clip(np.rint(raw), 0, self.board.adc_max)
        ambient = self.scene.ambient + amb_rng.normal(0.0, 0.05, m)
        duty = np.full(self._channels, 255, dtype=np.uint8)
        channel_counts = np.zeros((m, self._channels), dtype=np.uint16)
        channel_counts[:, self._addr] = counts[:, self._idx]
        status = np.zeros((m, self._channels), dtype=np.uint8)
        rails = (counts <= 0) | (counts >= self.board.adc_max)
        status[:, self._addr] = np.where(rails[:, self._idx], FLAG_ADC_SATURATED, 0)
        flags = np.where(status.any(axis=1), FLAG_ADC_SATURATED, 0)
        force = None
        if self.scene.force:  # channels with no taxel have no reading
            force = np.full((m, self._channels), np.nan)
            force[:, self._addr] = self.forces(k0, m, force_rng)[:, self._idx]
        for i in range(m):
            k = k0 + i
            yield Frame(k, k / self.sample_rate, time.monotonic(), channel_counts[i],
                        float(ambient[i]), duty, int(flags[i]), self.board.id, status[i],
                        None if force is None else force[i])

    def identity(self, token: int = 0) -> Identity:
        """Return the IDENTITY a board with this simulator's layout would reply.

        ``adc_bits`` is the scale of the simulated counts (the layout's board), ``mcu`` 0 (a
        host build), and the sample rate is fixed by the scene.
        """
        order = np.argsort(self._addr)
        ids = self.layout.ids[self._idx[order]].tolist()
        rate = round(self.sample_rate)
        return Identity(token, fw_major=0, fw_minor=0, fw_patch=0, board_id=self.board.id & 0xFF,
                        mcu=0, transport=0,
                        options=OPTION_FORCE if self.scene.force else 0,
                        taxels=self._channels,
                        adc_bits=self.board.adc_bits, oversampling=1, rate_hz=rate,
                        max_rate_hz=rate, layout_hash=layout_hash(ids), baud_div=10000)


class _Pacer:
    """Release items at ``speed`` times real time (speed <= 0: as fast as possible)."""

    def __init__(self, speed: float) -> None:
        self.speed = speed
        self.t0 = time.monotonic()

    def wait(self, device_time: float, stop: threading.Event | None = None) -> None:
        if self.speed <= 0:
            return
        delay = self.t0 + device_time / self.speed - time.monotonic()
        if delay > 0:
            if stop is None:
                time.sleep(delay)
            else:
                stop.wait(delay)


class SimDriver(Driver):
    """Frames straight from a `SkinSimulator` (``sim://``), paced at ``speed`` x real time."""

    def __init__(self, simulator: SkinSimulator, speed: float = 1.0) -> None:
        super().__init__()
        self.url = f"sim://{simulator.scene.name}"
        self.simulator = simulator
        self._frames = simulator.frames()
        self._pacer = _Pacer(speed)

    def _recv_internal(self, timeout: float | None) -> Frame | None:
        frame = next(self._frames, None)
        if frame is None:
            self.finished = True
            return None
        self._pacer.wait(frame.device_time)
        self.stats.frames += 1
        if self.tap is not None:  # the bytes a board would have sent (ambient to 0.01 K)
            data = encode_sample(frame.seq, round(frame.device_time * 1e6), frame.counts,
                                 frame.ambient, frame.duty, frame.flags, frame.status)
            if frame.force is not None:  # the FORCE a board with a force sensor sends
                data += encode_force(frame.seq, frame.force)
            self.tap(time.monotonic(), data)
        return frame


class PtySerialDevice:
    """Serve a simulator's frames as protocol bytes on a pseudo-terminal, like a real board.

    The slave end (``port``) is what a serial driver opens.  Once `start` is called, a
    background thread writes the frames at ``speed`` x real time (speed <= 0: as fast as the
    reader takes them). Start it after the reader has opened the port: opening a serial port
    empties its input buffer, which would drop the frames already written.

    The device answers commands as a board does, between sample packets: IDENTIFY with
    `SkinSimulator.identity`, STOP and START pause and resume the stream (the sequence number
    goes on where it stopped), SET_DUTY sets the duties the samples report, SELFTEST is
    acknowledged and then reports that no heater responded (the simulated readings do not
    depend on the heaters). SET_RATE, SET_SETPOINT and CLEAR_FAULTS are acknowledged and change
    nothing: the scene fixes the rate and the simulator has no heater control loop. Malformed
    commands get the ERROR of `skin.drivers.protocol.parse_command_packet`. The device keeps
    answering after its last frame, until closed.

    Parameters
    ----------
    simulator : SkinSimulator
        Source of frames.
    speed : float
        Pacing relative to real time.
    """

    def __init__(self, simulator: SkinSimulator, speed: float = 1.0) -> None:
        self.simulator = simulator
        self.speed = speed
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)  # no line discipline: bytes pass unchanged, no echo
        os.set_blocking(self._master, False)
        self.port = os.ttyname(self._slave)
        self.frames_sent = 0
        self.streaming = True
        self.commands: list[Command] = []  # the valid commands received, in order
        self.done = threading.Event()
        self._stop = threading.Event()
        self._duty: np.ndarray | None = None  # set by SET_DUTY
        self._received = b""
        self._outbox: list[bytes] = []  # replies, written between sample packets
        self._thread = threading.Thread(target=self._serve, name="pty-skin", daemon=True)

    def start(self) -> None:
        """Start writing the frames (see the class docstring)."""
        self._thread.start()

    def _write(self, data: bytes) -> bool:
        view = memoryview(data)
        while view:
            if self._stop.is_set():
                return False
            readable, writable, _ = select.select([self._master], [self._master], [], 0.1)
            if readable:
                self._read_commands()
            if writable:
                try:
                    view = view[os.write(self._master, view) :]
                except BlockingIOError:
                    continue
        return True

    def _flush_replies(self) -> bool:
        while self._outbox:
            data = b"".join(self._outbox)
            self._outbox.clear()
            if not self._write(data):
                return False
        return True

    def _poll(self, timeout: float) -> None:
        """Wait up to ``timeout`` s for commands; answer them."""
        readable, _, _ = select.select([self._master], [], [], timeout)
        if readable:
            self._read_commands()
        self._flush_replies()

    def _read_commands(self) -> None:
        try:
            data = os.read(self._master, 4096)
        except (BlockingIOError, OSError):
            return
        *packets, self._received = (self._received + data).split(b"\x00")
        for packet in packets:
            if packet:
                self._outbox += self._answer(packet)

    def _answer(self, packet: bytes) -> list[bytes]:
        sim = self.simulator
        channels = sim._channels
        command = parse_command_packet(packet, channels, round(sim.sample_rate))
        if isinstance(command, ErrorReply):
            return [command.encode()]
        self.commands.append(command)
        ack = Ack(command.token, command.type).encode()
        if command.type == MsgType.IDENTIFY:
            return [sim.identity(command.token).encode()]
        if command.type in (MsgType.START, MsgType.STOP):
            self.streaming = command.type == MsgType.START
        elif command.type == MsgType.SET_DUTY:
            if self._duty is None:
                self._duty = np.full(channels, 255, dtype=np.uint8)
            self._duty[slice(None) if command.taxel == ALL_TAXELS else command.taxel] = (
                command.duty)
        elif command.type == MsgType.SELFTEST:
            return [ack, SelftestResult(command.token, (0,) * channels,
                                        (0xFFFF,) * channels).encode()]
        return [ack]

    def _serve(self) -> None:
        chunk: list[bytes] = []
        per = 2 if self.simulator.scene.force else 1  # packets per frame: SAMPLE (+ FORCE)
        try:
            frames = self.simulator.frames()
            first = next(frames, None)  # the first chunk is computed before the pacing starts
            pacer = _Pacer(self.speed)
            for frame in itertools.chain([] if first is None else [first], frames):
                paused = time.monotonic()
                while not self.streaming and not self._stop.is_set():
                    self._poll(0.05)
                pacer.t0 += time.monotonic() - paused  # a pause does not make a backlog
                duty = frame.duty if self._duty is None else self._duty
                chunk.append(encode_sample(frame.seq, round(frame.device_time * 1e6),
                                           frame.counts, frame.ambient, duty,
                                           frame.flags | FLAG_STREAMING, frame.status))
                if frame.force is not None:
                    chunk.append(encode_force(frame.seq, frame.force))
                if len(chunk) >= 10 * per:  # 50 ms of frames per write
                    pacer.wait(frame.device_time, self._stop)
                    if not self._write(b"".join(chunk)) or not self._flush_replies():
                        return
                    self.frames_sent += len(chunk) // per
                    chunk = []
            if chunk and self._write(b"".join(chunk)):
                self.frames_sent += len(chunk) // per
        finally:
            self.done.set()
        while not self._stop.is_set():  # the last frame is out: answer commands until closed
            self._poll(0.1)

    def close(self) -> None:
        """Stop writing and close both ends; calling it again does nothing."""
        if self._stop.is_set():
            return
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self) -> PtySerialDevice:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
