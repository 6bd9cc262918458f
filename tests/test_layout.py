import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

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


def test_traced_and_array_fields_are_not_checked():
    # Out-of-domain values inside arrays pass: the domain check is for Python numbers only.
    Layout(jnp.array(-1.0), jnp.array(500.0), jnp.array(2.0))
    jax.jit(lambda g: Layout(25.0, 500.0, g).gamma0)(jnp.array(1.5))


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
    with pytest.raises(ValueError, match="got 50°"):
        Layout.from_degrees(25.0, 500.0, 50.0)


def test_seed_cases():
    assert len(TABLE_2_1) == 11
    assert seed_case("L3").l == 300.0 and seed_case("R4").R == 40.0
    with pytest.raises(ValueError, match="unknown Table 2.1 case 'X'"):
        seed_case("X")
