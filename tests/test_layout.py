import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tripodjax as tj
from tripodjax import TABLE_2_1, Layout, seed_case


def test_fields_and_degrees():
    layout = Layout.from_degrees(25.0, 500.0, 20.0)
    assert layout.R == 25.0 and layout.l == 500.0
    assert layout.gamma0 == pytest.approx(math.radians(20.0), abs=1e-15)
    assert seed_case("N") == layout


def test_is_immutable():
    layout = seed_case("N")
    with pytest.raises(AttributeError):
        layout.R = 30.0


def test_pytree_roundtrip_jit_and_vmap():
    layout = seed_case("N")
    leaves, treedef = jax.tree_util.tree_flatten(layout)
    assert len(leaves) == 3
    assert jax.tree_util.tree_unflatten(treedef, leaves) == layout
    batch = Layout(jnp.array([20.0, 30.0]), jnp.array([400.0, 500.0]), jnp.array([0.1, 0.2]))
    ratio = jax.jit(jax.vmap(lambda lay: lay.R / lay.l))(batch)
    np.testing.assert_allclose(ratio, [0.05, 0.06])


def test_only_traced_fields_are_not_range_checked():
    jax.jit(lambda g: Layout(25.0, 500.0, g).gamma0)(jnp.array(1.5))
    jax.vmap(lambda r: Layout(r, 500.0, 0.3).R)(jnp.array([-1.0, 200.0]))


@pytest.mark.parametrize(
    "make",
    [
        lambda v, good: float(v),
        lambda v, good: np.float32(v),
        lambda v, good: np.asarray(v),
        lambda v, good: jnp.asarray(v),
        lambda v, good: jnp.asarray([good, v, good]),
        lambda v, good: np.asarray([[good, v]]),
    ],
)
@pytest.mark.parametrize(
    "field, value, fragment",
    [
        ("R", -25.0, "R > 0 mm"),
        ("R", 125.0, "R/l ≤ 0.2"),
        ("gamma0", 1.2, "π/4"),
        ("l", math.nan, "l > 0 mm"),
    ],
)
def test_every_concrete_field_is_checked_element_by_element(make, field, value, fragment):
    fields = dict(R=25.0, l=500.0, gamma0=0.3)
    fields[field] = make(value, fields[field])
    with pytest.raises(ValueError, match=fragment) as info:
        Layout(**fields)
    if np.ndim(fields[field]):  # the first bad index is named
        index = "1" if np.ndim(fields[field]) == 1 else "0,1"
        assert f"{field}[{index}]" in str(info.value)


@pytest.mark.parametrize(
    "fields, fragment",
    [
        (dict(R=np.full(3, 25.0), l=np.full(2, 500.0), gamma0=0.3), "R (3,), l (2,), gamma0 ()"),
        (dict(R=np.zeros((2, 3)) + 25, l=np.full(2, 500.0), gamma0=0.3), "broadcast together"),
        (dict(R=np.zeros(0), l=500.0, gamma0=0.3), "Layout.R is empty"),
        (dict(R=25.0, l=jnp.zeros((0, 2)), gamma0=0.3), "Layout.l is empty"),
    ],
)
def test_field_shapes_must_broadcast_and_not_be_empty(fields, fragment):
    with pytest.raises(ValueError, match=fragment.replace("(", r"\(").replace(")", r"\)")):
        Layout(**fields)
    traced = {k: v for k, v in fields.items() if np.ndim(v)}
    with pytest.raises(ValueError, match="Layout"):  # shapes are static: checked under jit too
        jax.jit(lambda kw: Layout(**{**fields, **kw}))(traced)


def test_jax_rebuilds_layouts_without_the_checks():
    layout = seed_case("N")
    # Cotangents may be negative or zero, and tree_map may put None in every field.
    grad = jax.grad(lambda lay: -lay.R * lay.gamma0 - lay.l)(layout)
    assert isinstance(grad, Layout) and float(grad.l) == -1.0
    assert jax.tree.map(lambda x: None, layout).R is None
    zero = jax.tree.map(jnp.zeros_like, layout)
    assert float(zero.l) == 0.0


@pytest.mark.parametrize(
    "bad",
    ["25", b"25", True, False, np.bool_(True), None, 1 + 2j, [25.0, "a"], {"R": 25.0}, object()],
)
@pytest.mark.parametrize("field", ["R", "l", "gamma0"])
def test_fields_must_be_real_numbers(field, bad):
    kwargs = dict(R=25.0, l=500.0, gamma0=0.3)
    kwargs[field] = bad
    with pytest.raises(TypeError, match=f"Layout.{field}"):
        Layout(**kwargs)


@pytest.mark.parametrize("sequence", [list, tuple])
def test_python_sequences_are_arrays(sequence):
    layout = Layout(sequence([25.0, 26.0]), sequence([500.0, 500.0]), sequence([0.3, 0.3]))
    assert all(isinstance(getattr(layout, f), np.ndarray) for f in ("R", "l", "gamma0"))
    assert len(jax.tree_util.tree_leaves(layout)) == 3  # three leaves, not six
    arrays = Layout(np.array([25.0, 26.0]), np.array([500.0, 500.0]), np.array([0.3, 0.3]))
    got, want = tj.sweep(layout, n_theta=36), tj.sweep(arrays, n_theta=36)
    for name in want:
        np.testing.assert_array_equal(got[name], want[name])


def test_float16_is_refused_in_one_line():
    for call in (
        lambda: Layout(np.float16(25.0), 500.0, 0.3),
        lambda: tj.solve_halfshaft(Layout(25.0, 500.0, 0.3), np.float16(0.3)),
        lambda: tj.solve_halfshaft(Layout(25.0, 500.0, 0.3), jnp.zeros(3, jnp.float16)),
    ):
        with pytest.raises(TypeError, match=r"has dtype float16; allowed: float32 or float64"):
            call()


def test_boolean_and_string_arrays_are_rejected():
    with pytest.raises(TypeError, match="Layout.R .* has dtype bool"):
        Layout(np.array([True, False]), np.ones(2), np.ones(2))
    with pytest.raises(TypeError, match="Layout.gamma0"):
        Layout(25.0, 500.0, np.array(["0.1"]))


def test_numpy_scalars_are_checked_like_python_numbers():
    Layout(np.float32(25.0), np.int64(500), np.float64(0.3))
    with pytest.raises(ValueError, match="Layout.R = -1.0"):
        Layout(np.float32(-1.0), 500.0, 0.3)
    with pytest.raises(ValueError, match="Layout.gamma0 = nan"):
        Layout(25.0, 500.0, np.array(np.nan))


@pytest.mark.parametrize(
    "kwargs, field, allowed",
    [
        (dict(R=0.0, l=500.0, gamma0=0.3), "Layout.R = 0.0", "R > 0"),
        (dict(R=-5.0, l=500.0, gamma0=0.3), "Layout.R = -5.0", "R > 0"),
        (dict(R=25.0, l=0.0, gamma0=0.3), "Layout.l = 0.0", "l > 0"),
        (dict(R=25.0, l=-1.0, gamma0=0.3), "Layout.l = -1.0", "l > 0"),
        (dict(R=25.0, l=100.0, gamma0=0.3), "Layout.R / Layout.l", "R/l ≤ 0.2"),
        (dict(R=25.0, l=500.0, gamma0=-0.01), "Layout.gamma0 = -0.01", "0 ≤ gamma0"),
        (dict(R=25.0, l=500.0, gamma0=0.8), "Layout.gamma0 = 0.8", "(45°)"),
        (dict(R=float("nan"), l=500.0, gamma0=0.3), "Layout.R = nan", "finite"),
        (dict(R=25.0, l=float("inf"), gamma0=0.3), "Layout.l = inf", "finite"),
    ],
)
def test_bad_inputs_name_field_value_and_range(kwargs, field, allowed):
    with pytest.raises(ValueError) as info:
        Layout(**kwargs)
    message = str(info.value)
    assert field in message and allowed in message


def test_domain_edges_are_allowed():
    Layout(25.0, 125.0, 0.0)  # R/l = 0.2, gamma0 = 0
    Layout.from_degrees(25.0, 500.0, 45.0)


def test_from_degrees_rejects_out_of_range_in_degrees():
    with pytest.raises(
        ValueError, match="gamma0_deg = 50.0 is outside the allowed range: 0 ≤ gamma0_deg ≤ 45"
    ):
        Layout.from_degrees(25.0, 500.0, 50.0)
    for bad in (float("nan"), float("inf"), -1.0):
        with pytest.raises(ValueError, match="gamma0_deg"):
            Layout.from_degrees(25.0, 500.0, bad)
    for bad in ("20", True, None):
        with pytest.raises(TypeError, match="gamma0_deg"):
            Layout.from_degrees(25.0, 500.0, bad)
    with pytest.raises(TypeError, match="Layout.R"):
        Layout.from_degrees("25", 500.0, 20.0)


def test_the_rule_is_shared_with_array_names_and_degrees():
    from tripodjax._checks import check_layout_domain

    with pytest.raises(
        ValueError, match=r"layouts.R\[1\] = -3.0 is outside the allowed range: R > 0 mm"
    ):
        check_layout_domain(np.array([25.0, -3.0]), np.array([500.0, 500.0]), prefix="layouts.")
    with pytest.raises(
        ValueError,
        match=r"layouts.R\[1\] / layouts.l\[1\] = 0.3 is outside the allowed range: R/l ≤ 0.2",
    ):
        check_layout_domain(np.array([25.0, 150.0]), np.array([500.0, 500.0]), prefix="layouts.")
    with pytest.raises(ValueError, match=r"layout.gamma0_deg = 60.0 .*0 ≤ gamma0_deg ≤ 45"):
        check_layout_domain(gamma0=60.0, names={"gamma0": "layout.gamma0_deg"}, degrees=True)
    with pytest.raises(ValueError, match=r"bounds.R\[1\] / layout.l = 0.44"):
        check_layout_domain(R=[20.0, 220.0], l=500.0, names={"R": "bounds.R", "l": "layout.l"})
    with pytest.raises(TypeError, match="layout.l = 'x'"):
        check_layout_domain(l="x", names={"l": "layout.l"})
    check_layout_domain(R=np.array([25.0, 100.0]), l=500.0, gamma0=np.array([0.0, np.pi / 4]))


def test_seed_cases():
    assert len(TABLE_2_1) == 11
    assert seed_case("L3").l == 300.0 and seed_case("R4").R == 40.0
    with pytest.raises(ValueError, match="code = 'X' is not allowed; allowed: 'N', 'L3'"):
        seed_case("X")
    for bad in (None, 1, True, ["N"]):
        with pytest.raises(TypeError, match="code = "):
            seed_case(bad)
    with pytest.raises(TypeError, match="does not support item assignment"):
        TABLE_2_1["N"] = (500.0, 99.0, 20.0)  # type: ignore[index]  # read-only: seed_case stays
