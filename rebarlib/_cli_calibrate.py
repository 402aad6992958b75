"""``rebar calibrate``: focal length, principal point, depth scale and offset of a depth camera
from a few captures of a flat printed checkerboard (``rebarlib.calibration``), written to a
calibration file that ``rebar inspect --calibration FILE`` applies."""

from __future__ import annotations

import re


def add_parser(sub):
    p = sub.add_parser(
        "calibrate",
        help="calibrate a depth camera from checkerboard captures",
        description="Estimate the intrinsics and the depth scale and offset, with their "
        "uncertainties, from captures of a flat printed checkerboard at several "
        "distances and tilted views (at least 3; 6-10 is better).",
    )
    p.add_argument("captures", nargs="+", metavar="CAPTURE", help="capture folders, each showing the whole board")
    p.add_argument(
        "--board",
        required=True,
        metavar="COLSxROWS",
        help="inner corners of the board, e.g. 9x6 (a board of 10 x 7 squares)",
    )
    p.add_argument("--square-mm", required=True, type=float, help="side of a printed square, measured (mm)")
    p.add_argument("--out", required=True, metavar="FILE", help="calibration file to write (.json)")
    p.add_argument("--device", default=None, help="the camera's name for the file (default: the captures')")
    return p


def _board(text: str):
    from ._checks import RebarInputError

    m = re.fullmatch(r"\s*(\d+)\s*[xX×]\s*(\d+)\s*", str(text))
    if not m:
        raise RebarInputError(f"--board {text!r}: expected inner corners as COLSxROWS, e.g. 9x6")
    return int(m.group(1)), int(m.group(2))


def run(args) -> int:
    from pathlib import Path

    from . import load_capture
    from ._checks import RebarInputError
    from .calibration import calibrate

    cols, rows = _board(args.board)
    out = Path(args.out)
    caps = []
    for c in args.captures:
        if not Path(c).is_dir():
            raise RebarInputError(
                f"CAPTURE {c}: not a folder (expected a capture folder with color.png, depth.png, camera.json)"
            )
        if out.resolve().parent == Path(c).resolve():
            raise RebarInputError(f"--out {out}: inside the capture folder {c}; write the calibration elsewhere")
        caps.append(load_capture(c))
    cal = calibrate(caps, cols=cols, rows=rows, square_mm=args.square_mm, device=args.device)
    cal.save(out)
    print(
        f"{out}: {cal.summary()}; reprojection {cal.reprojection_rms_px:.2f} px rms, depth residual "
        f"{cal.depth_rms_mm:.2f} mm rms over {cal.depth_range_mm[0]:.0f}-{cal.depth_range_mm[1]:.0f} mm"
    )
    return 0
