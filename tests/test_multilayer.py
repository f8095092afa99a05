"""The finite-contact-conductance closed form and the 1-D multilayer column model.

Tolerances below were measured on this code (numbers in the comments) and given a margin.
"""

import dataclasses
import warnings

import numpy as np
import pytest

import skin.models.multilayer as ml
from skin.models.multilayer import (
    SCHEMES,
    ColumnState,
    Layer,
    ModelError,
    MultilayerModel,
    ObjectBody,
    Phase,
    SensorStack,
)
from skin.models.physics import (
    SensorConstants,
    conductance_rate,
    contact_response,
    contact_temperature,
    contact_trace,
    depth_response,
    effusivity,
    heated_temperature,
    thermistor_temperature,
)

pytestmark = pytest.mark.filterwarnings("error")  # any RuntimeWarning is a failure

AMBIENT = 25.0
SENSOR = SensorConstants()
T_SENSOR = float(heated_temperature(AMBIENT, SENSOR))  # eq. 2: 38.963 C
E_S = SENSOR.effusivity

# (k W/(m K), alpha m^2/s)
ALUMINIUM = (80.0, 3.55e-5)
PINE = (0.15, 2.05e-7)
COPPER = (400.0, 1.17e-4)
# (k, rho, c): the stiff and the extreme objects
STIFF = {
    "copper": (400.0, 8933.0, 385.0),
    "diamond": (2200.0, 3500.0, 509.0),
    "polyurethane foam": (0.03, 30.0, 1400.0),
    "silica aerogel": (0.015, 100.0, 1000.0),
}
E_OBJECTS = {
    "aluminium": ALUMINIUM[0] / np.sqrt(ALUMINIUM[1]),
    "pine": PINE[0] / np.sqrt(PINE[1]),
    "copper": float(effusivity(*STIFF["copper"])),
    "polyurethane foam": float(effusivity(*STIFF["polyurethane foam"])),
}


def eq5(t, e_object, t_object=AMBIENT, t_sensor=T_SENSOR):
    """The paper's perfect-contact reading (eqs. 3 and 5)."""
    surface = contact_temperature(t_sensor, t_object, E_S, e_object)
    return thermistor_temperature(t, t_sensor, surface, SENSOR)


def thick_stack(body_cells):
    """The paper's taxel with a 1 mm sensor body and no edge loss: eq. 5's semi-infinite solid
    over a few seconds."""
    stack = SensorStack.paper()
    body = dataclasses.replace(stack.layers[0], thickness=1e-3, cells=body_cells)
    return dataclasses.replace(stack, layers=(body, *stack.layers[1:]), edge_loss=0.0)


def semi_infinite_error(material, body_cells, object_cells, conductance=np.inf, dt=4e-3,
                        duration=2.0):
    """RMS and max error of the multilayer reading against `contact_trace` (heater off)."""
    k, alpha = material
    body = ObjectBody(k, alpha, thickness=0.1, cells=object_cells, grading=200.0)
    model = MultilayerModel(thick_stack(body_cells), body, ambient=AMBIENT, dt=dt)
    run = model.run(model.state(T_SENSOR, AMBIENT),
                    [Phase(duration, True, heater=0.0, conductance=conductance)])
    exact = contact_trace(run.t, T_SENSOR, AMBIENT, k / np.sqrt(alpha), SENSOR, conductance)
    err = run.thermistor[0] - exact
    return float(np.sqrt(np.mean(err**2))), float(np.abs(err).max()), exact


def stiff_body(**kwargs):
    """One column per stiff/extreme object, in the order of STIFF."""
    k, rho, c = (np.array(v) for v in zip(*STIFF.values(), strict=True))
    return ObjectBody.of(k, rho, c, **kwargs)


class StepRecorder(MultilayerModel):
    """A model that keeps a copy of the state after every time step (the banded path only)."""

    def _stepper(self, dt, phase):
        step, first = super()._stepper(dt, phase)
        self.states = getattr(self, "states", [])

        def keep(f):
            if f is None:
                return None

            def wrapped(u):
                out = f(u)
                if out.ndim == 2:  # a state, not the identity columns of the dense path
                    self.states.append(out.copy())
                return out
            return wrapped

        return keep(step), keep(first)


# ------------------------------------------------------------------ the closed form with h


@pytest.mark.parametrize("name", sorted(E_OBJECTS))
def test_contact_trace_with_perfect_contact_is_eq5_exactly(name):
    e = E_OBJECTS[name]
    t = np.linspace(-1.0, 10.0, 1101)
    expected = eq5(t, e)
    assert np.array_equal(contact_trace(t, T_SENSOR, AMBIENT, e, SENSOR), expected)
    assert np.array_equal(contact_trace(t, T_SENSOR, AMBIENT, e, SENSOR, np.inf), expected)
    assert np.array_equal(contact_response(t, np.inf, SENSOR), depth_response(t, SENSOR))


@pytest.mark.parametrize("name", sorted(E_OBJECTS))
def test_contact_trace_converges_to_eq5_as_conductance_grows(name):
    e = E_OBJECTS[name]
    t = np.linspace(0.0, 10.0, 1001)
    errors = [np.abs(contact_trace(t, T_SENSOR, AMBIENT, e, SENSOR, h) - eq5(t, e)).max()
              for h in (1e3, 1e5, 1e7)]
    # measured: aluminium 1.92, 0.0267, 2.68e-4 K; each factor of 100 in h gains 70-100x
    assert errors[0] > errors[1] > errors[2]
    assert errors[0] / errors[1] > 30
    assert errors[1] / errors[2] > 30
    assert errors[2] < 1e-3


def test_contact_trace_with_zero_conductance_does_not_move():
    t = np.linspace(-1.0, 3600.0, 500)
    for e in E_OBJECTS.values():
        assert np.all(contact_trace(t, T_SENSOR, AMBIENT, e, SENSOR, 0.0) == T_SENSOR)
    assert np.all(contact_response(t, 0.0, SENSOR) == 0.0)
    assert conductance_rate(0.0, E_S, 1e4) == 0.0
    assert conductance_rate(np.inf, E_S, 1e4) == np.inf


@pytest.mark.parametrize("h", [0.0, 1e2, 1e3, 1e5, np.inf])
@pytest.mark.parametrize("t", [-1.0, 0.0, 1e-6, 3600.0])
def test_contact_trace_finite_and_in_range_at_special_times(t, h):
    e = E_OBJECTS["aluminium"]
    surface = float(contact_temperature(T_SENSOR, AMBIENT, E_S, e))
    y = float(contact_trace(t, T_SENSOR, AMBIENT, e, SENSOR, h))
    assert np.isfinite(y)
    assert surface <= y <= T_SENSOR
    if t <= 0:
        assert y == T_SENSOR  # before contact
    if t == 1e-6:
        assert y == pytest.approx(T_SENSOR, abs=1e-12)  # the step has not reached x yet
    if t == 3600.0 and h >= 1e3:
        assert y < surface + 0.3  # measured 25.84 (h = inf), 25.92 (h = 1e3) vs 25.65


@pytest.mark.parametrize("h", [1e2, 1e3, 1e5, np.inf])
def test_contact_trace_rises_monotonically_towards_the_surface(h):
    t = np.linspace(0.0, 3600.0, 20001)
    y = contact_trace(t, T_SENSOR, AMBIENT, E_OBJECTS["aluminium"], SENSOR, h)
    assert np.all(np.diff(y) <= 1e-12)  # cooling only
    r = contact_response(t, conductance_rate(h, E_S, E_OBJECTS["aluminium"]), SENSOR)
    assert np.all((r >= 0) & (r < 1))


def test_contact_trace_broadcasts_time_against_parameter_columns():
    t = np.linspace(0.0, 5.0, 51)
    h = np.array([[0.0], [1e2], [1e4], [np.inf]])
    e = np.array([[300.0], [3000.0], [13427.0], [30000.0]])
    t_sensor = np.array([[30.0], [35.0], [38.963], [40.0]])
    out = contact_trace(t, t_sensor, AMBIENT, e, SENSOR, h)
    assert out.shape == (4, 51)
    for i in range(4):
        row = contact_trace(t, t_sensor[i, 0], AMBIENT, e[i, 0], SENSOR, h[i, 0])
        np.testing.assert_array_equal(out[i], row)
    assert contact_response(t, np.array([[1.0], [np.inf]]), SENSOR).shape == (2, 51)


def test_contact_trace_emits_no_warnings_at_extremes():
    t = np.array([-np.inf, -1.0, 0.0, 1e-300, 1e-12, 1e-6, 1.0, 3600.0, 1e12, np.inf])[:, None]
    h = np.array([0.0, 1e-300, 1.0, 1e3, 1e7, 1e300, np.inf])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for e in (*E_OBJECTS.values(), 1e-3, 1e6):
            y = contact_trace(t, T_SENSOR, AMBIENT, e, SENSOR, h)
            surface = float(contact_temperature(T_SENSOR, AMBIENT, E_S, e))
            assert np.all(np.isfinite(y))
            assert np.all((y >= surface - 1e-12) & (y <= T_SENSOR))


@pytest.mark.parametrize(("material", "h"), [(ALUMINIUM, 300.0), (ALUMINIUM, 1000.0),
                                             (PINE, 300.0), (PINE, 1000.0)],
                         ids=["aluminium-300", "aluminium-1000", "pine-300", "pine-1000"])
def test_contact_trace_with_finite_conductance_matches_the_multilayer_model(material, h):
    """Independent check: the column with a contact link 1/h against the Laplace solution."""
    errors = [semi_infinite_error(material, cells, obj, conductance=h)
              for cells, obj in ((48, 30), (96, 60), (192, 120))]
    rms = [e[0] for e in errors]
    exact = errors[0][2]
    k, alpha = material
    perfect = eq5(np.arange(exact.size) / 200.0, k / np.sqrt(alpha))
    assert np.abs(exact - perfect).max() > 0.25  # h matters: 0.29 (pine, 1000) .. 3.8 K
    # measured RMS (48, 96, 192 body cells): aluminium/1000 0.032, 0.0059, 0.0014 K;
    # pine/300 0.013, 0.0024, 0.00057 K; ratios 5.2-5.5 then 4.1-4.4
    assert rms[0] / rms[1] > 2.5
    assert rms[1] / rms[2] > 2.5
    assert rms[2] < 2.5e-3
    assert errors[2][1] < 5e-3  # max error, measured <= 3.4e-3


# --------------------------------------------------- spatial convergence to the paper's form


@pytest.mark.parametrize("material", [ALUMINIUM, PINE, COPPER], ids=["aluminium", "pine", "copper"])
def test_multilayer_converges_to_eq5_at_second_order_in_space(material):
    # dt = 4e-3 s: the time error is < 1e-5 K here (measured), the grid dominates
    rms = [semi_infinite_error(material, cells, obj, duration=3.0)[0]
           for cells, obj in ((48, 30), (96, 60), (192, 120))]
    # measured: aluminium 0.0268, 0.0060, 0.0016; pine 0.0147, 0.0030, 0.00076;
    # copper 0.0268, 0.0061, 0.0017 K (ratios 4.4-4.9 then 3.6-3.9)
    assert rms[0] / rms[1] > 2.5
    assert rms[1] / rms[2] > 2.5
    assert rms[2] < 2.5e-3


# --------------------------------------------------------------- time convergence per scheme


@pytest.fixture(scope="module")
def time_reference():
    """A fixed coarse grid and its solution with a tiny step (TR-BDF2, dt = 2.5e-4 s)."""
    stack = SensorStack.paper(cells=12)
    body = ObjectBody(*ALUMINIUM, cells=20)

    def run(scheme, dt):
        model = MultilayerModel(stack, body, ambient=AMBIENT, scheme=scheme, dt=dt)
        # heater on in contact, so the source terms are part of what converges
        return model.run(model.state(T_SENSOR, AMBIENT), [Phase(2.0, True, heater=1.0)], fs=20)

    return run, run("tr-bdf2", 2.5e-4)


@pytest.mark.parametrize(("scheme", "low", "high"),
                         [("euler", 1.7, 2.3), ("tr-bdf2", 3.0, 5.0),
                          ("crank-nicolson", 3.0, 5.0)])
def test_time_error_falls_at_the_order_of_the_scheme(time_reference, scheme, low, high):
    run, reference = time_reference
    later = reference.t > 0.5  # after the start-up transient; fs = 20 samples on every step
    errors = [np.abs(run(scheme, dt).thermistor - reference.thermistor)[:, later].max()
              for dt in (0.05, 0.025, 0.0125)]
    # measured ratios: euler 1.96, 1.98; tr-bdf2 4.13, 4.07; crank-nicolson 4.00, 4.00
    assert low < errors[0] / errors[1] < high
    assert low < errors[1] / errors[2] < high


# ------------------------------------------------------------------- stiff and extreme cases

# second-order schemes are not M-matrix schemes, so give them a (measured-safe) tolerance;
# measured worst overshoot over all schemes, dt and materials: 4e-10 K (round-off)
BOUND_TOL = {"euler": 1e-9, "tr-bdf2": 1e-8, "crank-nicolson": 1e-8}


@pytest.mark.parametrize("dt", [1e-4, 1e-2, 0.1])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_stiff_objects_stay_bounded_at_every_step(monkeypatch, scheme, dt):
    monkeypatch.setattr(ml, "_DENSE_LIMIT", 0)  # step by banded solves, so each step is seen
    model = StepRecorder(SensorStack.paper(), stiff_body(), ambient=AMBIENT, scheme=scheme,
                         dt=dt)
    model.states = []
    model.run(model.state(T_SENSOR, AMBIENT), [Phase(100 * dt, True, heater=0.0)], fs=1 / dt)
    u = np.array(model.states)
    assert len(u) == 100
    tol = BOUND_TOL[scheme]
    assert u.min() >= AMBIENT - tol  # measured -3.4e-12
    assert u.max() <= T_SENSOR + tol


@pytest.mark.parametrize("dt", [1e-4, 1e-2, 0.1])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_stiff_objects_cool_the_thermistor_monotonically(scheme, dt):
    model = MultilayerModel(SensorStack.paper(), stiff_body(), ambient=AMBIENT, scheme=scheme,
                            dt=dt)
    run = model.run(model.state(T_SENSOR, AMBIENT), [Phase(2.0, True, heater=0.0)], fs=1 / dt)
    tol = BOUND_TOL[scheme]
    assert run.thermistor.shape == (4, round(2.0 / dt) + 1)
    assert np.all(np.diff(run.thermistor, axis=1) <= tol)  # measured max rise 2.8e-14
    assert run.state.u.min() >= AMBIENT - tol  # measured -1.4e-10 (dense, dt = 1e-4)
    assert run.state.u.max() <= T_SENSOR + tol
    # and it cooled: copper and diamond by ~4.8 K, the foams by ~0.3 K in 2 s
    assert np.all(run.thermistor[:, -1] < T_SENSOR - 0.1)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_a_hotter_object_warms_the_thermistor_within_bounds(scheme):
    hot = 45.0
    # without the edge loss (a sink at ambient) the reading can only rise towards the object
    stack = dataclasses.replace(SensorStack.paper(), edge_loss=0.0)
    model = MultilayerModel(stack, stiff_body(), ambient=AMBIENT, scheme=scheme, dt=0.01)
    run = model.run(model.state(T_SENSOR, hot), [Phase(5.0, True, heater=0.0)], fs=100)
    y = run.thermistor
    tol = BOUND_TOL[scheme]
    assert np.all(np.diff(y, axis=1) >= -tol)  # heat flows in
    assert np.all(y[:, -1] > T_SENSOR + 0.1)
    assert y.max() <= hot + tol
    # the foam backing still loses heat to the 25 C ambient at the back
    assert run.state.u.min() >= AMBIENT - tol
    assert run.state.u.max() <= hot + tol


@pytest.mark.parametrize("scheme", SCHEMES)
def test_nothing_moves_when_everything_is_at_one_temperature(scheme):
    model = MultilayerModel(SensorStack.paper(), stiff_body(), ambient=30.0, scheme=scheme,
                            dt=0.1)
    run = model.run(model.state(30.0, 30.0),
                    [Phase(5.0, True, heater=0.0), Phase(5.0, False, heater=0.0)], fs=10)
    assert np.abs(run.thermistor - 30.0).max() < 1e-9  # measured 6.6e-12
    assert np.abs(run.state.u - 30.0).max() < 1e-9  # measured 2.7e-11


@pytest.mark.parametrize("dt", [1e-4, 1e-2, 0.1])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_an_hour_of_contact_stays_finite_and_bounded(scheme, dt):
    model = MultilayerModel(SensorStack.paper(), stiff_body(), ambient=AMBIENT, scheme=scheme,
                            dt=dt)
    run = model.run(model.state(T_SENSOR, AMBIENT),
                    [Phase(3600.0, True, heater=0.0, record=False)])
    assert run.t.size == 0
    assert run.thermistor.shape == (4, 0)
    assert run.steps == round(3600.0 / dt)
    assert run.state.time == 3600.0
    u = run.state.u
    assert np.all(np.isfinite(u))
    assert u.min() >= AMBIENT - BOUND_TOL[scheme]
    assert u.max() <= T_SENSOR + BOUND_TOL[scheme]
    # measured: the thermistor reads 25.0928 C after the hour with copper, for every dt
    assert model.thermistor(run.state)[0] == pytest.approx(25.0928, abs=1e-3)
    # heater on: with an insulated object all its power leaves through the foil, the foam
    # and the back, so no cell can exceed that path's steady rise (155.7 C; measured 154.0 C
    # in the polyurethane foam column after the hour)
    stack = model.stack
    back = sum(layer.thickness / layer.conductivity for layer in stack.layers[1:])
    ceiling = AMBIENT + stack.heater_power * (back + 1.0 / stack.back_loss)
    heated = model.run(model.state(T_SENSOR, AMBIENT),
                       [Phase(3600.0, True, heater=1.0, record=False)]).state.u
    assert np.all(np.isfinite(heated))
    assert heated.min() >= AMBIENT
    assert heated.max() <= ceiling


@pytest.mark.parametrize("heater", [0.0, 1.0])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_copper_at_a_long_step_does_not_ring(scheme, heater):
    model = MultilayerModel(SensorStack.paper(), ObjectBody.of(*STIFF["copper"]),
                            ambient=AMBIENT, scheme=scheme, dt=0.1)
    run = model.run(model.state(T_SENSOR, AMBIENT), [Phase(20.0, True, heater=heater)], fs=10)
    d = np.diff(run.thermistor[0])
    moving = d[np.abs(d) > 1e-12]  # steps that moved by more than round-off
    assert moving.size > 150
    assert np.count_nonzero(np.diff(np.sign(moving))) == 0  # measured: no sign change at all


# ------------------------------------------------------------------------ heater and history


def test_free_steady_state_puts_the_thermistor_at_eq2():
    model = MultilayerModel(SensorStack.paper(), ObjectBody(*ALUMINIUM), ambient=AMBIENT)
    steady = model.steady_state(1.0)
    assert model.thermistor(steady)[0] == pytest.approx(T_SENSOR, abs=1e-6)  # measured 8e-12
    assert np.all(steady.u[: model.surface] == AMBIENT)  # the object sits at ambient
    off = model.steady_state(0.0)
    assert np.abs(off.u - AMBIENT).max() < 1e-9


@pytest.mark.parametrize("scheme", SCHEMES)
def test_the_steady_state_is_a_fixed_point_of_every_scheme(scheme):
    model = MultilayerModel(SensorStack.paper(), ObjectBody(*ALUMINIUM), ambient=AMBIENT,
                            scheme=scheme, dt=0.1)
    steady = model.steady_state(1.0)
    run = model.run(steady, [Phase(10.0, False, heater=1.0)], fs=10)
    assert np.abs(run.state.u - steady.u).max() < 1e-9  # measured 2e-11
    assert np.abs(run.thermistor - T_SENSOR).max() < 1e-9


def test_reheating_from_ambient_approaches_eq2_with_a_one_minute_time_constant():
    model = MultilayerModel(SensorStack.paper(), ObjectBody(*ALUMINIUM), ambient=AMBIENT,
                            dt=0.05)
    run = model.run(model.state(AMBIENT, AMBIENT), [Phase(600.0, False, heater=1.0)], fs=1)
    y = run.thermistor[0]
    assert np.all(np.diff(y) > 0)  # measured smallest rise per second 3e-5 K
    assert T_SENSOR - 0.01 < y[-1] < T_SENSOR  # measured 0.002 K short after 600 s
    gap = (T_SENSOR - y) / (T_SENSOR - AMBIENT)
    late = (run.t >= 100) & (run.t <= 400)
    tau = -1.0 / np.polyfit(run.t[late], np.log(gap[late]), 1)[0]
    assert 50.0 < tau < 100.0  # measured 67.6 s
    assert 50.0 < run.t[np.argmax(gap < np.exp(-1))] < 100.0  # measured 71 s


def test_history_leaves_a_profile_that_changes_the_next_contact():
    stack = SensorStack.paper()
    model = MultilayerModel(stack, ObjectBody(*ALUMINIUM), ambient=AMBIENT, dt=0.01)
    steady = model.steady_state(1.0)
    touched = model.run(steady, [Phase(3.0, True, heater=1.0),
                                 Phase(5.0, False, heater=1.0, record=False)]).state
    body = slice(model.surface, model.surface + stack.layers[0].cells)
    assert np.ptp(touched.u[body]) > 1.0  # measured 4.05 K across the sensor body
    assert np.abs(touched.u[body] - steady.u[body]).max() > 0.5  # not back to steady yet
    # the next contact, with a fresh object at ambient, from the remembered profile ...
    fresh = ColumnState(touched.u.copy())
    fresh.u[: model.surface] = AMBIENT
    reading = float(model.thermistor(fresh)[0])
    after = model.run(fresh, [Phase(3.0, True, heater=1.0)], fs=100).thermistor[0]
    # ... against a uniform start at the same thermistor reading
    uniform = model.run(model.state(reading, AMBIENT), [Phase(3.0, True, heater=1.0)],
                        fs=100).thermistor[0]
    assert after[0] == uniform[0] == reading
    assert np.abs(after - uniform).max() > 0.1  # measured 0.60 K


def _model(**kwargs):
    body = kwargs.pop("body", ObjectBody(np.array([80.0, 0.15, 400.0]),
                                         np.array([3.55e-5, 2.05e-7, 1.17e-4]), cells=10))
    return MultilayerModel(SensorStack.paper(cells=8), body, **kwargs)


def _run(*phases, **kwargs):
    model = _model()
    return model.run(model.state(T_SENSOR, AMBIENT), list(phases), **kwargs)


@pytest.mark.parametrize(("make", "match"), [
    (lambda: _run(Phase(0.1, False, heater=1.5)), r"heater duty must be in \[0, 1\]"),
    (lambda: _run(Phase(0.1, True, heater=-0.1)), r"heater duty must be in \[0, 1\]"),
    (lambda: _run(Phase(0.1, True, heater=np.nan)), r"heater duty must be in \[0, 1\]"),
    (lambda: _run(Phase(0.1, True, heater=np.array([0.5, 1.0, 1.01]))), r"heater duty"),
    (lambda: _run(Phase(1.0, True), Phase(-1.0, False)), r"phase 1: duration must be >= 0"),
    (lambda: _run(Phase(np.nan, True)), r"duration must be >= 0"),
    (lambda: _run(Phase(0.1, True, conductance=0.0)), r"contact conductance must be positive"),
    (lambda: _run(Phase(0.1, True, conductance=-5.0)), r"contact conductance must be positive"),
    (lambda: _model(scheme="rk4"), r"unknown scheme 'rk4'"),
    (lambda: _model(dt=0.0), r"time step must be positive"),
    (lambda: _model(dt=-0.01), r"time step must be positive"),
    (lambda: _model(dt=np.nan), r"time step must be positive"),
    (lambda: Layer("sensor body", -1e-3, 0.0349, 2.796e-9, 8), r"'sensor body'.*thickness"),
    (lambda: Layer("foam", 1e-3, np.nan, 1e-6, 8), r"'foam'.*conductivity"),
    (lambda: Layer("foam", 1e-3, 0.03, 0.0, 8), r"'foam'.*diffusivity"),
    (lambda: Layer("foam", 1e-3, 0.03, 1e-6, 0), r"'foam'.*cells must be a whole number"),
    (lambda: dataclasses.replace(SensorStack.paper().layers[0], thickness=0.0), r"thickness"),
    (lambda: ObjectBody(-80.0, 3.55e-5), r"object conductivity must be positive"),
    (lambda: ObjectBody(80.0, 3.55e-5, back="wall"), r"object back"),
    (lambda: _model(body=ObjectBody(np.array([1.0, 2.0]), np.array([1e-6, 2e-6, 3e-6]))),
     r"per-trial arrays disagree in length: \[2, 3\]"),
    (lambda: _model(ambient=np.array([25.0, 26.0])), r"per-trial arrays disagree in length"),
    (lambda: _model().run(ColumnState(np.zeros((3, 3))), [Phase(1.0, True)]),
     r"state has shape \(3, 3\)"),
    (lambda: _model().state(np.nan, AMBIENT), r"initial temperatures must be finite"),
    (lambda: SensorStack.paper(SensorConstants(depth=3e-4)), r"thermistor depth"),
    (lambda: MultilayerModel(dataclasses.replace(SensorStack.paper(), thermistor_depth=1.0),
                             ObjectBody(*ALUMINIUM)), r"thermistor depth 1.0 m is outside"),
], ids=["duty>1", "duty<0", "duty-nan", "duty-array", "negative-duration", "nan-duration",
        "h=0", "h<0", "scheme", "dt=0", "dt<0", "dt-nan", "layer-thickness", "layer-k",
        "layer-alpha", "layer-cells", "replaced-layer", "object-k", "object-back",
        "object-arrays", "ambient-array", "state-shape", "state-nan", "paper-depth",
        "stack-depth"])
def test_invalid_input_raises_model_error_naming_the_problem(make, match):
    with pytest.raises(ModelError, match=match):
        make()


@pytest.mark.parametrize("phase", [Phase(0.1, True, heater=np.array([0.5, 1.0])),
                                   Phase(0.1, False, heater=np.array([0.5, 1.0])),
                                   Phase(0.1, True, conductance=np.array([1e3, 1e4]))],
                         ids=["heater-contact", "heater-free", "conductance"])
def test_phase_arrays_of_the_wrong_length_raise_model_error(phase):
    with pytest.raises(ModelError, match="per-trial"):
        _run(phase)  # a batch of 3 trials, arrays of 2


@pytest.mark.parametrize("which", ["sensor", "object"])
def test_state_arrays_of_the_wrong_length_raise_model_error(which):
    model = _model()  # batch of 3
    two = np.array([30.0, 31.0])
    with pytest.raises(ModelError):
        model.state(two, AMBIENT) if which == "sensor" else model.state(T_SENSOR, two)


@pytest.mark.parametrize("index", [3, -1])
def test_a_heater_layer_outside_the_stack_raises_model_error(index):
    with pytest.raises(ModelError, match="heater"):
        dataclasses.replace(SensorStack.paper(), heater_layer=index)


def test_a_fractional_cell_count_raises_model_error():
    with pytest.raises(ModelError, match="cell"):
        Layer("foam", 1e-3, 0.03, 1e-6, 2.5)


@pytest.mark.parametrize("fs", [0.0, -1.0])
def test_a_non_positive_sampling_rate_raises_model_error(fs):
    with pytest.raises(ModelError, match=r"fs|sampl"):
        _run(Phase(0.1, True), fs=fs)


# --------------------------------------------------------------------- batching and sampling


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("path", ["dense", "banded"])
def test_a_batch_equals_single_runs(monkeypatch, path, scheme):
    monkeypatch.setattr(ml, "_DENSE_LIMIT", 10**9 if path == "dense" else 0)
    stack = SensorStack.paper(cells=8)
    k = np.array([80.0, 0.15, 400.0])
    alpha = np.array([3.55e-5, 2.05e-7, 1.17e-4])
    duty = np.array([0.0, 0.5, 1.0])
    h = np.array([np.inf, 300.0, 3000.0])
    ambient = np.array([25.0, 22.0, 28.0])

    def phases(i=slice(None)):
        return [Phase(0.5, True, heater=0.0),
                Phase(0.3, False, heater=duty[i], record=False),
                Phase(0.5, True, heater=duty[i], conductance=h[i])]

    batch = MultilayerModel(stack, ObjectBody(k, alpha, cells=12), ambient=ambient,
                            scheme=scheme, dt=0.01)
    together = batch.run(batch.state(np.array([38.963, 35.0, 30.0]), ambient), phases())
    for i, t_sensor in enumerate((38.963, 35.0, 30.0)):
        one = MultilayerModel(stack, ObjectBody(k[i], alpha[i], cells=12), ambient=ambient[i],
                              scheme=scheme, dt=0.01)
        alone = one.run(one.state(t_sensor, ambient[i]), phases(i))
        np.testing.assert_array_equal(alone.t, together.t)
        np.testing.assert_allclose(together.thermistor[i], alone.thermistor[0], rtol=0,
                                   atol=1e-10)
        np.testing.assert_allclose(together.state.u[:, i], alone.state.u[:, 0], rtol=0,
                                   atol=1e-10)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_dense_and_banded_paths_agree(monkeypatch, scheme):
    body = ObjectBody(np.array([80.0, 0.15]), np.array([3.55e-5, 2.05e-7]), cells=12)
    phases = [Phase(0.7, True, heater=0.2), Phase(0.5, False, heater=1.0, record=False),
              Phase(0.4, True, heater=0.0, conductance=500.0)]
    out = {}
    for path, limit in (("dense", 10**9), ("banded", 0)):
        monkeypatch.setattr(ml, "_DENSE_LIMIT", limit)
        model = MultilayerModel(SensorStack.paper(cells=8), body, scheme=scheme, dt=0.01)
        out[path] = model.run(model.state(T_SENSOR, AMBIENT), phases)
    # measured 1.2e-12
    np.testing.assert_allclose(out["dense"].thermistor, out["banded"].thermistor, atol=1e-10)
    np.testing.assert_allclose(out["dense"].state.u, out["banded"].state.u, atol=1e-10)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_unrecorded_phases_end_where_recorded_ones_do(scheme):
    """The dense path squares the step matrix when nothing is recorded; same end state."""
    model = _model(scheme=scheme, dt=0.01)
    start = model.state(T_SENSOR, AMBIENT)
    for duration in (0.01, 0.02, 0.03, 1.37):
        ends = [model.run(start, [Phase(duration, True, heater=0.3, record=rec)]).state.u
                for rec in (True, False)]
        np.testing.assert_allclose(ends[0], ends[1], rtol=0, atol=1e-10)  # measured 1.6e-12


def test_samples_fall_on_multiples_of_the_sample_period():
    run = _run(Phase(1.0, True, heater=0.0), fs=200)
    np.testing.assert_array_equal(run.t, np.arange(201) / 200)
    assert run.thermistor.shape == (3, 201)
    # the first sample is the start state (interpolated between two equal cells)
    np.testing.assert_allclose(run.thermistor[:, 0], T_SENSOR, rtol=0, atol=1e-12)


def test_consecutive_recorded_phases_do_not_repeat_the_boundary_sample():
    run = _run(Phase(0.5, True), Phase(0.0123, True), Phase(0.3, True), fs=200)
    np.testing.assert_array_equal(run.t, np.arange(163) / 200)  # 0 .. 0.81 s
    assert np.all(np.diff(run.t) > 0)


def test_an_unrecorded_phase_contributes_no_samples():
    run = _run(Phase(0.5, True), Phase(0.25, False, record=False), Phase(0.5, True), fs=200)
    k = np.rint(run.t * 200).astype(int)
    np.testing.assert_array_equal(run.t, k / 200)
    assert not np.any((run.t > 0.5) & (run.t < 0.75))  # nothing inside the unrecorded phase
    assert np.all(np.isin(np.arange(151, 251), k))  # the whole later phase is there
    assert run.t[-1] == 1.25
    only = _run(Phase(0.5, True, record=False), fs=200)
    assert only.t.size == 0
    assert only.thermistor.shape == (3, 0)


def test_sampling_between_long_steps_interpolates_the_step_values():
    model = _model(dt=0.1)
    start = model.state(T_SENSOR, AMBIENT)
    fine = model.run(start, [Phase(2.0, True, heater=0.0)], fs=200)
    coarse = model.run(start, [Phase(2.0, True, heater=0.0)], fs=10)
    np.testing.assert_allclose(fine.thermistor[:, ::20], coarse.thermistor, rtol=0, atol=1e-12)
    # between two steps the sample lies on the chord
    mid = 0.5 * (coarse.thermistor[:, :-1] + coarse.thermistor[:, 1:])
    np.testing.assert_allclose(fine.thermistor[:, 10::20], mid, rtol=0, atol=1e-12)


# ------------------------------------------------------------ insulated faces (issue 20 item 7)


def _insulated_stack(**losses):
    stack = SensorStack.paper()
    return dataclasses.replace(stack, **{"front_loss": 0.0, "back_loss": 0.0, "edge_loss": 0.0,
                                         **losses})


@pytest.mark.parametrize("scheme", SCHEMES)
def test_a_fully_insulated_column_conserves_its_heat(scheme):
    # every face insulated (front, back, edges, the object's surface and back): no heat leaves,
    # so with the heater off the total heat content stays where it was, in and out of contact
    body = ObjectBody(*ALUMINIUM, thickness=0.01, surface_loss=0.0)
    model = MultilayerModel(_insulated_stack(), body, ambient=AMBIENT, scheme=scheme, dt=0.05)
    state = model.state(T_SENSOR, AMBIENT)
    heat0 = float((model.capacity * state.u).sum())
    run = model.run(state, [Phase(1.0, False, heater=0.0), Phase(5.0, True, heater=0.0),
                            Phase(5.0, False, heater=0.0)], fs=10)
    assert np.all(np.isfinite(run.thermistor))
    heat1 = float((model.capacity * run.state.u).sum())
    assert heat1 == pytest.approx(heat0, rel=1e-12)
    # heater on for a second: the heat content grows by exactly power x time
    run = model.run(state, [Phase(1.0, False, heater=1.0, record=False)])
    added = float((model.capacity * run.state.u).sum()) - heat0
    assert added == pytest.approx(model.stack.heater_power * 1.0, rel=1e-9)


def test_an_insulated_front_leaves_no_gradient_in_front_of_the_heater():
    # front and edges insulated: in the free steady state no heat crosses the sensor body, so
    # it sits at one temperature, the heater foil's front
    model = MultilayerModel(_insulated_stack(back_loss=10.0), ObjectBody(*ALUMINIUM),
                            ambient=AMBIENT)
    u = model.steady_state(1.0).u[:, 0]
    body = u[model.surface: model.surface + model.stack.layers[0].cells]
    assert np.ptp(body) < 1e-9 * (body[0] - AMBIENT)
    assert body[0] > AMBIENT + 1.0


@pytest.mark.parametrize("make", [
    lambda: dataclasses.replace(SensorStack.paper(), front_loss=-1.0),
    lambda: dataclasses.replace(SensorStack.paper(), back_loss=-1.0),
    lambda: SensorStack.paper(front_loss=np.nan),
    lambda: ObjectBody(*ALUMINIUM, surface_loss=-1.0),
    lambda: ObjectBody(*ALUMINIUM, surface_loss=np.inf),
], ids=["front<0", "back<0", "front-nan", "surface<0", "surface-inf"])
def test_negative_or_non_finite_losses_raise_model_error(make):
    with pytest.raises(ModelError, match="loss"):
        make()


def test_a_column_that_loses_no_heat_has_no_steady_state():
    model = MultilayerModel(_insulated_stack(), ObjectBody(*ALUMINIUM), ambient=AMBIENT)
    with pytest.raises(ModelError, match="no steady state"):
        model.steady_state(1.0)


# ------------------------------------------------- TR-BDF2 with long steps (issue 20 item 9)


@pytest.mark.parametrize("dt", [0.2, 0.5, 1.0, 2.0])
@pytest.mark.parametrize("scheme", SCHEMES)
def test_long_steps_neither_undershoot_nor_overshoot_after_contact(monkeypatch, scheme, dt):
    # before the damped start, TR-BDF2 took diamond's cells 0.08 K (dt = 0.2 s) to 0.25 K
    # (dt = 0.5 s) below the 25 C they start from; every step is now within round-off of
    # [ambient, sensor] (measured: the lowest cell stays above 25 C)
    monkeypatch.setattr(ml, "_DENSE_LIMIT", 0)
    model = StepRecorder(SensorStack.paper(), stiff_body(), ambient=AMBIENT, scheme=scheme,
                         dt=dt)
    model.states = []
    model.run(model.state(T_SENSOR, AMBIENT), [Phase(40 * dt, True, heater=0.0)], fs=1 / dt)
    u = np.array(model.states)
    assert u.min() >= AMBIENT - BOUND_TOL[scheme]
    assert u.max() <= T_SENSOR + BOUND_TOL[scheme]
