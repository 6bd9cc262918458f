"""Batch sweeps and fidelity levels (tripodjax.sweep, analytic_halfshaft)."""

import json
import os
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from tripodjax import Layout, friction, kinematic_metrics, sweep
from tripodjax.bench import numpy_newton_metrics, random_layouts
from tripodjax.halfshaft import analytic_halfshaft, solve_halfshaft


def layouts(n, seed=0, dtype=np.float64):
    return Layout(*(a.astype(dtype) for a in random_layouts(n, seed)))


def test_sweep_matches_kinematic_metrics_one_by_one():
    batch = layouts(7)
    result = sweep(batch, outputs=("irregularity", "ecc_max", "roller_stroke", "converged"))
    for i in range(7):
        single = kinematic_metrics(
            Layout(float(batch.R[i]), float(batch.l[i]), float(batch.gamma0[i]))
        )
        assert result["irregularity"][i] == pytest.approx(float(single.irregularity), rel=1e-12)
        assert result["ecc_max"][i] == pytest.approx(float(single.ecc_max), rel=1e-12)
        assert result["roller_stroke"][i] == pytest.approx(float(single.roller_stroke), rel=1e-12)
    assert result["converged"].all() and set(result) == {
        "irregularity",
        "ecc_max",
        "roller_stroke",
        "converged",
    }


def test_chunking_does_not_change_results():
    batch = layouts(23)
    whole = sweep(batch, outputs=("delta_pp", "irregularity"))
    chunked = sweep(batch, outputs=("delta_pp", "irregularity"), chunk_size=5)
    for name in whole:
        np.testing.assert_array_equal(chunked[name], whole[name])


def test_gaf_outputs_match_gaf_halfshaft():
    batch = layouts(3)
    result = sweep(batch, outputs=("gaf_rms", "gaf_third_order"), torque=800.0, gaf_model="stroke")
    for i in range(3):
        one = friction.gaf_halfshaft(
            Layout(float(batch.R[i]), float(batch.l[i]), float(batch.gamma0[i])),
            800.0,
            model="stroke",
        )
        assert result["gaf_rms"][i] == pytest.approx(float(one.rms), rel=1e-12)
        assert result["gaf_third_order"][i] == pytest.approx(float(one.third_order), rel=1e-12)


def test_newton_controls_are_passed_through():
    batch = layouts(4)
    capped = sweep(batch, outputs=("converged",), max_steps=1)
    assert not capped["converged"].any()


def test_analytic_fidelity_accuracy_over_the_design_range():
    """Issue acceptance: irregularity within 2 % for R 18–42 mm, l 300–800 mm, γ0 5–25°."""
    batch = layouts(400, seed=3)
    newton = sweep(batch, outputs=("delta_pp", "irregularity"))
    analytic = sweep(batch, fidelity="analytic", outputs=("delta_pp", "irregularity", "converged"))
    assert np.max(np.abs(analytic["irregularity"] / newton["irregularity"] - 1)) < 0.005
    assert np.max(np.abs(analytic["delta_pp"] / newton["delta_pp"] - 1)) < 0.001
    assert analytic["converged"].all()


def test_analytic_solution_at_zero_angle_and_its_residual():
    exact = analytic_halfshaft(Layout(25.0, 500.0, 0.0), np.linspace(0, 2, 9))
    np.testing.assert_array_equal(exact.delta, 0.0)
    np.testing.assert_array_equal(exact.gamma, 0.0)
    layout = Layout.from_degrees(25.0, 500.0, 20.0)
    theta = np.linspace(0, 2 * np.pi / 3, 41)
    approx, solved = analytic_halfshaft(layout, theta), solve_halfshaft(layout, theta)
    assert float(jnp.max(jnp.abs(approx.delta - solved.delta))) < 2e-3 * float(
        jnp.max(jnp.abs(solved.delta))
    )
    # Its residual is its truncation error: far above the solve's (~1e-18), and bounded by the
    # first-order γ ripple (v is ~3 % off, Δ ~ 5e-3 here, so g2 ~ 2e-4).
    assert 1e-12 < float(jnp.max(jnp.abs(approx.residual))) < 1e-3


def test_analytic_gradients_match_central_differences():
    base = dict(R=30.0, l=450.0, gamma0=0.3)
    grads = jax.grad(lambda lay: kinematic_metrics(lay, fidelity="analytic").irregularity)(
        Layout(**base)
    )
    for name in base:
        step = 1e-6 * base[name]
        plus, minus = dict(base), dict(base)
        plus[name] += step
        minus[name] -= step
        fd = (
            float(kinematic_metrics(Layout(**plus), fidelity="analytic").irregularity)
            - float(kinematic_metrics(Layout(**minus), fidelity="analytic").irregularity)
        ) / (2 * step)
        assert float(getattr(grads, name)) == pytest.approx(fd, rel=1e-6)


def test_float32_sweep(float32_default):
    batch = layouts(5, dtype=np.float32)
    result = sweep(batch, outputs=("irregularity", "converged"))
    assert result["irregularity"].dtype == np.float32 and result["converged"].all()
    with jax.enable_x64(True):
        reference = sweep(layouts(5), outputs=("irregularity",))["irregularity"]
    np.testing.assert_allclose(result["irregularity"], reference, rtol=1e-4)


def test_numpy_peer_solves_the_same_equations():
    R, l, g = random_layouts(6, seed=4)
    peer = numpy_newton_metrics(R, l, g, 360)
    ours = sweep(Layout(R, l, g), outputs=("delta_pp", "irregularity", "gamma_pp"))
    for name in peer:
        np.testing.assert_allclose(peer[name], ours[name], rtol=1e-11)


@pytest.mark.parametrize(
    "build, kwargs, message",
    [
        (
            lambda: Layout(np.array([25.0, -3.0]), np.array([500.0, 500.0]), np.array([0.2, 0.2])),
            {},
            "layouts.R[1] = -3.0 is outside the allowed range: R > 0 mm",
        ),
        (
            lambda: Layout(np.array([25.0, 30.0]), np.array([500.0, 100.0]), np.array([0.2, 0.2])),
            {},
            "layouts.R[1] / layouts.l[1] = 0.3 is outside the allowed range: R/l ≤ 0.2",
        ),
        (
            lambda: Layout(np.array([25.0]), np.array([500.0]), np.array([0.9])),
            {},
            "layouts.gamma0[0] = 0.9 is outside the allowed range",
        ),
        (
            lambda: Layout(np.array([25.0, 30.0]), np.array([500.0]), np.array([0.2, 0.2])),
            {},
            "1-D arrays of one length",
        ),
        (lambda: layouts(2), {"outputs": ("irregularity", "gaf_rms")}, "need a torque"),
        (lambda: layouts(2), {"outputs": ("speed",)}, "not allowed; allowed: delta_pp"),
        (
            lambda: layouts(2),
            {"fidelity": "exact"},
            "fidelity = 'exact' is not allowed; allowed: newton, analytic",
        ),
        (lambda: layouts(2), {"n_theta": 100}, "n_theta = 100 is not allowed"),
    ],
)
def test_bad_inputs(build, kwargs, message):
    with pytest.raises(ValueError) as info:
        sweep(build(), **kwargs)
    assert message in str(info.value)


def test_progress_bar_only_when_asked_or_on_a_terminal(capsys):
    sweep(layouts(6), outputs=("irregularity",), chunk_size=2, progress=True)
    assert "6/6 layouts" in capsys.readouterr().err
    sweep(layouts(6), outputs=("irregularity",), chunk_size=2)
    assert capsys.readouterr().err == ""  # stderr is no terminal under pytest


def test_sharded_sweep_equals_one_device_sweep():
    """Four CPU devices (XLA's host-platform flag), in a fresh process."""
    code = textwrap.dedent(
        """
        import json, jax, numpy as np
        jax.config.update("jax_enable_x64", True)
        import tripodjax as tj
        from tripodjax.bench import random_layouts
        lay = tj.Layout(*random_layouts(37, seed=9))
        names = ("delta_pp", "irregularity", "gamma_pp", "gaf_rms")
        many = tj.sweep(lay, outputs=names, torque=500.0, chunk_size=16)
        one = tj.sweep(lay, outputs=names, torque=500.0, chunk_size=16, devices=jax.devices()[:1])
        print(json.dumps({"devices": len(jax.devices()), "diff": max(float(np.max(np.abs(many[n] - one[n]) / np.abs(one[n]))) for n in names)}))
        """
    )
    env = dict(
        os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=4", JAX_PLATFORMS="cpu"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600
    )
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["devices"] == 4
    assert result["diff"] <= 1e-12
