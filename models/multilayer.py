"""A 1-D multilayer finite-volume model of a heated taxel touching an object.

The column, from the object's back to the taxel's back::

    object (finite thickness)  |h|  sensor body (thermistor at depth x)  heater foil  foam  ->
    insulated or at ambient         contact conductance h                      convective loss

Each layer is split into cells (finer towards the contact surface); the unknowns are cell
temperatures, ``C du/dt = A u + b`` with ``C`` the heat capacity per area of each cell, ``A`` the
tridiagonal conductance matrix and ``b`` the heater power and the losses to ambient. Free
surfaces lose heat to ambient through a loss coefficient; in contact, the two surfaces are
joined through the contact conductance (``inf`` = perfect contact).

Time stepping is implicit, so stiff columns (copper against the sensor, diffusivity ratio 4e4;
dt up to 0.1 s) stay stable:

- ``"tr-bdf2"`` (default): trapezoidal stage then BDF2, second order and L-stable: stiff modes
  are damped rather than left ringing. Both stages share one matrix. Its amplification is
  negative (down to -0.2) for lambda dt < -2.41, so each phase starts with four backward
  Euler half steps, as Crank-Nicolson does: otherwise long steps (dt >= 0.2 s) undershoot
  after a contact (0.25 K, diamond against the paper's stack, dt = 0.5 s).
- ``"crank-nicolson"``: second order but only A-stable; each phase starts with four backward
  Euler half steps (Rannacher's damped start) to kill the ringing of the jump at contact.
- ``"euler"``: backward Euler, first order; its matrix is an M-matrix, so it never over- or
  undershoots (a discrete maximum principle).

The tridiagonal systems are solved by the Thomas algorithm vectorised over a batch of trials
(the factorisation is computed once per phase), so one call simulates many trials at once:
material properties, conductances, heater power and initial profiles may differ per trial,
the grid and the timeline are shared.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from skin.errors import SkinError
from skin.models.physics import SensorConstants, heated_temperature

SCHEMES = ("tr-bdf2", "crank-nicolson", "euler")
_GAMMA = 2.0 - np.sqrt(2.0)  # TR-BDF2 stage fraction; makes both stages share one matrix
_DENSE_LIMIT = 6000  # batch * cells up to which a step is applied as a dense matrix product


class ModelError(SkinError):
    """Invalid multilayer model input (a layer, a phase, a time step)."""


@dataclass(frozen=True)
class Layer:
    """One solid layer of the column.

    Attributes
    ----------
    name : str
        What it is (``"sensor body"``).
    thickness : float
        m.
    conductivity : float
        k, W/(m K).
    diffusivity : float
        alpha = k / (rho c), m^2/s.
    cells : int
        Number of finite-volume cells.
    grading : float
        Ratio of the cell farthest from the contact surface to the nearest one (1 = uniform).
    """

    name: str
    thickness: float
    conductivity: float
    diffusivity: float
    cells: int
    grading: float = 1.0

    def __post_init__(self) -> None:
        for key in ("thickness", "conductivity", "diffusivity", "grading"):
            value = getattr(self, key)
            if not (np.isfinite(value) and value > 0):
                raise ModelError(f"layer {self.name!r}: {key} must be positive, got {value!r}")
        if isinstance(self.cells, bool) or not isinstance(self.cells, (int, np.integer)) \
                or self.cells < 1:
            raise ModelError(f"layer {self.name!r}: cells must be a whole number >= 1, "
                             f"got {self.cells!r}")

    def widths(self) -> np.ndarray:
        """Cell widths from the contact side inwards (geometric when graded), summing to l."""
        if self.cells == 1 or self.grading == 1.0:
            return np.full(self.cells, self.thickness / self.cells)
        ratio = self.grading ** (1.0 / (self.cells - 1))
        w = ratio ** np.arange(self.cells)
        return self.thickness * w / w.sum()


@dataclass(frozen=True)
class SensorStack:
    """The taxel's layers from the contact surface inwards, its heater and its losses.

    Attributes
    ----------
    layers : tuple of Layer
        From the contact surface inwards.
    heater_layer : int
        Index of the layer that dissipates the heater power (uniformly through it).
    thermistor_depth : float
        Depth of the thermistor below the contact surface, m.
    heater_power : float
        Heater power per area at full duty, W/m^2.
    front_loss : float
        Loss coefficient of the free contact surface to ambient, W/(m^2 K) (0 = insulated).
    back_loss : float
        Loss coefficient of the back face to ambient, W/(m^2 K) (0 = insulated).
    edge_loss : float
        Loss through the taxel's edges and leads, W/(m^2 K) of face area, spread over the
        layers in front of the foam (by thickness); unlike ``front_loss`` it stays in contact.
    """

    layers: tuple[Layer, ...]
    heater_layer: int
    thermistor_depth: float
    heater_power: float
    front_loss: float
    back_loss: float
    edge_loss: float = 0.0

    def __post_init__(self) -> None:
        if not self.layers:
            raise ModelError("a sensor stack needs at least one layer")
        if not 0 <= self.heater_layer < len(self.layers):
            raise ModelError(f"heater layer {self.heater_layer} is not one of the stack's "
                             f"{len(self.layers)} layers (0..{len(self.layers) - 1})")
        for key in ("heater_power", "front_loss", "back_loss", "edge_loss"):
            value = getattr(self, key)
            if not (np.isfinite(value) and value >= 0):
                raise ModelError(f"sensor stack: {key} must be >= 0 and finite, got {value!r}")

    @classmethod
    def paper(
        cls,
        sensor: SensorConstants | None = None,
        cells: int = 24,
        front_loss: float = 12.0,
        back_loss: float = 10.0,
        edge_loss: float = 33.0,
    ) -> SensorStack:
        """Build the paper's taxel as a column: sensor body, heater foil, foam backing.

        The sensor body has the paper's fitted ``k_s`` and ``alpha_s`` and thickness ``l``, with
        the thermistor at depth ``x``; behind it a 25 um polyimide heater foil and 3 mm of
        polyurethane foam. ``front_loss`` is natural convection and radiation from the free face
        (about 12 W/(m^2 K) for a small plate); ``edge_loss`` stands for the edges and leads a
        1-D column cannot see, which keep losing heat during a contact. Together, 45
        W/(m^2 K) give a reheat time constant of about 63 s, near the 65 s that reproduces the
        paper's initial temperatures (26-40 C, mean 30 C, after 2-60 s reheats). The heater
        power is set so that the free steady state at the thermistor is eq. 2's T_sens(0)
        (38.96 C at 25 C ambient): about a third of V^2 / (R A), the power a 1-D column with
        these losses can hold at that temperature.

        Parameters
        ----------
        sensor : SensorConstants, optional
            The taxel's constants (default: the paper's).
        cells : int
            Cells across the sensor body (the foil and foam get a quarter each, at least 4).
        front_loss, back_loss, edge_loss : float
            Loss coefficients of the free face, the back and the edges, W/(m^2 K).
        """
        s = SensorConstants() if sensor is None else sensor
        if not 0 < s.depth < s.thickness:
            raise ModelError(f"thermistor depth {s.depth} m is not inside the sensor body "
                             f"(0, {s.thickness}) m")
        body = Layer("sensor body", s.thickness, s.conductivity, s.diffusivity, cells)
        foil = Layer("heater foil", 25e-6, 0.12, 0.12 / (1420 * 1090), max(4, cells // 4))
        foam = Layer("foam backing", 3e-3, 0.03, 0.03 / (30 * 1400), max(4, cells // 4), 8.0)
        stack = cls((body, foil, foam), 1, s.depth, 1.0, front_loss, back_loss, edge_loss)
        rise = float(heated_temperature(0.0, s))
        per_watt = _steady_thermistor_rise(stack)
        return cls((body, foil, foam), 1, s.depth, rise / per_watt, front_loss, back_loss,
                   edge_loss)

    @property
    def thickness(self) -> float:
        """Total thickness, m."""
        return float(sum(layer.thickness for layer in self.layers))


@dataclass(frozen=True)
class ObjectBody:
    """The touched object as a slab; properties may be arrays, one value per trial.

    Attributes
    ----------
    conductivity, diffusivity : float or numpy.ndarray
        k (W/(m K)) and alpha (m^2/s), scalars or one per trial.
    thickness : float
        m (shared by the batch: the grid is shared).
    cells : int
        Number of cells.
    grading : float
        Ratio of the deepest cell to the surface cell.
    surface_loss : float
        Loss coefficient of its free surface to ambient, W/(m^2 K) (0 = insulated).
    back : str
        ``"insulated"`` (lying on a table) or ``"ambient"`` (its back held at ambient).
    """

    conductivity: float | np.ndarray
    diffusivity: float | np.ndarray
    thickness: float = 0.02
    cells: int = 40
    grading: float = 200.0
    surface_loss: float = 10.0
    back: str = "insulated"

    def __post_init__(self) -> None:
        for key in ("conductivity", "diffusivity"):
            v = np.asarray(getattr(self, key), dtype=float)
            if v.ndim > 1 or not np.all(np.isfinite(v) & (v > 0)):
                raise ModelError(f"object {key} must be positive and finite (a scalar or one "
                                 f"per trial), got {getattr(self, key)!r}")
        if not (np.isfinite(self.surface_loss) and self.surface_loss >= 0):
            raise ModelError(f"object surface_loss must be >= 0 and finite (0 = insulated), "
                             f"got {self.surface_loss!r}")
        if self.back not in ("insulated", "ambient"):
            raise ModelError(f"object back must be 'insulated' or 'ambient', got {self.back!r}")
        Layer("object", self.thickness, 1.0, 1.0, self.cells, self.grading)  # validates the grid

    @classmethod
    def of(cls, k: float | np.ndarray, rho: float | np.ndarray, c: float | np.ndarray,
           **kwargs: object) -> ObjectBody:
        """Build from conductivity, density and specific heat."""
        k = np.asarray(k, dtype=float)
        return cls(conductivity=k, diffusivity=k / (np.asarray(rho) * np.asarray(c)), **kwargs)


@dataclass(frozen=True)
class Phase:
    """A stretch of time with constant conditions.

    Attributes
    ----------
    duration : float
        s.
    contact : bool
        Whether the taxel touches the object.
    heater : float or numpy.ndarray
        Heater duty in [0, 1] (of the stack's ``heater_power``), scalar or one per trial.
    conductance : float or numpy.ndarray
        Contact conductance h while in contact, W/(m^2 K) (``inf``: perfect contact).
    record : bool
        Whether the thermistor is sampled during this phase.
    """

    duration: float
    contact: bool
    heater: float | np.ndarray = 1.0
    conductance: float | np.ndarray = np.inf
    record: bool = True


@dataclass
class ColumnState:
    """Cell temperatures of a batch of columns, shape (n_cells, n_trials), deg C."""

    u: np.ndarray
    time: float = 0.0


@dataclass
class MultilayerResult:
    """What `MultilayerModel.run` returns.

    Attributes
    ----------
    t : numpy.ndarray
        Sample times since the start of the run, s, shape (n_samples,).
    thermistor : numpy.ndarray
        Thermistor readings, shape (n_trials, n_samples), deg C.
    state : ColumnState
        The state at the end (to continue from).
    """

    t: np.ndarray
    thermistor: np.ndarray
    state: ColumnState
    steps: int = field(default=0)


class MultilayerModel:
    """Finite-volume column of object + taxel, stepped implicitly (see the module docstring).

    Parameters
    ----------
    stack : SensorStack
        The taxel's layers.
    body : ObjectBody
        The object (properties may be per trial).
    ambient : float or numpy.ndarray
        Ambient temperature, deg C (scalar or one per trial).
    scheme : str
        ``"tr-bdf2"``, ``"crank-nicolson"`` or ``"euler"``.
    dt : float
        Largest time step, s (each phase is split into equal steps no longer than this).
    """

    def __init__(self, stack: SensorStack, body: ObjectBody, ambient: float | np.ndarray = 25.0,
                 scheme: str = "tr-bdf2", dt: float = 0.005) -> None:
        if scheme not in SCHEMES:
            raise ModelError(f"unknown scheme {scheme!r}; choose one of {', '.join(SCHEMES)}")
        if not (np.isfinite(dt) and dt > 0):
            raise ModelError(f"time step must be positive, got {dt!r}")
        self.stack, self.body, self.scheme, self.dt = stack, body, scheme, float(dt)
        self.ambient = np.asarray(ambient, dtype=float)
        k_o = np.atleast_1d(np.asarray(body.conductivity, dtype=float))
        a_o = np.atleast_1d(np.asarray(body.diffusivity, dtype=float))
        sizes = {v.size for v in (k_o, a_o, np.atleast_1d(self.ambient))} - {1}
        if len(sizes) > 1:
            raise ModelError(f"per-trial arrays disagree in length: {sorted(sizes)}")
        self.batch = sizes.pop() if sizes else 1

        # object cells from its back to its surface (fine at the surface), then the stack's
        w_obj = Layer("object", body.thickness, 1.0, 1.0, body.cells, body.grading).widths()[::-1]
        widths = [w_obj] + [layer.widths() for layer in stack.layers]
        self.n_object = body.cells
        self.width = np.concatenate(widths)
        n = self.width.size
        k = np.empty((n, self.batch))
        rho_c = np.empty((n, self.batch))
        k[: body.cells] = k_o
        rho_c[: body.cells] = k_o / a_o
        i = body.cells
        self.heater_share = np.zeros(n)  # fraction of the heater power each cell dissipates
        self.edge_share = np.zeros(n)  # fraction of the edge loss each cell carries
        front = stack.layers[:-1] if len(stack.layers) > 1 else stack.layers
        front_thickness = sum(layer.thickness for layer in front)
        for j, layer in enumerate(stack.layers):
            sl = slice(i, i + layer.cells)
            if j < len(front):
                self.edge_share[sl] = self.width[sl] / front_thickness
            k[sl] = layer.conductivity
            rho_c[sl] = layer.conductivity / layer.diffusivity
            if j == stack.heater_layer:
                self.heater_share[sl] = self.width[sl] / layer.thickness
            i += layer.cells
        self.k = k
        self.capacity = rho_c * self.width[:, None]  # J/(m^2 K)
        # half-cell resistances; the link between cells i and i+1 is the sum of two halves
        half = self.width[:, None] / (2.0 * k)
        self._link = 1.0 / (half[:-1] + half[1:])  # (n-1, batch); the contact link is set later
        self.surface = body.cells  # index of the sensor's surface cell
        self._half = half
        # the thermistor: linear interpolation between the two sensor cell centres around it
        centres = np.cumsum(self.width[self.surface:]) - self.width[self.surface:] / 2
        depth = stack.thermistor_depth
        if not 0 <= depth <= stack.thickness:
            raise ModelError(f"thermistor depth {depth} m is outside the stack")
        j = int(np.clip(np.searchsorted(centres, depth) - 1, 0, centres.size - 2))
        frac = float(np.clip((depth - centres[j]) / (centres[j + 1] - centres[j]), 0.0, 1.0))
        self._probe = (self.surface + j, frac)

    # ----------------------------------------------------------------- geometry and states
    @property
    def depth(self) -> np.ndarray:
        """Cell centres as depth below the contact surface, m (negative inside the object)."""
        edges = np.concatenate([[0.0], np.cumsum(self.width)]) - self.width[: self.n_object].sum()
        return (edges[:-1] + edges[1:]) / 2.0

    def thermistor(self, state: ColumnState) -> np.ndarray:
        """Thermistor reading of each trial, deg C."""
        i, f = self._probe
        return (1.0 - f) * state.u[i] + f * state.u[i + 1]

    def state(self, sensor: float | np.ndarray | Callable[[np.ndarray], np.ndarray],
              obj: float | np.ndarray | Callable[[np.ndarray], np.ndarray]) -> ColumnState:
        """Build an initial state from the sensor's and the object's temperatures.

        Each may be a scalar, one value per trial, or a function of depth (m below the contact
        surface for the sensor, m below the object's surface for the object; positive) that
        returns a profile (non-uniform, e.g. an object the taxel warmed a moment ago).
        """
        u = np.empty((self.width.size, self.batch))
        d = self.depth
        for sl, value, depth, name in (
                (slice(0, self.surface), obj, -d[: self.surface], "object"),
                (slice(self.surface, None), sensor, d[self.surface:], "sensor")):
            if callable(value):
                prof = np.asarray(value(depth), dtype=float)
                u[sl] = prof if prof.ndim == 2 else prof[:, None]
            else:
                u[sl] = _per_trial(value, self.batch, f"per-trial {name} temperature")
        if not np.all(np.isfinite(u)):
            raise ModelError("initial temperatures must be finite")
        return ColumnState(u)

    def steady_state(self, heater: float | np.ndarray = 1.0,
                     obj: float | np.ndarray | None = None) -> ColumnState:
        """Free (no contact) steady state with the heater at ``heater`` duty.

        The object sits at ``obj`` (default: ambient) and is not part of the solve.
        """
        lower, diag, upper, b, _, loss = self._system(0.0, 1.0, False, heater, np.inf)
        if np.any(loss[self.surface:].sum(axis=0) <= 0):
            raise ModelError("the free taxel loses no heat to ambient (front, back and edge "
                             "losses all 0): it has no steady state")
        u = _solve(_factor(lower, diag, upper), b)  # -A u = b
        amb = np.broadcast_to(self.ambient, (self.batch,))
        u[: self.surface] = amb if obj is None else np.asarray(obj, dtype=float)
        return ColumnState(u)

    def reheat_time_constant(self) -> np.ndarray:
        """Slowest time constant of the free taxel (heater on, no contact), s, per trial.

        The smallest eigenvalue of ``C^-1 (-A)`` over the taxel's cells, from the symmetric
        tridiagonal ``C^-1/2 (-A) C^-1/2``.
        """
        from scipy.linalg import eigh_tridiagonal

        lower, diag, _, _, _, _ = self._system(0.0, 1.0, False, 1.0, np.inf)
        s = self.surface
        out = np.empty(self.batch)
        for b in range(self.batch):
            scale = 1.0 / np.sqrt(self.capacity[s:, b])
            d = diag[s:, b] * scale**2
            e = lower[s:, b] * scale[:-1] * scale[1:]
            lam = eigh_tridiagonal(d, e, eigvals_only=True, select="i", select_range=(0, 0))
            out[b] = 1.0 / lam[0]
        return out

    # ---------------------------------------------------------------------- the operator
    def _system(self, capacity_factor: float, theta_dt: float, contact: bool,
                heater: float | np.ndarray, conductance: float | np.ndarray
                ) -> tuple[np.ndarray, ...]:
        """Return the tridiagonal ``capacity_factor * C - theta_dt * A`` and its parts.

        The tuple is ``(lower, diag, upper, b, link, loss)``: ``b`` is the source, ``link``
        and ``loss`` are the conductances that make ``A``. With ``capacity_factor`` 0 and
        ``theta_dt`` 1 it is ``-A`` (for the steady state).
        """
        link = self._link.copy()
        s = self.surface
        loss = np.zeros_like(self.capacity)
        amb = np.broadcast_to(self.ambient, (self.batch,))
        h_c = _per_trial(conductance, self.batch, "per-trial contact conductance")
        if contact:
            if np.any(~(h_c > 0)):
                raise ModelError("contact conductance must be positive (inf = perfect)")
            link[s - 1] = 1.0 / (self._half[s - 1] + self._half[s] + 1.0 / h_c)
        else:
            link[s - 1] = 0.0
            loss[s - 1] = _in_series(self._half[s - 1], self.body.surface_loss)
            loss[s] = _in_series(self._half[s], self.stack.front_loss)
        loss[-1] = _in_series(self._half[-1], self.stack.back_loss)
        loss += self.edge_share[:, None] * self.stack.edge_loss
        if self.body.back == "ambient":  # added: a one-cell object also has its free surface
            loss[0] += 1.0 / self._half[0]
        duty = _per_trial(heater, self.batch, "per-trial heater duty")
        b = loss * amb + self.heater_share[:, None] * (self.stack.heater_power * duty)
        diag = capacity_factor * self.capacity + theta_dt * loss
        diag[:-1] += theta_dt * link
        diag[1:] += theta_dt * link
        off = -theta_dt * link
        return off, diag, off, b, link, loss

    # ------------------------------------------------------------------------ stepping
    def run(self, state: ColumnState, phases: Sequence[Phase], fs: float = 200.0
            ) -> MultilayerResult:
        """Step through ``phases`` from ``state``; sample the thermistor at ``fs`` Hz.

        Samples fall at multiples of 1/fs from the start of the run, in the phases whose
        ``record`` is set (interpolated linearly between steps when a step is longer than
        the sample period); the first sample is the state at t = 0 if the first phase records.
        """
        if not (np.isfinite(fs) and fs > 0):
            raise ModelError(f"sampling rate fs must be positive, got {fs!r}")
        u = np.array(state.u, dtype=float)
        if u.shape != (self.width.size, self.batch):
            raise ModelError(f"state has shape {u.shape}, expected {(self.width.size, self.batch)}")
        times: list[np.ndarray] = []
        values: list[np.ndarray] = []
        t0 = 0.0
        steps = 0
        next_k = 0  # index of the next sample time k / fs not yet taken
        for p, phase in enumerate(phases):
            if not (np.isfinite(phase.duration) and phase.duration >= 0):
                raise ModelError(f"phase {p}: duration must be >= 0, got {phase.duration!r}")
            duty = np.asarray(phase.heater, dtype=float)
            if np.any(~np.isfinite(duty)) or np.any(duty < 0) or np.any(duty > 1):
                raise ModelError(f"phase {p}: heater duty must be in [0, 1], got {phase.heater!r}")
            if phase.duration == 0:
                continue
            n = max(1, int(np.ceil(phase.duration / self.dt - 1e-9)))
            dt = phase.duration / n
            u, probe = self._advance(u, n, dt, phase, record=phase.record)
            steps += n
            t1 = t0 + phase.duration
            first = max(next_k, int(np.ceil(t0 * fs - 1e-6)))
            last = int(np.floor(t1 * fs + 1e-6))
            next_k = max(next_k, last + 1)
            if phase.record and last >= first:
                ts = np.arange(first, last + 1) / fs
                ys = np.asarray(probe)  # (n + 1, batch) at t0 + i dt
                pos = np.clip((ts - t0) / dt, 0.0, n)
                idx = np.minimum(pos.astype(int), n - 1)
                w = (pos - idx)[:, None]
                times.append(ts)
                values.append((1 - w) * ys[idx] + w * ys[idx + 1])
            t0 = t1
        t = np.concatenate(times) if times else np.empty(0)
        y = np.concatenate(values).T if values else np.empty((self.batch, 0))
        return MultilayerResult(t, y, ColumnState(u, state.time + t0), steps)

    def _advance(self, u: np.ndarray, n: int, dt: float, phase: Phase, record: bool
                 ) -> tuple[np.ndarray, np.ndarray | None]:
        """Take ``n`` steps of ``dt`` through one phase.

        Returns the final state and, if ``record``, the thermistor at the n + 1 step times.
        A step is an affine map ``u -> P u + q``. Small batches build ``P`` once per phase
        (one banded solve with the identity as right-hand sides) and apply it as a matrix
        product, squaring it when nothing is recorded; large batches step by banded solves.
        """
        step, first = self._stepper(dt, phase)
        probe = [self.thermistor(ColumnState(u))] if record else []
        k = 0
        while k < n and first is not None and k < 2:
            u = first(u)  # the damped start of Crank-Nicolson
            k += 1
            if record:
                probe.append(self.thermistor(ColumnState(u)))
        m = n - k
        if m and self.batch * self.width.size <= _DENSE_LIMIT:
            zero = np.zeros_like(u)
            q = step(zero)  # (n_cells, batch)
            eye = np.broadcast_to(np.eye(self.width.size)[:, None, :],
                                  (self.width.size, self.batch, self.width.size))
            p = np.moveaxis(step(np.ascontiguousarray(eye)), 1, 0)  # (batch, n, n), no sources
            v = u.T[:, :, None]
            if record:
                i, f = self._probe
                for _ in range(m):
                    v = p @ v + q.T[:, :, None]
                    probe.append((1.0 - f) * v[:, i, 0] + f * v[:, i + 1, 0])
            else:
                v = _power_apply(p, q.T[:, :, None], v, m)
            u = np.ascontiguousarray(v[:, :, 0].T)
        else:
            for _ in range(m):
                u = step(u)
                if record:
                    probe.append(self.thermistor(ColumnState(u)))
        return u, (np.asarray(probe) if record else None)

    def _stepper(self, dt: float, phase: Phase):
        """Return ``(step, first)``, functions that take a state to the next one.

        ``first`` is the damped start of Crank-Nicolson (None for the other schemes). States
        are arrays (n_cells, batch) or (n_cells, batch, columns).
        """
        contact, heater, h = phase.contact, phase.heater, phase.conductance
        cap = self.capacity
        g = {"euler": 1.0, "crank-nicolson": 0.5, "tr-bdf2": _GAMMA / 2}[self.scheme]
        lower, diag, upper, b, link, loss = self._system(1.0, g * dt, contact, heater, h)
        lu = _factor(lower, diag, upper)

        def c(x: np.ndarray, u: np.ndarray) -> np.ndarray:  # coefficients shaped like u
            return x if u.ndim == 2 else x[:, :, None]

        def apply(u: np.ndarray) -> np.ndarray:  # A u, without sources
            flow = c(link, u) * (u[1:] - u[:-1])
            out = -c(loss, u) * u
            out[:-1] += flow
            out[1:] -= flow
            return out

        def source(u: np.ndarray, scale: float) -> np.ndarray:
            return b * scale if u.ndim == 2 else np.zeros(1)

        # a source term only in the affine part: the identity columns carry none of it
        if self.scheme == "euler":
            def step(u: np.ndarray) -> np.ndarray:
                return _solve(lu, c(cap, u) * u + source(u, dt))
            return step, None
        if self.scheme == "crank-nicolson":
            def step(u: np.ndarray) -> np.ndarray:
                return _solve(lu, c(cap, u) * u + dt / 2 * apply(u) + source(u, dt))

            def first(u: np.ndarray) -> np.ndarray:  # Rannacher: two backward Euler half steps
                u = _solve(lu, c(cap, u) * u + source(u, dt / 2))
                return _solve(lu, c(cap, u) * u + source(u, dt / 2))
            return step, first
        w1 = 1.0 / (_GAMMA * (2.0 - _GAMMA))
        w0 = (1.0 - _GAMMA) ** 2 / (_GAMMA * (2.0 - _GAMMA))

        def step(u: np.ndarray) -> np.ndarray:
            mid = _solve(lu, c(cap, u) * u + g * dt * apply(u) + source(u, _GAMMA * dt))
            return _solve(lu, c(cap, u) * (w1 * mid - w0 * u) + source(u, g * dt))

        # TR-BDF2's amplification R(z) is negative for z = lambda dt < -2.41 (down to about
        # -0.2): with long steps the modes a jump excites (the contact, the heater switching)
        # fall there and the object's temperature undershoots (0.25 K, diamond, dt = 0.5 s).
        # A damped start as for Crank-Nicolson: backward Euler half steps (an M-matrix, no
        # under- or overshoot) smooth the jump; they cost one more factorisation per phase.
        lower, diag, upper, _, _, _ = self._system(1.0, dt / 2, contact, heater, h)
        lu_half = _factor(lower, diag, upper)

        def first(u: np.ndarray) -> np.ndarray:
            u = _solve(lu_half, c(cap, u) * u + source(u, dt / 2))
            return _solve(lu_half, c(cap, u) * u + source(u, dt / 2))
        return step, first


def _power_apply(p: np.ndarray, q: np.ndarray, v: np.ndarray, m: int) -> np.ndarray:
    """Apply ``v -> p v + q`` ``m`` times by repeated squaring (O(log m) matrix products)."""
    while m:
        if m & 1:
            v = p @ v + q
        m >>= 1
        if m:
            q = p @ q + q
            p = p @ p
    return v


def _in_series(half: np.ndarray, coefficient: float) -> np.ndarray:
    """Conductance of a half cell in series with a surface loss ``coefficient`` (0 = insulated).

    ``1 / (half + 1 / h)`` written as ``h / (1 + h half)``, which is exactly 0 for ``h = 0``.
    """
    return coefficient / (1.0 + coefficient * half)


def _per_trial(value: object, batch: int, what: str) -> np.ndarray:
    """Broadcast a scalar or one-per-trial array to (batch,), or raise `ModelError`."""
    a = np.asarray(value, dtype=float)
    if a.ndim > 1 or (a.ndim == 1 and a.size not in (1, batch)):
        raise ModelError(f"{what}: expected a scalar or one value per trial ({batch}), "
                         f"got shape {a.shape}")
    return np.broadcast_to(a.reshape(-1) if a.ndim else a, (batch,))


def _factor(lower: np.ndarray, diag: np.ndarray, upper: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Thomas factorisation of a batch of tridiagonal matrices, arrays (n, batch).

    No pivoting: the matrices are diagonally dominant (capacity plus conductances).
    """
    n = diag.shape[0]
    inv = np.empty_like(diag)
    cp = np.empty_like(upper)
    inv[0] = 1.0 / diag[0]
    for i in range(1, n):
        cp[i - 1] = upper[i - 1] * inv[i - 1]
        inv[i] = 1.0 / (diag[i] - lower[i - 1] * cp[i - 1])
    return lower, inv, cp


def _solve(lu: tuple[np.ndarray, np.ndarray, np.ndarray], d: np.ndarray) -> np.ndarray:
    """Solve with a `_factor` result for right-hand sides ``d`` (n, batch)."""
    lower, inv, cp = lu
    if d.ndim == 3:  # several right-hand sides per trial
        lower, inv, cp = lower[:, :, None], inv[:, :, None], cp[:, :, None]
    n = d.shape[0]
    y = np.empty_like(d)
    y[0] = d[0] * inv[0]
    for i in range(1, n):
        y[i] = (d[i] - lower[i - 1] * y[i - 1]) * inv[i]
    for i in range(n - 2, -1, -1):
        y[i] -= cp[i] * y[i + 1]
    return y


def _steady_thermistor_rise(stack: SensorStack) -> float:
    """Free steady rise of the thermistor over ambient per W/m^2 of heater power."""
    probe = ObjectBody(1.0, 1e-6, thickness=1e-3, cells=1, grading=1.0)
    model = MultilayerModel(stack, probe, ambient=0.0)
    return float(model.thermistor(model.steady_state(1.0))[0]) / stack.heater_power
