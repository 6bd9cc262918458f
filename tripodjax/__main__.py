"""``python -m tripodjax``: kinematics report of a halfshaft layout (default: the seed's case N)."""

import math
import sys

from tripodjax._cli import ArgumentParser, count, finish


def _parser():
    parser = ArgumentParser(
        prog="python -m tripodjax",
        description="Kinematics report of a tripod-joint halfshaft (float64).",
    )
    parser.add_argument(
        "--R", type=float, default=25.0, help="track pitch-circle radius [mm] (default 25)"
    )
    parser.add_argument("--l", type=float, default=500.0, help="shaft length [mm] (default 500)")
    parser.add_argument(
        "--gamma0", type=float, default=20.0, help="layout articulation angle [deg] (default 20)"
    )
    parser.add_argument(
        "--n-theta",
        type=count(6, 6),
        default=360,
        help="angles per revolution, a multiple of 6 (default 360)",
    )
    parser.add_argument(
        "--solver",
        default="newton",
        choices=("newton", "analytic", "closed_form"),
        help="solver level (default newton)",
    )
    return parser


def main(argv=None):
    parser = _parser()
    args = parser.parse_args(argv)
    import jax

    jax.config.update(
        "jax_enable_x64", True
    )  # the command's own choice; the library never does this
    import tripodjax
    from tripodjax._checks import check_layout_domain
    from tripodjax.results import RESULTS

    try:
        # Named as the command's options (γ0 in degrees), then the Layout checks nothing new.
        check_layout_domain(
            args.R,
            args.l,
            args.gamma0,
            names={"R": "--R", "l": "--l", "gamma0": "--gamma0"},
            degrees=True,
        )
        layout = tripodjax.Layout.from_degrees(args.R, args.l, args.gamma0)
        metrics = tripodjax.kinematic_metrics(layout, n_theta=args.n_theta, solver=args.solver)
    except ValueError as error:  # the parser's one line, as for its own argument errors
        parser.error(str(error))
    nominal = (args.R, args.l, args.gamma0) == (25.0, 500.0, 20.0)
    seed = {
        "delta_amp": "4.7e-3 rad (§2.11.3)",
        "irregularity": "2.82 % (§2.11.3)",
    }
    rows = [
        ("Δ amplitude (delta_pp/2)", f"{float(metrics.delta_pp) / 2:.4e} rad", seed["delta_amp"]),
        ("irregularity", f"{100 * float(metrics.irregularity):.3f} %", seed["irregularity"]),
        ("γ peak-to-peak", f"{math.degrees(float(metrics.gamma_pp)):.4f} °", ""),
        ("γ max", f"{math.degrees(float(metrics.gamma_max)):.4f} °", ""),
        ("eccentricity max", f"{float(metrics.ecc_max):.4f} mm", ""),
        ("roller radial stroke", f"{float(metrics.roller_stroke):.4f} mm", ""),
        (
            "spider orbit a / b p-p",
            f"{float(metrics.spider_orbit_x):.4f} / {float(metrics.spider_orbit_y):.4f} mm",
            "",
        ),
        ("spider axial Z*−c p-p", f"{float(metrics.spider_orbit_z):.4f} mm", ""),
        ("roller axial stroke", f"{float(metrics.roller_axial_stroke):.4f} mm", ""),
        ("solve result", RESULTS(int(metrics.result)).name, ""),
        ("error estimate", f"{float(metrics.error_estimate):.1e}", ""),
    ]
    print(
        f"tripodjax {tripodjax.__version__} — halfshaft kinematics, float64, {args.n_theta} angles/rev, "
        f"solver {args.solver}"
    )
    print(
        f"layout: R = {args.R:g} mm, l = {args.l:g} mm, γ0 = {args.gamma0:g}°"
        + (" (seed case N)" if nominal else "")
    )
    width = max(len(r[0]) for r in rows)
    for name, value, ref in rows:
        ref = f"   seed: {ref}" if (ref and nominal) else ""
        print(f"  {name:<{width}}  {value:>22}{ref}")
    return 0 if bool(metrics.converged) else 1


if __name__ == "__main__":
    sys.exit(finish(main))
