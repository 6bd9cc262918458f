"""Fuzz of the library boundary (issue #13): bad values for every public argument.

Two properties:

1. At the Python boundary every bad argument (NaN, ±inf, negative or zero where
   not allowed, out of range, wrong types: str, bytes, bool, None, complex,
   dicts, objects, lists holding such things) raises ``ValueError`` or
   ``TypeError`` whose message names the argument. These checks run on concrete
   values before anything is traced, so no example compiles anything.
2. Inside ``jax.jit``, where nothing can raise, a non-finite input never comes
   back as a finite number: the output is NaN and/or a non-successful result
   code. These use a few compiled functions of fixed shapes.

Hypothesis draws the values (small ``max_examples``, no shrinking, derandomised:
the module runs in well under a minute).
"""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

import tripodjax as tj
from tripodjax import catalogue, forces, friction, hertz, joint, life, outboard, shaft

FUZZ = settings(
    max_examples=25,
    deadline=None,
    derandomize=True,
    database=None,
    phases=(Phase.explicit, Phase.generate),
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)

NON_FINITE = (math.nan, math.inf, -math.inf)


# --------------------------------------------------------------------------- bad values


class _Opaque:
    def __repr__(self):
        return "<opaque>"


WRONG_TYPES = st.sampled_from(
    [
        "1.0",
        "abc",
        "",
        b"1",
        True,
        False,
        np.bool_(True),
        None,
        1 + 1j,
        {"x": 1.0},
        _Opaque(),
        [1.0, "a"],
        [None],
    ]
)


def _finite_floats(**bounds):
    return st.floats(allow_nan=False, allow_infinity=False, **bounds)


def _below(limit, open_=False):
    """Finite floats below ``limit`` (≤ when not ``open_``: the limit itself is bad too)."""
    values = _finite_floats(max_value=limit, exclude_max=open_, min_value=-1e12)
    return values | st.just(float(limit)) if not open_ else values


def _above(limit, open_=False):
    values = _finite_floats(min_value=limit, exclude_min=open_, max_value=1e12)
    return values | st.just(float(limit)) if not open_ else values


def bad_numbers(kind):
    """Bad numbers (finite or not) for one value rule, by ``kind``."""
    non_finite = st.sampled_from(NON_FINITE)
    if kind == "positive":  # finite, > 0
        return non_finite | _below(0.0)
    if kind == "non_negative":  # finite, ≥ 0
        return non_finite | _finite_floats(max_value=-1e-12, min_value=-1e12)
    if kind == "finite":
        return non_finite
    if kind == "unit":  # 0 ≤ x < 1 (cos τ, m)
        return (
            non_finite
            | _finite_floats(max_value=-1e-300, min_value=-1e6)
            | _finite_floats(min_value=1.0, max_value=1e6)
        )
    if kind == "conformity":  # ≥ 1.0005
        return non_finite | _finite_floats(max_value=1.0004, min_value=-10.0) | st.just(1 + 1e-15)
    if kind == "gamma0":  # 0 ≤ γ0 ≤ π/4 rad
        return (
            non_finite
            | _finite_floats(max_value=-1e-9, min_value=-10.0)
            | _finite_floats(min_value=math.pi / 4 + 1e-9, max_value=100.0)
        )
    if kind == "gamma0_deg":
        return (
            non_finite
            | _finite_floats(max_value=-1e-9, min_value=-100.0)
            | _finite_floats(min_value=45.0 + 1e-9, max_value=1e4)
        )
    if kind == "working_angle":  # 0 ≤ γ < π/2
        return (
            non_finite
            | _finite_floats(max_value=-1e-9, min_value=-10.0)
            | _finite_floats(min_value=math.pi / 2, max_value=100.0)
        )
    if kind == "pressure_angle":  # 0 < ε ≤ π/2
        return (
            non_finite | _below(0.0) | _finite_floats(min_value=math.pi / 2 + 1e-9, max_value=10.0)
        )
    if kind == "helix_angle":  # 0 ≤ ζ < π/2
        return (
            non_finite
            | _finite_floats(max_value=-1e-9, min_value=-10.0)
            | _finite_floats(min_value=math.pi / 2, max_value=10.0)
        )
    if kind == "poisson":  # −1 < ν < 0.5
        return non_finite | _below(-1.0) | _above(0.5)
    raise AssertionError(kind)


BAD_COUNTS = st.sampled_from([0, -1, -5, -3]) | st.sampled_from(
    [2.5, 3.0, 1e20, math.nan, math.inf]
)
BAD_COUNT_TYPES = st.sampled_from([True, False, "3", None, [3], 3 + 0j])


HUGE = st.sampled_from([10**400, -(10**400)])  # Python integers beyond the float range


def bad_values(kind):
    """Every bad value for an argument of ``kind``: its bad numbers and the wrong types."""
    if kind == "count":  # an integer ≥ 1
        return BAD_COUNTS | BAD_COUNT_TYPES | HUGE
    if kind == "shares":
        return WRONG_TYPES | st.sampled_from(
            [[0.5, 0.6, 0.0], [-0.5, 1.0, 0.5], [math.nan, 0.5, 0.5], [math.inf, 0.0, 0.0]]
        )
    if kind == "flag":  # True or False
        return st.sampled_from(["yes", "", 1, 0, 1.0, None, [True], np.array([True, False])])
    if kind in ("choice",):
        return st.sampled_from(["", "nope", "Newton", "NEWTON ", None, 1, True, ["newton"]])
    if kind == "object":
        return st.sampled_from([None, "N", 1.0, {"R": 25.0}, [25.0, 500.0, 0.3]])
    return WRONG_TYPES | bad_numbers(kind) | HUGE


NUMBER_KINDS = (
    "positive",
    "non_negative",
    "finite",
    "unit",
    "conformity",
    "gamma0",
    "gamma0_deg",
    "working_angle",
    "pressure_angle",
    "helix_angle",
    "poisson",
)
# A bad number as a concrete array of any kind: checked like a Python number, never skipped
# (only traced values pass unchecked).
AS_ARRAYS = st.sampled_from(
    [
        ("numpy 0-d", np.asarray),
        ("numpy scalar", np.float64),
        ("jax 0-d", jnp.asarray),
        # float32 only for non-finite values: rounding may move an edge value into the domain
        ("jax float32 0-d", lambda v: jnp.asarray(v, jnp.float32) if not np.isfinite(v) else v),
    ]
)


def _assert_rejected(call, name, value):
    with pytest.raises((ValueError, TypeError)) as info:
        call()
    message = str(info.value)
    assert name in message, f"{name} = {value!r}: the error does not name the argument: {message}"


def _with_element(good, value):
    """The good array with its first element replaced by a bad number, or the bad value itself."""
    if isinstance(value, float) and np.ndim(good):
        array = np.array(good, dtype=float)
        array.flat[0] = value
        return array
    return value


# --------------------------------------------------------------------------- the boundary table

HALF_PI = math.pi / 2
WORKBOOK = dict(conformity=1.002, P_s=2350.0, P_d=1347.0, P_sd=2005.0, C_s=1.2)
ANGLES = dict(n_rollers=3, pressure_angle=HALF_PI, helix_angle=0.0)


def _spectrum(**changes):
    fields = dict(
        torque=np.array([900.0, 400.0, 150.0]),
        speed=np.array([300.0, 800.0, 1200.0]),
        vehicle_speed=np.array([40.0, 90.0, 130.0]),
        share=np.array([0.1, 0.5, 0.4]),
    )
    return life.LoadSpectrum(**{**fields, **changes})


def _conditions(**changes):
    fields = dict(angle=np.radians([6.5, 0.0, 12.8]), share=np.array([0.45, 0.2, 0.35]))
    return life.WorkingConditions(**{**fields, **changes})


def _layout():
    return tj.seed_case("N")


def _layouts(n=3):
    return tj.Layout(np.full(n, 25.0), np.full(n, 500.0), np.full(n, 0.3))


# name → (function, good keyword arguments, {argument: kind}, how the error names it)
BOUNDARY = {
    "Layout": (
        tj.Layout,
        dict(R=25.0, l=500.0, gamma0=0.3),
        {"R": "positive", "l": "positive", "gamma0": "gamma0"},
        "Layout.{}",
    ),
    "Layout.from_degrees": (
        tj.Layout.from_degrees,
        dict(R=25.0, l=500.0, gamma0_deg=20.0),
        {"R": "positive", "l": "positive", "gamma0_deg": "gamma0_deg"},
        None,  # R and l are named Layout.R, Layout.l
    ),
    "seed_case": (tj.seed_case, dict(code="N"), {"code": "choice"}, "{}"),
    "joint.eccentricity": (
        joint.eccentricity,
        dict(R=25.0, gamma=0.3),
        {"R": "positive", "gamma": "working_angle"},
        "{}",
    ),
    "joint.spider_offset": (
        joint.spider_offset,
        dict(l=500.0, gamma0=0.3, gamma=0.31),
        {"l": "positive", "gamma0": "working_angle", "gamma": "working_angle"},
        "{}",
    ),
    "joint.roller_centres": (
        joint.roller_centres,
        dict(R=25.0, gamma=0.3, psi=np.linspace(0.0, 1.0, 4)),
        {"R": "positive", "gamma": "working_angle"},
        "{}",
    ),
    "hertz.elliptic_integrals": (hertz.elliptic_integrals, dict(m=0.5), {"m": "unit"}, "{}"),
    "hertz.hertz_coefficients": (
        hertz.hertz_coefficients,
        dict(cos_tau=0.5),
        {"cos_tau": "unit"},
        "{}",
    ),
    "hertz.mu_nu": (hertz.mu_nu, dict(cos_tau=0.5), {"cos_tau": "unit"}, "{}"),
    "hertz.contact_geometry": (
        hertz.contact_geometry,
        dict(conformity=1.002),
        {"conformity": "conformity"},
        "{}",
    ),
    "hertz.conformity_coefficient": (
        hertz.conformity_coefficient,
        dict(conformity=1.002),
        {"conformity": "conformity"},
        "{}",
    ),
    "hertz.roller_contact": (
        hertz.roller_contact,
        dict(load=12000.0, d=43.5, conformity=1.002, young_modulus=208000.0, poisson=0.3),
        {
            "load": "non_negative",
            "d": "positive",
            "conformity": "conformity",
            "young_modulus": "positive",
            "poisson": "poisson",
        },
        "{}",
    ),
    "hertz.torque_at_pressure": (
        hertz.torque_at_pressure,
        dict(pressure=1347.0, d=43.5, R=25.55, C_p=514.6, C_s=1.2, gamma=0.1, **ANGLES),
        {
            "pressure": "non_negative",
            "d": "positive",
            "R": "positive",
            "C_p": "positive",
            "C_s": "positive",
            "n_rollers": "count",
            "pressure_angle": "pressure_angle",
            "helix_angle": "helix_angle",
            "gamma": "working_angle",
        },
        "{}",
    ),
    "hertz.capacities": (
        hertz.capacities,
        dict(d=43.5, R=25.55, gamma=0.1, **WORKBOOK, **ANGLES),
        {
            "d": "positive",
            "R": "positive",
            "conformity": "conformity",
            "P_s": "positive",
            "P_d": "positive",
            "P_sd": "positive",
            "C_s": "positive",
            "n_rollers": "count",
            "pressure_angle": "pressure_angle",
            "helix_angle": "helix_angle",
            "gamma": "working_angle",
        },
        "{}",
    ),
    "hertz.min_roller_diameter": (
        hertz.min_roller_diameter,
        dict(M_max=1154.0, R_over_d=0.63, conformity=1.002, P_s=2350.0, C_s=1.35, rule="consistent")
        | ANGLES,
        {
            "M_max": "positive",
            "R_over_d": "positive",
            "conformity": "conformity",
            "P_s": "positive",
            "C_s": "positive",
            "n_rollers": "count",
            "pressure_angle": "pressure_angle",
            "helix_angle": "helix_angle",
            "rule": "choice",
        },
        "{}",
    ),
    "life.life_hours": (
        life.life_hours,
        dict(M_d=1505.0, torque=[900.0, 400.0], speed=[300.0, 800.0], share=[0.5, 0.5]),
        {"M_d": "positive", "torque": "non_negative", "speed": "non_negative", "share": "shares"},
        "{}",
    ),
    "life.LoadSpectrum": (
        _spectrum,
        {},
        {
            "torque": "non_negative",
            "speed": "non_negative",
            "vehicle_speed": "non_negative",
            "share": "shares",
        },
        "LoadSpectrum.{}",
    ),
    "life.WorkingConditions": (
        _conditions,
        {},
        {"angle": "working_angle", "share": "shares"},
        "WorkingConditions.{}",
    ),
    "life.joint_life": (
        life.joint_life,
        dict(d=43.5, R=25.55, conformity=1.002, P_d=1347.0, C_s=1.2, **ANGLES),
        {
            "d": "positive",
            "R": "positive",
            "conformity": "conformity",
            "P_d": "positive",
            "C_s": "positive",
            "n_rollers": "count",
            "pressure_angle": "pressure_angle",
            "helix_angle": "helix_angle",
            "spectrum": "object",
            "conditions": "object",
        },
        "{}",
    ),
    "friction.FrictionParams": (
        friction.FrictionParams,
        {},
        {name: "non_negative" for name in friction.FrictionParams.__dataclass_fields__},
        "FrictionParams.{}",
    ),
    "friction.mu_sta": (
        friction.mu_sta,
        dict(gamma=0.3, torque=100.0),
        {"gamma": "working_angle", "torque": "non_negative", "params": "object"},
        "{}",
    ),
    "friction.mu_avg": (
        friction.mu_avg,
        dict(theta=0.3, gamma=0.3, torque=100.0),
        {"theta": "finite", "gamma": "working_angle", "torque": "non_negative", "params": "object"},
        "{}",
    ),
    "friction.mu_slip_to_roll": (
        friction.mu_slip_to_roll,
        dict(gamma=0.3),
        {"gamma": "working_angle", "params": "object"},
        "{}",
    ),
    "friction.mu_dyn": (
        friction.mu_dyn,
        dict(theta=0.3, gamma=0.3, stroke="in"),
        {"theta": "finite", "gamma": "working_angle", "params": "object", "stroke": "choice"},
        "{}",
    ),
    "friction.friction_from_trunnion_force": (
        friction.friction_from_trunnion_force,
        dict(F_x=1000.0, F_y=100.0, F_z=0.0, theta=0.3, gamma=0.2),
        {
            "F_x": "finite",
            "F_y": "finite",
            "F_z": "finite",
            "theta": "finite",
            "gamma": "working_angle",
        },
        "{}",
    ),
    "friction.gaf": (
        friction.gaf,
        dict(theta=0.3, gamma=0.3, torque=100.0, R=25.0, model="printed", width=0.01),
        {
            "theta": "finite",
            "gamma": "working_angle",
            "torque": "non_negative",
            "R": "positive",
            "model": "choice",
            "width": "positive",
            "params": "object",
            "factor": "choice",
        },
        "{}",
    ),
    "friction.gaf_halfshaft": (
        friction.gaf_halfshaft,
        dict(torque=100.0, n_theta=36, model="printed", width=0.01, fidelity="newton"),
        {
            "layout": "object",
            "torque": "non_negative",
            "params": "object",
            "n_theta": "count",
            "model": "choice",
            "width": "positive",
            "fidelity": "choice",
            "factor": "choice",
        },
        "{}",
    ),
    "solve_halfshaft": (
        tj.solve_halfshaft,
        dict(theta=np.linspace(0.0, 1.0, 4), rtol=1e-10, max_steps=24),
        {"layout": "object", "rtol": "positive", "max_steps": "count", "throw": "flag"},
        "{}",
    ),
    "kinematic_metrics": (
        tj.kinematic_metrics,
        dict(n_theta=36, fidelity="newton"),
        {"layout": "object", "n_theta": "count", "fidelity": "choice", "throw": "flag"},
        "{}",
    ),
    "sweep": (
        tj.sweep,
        dict(n_theta=36, outputs=("delta_pp", "gaf_rms"), chunk_size=2),
        {
            "chunk_size": "count",
            "n_theta": "count",
            "solver": "choice",
            "gaf": "object",
            "layouts": "object",
            "throw": "flag",
        },
        "{}",
    ),
    "shaft.Section": (
        shaft.Section,
        dict(outer_diameter=30.0, hardened_depth=2.5, transition_depth=3.5, inner_diameter=5.0),
        {
            "outer_diameter": "positive",
            "hardened_depth": "non_negative",
            "transition_depth": "non_negative",
            "inner_diameter": "non_negative",
        },
        "Section.{}",
    ),
    "shaft.Material": (
        shaft.Material,
        dict(core_uts=690.0, surface_uts=2180.0, depth_drop=0.1, fatigue_ratio=1.6, safety=1.2),
        {"core_uts": "positive", "surface_uts": "positive", "depth_drop": "unit"},
        "Material.{}",
    ),
    "outboard.FixedJoint": (
        outboard.FixedJoint,
        dict(
            d=18.256,
            R=29.958,
            conformity=1.003,
            longitudinal_conformity=0.268,
            P_s=3750.0,
            P_d=2150.0,
            P_sd=3200.0,
            C_s=1.1,
        ),
        {
            "d": "positive",
            "R": "positive",
            "conformity": "conformity",
            "P_s": "positive",
            "P_d": "positive",
            "P_sd": "positive",
            "C_s": "positive",
            "pressure_angle": "pressure_angle",
            "oblique_angle": "helix_angle",
            "tolerance": "non_negative",
        },
        "FixedJoint.{}",
    ),
    "GAFInputs": (
        tj.GAFInputs,
        dict(torque=100.0),
        {
            "torque": "non_negative",
            "model": "choice",
            "width": "positive",
            "params": "object",
            "factor": "choice",
        },
        "{}",
    ),
    "forces.ForceInputs": (
        forces.ForceInputs,
        dict(torque=100.0),
        {
            "torque": "non_negative",
            "params": "object",
            "mu_trunnion": "non_negative",
            "contact_angle": "helix_angle",  # 0 ≤ α < π/2
            "speed": "finite",
            "plunge_speed": "finite",
            "lts_speed": "finite",
            "width": "positive",
            "transverse_x": "finite",
            "transverse_y": "finite",
        },
        "{}",
    ),
    "forces.roller_forces": (
        forces.roller_forces,
        dict(theta=np.linspace(0.0, 1.0, 4), case="running"),
        {"layout": "object", "inputs": "object", "solver": "choice", "case": "choice"},
        "{}",
    ),
    "forces.forces_halfshaft": (
        forces.forces_halfshaft,
        dict(n_theta=36),
        {"layout": "object", "inputs": "object", "n_theta": "count", "solver": "choice"},
        "{}",
    ),
}

# Arguments whose good value is not in the table (built per call).
_DEFAULT_OBJECTS = {
    "layout": _layout,
    "layouts": lambda: _layouts(3),
    "spectrum": _spectrum,
    "conditions": _conditions,
    "params": lambda: friction.GREASE_A,
    "friction_params": lambda: friction.GREASE_A,
    "gaf": lambda: friction.GAFInputs(100.0),
    "inputs": lambda: forces.ForceInputs(100.0),
}

CASES = [
    (function_name, argument)
    for function_name, (_, _, arguments, _) in BOUNDARY.items()
    for argument in arguments
]


# Arguments for which None is the documented default, so a good value.
_NONE_ALLOWED = {("solve_halfshaft", "rtol"), ("sweep", "chunk_size")}


def _good_kwargs(function_name):
    function, good, arguments, _ = BOUNDARY[function_name]
    kwargs = dict(good)
    for argument in arguments:
        if argument not in kwargs and argument in _DEFAULT_OBJECTS:
            kwargs[argument] = _DEFAULT_OBJECTS[argument]()
    return function, kwargs


def _display_name(function_name, argument):
    pattern = BOUNDARY[function_name][3]
    if pattern is None:
        return f"Layout.{argument}" if argument in ("R", "l") else argument
    return pattern.format(argument)


@pytest.mark.parametrize("function_name", list(BOUNDARY))
def test_the_good_call_works(function_name):
    function, kwargs = _good_kwargs(function_name)
    function(**kwargs)


@pytest.mark.parametrize("function_name, argument", CASES, ids=[f"{f}-{a}" for f, a in CASES])
@FUZZ
@given(data=st.data())
def test_every_bad_argument_raises_an_error_that_names_it(function_name, argument, data):
    function, kwargs = _good_kwargs(function_name)
    kind = BOUNDARY[function_name][2][argument]
    values = bad_values(kind)
    if (function_name, argument) in _NONE_ALLOWED:
        values = values.filter(lambda v: v is not None)
    value = data.draw(values, label=argument)
    kwargs[argument] = _with_element(kwargs.get(argument, 0.0), value)
    _assert_rejected(lambda: function(**kwargs), _display_name(function_name, argument), value)


ARRAY_CASES = [(f, a) for f, a in CASES if BOUNDARY[f][2][a] in NUMBER_KINDS]


@pytest.mark.parametrize(
    "function_name, argument", ARRAY_CASES, ids=[f"{f}-{a}" for f, a in ARRAY_CASES]
)
@FUZZ
@given(data=st.data())
def test_every_bad_number_as_a_concrete_array_names_the_argument(function_name, argument, data):
    function, kwargs = _good_kwargs(function_name)
    value = data.draw(bad_numbers(BOUNDARY[function_name][2][argument]), label=argument)
    _, wrap = data.draw(AS_ARRAYS, label="as")
    kwargs[argument] = wrap(value)
    _assert_rejected(lambda: function(**kwargs), _display_name(function_name, argument), value)


@FUZZ
@given(
    field=st.sampled_from(["R", "l", "gamma0"]),
    index=st.integers(0, 4),
    value=bad_numbers("positive") | st.just(200.0) | st.just(0.9),
    library=st.sampled_from([np.asarray, jnp.asarray]),
)
def test_layout_arrays_are_checked_element_by_element(field, index, value, library):
    good = {"R": 25.0, "l": 500.0, "gamma0": 0.3}
    if value == 0.9 and field != "gamma0" or value == 200.0 and field != "R":
        return  # in the domain for this field
    array = np.full(5, good[field])
    array[index] = value
    fields = {**good, field: library(array)}
    with pytest.raises(ValueError, match=rf"Layout\.{field}\[{index}\]"):
        tj.Layout(**fields)


@FUZZ
@given(
    shapes=st.lists(
        st.lists(st.integers(0, 4), min_size=0, max_size=3).map(tuple), min_size=3, max_size=3
    )
)
def test_layout_field_shapes_broadcast_and_are_not_empty_or_the_error_says_so(shapes):
    good = {"R": 25.0, "l": 500.0, "gamma0": 0.3}
    fields = {k: np.full(shape, v) for (k, v), shape in zip(good.items(), shapes, strict=True)}
    try:
        ok = 0 not in np.broadcast_shapes(*shapes) and all(0 not in s for s in shapes)
    except ValueError:
        ok = False
    if ok:
        tj.Layout(**fields)
        return
    with pytest.raises(ValueError, match="Layout") as info:
        tj.Layout(**fields)
    assert "empty" in str(info.value) or "broadcast together" in str(info.value)


def _unchecked_layouts(R, l, gamma0):
    """Layouts that skipped their checks (as JAX rebuilds them): sweep checks them again."""
    treedef = jax.tree_util.tree_structure(_layout())
    return jax.tree_util.tree_unflatten(treedef, [np.asarray(a, float) for a in (R, l, gamma0)])


@pytest.mark.parametrize(
    "call, fragment",
    [
        (
            lambda: tj.sweep(
                _layouts(3), gaf=tj.GAFInputs(torque=np.full(3, 100.0)), outputs=("gaf_rms",)
            ),
            "shape ()",
        ),
        (
            lambda: tj.sweep(
                _layouts(3), gaf=tj.GAFInputs(torque=[100.0, 50.0]), outputs=("gaf_rms",)
            ),
            "shape ()",
        ),
        (lambda: tj.sweep(_layouts(3), n_theta=36, devices=[]), "devices = [] is empty"),
        (
            lambda: tj.map_chunks(lambda x: x, {"x": np.ones(3)}, 2, devices=[]),
            "devices = [] is empty",
        ),
        (lambda: tj.map_chunks(lambda x: x, {"x": np.ones(3)}, 2, devices=["cpu"]), "jax.Device"),
        (lambda: tj.sweep(_layouts(3), n_theta=36, devices=["cpu"]), "jax.Device"),
        (lambda: tj.sweep(_layouts(3), n_theta=36, devices=5), "devices"),
        (lambda: tj.sweep(_unchecked_layouts([], [], []), n_theta=36), "empty"),
    ],
)
def test_sweep_shapes_and_devices_say_what_is_allowed(call, fragment):
    with pytest.raises((ValueError, TypeError)) as info:
        call()
    assert fragment in str(info.value)


# --------------------------------------------------------------------------- extra boundary cases


@FUZZ
@given(
    R=st.floats(0.1, 1e4),
    ratio=st.floats(0.2 + 1e-6, 1e3),
    gamma0=st.floats(0.0, math.pi / 4),
)
def test_layout_beyond_r_over_l_raises(R, ratio, gamma0):
    with pytest.raises(ValueError, match="R/l ≤ 0.2"):
        tj.Layout(R, R / ratio, gamma0)


@pytest.mark.parametrize(
    "outputs", ["delta_pp", "gaf_rms", ("nope",), (), ["delta_pp", 3], None, 5, {"delta_pp": 1}]
)
def test_sweep_outputs_must_be_a_sequence_of_names(outputs):
    _assert_rejected(
        lambda: tj.sweep(_layouts(2), n_theta=36, gaf=tj.GAFInputs(100.0), outputs=outputs),
        "outputs",
        outputs,
    )


@pytest.mark.parametrize("torque", [math.nan, -1.0, math.inf, "100", True, [100.0, math.nan]])
def test_sweep_torque_is_checked_like_gaf_halfshaft(torque):
    _assert_rejected(
        lambda: tj.sweep(_layouts(2), n_theta=36, gaf=tj.GAFInputs(torque), outputs=("gaf_rms",)),
        "torque",
        torque,
    )


@pytest.mark.parametrize(
    "field, value, index",
    [("R", -3.0, 1), ("l", math.nan, 0), ("gamma0", math.inf, 2), ("gamma0", 0.9, 1)],
)
def test_sweep_layouts_name_the_field_and_index(field, value, index):
    arrays = {name: np.asarray(getattr(_layouts(3), name)).copy() for name in ("R", "l", "gamma0")}
    arrays[field][index] = value
    with pytest.raises(ValueError, match=rf"Layout\.{field}\[{index}\]"):  # Layout checks itself
        tj.Layout(**arrays)
    layouts = _unchecked_layouts(**arrays)  # and sweep again, as JAX rebuilds Layouts unchecked
    _assert_rejected(lambda: tj.sweep(layouts, n_theta=36), f"layouts.{field}[{index}]", value)


def test_catalogue_tables_hold_finite_positive_sizes():
    for table in (catalogue.GE, catalogue.GI):
        for size, entry in table.items():
            for key, value in entry.items():
                assert isinstance(value, float) and math.isfinite(value) and value > 0, (
                    size,
                    key,
                )
            assert entry["M_drive"] <= entry["M_b"] and entry["M_d"] < entry["M_drive"]
    for low, high in (catalogue.GE_RATING_ANGLES, catalogue.GI_RATING_ANGLES):
        assert 0 < low < high < math.pi / 2


# --------------------------------------------------------------------------- inside jit


def _not_finite_or_flagged(outputs, result=None):
    """True when some output is not finite, or the result code is not successful."""
    leaves = [np.asarray(x) for x in jax.tree.leaves(outputs)]
    some_nan = any(np.any(~np.isfinite(x)) for x in leaves if x.dtype.kind == "f")
    flagged = result is not None and np.any(np.asarray(result) != int(hertz.RESULTS.successful))
    return some_nan or flagged


def _all_nan(*values):
    return all(np.all(np.isnan(np.asarray(v))) for v in values)


@jax.jit
def _hertz_all(d, R, conformity, P_s, P_d, C_s, gamma, cos_tau, m, load, torque0, share0):
    caps = hertz.capacities(
        d, R, conformity=conformity, P_s=P_s, P_d=P_d, P_sd=P_s, C_s=C_s, gamma=gamma
    )
    contact = hertz.roller_contact(load, d, conformity=conformity)
    coefficients = hertz.hertz_coefficients(cos_tau)
    K, E = hertz.elliptic_integrals(m)
    spectrum = life.LoadSpectrum(
        torque=jnp.stack([torque0, 400.0]),
        speed=jnp.array([300.0, 800.0]),
        vehicle_speed=jnp.array([40.0, 90.0]),
        share=jnp.stack([share0, 1.0 - share0]),
    )
    conditions = life.WorkingConditions(angle=jnp.stack([gamma, 0.0]), share=jnp.array([0.5, 0.5]))
    joint = life.joint_life(d, R, spectrum, conditions, conformity=conformity, P_d=P_d, C_s=C_s)
    d_min, _ = hertz.min_roller_diameter(
        1154.0 * P_s / 2350.0, R_over_d=R / d, conformity=conformity, P_s=P_s, C_s=C_s
    )
    return dict(
        caps=caps,
        contact=contact,
        coefficients=coefficients,
        K=K,
        E=E,
        life=joint,
        d_min=d_min,
        mu_nu=hertz.mu_nu(cos_tau),
        C_p=hertz.conformity_coefficient(conformity),
        hours=life.life_hours(P_d, torque0, 730.0, 1.0),
    )


_HERTZ_GOOD = dict(
    d=43.5,
    R=25.55,
    conformity=1.002,
    P_s=2350.0,
    P_d=1347.0,
    C_s=1.2,
    gamma=0.1,
    cos_tau=0.5,
    m=0.5,
    load=12000.0,
    torque0=900.0,
    share0=0.5,
)

# Which outputs each input reaches (each must come back NaN or flagged).
_HERTZ_REACH = {
    "d": lambda o: [
        (o["caps"].M_s, o["caps"].result),
        (o["contact"].p_max, o["contact"].result),
        (o["life"].km, o["life"].result),
        (o["d_min"], None),
    ],
    "R": lambda o: [(o["caps"].M_s, o["caps"].result), (o["life"].km, o["life"].result)],
    "conformity": lambda o: [
        (o["caps"].M_s, o["caps"].result),
        (o["C_p"], None),
        (o["contact"].p_max, o["contact"].result),
        (o["d_min"], None),
        (o["life"].km, o["life"].result),
    ],
    "P_s": lambda o: [(o["caps"].M_s, o["caps"].result), (o["d_min"], None)],
    "P_d": lambda o: [
        (o["caps"].M_d, o["caps"].result),
        (o["life"].km, o["life"].result),
        (o["hours"], None),
    ],
    "C_s": lambda o: [(o["caps"].M_s, o["caps"].result), (o["life"].km, o["life"].result)],
    "gamma": lambda o: [(o["caps"].M_d, o["caps"].result), (o["life"].km, o["life"].result)],
    "cos_tau": lambda o: [(o["coefficients"].mu_nu, o["coefficients"].result), (o["mu_nu"], None)],
    "m": lambda o: [(o["K"], None), (o["E"], None)],
    "load": lambda o: [(o["contact"].p_max, o["contact"].result)],
    "torque0": lambda o: [(o["life"].km, o["life"].result), (o["hours"], None)],
    "share0": lambda o: [(o["life"].km, o["life"].result)],
}


def test_hertz_inside_jit_is_finite_and_successful_for_good_input():
    out = _hertz_all(**_HERTZ_GOOD)
    for argument, reach in _HERTZ_REACH.items():
        for value, code in reach(out):
            assert np.all(np.isfinite(value)), argument
            if code is not None:
                assert np.all(code == hertz.RESULTS.successful), argument


@FUZZ
@given(argument=st.sampled_from(sorted(_HERTZ_REACH)), value=st.sampled_from(NON_FINITE))
def test_hertz_inside_jit_never_turns_non_finite_input_into_a_number(argument, value):
    out = _hertz_all(**{**_HERTZ_GOOD, argument: value})
    for output, code in _HERTZ_REACH[argument](out):
        assert _not_finite_or_flagged(output, code), (argument, value, output, code)


@jax.jit
def _gaf_stroke(theta, gamma, torque, R, width):
    return friction.gaf(theta, gamma, torque, R, model="stroke", width=width)


@FUZZ
@given(argument=st.integers(0, 4), value=st.sampled_from(NON_FINITE))
def test_gaf_inside_jit_never_turns_non_finite_input_into_a_number(argument, value):
    args = [0.3, 0.3, 100.0, 25.0, 0.01]
    args[argument] = value
    assert _not_finite_or_flagged(_gaf_stroke(*args)), (argument, value)


@jax.jit
def _gaf_rms(R, l, gamma0, torque, mu_slp):
    layout = tj.Layout(R, l, gamma0)
    params = friction.GREASE_A.replace(mu_slp=mu_slp)
    result = friction.gaf_halfshaft(layout, torque, params, n_theta=36, model="stroke")
    return result.rms, getattr(result, "result", None)


def test_gaf_rms_of_a_nan_torque_inside_jit_is_nan_not_zero():
    rms, _ = _gaf_rms(25.0, 500.0, 0.3, math.nan, 0.06)
    assert np.isnan(float(rms))


@FUZZ
@given(argument=st.integers(0, 4), value=st.sampled_from(NON_FINITE))
def test_gaf_halfshaft_inside_jit_never_turns_non_finite_input_into_a_number(argument, value):
    args = [25.0, 500.0, 0.3, 100.0, 0.06]
    args[argument] = value
    rms, code = _gaf_rms(*args)
    assert _not_finite_or_flagged(rms, code), (argument, value, rms, code)


@jax.jit
def _metrics(R, l, gamma0):
    return tj.kinematic_metrics(tj.Layout(R, l, gamma0), n_theta=36)


@FUZZ
@given(argument=st.integers(0, 2), value=st.sampled_from(NON_FINITE))
def test_kinematic_metrics_inside_jit_never_turn_non_finite_input_into_a_number(argument, value):
    args = [25.0, 500.0, 0.3]
    args[argument] = value
    metrics = _metrics(*args)
    assert not bool(metrics.converged), (argument, value)
    floats = {k: v for k, v in vars(metrics).items() if np.asarray(v).dtype.kind == "f"}
    assert all(not np.isfinite(v) for k, v in floats.items() if k.endswith("_pp")), floats
    code = getattr(metrics, "result", None)
    if code is not None:
        assert int(code) != int(hertz.RESULTS.successful)


def test_solve_halfshaft_at_a_nan_theta_is_not_successful():
    theta = jnp.array([0.1, math.nan, math.inf, 0.3])
    solution = tj.solve_halfshaft(_layout(), theta)
    converged = np.asarray(solution.converged)
    assert converged[0] and converged[3] and not converged[1] and not converged[2]
    assert _all_nan(solution.psi[1], solution.gamma[1])
    code = getattr(solution, "result", None)
    if code is not None:
        assert np.all(np.asarray(code)[1:3] != int(hertz.RESULTS.successful))


# --------------------------------------------------------------------------- the optimiser's objects


def _optimize():
    from tripodjax import optimize

    return optimize


def _result_of(spec):
    """A Result of ``spec``'s structure, as ``solve`` returns it (no solve: only its shape)."""
    from tripodjax.optimize.problem import constraint_names
    from tripodjax.optimize.solver import Result

    names = constraint_names(spec.structure)
    design = {k: 1.0 for k in spec.structure.free}
    return Result(
        design=design,
        objective=1.0,
        constraints={n: {"margin": 0.1} for n in names},
        quantities={},
        kkt_residual=0.0,
        kkt_converged=True,
        halfshaft_converged=True,
        hertz_converged=True,
        converged=True,
        feasible=True,
        result="successful",
        multipliers={n: 0.0 for n in names},
        history={},
        starts=[{"design": design}],
        fidelity="newton",
        x=np.ones(len(spec.structure.free)),
    )


OBJECTS = [None, {}, "spec", 5, [1.0], _Opaque()]


@pytest.mark.parametrize("bad", OBJECTS, ids=repr)
@pytest.mark.parametrize(
    "function",
    ["evaluate", "evaluate_catalogue", "constraint_landscape", "sensitivities"],
)
def test_optimiser_functions_name_a_spec_of_the_wrong_type(function, bad):
    optimize = _optimize()
    spec = optimize.load_spec()
    calls = {
        "evaluate": lambda: optimize.evaluate(bad, {"R": 21.3, "d_roller": 27.8}),
        "evaluate_catalogue": lambda: optimize.evaluate_catalogue(bad),
        "constraint_landscape": lambda: optimize.constraint_landscape(bad, [20.0], [30.0]),
        "sensitivities": lambda: optimize.sensitivities(bad, _result_of(spec)),
    }
    with pytest.raises(TypeError, match="^spec = .*allowed: a Spec"):
        calls[function]()


@pytest.mark.parametrize("bad", [None, [21.3, 27.8], "R", 5, (("R", 21.3),)], ids=repr)
def test_evaluate_names_a_design_that_is_no_mapping(bad):
    optimize = _optimize()
    with pytest.raises(TypeError, match="^design = .*allowed: a mapping"):
        optimize.evaluate(optimize.load_spec(), bad)


@pytest.mark.parametrize("bad", [None, {}, "result", 1.0], ids=repr)
def test_sensitivities_names_a_result_of_the_wrong_type(bad):
    optimize = _optimize()
    with pytest.raises(TypeError, match="^result = .*allowed: the Result"):
        optimize.sensitivities(optimize.load_spec(), bad)


@pytest.mark.parametrize(
    "other",
    [
        "[bounds]\nconformity = [1.002, 1.008]",  # another free variable
        "[constraints]\nmax_outer_diameter = 90.0",  # another constraint
        '[bounds]\nd_roller = "fixed"',
    ],
)
def test_sensitivities_of_another_specs_result_is_a_type_error(other):
    optimize = _optimize()
    result = _result_of(optimize.parse_spec(other))
    with pytest.raises(TypeError, match="^result is the Result of another spec"):
        optimize.sensitivities(optimize.load_spec(), result)


@pytest.mark.parametrize(
    "R, d",
    [
        (jnp.asarray(21.3), jnp.asarray(27.8)),
        (np.float32(21.3), np.float64(27.8)),
        (np.asarray(21.3), 27.8),
        (jnp.asarray(21.3, jnp.float32), np.int64(28)),
    ],
    ids=["jax 0-d", "numpy scalars", "numpy 0-d", "jax float32, numpy int"],
)
def test_evaluate_takes_real_scalars_of_any_library_in_any_mapping(R, d):
    import types

    optimize = _optimize()
    spec = optimize.load_spec()
    plain = optimize.evaluate(spec, {"R": float(R), "d_roller": float(d)})
    given = optimize.evaluate(spec, types.MappingProxyType({"R": R, "d_roller": d}))
    assert given == plain


@pytest.mark.parametrize(
    "value, error, fragment",
    [
        (10**400, ValueError, "beyond the float range"),
        (jnp.asarray([21.3, 22.0]), TypeError, "shape (2,)"),
        (True, TypeError, "design['R'] = True"),
        ("21.3", TypeError, "design['R'] = '21.3'"),
    ],
)
def test_evaluate_design_values_that_are_no_real_number_name_the_key(value, error, fragment):
    optimize = _optimize()
    with pytest.raises(error) as info:
        optimize.evaluate(optimize.load_spec(), {"R": value, "d_roller": 27.8})
    assert fragment in str(info.value)
