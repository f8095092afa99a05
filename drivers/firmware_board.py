"""A simulated scene played to the compiled firmware in simavr (``skin run --firmware-sim``).

The scene's physics (`skin.drivers.sim.SkinSimulator`) gives every taxel's thermistor
temperature; the harness turns them into ADC voltages for the emulated ATmega2560 running the
real ``skin_controller`` build, whose frames the serial driver reads from its pseudo-terminal.
The build serves 72 taxels (the default arm); a larger scene is cut to its first 72 addresses. The
layout's board reports the firmware's 12-bit counts.
"""

from __future__ import annotations

import dataclasses
import tempfile
from pathlib import Path

import numpy as np

from skin.drivers.avr_sim import EmulatedBoard, firmware_elf, write_scene
from skin.errors import SceneError
from skin.formats.layout import Layout
from skin.formats.scene import Scene

#: The emulated board: ``make -C firmware`` builds it as ``build/mega``.
BOARD, MCU, TAXELS, MUXES = "mega", "atmega2560", 72, 5


def firmware_scene(scene: Scene, taxels: int = TAXELS) -> Scene:
    """Cut a scene to the taxels one firmware board serves, with the firmware's ADC scale.

    Parameters
    ----------
    scene : Scene
        A one-board scene.
    taxels : int
        Taxels on the board: those at addresses below it are kept.

    Returns
    -------
    Scene
        The same scene on the cut layout (board ``adc_bits`` 12); touches keep the taxels
        that remain and are dropped when none do.
    """
    layout = scene.layout
    if len(layout.boards) != 1:
        raise SceneError(f"{scene.source}: --firmware-sim emulates one board")
    board = next(iter(layout.boards.values()))
    kept = [t for t in layout.taxels if t.address < taxels]
    cut = Layout(kept, [dataclasses.replace(board, adc_bits=12)],
                 name=f"{layout.name} (first {taxels} taxels, firmware board)",
                 source=layout.source)
    ids = {int(t.id) for t in kept}
    touches = []
    for touch in scene.touches:
        mine = tuple(t for t in touch.taxels if t in ids)
        if mine:
            touches.append(dataclasses.replace(touch, taxels=mine))
    return dataclasses.replace(scene, layout=cut, touches=tuple(touches))


def emulated_board(simulator, folder: str | Path | None = None,
                   realtime: float | None = None) -> EmulatedBoard:
    """Write a simulator's thermistor temperatures as a harness scene and make its board.

    Parameters
    ----------
    simulator : skin.drivers.sim.SkinSimulator
        The simulation of a scene from `firmware_scene`.
    folder : str or Path, optional
        Where to write the scene file (a temporary folder by default).
    realtime : float, optional
        Pace of the emulation relative to real time (None: as fast as it goes).

    Returns
    -------
    EmulatedBoard
        Not started yet; once started, it powers up on the host's first command.
    """
    scene = simulator.scene
    rng = np.random.default_rng(scene.seed + 1)
    temps = simulator.temperatures()
    temps = temps + rng.normal(0.0, simulator.noise, temps.shape)
    idx, addr = scene.layout.channel_map(simulator.board.id)
    channels = np.full((temps.shape[0], TAXELS), simulator.heated)
    channels[:, addr] = temps[:, idx]
    folder = Path(folder or tempfile.mkdtemp(prefix="skin-firmware-sim-"))
    folder.mkdir(parents=True, exist_ok=True)
    path = write_scene(folder / "scene.bin", channels.astype(np.float32),
                       np.full(temps.shape[0], scene.ambient), simulator.sample_rate,
                       nominal_duty=1.0, heater_rise=simulator.heated - scene.ambient,
                       heater_tau=simulator.sensor.reheat_time_constant)
    return EmulatedBoard(firmware_elf(BOARD), path, taxels=TAXELS, muxes=MUXES, mcu=MCU,
                         realtime=realtime, duration=simulator.duration + 1.0, wait_host=True)
