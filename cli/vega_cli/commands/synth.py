"""``vega synth``: regenerate the scheduled controller table (offline LPV synthesis)."""

from __future__ import annotations

import argparse

__all__ = ["register"]


def _run(args: argparse.Namespace) -> int:
    from vega_lpv.pipeline import run_synthesis

    def progress(line: str) -> None:
        print(line, flush=True)

    rep = run_synthesis(grid=args.grid, weights=args.weights, out=args.out,
                        progress=progress, verify=not args.no_verify, box=args.rate_box,
                        solver_path=args.solver_path)
    print()
    print(f"summary: grid {rep.grid} ({len(rep.times_s)} points), weights {rep.weights}, "
          f"solver path {args.solver_path}")
    print(f"  gamma_LTI max {max(rep.gamma_lti):.4f} | gamma_min {rep.gamma_min:.4f} | "
          f"back-off gamma {rep.gamma:.4f} | quadratic {rep.gamma_quadratic:.4f} | "
          f"gamma_min/gamma_LTI {rep.conservatism:.3f}")
    total = sum(rep.stage_times_s.values())
    print("  time: " + ", ".join(f"{k} {v:.1f} s" for k, v in rep.stage_times_s.items())
          + f"; total {total:.1f} s")
    if rep.frozen:
        ok = rep.certificate_dense_max < 0 and all(f["all_stable"] for f in rep.frozen.values())
        print(f"  verification: {'PASS' if ok else 'FAIL'} "
              f"(certificate {rep.certificate_dense_max:.2e}, "
              + ", ".join(f"{k}: worst Hinf {f['worst_hinf']:.4f}" for k, f in rep.frozen.items())
              + ")")
    print(f"  table: {rep.table}")
    return 0 if rep.gamma <= 1.0 or args.allow_gamma_above_one else 1


def register(subparsers) -> None:
    """Add the ``synth`` sub-command."""
    p = subparsers.add_parser(
        "synth", help="synthesise, verify and export the LPV controller table",
        description="Offline LPV synthesis (cvxpy; the in-house IPM, Clarabel): weighted "
                    "interconnection on the grid, frozen-point LTI bounds, rate-bounded and "
                    "quadratic synthesis, verification, Tustin export. Exit status 1 if gamma > 1.")
    p.add_argument("--grid", choices=("thesis", "refined", "full"), default="refined",
                   help="refined (default, the shipped table): the thesis' points plus the kinks "
                        "of the plant data, gaps <= 5 s; thesis: t = 10..90 s (9 points); "
                        "full: 0-100 s, placed in velocity")
    p.add_argument("--weights", choices=("shipped", "thesis"), default="shipped",
                   help="named weight set (docs/SYNTHESIS_WEIGHTS.md)")
    p.add_argument("--rate-box", choices=("with_frozen", "thesis"), default="with_frozen",
                   help="scheduling-rate box: with_frozen = [min(lo, 0), hi] (default, covers "
                        "constant velocity), thesis = [lo, hi] of the trajectory (all positive)")
    p.add_argument("--out", metavar="FILE",
                   help="output .npz (default: ros2_ws/src/vega_gnc/config/lpv_controller.npz)")
    # literal, not imported: vega_lpv.pipeline takes 0.7 s to import; a test holds
    # these equal to pipeline.SOLVER_PATHS and DEFAULT_SOLVER_PATH
    p.add_argument("--solver-path", choices=("ipm", "hybrid", "clarabel"), default="ipm",
                   help="ipm (default): the in-house interior point for both stages, Clarabel "
                        "then SCS as fallbacks; hybrid: Clarabel for stage 1, the IPM for stage "
                        "2; clarabel: the path that produced the shipped lpv_controller.npz "
                        "(about 5x slower; docs/SYNTHESIS.md §8)")
    p.add_argument("--no-verify", action="store_true", help="skip the verification stage")
    p.add_argument("--allow-gamma-above-one", action="store_true",
                   help="exit 0 even if the achieved gamma exceeds 1")
    p.set_defaults(func=_run)
