"""``rebar synth``: render a synthetic capture of a slab design, with ground truth."""

from __future__ import annotations

from dataclasses import replace


def add_parser(sub):
    p = sub.add_parser(
        "synth",
        help="render a synthetic RGB-D capture of a design, with ground truth",
        description="Render a synthetic RGB-D capture (color.png, depth.png, camera.json, "
        "truth.json, labels.png, bar_ids.png) of the slab in a design file.",
    )
    p.add_argument("out_dir", help="capture folder to create (must not exist or be empty)")
    p.add_argument("--design", required=True, help="design.toml of the slab")
    p.add_argument("--seed", type=int, default=0, help="random seed (same seed, same files)")
    p.add_argument(
        "--scene-seed",
        type=int,
        default=None,
        help="seed of the as-built mesh alone: captures sharing it show one slab",
    )
    p.add_argument("--height", type=float, default=500.0, help="camera height above formwork, mm")
    p.add_argument("--tilt", type=float, default=10.0, help="optical axis tilt from vertical, degrees")
    p.add_argument("--yaw", type=float, default=0.0, help="camera yaw about the vertical, degrees")
    p.add_argument(
        "--target",
        type=float,
        nargs=2,
        default=(0.0, 0.0),
        metavar=("X", "Y"),
        help="where the optical axis meets the formwork, mm from the mesh centre",
    )
    p.add_argument("--mesh-yaw", type=float, default=0.0, help="mesh rotation in plan, degrees")
    p.add_argument("--position-sigma", type=float, default=2.0, help="bar position jitter, mm")
    p.add_argument("--height-sigma", type=float, default=0.5, help="bar height jitter (local cover), mm")
    p.add_argument("--bow", type=float, default=0.0, help="bar bow (sagitta over its length), mm")
    p.add_argument("--missing", type=int, default=0, help="number of missing bars")
    p.add_argument("--wrong-size", type=int, default=0, help="number of bars of a wrong size")
    p.add_argument(
        "--laps", type=int, default=0, help="number of bars made of two pieces lapped side by side (40 diameters)"
    )
    p.add_argument("--no-ribs", action="store_true", help="smooth bars (no rib envelope)")
    p.add_argument("--formwork", choices=("plywood", "film", "plastic"), default=None)
    p.add_argument("--rust", type=float, default=0.0, help="fraction of rusty bars, 0..1")
    p.add_argument("--sensor", choices=("realistic", "ideal"), default="realistic")
    p.add_argument("--bias", type=float, default=0.0, help="depth bias k in b = k z^2 (mm per m^2)")
    p.add_argument("--depth-scale", type=float, default=None, help="mm per stored depth unit")
    p.add_argument("--jpg", action="store_true", help="store colour as JPEG")
    p.add_argument("--overwrite", action="store_true", help="write into a non-empty folder")
    return p


def run(args) -> int:
    from . import load_design, save_capture
    from .synth import Appearance, Deviations, SensorModel, synth_capture
    from pathlib import Path

    from ._checks import RebarInputError

    for opt in ("missing", "wrong_size", "laps"):
        if getattr(args, opt) < 0:
            raise RebarInputError(
                f"--{opt.replace('_', '-')}: expected a number of bars >= 0, got {getattr(args, opt)}"
            )
    design = load_design(args.design)
    dev = Deviations(
        position_sigma_mm=args.position_sigma,
        height_sigma_mm=args.height_sigma,
        bow_mm=args.bow,
        mesh_yaw_deg=args.mesh_yaw,
        missing=args.missing,
        wrong_size=args.wrong_size,
        ribs=not args.no_ribs,
        laps=args.laps,
    )
    sensor = SensorModel() if args.sensor == "realistic" else SensorModel.ideal()
    sensor = replace(sensor, bias_mm_per_m2=args.bias)
    if args.depth_scale:
        sensor = replace(sensor, depth_scale_mm=args.depth_scale)
    app = Appearance(formwork=args.formwork, rust_fraction=args.rust)
    out = Path(args.out_dir)
    cap = synth_capture(
        design,
        height_mm=args.height,
        tilt_deg=args.tilt,
        yaw_deg=args.yaw,
        target_mm=tuple(args.target),
        deviations=dev,
        sensor=sensor,
        appearance=app,
        seed=args.seed,
        scene_seed=args.scene_seed,
        name=out.name,
    )
    save_capture(cap, out, color_format="jpg" if args.jpg else "png", overwrite=args.overwrite)
    t = cap.truth
    vis = sum(b["visible"] for b in t["bars"])
    print(
        f"{out}: {cap.intrinsics.width}x{cap.intrinsics.height}, camera {args.height:g} mm, "
        f"tilt {args.tilt:g} deg; cover {t['cover_mm']:.2f} mm, layer distance "
        f"{t['layer_distance_mm']:.2f} mm, {vis} visible bars"
    )
    return 0
