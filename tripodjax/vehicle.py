"""From the customer's vehicle to the joint's load cycles (the company workbook, seed §4.3).

The workbook's sheets "Vehicle performances" and "Loadcycles Definition" (seed
figs. 4.3.3, 4.3.4, with the gear-use tables of fig. 4.3.11), for the halfshaft of
one axle (``axle="rear"`` or ``"front"``). Per gear g (forward gears, then
reverse last) and engine condition c (mean torque, maximum torque, maximum power,
engine brake; `ENGINE_CONDITIONS`):

- shaft speed n = n_engine,c / i_g [rpm]; vehicle speed V = n · 2π r · 60/1000 [km/h];
- engine-side torque T_c · k_s · i_g [N·m] (the sheet's "Engine Output", k_s the
  shock factor), of which one shaft of the axle takes at most the axle's torque
  share × (1 + λ)/2, λ the differential locking (0 open: half; 1 locked, the
  workbook's 100 %: all);
- wheel load: static m g s_axle / 2 plus the load transfer of acceleration
  ΔF_g = min(c_lt · i_g, μ m g h / (2 L)) per wheel (to the rear axle, from the
  front; the other way in reverse, ΔF_R an input);
- adhesion limit μ · F_wheel · r · k_s [N·m]; working torque the smaller of the
  shaft's engine-side torque and the adhesion limit;
- revolutions: relative use u[m, g, c] × mode weight w_m × N, with
  N = required mileage / (2π r).

The load-transfer rule is not printed in the seed; the one above reproduces the
sheet's 702, 534, 362, 282, 225 N (1st–5th) and the 189 N that its 6th gear
implies, within 0.3 %, with c_lt = 67.45 N (fitted to the sheet: the transfer is
proportional to the overall ratio, 1st gear capped at the adhesion limit of the
whole vehicle). The reverse transfer (627 N in the sheet) follows no such rule
and is an input.

The life spectrum ([`load_spectrum`][tripodjax.vehicle.load_spectrum]) reads the
relative uses as shares of the revolutions of the whole mileage, takes the working
torques without the shock factor (the life is a mean, the shock a peak), and gives
the revolutions that no case claims (1 − Σ share, e.g. cruising and coasting) to a
case of zero torque at the revolution-weighted mean speed of the others; time
shares follow as a_i ∝ revolutions_i / n_i. The life in km is then the
revolutions the cycle lasts times 2π r (independent of the speeds). With the
workbook's vehicle and M_d = 1507 N·m it is 240 311 km at 0° (the sheet:
244 574 km, −1.7 %). The sheet's hours (2148 h) come from 4.2.1 with the
revolution shares taken as time shares (that gives 2140 h, −0.4 %), which its own
4.2.3 does not support; here the hours are km / V_m with V_m the time-weighted
mean speed (4.2.3): about 2500 h, V_m about 96 km/h (the sheet: 113.9 km/h).

Units at the API: kg, m, N, N·m, rpm, km/h, km. Every number is a pytree leaf
(``jit``/``vmap``/``grad`` through all of them); the number of gears and modes
is the arrays' shape.
"""

import dataclasses
import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from tripodjax._checks import (
    Domain,
    check,
    check_broadcast,
    check_choice,
    check_domains,
    check_flag,
    check_range,
    check_real,
    check_shares,
    checked_pytree_dataclass,
    outside_domains,
    outside_shares,
)
from tripodjax._compile import latency_bound_at_top_level
from tripodjax._pytree import pytree_dataclass
from tripodjax.life import LoadSpectrum

__all__ = [
    "AXLES",
    "ENGINE_CONDITIONS",
    "GRAVITY",
    "DrivingModes",
    "LoadCycles",
    "Vehicle",
    "load_cycles",
    "load_spectrum",
]

ENGINE_CONDITIONS = ("T_mean", "T_max", "P_max", "brake")
AXLES = ("rear", "front")
GRAVITY = 9.81  # m/s², as the workbook (3087 N = 629.66 kg · 9.81 / 2)


def _shape(value):
    return None if isinstance(value, jax.core.Tracer) else np.shape(value)


_POSITIVE = Domain(0.0, low_open=True)
_SHARE = Domain(0.0, 1.0)
DOMAINS = {
    **dict.fromkeys(
        (
            "mass",
            "wheelbase",
            "tyre_radius",
            "adhesion",
            "shock_factor",
            "engine_speed",
            "ratios",
            "reverse_ratio",
            "required_km",
        ),
        _POSITIVE,
    ),
    **dict.fromkeys(("front_share", "rear_torque_share", "differential_locking"), _SHARE),
    "cg_height": Domain(0.0, unit=" m"),
    "engine_torque": Domain(0.0, unit=" N·m"),
    "load_transfer_per_ratio": Domain(0.0, unit=" N"),
    "reverse_load_transfer": Domain(0.0, unit=" N"),
    "use": _SHARE,
}
"""Each input's domain: one rule for the check of a concrete value and the flag of a traced one
(NaN load cycles)."""
_ARRAYS = {"engine_torque": (4,), "engine_speed": (4,), "ratios": None}  # the rest: one number


@checked_pytree_dataclass
class Vehicle:
    """The customer's vehicle, engine and transmission (seed fig. 4.3.1).

    Attributes:
        mass: gross vehicle mass [kg], > 0.
        front_share: share of the mass on the front axle [–], in [0, 1].
        wheelbase: [m], > 0.
        cg_height: centre-of-gravity height [m], ≥ 0.
        tyre_radius: static loaded tyre radius [m], > 0.
        adhesion: tyre–road friction coefficient μ [–], > 0.
        rear_torque_share: share of the engine torque to the rear axle [–], in
            [0, 1] (1 rear-wheel drive, 0 front-wheel drive, between all-wheel drive).
        engine_torque: engine torque at mean torque, at maximum torque, at maximum
            power and the engine brake torque [N·m], shape (4,), ≥ 0.
        engine_speed: their engine speeds [rpm], shape (4,), > 0.
        shock_factor: k_s [–], > 0 (the workbook's 1.1).
        ratios: overall ratios (gear × final drive) of the forward gears [–],
            shape (G,) with 1 ≤ G ≤ 11, > 0.
        reverse_ratio: overall ratio of reverse [–], > 0.
        load_transfer_per_ratio: c_lt [N]: wheel-load transfer per unit overall
            ratio, ≥ 0 (67.45 N reproduces the workbook).
        reverse_load_transfer: wheel-load transfer in reverse [N], ≥ 0.
        differential_locking: λ [–] in [0, 1]: one shaft takes at most (1 + λ)/2 of
            its axle's torque (1, the workbook's 100 %, by default).

    One vehicle: every field but ``engine_torque``, ``engine_speed`` and ``ratios``
    one number (shape ()); ``jax.vmap`` over several. All finite; checked when built
    from concrete values (traced ones outside their domain give NaN load cycles).
    """

    mass: ArrayLike
    front_share: ArrayLike
    wheelbase: ArrayLike
    cg_height: ArrayLike
    tyre_radius: ArrayLike
    adhesion: ArrayLike
    rear_torque_share: ArrayLike
    engine_torque: ArrayLike
    engine_speed: ArrayLike
    shock_factor: ArrayLike
    ratios: ArrayLike
    reverse_ratio: ArrayLike
    load_transfer_per_ratio: ArrayLike
    reverse_load_transfer: ArrayLike
    differential_locking: ArrayLike = 1.0

    def __post_init__(self) -> None:
        fields = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        check_domains(DOMAINS, **{f"Vehicle.{k}": v for k, v in fields.items()})
        for k, value in fields.items():
            shape = _shape(value)
            if k not in _ARRAYS and shape not in (None, ()):
                raise ValueError(
                    f"Vehicle.{k} has shape {shape}; allowed: one number (shape ()) for one "
                    "vehicle; jax.vmap over several"
                )
        for k in ("engine_torque", "engine_speed"):
            shape = _shape(getattr(self, k))
            if shape is not None and shape != (len(ENGINE_CONDITIONS),):
                raise ValueError(
                    f"Vehicle.{k} has shape {shape}; allowed: shape (4,), one value per "
                    f"engine condition {', '.join(ENGINE_CONDITIONS)}"
                )
        shape = _shape(self.ratios)
        if shape is not None and not (len(shape) == 1 and 1 <= shape[0] <= 11):
            raise ValueError(
                f"Vehicle.ratios has shape {shape}; allowed: a 1-D array of 1 to 11 forward gears"
            )


@checked_pytree_dataclass
class DrivingModes:
    """How the vehicle is driven: modes (sport, intercity, city or the user's own).

    Attributes:
        weight: share of the mileage in each mode [–], shape (M,), ≥ 0, summing to 1.
        use: relative use, as a share of the revolutions in that mode, of each gear
            (forward gears, then reverse) and engine condition
            (`ENGINE_CONDITIONS`) [–], shape (M, G + 1, 4), each in [0, 1] (seed
            fig. 4.3.11). Their sum over gears and conditions may be below 1 (the
            remaining revolutions do no damage, e.g. coasting).
    """

    weight: ArrayLike
    use: ArrayLike

    def __post_init__(self) -> None:
        check_real("DrivingModes.weight", self.weight)
        check_range("DrivingModes.use", self.use, 0.0, 1.0)
        check(
            "DrivingModes.use",
            self.use,
            lambda a: (
                np.broadcast_to(np.sum(a, axis=(-2, -1), keepdims=True) <= 1 + 1e-9, a.shape)
                if a.ndim == 3
                else np.ones(a.shape, bool)
            ),
            "a sum over gears and conditions ≤ 1 in each mode",
        )
        w, u = _shape(self.weight), _shape(self.use)
        if w is not None and len(w) != 1:
            raise ValueError(
                f"DrivingModes.weight has shape {w}; allowed: a 1-D array (one per mode)"
            )
        if u is not None and (len(u) != 3 or u[-1] != len(ENGINE_CONDITIONS)):
            raise ValueError(f"DrivingModes.use has shape {u}; allowed: (modes, gears + 1, 4)")
        if w is not None and u is not None and u[0] != w[0]:
            raise ValueError(
                f"DrivingModes.use has {u[0]} modes and weight {w[0]}; they must agree"
            )
        check_shares("DrivingModes.weight", self.weight)  # after the shape: one share per mode


@pytree_dataclass
class LoadCycles:
    """The load cycles of one halfshaft: per mode × gear × engine condition, shape (M, G + 1, 4).

    The gear axis holds the forward gears, then reverse.

    Attributes:
        shaft_speed: shaft speed [rpm].
        vehicle_speed: vehicle speed [km/h].
        engine_torque: engine-side torque T · k_s · i (the sheet's "Engine Output") [N·m].
        adhesion_limit: largest torque the wheel takes, with the load transfer and k_s [N·m].
        working_torque: the smaller of the shaft's engine-side torque and the adhesion limit [N·m].
        revolutions: shaft revolutions spent in the case over the required mileage [–].
        share: those revolutions over the total [–].
        wheel_load: dynamic wheel load per gear [N], shape (G + 1,).
        total_revolutions: required mileage / (2π r) [–].
        M_max_forward: largest forward working torque [N·m].
        M_max_backward: largest reverse working torque [N·m].
        shock_factor: k_s [–], to take the shock out of the life torques.
    """

    shaft_speed: jax.Array
    vehicle_speed: jax.Array
    engine_torque: jax.Array
    adhesion_limit: jax.Array
    working_torque: jax.Array
    revolutions: jax.Array
    share: jax.Array
    wheel_load: jax.Array
    total_revolutions: jax.Array
    M_max_forward: jax.Array
    M_max_backward: jax.Array
    shock_factor: jax.Array


def load_cycles(
    vehicle: Vehicle,
    modes: DrivingModes,
    required_km: ArrayLike,
    *,
    axle: str = "rear",
    domain_flags: bool = True,
) -> LoadCycles:
    """The load cycles of the halfshaft of ``axle`` ("rear" or "front") over ``required_km`` [km].

    See the module docstring for the chain. Differentiable in every number of
    ``vehicle``, ``modes`` and ``required_km``; ``vmap`` over any of them. ``required_km``
    a number > 0 (or an array that broadcasts against the cycles' shape (M, G + 1, 4)).
    Inside ``jit`` a traced input outside its domain (a mass ≤ 0, shares that do not sum to
    1…) gives NaN in every field (``LoadCycles`` has no result code). ``domain_flags=False``
    leaves those traced flags out, for a caller that keeps its inputs inside their domains
    itself (the optimiser: its spec's ranges lie inside them).
    """
    if not isinstance(vehicle, Vehicle):
        raise TypeError(f"vehicle = {vehicle!r} is not allowed; allowed: a vehicle.Vehicle")
    if not isinstance(modes, DrivingModes):
        raise TypeError(f"modes = {modes!r} is not allowed; allowed: a vehicle.DrivingModes")
    check_choice("axle", axle, AXLES)
    check_flag("domain_flags", domain_flags)
    check_domains(DOMAINS, required_km=required_km)
    check_broadcast(required_km=required_km)  # not empty
    g_ratios, u = _shape(vehicle.ratios), _shape(modes.use)
    if g_ratios is not None and u is not None and u[1] != g_ratios[0] + 1:
        raise ValueError(
            f"DrivingModes.use has {u[1]} gears; the vehicle has {g_ratios[0]} forward gears "
            "and reverse: use needs shape (modes, gears + 1, 4)"
        )
    km = _shape(required_km)
    if km is not None and u is not None and not _broadcasts(km, u):
        raise ValueError(
            f"required_km has shape {km}; allowed: one number [km] (shape ()), or an array "
            f"that broadcasts against the cycles' shape (modes, gears + 1, 4) = {u}"
        )
    return _load_cycles(vehicle, modes, required_km, axle, domain_flags)


def _broadcasts(shape, onto):
    """``shape`` broadcasts onto ``onto`` without growing it."""
    try:
        return np.broadcast_shapes(shape, onto) == tuple(onto)
    except ValueError:
        return False


@functools.partial(latency_bound_at_top_level, small_inputs=True, static_argnums=(3, 4))
def _load_cycles(vehicle, modes, required_km, axle, domain_flags):
    """`load_cycles` past its checks: one compiled program (its operations one by one compiled
    each on a first call: 1.1 s, against 0.3 s)."""
    v = jax.tree_util.tree_map(jnp.asarray, vehicle)
    r, mu, k_s = v.tyre_radius, v.adhesion, v.shock_factor
    ratios = jnp.concatenate([v.ratios, v.reverse_ratio[None]])
    forward = jnp.arange(ratios.shape[0]) < ratios.shape[0] - 1
    weight = v.mass * GRAVITY
    rear = axle == "rear"
    static = weight * ((1.0 - v.front_share) if rear else v.front_share) / 2.0
    cap = mu * weight * v.cg_height / (2.0 * v.wheelbase)  # 1st-gear transfer, whole vehicle at μ
    transfer = jnp.where(
        forward, jnp.minimum(v.load_transfer_per_ratio * ratios, cap), -v.reverse_load_transfer
    )
    wheel_load = jnp.maximum(static + (transfer if rear else -transfer), 0.0)
    adhesion = mu * wheel_load * r * k_s  # per wheel [N·m]
    shaft_speed = v.engine_speed[None, :] / ratios[:, None]  # (G+1, 4)
    vehicle_speed = shaft_speed * 2.0 * math.pi * r * 60.0 / 1000.0
    engine = v.engine_torque[None, :] * k_s * ratios[:, None]
    split = v.rear_torque_share if rear else 1.0 - v.rear_torque_share
    working = jnp.minimum(engine * split * (1.0 + v.differential_locking) / 2.0, adhesion[:, None])
    total = jnp.asarray(required_km) * 1000.0 / (2.0 * math.pi * r)
    share = jnp.asarray(modes.use) * jnp.asarray(modes.weight)[:, None, None]
    n_modes = share.shape[0]

    def per_mode(x):
        return jnp.broadcast_to(x, (n_modes, *x.shape))

    cycles = LoadCycles(
        shaft_speed=per_mode(shaft_speed),
        vehicle_speed=per_mode(vehicle_speed),
        engine_torque=per_mode(engine),
        adhesion_limit=per_mode(jnp.broadcast_to(adhesion[:, None], engine.shape)),
        working_torque=per_mode(working),
        revolutions=share * total,
        share=share,
        wheel_load=wheel_load,
        total_revolutions=total,
        M_max_forward=jnp.max(jnp.where(forward[:, None], working, 0.0)),
        M_max_backward=jnp.max(working[-1]),
        shock_factor=k_s,
    )
    if not domain_flags:
        return cycles
    # Every number inside its domain (checked where concrete; here where traced: NaN outside).
    fields = {f.name: getattr(v, f.name) for f in dataclasses.fields(v)}
    outside = outside_shares(modes.weight)
    for name, value in {**fields, "required_km": required_km, "use": modes.use}.items():
        outside |= jnp.any(outside_domains(DOMAINS, **{name: value}))
    return jax.tree_util.tree_map(lambda x: jnp.where(outside, jnp.nan, x), cycles)


def load_spectrum(cycles: LoadCycles) -> LoadSpectrum:
    """The life's [`LoadSpectrum`][tripodjax.life.LoadSpectrum] of the load cycles.

    M·(G+1)·4 cases, flattened (mode, gear, engine condition), then one case of zero
    torque for the revolutions no case claims (see the module docstring). Torques:
    the working torques without the shock factor; time shares a_i ∝ revolutions_i /
    n_i. Traced (no checks): built from checked cycles.
    """
    revolutions = cycles.share.ravel()
    speed = cycles.shaft_speed.ravel()
    used = jnp.sum(revolutions)
    mean_speed = jnp.where(
        used > 0, jnp.sum(revolutions * speed) / jnp.where(used > 0, used, 1.0), jnp.mean(speed)
    )
    revolutions = jnp.append(revolutions, jnp.maximum(1.0 - used, 0.0))
    speed = jnp.append(speed, mean_speed)
    torque = jnp.append((cycles.working_torque / cycles.shock_factor).ravel(), 0.0)
    per_rpm = cycles.vehicle_speed.ravel()[0] / cycles.shaft_speed.ravel()[0]  # 2π r · 60/1000
    time = revolutions / speed
    share = time / jnp.sum(time)
    leaves = (torque, speed, speed * per_rpm, share)
    return jax.tree_util.tree_unflatten(_SPECTRUM_TREE, leaves)  # no __post_init__: traced values


_SPECTRUM_TREE = jax.tree_util.tree_structure(LoadSpectrum(*(np.ones(1),) * 4))
