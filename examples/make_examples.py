"""Regenerate the shipped example captures from the committed design files.

    python examples/make_examples.py

Each slab folder holds its design.toml and one folder per capture. The captures are synthetic
(rebarlib.synth, realistic sensor) and carry their ground truth (truth.json, labels.png,
bar_ids.png). Colour is stored as JPEG to keep the examples small, as many SDKs save it.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from rebarlib import load_design, save_capture
from rebarlib.synth import Appearance, Deviations, synth_capture

HERE = Path(__file__).resolve().parent

# (slab, capture, camera height mm, tilt deg, camera yaw deg, target x/y mm, render seed)
CAPTURES = [
    ("paper_slab", "A_400", 400, 10, 0, (-250, -150), 11),
    ("paper_slab", "B_500", 500, 10, 4, (250, -150), 12),
    ("paper_slab", "C_600", 600, 10, -3, (-200, 200), 13),
    ("paper_slab", "D_500", 500, 8, 2, (250, 200), 14),
    ("site_slab", "P1_500", 500, 12, 0, (0, 0), 21),
]
SLABS = {
    # one as-built mesh per slab (scene_seed): the captures look at different parts of it
    "paper_slab": dict(
        scene_seed=101,
        deviations=Deviations(mesh_yaw_deg=3.0),
        appearance=Appearance(formwork="plywood", rust_fraction=0.1),
    ),
    "site_slab": dict(
        scene_seed=305,
        deviations=Deviations(mesh_yaw_deg=21.0, position_sigma_mm=4.0, missing=1),
        appearance=Appearance(formwork="film", rust_fraction=0.6, sun_elevation_deg=40),
    ),
}


def main() -> None:
    for slab, name, height, tilt, yaw, target, seed in CAPTURES:
        design = load_design(HERE / slab / "design.toml")
        out = HERE / slab / name
        if out.exists():
            shutil.rmtree(out)
        cfg = SLABS[slab]
        cap = synth_capture(
            design,
            height_mm=height,
            tilt_deg=tilt,
            yaw_deg=yaw,
            target_mm=target,
            deviations=cfg["deviations"],
            appearance=cfg["appearance"],
            seed=seed,
            scene_seed=cfg["scene_seed"],
            name=name,
        )
        save_capture(cap, out, color_format="jpg")
        t = cap.truth
        print(
            f"{out.relative_to(HERE)}: cover {t['cover_mm']:.2f} mm, layer distance "
            f"{t['layer_distance_mm']:.2f} mm, {sum(b['visible'] for b in t['bars'])} visible bars"
        )


if __name__ == "__main__":
    main()
