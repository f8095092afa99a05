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
#: Builds `emulated_board` can play a scene to: MCU, taxels, multiplexers, force inputs.
BUILDS = {"mega": (MCU, TAXELS, MUXES, 0), "uno": ("atmega328p", 16, 1, 0),
          "uno_force": ("atmega328p", 16, 1, 16)}
#: The force at the ADC's full scale of the force builds (``SKIN_FORCE_FULL_MN``'s default), N.
FORCE_FULL_N = 20.0


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
                   realtime: float | None = None, build: str = BOARD) -> EmulatedBoard:
    """Write a simulator's thermistor temperatures as a harness scene and make its board.

    With a build that has force inputs and a scene with a force channel (``force = "force"``
    or ``"contact"``), the scene's force goes to the board's force inputs too (capped at the
    full scale, `FORCE_FULL_N`), and the firmware sends it as FORCE.

    Parameters
    ----------
    simulator : skin.drivers.sim.SkinSimulator
        The simulation of a scene from `firmware_scene`.
    folder : str or Path, optional
        Where to write the scene file (a temporary folder by default).
    realtime : float, optional
        Pace of the emulation relative to real time (None: as fast as it goes).
    build : str
        A key of `BUILDS`: the firmware build (``make -C firmware``) and its board; the
        simulator's scene must be cut to its taxels (`firmware_scene`).

    Returns
    -------
    EmulatedBoard
        Not started yet; once started, it powers up on the host's first command.
    """
    if build not in BUILDS:
        raise SceneError(f"no firmware build {build!r} to emulate; choose from "
                         f"{', '.join(BUILDS)}")
    mcu, taxels, muxes, n_force = BUILDS[build]
    scene = simulator.scene
    rng = np.random.default_rng(scene.seed + 1)
    temps = simulator.temperatures()
    temps = temps + rng.normal(0.0, simulator.noise, temps.shape)
    idx, addr = scene.layout.channel_map(simulator.board.id)
    if np.any(addr >= taxels):
        raise SceneError(f"{scene.source}: taxels at addresses up to {int(addr.max())}; the "
                         f"{build} build serves {taxels} (cut the scene with firmware_scene)")
    channels = np.full((temps.shape[0], taxels), simulator.heated)
    channels[:, addr] = temps[:, idx]
    force = None
    if n_force and scene.force:
        from skin.drivers.sim import FORCE_STREAM

        newtons = simulator.forces(0, temps.shape[0],
                                   np.random.default_rng([scene.seed + 1, FORCE_STREAM]))
        force = np.zeros((temps.shape[0], taxels))
        force[:, addr] = np.minimum(newtons[:, idx], FORCE_FULL_N)
    folder = Path(folder or tempfile.mkdtemp(prefix="skin-firmware-sim-"))
    folder.mkdir(parents=True, exist_ok=True)
    path = write_scene(folder / "scene.bin", channels.astype(np.float32),
                       np.full(temps.shape[0], scene.ambient), simulator.sample_rate,
                       nominal_duty=1.0, heater_rise=simulator.heated - scene.ambient,
                       heater_tau=simulator.sensor.reheat_time_constant, force=force)
    return EmulatedBoard(firmware_elf(build), path, taxels=taxels, muxes=muxes, mcu=mcu,
                         force_inputs=n_force, force_full_n=FORCE_FULL_N, realtime=realtime,
                         duration=simulator.duration + 1.0, wait_host=True)
