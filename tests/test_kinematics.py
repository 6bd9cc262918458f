"""Kinematic metrics (seed §2.10, §2.11.3): seed numbers, independent solve, gradients, limits."""

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import reference

from tripodjax import (
    TABLE_2_1,
    Layout,
    forces,
    friction,
    kinematic_metrics,
    kinematics,
    seed_case,
    sweep,
)
from tripodjax._compile import latency_bound_jit
from tripodjax.bench import domain_layouts
from tripodjax.kinematics import FROM_SERIES, metrics_and_window, metrics_from, revolution
from tripodjax.results import RESULTS
from tripodjax.solvers import Analytic

COMPARED = ("delta_pp", "irregularity", "gamma_pp", "ecc_max")


def assert_metrics_match_reference(layout, rtol):
    ours = kinematic_metrics(layout)
    assert bool(ours.converged)
    theirs = reference.metrics(layout.R, layout.l, layout.gamma0)
    for name in COMPARED:
        assert float(getattr(ours, name)) == pytest.approx(theirs[name], rel=rtol), name


def test_seed_case_N_numbers():
    metrics = kinematic_metrics(seed_case("N"))
    # §2.11.3: Δ(θ) = −4.7·10⁻³ sin 3θ rad and Irr = 2.82 %; the brief's check gives 2.83 %.
    assert float(metrics.delta_pp) / 2 == pytest.approx(4.7e-3, abs=0.05e-3)
    assert 0.0282 <= float(metrics.irregularity) <= 0.0283
    # The brief: γ ripples +0.19° above γ0.
    assert math.degrees(float(metrics.gamma_max) - seed_case("N").gamma0) == pytest.approx(
        0.19, abs=0.005
    )


def test_seed_trends_over_table_2_1():
    """§2.10: Δ p-p grows with R and γ0, falls with l, about 0.4–0.9° over the table."""
    pp = {
        code: math.degrees(float(kinematic_metrics(seed_case(code)).delta_pp)) for code in TABLE_2_1
    }
    assert pp["R2"] < pp["N"] < pp["R3"] < pp["R4"]
    assert pp["g5"] < pp["g10"] < pp["g15"] < pp["N"] < pp["g25"]
    assert pp["L3"] > pp["L4"] > pp["N"] > pp["L7"]
    nonzero = [v for k, v in pp.items() if k not in ("g5", "g10")]
    assert 0.35 < min(nonzero) and max(pp.values()) < 0.95


@pytest.mark.parametrize("code", list(TABLE_2_1))
def test_table_2_1_metrics_against_fsolve(code):
    # The reference's dψ/dθ is a central difference (error ~1e-9): rtol 1e-6.
    assert_metrics_match_reference(seed_case(code), rtol=1e-6)


def test_random_layout_metrics_against_fsolve():
    rng = np.random.default_rng(11)
    for _ in range(6):
        layout = Layout.from_degrees(rng.uniform(15, 45), rng.uniform(250, 900), rng.uniform(1, 40))
        assert_metrics_match_reference(layout, rtol=1e-6)


@pytest.mark.parametrize(
    "layout", [Layout.from_degrees(25.0, 500.0, 45.0), Layout(40.0, 200.0, 0.6)]
)
def test_extreme_layout_metrics_against_fsolve(layout):
    assert_metrics_match_reference(layout, rtol=1e-6)


@pytest.mark.parametrize(
    "name", ["irregularity", "ecc_max", "delta_pp", "gamma_pp", "roller_stroke"]
)
def test_gradients_match_central_differences(name):
    base = {"R": 28.0, "l": 420.0, "gamma0": 0.31}
    grads = jax.grad(lambda lay: getattr(kinematic_metrics(lay), name))(Layout(**base))
    for field in ("R", "l", "gamma0"):
        step = 1e-5 * base[field]
        values = []
        for sign in (1, -1):
            moved = dict(base)
            moved[field] += sign * step
            values.append(float(getattr(kinematic_metrics(Layout(**moved)), name)))
        fd = (values[0] - values[1]) / (2 * step)
        assert float(getattr(grads, field)) == pytest.approx(fd, rel=1e-3, abs=1e-12), field


DIFFERENTIATED = tuple(name for name in kinematics.METRICS if name not in ("converged", "result"))


@pytest.mark.parametrize(
    "dtype, rtol, solver",
    [
        ("float64", 1e-9, "newton"),
        ("float32", 1e-4, "newton"),
        ("float64", 1e-9, Analytic(nodes=None)),  # solved again at the extremes' angles
    ],
)
def test_jacobian_at_the_extremes_equals_the_whole_revolutions(dtype, rtol, solver):
    """Each metric's Jacobian comes from the revolution linearised at its extremes' angles
    alone (Danskin; Newton's from the implicit derivative at the grid's answer): it equals
    JAX's linearisation of the whole revolution (every angle), over the domain, its corner
    and edges included, in both dtypes."""
    with jax.enable_x64(dtype == "float64"):
        fields = [jnp.asarray(a, dtype) for a in domain_layouts(64, seed=5)]
        keep = np.flatnonzero(fields[2] > 1e-3)[:24]  # γ0 = 0: γ − γ0 ties at every angle
        layouts = Layout(*(f[keep] for f in fields))

        def ours(layout):
            metrics = kinematic_metrics(layout, solver=solver)
            return {name: getattr(metrics, name) for name in DIFFERENTIATED}

        def whole(layout):
            sol, rates = revolution(layout, 360, solver, with_rates=True)
            return metrics_from(layout, sol, rates, DIFFERENTIATED)

        ours, whole = (latency_bound_jit(jax.vmap(jax.jacfwd(f)))(layouts) for f in (ours, whole))
        for name in DIFFERENTIATED:
            for field in ("R", "l", "gamma0"):
                a, b = (np.asarray(getattr(j[name], field)) for j in (ours, whole))
                np.testing.assert_allclose(a, b, rtol=rtol, atol=0, err_msg=f"{name} {field}")


@pytest.mark.parametrize("solver", ["newton", "analytic"])
def test_roller_axial_stroke_gradient_is_finite_over_the_domain(solver):
    """jax.grad of a grid extreme at top level (its program compiled for latency): JAX's rule
    for max compares the series with its maximum to find it, and XLA's two roundings of the
    series there compared unequal at 7 of these layouts (0/0: NaN). The gradient is finite
    and matches central differences."""
    fields = domain_layouts(64, seed=5)
    keep = np.flatnonzero(fields[2] > 1e-3)[:24]

    @jax.jit
    def stroke(R, l, gamma0):  # unchecked: a step may leave the domain's edge R/l = 0.2
        layout = Layout(R, l, gamma0)
        sol, rates = revolution(layout, 360, solver, with_rates=True)
        return metrics_from(layout, sol, rates, ("roller_axial_stroke",))["roller_axial_stroke"]

    for i in keep:
        base = {name: float(f[i]) for name, f in zip(("R", "l", "gamma0"), fields, strict=True)}
        grads = jax.grad(lambda lay: kinematic_metrics(lay, solver=solver).roller_axial_stroke)(
            Layout(**base)
        )
        for name in ("R", "gamma0"):
            step = 1e-6 * base[name]
            moved = [dict(base, **{name: base[name] + sign * step}) for sign in (1, -1)]
            fd = (float(stroke(**moved[0])) - float(stroke(**moved[1]))) / (2 * step)
            assert float(getattr(grads, name)) == pytest.approx(fd, rel=1e-4, abs=1e-9), (i, name)


def test_second_derivatives_match_differences_of_the_gradient():
    """The Jacobian's rule is itself differentiable (the implicit derivative at the known
    solution): a Hessian-vector product of the irregularity w.r.t. (R, l, γ0) equals central
    differences of its gradient (the same program's primal output)."""
    base = {"R": 28.0, "l": 420.0, "gamma0": 0.31}
    direction = Layout(0.3, 2.0, 0.01)

    def gradient(lay):
        return jax.grad(lambda lay: kinematic_metrics(lay).irregularity)(lay)

    # Compiled for latency (no LLVM optimisation): the test waits for the compile alone.
    product_of = latency_bound_jit(lambda lay: jax.jvp(gradient, (lay,), (direction,)))
    _, product = product_of(Layout(**base))
    step = 1e-5
    plus, minus = (
        product_of(Layout(*(base[f] + sign * step * getattr(direction, f) for f in base)))[0]
        for sign in (1, -1)
    )
    for field in base:
        fd = (float(getattr(plus, field)) - float(getattr(minus, field))) / (2 * step)
        assert float(getattr(product, field)) == pytest.approx(fd, rel=1e-4), field


def test_jacfwd_over_all_fields():
    jac = jax.jacfwd(lambda lay: kinematic_metrics(lay).irregularity)(seed_case("N"))
    assert all(np.isfinite(float(v)) for v in jax.tree_util.tree_leaves(jac))


def test_gamma0_zero_values_and_gradients_are_finite():
    layout = Layout(25.0, 500.0, 0.0)
    metrics = kinematic_metrics(layout)
    assert bool(metrics.converged)
    for name in ("delta_pp", "irregularity", "gamma_pp", "ecc_max", "roller_stroke"):
        assert float(getattr(metrics, name)) == pytest.approx(0.0, abs=1e-14)
    grads = jax.grad(lambda lay: kinematic_metrics(lay).irregularity)(layout)
    assert all(np.isfinite(float(v)) for v in jax.tree_util.tree_leaves(grads))


def test_right_limit_at_gamma0_zero_is_continuous():
    """Irr ≈ 6 e(γ0)/|h| ≈ 1.5 (R/l) γ0 as γ0 → 0+ (§2.11 first order)."""
    R, l = 25.0, 500.0
    for gamma0 in (1e-3, 1e-5, 1e-8):
        irr = float(kinematic_metrics(Layout(R, l, gamma0)).irregularity)
        assert irr / gamma0 == pytest.approx(1.5 * R / l, rel=2e-3)


def test_float32_irregularity_within_1e_3_of_float64(float32_default):
    metrics32 = kinematic_metrics(seed_case("N"))
    assert metrics32.irregularity.dtype == jnp.float32 and bool(metrics32.converged)
    with jax.enable_x64(True):
        irr64 = float(kinematic_metrics(seed_case("N")).irregularity)
    assert float(metrics32.irregularity) == pytest.approx(irr64, rel=1e-3)


def test_inside_a_users_jit_equals_the_top_level_call():
    """The top-level call is compiled for latency (its own compiler options); inside a user's
    jax.jit, jax.grad or both the same metrics and derivatives come from the caller's program
    (JAX takes compiler options on a top-level program only)."""
    layout = seed_case("N")

    def irregularity(lay):
        return kinematic_metrics(lay).irregularity

    top, slope = kinematic_metrics(layout), jax.grad(irregularity)(layout)
    inside = jax.jit(kinematic_metrics)(layout)
    slope_inside = jax.jit(jax.grad(irregularity))(layout)
    for name in ("irregularity", "delta_pp", "gamma_pp", "roller_axial_stroke"):
        assert float(getattr(inside, name)) == pytest.approx(float(getattr(top, name)), rel=1e-13)
    for field in ("R", "l", "gamma0"):
        assert float(getattr(slope_inside, field)) == pytest.approx(
            float(getattr(slope, field)), rel=1e-12
        )


def test_vmap_over_layouts_matches_one_by_one():
    codes = ["N", "R4", "g5"]
    batch = Layout(
        *(jnp.array([getattr(seed_case(c), f) for c in codes]) for f in ("R", "l", "gamma0"))
    )
    batched = jax.vmap(kinematic_metrics)(batch)
    for i, code in enumerate(codes):
        single = kinematic_metrics(seed_case(code))
        assert float(batched.irregularity[i]) == pytest.approx(
            float(single.irregularity), rel=1e-13
        )


def test_n_theta_must_be_a_multiple_of_6_and_solver_known():
    with pytest.raises(ValueError, match="n_theta = 100 is not allowed"):
        kinematic_metrics(seed_case("N"), n_theta=100)
    with pytest.raises(ValueError, match="solver = 'exact' is not allowed; allowed: 'newton'"):
        kinematic_metrics(seed_case("N"), solver="exact")
    # revolution, the building block of custom metrics, checks its own arguments.
    with pytest.raises(
        TypeError, match=r"layout = \(25, 500, 0.3\) is not allowed; allowed: a Layout"
    ):
        revolution((25, 500, 0.3), 36, with_rates=True)
    with pytest.raises(TypeError, match="with_rates = 'no' is not allowed; allowed: True or False"):
        revolution(seed_case("N"), 36, with_rates="no")
    with pytest.raises(ValueError, match=r"shapes R \(2,\).*jax.vmap over the layouts"):
        revolution(Layout([25.0, 26.0], 500.0, 0.3), 36, with_rates=False)


def test_status_and_throw():
    from tripodjax.results import RESULTS
    from tripodjax.solvers import Newton, SolverError

    ok = kinematic_metrics(seed_case("N"))
    assert int(ok.result) == RESULTS.successful and bool(ok.converged)
    capped = kinematic_metrics(seed_case("g25"), 36, Newton(max_steps=1))
    assert int(capped.result) == RESULTS.max_steps_reached and not bool(capped.converged)
    with pytest.raises(SolverError, match="kinematic_metrics: point \\[1\\] at θ = 0.174533 rad"):
        kinematic_metrics(seed_case("g25"), 36, Newton(max_steps=1), throw=True)


@pytest.mark.parametrize("dtype, rtol", [(np.float64, 1e-12), (np.float32, 1e-5)])
@pytest.mark.parametrize(
    "solver, n_theta",
    [("analytic", 360), ("closed_form", 60), (Analytic(corrections=1, nodes=12), 120)],
)
def test_series_extremes_equal_the_interpolated_answer_on_the_whole_grid(
    solver, n_theta, dtype, rtol
):
    """An interpolating level's peak-to-peak metrics come from its node series on half the
    period (Δ odd, γ even in θ): the same numbers as its interpolated answer at every angle of
    the grid, over the domain's corners, edges and γ0 = 0 (its one-sided limit)."""
    R, l, g0 = domain_layouts(48, seed=6)
    R[-1], g0[-1] = 40.0, 0.0
    batch = Layout(*(np.asarray(a, dtype) for a in (R, l, g0)))

    def both(layout):
        sol, rates = revolution(layout, n_theta, solver, with_rates=True)
        assert sol.series is not None
        grid = dataclasses.replace(sol, series=None)
        return (
            metrics_from(layout, sol, rates, FROM_SERIES),
            metrics_from(layout, grid, rates, FROM_SERIES),
        )

    # The test's own programs, compiled for latency (the values are the same arithmetic).
    fast, grid = latency_bound_jit(jax.vmap(both))(batch)
    for name in FROM_SERIES:
        np.testing.assert_allclose(fast[name], grid[name], rtol=rtol, atol=0, err_msg=name)
    irregularity = jax.grad(lambda g: metrics_from(*_at_gamma0(g, solver))["irregularity"])
    slopes = latency_bound_jit(irregularity)(0.0)
    assert float(slopes) == pytest.approx(1.5 * 40.0 / 500.0, rel=1e-6)


def test_series_metrics_need_no_angle_of_the_grid():
    """FROM_SERIES (which lets sweep take larger chunks) holds only metrics formed from the
    series: the same numbers when every per-angle field is NaN and every code a failure."""
    layout = Layout(30.0, 500.0, 0.3)
    sol, rates = revolution(layout, 360, "analytic", with_rates=True)

    def spoiled(s):
        floats = {
            name: jnp.full_like(getattr(s, name), jnp.nan)
            for name in ("psi", "gamma", "delta", "delta_gamma", "residual", "error_estimate")
        }
        if s.result.dtype == jax.dtypes.float0:  # the rates: no code to spoil
            return dataclasses.replace(s, **floats)
        failed = jnp.full_like(s.result, RESULTS.nonfinite)
        return dataclasses.replace(s, **floats, result=failed, converged=failed == 0)

    names = FROM_SERIES + ("roller_stroke",)
    clean = metrics_from(layout, sol, rates, names)
    blind = metrics_from(layout, spoiled(sol), spoiled(rates), names)
    for name in FROM_SERIES:
        np.testing.assert_array_equal(blind[name], clean[name], err_msg=name)
    assert np.isfinite(clean["roller_stroke"]) and np.isnan(blind["roller_stroke"])


SERIES_EXTREMES = ("delta_pp", "irregularity", "gamma_pp", "gamma_max", "ecc_max")


@pytest.mark.parametrize("dtype, rtol", [(np.float64, 4e-16), (np.float32, 4e-7)])
@pytest.mark.parametrize(
    "solver, n_theta", [("analytic", 360), ("analytic", 3600), (Analytic(nodes=4), 18)]
)
def test_the_window_holds_the_grid_extremes_over_the_domain(solver, n_theta, dtype, rtol):
    """The few angles of the series' extremes give every angle's over the domain (its
    edges, corner and γ0 = 0 included): the check holds everywhere, and the numbers match."""
    R, l, g0 = domain_layouts(64, seed=11)
    R[-1], l[-1], g0[-1] = 40.0, 500.0, 0.0
    batch = Layout(*(np.asarray(a, dtype) for a in (R, l, g0)))

    def both(layout):
        sol, rates = revolution(layout, n_theta, solver, with_rates=False)
        window, holds = metrics_and_window(layout, sol, rates, SERIES_EXTREMES, "window")
        grid, _ = metrics_and_window(layout, sol, rates, SERIES_EXTREMES, "grid")
        return window, grid, holds

    window, grid, holds = jax.jit(jax.vmap(both))(batch)
    assert np.all(holds)
    for name in SERIES_EXTREMES:
        np.testing.assert_allclose(window[name], grid[name], rtol=rtol, atol=0, err_msg=name)


def test_the_window_check_is_the_bound_it_states():
    """Random sine and cosine series, harmonics 1…3 (Δ, dΔ/dθ) and 0…4 (γ − γ0), on
    random even grids: wherever ``_window_holds``, the window's extremes are the grid's
    (to roundoff: the few angles are summed term by term, the grid by a dot); the check
    passes often and fails often, and where it fails the window may miss (so it is needed)."""
    rng = np.random.default_rng(3)
    count = 4000
    first = rng.choice([-1.0, 1.0], count) * rng.uniform(0.1, 10.0, count)
    share = 10.0 ** rng.uniform(-4.0, 0.0, (count, 1))  # the higher harmonics' size
    sine = np.concatenate([first[:, None], first[:, None] * share * rng.normal(size=(count, 2))], 1)
    rate = sine * np.array([3.0, 6.0, 9.0])
    cosine = np.concatenate(
        [rng.normal(size=(count, 2)), first[:, None] * share * rng.normal(size=(count, 3))], 1
    )
    shapes = tuple(jnp.asarray(a) for a in (sine, rate, cosine))
    checked = missed = 0
    for n in (6, 40, 120, 374, 1200):
        holds = np.asarray(kinematics._window_holds(shapes))
        window = kinematics._window_extremes(shapes, n)
        grid = kinematics._grid_extremes(shapes, n)
        equal = np.all(
            [np.isclose(w, g, rtol=1e-14, atol=0) for w, g in zip(window, grid, strict=True)],
            axis=0,
        )
        assert np.all(equal[holds]), n
        checked += holds.sum()
        missed += (~equal[~holds]).sum()
    assert 0.2 * 5 * count < checked < 0.8 * 5 * count
    assert missed > 0


def test_a_sweep_takes_every_angle_where_the_window_does_not_hold(monkeypatch):
    """sweep takes the series' extremes from the window when it holds for the whole chunk,
    else evaluates the chunk again at every angle of the half period. Seen through a window
    that answers twice the truth: its numbers where the check passes, the grid's where no
    series can pass it (no window at all)."""
    batch = Layout(*domain_layouts(16, seed=4))

    def doubled(shapes, n):
        return tuple(2.0 * e for e in window_extremes(shapes, n))

    def grid(layout):
        sol, rates = revolution(layout, 360, "analytic", with_rates=False)
        return metrics_and_window(layout, sol, rates, SERIES_EXTREMES, "grid")[0]

    expected = jax.vmap(grid)(batch)
    window_extremes = kinematics._window_extremes
    monkeypatch.setattr(kinematics, "_window_extremes", doubled)
    # Solvers of their own, so each sweep is compiled with the patches.
    through_window = sweep(batch, solver=Analytic(validity=0.5), outputs=SERIES_EXTREMES)
    monkeypatch.setattr(kinematics, "PEAK_WINDOW", 0.0)
    no_window = sweep(batch, solver=Analytic(validity=0.25), outputs=SERIES_EXTREMES)
    for name in ("delta_pp", "irregularity", "gamma_pp"):
        np.testing.assert_allclose(through_window[name], 2.0 * expected[name], rtol=1e-15)
        np.testing.assert_allclose(no_window[name], expected[name], rtol=4e-16, atol=0)


def _at_gamma0(gamma0, solver):
    layout = Layout(40.0, 500.0, gamma0)
    sol, rates = revolution(layout, 60, solver, with_rates=True)
    return layout, sol, rates, ("irregularity",)


@pytest.mark.parametrize(
    "call",
    [
        lambda lay: kinematic_metrics(lay, 36),
        lambda lay: friction.gaf_halfshaft(lay, 100.0, n_theta=36),
        lambda lay: forces.forces_halfshaft(lay, forces.ForceInputs(100.0), 36),
    ],
    ids=["kinematic_metrics", "gaf_halfshaft", "forces_halfshaft"],
)
def test_a_batch_where_one_layout_is_asked_for_is_one_line_saying_what_to_do(call):
    batch = Layout(R=np.array([25.0, 26.0]), l=500.0, gamma0=0.3)
    with pytest.raises(ValueError) as info:
        call(batch)
    message = str(info.value)
    assert message.startswith("layout has fields of shapes R (2,), l (), gamma0 ()")
    assert "jax.vmap" in message and "sweep" in message and "\n" not in message
    # one layout at a time under jax.vmap is the way
    one = jax.vmap(lambda R: kinematic_metrics(Layout(R, 500.0, 0.3), 36).irregularity)
    assert np.all(np.isfinite(one(jnp.asarray([25.0, 26.0]))))


def test_n_theta_may_be_a_numpy_integer():
    case = seed_case("N")
    plain = kinematic_metrics(case, 36)
    assert float(kinematic_metrics(case, np.int64(36)).irregularity) == float(plain.irregularity)
    for bad in (np.float64(36.0), True, 37, np.int32(0)):
        with pytest.raises(ValueError, match="n_theta = .* is not allowed"):
            kinematic_metrics(case, bad)
