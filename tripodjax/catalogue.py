"""Catalogue sizes of real GE and GI tripod joints (seed §1.1.2, figures 1.1.6 and 1.1.10).

Each table maps the joint size to its pitch-circle radius R [mm], roller
diameter d [mm], static failure torque at γ = 0 M_b [N·m], maximum drive
torque 0.6 M_b [N·m] and the permanent torque M_d for 500 h at 730 rpm [N·m].
Entries the seed leaves blank are omitted (the GI 100 C has no R).
"""

import math

GE: dict[str, dict[str, float]] = {
    "58": dict(R=14.1, d=16.9, M_b=1350.0, M_drive=1200.0, M_d=100.0),
    "66": dict(R=16.15, d=19.7, M_b=1950.0, M_drive=1750.0, M_d=150.0),
    "76": dict(R=18.3, d=21.9, M_b=2400.0, M_drive=2100.0, M_d=220.0),
    "82A": dict(R=20.2, d=23.7, M_b=3000.0, M_drive=2850.0, M_d=290.0),
    "86": dict(R=20.85, d=24.9, M_b=3500.0, M_drive=3200.0, M_d=330.0),
    "90A": dict(R=21.6, d=25.9, M_b=4000.0, M_drive=3600.0, M_d=370.0),
    "92": dict(R=22.5, d=26.8, M_b=4270.0, M_drive=3900.0, M_d=410.0),
    "99": dict(R=24.2, d=28.4, M_b=5250.0, M_drive=4900.0, M_d=500.0),
    "113": dict(R=27.4, d=31.69, M_b=7850.0, M_drive=7200.0, M_d=750.0),
}
"""GE sizes (Glaenzer Exterior, plain-bearing rollers; seed §1.1.2): size → ``R`` pitch-circle
radius [mm], ``d`` roller diameter [mm], ``M_b`` static failure torque at γ = 0 [N·m],
``M_drive`` maximum drive torque 0.6 M_b [N·m], ``M_d`` permanent torque for 500 h at 730 rpm
[N·m], rated for working angles β = 6–27° (`GE_RATING_ANGLES`)."""

GI: dict[str, dict[str, float]] = {
    "580": dict(R=18.64, d=29.2, M_b=1900.0, M_drive=1040.0, M_d=220.0),
    "62": dict(R=20.84, d=31.95, M_b=2600.0, M_drive=1240.0, M_d=290.0),
    "69": dict(R=23.2, d=29.95, M_b=3000.0, M_drive=1660.0, M_d=330.0),
    "720": dict(R=28.15, d=37.1, M_b=4500.0, M_drive=2530.0, M_d=450.0),
    "82": dict(R=30.5, d=33.95, M_b=5500.0, M_drive=3150.0, M_d=560.0),
    "87 C": dict(R=36.8, d=33.95, M_b=7700.0, M_drive=4300.0, M_d=750.0),
}
"""GI sizes (Glaenzer Interior, needle-bearing rollers; seed §1.1.2): size → ``R`` [mm], ``d``
[mm], ``M_b``, ``M_drive`` and ``M_d`` [N·m] as in `GE`, ``M_d`` rated for working angles
β = 6–12° (`GI_RATING_ANGLES`) and a plunge of ±10 mm."""

# Working-angle ranges of the M_d ratings [rad].
GE_RATING_ANGLES: tuple[float, float] = (math.radians(6.0), math.radians(27.0))
GI_RATING_ANGLES: tuple[float, float] = (math.radians(6.0), math.radians(12.0))
