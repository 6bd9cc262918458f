"""Independent float64 reference for the halfshaft: SciPy's fsolve on the unscaled pair.

Solves 2.9.1–2.9.2 directly in (ψ, γ) as printed, one θ at a time, the way the
seed's own study did; dψ/dθ by central differences of that solve.
"""

import math

import numpy as np
from scipy.optimize import fsolve


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
