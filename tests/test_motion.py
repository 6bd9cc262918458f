"""Velocities and accelerations (seed §2.11): exact by implicit AD, first order as printed."""

import numpy as np
import pytest

from tripodjax import first_order_motion, halfshaft_motion, joint, seed_case

THETA = np.linspace(0, 2 * np.pi, 73)


def printed_first_order(R, gamma, theta, w, alpha):
    """2.11.1 and 2.11.2 exactly as printed (accelerations), ψ ≈ θ, γ const."""
    e = 0.5 * R * (1 - np.cos(gamma)) / np.cos(gamma)
    s3, c3 = np.sin(3 * theta), np.cos(3 * theta)
    spider = np.stack(
        [
            3 * alpha * e * np.cos(gamma) * s3 + 9 * w**2 * e * np.cos(gamma) * c3,
            -3 * alpha * e * c3 + 9 * w**2 * e * s3,
            3 * alpha * e * np.sin(gamma) * s3 + 9 * w**2 * e * np.sin(gamma) * c3,
        ],
        -1,
    )
    ti = theta[:, None] + np.array([0, 2, 4]) * np.pi / 3
    rollers = np.stack(
        [
            alpha * R / np.cos(gamma) * np.sin(ti) + w**2 * R / np.cos(gamma) * np.cos(ti),
            -alpha * R * np.cos(ti) + w**2 * R * np.sin(ti),
            -0.5
            * R
            * np.tan(gamma)
            * (
                -2 * alpha * np.sin(ti)
                - 2 * w**2 * np.cos(ti)
                - (1 - np.cos(gamma)) * (3 * alpha * s3 + 9 * w**2 * c3)[:, None]
            ),
        ],
        -1,
    )
    return spider, rollers


def test_first_order_matches_printed_2_11_1_and_2_11_2():
    layout = seed_case("N")
    w, alpha = 100.0, 250.0
    motion = first_order_motion(layout, THETA, w, alpha)
    spider, rollers = printed_first_order(layout.R, layout.gamma0, THETA, w, alpha)
    np.testing.assert_allclose(motion.spider_acceleration, spider, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(motion.roller_acceleration, rollers, rtol=1e-12, atol=1e-9)


def test_first_order_roller_peaks_match_the_seed_numbers():
    """§2.11, case N at θ̇ = 100 rad/s: X̃̈ ≈ 266, Ỹ̈ ≈ 250, Z̈ ≈ 115.7 m/s²."""
    theta = np.linspace(0, 2 * np.pi, 3601)
    acc = np.asarray(first_order_motion(seed_case("N"), theta, 100.0).roller_acceleration) / 1000
    assert np.abs(acc[..., 0]).max() == pytest.approx(266, abs=0.5)
    assert np.abs(acc[..., 1]).max() == pytest.approx(250, abs=0.5)
    assert np.abs(acc[..., 2]).max() == pytest.approx(115.7, abs=0.1)


def test_first_order_spider_peaks_scale_with_the_eccentricity():
    """The seed's 65.1 / 69.3 / 23.7 m/s² use e = 0.77 mm; 2.5.9 gives e(20°) = 0.802 mm for R 25."""
    layout = seed_case("N")
    theta = np.linspace(0, 2 * np.pi, 3601)
    acc = (
        np.abs(np.asarray(first_order_motion(layout, theta, 100.0).spider_acceleration)).max(axis=0)
        / 1000
    )
    e = float(joint.eccentricity(layout.R, layout.gamma0))
    np.testing.assert_allclose(acc * 0.77 / e, [65.1, 69.3, 23.7], atol=0.06)


def test_exact_motion_against_time_differences():
    """θ(t) = θ0 + θ̇ t + θ̈ t²/2 sampled at ±dt: central differences of the positions."""
    layout = seed_case("R4")
    w, alpha, dt = 80.0, 300.0, 1e-5
    theta0 = np.array([0.1, 0.7, 2.0, 4.4])
    motion = halfshaft_motion(layout, theta0, w, alpha)
    at = [halfshaft_motion(layout, theta0 + w * t + 0.5 * alpha * t**2, w) for t in (-dt, dt)]
    for field in ("spider", "roller"):
        p_minus, p_plus = (np.asarray(getattr(m, f"{field}_position")) for m in at)
        p0 = np.asarray(getattr(motion, f"{field}_position"))
        velocity = (p_plus - p_minus) / (2 * dt)
        acceleration = (p_plus - 2 * p0 + p_minus) / dt**2
        np.testing.assert_allclose(
            getattr(motion, f"{field}_velocity"), velocity, rtol=1e-6, atol=1e-4
        )
        np.testing.assert_allclose(
            getattr(motion, f"{field}_acceleration"), acceleration, rtol=1e-3, atol=20.0
        )


def test_exact_positions_are_the_joint_relations_at_the_solution():
    layout = seed_case("N")
    motion = halfshaft_motion(layout, THETA, 1.0)
    z_star = np.asarray(motion.spider_position)[:, 2]
    z_rollers = np.asarray(motion.roller_position)[..., 2]
    np.testing.assert_allclose(z_rollers.mean(axis=-1), z_star, atol=1e-12)  # mean Z_i = Z*


def test_exact_and_first_order_roller_accelerations_agree_to_first_order():
    theta = np.linspace(0, 2 * np.pi, 721)
    layout = seed_case("N")
    exact = np.abs(np.asarray(halfshaft_motion(layout, theta, 100.0).roller_acceleration)).max(
        axis=(0, 1)
    )
    approx = np.abs(np.asarray(first_order_motion(layout, theta, 100.0).roller_acceleration)).max(
        axis=(0, 1)
    )
    np.testing.assert_allclose(exact[:2], approx[:2], rtol=0.03)


@pytest.mark.parametrize("motion", [halfshaft_motion, first_order_motion])
@pytest.mark.parametrize(
    "layout, theta, says",
    [
        ((25.0, 500.0, 0.3), 0.1, "layout = (25.0, 500.0, 0.3) is not allowed; allowed: a Layout"),
        ("batch", 0.1, "layout has fields of shapes R (2,)"),
        ("N", "0", "theta = '0' is not allowed"),
        ("N", np.zeros(3), "the fields have shapes theta (3,), theta_dot (2,)"),
    ],
)
def test_bad_input_is_one_line_naming_the_argument(motion, layout, theta, says):
    import tripodjax as tj

    if layout == "N":
        layout = seed_case("N")
    elif layout == "batch":
        layout = tj.Layout(np.array([25.0, 26.0]), 500.0, 0.3)
    theta_dot = np.ones(2) if np.ndim(theta) else 100.0
    with pytest.raises((TypeError, ValueError)) as info:
        motion(layout, theta, theta_dot)
    assert str(info.value).startswith(says) and "\n" not in str(info.value)
