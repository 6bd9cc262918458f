"""Independent float64 reference for the halfshaft: SciPy's fsolve on the unscaled pair.

Solves 2.9.1–2.9.2 directly in (ψ, γ) as printed, one θ at a time, the way the
seed's own study did; dψ/dθ by central differences of that solve.
"""

import math

import numpy as np
from scipy.optimize import brentq, fsolve


def residual(x, theta, R, l, gamma0):
    psi, gamma = x
    h = -l * math.sin(gamma0) - 0.5 * R * (1 - math.cos(gamma0))
    e = 0.5 * R * (1 - math.cos(gamma)) / math.cos(gamma)
    delta = theta - psi
    return [
        h * math.sin(delta) - e * math.sin(3 * psi),
        h * math.cos(delta) + l * math.sin(gamma) + e * math.cos(gamma) * math.cos(3 * psi),
    ]


def solve(theta, R, l, gamma0):
    """ψ, γ at each θ (array) by fsolve from (θ, γ0)."""
    out = []
    for t in np.atleast_1d(theta):
        x, info, ier, msg = fsolve(
            residual, [t, gamma0], args=(t, R, l, gamma0), xtol=1e-13, full_output=True
        )
        assert max(abs(f) for f in residual(x, t, R, l, gamma0)) < 1e-9 * l, msg
        out.append(x)
    out = np.array(out)
    return out[:, 0], out[:, 1]


def metrics(R, l, gamma0, n_theta=360, step=1e-5):
    """delta_pp, irregularity, gamma_pp, ecc_max over a full revolution of n_theta angles."""
    theta = np.arange(n_theta) * 2 * np.pi / n_theta
    psi, gamma = solve(theta, R, l, gamma0)
    psi_plus, _ = solve(theta + step, R, l, gamma0)
    psi_minus, _ = solve(theta - step, R, l, gamma0)
    dpsi = (psi_plus - psi_minus) / (2 * step)
    delta = theta - psi
    ecc = 0.5 * R * (1 - np.cos(gamma)) / np.cos(gamma)
    return {
        "delta_pp": np.ptp(delta),
        "irregularity": np.ptp(dpsi),
        "gamma_pp": np.ptp(gamma),
        "ecc_max": ecc.max(),
    }


# --------------------------------------------------------------------------- the workbook's life chain
# Written out from the sheet (seed figs. 4.3.1–4.3.4, 4.3.10, 4.3.11) without tripodjax.life or
# tripodjax.vehicle: the revolutions of 100 000 km at the adhesion-limited torques (shock factor
# out), the 500 h at 730 rpm rating, and the workbook's angle derating fitted here to its two points.

WB_RATIOS = [13.128, 7.931, 5.367, 4.181, 3.336, 2.788, 13.584]  # 1st–6th, reverse
WB_USE = np.array(  # % of revolutions at T_max and P_max (fig. 4.3.11)
    [[1.62, 4.55, 11.00, 11.93, 9.60, 7.04, 0.40], [0.14, 1.23, 4.50, 7.29, 7.20, 6.53, 0.05]]
)
WB_CONDITIONS = ([6.5, 0.0, 0.0, 8.0, 12.8], [0.30, 0.0, 0.0, 0.35, 0.35])


def workbook_wheel_torques(radius=0.30773, adhesion=0.9):
    """Adhesion-limited wheel torque [N·m] without the shock factor, per gear (1st–6th, R)."""
    g, mass = 9.81, 937.0
    rear = mass * (1 - 0.328)  # front axle 307.34 kg of 937 kg
    cap = adhesion * mass * g * 0.42 / (2 * 2.475)
    transfer = [min(67.45 * i, cap) for i in WB_RATIOS[:-1]] + [-627.0]
    return np.array([adhesion * (rear * g / 2 + t) * radius for t in transfer])


def workbook_km_at_0deg(M_d, radius=0.30773, adhesion=0.9):
    """Life [km] at 0° of a joint of capacity M_d: revolutions to failure × 2π r."""
    torque = workbook_wheel_torques(radius, adhesion)
    revolution_share = WB_USE.sum(axis=0) / 100  # every mode has the same table; weights sum to 1
    revolutions = 365000 * 60 / np.sum(revolution_share * (torque / M_d) ** 3)
    return revolutions * 2 * math.pi * radius / 1000


def workbook_angle_factor(angle_deg):
    """exp(−(a γ + b γ²)) through 164 088 / 244 574 at 6.5° and 99 204 / 244 574 at 12.8°."""
    t = np.radians([6.5, 12.8])
    a, b = np.linalg.solve(np.c_[t, t**2], -np.log(np.array([164_088, 99_204]) / 244_574))
    gamma = np.radians(angle_deg)
    return np.exp(-(a * gamma + b * gamma**2))


def workbook_combined_km(M_d, **vehicle):
    angles, shares = WB_CONDITIONS
    km = workbook_km_at_0deg(M_d, **vehicle) * workbook_angle_factor(np.array(angles))
    return 1 / np.sum(np.array(shares) / km)  # Miner over the mileage shares


def reference_default_design(**vehicle):
    """The workbook's life chain written out (tests/reference.py), solved for 100 000 km at R/d 0.63.

    Both are active at the default optimum: the smallest joint of the lowest allowed R/d that
    lives the required mileage. M_d from the Hertz capacity law (checked against the sheet's
    1507 N·m in test_hertz.py).
    """
    from tripodjax import hertz

    C_p = float(hertz.conformity_coefficient(1.002))

    def margin(d):
        M_d = float(hertz.torque_at_pressure(1347.0, d, 0.63 * d, C_p=C_p, C_s=1.2))
        return workbook_combined_km(M_d, **vehicle) - 100_000.0

    d = brentq(margin, 20.0, 50.0, xtol=1e-12)
    return 0.63 * d, d
