"""Single-joint relations (seed §2.3–2.6) against identities and the printed forms."""

import numpy as np
import pytest

from tripodjax import joint

RNG = np.random.default_rng(7)
R = 25.0
GAMMA = RNG.uniform(0.01, 0.75, 64)
PSI = RNG.uniform(-np.pi, np.pi, 64)
TAU = RNG.uniform(-0.05, 0.05, 64)


def test_direction_cosines_orthonormal_with_spider_axis():
    m = np.asarray(joint.direction_cosines(GAMMA, TAU))
    np.testing.assert_allclose(
        m @ np.swapaxes(m, -1, -2), np.broadcast_to(np.eye(3), m.shape), atol=1e-14
    )
    np.testing.assert_allclose(np.linalg.det(m), 1.0, atol=1e-14)  # a proper rotation
    # The last column is the spider axis Z' (2.3.3).
    axis = np.stack([np.sin(GAMMA) * np.cos(TAU), np.sin(GAMMA) * np.sin(TAU), np.cos(GAMMA)], -1)
    np.testing.assert_allclose(m[..., :, 2], axis, atol=1e-15)
    assert np.all(m[..., 2, 1] == 0)  # n2 = 0: Y' normal to Z and Z'


def test_eccentricity_printed_form_and_small_angle_accuracy():
    printed = 0.5 * R * (1 - np.cos(GAMMA)) / np.cos(GAMMA)
    # the printed form loses ~ε·R digits to the 1 − cos γ cancellation: absolute tolerance
    np.testing.assert_allclose(joint.eccentricity(R, GAMMA), printed, rtol=1e-13, atol=4e-16 * R)
    # float32 near γ = 0 keeps its relative accuracy (no 1 − cos γ cancellation).
    g = np.float32(1e-3)
    reference = 0.5 * R * 2 * np.sin(0.5e-3) ** 2 / np.cos(1e-3)
    assert joint.eccentricity(np.float32(R), g) == pytest.approx(reference, rel=1e-6)


def test_eccentricity_components_solve_system_2_5_4():
    ex, ey = (np.asarray(c) for c in joint.eccentricity_components(R, GAMMA, PSI))
    k = 0.5 * R * (1 - np.cos(GAMMA)) / np.cos(GAMMA)
    np.testing.assert_allclose(
        ex * np.sin(PSI) - ey * np.cos(PSI), -k * np.sin(2 * PSI), atol=1e-12
    )
    np.testing.assert_allclose(ex * np.cos(PSI) + ey * np.sin(PSI), k * np.cos(2 * PSI), atol=1e-12)
    np.testing.assert_allclose(np.hypot(ex, ey), joint.eccentricity(R, GAMMA), rtol=1e-13)


def test_spider_centre_distance_identities():
    theta = PSI + TAU
    a, b, z = (np.asarray(c) for c in joint.spider_centre(R, GAMMA, theta, PSI))
    e = np.asarray(joint.eccentricity(R, GAMMA))
    # 2.5.14 and (Z* − c)² + ρ² = e² (figure 2.5.1)
    rho2 = e**2 * (np.sin(3 * PSI) ** 2 + np.cos(GAMMA) ** 2 * np.cos(3 * PSI) ** 2)
    np.testing.assert_allclose(a**2 + b**2, rho2, atol=1e-13)
    np.testing.assert_allclose(z**2 + a**2 + b**2, e**2, atol=1e-13)


def test_mean_of_roller_axial_positions_is_spider_axial_position():
    _, _, z_i = joint.roller_centres(R, GAMMA, PSI)
    _, _, z_star = joint.spider_centre(R, GAMMA, PSI + TAU, PSI)
    np.testing.assert_allclose(np.mean(z_i, axis=-1), z_star, atol=1e-12)


def test_roller_centres_from_track_points_through_the_direction_cosines():
    """Track point i at (R cos θ_i, R sin θ_i, Z_i) maps to (X̃_i, Ỹ_i, 0) by 2.3.7."""
    theta = PSI + TAU  # tan(θ − ψ) = tan τ (2.4.21)
    theta_i = theta[:, None] + np.array([0, 2, 4]) * np.pi / 3
    psi_i = np.asarray(joint.roller_angles(PSI))
    z_minus_zstar = -R * np.tan(GAMMA)[:, None] * np.cos(psi_i)  # 2.6.1
    pot = np.stack([R * np.cos(theta_i), R * np.sin(theta_i), z_minus_zstar], -1)
    m = np.asarray(joint.direction_cosines(GAMMA, TAU))
    intermediate = np.einsum("nij,nki->nkj", m, pot)
    x, y, _ = joint.roller_centres(R, GAMMA, PSI)
    np.testing.assert_allclose(intermediate[..., 0], x, atol=1e-12)
    np.testing.assert_allclose(intermediate[..., 1], y, atol=1e-12)
    np.testing.assert_allclose(intermediate[..., 2], 0.0, atol=1e-12)


def test_roller_centres_lie_on_the_path_ellipse():
    x, y, _ = joint.roller_centres(R, GAMMA, PSI)
    major, minor = joint.roller_path_semi_axes(R, GAMMA)
    np.testing.assert_allclose(
        (x / major[:, None]) ** 2 + (y / minor[:, None]) ** 2, 1.0, rtol=1e-13
    )


def test_stable_radial_distance_equals_printed_2_6_4_away_from_singularity():
    psi_i = np.asarray(joint.roller_angles(PSI))
    e = np.asarray(joint.eccentricity(R, GAMMA))[:, None]
    printed = -R - e * np.sin(3 * PSI)[:, None] / np.sin(psi_i)
    stable = np.asarray(joint.roller_radial_distance(R, GAMMA, PSI))
    away = np.abs(np.sin(psi_i)) > 1e-3
    np.testing.assert_allclose(stable[away], np.abs(printed[away]), rtol=1e-12)


def test_radial_distance_at_the_singularity_range_and_period():
    gamma = 0.35
    e = float(joint.eccentricity(R, gamma))
    r = np.asarray(joint.roller_radial_distance(R, gamma, np.array([0.0, np.pi])))
    np.testing.assert_allclose(r[:, 0], R + 3 * e, rtol=1e-14)  # sin ψ_1 = 0: finite, R + 3e
    psi = np.linspace(0, 2 * np.pi, 2001)
    r1 = np.asarray(joint.roller_radial_distance(R, gamma, psi))[:, 0]
    assert r1.min() == pytest.approx(R - e, rel=1e-9) and r1.max() == pytest.approx(
        R + 3 * e, rel=1e-12
    )
    shifted = np.asarray(joint.roller_radial_distance(R, gamma, psi + np.pi))[:, 0]
    np.testing.assert_allclose(shifted, r1, rtol=1e-13)  # period π


def test_spider_offset_matches_printed_form():
    l, gamma0 = 500.0, 0.3
    np.testing.assert_allclose(
        joint.spider_offset(l, gamma0, GAMMA), l * (np.cos(gamma0) - np.cos(GAMMA)), atol=1e-11
    )


def test_a_list_of_numbers_is_an_array_at_the_kinematics_boundary():
    """A plain list passes the type check (check_real) and is then taken as its array; it failed
    inside JAX ("Cannot determine dtype", "can't multiply sequence")."""
    from tripodjax import Layout, motion, seed_case, solve_halfshaft

    layout = seed_case("N")
    pairs = [
        (lambda a: joint.eccentricity(a, 0.3), [25.0, 26.0]),
        (lambda a: joint.roller_centres(25.0, a, 0.1)[2], [0.3, 0.2]),
        (lambda a: joint.direction_cosines(0.3, a), [0.1, 0.2]),
        (lambda a: solve_halfshaft(layout, a).delta, [0.1, 0.2]),
        (lambda a: motion.halfshaft_motion(layout, a, 100.0).spider_velocity, [0.1, 0.2]),
        (lambda a: Layout.from_degrees(25.0, 500.0, a).gamma0, [10.0, 20.0]),
    ]
    for f, values in pairs:
        np.testing.assert_array_equal(f(values), f(np.asarray(values)))
