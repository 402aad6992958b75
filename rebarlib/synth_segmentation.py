"""The synthetic segmentation data set: what the shipped model was trained and is tested on.

Not part of the runtime (it renders with :mod:`rebarlib.synth`): used by ``training/``, the
tests and ``benchmarks/bench_segmentation.py``. Capture ``i`` of the set is
``synth_segmentation_capture(i, seed=DATASET_SEED)``; the 6:2:2 split is :func:`split_indices`.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "DATASET_SEED",
    "DATASET_SIZE",
    "segmentation_scene_params",
    "synth_segmentation_capture",
    "split_indices",
    "synth_eval_regions",
]


#: The recipe of the shipped model's data set: capture ``i`` of the set is
#: ``synth_segmentation_capture(i, seed=DATASET_SEED)``; the 6:2:2 split is ``split_indices``.
DATASET_SEED = 20240611
DATASET_SIZE = 300


def segmentation_scene_params(index: int, *, seed: int = DATASET_SEED) -> dict:
    """The randomised design, pose, deviations and appearance of capture ``index`` of a data set.

    Everything is drawn from ``numpy.random.default_rng([seed, index])``, so a data set is
    regenerated exactly from ``(seed, index)`` at any resolution.

    Examples
    --------
    >>> p = segmentation_scene_params(3)
    >>> 350 <= p["height_mm"] <= 700 and 0 <= p["tilt_deg"] <= 20
    True
    """
    from .synth import rib_envelope_mm

    rng = np.random.default_rng([int(seed), int(index)])
    sizes = (8, 10, 12, 14, 16, 18, 20)
    d_lo, d_up = (int(rng.choice(sizes)) for _ in range(2))
    s_lo, s_up = (float(10 * round(rng.uniform(100, 250) / 10)) for _ in range(2))
    cover = float(round(rng.uniform(15, 50)))
    layer = float(round(2 * rib_envelope_mm(d_lo) + rng.uniform(10, 90)))
    design = {
        "slab": {"id": f"SEG-{seed}-{index}"},
        "design": {
            "cover_mm": cover,
            "layer_distance_mm": layer,
            "lower": {"diameter_mm": d_lo, "spacing_mm": s_lo},
            "upper": {"diameter_mm": d_up, "spacing_mm": s_up},
        },
    }
    deviations = dict(
        position_sigma_mm=float(rng.uniform(0, 6)),
        height_sigma_mm=float(rng.uniform(0, 2)),
        bow_mm=float(rng.uniform(0, 10)),
        mesh_yaw_deg=float(rng.uniform(-45, 45)),
        missing=int(rng.integers(0, 3)),
        wrong_size=int(rng.integers(0, 2)),
    )
    rusty = rng.random() < 0.5
    appearance = dict(
        formwork=str(rng.choice(["plywood", "film", "plastic"])),
        rust_fraction=float(rng.uniform(0.3, 1.0)) if rusty else 0.0,
        sun_elevation_deg=float(rng.uniform(20, 85)),
        sun_azimuth_deg=float(rng.uniform(0, 360)),
        ambient=float(rng.uniform(0.15, 0.6)),
        exposure=float(rng.uniform(0.6, 1.4)),
        noise_sigma=float(rng.uniform(1.0, 6.0)),
        blur_px=float(rng.uniform(0.0, 1.2)) if rng.random() < 0.5 else 0.0,
        jpeg_quality=int(rng.integers(50, 96)) if rng.random() < 0.5 else None,
    )
    return {
        "design": design,
        "height_mm": float(rng.uniform(350, 700)),
        "tilt_deg": float(rng.uniform(0, 20)),
        "yaw_deg": float(rng.uniform(0, 360)),
        "target_mm": (float(rng.uniform(-300, 300)), float(rng.uniform(-300, 300))),
        "deviations": deviations,
        "appearance": appearance,
        "render_seed": int(rng.integers(2**31)),
    }


def synth_segmentation_capture(
    index: int, *, seed: int = DATASET_SEED, intrinsics=None, sensor=None, rib_relief: bool = False
):
    """Render capture ``index`` of the segmentation data set (see :func:`segmentation_scene_params`).

    Parameters
    ----------
    index : which capture of the set
    seed : the data set's seed
    intrinsics : camera (default GEMINI2, 1280 x 800); ``GEMINI2.scaled(0.5)`` renders the same
        scene at 640 x 400
    sensor : depth sensor model (default: the realistic ``SensorModel()``)
    rib_relief : draw the bars' ribs in relief (core, longitudinal and crescent transverse ribs,
        ``synth.Deviations.rib_relief``) instead of as their smooth envelope: the same scene
        otherwise, so a capture can be had both ways

    Returns
    -------
    Capture with ``labels`` (rebar = ``labels > 0``) and ``metadata["truth"]``.
    """
    from ._camera import GEMINI2
    from ._design import design_from_dict
    from .synth import Appearance, Deviations, synth_capture

    p = segmentation_scene_params(index, seed=seed)
    return synth_capture(
        design_from_dict(p["design"], source="segmentation data set"),
        height_mm=p["height_mm"],
        tilt_deg=p["tilt_deg"],
        yaw_deg=p["yaw_deg"],
        target_mm=p["target_mm"],
        deviations=Deviations(**p["deviations"], rib_relief=bool(rib_relief)),
        sensor=sensor,
        appearance=Appearance(**p["appearance"]),
        intrinsics=intrinsics or GEMINI2,
        seed=p["render_seed"],
        name=f"seg-{seed}-{index}" + ("-relief" if rib_relief else ""),
    )


def split_indices(n: int = DATASET_SIZE, *, seed: int = DATASET_SEED) -> dict:
    """Split capture indices ``0..n-1`` 6:2:2 into train / val / test, by capture, seeded.

    Examples
    --------
    >>> s = split_indices(10, seed=1)
    >>> [len(s[k]) for k in ("train", "val", "test")]
    [6, 2, 2]
    """
    perm = np.random.default_rng([int(seed), 622]).permutation(int(n))
    n_train, n_val = int(round(0.6 * n)), int(round(0.2 * n))
    return {
        "train": np.sort(perm[:n_train]),
        "val": np.sort(perm[n_train : n_train + n_val]),
        "test": np.sort(perm[n_train + n_val :]),
    }


def synth_eval_regions(
    index: int, capture, *, seed: int = DATASET_SEED, margin_px: int | None = None, rib_relief: bool = False
) -> dict:
    """The hard-case subsets of a data-set capture, for the shadow / rust breakdown.

    * ``shadow`` (bars in shadow, the paper's hard case): bar pixels that lie in a *cast* shadow
      (sunlight blocked by another bar, a chair or a spacer), grown by ``margin_px`` so that
      false positives around them count too.
    * ``unlit``: every pixel that receives no direct sunlight, bar and formwork alike: cast
      shadows plus the *attached* shadow of every bar (its half facing away from the sun). A
      harder, edge-dominated subset: the dark side of every bar lies along its edge (about twice
      the edge share of the bar pixels overall, ``benchmarks/edge_sensitivity.py``), so it scores
      the edge placement on the dark side rather than bars in shadow. Reported beside ``shadow``.
    * ``rust``: pixels of bars with ``truth rust > 0``, grown by ``margin_px``.

    ``margin_px`` defaults to 3 px per 1280 px of width. Unlit pixels are found by rendering the
    same scene again with no ambient light and no noise (they come out exactly black); attached
    shadow by rendering it once more without cast shadows. Metrics on a subset count only its
    pixels (``confusion_counts(..., region=...)``).

    Parameters
    ----------
    index, seed : the capture of the data set (see :func:`synth_segmentation_capture`)
    capture : that capture, as rendered (gives the resolution and the bar ids)
    rib_relief : as the capture was rendered (:func:`synth_segmentation_capture`)
    """
    import cv2
    from dataclasses import replace

    from ._design import design_from_dict
    from .synth import Appearance, Deviations, SensorModel, synth_capture

    p = segmentation_scene_params(index, seed=seed)
    app = Appearance(**p["appearance"])

    def black(cast_shadows):
        dark = replace(
            app, ambient=0.0, exposure=1.0, noise_sigma=0.0, blur_px=0.0, jpeg_quality=None, cast_shadows=cast_shadows
        )
        ref = synth_capture(
            design_from_dict(p["design"], source="segmentation data set"),
            height_mm=p["height_mm"],
            tilt_deg=p["tilt_deg"],
            yaw_deg=p["yaw_deg"],
            target_mm=p["target_mm"],
            deviations=Deviations(**p["deviations"], rib_relief=bool(rib_relief)),
            sensor=SensorModel.ideal(),
            appearance=dark,
            intrinsics=capture.intrinsics,
            seed=p["render_seed"],
        )
        return ref.color.max(axis=2) == 0

    margin = margin_px if margin_px is not None else max(1, round(3 * capture.intrinsics.width / 1280))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin + 1, 2 * margin + 1))

    def grow(mask):
        return cv2.dilate(mask.astype(np.uint8), kernel).astype(bool) if margin > 0 and mask.any() else mask

    unlit = black(True)
    cast = unlit & ~black(False)
    rusty = [b["id"] + 1 for b in capture.truth["bars"] if b["rust"] > 0]
    return {"shadow": grow(cast & (capture.bar_ids > 0)), "unlit": unlit, "rust": grow(np.isin(capture.bar_ids, rusty))}
