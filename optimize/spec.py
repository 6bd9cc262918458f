"""The design-problem specification: a TOML file, checked, with an embedded default.

Every number carries its unit in its name or comment; angles are in degrees in
the file (``*_deg``) and in radians inside. [`load_spec`][tripodjax.optimize.load_spec]
returns a [`Spec`][tripodjax.optimize.Spec]: a frozen pytree whose *numbers* are
leaves (traced by ``jit``: a new value never recompiles) and whose *structure*
(which variables are free, which objective terms and constraints exist, list
lengths, ``n_theta``, the number of starts, the fidelity) is static; the solver's
iteration counts are numbers (a new ``max_outer`` or ``inner_steps`` reuses the compiled
solve). Any problem in the file raises [`SpecError`][tripodjax.optimize.SpecError]
with one line naming the key, the value and what is allowed.
"""

import copy
import dataclasses
import functools
import json
import math
import os
import sys
import tomllib
import typing
from collections.abc import Mapping

import jax
import numpy as np

from tripodjax._checks import MAX_GAMMA0, check_layout_domain, real_scalar
from tripodjax.hertz import MIN_CONFORMITY
from tripodjax.life import ANGLE_LAWS, SPECTRUM_COLUMNS, read_spectrum_rows
from tripodjax.optimize._texts import (
    MAX_PATH_LENGTH,
    MAX_TEXT_LENGTH,
    label_problem,
    length_problem,
)
from tripodjax.outboard import MIN_BALLS
from tripodjax.vehicle import AXLES, ENGINE_CONDITIONS

MAX_GAMMA0_DEG = math.degrees(MAX_GAMMA0)
MAX_FLOAT = sys.float_info.max

DEFAULT_SPEC_TOML = """\
# The company validation workbook's tripod (seed §4.3), its vehicle and working conditions, on the
# seed's nominal halfshaft, case N of Table 2.1 (§2.10). Units in the key names and comments.

[design]
# Values of the joint-size variables when they are not free (see [bounds]): the workbook's joint.
R = 25.55              # track pitch-circle radius [mm]
d_roller = 43.5        # roller diameter [mm]

[layout]
l = 500.0              # shaft length, spider centre to the fixed joint's pivot [mm]
gamma0_deg = 20.0      # layout articulation angle [deg]

[loads]
# M_max, the largest forward torque on the shaft, comes from [vehicle] (its adhesion-limited
# first-gear torque, 1154 N·m here); give loads.M_max instead to set it yourself.
# M_max = 1154.0       # the largest forward torque on the shaft [N·m] (when absent: from [vehicle])
shock_factor = 1.1     # shock factor: in the vehicle's torques, and the static check at shock_factor · M_max
gaf_torque = 1000.0    # torque at which GAF is judged [N·m] (the seed's GAF example, §3.2)

[hertz]
P_s = 2350.0           # allowed static contact pressure [MPa] (workbook)
P_d = 1347.0           # allowed long-lasting dynamic pressure [MPa]
P_sd = 2005.0          # allowed short-lasting dynamic pressure [MPa]
C_s = 1.2              # safety coefficient on the pressure (workbook)
conformity = 1.002     # Ψ = 2 R_groove / d (workbook range 1.002–1.008)
n_rollers = 3

[vehicle]
# The company workbook's vehicle (seed figs. 4.3.1, 4.3.3, 4.3.4): a rear-wheel-drive sportscar.
# It gives M_max and the life's load spectrum (tripodjax.vehicle); replace it with the
# customer's, or give loads.M_max and the [life] lists (or life.spectrum_file) instead.
axle = "rear"                  # the halfshaft studied: "rear" or "front"
mass_kg = 937.0                # gross vehicle mass
front_share = 0.328            # share of the mass on the front axle (307.34 of 937 kg)
wheelbase_m = 2.475
cg_height_m = 0.42             # centre-of-gravity height
tyre_radius_m = 0.30773        # static loaded radius (printed 0.308; the sheet's cycle count implies 0.30773)
adhesion = 0.9                 # tyre–road friction coefficient
rear_torque_share = 1.0        # engine torque to the rear axle: 1 rear-, 0 front-wheel drive, between AWD
differential_locking = 1.0     # one shaft takes at most (1 + this)/2 of its axle's torque (workbook 100 %)
engine_torque_Nm = [555.0, 555.0, 517.4, 50.0]       # engine torque at mean torque, maximum
                                                     # torque, maximum power, and the engine brake
engine_speed_rpm = [3000.0, 3000.0, 5500.0, 3000.0]  # engine speed at the same four conditions
load_transfer_per_ratio_N = 67.45  # wheel-load transfer per unit overall ratio (fitted to the sheet)
reverse_load_transfer_N = 627.0    # wheel-load transfer in reverse (the sheet)

[vehicle.gears]
ratios = [13.128, 7.931, 5.367, 4.181, 3.336, 2.788]  # overall ratios (gear × final drive), up to 11
reverse = 13.584

[vehicle.modes]
# Driving modes: names, share of the mileage, and the relative use of each gear (1st…, reverse
# last) at each engine condition as % of that mode's revolutions (fig. 4.3.11): one list for
# every mode, or a list of lists (one per mode).
names = ["sport", "intercity", "city"]
weight = [0.5, 0.1, 0.4]
use_T_mean_pct = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
use_T_max_pct = [1.62, 4.55, 11.00, 11.93, 9.60, 7.04, 0.40]
use_P_max_pct = [0.14, 1.23, 4.50, 7.29, 7.20, 6.53, 0.05]
use_brake_pct = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]

[life]
required_km = 100000.0 # required life [km] (workbook)
angle_law = "workbook" # life against working angle: "workbook" (fitted to fig. 4.3.10) or "seed"
# The load spectrum comes from [vehicle]. To give it yourself: the four lists torque, speed,
# vehicle_speed and share (one entry per load case), or spectrum_file.
# torque = [1154.0, 350.0]     # shaft torque of each load case [N·m]
# speed = [230.0, 700.0]       # shaft speed of each load case [rpm]
# vehicle_speed = [28.0, 90.0] # vehicle speed of each load case [km/h]
# share = [0.55, 0.45]         # share of the running time of each load case (summing to 1)
# spectrum_file = "x.csv"      # the cases as a CSV file (columns torque_Nm, speed_rpm,
                               # vehicle_speed_kmh and revolutions or hours), relative to the
                               # spec's folder

[life.conditions]
# The workbook's five working conditions (fig. 4.3.10): angles and shares of the mileage,
# combined by Miner's rule. Shock + is unreadable in the sheet; 8.0° is what its "P" entry
# (58 %) implies under the workbook law.
names = ["static trim", "steering +", "steering -", "shock +", "shock -"]
angle_deg = [6.5, 0.0, 0.0, 8.0, 12.8]
share = [0.30, 0.0, 0.0, 0.35, 0.35]

[friction]
grease = "A"           # "A" (μ_slp 0.06), "B" (0.09) or "dry" (0.30) (seed §3.2.3)
# mu_slp = 0.06        # pure-sliding coefficient; when absent it comes from the grease
lam = 0.007            # rolling resistance λ
gaf_model = "stroke"   # "stroke" (no GAF at γ = 0), "printed" (the seed's 3.2.14) or "forces" (the force model)

[forces]
# The force model (tripodjax.forces: quasi-static roller forces on the exact kinematics, §3.1) at
# loads.gaf_torque with friction.mu_slp and friction.lam: the quantities lts, lts_ripple,
# complementary_torque (and its _third_order, _sixth_order), roller_load_ratio and
# friction_power, and the GAF when friction.gaf_model = "forces".
speed_rpm = 1000.0         # shaft speed, running case [rpm], not 0 (its sign: the sense of rotation)
mu_trunnion = 0.0          # roller–trunnion sliding friction (0: needle bearings)
contact_angle_deg = 0.0    # contact angle of the roller on its flank [deg] (0: flat flanks)
plunge_speed_mm_s = 10.0   # plunge speed of the LTS test [mm/s] (> 0 into the pot, < 0 out; not 0)
lts_speed_rpm = 0.0        # shaft speed during the LTS test [rpm] (0: held still, the idle test)

[shaft]
# The halfshaft's sections that carry the torque (seed fig. 4.3.5, sheets 5–7; tripodjax.shaft):
# the shaft's cross-sections and both joints' stems, each checked statically (at M_max forward
# and backward, through the hardened layer) and in fatigue (the vehicle's load → engine-brake
# cycles, Goodman, the semi-log S–N line, Miner's sum) in every optimize-joint report. One entry
# per section in each list; the workbook's rear halfshaft (its inboard stem's printed 20.44 mm
# read as 28.44 mm).
names = ["A-A", "B-B", "C-C", "outboard stem", "inboard stem"]
outer_diameter_mm = [26.0, 27.5, 25.8, 30.685, 28.44]  # Øe (at a spline, its root)
inner_diameter_mm = [0.0, 0.0, 0.0, 0.0, 0.0]         # Øi (0: a round bar)
hardened_depth_mm = [5.6, 5.6, 5.6, 2.5, 1.2]          # induction-hardened depth h
transition_depth_mm = [3.5, 3.5, 3.5, 3.5, 1.1]        # transition t below it (h + t ≤ the wall)
safety = [1.2, 1.2, 1.2, 1.3, 1.2]                     # safety coefficient C_s on the static limits
core_uts_MPa = 690.0        # core ultimate strength σ_R,c (C53, 42CrMo4)
surface_uts_MPa = 2180.0    # surface ultimate strength σ_R,s (from the micro-hardness)
depth_drop = 0.10           # strength lost from the surface to the depth h
fatigue_ratio = 1.6         # UTS / fatigue limit (the rear's 1.6; 2 where the sheet says so)
allowed_damage = 1.0        # a section passes in fatigue when Miner's sum is at most this
reading = "consistent"      # "consistent" or "workbook" (the sheet's readings, docs/physics.md)

[outboard]
# The outboard fixed ball joint ("Fixed FR", seed fig. 4.3.10, second column; tripodjax.outboard):
# its Hertz static safety (M_s / M_max, required ≥ loads.shock_factor like the tripod's) and its
# life under its working conditions (required ≥ life.required_km), in every report.
n_balls = 6                 # 3 to 24, fitting on the pitch circle: d < 2 PCR sin(π/n_balls)
ball_diameter_mm = 18.256
pcr_mm = 29.958             # pitch-centre radius
conformity = 1.003          # transverse conformity Ψ = 2 R_g / d
longitudinal_conformity = 0.268  # χ_l of the curved tracks
P_s = 3750.0                # allowed static contact pressure [MPa]
P_d = 2150.0                # allowed long-lasting dynamic pressure [MPa]
P_sd = 3200.0               # allowed short-lasting dynamic pressure [MPa]
C_s = 1.1                   # safety coefficient on the pressure
pressure_angle_deg = 45.0   # ε
oblique_angle_deg = 0.0     # the tracks' oblique angle ζ
tolerance = 0.15            # tolerance on the life's calculation spread (life × (1 + tolerance))
reading = "consistent"      # "consistent" (exact Hertz μν, km = the distance rolled) or
                            # "workbook" (the sheet's μν table, km = hours × the
                            # revolution-weighted mean vehicle speed; docs/physics.md)

[outboard.conditions]
# The outboard joint's working conditions (fig. 4.3.10): angles and shares of the mileage.
names = ["static trim", "steering +", "steering -", "shock +", "shock -"]
angle_deg = [6.0, 0.0, 0.0, 8.0, 10.5]
share = [0.30, 0.0, 0.0, 0.35, 0.35]

[objective]
# Dimensionless: Σ w_<q> · <q> / <q>_ref over any quantity q (see the quantity table in the
# docs). The references are the seed's case N with the workbook's joint (R 25.55 mm,
# d 43.5 mm), so the objective is about 3 there.
w_irregularity = 1.0
w_gaf_rms = 1.0
w_outer_diameter = 1.0
irregularity_ref = 0.0283  # transmission irregularity of case N [–] (§2.11.3)
gaf_rms_ref = 625.0        # GAF RMS of case N at gaf_torque, grease A, stroke model [N]
outer_diameter_ref = 94.6  # outer-diameter proxy 2R + d of the workbook joint [mm]

[bounds]
# A variable is free when it has an interval here, else fixed at its value in its own
# section ([design], [layout], [hertz], [friction]). Free-able: R, d_roller [mm], l [mm],
# gamma0_deg [deg], conformity, lam, mu_slp, and one [shaft] entry as a quoted key
# "shaft.<list>[<section>]" with <list> outer_diameter_mm, inner_diameter_mm, hardened_depth_mm
# or transition_depth_mm [mm], e.g. "shaft.outer_diameter_mm[C-C]" = [18.5, 30.0] (the section
# must stay valid at every corner: Øi < Øe, h + t ≤ (Øe − Øi)/2). "fixed" removes a default interval.
R = [15.0, 40.0]         # track pitch-circle radius [mm]
d_roller = [20.0, 70.0]  # roller diameter [mm]

[constraints]
# max_<q> / min_<q> for any quantity q; the Hertz static capacity (≥ shock_factor · M_max)
# and the life (≥ required_km) are always required, and with a [vehicle] the rest of the
# halfshaft: each [shaft] section's static safety ≥ 1 and damage ≤ shaft.allowed_damage, the
# [outboard] joint's M_s / M_max ≥ shock_factor and life ≥ required_km.
min_R_over_d = 0.63      # experience range for tripods (workbook)
max_R_over_d = 0.83
# max_outer_diameter = 100.0  # optional envelope on 2R + d [mm]
# max_eccentricity = 0.5      # spider-centre eccentricity [mm]

[uncertainty]
# Distributions on any spec number (design variables: a tolerance around the design), e.g.
#   R = { distribution = "normal", sd = 0.01 }                      # [mm]
#   conformity = { distribution = "uniform", low = 1.002, high = 1.008 }
#   hertz.P_d = { distribution = "normal", cov = 0.05 }
#   correlation = [["R", "d_roller", 0.3]]
# Kinds: normal (sd or cov; low/high truncate), lognormal (sd or cov), uniform (low and high,
# or half_width). With any entry the report gives the probability of missing each requirement,
# and [constraints] accepts max_failure_probability_<q> / min_reliability_index_<q>.

[solver]
# Among the cheapest settings (first solve: trace, compile and run) whose design lies within 0.1 %
# of the newton / n_theta = 360 answer (python -m tripodjax.optimize.bench; analytic at 360 angles
# costs the same and lands within 1e-9 of it); optimize-joint re-checks the design at full fidelity.
# n_theta × starts × max_outer × inner_steps is at most 1.5e6: it bounds the work of one solve.
fidelity = "newton"    # halfshaft kinematics: "newton" (exact) or "analytic" (cheap)
n_theta = 168          # input angles per revolution for the kinematics (multiple of 6)
starts = 4             # multi-start points (a deterministic grid over the bounds)
max_outer = 25         # augmented-Lagrangian outer iterations
inner_steps = 30       # L-BFGS iterations per outer iteration
tolerance = 1e-5       # KKT residual (projected gradient, feasibility, complementarity)
"""
"""The embedded default design specification, a TOML text: every key of the file with its
default, its unit (in the key's name or its comment) and its meaning; the keys a file may add
are commented out. A spec file need only hold the keys it changes (`parse_spec`, `load_spec`);
docs/cli.md renders it as the spec reference."""

QUANTITIES = {
    "irregularity": ("–", "transmission irregularity (Ω2max − Ω2min)/Ω1 (§2.11.3)"),
    "eccentricity": ("mm", "maximum spider-centre eccentricity over a revolution (2.5.9)"),
    "gamma_ripple": ("deg", "peak-to-peak articulation angle over a revolution"),
    "roller_stroke": (
        "mm",
        "peak-to-peak axial roller travel along its track (2.6.2, with the spider plunge)",
    ),
    "gaf_rms": ("N", "RMS of the generated axial force at loads.gaf_torque (§3.2)"),
    "gaf_peak": ("N", "peak |GAF| at loads.gaf_torque"),
    "gaf_third_order": ("N", "third-order GAF amplitude at loads.gaf_torque"),
    "gaf_sixth_order": (
        "N",
        "sixth-order GAF amplitude at loads.gaf_torque (force model, whatever friction.gaf_model)",
    ),
    "gaf_ninth_order": (
        "N",
        "ninth-order GAF amplitude at loads.gaf_torque (force model, whatever friction.gaf_model)",
    ),
    "lts": (
        "N",
        "load-to-stroke resistance: mean axial force against a plunge at "
        "forces.plunge_speed_mm_s, at loads.gaf_torque (force model, §3.1)",
    ),
    "lts_ripple": ("N", "half the peak-to-peak of the LTS over a revolution (force model)"),
    "complementary_torque": (
        "N·m",
        "steady complementary torque, the bending moment of the rollers on the housing, at "
        "loads.gaf_torque (force model, §3.1)",
    ),
    "complementary_torque_third_order": (
        "N·m",
        "amplitude of the complementary torque's order 3 at loads.gaf_torque (force model)",
    ),
    "complementary_torque_sixth_order": (
        "N·m",
        "amplitude of the complementary torque's order 6 at loads.gaf_torque (force model)",
    ),
    "roller_load_ratio": (
        "–",
        "largest roller normal force over a revolution / (T/3R) at loads.gaf_torque (force model)",
    ),
    "friction_power": (
        "W",
        "mean power dissipated by friction at loads.gaf_torque and forces.speed_rpm (force model)",
    ),
    "outer_diameter": ("mm", "outer-diameter proxy 2R + d"),
    "static_capacity": ("N·m", "static torque capacity M_s at P_s (§4.2)"),
    "M_d": ("N·m", "long-lasting dynamic capacity at P_d and γ0 (§4.2)"),
    "M_sd": ("N·m", "short-lasting dynamic capacity at P_sd and γ0 (§4.2)"),
    "life_km": ("km", "Palmgren–Miner life under the spectrum (4.2.1–4.2.3)"),
    "R_over_d": ("–", "R / d"),
    "shaft_area": (
        "mm²",
        "the [shaft] sections' cross-section areas π(Øe² − Øi²)/4, summed: the shaft's weight "
        "per unit length, each section alike",
    ),
    "shaft_static_safety": (
        "–",
        "the smallest static safety τ_adm/τ of the [shaft] sections (each at its strength "
        "profile's kinks, M_max forward and backward; required ≥ 1); per section as "
        "shaft_static_safety[<name>]",
    ),
    "shaft_damage": (
        "–",
        "the largest fatigue damage of the [shaft] sections (Miner's sum at r_o and r_TR; "
        "required ≤ shaft.allowed_damage); per section as shaft_damage[<name>]",
    ),
    "outboard_static_safety": (
        "–",
        "the outboard joint's static safety M_s / M_max (required ≥ loads.shock_factor)",
    ),
    "outboard_life_km": (
        "km",
        "the outboard joint's life under [outboard.conditions] (required ≥ life.required_km)",
    ),
}
"""Every quantity of a design: name → (unit, what it is). Each can be an objective term
(``w_<q>`` with its reference ``<q>_ref``, in the quantity's unit) or a constraint (``max_<q>``,
``min_<q>``); `evaluate` computes them."""
KINEMATIC_QUANTITIES = ("irregularity", "eccentricity", "gamma_ripple", "roller_stroke")
GAF_QUANTITIES = ("gaf_rms", "gaf_peak", "gaf_third_order")
# Quantity → its name in tripodjax.forces (the GAF's too when friction.gaf_model = "forces").
FORCE_QUANTITIES = {
    "gaf_sixth_order": "gaf_sixth_order",  # the force model's whatever the GAF's: Lee's has none
    "gaf_ninth_order": "gaf_ninth_order",
    "lts": "lts_mean",
    "lts_ripple": "lts_ripple",
    "complementary_torque": "complementary_torque_steady",
    "complementary_torque_third_order": "complementary_torque_third_order",
    "complementary_torque_sixth_order": "complementary_torque_sixth_order",
    "roller_load_ratio": "roller_load_ratio",
    "friction_power": "friction_power",
}
# The quantities computed from the halfshaft's revolution (a kinematic solve per design).
REVOLUTION_QUANTITIES = KINEMATIC_QUANTITIES + GAF_QUANTITIES + tuple(FORCE_QUANTITIES)
# The rest of the halfshaft ([shaft], [outboard]; tripodjax.optimize.structural), from the
# vehicle's load cycles; the two per-section ones are also given per section, "<q>[<name>]".
HALFSHAFT_QUANTITIES = (
    "shaft_area",
    "shaft_static_safety",
    "shaft_damage",
    "outboard_static_safety",
    "outboard_life_km",
)
PER_SECTION_QUANTITIES = ("shaft_static_safety", "shaft_damage")


def quantity_unit(name):
    """The unit of a quantity, a per-section one (``shaft_damage[C-C]``) as its quantity's."""
    return QUANTITIES[name.partition("[")[0]][0]


class Range(typing.NamedTuple):
    """The allowed values of a spec number: from ``low`` to ``high`` (None: no end), each end
    excluded when ``*_open``; ``unit`` as the messages write it after a number (" mm", "°")."""

    low: float | None
    high: float | None
    low_open: bool = False
    high_open: bool = False
    unit: str = ""

    def holds(self, value: float) -> bool:
        ok = math.isfinite(value)
        ok = ok and (self.low is None or (value > self.low if self.low_open else value >= self.low))
        return ok and (
            self.high is None or (value < self.high if self.high_open else value <= self.high)
        )

    def text(self) -> str:
        """E.g. "a finite number > 0 and ≤ 200 mm"."""
        parts = []
        if self.low is not None:
            parts.append(f"{'>' if self.low_open else '≥'} {self.low:g}{self.unit}")
        if self.high is not None:
            parts.append(f"{'<' if self.high_open else '≤'} {self.high:g}{self.unit}")
        return "a finite number " + " and ".join(parts) if parts else "a finite number"

    @property
    def domain(self) -> tuple:
        """(low, high, low open): a design variable's domain (its high end is closed)."""
        return (self.low, self.high, self.low_open)


# Limits generous for a passenger car's or a light commercial vehicle's halfshaft and joints
# (seed §4.3: the workbook's sportscar has 937 kg, M_max 1154 N·m, a 25.8 mm shaft, allowed
# pressures of 1347–3750 MPa): ten times and more what such a halfshaft sees, yet finite, so
# that no number of a spec overflows the computation or answers nonsense. A number that a
# quantity is divided by (a safety, a radius, an allowed pressure, M_max) has a lower limit
# above 0 for the same reason.
MAX_TORQUE_NM = 5.0e4  # a 3.5 t van's first gear through a locked differential: < 1e4 N·m
MIN_PRESSURE_MPA, MAX_PRESSURE_MPA = 100.0, 1.0e4  # hardened bearing steel: 1000–4500 MPa
MAX_SHAFT_SPEED_RPM = 1.0e4  # a wheel at 300 km/h on a 0.25 m tyre: 3200 rpm
MAX_JOINT_MM = 200.0  # a joint's radii and diameters (the workbook's: 18–44 mm)
MAX_CONFORMITY = 2.0  # Ψ = 2 R_g / d (workbook 1.002–1.008)
SAFETY = Range(1.0, 10.0)  # a safety coefficient on a capacity or a limit [–]
SHARE = Range(0.0, 1.0)
ANGLE = Range(0.0, 89.999, unit="°")  # a working angle [deg], below 90°
# Every number of the spec file: key → its allowed Range (a list's entries each). The one
# table of the spec's ranges: the checks at parse, the bounds and designs of the design
# variables (VARIABLES), and the spec reference of the docs (docs/cli.md) read it.
RANGES = {
    "design.R": Range(1.0, MAX_JOINT_MM, unit=" mm"),
    "design.d_roller": Range(1.0, MAX_JOINT_MM, unit=" mm"),
    "layout.l": Range(10.0, 5000.0, unit=" mm"),
    "layout.gamma0_deg": Range(0.0, MAX_GAMMA0_DEG, unit="°"),
    "loads.shock_factor": Range(1.0, 10.0),
    "loads.gaf_torque": Range(0.0, MAX_TORQUE_NM, unit=" N·m"),
    "loads.M_max": Range(1.0, MAX_TORQUE_NM, unit=" N·m"),
    **{
        f"{joint}.{key}": Range(MIN_PRESSURE_MPA, MAX_PRESSURE_MPA, unit=" MPa")
        for joint in ("hertz", "outboard")
        for key in ("P_s", "P_d", "P_sd")
    },
    "hertz.C_s": SAFETY,
    "hertz.conformity": Range(MIN_CONFORMITY, MAX_CONFORMITY),
    "vehicle.mass_kg": Range(50.0, 1.0e4, unit=" kg"),
    "vehicle.front_share": SHARE,
    "vehicle.wheelbase_m": Range(0.5, 10.0, unit=" m"),
    "vehicle.cg_height_m": Range(0.0, 5.0, unit=" m"),
    "vehicle.tyre_radius_m": Range(0.1, 2.0, unit=" m"),
    "vehicle.adhesion": Range(0.01, 3.0),
    "vehicle.rear_torque_share": SHARE,
    "vehicle.differential_locking": SHARE,
    "vehicle.engine_torque_Nm": Range(0.0, 5000.0, unit=" N·m"),
    "vehicle.engine_speed_rpm": Range(100.0, 2.0e4, unit=" rpm"),
    "vehicle.load_transfer_per_ratio_N": Range(0.0, 1.0e5, unit=" N"),
    "vehicle.reverse_load_transfer_N": Range(0.0, 1.0e5, unit=" N"),
    "vehicle.gears.ratios": Range(0.5, 100.0),
    "vehicle.gears.reverse": Range(0.5, 100.0),
    "vehicle.modes.weight": SHARE,
    **{f"vehicle.modes.use_{c}_pct": Range(0.0, 100.0, unit=" %") for c in ENGINE_CONDITIONS},
    "life.required_km": Range(1.0, 1.0e7, unit=" km"),
    "life.torque": Range(0.0, MAX_TORQUE_NM, unit=" N·m"),
    "life.speed": Range(0.0, MAX_SHAFT_SPEED_RPM, unit=" rpm"),
    "life.vehicle_speed": Range(0.0, 500.0, unit=" km/h"),
    "life.share": SHARE,
    "life.conditions.angle_deg": ANGLE,
    "life.conditions.share": SHARE,
    "friction.lam": Range(0.0, 1.0),
    "friction.mu_slp": Range(0.0, 1.0),
    "forces.speed_rpm": Range(-MAX_SHAFT_SPEED_RPM, MAX_SHAFT_SPEED_RPM, unit=" rpm"),
    "forces.mu_trunnion": Range(0.0, 1.0),
    "forces.contact_angle_deg": ANGLE,
    "forces.plunge_speed_mm_s": Range(-1.0e4, 1.0e4, unit=" mm/s"),
    "forces.lts_speed_rpm": Range(-MAX_SHAFT_SPEED_RPM, MAX_SHAFT_SPEED_RPM, unit=" rpm"),
    "shaft.outer_diameter_mm": Range(1.0, MAX_JOINT_MM, unit=" mm"),
    "shaft.inner_diameter_mm": Range(0.0, MAX_JOINT_MM, unit=" mm"),
    "shaft.hardened_depth_mm": Range(0.0, MAX_JOINT_MM / 2, unit=" mm"),
    "shaft.transition_depth_mm": Range(0.0, MAX_JOINT_MM / 2, unit=" mm"),
    "shaft.safety": SAFETY,
    "shaft.core_uts_MPa": Range(MIN_PRESSURE_MPA, MAX_PRESSURE_MPA, unit=" MPa"),
    "shaft.surface_uts_MPa": Range(MIN_PRESSURE_MPA, MAX_PRESSURE_MPA, unit=" MPa"),
    "shaft.depth_drop": Range(0.0, 1.0, high_open=True),
    "shaft.fatigue_ratio": Range(1.0, 10.0, low_open=True),
    "shaft.allowed_damage": Range(0.01, 10.0),
    "outboard.ball_diameter_mm": Range(1.0, MAX_JOINT_MM, unit=" mm"),
    "outboard.pcr_mm": Range(1.0, MAX_JOINT_MM, unit=" mm"),
    "outboard.conformity": Range(MIN_CONFORMITY, MAX_CONFORMITY),
    "outboard.longitudinal_conformity": Range(-1.0, 1.0, low_open=True),
    "outboard.C_s": SAFETY,
    "outboard.pressure_angle_deg": Range(0.0, 90.0, low_open=True, high_open=True, unit="°"),
    "outboard.oblique_angle_deg": ANGLE,
    "outboard.tolerance": Range(0.0, 1.0),
    "outboard.conditions.angle_deg": ANGLE,
    "outboard.conditions.share": SHARE,
    "solver.tolerance": Range(1e-12, 1e-1),
}
# The keys the file names freely (any quantity q): an objective's weight and reference, a
# constraint's limit (a chance constraint's: see _chance).
OBJECTIVE_WEIGHT = Range(None, None)
OBJECTIVE_REFERENCE = Range(0.0, None, low_open=True)
CONSTRAINT_LIMIT = Range(0.0, None, low_open=True)

VARIABLES = {
    "R": ("design", "R", "mm", RANGES["design.R"].domain),
    "d_roller": ("design", "d_roller", "mm", RANGES["design.d_roller"].domain),
    "l": ("layout", "l", "mm", RANGES["layout.l"].domain),
    "gamma0_deg": ("layout", "gamma0", "deg", RANGES["layout.gamma0_deg"].domain),
    "conformity": ("hertz", "conformity", "–", RANGES["hertz.conformity"].domain),
    "lam": ("friction", "lam", "–", RANGES["friction.lam"].domain),
    "mu_slp": ("friction", "mu_slp", "–", RANGES["friction.mu_slp"].domain),
}
"""The design variables, free when ``[bounds]`` gives them an interval: name → (section, the
key of its value inside that section (``gamma0``, in rad), unit, domain (low, high, low open):
its spec number's `Range`). Its key in the file is its name (``gamma0_deg`` in degrees); the
report's keys add the unit suffix (``R_mm``). A ``[shaft]`` entry is free too, as
``shaft.<list>[<section>]`` [mm] (`SHAFT_VARIABLES`)."""
# A [shaft] entry as a design variable: "shaft.<list>[<section name>]" [mm], one of these lists.
SHAFT_VARIABLES = (
    "outer_diameter_mm",
    "inner_diameter_mm",
    "hardened_depth_mm",
    "transition_depth_mm",
)


def shaft_variable(name):
    """(list key, section name) of a shaft design variable's name, or None for another name."""
    if not (name.startswith("shaft.") and name.endswith("]") and "[" in name):
        return None
    key, _, section = name[len("shaft.") : -1].partition("[")
    return key, section


def shaft_variable_name(key, section):
    return f"shaft.{key}[{section}]"


def variable_range(name):
    """The Range of a design variable's values in the file (a [shaft] entry's in mm)."""
    entry = shaft_variable(name)
    if entry is None:
        section, key = VARIABLES[name][0], name
    else:
        section, key = "shaft", entry[0]
    return RANGES[f"{section}.{key}"]


def variable_domain(name):
    """(unit, (low, high, low open)) of a design variable's values; a [shaft] entry's in mm."""
    unit = VARIABLES[name][2] if shaft_variable(name) is None else "mm"
    return unit, variable_range(name).domain


REPORT_KEYS = {
    "R": "R_mm",
    "d_roller": "d_roller_mm",
    "l": "l_mm",
    "gamma0_deg": "gamma0_deg",
    "conformity": "conformity",
    "lam": "lam",
    "mu_slp": "mu_slp",
}
GREASE_MU_SLP = {"A": 0.06, "B": 0.09, "dry": 0.30}  # seed §3.2.3
FIDELITIES = ("newton", "analytic")
GAF_MODELS = ("stroke", "printed", "forces")
# Integer solver sizes: upper limits that keep a solve within memory and minutes.
INTEGER_LIMITS = {
    "n_theta": (6, 3600, "a multiple of 6"),
    "starts": (1, 64, ""),
    "max_outer": (1, 200, ""),  # its upper limit sizes the solve's history (MAX_OUTER_ITERATIONS)
    "inner_steps": (1, 200, ""),
}
# The joints' integer counts: key → (low, high, what else).
COUNT_LIMITS = {
    "hertz.n_rollers": (1, 12, ""),
    "outboard.n_balls": (MIN_BALLS, 24, "the balls fitting on the pitch circle"),
}
# A solve evaluates the revolution's n_theta angles for each start max_outer · inner_steps times
# (times the backtracks of each line search, at most MAX_BACKTRACKS + 1 = 31): the product bounds
# its work. Measured on a 2-core CPU at 1.25 µs per angle and start, the worst case at MAX_WORK is
# about a minute (the default spec, 168 × 4 × 25 × 30 = 5.04e5, about 20 s; typically 0.1 s).
WORK_KEYS = ("n_theta", "starts", "max_outer", "inner_steps")
MAX_OUTER_ITERATIONS = INTEGER_LIMITS["max_outer"][1]
MAX_WORK = 1.5e6
MAX_LIST_LENGTH = 1000
# Text in a spec: a key or a text value (a name, a choice) is a label of the report's tables and
# figures, at most MAX_TEXT_LENGTH characters; a file path (PATH_KEYS) at most MAX_PATH_LENGTH.
PATH_KEYS = ("life.spectrum_file",)
# Legacy keys that keep working (old name → new name).
LEGACY_OBJECTIVE = {
    "w_gaf": "w_gaf_rms",
    "w_size": "w_outer_diameter",
    "size_ref": "outer_diameter_ref",
}


LIFE_LISTS = ("torque", "speed", "vehicle_speed", "share")
# Keys the default leaves out (commented out in DEFAULT_SPEC_TOML): giving one replaces what
# [vehicle] (or, for mu_slp, friction.grease) would give.
OPTIONAL_KEYS = {
    "loads.M_max",
    "friction.mu_slp",
    "life.spectrum_file",
    *(f"life.{k}" for k in LIFE_LISTS),
}
# Sections whose keys the file names freely: [objective] and [constraints] (any quantity q),
# [bounds] (any design variable), [uncertainty] (any spec number); their keys are checked
# when the section is read.
FREE_SECTIONS = ("objective", "constraints", "bounds", "uncertainty")
VEHICLE_NUMBERS = (  # the [vehicle] section's single numbers (RANGES)
    "mass_kg",
    "front_share",
    "wheelbase_m",
    "cg_height_m",
    "tyre_radius_m",
    "adhesion",
    "rear_torque_share",
    "differential_locking",
    "load_transfer_per_ratio_N",
    "reverse_load_transfer_N",
)
MAX_GEARS = 11


@functools.cache
def accepted_keys(path: tuple[str, ...] = ()) -> tuple[str, ...] | None:
    """The keys the spec's table at ``path`` accepts, sorted: the default spec's and the
    optional ones (OPTIONAL_KEYS); the sections at ``()``. None inside a section that names its
    keys freely (FREE_SECTIONS) and for a ``path`` that is no table of the default spec. The one
    list of what a table accepts: the parser's check and its "allowed here" read it."""
    if path and path[0] in FREE_SECTIONS:
        return None
    table = tomllib.loads(DEFAULT_SPEC_TOML)
    for part in path:
        table = table.get(part)
        if not isinstance(table, dict):
            return None
    prefix = ".".join(path)
    optional = {k.rpartition(".")[2] for k in OPTIONAL_KEYS if k.rpartition(".")[0] == prefix}
    return tuple(sorted(set(table) | optional))


def unit_text(key: str) -> str:
    """The unit of a spec key in the file (``section.key``; a list's entries each), "–" for
    none: the unit of its allowed range (RANGES), of its design variable's in [bounds], of its
    quantity's in [objective] and [constraints] (a weight is dimensionless). The spec
    reference of the docs shows it beside ``allowed_text``, so the two agree."""
    section, _, name = key.rpartition(".")
    if key in RANGES:
        unit = RANGES[key].unit
    elif section == "bounds" and (name in VARIABLES or shaft_variable(name)):
        unit = variable_range(name).unit
    elif section == "objective" and name.endswith("_ref") and name[:-4] in QUANTITIES:
        unit = quantity_unit(name[:-4])
    elif section == "constraints" and name[:4] in ("max_", "min_") and name[4:] in QUANTITIES:
        unit = quantity_unit(name[4:])
    else:
        unit = ""
    return unit.strip() or "–"


def allowed_text(key: str) -> str | None:
    """What the file allows for a number of the spec, in words (the spec reference of the docs
    shows it): ``"≥ 1 mm and ≤ 200 mm"`` for ``"design.R"``; None for a key that is no number."""
    section, _, name = key.rpartition(".")
    if key in RANGES:
        rule = RANGES[key]
    elif section == "solver" and name in INTEGER_LIMITS or key in COUNT_LIMITS:
        low, high, extra = INTEGER_LIMITS[name] if section == "solver" else COUNT_LIMITS[key]
        return f"an integer from {low} to {high}" + (f", {extra}" if extra else "")
    elif section == "objective" and name.startswith("w_"):
        rule = OBJECTIVE_WEIGHT
    elif section in ("objective", "constraints"):  # a reference or a limit: its quantity's unit
        rule = OBJECTIVE_REFERENCE if section == "objective" else CONSTRAINT_LIMIT
        unit = unit_text(key)
        rule = rule if unit == "–" else rule._replace(unit=f" {unit}")
    elif section == "bounds" and name in VARIABLES:
        return f"[lo, hi], lo < hi, each {allowed_text(f'{VARIABLES[name][0]}.{name}')}"
    else:
        return None
    return rule.text().removeprefix("a finite number ")


class SpecError(ValueError):
    """A problem in a design specification: the message names the key and what is allowed."""


@dataclasses.dataclass(frozen=True)
class Structure:
    """The static part of a spec: what is free, which terms and constraints exist, the sizes.

    Two specs with equal structures share one compiled optimiser.
    """

    free: tuple  # free design variables, in VARIABLES order, then the [shaft] entries' (section order)
    objective: tuple  # quantities with a weight
    constraints: tuple  # (name, quantity, sense) with sense "max" or "min"
    condition_names: tuple
    n_rollers: int
    angle_law: str
    vehicle_modes: tuple  # mode names; () when no vehicle is used
    axle: str
    m_max_from_vehicle: bool
    spectrum_from_vehicle: bool
    gaf_model: str
    fidelity: str
    n_theta: int
    starts: int
    uncertainty: tuple = ()  # uncertainty.Input per uncertain number
    chance: tuple = ()  # (key, "probability" or "index", constrained requirement names)
    shaft_sections: tuple = ()  # [shaft] section names
    shaft_reading: str = "consistent"
    outboard_balls: int = 6
    outboard_reading: str = "consistent"
    outboard_conditions: tuple = ()  # [outboard.conditions] names
    # False only in the chance constraints' own structure (problem.chance_target_structure):
    # targets that are no halfshaft quantity's constraint compute none of the halfshaft.
    halfshaft_checked: bool = True

    @property
    def halfshaft(self):
        """Whether the rest of the halfshaft is checked: it needs the vehicle's load cycles."""
        return bool(self.vehicle_modes) and self.halfshaft_checked

    @property
    def needs(self):
        """The quantities the objective and constraints use (computed; nothing else is)."""
        used = set(self.objective) | {q for _, q, _ in self.constraints}
        return used | {"static_capacity", "life_km"} | set(HALFSHAFT_QUANTITIES * self.halfshaft)


# Internal value (section, key) in radians → its key in the file (a pair: a nested table), in degrees.
_SPEC_UNITS = {
    ("layout", "gamma0"): ("gamma0_deg", "deg"),
    ("forces", "contact_angle"): ("contact_angle_deg", "deg"),
    ("outboard", "pressure_angle"): ("pressure_angle_deg", "deg"),
    ("outboard", "oblique_angle"): ("oblique_angle_deg", "deg"),
    ("outboard", "condition_angle"): (("conditions", "angle_deg"), "deg"),
    ("outboard", "condition_share"): (("conditions", "share"), None),
    ("life", "condition_angle"): (("conditions", "angle_deg"), "deg"),
    ("life", "condition_share"): (("conditions", "share"), None),
}


def _flatten_spec(spec):
    return (spec.values,), spec.structure


def _unflatten_spec(structure, children):
    return Spec(structure=structure, values=children[0], resolved=None)


@dataclasses.dataclass(frozen=True)
class Spec:
    """A checked design specification (see ``DEFAULT_SPEC_TOML`` for every key and unit).

    Attributes:
        structure: the static [`Structure`][tripodjax.optimize.spec.Structure].
        values: the numbers, ``{section: {key: float or 1-D array}}``, in internal
            units (angles in rad under ``gamma0``, ``angle``; lengths in mm). A
            pytree leaf each: ``jit`` traces them.
        resolved: the full specification as a plain dict (the file merged over
            the default), for reports; not part of the pytree.
    """

    structure: Structure
    values: dict
    resolved: dict = dataclasses.field(default=None, compare=False)

    def __getitem__(self, section: str) -> dict:
        """The numbers of one section in the spec file's own keys and units (a copy).

        ``spec["layout"]`` is ``{"l": mm, "gamma0_deg": deg}``, ``spec["bounds"]["gamma0_deg"]``
        is ``[lo, hi]`` in degrees and ``spec["life"]["conditions"]`` holds ``angle_deg`` and
        ``share``: what a file says is what the view says, so bounds read here can be handed
        to [`evaluate`][tripodjax.optimize.evaluate] as they are. The internal values (radians,
        the traced pytree) are [`values`][tripodjax.optimize.Spec].
        """
        if section not in self.values:
            raise KeyError(f"{section!r}; sections: {', '.join(self.values)}")
        view = {}
        for key, value in self.values[section].items():
            name, to_spec = _SPEC_UNITS.get((section, key), (key, None))
            value = np.array(value, np.float64)
            if to_spec is not None or (section == "bounds" and key == "gamma0_deg"):
                value = np.degrees(value)
            value = float(value) if value.ndim == 0 else value
            if isinstance(name, tuple):  # a nested table of the file, e.g. life.conditions
                view.setdefault(name[0], {})[name[1]] = value
            else:
                view[name] = value
        if section == "life" and "conditions" in view and self.structure.condition_names:
            view["conditions"]["names"] = list(self.structure.condition_names)
        if section == "outboard" and "conditions" in view:
            view["conditions"]["names"] = list(self.structure.outboard_conditions)
            view["n_balls"] = self.structure.outboard_balls
        if section == "shaft":
            view["names"] = list(self.structure.shaft_sections)
        return view

    def replace_values(self, **sections: Mapping) -> "Spec":
        """A copy with some numbers changed, e.g. ``spec.replace_values(loads={"M_max": 1200.0})``.

        Checked like the file: an unknown section or key is an error, and the new numbers go
        through the same rules. Sections are any mappings; a number is any real scalar (Python,
        NumPy, a 0-d JAX array), a list any sequence or 1-D array of them.
        """
        given = _given(_plain(sections), None)
        return _check(_merge(self.resolved, given))

    def deterministic(self) -> "Spec":
        """The spec whose problem a solve needs: without a chance constraint the
        ``[uncertainty]`` section enters only the reliability table, so this is the spec
        less it (the same structure, and so the same compiled programs, as a spec written
        without it); a spec with a chance constraint, or without uncertainty, is itself."""
        if self.structure.chance or not self.structure.uncertainty:
            return self
        structure = dataclasses.replace(self.structure, uncertainty=())
        return Spec(
            structure=structure,
            values={**self.values, "uncertainty": {}},
            resolved=self.resolved,
        )


jax.tree_util.register_pytree_node(Spec, _flatten_spec, _unflatten_spec)


# --------------------------------------------------------------------------- checking


def _plain(value):
    """A value given in Python (``replace_values``) as the TOML reader gives it.

    Mappings become dicts, tuples and 1-D arrays lists, real scalars of any array library
    Python numbers; anything else stays as it is, for the checks to name.
    """
    if isinstance(value, Mapping):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    if value is None or isinstance(value, (str, bytes, bool, int, float)):
        return value
    if hasattr(value, "__array__") or isinstance(value, np.generic):
        try:
            array = np.asarray(value)
        except Exception:  # a tracer: left for the checks to name
            return value
        if array.dtype.kind in "biuf" and array.ndim <= 1:
            return array.tolist()
    return value


def _bounded_text(table, path=()):
    """Refuse a key or a text of ``table`` longer than allowed, before a message repeats it."""
    where = ".".join(map(str, path))
    if isinstance(table, dict):
        for key, value in table.items():
            if isinstance(key, str) and len(key) > MAX_TEXT_LENGTH:
                raise SpecError(
                    f"the key {key[:20]!r}… in {where or 'the spec'} is {len(key)} characters "
                    f"long; at most {MAX_TEXT_LENGTH} allowed"
                )
            _bounded_text(value, path + (key,))
    elif isinstance(table, list):
        for i, value in enumerate(table):
            _bounded_text(value, path[:-1] + (f"{path[-1]}[{i}]",))
    elif isinstance(table, str):
        limit = MAX_PATH_LENGTH if where in PATH_KEYS else MAX_TEXT_LENGTH
        problem = length_problem(where, table, limit)
        if problem:
            raise SpecError(problem)
    return table


def _given(given, base):
    """A file's (or ``replace_values``') table, checked for its texts, renamed, with its sources."""
    return _sources(_legacy(_bounded_text(given)), base)


def _toml(value):
    """A value as the spec file writes it (``true``, ``"text"``), for a message."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    return repr(value)


def _real(where, value, allowed="a finite number"):
    """A real number as a float, or SpecError naming ``allowed`` (wrong type, beyond the float
    range)."""
    try:
        return real_scalar(where, value)
    except TypeError:
        raise SpecError(f"{where} = {_toml(value)} is not allowed: {allowed}") from None
    except ValueError as error:
        raise SpecError(str(error)) from None


def _number(table, section, key, low=None, high=None, *, low_open=False, unit="", rule=None):
    """A finite number in its Range: ``rule``, or the one of ``low`` … ``unit`` given (a key the
    file names freely), else the key's in RANGES."""
    where = f"{section}.{key}"
    if rule is None:
        given = low is not None or high is not None
        rule = Range(low, high, low_open, unit=unit) if given else RANGES[where]
    return _in_range(where, _real(where, table[section][key], rule.text()), rule)


def _in_range(where, value, rule):
    """``value`` when its Range ``rule`` holds, else one SpecError naming it and the range."""
    if not rule.holds(value):
        raise SpecError(f"{where} = {value!r} is not allowed: {rule.text()}")
    return value


def _numbers(table, section, key, rule=None, *, where=None):
    """A non-empty list of finite numbers, each in its Range (``rule``, else the key's in
    RANGES); errors name the index after ``where`` (default ``section.key``)."""
    where = where or f"{section}.{key}"
    node = table
    for part in section.split("."):
        node = node[part]
    values = node[key]
    rule = rule or RANGES[f"{section}.{key}"]
    if not isinstance(values, list) or not values:
        raise SpecError(f"{where} = {values!r} must be a non-empty list of numbers")
    if len(values) > MAX_LIST_LENGTH:
        raise SpecError(f"{where} has {len(values)} entries; at most {MAX_LIST_LENGTH} allowed")
    return [
        _in_range(f"{where}[{i}]", _real(f"{where}[{i}]", value, rule.text()), rule)
        for i, value in enumerate(values)
    ]


def _string(table, section, key, allowed):
    """One of the texts ``allowed``; the message spells the value and the choices as TOML."""
    where = f"{section}.{key}"
    value = table[section][key]
    if not isinstance(value, str) or value not in allowed:
        raise SpecError(
            f"{where} = {_toml(value)} is not allowed; allowed: {', '.join(map(_toml, allowed))}"
        )
    return value


def _integer(table, key):
    low, high, extra = INTEGER_LIMITS[key]
    value = table["solver"][key]
    where = f"solver.{key}"
    if isinstance(value, float) and value.is_integer() and abs(value) < 2**53:
        value = int(value)
    if not isinstance(value, int) or isinstance(value, bool):
        raise SpecError(f"{where} = {value!r} must be an integer")
    if not low <= value <= high or (key == "n_theta" and value % 6):
        limits = f"an integer from {low} to {high}" + (f", {extra}" if extra else "")
        raise SpecError(f"{where} = {_integer_text(value)} is not allowed: {limits}")
    return value


def _count(table, key):
    """A joint's integer count (COUNT_LIMITS): an int (not a bool, nor a float such as 6.0)."""
    low, high, _ = COUNT_LIMITS[key]
    section, name = key.split(".")
    value = table[section][name]
    if not isinstance(value, int) or isinstance(value, bool) or not low <= value <= high:
        raise SpecError(
            f"{key} = {_integer_text(value)} is not allowed: an integer from {low} to {high}"
        )
    return value


def _integer_text(value):
    """An integer for a message; a huge one by its size (repr fails beyond 4300 digits)."""
    if isinstance(value, int) and abs(value) > 10**12:
        return f"an integer of about {int(value.bit_length() * math.log10(2)) + 1} digits"
    return repr(value)


def _shares(where, shares):
    total = sum(shares)
    if abs(total - 1.0) > 1e-6:
        raise SpecError(
            f"{where} = {shares!r} is not allowed: shares summing to 1 (sum {total:.6g})"
        )


def _merge(default, override, path=()):
    """Deep-merge ``override`` into ``default``, rejecting keys the default does not know."""
    merged = copy.deepcopy(default)
    for key, value in override.items():
        where = ".".join(map(str, path + (key,)))
        accepted = accepted_keys(tuple(map(str, path)))
        if accepted is not None and key not in accepted:
            raise SpecError(f"unknown key {where}; allowed here: {', '.join(accepted)}")
        if isinstance(default.get(key), dict):
            if not isinstance(value, Mapping):
                raise SpecError(f"{where} must be a table")
            merged[key] = _merge(default[key], value, path + (key,))
        else:
            merged[key] = value
    return merged


def _quantity_key(section, key, prefixes):
    """The quantity named by an objective/constraint key, e.g. 'w_gaf_rms' → 'gaf_rms'."""
    for prefix, suffix in prefixes:
        if key.startswith(prefix) and key.endswith(suffix):
            name = key[len(prefix) : len(key) - len(suffix)]
            if name in QUANTITIES:
                return prefix, name
    forms = " / ".join(f"{p}<q>{s}" for p, s in prefixes)
    raise SpecError(
        f"unknown key {section}.{key}; allowed: {forms} with <q> one of {', '.join(QUANTITIES)}"
    )


def _legacy(given):
    """Today's earlier keys, renamed in the file's own table before it meets the default."""
    objective = given.get("objective")
    if isinstance(objective, dict):
        for old, new in LEGACY_OBJECTIVE.items():
            if old in objective:
                if new in objective:
                    raise SpecError(
                        f"objective.{old} and objective.{new} are the same key; give one"
                    )
                objective[new] = objective.pop(old)
    constraints = given.get("constraints")
    if isinstance(constraints, dict) and "R_over_d" in constraints:
        pair = constraints.pop("R_over_d")
        if not isinstance(pair, list) or len(pair) != 2:
            raise SpecError(f"constraints.R_over_d = {pair!r} must be a pair [lo, hi]")
        constraints["min_R_over_d"], constraints["max_R_over_d"] = pair
    return given


def _objective(table):
    given = dict(table["objective"])
    weights, refs = {}, {}
    for key, value in given.items():
        prefix, q = _quantity_key("objective", key, (("w_", ""), ("", "_ref")))
        tab = {"objective": {key: value}}
        if prefix == "w_":
            weights[q] = _number(tab, "objective", key, rule=OBJECTIVE_WEIGHT)
        else:
            refs[q] = _number(tab, "objective", key, rule=OBJECTIVE_REFERENCE)
    terms = tuple(q for q in QUANTITIES if q in weights)
    if not any(weights[q] != 0 for q in terms):
        raise SpecError("objective has no non-zero weight w_<q>; give at least one")
    if not any(weights[q] > 0 for q in terms):
        given = ", ".join(f"w_{q} = {weights[q]:g}" for q in terms if weights[q])
        raise SpecError(
            f"objective has no positive weight ({given}): minimising it maximises every term, "
            "which drives the design to its bounds; give at least one w_<q> > 0"
        )
    for q in terms:
        if q not in refs:
            raise SpecError(f"objective.w_{q} needs objective.{q}_ref (> 0, in {QUANTITIES[q][0]})")
    for q in refs:  # the spec's one rule for its keys: none is given and left unused
        if q not in weights:
            raise SpecError(
                f"objective.{q}_ref = {refs[q]:g} has no weight objective.w_{q}: a reference "
                f"enters the objective with its weight only; give w_{q} or leave {q}_ref out"
            )
    for q in terms:
        if not math.isfinite(weights[q] / refs[q]):
            raise SpecError(
                f"objective.w_{q} / objective.{q}_ref = {weights[q]:g} / {refs[q]:g} overflows: "
                f"allowed: |w_{q} / {q}_ref| ≤ {MAX_FLOAT:.4g}"
            )
    values = {f"w_{q}": weights[q] for q in terms} | {f"{q}_ref": refs[q] for q in terms}
    return terms, values


CHANCE_PREFIXES = {"max_failure_probability_": "probability", "min_reliability_index_": "index"}
# A chance constraint's target reliability index β_t from 0 to MAX_RELIABILITY_INDEX, one rule
# for both forms: a probability P = Φ(−β_t) from Φ(−8) ≈ 6.2e-16 to 0.5.
MAX_RELIABILITY_INDEX = 8.0
CHANCE_RANGES = {
    "index": Range(0.0, MAX_RELIABILITY_INDEX),
    "probability": Range(0.5 * math.erfc(MAX_RELIABILITY_INDEX / math.sqrt(2.0)), 0.5),
}


def _chance(key, value):
    """A chance constraint's (kind, quantity, number) from its key, or None for another key."""
    for prefix, kind in CHANCE_PREFIXES.items():
        if key.startswith(prefix):
            q = key[len(prefix) :]
            if q not in (*QUANTITIES, "life"):
                raise SpecError(
                    f"unknown key constraints.{key}; allowed: {prefix}<q> with <q> life, static_capacity "
                    "or a quantity with a max_<q> / min_<q> constraint"
                )
            number = _number(
                {"constraints": {key: value}}, "constraints", key, rule=CHANCE_RANGES[kind]
            )
            return kind, "life_km" if q == "life" else q, number
    return None


def _chance_constraints(chances, names, uncertainty):
    """(key, kind, requirement names) of each chance constraint; needs [uncertainty]."""
    out = []
    for key, (kind, q) in chances.items():
        if not uncertainty:
            raise SpecError(
                f"constraints.{key} needs uncertain numbers: give at least one [uncertainty] entry"
            )
        targets = [n for n, k, _ in names if k == q]
        targets = {"life_km": ["life"], "static_capacity": ["static_capacity"]}.get(q, targets)
        if not targets:
            raise SpecError(
                f"constraints.{key}: {q} has no constraint to hold with a probability; "
                f"give constraints.max_{q} or constraints.min_{q}"
            )
        out.append((key, kind, tuple(targets)))
    return tuple(out)


def _constraints(table):
    given = dict(table["constraints"])
    names, values, chances = [], {}, {}
    for key, value in given.items():
        chance = _chance(key, value)
        if chance is not None:
            chances[key] = chance[:2]
            values[key] = chance[2]
            continue
        prefix, q = _quantity_key("constraints", key, (("max_", ""), ("min_", "")))
        values[key] = _number(
            {"constraints": {key: value}}, "constraints", key, rule=CONSTRAINT_LIMIT
        )
        names.append((key, q, prefix[:-1]))
    order = {q: i for i, q in enumerate(QUANTITIES)}
    names.sort(key=lambda c: (order[c[1]], c[2]))
    for key, q, sense in names:
        if sense == "min" and f"max_{q}" in values and values[f"max_{q}"] < values[key]:
            raise SpecError(
                f"constraints.min_{q} = {values[key]:g} is above constraints.max_{q} = "
                f"{values[f'max_{q}']:g}: no design can meet both"
            )
    return tuple(names), values, chances


def _check_force_model(structure, values):
    """SpecError where the objective or a constraint takes a GAF or force quantity (each judged
    at loads.gaf_torque) and solver.n_theta is below the minimum of the orders (they would
    not be told apart), or loads.gaf_torque is 0: the force model's (tripodjax.forces) roller loads over
    T/3R are then 0/0 and its forces 0, Lee's GAF (friction.gaf_model "stroke" or "printed")
    0 whatever the design."""
    from tripodjax.kinematics import MIN_N_THETA_ORDERS

    used = [q for q in (*FORCE_QUANTITIES, *GAF_QUANTITIES) if q in structure.needs]
    if used and structure.n_theta < MIN_N_THETA_ORDERS:
        first = next(q for q in (*GAF_QUANTITIES, *FORCE_QUANTITIES) if q in used)
        raise SpecError(
            f"solver.n_theta = {structure.n_theta} is not allowed with {first} in the "
            f"objective or the constraints: at least {MIN_N_THETA_ORDERS} (the fewest that tell "
            "the orders 3, 6 and 9 apart)"
        )
    # A term of weight 0 (the default spec's GAF term switched off) judges nothing at the torque.
    constrained = {q for _, q, _ in structure.constraints}
    weights = values.get("objective", {})
    judged = [q for q in used if q in constrained or weights.get(f"w_{q}", 1.0) != 0]
    if judged and not values["loads"]["gaf_torque"] > 0:
        forces = judged[0] in FORCE_QUANTITIES or structure.gaf_model == "forces"
        model = "the force model's " if forces else ""
        zero = "its forces 0, the roller loads over T/3R 0/0" if forces else "the GAF is 0"
        raise SpecError(
            f"loads.gaf_torque = {values['loads']['gaf_torque']:g} is not allowed with "
            f"{model}{judged[0]} in the objective or the constraints: > 0 N·m (the torque at "
            f"which it is judged; at 0 {zero} whatever the design)"
        )


def _no_halfshaft(free, terms, constraints):
    """SpecError when a spec without a vehicle frees a [shaft] entry or uses the halfshaft's
    quantities: its checks need the vehicle's load cycles."""
    used = [f"bounds.{k}" for k in free if shaft_variable(k)]
    used += [f"objective.w_{q}" for q in terms if q in HALFSHAFT_QUANTITIES]
    used += [f"constraints.{n}" for n, q, _ in constraints if q in HALFSHAFT_QUANTITIES]
    if used:
        raise SpecError(
            f"{used[0]} needs the spec's [vehicle]: the halfshaft's checks take its load cycles "
            "(gears and driving modes); this spec gives loads.M_max and the load spectrum instead"
        )


def _shaft_bound(key, names):
    """SpecError unless a [bounds] key names a [shaft] entry that can be free."""
    entry = shaft_variable(key)
    if entry is None or entry[0] not in SHAFT_VARIABLES or entry[1] not in names:
        raise SpecError(
            f'unknown key bounds.{key}; allowed: {", ".join(VARIABLES)}, or "shaft.<list>[<section>]" '
            f"with <list> one of {', '.join(SHAFT_VARIABLES)} and <section> one of shaft.names "
            f"({', '.join(names)})"
        )


def _shaft_corners(bounds, lists, names):
    """Refuse bounds under which a [shaft] section can leave its domain (Øi < Øe, h + t within
    the wall): each section with a free entry is checked at its thinnest-walled corner."""
    from tripodjax import shaft

    for i, name in enumerate(names):
        keys = {k: shaft_variable_name(k, name) for k in SECTION_LISTS}
        if not any(v in bounds for v in keys.values()):
            continue
        corner, where = [], []
        for k, variable in keys.items():
            side = 0 if k == "outer_diameter_mm" else 1  # the smallest Øe, the largest others
            if variable in bounds:
                corner.append(bounds[variable][side])
                where.append(f'bounds."{variable}"[{side}]')
            else:
                corner.append(float(lists[k][i]))
                where.append(f"shaft.{k}[{i}]")
        try:
            shaft.check_section_fits(*corner, names=tuple(where))
        except ValueError as error:
            at = ", ".join(f"{w} = {c:g}" for w, c in zip(where, corner, strict=True))
            raise SpecError(
                f"bounds of shaft section {name!r}: {error} at the corner of its bounds with the "
                f"thinnest wall ({at}); narrow the bounds"
            ) from None


def _bounds(table, fixed, shaft_lists, shaft_names):
    given = table["bounds"]
    bounds = {}
    for key, value in given.items():
        if key == "shaft" and isinstance(value, dict):
            raise SpecError(
                "bounds.shaft is a table; give each [shaft] entry as one quoted key, e.g. "
                '"shaft.outer_diameter_mm[C-C]" = [18.5, 30.0]'
            )
        if key not in VARIABLES:
            _shaft_bound(key, shaft_names)
        where = f'bounds."{key}"' if shaft_variable(key) else f"bounds.{key}"  # as TOML spells it
        if isinstance(value, str) and value == "fixed":
            continue
        if not isinstance(value, list) or len(value) != 2:
            raise SpecError(f'{where} = {value!r} must be a pair [lo, hi] or "fixed"')
        rule = variable_range(key)  # the variable's own number's range
        lo, hi = _numbers({"bounds": {key: value}}, "bounds", key, rule, where=where)
        if not lo < hi:
            raise SpecError(f"{where} = {value!r} is not allowed: [lo, hi] with lo < hi")
        bounds[key] = (lo, hi)
    _shaft_corners(bounds, shaft_lists, shaft_names)
    # R/l ≤ 0.2 at every corner of the box (and at the fixed values).
    r_hi = bounds["R"][1] if "R" in bounds else fixed["R"]
    l_lo = bounds["l"][0] if "l" in bounds else fixed["l"]
    names = {"R": "bounds.R[1]" if "R" in bounds else "design.R"}
    names["l"] = "bounds.l[0]" if "l" in bounds else "layout.l"
    try:  # the one layout-domain rule of the package
        check_layout_domain(R=r_hi, l=l_lo, names=names)
    except ValueError as error:
        raise SpecError(f"{error} (at the corner of the bounds with the largest R/l)") from None
    return bounds


def _spectrum(table):
    """The explicit load spectrum: the [life] lists or life.spectrum_file, checked."""
    life = table["life"]
    given = [k for k in LIFE_LISTS if k in life]
    if "spectrum_file" in life:
        path = life["spectrum_file"]
        if not isinstance(path, str):
            raise SpecError(f"life.spectrum_file = {path!r} must be a path (a string)")
        try:
            spectrum = read_spectrum_rows(path)
        except ValueError as error:
            raise SpecError(f"life.spectrum_file: {error}") from None
        for key, column in zip(LIFE_LISTS[:3], SPECTRUM_COLUMNS, strict=True):
            for i, value in enumerate(spectrum[key]):  # the [life] list's range, level by level
                where = f"life.spectrum_file: spectrum file {path} level {i + 1}: {column}"
                _in_range(where, value, RANGES[f"life.{key}"])
        where = "life.spectrum_file"
    else:
        missing = [k for k in LIFE_LISTS if k not in life]
        if missing:
            raise SpecError(
                f"life.{given[0]} is given without life.{missing[0]}: an explicit spectrum needs "
                "torque, speed, vehicle_speed and share"
            )
        spectrum = {k: _numbers(table, "life", k) for k in LIFE_LISTS}
        lengths = {k: len(x) for k, x in spectrum.items()}
        if len(set(lengths.values())) != 1:
            raise SpecError(
                f"life lists have lengths {lengths}; torque, speed, vehicle_speed and share must have one length"
            )
        _shares("life.share", spectrum["share"])
        where = "life spectrum"
    if len(spectrum["torque"]) > MAX_LIST_LENGTH:
        raise SpecError(
            f"{where} has {len(spectrum['torque'])} levels; at most {MAX_LIST_LENGTH} allowed"
        )
    cases = list(zip(spectrum["share"], spectrum["speed"], spectrum["torque"], strict=True))
    if not any(a > 0 and n > 0 and t > 0 for a, n, t in cases):
        raise SpecError(
            f"{where} has no case with torque, speed and share > 0: the life would be infinite"
        )
    if not any(
        a > 0 and v > 0 for a, v in zip(spectrum["share"], spectrum["vehicle_speed"], strict=True)
    ):
        raise SpecError(
            f"{where} has vehicle speed 0 in every case with a share > 0: the life in km would be 0"
        )
    return spectrum


def _vehicle(table):
    """The [vehicle] section as spec-number sections, the mode names and the axle."""
    gears, modes = table["vehicle"]["gears"], table["vehicle"]["modes"]
    axle = _string(table, "vehicle", "axle", AXLES)
    numbers = {}
    for key in VEHICLE_NUMBERS:
        numbers[key] = _number(table, "vehicle", key)
    for key in ("engine_torque_Nm", "engine_speed_rpm"):
        entries = _numbers(table, "vehicle", key)
        if len(entries) != len(ENGINE_CONDITIONS):
            raise SpecError(
                f"vehicle.{key} has {len(entries)} entries; allowed: 4, at mean torque, maximum "
                "torque, maximum power and the engine brake"
            )
        numbers[key] = np.asarray(entries)
    ratios = _numbers(table, "vehicle.gears", "ratios")
    if len(ratios) > MAX_GEARS:
        raise SpecError(
            f"vehicle.gears.ratios has {len(ratios)} gears; at most {MAX_GEARS} allowed"
        )
    reverse = _number({"vehicle.gears": gears}, "vehicle.gears", "reverse")
    names = _names(modes.get("names"), "vehicle.modes.names")
    weight = _numbers(table, "vehicle.modes", "weight")
    if len(weight) != len(names):
        raise SpecError(
            f"vehicle.modes.weight has {len(weight)} entries and names {len(names)}; they must agree"
        )
    _shares("vehicle.modes.weight", weight)
    use = {}
    for condition in ENGINE_CONDITIONS:
        key = f"use_{condition}_pct"
        where = f"vehicle.modes.{key}"
        value = modes.get(key)
        rows = value if isinstance(value, list) and value and isinstance(value[0], list) else None
        if rows is None:
            rows = [_numbers(table, "vehicle.modes", key)] * len(names)
        else:
            if len(rows) != len(names):
                raise SpecError(
                    f"{where} has {len(rows)} rows and vehicle.modes.names {len(names)}; one row per mode"
                )
            rows = [
                _numbers(
                    {"vehicle": {"modes": {f"{key}[{i}]": row}}},
                    "vehicle.modes",
                    f"{key}[{i}]",
                    RANGES[f"vehicle.modes.{key}"],
                )
                for i, row in enumerate(rows)
            ]
        for row in rows:
            if len(row) != len(ratios) + 1:
                raise SpecError(
                    f"{where} has {len(row)} entries; allowed: {len(ratios) + 1}, one per gear of "
                    "vehicle.gears.ratios and reverse last"
                )
        use[key] = np.asarray(rows).ravel()  # 1-D leaves: mode-major (mode, gear)
    total = sum(use.values()).reshape(len(names), -1)
    for i, name in enumerate(names):
        if np.sum(total[i]) > 100.0 + 1e-9:
            raise SpecError(
                f"vehicle.modes use_*_pct of mode {name!r} sum to {np.sum(total[i]):g} %; at most 100 % "
                "of its revolutions"
            )
    share = numbers["rear_torque_share"] if axle == "rear" else 1.0 - numbers["rear_torque_share"]
    if share == 0:
        raise SpecError(
            f"vehicle.axle = {_toml(axle)} with vehicle.rear_torque_share = "
            f"{numbers['rear_torque_share']:g}: that axle's shafts carry no torque"
        )
    if not np.any(total * np.asarray(weight)[:, None] > 0) or not any(
        t > 0 for t in numbers["engine_torque_Nm"]
    ):
        raise SpecError(
            "vehicle.modes use_*_pct (weighted by vehicle.modes.weight) or vehicle.engine_torque_Nm "
            "are all 0: no load cycle, the life would be infinite"
        )
    sections = {
        "vehicle": numbers,
        "vehicle.gears": {"ratios": np.asarray(ratios), "reverse": reverse},
        "vehicle.modes": {"weight": np.asarray(weight), **use},
    }
    return sections, tuple(names), axle


def _sources(given, base):
    """One source for M_max and one for the spectrum; a file's spectrum_file made absolute."""
    loads, life = given.get("loads"), given.get("life")
    loads, life = (x if isinstance(x, dict) else {} for x in (loads, life))
    lists = [f"life.{k}" for k in LIFE_LISTS if k in life]
    if "spectrum_file" in life:
        lists.insert(0, "life.spectrum_file")
    if "vehicle" in given and "M_max" in loads:
        raise SpecError(
            "loads.M_max and [vehicle] both give M_max; give one (without loads.M_max it is the "
            "vehicle's adhesion-limited torque)"
        )
    if "vehicle" in given and lists:
        raise SpecError(f"{lists[0]} and [vehicle] both give the load spectrum; give one")
    if "spectrum_file" in life and len(lists) > 1:
        raise SpecError(f"life.spectrum_file and {lists[1]} both give the load spectrum; give one")
    path = life.get("spectrum_file")
    if isinstance(path, str) and base is not None and not os.path.isabs(path):
        life["spectrum_file"] = os.path.join(base, path)
    return given


def _check(table):
    """Check a merged table; returns the Spec."""
    v = {}
    fixed = {
        key: _number(table, section, key)
        for key, (section, *_) in VARIABLES.items()
        if section != "friction"
    }
    v["design"] = {"R": fixed["R"], "d_roller": fixed["d_roller"]}
    v["layout"] = {"l": fixed["l"], "gamma0": math.radians(fixed["gamma0_deg"])}
    v["loads"] = {
        "shock_factor": _number(table, "loads", "shock_factor"),
        "gaf_torque": _number(table, "loads", "gaf_torque"),
    }
    m_max_from_vehicle = "M_max" not in table["loads"]
    if not m_max_from_vehicle:
        v["loads"]["M_max"] = _number(table, "loads", "M_max")
    hertz = {k: _number(table, "hertz", k) for k in ("P_s", "P_d", "P_sd", "C_s")}
    hertz["conformity"] = fixed["conformity"]
    n_rollers = _count(table, "hertz.n_rollers")
    v["hertz"] = hertz
    life = {"required_km": _number(table, "life", "required_km")}
    angle_law = _string(table, "life", "angle_law", ANGLE_LAWS)
    spectrum_from_vehicle = not any(k in table["life"] for k in (*LIFE_LISTS, "spectrum_file"))
    if not spectrum_from_vehicle:
        life.update({k: np.asarray(x) for k, x in _spectrum(table).items()})
    angles, shares, names = _conditions(table, "life")
    life["condition_angle"], life["condition_share"] = angles, shares
    v["life"] = life
    modes, axle = (), "rear"
    if m_max_from_vehicle or spectrum_from_vehicle:
        vehicle, modes, axle = _vehicle(table)
        v.update(vehicle)
    grease = _string(table, "friction", "grease", tuple(GREASE_MU_SLP))
    if "mu_slp" in table["friction"]:
        mu_slp = _number(table, "friction", "mu_slp")
    else:
        mu_slp = GREASE_MU_SLP[grease]
    v["friction"] = {"lam": _number(table, "friction", "lam"), "mu_slp": mu_slp}
    fixed.update(v["friction"])
    gaf_model = _string(table, "friction", "gaf_model", GAF_MODELS)
    v["forces"] = _forces(table)
    v["shaft"], shaft_sections, shaft_reading = _shaft(table)
    v["outboard"], outboard_balls, outboard_reading, outboard_conditions = _outboard(table)
    terms, v["objective"] = _objective(table)
    constraints, v["constraints"], chances = _constraints(table)
    max_life = v["constraints"].get("max_life_km")
    if max_life is not None and max_life < v["life"]["required_km"]:
        raise SpecError(
            f"constraints.max_life_km = {max_life:g} is below life.required_km = "
            f"{v['life']['required_km']:g}: no design can meet both"
        )
    bounds = _bounds(table, fixed, v["shaft"], shaft_sections)
    v["bounds"] = {
        k: (math.radians(lo), math.radians(hi)) if k == "gamma0_deg" else (lo, hi)
        for k, (lo, hi) in bounds.items()
    }
    v["bounds"] = {k: np.asarray(pair) for k, pair in v["bounds"].items()}
    sizes = {k: _integer(table, k) for k in INTEGER_LIMITS}
    work = math.prod(sizes[k] for k in WORK_KEYS)
    if work > MAX_WORK:
        product = " × ".join(f"solver.{k}" for k in WORK_KEYS)
        numbers = " × ".join(str(sizes[k]) for k in WORK_KEYS)
        raise SpecError(
            f"{product} = {numbers} = {work:.3g} is not allowed: at most {MAX_WORK:.3g} "
            "(the work of one solve); lower one of them"
        )
    free = tuple(k for k in VARIABLES if k in bounds) + tuple(
        shaft_variable_name(key, name)
        for name in shaft_sections
        for key in SHAFT_VARIABLES
        if shaft_variable_name(key, name) in bounds
    )
    if not (m_max_from_vehicle or spectrum_from_vehicle):
        _no_halfshaft(free, terms, constraints)
    inputs, v["uncertainty"] = _uncertainty(table, v, free)
    # The iteration counts are numbers (the solve's loop bounds), not structure: a new count
    # reuses the compiled solve, whose history arrays hold MAX_OUTER_ITERATIONS + 1 entries.
    v["solver"] = {
        "tolerance": _number(table, "solver", "tolerance"),
        **{k: np.asarray(float(sizes.pop(k))) for k in ("max_outer", "inner_steps")},
    }
    structure = Structure(
        free=free,
        objective=terms,
        constraints=constraints,
        condition_names=names,
        n_rollers=n_rollers,
        angle_law=angle_law,
        vehicle_modes=modes,
        axle=axle,
        m_max_from_vehicle=m_max_from_vehicle,
        spectrum_from_vehicle=spectrum_from_vehicle,
        gaf_model=gaf_model,
        fidelity=_string(table, "solver", "fidelity", FIDELITIES),
        **sizes,
        uncertainty=inputs,
        chance=_chance_constraints(chances, constraints, inputs),
        shaft_sections=shaft_sections,
        shaft_reading=shaft_reading,
        outboard_balls=outboard_balls,
        outboard_reading=outboard_reading,
        outboard_conditions=outboard_conditions,
    )
    _check_force_model(structure, v)
    if not structure.free:
        raise SpecError(
            f"bounds gives no free variable; give an interval for at least one of {', '.join(VARIABLES)} "
            'or a [shaft] entry ("shaft.<list>[<section>]")'
        )
    values = jax.tree_util.tree_map(lambda x: np.asarray(x, np.float64), v)
    return Spec(structure=structure, values=values, resolved=table)


def _conditions(table, section):
    """A [<section>.conditions] table: (angles [rad], shares, names), checked."""
    where = f"{section}.conditions"
    angles = _numbers(table, where, "angle_deg")
    shares = _numbers(table, where, "share")
    _shares(f"{where}.share", shares)
    names = table[section]["conditions"].get(
        "names", [f"condition {i + 1}" for i in range(len(angles))]
    )
    names = _names(names, f"{where}.names", "a list of strings")
    if not len(angles) == len(shares) == len(names):
        raise SpecError(
            f"{where} lists have lengths angle_deg {len(angles)}, share {len(shares)}, "
            f"names {len(names)}; they must have one length"
        )
    return np.radians(np.asarray(angles)), np.asarray(shares), tuple(names)


def _names(names, where, kind="a non-empty list of strings"):
    """A list of names (driving modes, conditions, sections): a non-empty list of distinct,
    non-empty, printable strings (the report's tables are keyed by them and its one-line
    summaries, HTML and workbook show them); else one SpecError naming the entry."""
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise SpecError(f"{where} = {names!r} must be {kind}")
    for i, name in enumerate(names):
        problem = label_problem(f"{where}[{i}]", name)  # the rule of --revision too
        if problem:
            raise SpecError(problem)
    if len(set(names)) != len(names):
        raise SpecError(f"{where} = {names!r} must not repeat a name")
    return names


# [shaft] lists, one entry per section (their ranges in RANGES); a section's dimensions in the
# order of tripodjax.shaft.check_section_fits (Øe, h, t, Øi).
SHAFT_LISTS = (*SHAFT_VARIABLES, "safety")
SECTION_LISTS = (
    "outer_diameter_mm",
    "hardened_depth_mm",
    "transition_depth_mm",
    "inner_diameter_mm",
)


def _shaft(table):
    """The [shaft] section: (numbers, section names, reading), each relation checked once, by
    tripodjax.shaft's own rules (the message names the keys)."""
    from tripodjax import shaft

    names = _names(table["shaft"]["names"], "shaft.names")
    lists = {key: _numbers(table, "shaft", key) for key in SHAFT_LISTS}
    for key, entries in lists.items():
        if len(entries) != len(names):
            raise SpecError(
                f"shaft.{key} has {len(entries)} entries and shaft.names {len(names)}; one per "
                "section"
            )
    keys = ("core_uts_MPa", "surface_uts_MPa", "depth_drop", "fatigue_ratio", "allowed_damage")
    numbers = {key: _number(table, "shaft", key) for key in keys}
    reading = _string(table, "shaft", "reading", shaft.READINGS)
    try:
        shaft.check_material_strength(
            *(numbers[k] for k in keys[:3]), names=tuple(f"shaft.{k}" for k in keys[:3])
        )
    except ValueError as error:
        raise SpecError(str(error)) from None
    for i, name in enumerate(names):
        try:
            shaft.check_section_fits(
                *(lists[k][i] for k in SECTION_LISTS),
                names=tuple(f"shaft.{k}[{i}]" for k in SECTION_LISTS),
            )
        except ValueError as error:
            raise SpecError(f"shaft section {name!r}: {error}") from None
    return {**{k: np.asarray(x) for k, x in lists.items()}, **numbers}, tuple(names), reading


def _outboard(table):
    """The [outboard] section: (numbers, ball count, reading, condition names)."""
    from tripodjax import outboard

    n_balls = _count(table, "outboard.n_balls")
    keys = ("ball_diameter_mm", "pcr_mm", "P_s", "P_d", "P_sd", "C_s")
    numbers = {key: _number(table, "outboard", key) for key in keys}
    try:
        keys = ("outboard.ball_diameter_mm", "outboard.pcr_mm", "outboard.n_balls")
        outboard.check_balls_fit(numbers["ball_diameter_mm"], numbers["pcr_mm"], n_balls, keys)
    except ValueError as error:
        raise SpecError(str(error)) from None
    for key in ("conformity", "longitudinal_conformity", "tolerance"):
        numbers[key] = _number(table, "outboard", key)
    pressure = _number(table, "outboard", "pressure_angle_deg")
    oblique = _number(table, "outboard", "oblique_angle_deg")
    numbers["pressure_angle"], numbers["oblique_angle"] = map(math.radians, (pressure, oblique))
    numbers["condition_angle"], numbers["condition_share"], names = _conditions(table, "outboard")
    reading = _string(table, "outboard", "reading", outboard.READINGS)
    return numbers, n_balls, reading, names


def _forces(table):
    """The [forces] section (tripodjax.forces.ForceInputs' numbers), in internal units."""
    plunge = _number(table, "forces", "plunge_speed_mm_s")
    if plunge == 0:
        raise SpecError(
            "forces.plunge_speed_mm_s = 0.0 is not allowed: a finite speed, not 0 (> 0 into the "
            "pot, < 0 out: the LTS opposes a plunge)"
        )
    speed = _number(table, "forces", "speed_rpm")
    if speed == 0:
        raise SpecError(
            "forces.speed_rpm = 0.0 is not allowed: a finite speed, not 0 (the running case needs "
            "a direction; its size sets the friction power alone)"
        )
    angle = _number(table, "forces", "contact_angle_deg")
    return {
        "speed_rpm": speed,
        "mu_trunnion": _number(table, "forces", "mu_trunnion"),
        "contact_angle": math.radians(angle),
        "plunge_speed_mm_s": plunge,
        "lts_speed_rpm": _number(table, "forces", "lts_speed_rpm"),
    }


def _uncertainty(table, values, free):
    """The [uncertainty] section: (inputs, their numbers); see tripodjax.optimize.uncertainty."""
    from tripodjax.optimize import uncertainty

    section = table["uncertainty"]
    if not isinstance(section, dict):
        raise SpecError("uncertainty must be a table")
    numbers = jax.tree_util.tree_map(np.asarray, values)
    numbers["bounds"] = {k: np.asarray(b) for k, b in values["bounds"].items()}
    return uncertainty.parse(section, numbers, VARIABLES, free, number_domain)


def number_domain(section, key, variable):
    """The allowed values of spec number ``values[section][key]``, as the spec checks them: its
    Range in ``RANGES`` (a design variable's too); None where none bounds it. An
    `uncertainty.Domain`, in the model's units (γ0 and other angles in rad)."""
    from tripodjax.optimize.uncertainty import Domain

    if variable is not None:
        name, degrees = variable, variable == "gamma0_deg"
        rule = variable_range(variable)
    else:
        file_key, units = _SPEC_UNITS.get((section, key), (key, None))
        name, degrees = f"{section}.{file_key}", units == "deg"
        rule = RANGES.get(name)
    if rule is None or (rule.low is None and rule.high is None):
        return None
    scale = math.pi / 180.0 if degrees else 1.0
    return Domain(
        low=None if rule.low is None else rule.low * scale,
        high=None if rule.high is None else rule.high * scale,
        low_open=rule.low_open,
        high_open=rule.high_open,
        name=name,
        allowed=rule.text(),
    )


def parse_spec(text: str, source: str = "spec", base: str | os.PathLike | None = None) -> Spec:
    """Check a TOML text (merged over the default: a file need only hold what it changes).

    ``base``: the folder that a relative ``life.spectrum_file`` is read from (the
    spec file's folder in [`load_spec`][tripodjax.optimize.load_spec]; the current
    directory when None). Raises ``TypeError`` unless ``text`` is a ``str`` (bytes: decode
    them, or use [`load_spec`][tripodjax.optimize.load_spec] on the file) and ``source`` a
    ``str``.
    """
    if not isinstance(text, str):
        hint = " (decode bytes first: text.decode('utf-8'))" if isinstance(text, bytes) else ""
        raise TypeError(
            f"text = {text!r:.60} is not allowed; allowed: the TOML text as a str{hint} "
            f"(got a {type(text).__name__})"
        )
    if not isinstance(source, str):
        raise TypeError(f"source = {source!r:.60} is not allowed; allowed: a str (a file name)")
    if text.startswith("\ufeff"):  # a UTF-8 byte-order mark, as Windows editors write
        text = text[1:]
    try:
        given = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise SpecError(f"{source} is not valid TOML: {error}") from None
    except ValueError as error:  # e.g. an integer of more than 4300 digits
        raise SpecError(f"{source} is not valid TOML: {error}") from None
    return _check(_merge(tomllib.loads(DEFAULT_SPEC_TOML), _given(given, base)))


def load_spec(path: str | os.PathLike | None = None) -> Spec:
    """The specification in the TOML file at ``path``, or the embedded default when None."""
    if path is None:
        return parse_spec(DEFAULT_SPEC_TOML, "the default spec")
    if not isinstance(path, (str, os.PathLike)):  # an int would be read as a file descriptor
        raise TypeError(
            f"path = {path!r:.60} is not allowed; allowed: a file path (str or os.PathLike) or "
            f"None for the default spec (got a {type(path).__name__})"
        )
    try:
        with open(path, "rb") as f:
            data = f.read()
    except IsADirectoryError:
        raise SpecError(f"spec file {path} is a directory, not a TOML file") from None
    except OSError as error:
        raise SpecError(f"cannot read spec file {path}: {error.strerror or error}") from None
    if b"\x00" in data:
        raise SpecError(f"spec file {path} is a binary file, not a TOML text")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise SpecError(
            f"spec file {path} is not UTF-8 text (byte {error.start}: {data[error.start : error.start + 1]!r}); "
            "save it as UTF-8"
        ) from None
    return parse_spec(text, str(path), os.path.dirname(os.path.abspath(path)))
