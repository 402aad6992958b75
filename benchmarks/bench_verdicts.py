"""Verdicts over many rendered slabs: is a slab rejected only for defects that are there?

Renders ``--slabs`` slabs (default 60) of finite double-layer meshes, 2-4 captures each (heights
400-700 mm, tilts 0-20°, any yaw of mesh and camera, the mesh's edge in view in a third of them,
lower bars without depth in a quarter of the captures, rust on some). Even-numbered slabs have no
defect; odd ones exactly one, in turn: a missing bar inside the view, a missing bar at a row's
end, a bar of the wrong size, cover off by +5 mm, one spacing off by +25 mm, layer distance off by
+8 mm. The first capture of a defective slab is aimed at the defect. Every slab is inspected
(``rebarlib.inspect``, refined, diameters) and judged (``rebarlib.evaluate``) under its design's
standard: GB 50204-2015, except the spacing-defect slabs, which are judged under EN 13670 class 1
(every spacing within ±20 mm): GB 50204's general-item rule accepts a lot with up to 20 % of its
spacings out of tolerance, so one spacing 25 mm off is within that code's allowance.

Prints the verdict confusion matrix (truth: clean / defective against accepted / incomplete /
rejected), per item the false fails and the missed defects, and whether each rejected slab names
its true defect, and why the clean slabs left incomplete are (per cause). Renders are cached
(``--cache DIR``), so a second run only inspects; each capture's result is saved there too
(``result_<capture>.json``), so ``--rejudge`` judges them again without inspecting (a change to
the acceptance alone).

Each slab's own as-built truth is judged too, as a perfect inspection of the same captures would
be (``rebarlib.synth.result_from_truth``): the bars' placing jitter can put a spacing out of
tolerance on a slab with no designed defect. Such a slab gets its own row ("clean design, out of
tolerance as built"), and an item its truth fails is not a false fail.

``--follow-advice`` acts as an inspector who reads the slab's sheet: where a capture says a bar
position lies hidden under a bar and how far to move the camera to see it, and no other capture of
the slab judged that position (the captures judged together), one more capture is taken as
told (moved across those bars by 1.25 times the distance named, towards the side the sheet names
— towards the position — or, on a sheet that names none, towards the slab's middle; height, tilt
and heading kept), one for each capture that asks (at most 4 captures a slab), and the slab is
judged again. Then, for each capture first taken whose note says its bars were left unsized for
its camera's pixels and a capture from nearer gives enough (docs/decisions/063), one capture as
a person takes it (``P<j>``): the optical axis on the middle of the bars still unsized, with a
hand's aim error, the farthest of them at the distance the note names, tilt and heading kept.
Then, for each bar no capture of the slab sized (and no such capture was taken for) whose reason
advises a capture from closer (``rebarlib.diameter.closer``, docs/decisions/038), one capture as told, aimed as a
person aims: the camera the advised distance from the bar's seen middle along its optical axis,
that axis put on the bar's middle with a hand's error (uniform within ±¼ of the bar's design
spacing across the bar and ±½ along it, seeded: ``AIM_ERROR``), tilt and heading kept (still at
most 4 captures a slab), and its folder marked with the bar it was aimed at (``aim.json``,
docs/decisions/043); what each says of its bar is printed. Then, where a spacing lot's verdict
depends on which spacings two captures not placed on each other share and the sheet says "a
capture placed on both settles it" (docs/decisions/039), one capture half-way between the first
such pair (the mean of their targets and heights, the first's tilt and heading). Both judgements are
printed. ``--second-round`` then acts as an inspector who reads the sheet again: what the
captures first taken still ask for, judged with the captures of the first round (a capture
already taken is not taken again), is taken too, up to 6 captures a slab, and the slab judged a
third time; all three judgements are printed (docs/decisions/041). A cached follow-up capture whose camera stood
elsewhere is rendered again.

``--as-guided`` takes the same number of captures a slab as first taken, but as docs/capturing.md
says ("cover each area of the slab twice, the second capture moved diagonally to the bars"): the
first capture of each area as before (``C0``, ``C1``: the first still aimed at the defect), the
second (``G<j>_<height>``) with the camera moved diagonally to the bars, towards the slab's middle,
by √2 times the guide's step across them, ``(r_u + r_l)·H / Δh`` (the design's largest upper and
lower radii, the camera's height above the lower bars' axes, the design's layer distance); height,
tilt, heading, sensor and light kept. With n captures first taken: ``C0, G0`` (n = 2),
``C0, G0, C1`` (3), ``C0, G0, C1, G1`` (4). Judged once, no follow-up (docs/decisions/046).

``--designs other`` draws the slabs' designs from another family (``DESIGNS_OTHER``: Φ10 at
100-120 mm, Φ20/Φ16 at 150 mm, Φ25/Φ20 at 200-250 mm; covers 15-40 mm): rules checked on
designs they were not built on. ``--heights LO,HI`` draws the captures' heights above the
formwork from another band than 400-700 mm (the other draws stay as they are): a camera with
fewer pixels rendered as the capture guide says for it (docs/capturing.md, docs/decisions/063).
``--laps N`` makes N inner bars of every slab of two pieces lapped side by side (touching, over 40
diameters, ``Deviations.laps``) and aims one capture of each slab within 100 mm of one lap's
middle (after the one aimed at the defect): a lap is no extra bar, no missing bar and no spacing
(docs/verdicts.md, "Laps and pieces"); the truth holds no spacing between a lap's two bars and
takes its neighbours' spacings from the lap's middle (docs/decisions/071).

    python benchmarks/bench_verdicts.py --slabs 60 --jobs 2 --cache /tmp/verdicts
    python benchmarks/bench_verdicts.py --slabs 60 --jobs 2 --cache /tmp/verdicts --rejudge --follow-advice
    python benchmarks/bench_verdicts.py --start 60 --slabs 40 --jobs 2 --cache /tmp/verdicts_held_out
    python benchmarks/bench_verdicts.py --slabs 60 --cache /tmp/verdicts --rejudge --follow-advice --second-round
    python benchmarks/bench_verdicts.py --slabs 60 --jobs 1 --cache /tmp/verdicts --rejudge --as-guided
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import re
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

#: How the captures are rendered (``--camera``, ``--sensor``, ``--photo``, ``--ribs``): the defaults, or
#: another camera, depth sensor, a photograph's softening and JPEG, ribs in relief (benchmarks/_cameras.py)
#: — the verdicts judged on captures unlike those their rules were built on. Kept in each slab.json.
RENDER = {
    "camera": "gemini2",
    "sensor": "default",
    "photo": False,
    "ribs": "envelope",
    "heights": [400.0, 700.0],
    "designs": "default",
    "jitter_mm": 4.0,
    "defects": "default",
    "laps": 0,
}
RENDER_DEFAULT = dict(RENDER)

DEFECTS = ("missing_inside", "missing_end", "wrong_size", "cover", "spacing", "layer_distance")
#: the defects of ``--defects extra``: a bar the design does not have, half-way between two
#: (every odd slab; a set of its own, so that the default set's slabs keep their defects)
DEFECTS_EXTRA = ("extra",)
#: the acceptance item a defect must fail
DEFECT_ITEM = {
    "extra": "bar_count",
    "missing_inside": "bar_count",
    "missing_end": "bar_count",
    "wrong_size": "bar_size",
    "cover": "cover",
    "spacing": "spacing",
    "layer_distance": "layer_distance",
}
DESIGNS = (  # (lower Φ, lower spacing, upper Φ, upper spacing, cover, layer distance)
    (14, 200, 12, 200, 20, 85),
    (12, 150, 10, 150, 25, 70),
    (16, 200, 14, 180, 30, 100),
)
#: another family (``--designs other``): a light mesh at tight spacings, heavier bars and covers
DESIGNS_OTHER = ((10, 100, 10, 120, 15, 55), (20, 150, 16, 150, 35, 110), (25, 200, 20, 250, 40, 130))


def design_toml(k: int, defect: str | None) -> str:
    family = DESIGNS_OTHER if RENDER["designs"] == "other" else DESIGNS
    dl, sl, du, su, cover, ld = family[k % len(family)]
    std = "EN13670-class1" if defect == "spacing" else "GB50204-2015"
    return (
        f'[slab]\nid = "V-{k:03d}"\nstandard = "{std}"\n\n[design]\ncover_mm = {cover}\n'
        f"layer_distance_mm = {ld}\n\n[design.lower]\ndiameter_mm = {dl}\nspacing_mm = {sl}\n\n"
        f"[design.upper]\ndiameter_mm = {du}\nspacing_mm = {su}\n"
    )


def _slab_plan(k: int, folder: Path):
    """Slab ``k``'s design, scene, defect and captures (name, pose, sensor, appearance, seed), as
    the benchmark always draws them (``folder`` receives design.toml)."""
    import rebarlib as R
    from rebarlib import synth as S

    rng = np.random.default_rng([2026, k])
    family = DEFECTS_EXTRA if RENDER["defects"] == "extra" else DEFECTS
    defect = None if k % 2 == 0 else family[(k // 2) % len(family)]
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "design.toml").write_text(design_toml(k, defect), encoding="utf-8")
    design = R.load_design(folder / "design.toml")
    render = design
    if defect == "cover":
        render = _with(design, cover_mm=design.cover_mm + 5)
    elif defect == "layer_distance":
        render = _with(design, layer_distance_mm=design.layer_distance_mm + 8)
    dev = S.Deviations(
        end_overhang_mm=float(rng.uniform(25, 75)),
        mesh_yaw_deg=float(rng.uniform(0, 180)),
        position_sigma_mm=1.5,
        position_uniform_mm=float(RENDER["jitter_mm"]),
        slab_size_mm=float(rng.uniform(1600, 2400)),
        missing=1 if defect == "missing_inside" else 0,
        missing_at_end=1 if defect == "missing_end" else 0,
        wrong_size=1 if defect == "wrong_size" else 0,
        extra=1 if defect == "extra" else 0,
        laps=int(RENDER["laps"]),
    )
    if RENDER["ribs"] == "relief":
        dev = dataclasses.replace(dev, rib_relief=True)
    scene = S.make_scene(render, dev, rng=np.random.default_rng([2026, k, 1]))
    gap = None
    if defect == "spacing":
        scene, gap = _open_one_gap(scene, rng, 25.0)
    n_cap = int(rng.integers(2, 5)) if k % 5 == 0 else 2
    edge_view = k % 3 == 0
    targets = _targets(scene, defect, gap, n_cap, edge_view, rng, laps=bool(RENDER["laps"]))
    specs = []
    for j, target in enumerate(targets):
        h = float(rng.uniform(*RENDER["heights"]))
        tilt, yaw = float(rng.uniform(0, 20)), float(rng.uniform(0, 360))
        shadow = int(rng.random() < 0.25)
        rust = float(rng.choice([0.0, 0.0, 0.3, 0.8]))
        specs.append(
            {
                "name": f"C{j}_{int(h)}",
                "h": h,
                "tilt": tilt,
                "yaw": yaw,
                "target": tuple(target),
                "shadow": shadow,
                "rust": rust,
                "seed": [2026, k, 2, j],
            }
        )
    return design, scene, defect, edge_view, specs


def _render_one(scene, spec: dict, folder: Path) -> str:
    import rebarlib as R
    from rebarlib import synth as S

    from _cameras import CAMERAS, SENSORS  # (the script's folder is on sys.path: benchmarks/__init__.py)

    pose = S.CameraPose.looking_down(spec["h"], tilt_deg=spec["tilt"], yaw_deg=spec["yaw"], target_mm=spec["target"])
    app = S.Appearance(rust_fraction=spec["rust"])
    if RENDER["photo"]:
        app = dataclasses.replace(app, pixel_samples=3, blur_px=0.8, jpeg_quality=90)
    cap = S.render_capture(
        scene,
        pose,
        intrinsics=CAMERAS[RENDER["camera"]],
        sensor=dataclasses.replace(SENSORS[RENDER["sensor"]], bars_without_depth=spec["shadow"]),
        appearance=app,
        rng=np.random.default_rng(spec["seed"]),
        name=spec["name"],
    )
    R.save_capture(cap, folder / spec["name"], overwrite=True)
    return spec["name"]


def _check_rendered_as_asked(folder, advice: str) -> None:
    """Stop where the slab in ``folder`` was rendered with other options than :data:`RENDER`."""
    made = {**RENDER_DEFAULT, **json.loads((Path(folder) / "slab.json").read_text()).get("render", {})}
    if made != RENDER:
        raise SystemExit(f"{folder}: rendered as {made}, not as asked ({RENDER}): {advice}")


def _render_slab(args) -> str:
    """Render slab ``k`` into ``cache/slab_k`` (design.toml, captures, slab.json); returns the folder."""
    k, cache = args
    folder = Path(cache) / f"slab_{k:03d}"
    if (folder / "slab.json").exists():
        _check_rendered_as_asked(folder, "use another --cache")
        return str(folder)
    _, scene, defect, edge_view, specs = _slab_plan(k, folder)
    caps = [_render_one(scene, spec, folder) for spec in specs]
    meta = {
        "slab": k,
        "defect": defect,
        "render": RENDER,
        "captures": caps,
        "edge_view": edge_view,
        "shadows": sum(spec["shadow"] for spec in specs),
    }
    (folder / "slab.json").write_text(json.dumps(meta), encoding="utf-8")
    return str(folder)


def _with(design, **kw):
    import dataclasses

    return dataclasses.replace(design, **kw)


def _open_one_gap(scene, rng, by_mm: float):
    """Move every bar beyond one inner gap of one upper set by ``by_mm`` (that gap opens by it);
    returns the scene and the ids of the two bars on either side of the gap."""
    import dataclasses

    sets = {}
    for b in scene.bars:
        sets.setdefault((b.layer, b.level), []).append(b)
    layer_level = ("upper", "bottom") if rng.random() < 0.5 else ("upper", "top")
    row = sorted(sets[layer_level], key=lambda b: b.offset_mm)
    cut = int(rng.integers(2, len(row) - 2))
    moved = {b.id for b in row[cut:]}
    bars = []
    for b in scene.bars:
        if b.id in moved:
            b = dataclasses.replace(b, offset_mm=b.offset_mm + by_mm, axis=b.axis + by_mm * _across(scene, b))
        bars.append(b)
    return dataclasses.replace(scene, bars=tuple(bars)), (row[cut - 1].id, row[cut].id)


def _across(scene, b) -> np.ndarray:
    """The unit vector along which ``make_scene`` offsets bar ``b``."""
    yaw = math.radians(scene.deviations.mesh_yaw_deg)
    ex = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    ey = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    return ey if b.level == "bottom" else ex


def _targets(scene, defect, gap, n: int, edge_view: bool, rng, *, laps: bool = False) -> list:
    """Where each capture looks (world x, y mm): the first at the defect, one at a lap with
    ``laps`` (within 100 mm of the lap's middle), one at the mesh's edge where asked, the others
    inside the mesh."""
    # the mesh's extent in its own frame (x along the bottom bars, y along the top bars)
    yaw = math.radians(scene.deviations.mesh_yaw_deg)
    ex = np.array([math.cos(yaw), math.sin(yaw)])
    ey = np.array([-math.sin(yaw), math.cos(yaw)])
    pts = np.vstack([b.axis[[0, -1], :2] for b in scene.bars])
    local = np.column_stack((pts @ ex, pts @ ey))
    lo, hi = local.min(axis=0), local.max(axis=0)

    def world(xy):
        return xy[0] * ex + xy[1] * ey

    out = []
    focus = None
    if defect in ("missing_inside", "missing_end") and scene.ghosts:
        g = scene.ghosts[0]
        focus = g.axis[0, :2] + rng.uniform(0.3, 0.7) * (g.axis[-1, :2] - g.axis[0, :2])
        if defect == "missing_end":  # step 100 mm towards the mesh's middle: the edge and the row in view
            mid = world(0.5 * (lo + hi))
            focus = focus + 100.0 * (mid - focus) / max(np.linalg.norm(mid - focus), 1.0)
    elif defect in ("wrong_size", "extra"):
        b = next(b for b in scene.bars if (b.extra if defect == "extra" else b.nominal_mm != b.design_mm))
        focus = b.axis[0, :2] + rng.uniform(0.35, 0.65) * (b.axis[-1, :2] - b.axis[0, :2])
    elif defect == "spacing":
        ia, ib = gap
        a, b = scene.bars[ia], scene.bars[ib]
        focus = 0.5 * (a.axis.mean(0)[:2] + b.axis.mean(0)[:2])
    if focus is not None:
        out.append(focus)
    if laps and scene.laps and len(out) < n:
        mid = scene.laps[int(rng.integers(len(scene.laps)))][2][:2]
        out.append(mid + rng.uniform(-100, 100, 2))
    if edge_view and len(out) < n:
        side = rng.integers(4)
        x = rng.uniform(lo[0] + 300, hi[0] - 300)
        y = rng.uniform(lo[1] + 300, hi[1] - 300)
        x = [lo[0] + 150, hi[0] - 150, x, x][side]
        y = [y, y, lo[1] + 150, hi[1] - 150][side]
        out.append(world((x, y)))
    while len(out) < n:
        out.append(world(rng.uniform(lo + 350, hi - 350)))
    return [tuple(map(float, t)) for t in out[:n]]


#: captures a slab at most, in the first round of captures asked for and in a second one
MAX_CAPTURES = (4, 6)


def _inspect_slab(
    folder: str, rejudge: bool = False, follow: bool = False, rounds: int = 1, guided: bool = False
) -> dict:
    """Inspect and judge one slab's captures; with ``follow``, when a capture says where to take
    another one (a bar position hidden under a bar, a bar a capture from closer would size), take
    it as told and judge again (the first judgement is kept under ``first_pass``). With ``rounds``
    2, what the captures first taken still ask for once those captures are judged with them is
    taken too, up to ``MAX_CAPTURES[1]`` a slab (the judgement after the first round is kept under
    ``round_1``). With ``guided``, the captures as docs/capturing.md says instead of those first
    taken (:func:`_guided`), judged once."""
    import rebarlib as R

    folder = Path(folder)
    meta = json.loads((folder / "slab.json").read_text())
    design = R.load_design(folder / "design.toml")
    t = time.perf_counter()
    if guided:
        meta = {**meta, "captures": _guided(folder, meta, design)}
        follow = False
    results = [_result(folder, c, design, rejudge) for c in meta["captures"]]
    rec = {**meta, **_judge(results, design)}
    keys = ("verdict", "failed", "failed_lots", "incomplete", "reasons")
    rec["first_pass"] = {k: rec[k] for k in keys}
    taken: list = []
    for rnd in range(rounds if follow else 0):
        added = _follow_advice(folder, meta, results, design, rejudge, taken=taken, max_captures=MAX_CAPTURES[rnd])
        if rnd == 1:
            rec["round_1"] = {**{k: rec[k] for k in keys}, "followups": list(taken)}
        if added:
            results += [_result(folder, c, design, rejudge) for c in added]
            rec.update(_judge(results, design))
            taken += added
            rec["followups"] = list(taken)
            rec["closer"] = [_closer_outcome(folder, c) for c in taken if c.startswith("Z")] + [
                o for c in taken if c.startswith("P") for o in _area_outcomes(folder, c)
            ]
    truth = _truth_judged(folder, list(meta["captures"]) + rec.get("followups", []), design)
    rec["truth_failed"], rec["truth_passed_lots"] = truth["failed"], truth["passed_lots"]
    rec["seconds"] = round(time.perf_counter() - t, 2)
    (folder / _verdict_file(follow, rounds, guided)).write_text(json.dumps(rec, indent=1), encoding="utf-8")
    return rec


def _verdict_file(follow: bool, rounds: int, guided: bool = False) -> str:
    if guided:
        name = "verdict_guided.json"
    else:
        name = ("verdict_follow2.json" if rounds > 1 else "verdict_follow.json") if follow else "verdict.json"
    # judged under another decision rule than the presets': kept beside, not over, those verdicts
    return name if not JUDGE["rule"] else name.replace(".json", "_" + JUDGE["rule"].replace(" ", "_") + ".json")


def _guided(folder: Path, meta: dict, design) -> list:
    """The slab's captures as docs/capturing.md says, as many as first taken (see the module's
    docstring, ``--as-guided``): each area's first capture as first taken, its second moved
    diagonally to the bars towards the slab's middle by √2 times the guide's step. Renders those
    not in the cache; returns their names."""
    _, scene, _, _, specs = _slab_plan(meta["slab"], folder)
    yaw = math.radians(scene.deviations.mesh_yaw_deg)
    ex = np.array([math.cos(yaw), math.sin(yaw)])
    ey = np.array([-math.sin(yaw), math.cos(yaw)])
    pts = np.vstack([b.axis[[0, -1], :2] for b in scene.bars])
    middle = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    r_u = 0.5 * max(design.upper.bottom.diameter_mm, design.upper.top.diameter_mm)
    r_l = 0.5 * max(design.lower.bottom.diameter_mm, design.lower.top.diameter_mm)
    out = []
    for j in range((len(specs) + 1) // 2):
        spec = specs[j]
        out.append(meta["captures"][j])
        if len(out) == len(specs):
            break
        target = np.array(spec["target"])
        diag = max((sx * ex + sy * ey for sx in (1, -1) for sy in (1, -1)), key=lambda v: v @ (middle - target))
        step = (r_u + r_l) * (spec["h"] - design.cover_mm - r_l) / design.layer_distance_mm
        new = dict(
            spec,
            name=f"G{j}_{int(spec['h'])}",
            target=tuple(map(float, target + step * diag)),  # |diag| = √2
            seed=[2026, meta["slab"], 7, j],
        )
        if not _rendered_as(folder / new["name"], new):
            _render_one(scene, new, folder)
            (folder / f"result_{new['name']}.json").unlink(missing_ok=True)  # inspect it anew
        out.append(new["name"])
    return out


def _closer_outcome(folder: Path, name: str) -> dict:
    """What a capture taken from closer for a bar (``Z<capture>_<bar id>``) says of that bar: the
    rendered bar it is (its bar ids), its true size, and the size found for it there (None: not
    found or not sized)."""
    j, bid = (int(x) for x in name[1:].split("_"))
    meta = json.loads((folder / "slab.json").read_text())
    return _bar_outcome(folder, meta["captures"][j], bid, name)


def _area_outcomes(folder: Path, name: str) -> list:
    """What a capture taken from nearer for a capture's pixels (``P<j>``) says of each bar it was
    taken for (``area_P<j>.json``): as :func:`_closer_outcome`, one per bar."""
    rec = json.loads((folder / f"area_{name}.json").read_text())
    return [
        {**_bar_outcome(folder, rec["capture"], int(bid), name), "capture": f"{name} ({rec['capture']} bar {bid})"}
        for bid in rec["bar_ids"]
    ]


def _bar_outcome(folder: Path, cap: str, bid: int, name: str) -> dict:
    """What capture ``name`` says of bar ``bid`` of capture ``cap``."""
    try:
        from study_ambiguous_closer import _truth_id
    except ModuleNotFoundError:
        from benchmarks.study_ambiguous_closer import _truth_id

    bar = next(b for b in json.loads((folder / f"result_{cap}.json").read_text())["bars"] if b["bar_id"] == bid)
    tid = _truth_id(folder / cap, bar)
    truth = next((b for b in json.loads((folder / cap / "truth.json").read_text())["bars"] if b["id"] == tid), None)
    seen = json.loads((folder / f"result_{name}.json").read_text())["bars"]
    # the same rendered bar, of the same lattice and level (a bar of the other lattice beside or
    # under it can match the same rendered bar by position alone)
    got = [
        b
        for b in seen
        if (b.get("layer"), b.get("level")) == (bar.get("layer"), bar.get("level"))
        and _truth_id(folder / name, b) == tid
    ]
    sized = [b for b in got if b.get("diameter_status") == "measured"]
    return {
        "capture": name,
        "true_mm": truth["diameter_mm"] if truth else None,
        "found": bool(got),
        "sized_mm": float(sized[0]["nominal_mm"]) if sized else None,
        "reason": "" if sized or not got else str(got[0].get("diameter_reason"))[:80],
    }


def _truth_judged(folder: Path, caps: list, design) -> dict:
    """The items the slab's own as-built truth fails, judged as a perfect inspection of the same
    captures would be (``rebarlib.synth.result_from_truth``): the placing jitter can put a
    spacing of a slab without a designed defect out of tolerance, and then rejecting it is right.
    The truth holds no missing bar and no bar size other than the true ones, so only the length
    items (cover, layer distance, spacing) and a wrong size can fail here."""
    from rebarlib.synth import result_from_truth

    results = [result_from_truth(folder / c, design, uncertainty_mm=0.0) for c in caps]
    for r in results:  # the truth's spacings are exact: two captures' readings of one pair are equal
        for s in r.get("spacings") or []:
            s.setdefault("uncertainty_mm", 0.0)
    return _judge(results, design, as_asked=False)


def _result(folder: Path, c: str, design, rejudge: bool) -> dict:
    import rebarlib as R

    saved = folder / f"result_{c}.json"
    if rejudge and saved.exists():  # judge again what was inspected before
        return json.loads(saved.read_text())
    res = R.inspect(R.load_capture(folder / c), design, rng=0)
    saved.write_text(res.to_json(), encoding="utf-8")
    return res.to_dict()


#: the decision rule the slabs are judged under (``--decision-rule``): None = as their standard's
#: preset names it
JUDGE = {"rule": None}


def _judge(results: list, design, *, as_asked: bool = True) -> dict:
    """The slab's verdict, its failed and open items; under ``--decision-rule`` where
    ``as_asked`` (the truth is judged as its standard's preset says: its values carry no
    uncertainty, but a bar size's confidence may still leave it "not proven")."""
    import dataclasses

    import rebarlib as R

    tol = None
    if JUDGE["rule"] and as_asked:
        from rebarlib._tolerances import load_tolerances

        tol = dataclasses.replace(load_tolerances(design.standard), decision_rule=JUDGE["rule"])
    acc = R.evaluate(results, design, tol)
    items = acc.items

    def short(i):
        return str(i).split("_lower")[0].split("_upper")[0]

    return {
        "verdict": acc.verdict,
        "failed": sorted({short(i) for i, v in zip(items["item"], items["verdict"]) if v == "fail"}),
        "failed_lots": sorted(str(i) for i, v in zip(items["item"], items["verdict"]) if v == "fail"),
        "passed_lots": sorted(str(i) for i, v in zip(items["item"], items["verdict"]) if v == "pass"),
        "incomplete": sorted({short(i) for i, v in zip(items["item"], items["verdict"]) if v not in ("pass", "fail")}),
        "reasons": list(acc.reasons),
    }


#: what a capture says when a bar position lies hidden under a bar: how far to move the camera
ADVICE = re.compile(r"camera about (\d+) mm or more to either side across these bars")
#: ... and which way keeps the position in view
TOWARDS = re.compile(r"moved towards it \(towards the image's (\w+) edge\)")


def _follow_advice(
    folder: Path, meta: dict, results: list, design, rejudge: bool, *, taken=(), max_captures: int = 4
) -> list:
    """One more capture for each capture first taken that asks for one on the slab's sheet (a
    position still not judged once the captures, ``results``, are judged together), as its first
    such position says (moved across the hidden position's bars by 1.25 times the distance it
    names, towards the position where the sheet says so, else towards the slab's middle; height,
    tilt and heading kept), in the captures' order; then one for each bar asked for from closer
    (:func:`_bars_to_size`); then one placed on both of two captures a lot's verdict depends on
    (:func:`_capture_on_both`). A capture already ``taken`` is not taken again; at most
    ``max_captures`` a slab. Returns the new captures' names."""
    import rebarlib as R

    # the slab's sheet: a position another capture of the slab already judged needs no capture
    sheet = R.evaluate(results, design)
    judged = sheet.results
    out = []
    n_have = len(meta["captures"]) + len(taken)
    for j, (name, res) in enumerate(zip(meta["captures"], judged)):
        if n_have + len(out) >= max_captures:
            break
        for p in res.get("positions") or []:
            m = ADVICE.search(str(p.get("reason") or ""))
            if p.get("status") != "not measured" or not m:
                continue
            _, scene, _, _, specs = _slab_plan(meta["slab"], folder)
            spec = specs[j]
            cam = json.loads((folder / name / "truth.json").read_text())["camera"]
            rot, centre = np.array(cam["rotation_world_to_camera"]), np.array(cam["centre_world_mm"])
            ends = np.array([[p[f"{e}_{a}_mm"] for a in "xyz"] for e in ("start", "end")])
            world = ends @ rot + centre  # camera to world: R^T c + C
            d = world[1, :2] - world[0, :2]
            across = np.array([-d[1], d[0]]) / max(np.linalg.norm(d), 1e-9)
            target = np.array(spec["target"])
            if TOWARDS.search(str(p.get("reason") or "")):  # the sheet names the side: towards the position
                if np.dot(world[:, :2].mean(axis=0) - np.array(cam["centre_world_mm"][:2]), across) < 0:
                    across = -across
            elif np.dot(target, across) > 0:  # towards the slab's middle
                across = -across
            new = dict(
                spec,
                name=f"F{j}_{int(spec['h'])}",
                target=tuple(map(float, target + 1.25 * float(m.group(1)) * across)),
                seed=[2026, meta["slab"], 3, j],
            )
            if new["name"] in taken:  # (the same advice as before: that capture was taken)
                break
            if not _rendered_as(folder / new["name"], new):
                _render_one(scene, new, folder)
                (folder / f"result_{new['name']}.json").unlink(missing_ok=True)  # inspect it anew
            out.append(new["name"])
            break
    covered = set()  # (capture, bar id) a capture from nearer for the capture's pixels was taken for
    unsized = _unsized(sheet)
    for name, g, adv in _areas_to_retake(folder, meta, results, design, unsized):
        j = meta["captures"].index(name)
        covered |= {(name, int(b)) for b in adv["bar_ids"]}
        if f"P{j}_{g}" in taken:
            continue
        if n_have + len(out) >= max_captures:
            break
        out.append(_capture_area(folder, meta, name, g, adv))
    for name, bid, dist in _bars_to_size(folder, meta, results, design, unsized):
        if n_have + len(out) >= max_captures:
            break
        if f"Z{meta['captures'].index(name)}_{bid}" in taken or (name, bid) in covered:
            continue
        out.append(_capture_closer(folder, meta, name, bid, dist))
    if n_have + len(out) < max_captures:
        both = _capture_on_both(folder, meta, sheet, taken)
        if both:
            out.append(both)
    return out


#: what a lot item's reason says when two captures first taken are not placed on each other and
#: the lot's verdict depends on which spacings they share (decision 039): the pairs
BOTH = re.compile(r"captures not placed on each other \(([^)]*)\) may show the same spacings")


def _capture_on_both(folder: Path, meta: dict, sheet, taken=()) -> str | None:
    """The capture a lot's reason on the slab's sheet (``sheet``, :func:`rebarlib.evaluate`'s)
    asks for ("a capture placed on both settles it"): for the first pair it names of captures
    first taken, one half-way between them (the mean of their targets and heights, the first's
    tilt and heading), as a person would stand to see both. Returns its name, or None where no lot
    asks for one."""
    for why in sheet.items["reason"].astype(str):
        m = BOTH.search(why)
        if not m:
            continue
        for pair in m.group(1).split("; "):
            a, _, b = pair.partition(" and ")
            if a not in meta["captures"] or b not in meta["captures"]:
                continue
            ia, ib = sorted((meta["captures"].index(a), meta["captures"].index(b)))
            _, scene, _, _, specs = _slab_plan(meta["slab"], folder)
            sa, sb = specs[ia], specs[ib]
            new = dict(
                sa,
                name=f"B{ia}{ib}_{int(0.5 * (sa['h'] + sb['h']))}",
                h=0.5 * (sa["h"] + sb["h"]),
                target=tuple(float(0.5 * (x + y)) for x, y in zip(sa["target"], sb["target"])),
                seed=[2026, meta["slab"], 6, ia, ib],
            )
            if new["name"] in taken:
                return None
            if not _rendered_as(folder / new["name"], new):
                _render_one(scene, new, folder)
                (folder / f"result_{new['name']}.json").unlink(missing_ok=True)  # inspect it anew
            return new["name"]
    return None


#: what a bar's reason says when a capture from closer, aimed at it, would size it: the distance
CLOSER = re.compile(r"a capture with the camera about (\d+) mm or less from the bar|from about (\d+) mm or less \(this")


def _unsized(sheet):
    """The bar-size checkpoints a slab's sheet (:func:`rebarlib.evaluate`'s, its captures judged
    together) leaves not measured."""
    cp = sheet.checkpoints
    return cp[cp["item"].str.startswith("bar_size") & (cp["status"] == "not measured")]


def _bars_to_size(folder: Path, meta: dict, results: list, design, unsized) -> list:
    """(capture, bar id, advised distance) of each bar the slab's sheet leaves unsized (its
    captures judged together: a bar another capture sized is not asked for) whose reason advises a
    capture from closer (:func:`rebarlib.diameter.closer.closer_advice`, computed on the saved
    bar's row where the result was saved before the advice existed: the advice is a function of
    that row, the capture's intrinsics and the design alone)."""
    import rebarlib as R
    from rebarlib.diameter.closer import closer_advice

    out = []
    for _, row in unsized.iterrows():
        name, bid = str(row["capture"]), int(str(row["what"]).split()[-1])
        if name not in meta["captures"]:
            continue
        bar = next(b for b in results[meta["captures"].index(name)]["bars"] if int(b["bar_id"]) == bid)
        reason = str(bar.get("diameter_reason") or "")
        if not CLOSER.search(reason):
            intr = R.load_capture(folder / name).intrinsics
            ends = [[float(bar[f"{e}_{a}_mm"]) for a in "xyz"] for e in ("start", "end")]
            reason += closer_advice(
                bar, *ends, intr, min_confidence=0.8, system=design.bar_system, deformed=True, design=design
            )
        m = CLOSER.search(reason)
        if m:
            out.append((name, bid, float(m.group(1) or m.group(2))))
    return out


def _areas_to_retake(folder: Path, meta: dict, results: list, design, unsized) -> list:
    """(capture, group, advice) for each group of bars (``groups``: those one capture covers) of
    each capture first taken whose note says its bars were left unsized for its camera's pixels
    and a capture from nearer would give enough (``extras["pixels_for_sizes"]``, ``reachable``;
    docs/decisions/063), counting only the bars the slab's sheet still leaves unsized. Computed
    from the saved bar table where the result was saved before the note existed (the advice is a
    function of the table, the intrinsics and the design alone)."""
    import pandas as pd

    import rebarlib as R
    from rebarlib.diameter.closer import pixels_for_sizes

    out = []
    for name, res in zip(meta["captures"], results):
        adv = (res.get("extras") or {}).get("pixels_for_sizes")
        if adv is None:
            intr = R.load_capture(folder / name).intrinsics
            adv = pixels_for_sizes(pd.DataFrame(res.get("bars") or []), intr, system=design.bar_system, design=design)
        if not adv or not adv.get("reachable"):
            continue
        still = set(unsized.loc[unsized["capture"] == name, "what"].astype(str))
        for g, group in enumerate(adv.get("groups") or [adv["bar_ids"]]):
            ids = [int(b) for b in group if f"bar {int(b)}" in still]
            if ids:
                out.append((name, g, {**adv, "bar_ids": ids}))
    return out


def _capture_area(folder: Path, meta: dict, name: str, g: int, adv: dict) -> str:
    """Take the capture a capture's pixels note asks for, as a person would: the camera's optical
    axis on the middle of the bars it names (with a hand's aim error, ``AIM_ERROR`` of the
    largest design spacing, seeded), tilt and heading kept, the camera as far from that middle
    along the axis as puts the farthest of them at the distance advised (``needed_mm``), not
    nearer than the nearest the note allows; its folder's ``aim.json`` names the bar nearest that
    middle. Returns its name (``P<j>_<group>``)."""

    bars = [
        b
        for b in json.loads((folder / f"result_{name}.json").read_text())["bars"]
        if int(b["bar_id"]) in set(adv["bar_ids"])
    ]
    design, scene, _, _, specs = _slab_plan(meta["slab"], folder)
    j = meta["captures"].index(name)
    spec = specs[j]
    cam = json.loads((folder / name / "truth.json").read_text())["camera"]
    rot, centre = np.array(cam["rotation_world_to_camera"]), np.array(cam["centre_world_mm"])
    mids_cam = np.array([[0.5 * (b[f"start_{a}_mm"] + b[f"end_{a}_mm"]) for a in "xyz"] for b in bars])
    mids = mids_cam @ rot + centre  # to world
    mid = mids.mean(axis=0)
    spacing = max(design.lattice(ly).level(lv).spacing_mm for ly in ("lower", "upper") for lv in ("bottom", "top"))
    err = np.random.default_rng([2026, meta["slab"], 8, j, g]).uniform(-1.0, 1.0, 2) * np.array(AIM_ERROR) * spacing
    mid[:2] += err
    # the bars' depths behind their middle along the axis stay as they were: the farthest at needed_mm
    behind = float((mids_cam[:, 2] - mids_cam[:, 2].mean()).max())
    dist = max(float(adv["needed_mm"]) - behind, float(adv["nearest_mm"]))
    nearest_bar = bars[int(np.argmin(np.linalg.norm(mids[:, :2] - mid[:2], axis=1)))]
    aim = {"aimed_at": {"capture": name, "bar_id": int(nearest_bar["bar_id"])}}
    new = _take_aimed(folder, scene, spec, mid, dist, f"P{j}_{g}", [2026, meta["slab"], 9, j, g], aim)
    # the bars it was taken for, for the outcome table (beside the capture, not in it)
    (folder / f"area_{new}.json").write_text(
        json.dumps({"capture": name, "bar_ids": [int(b) for b in adv["bar_ids"]]}) + "\n", encoding="utf-8"
    )
    return new


#: a person's aim at a bar's middle, as fractions of the bar's design spacing: uniform within
#: this across the bar and within the second along it (docs/decisions/043)
AIM_ERROR = (0.25, 0.5)


def _capture_closer(folder: Path, meta: dict, name: str, bid: int, dist: float) -> str:
    """Take the capture a bar's advice asks for, aimed as a person aims: the camera ``dist`` mm
    from the bar's seen middle along its optical axis, that axis put on the bar's middle with a
    hand's error (uniform within ``AIM_ERROR`` times the bar's design spacing: ±¼ across the bar,
    ±½ along it; seeded per slab, capture and bar), the capture's tilt and heading kept. The
    capture's folder gets the record of its aim (``aim.json``: the capture and bar it was aimed
    at, docs/formats.md). Returns its name."""

    bar = next(b for b in json.loads((folder / f"result_{name}.json").read_text())["bars"] if int(b["bar_id"]) == bid)
    design, scene, _, _, specs = _slab_plan(meta["slab"], folder)
    j = meta["captures"].index(name)
    spec = specs[j]
    cam = json.loads((folder / name / "truth.json").read_text())["camera"]
    rot, centre = np.array(cam["rotation_world_to_camera"]), np.array(cam["centre_world_mm"])
    ends = np.array([[bar[f"{e}_{a}_mm"] for a in "xyz"] for e in ("start", "end")]) @ rot + centre  # to world
    mid = ends.mean(axis=0)
    along = (ends[1, :2] - ends[0, :2]) / max(np.linalg.norm(ends[1, :2] - ends[0, :2]), 1e-9)
    spacing = design.lattice(bar["layer"]).level(bar["level"]).spacing_mm
    err = np.random.default_rng([2026, meta["slab"], 5, j, bid]).uniform(-1.0, 1.0, 2) * np.array(AIM_ERROR) * spacing
    mid[:2] += err[0] * np.array([-along[1], along[0]]) + err[1] * along
    aim = {"aimed_at": {"capture": name, "bar_id": int(bid)}}
    return _take_aimed(folder, scene, spec, mid, dist, f"Z{j}_{bid}", [2026, meta["slab"], 4, j, bid], aim)


def _take_aimed(folder: Path, scene, spec: dict, mid, dist: float, name: str, seed: list, aim: dict) -> str:
    """Render (where the cache does not hold it already) the capture ``name`` a person takes
    aiming at ``mid`` (world, mm): the optical axis of ``spec``'s tilt and heading through it,
    meeting the formwork at the capture's target, the camera ``dist`` mm from it along that axis;
    its folder's ``aim.json`` holds ``aim``. Returns ``name``."""
    from rebarlib import synth as S

    axis = S.CameraPose.looking_down(spec["h"], tilt_deg=spec["tilt"], yaw_deg=spec["yaw"]).rotation.T[:, 2]
    target = mid[:2] - (mid[2] / axis[2]) * axis[:2]
    new = dict(spec, name=name, h=float(mid[2] - dist * axis[2]), target=tuple(map(float, target)), seed=seed)
    aim_file = folder / name / "aim.json"
    if not _rendered_as(folder / name, new) or not aim_file.exists():
        _render_one(scene, new, folder)
        aim_file.write_text(json.dumps(aim) + "\n", encoding="utf-8")
        (folder / f"result_{name}.json").unlink(missing_ok=True)  # inspect it anew
    return name


def _rendered_as(folder: Path, spec: dict) -> bool:
    """Whether ``folder`` holds the capture ``spec`` describes (a cached follow-up capture is
    rendered again where the advice now moves the camera elsewhere)."""
    from rebarlib import synth as S

    truth = folder / "truth.json"
    if not truth.exists():
        return False
    pose = S.CameraPose.looking_down(spec["h"], tilt_deg=spec["tilt"], yaw_deg=spec["yaw"], target_mm=spec["target"])
    seen = np.array(json.loads(truth.read_text())["camera"]["centre_world_mm"])
    return bool(np.linalg.norm(seen - np.asarray(pose.centre, float)) < 1.0)


def main(argv=None) -> int:
    from _cameras import CAMERAS, SENSORS

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--slabs", type=int, default=60)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--cache", default="/tmp/rebarlib_verdicts")
    ap.add_argument("--start", type=int, default=0, help="first slab number")
    ap.add_argument(
        "--rejudge",
        action="store_true",
        help="judge again from the results saved in --cache (no rendering, no inspection)",
    )
    ap.add_argument(
        "--report-only",
        action="store_true",
        help="print the tables from the slabs already judged in --cache (no rendering)",
    )
    ap.add_argument(
        "--follow-advice",
        action="store_true",
        help="where a slab's captures ask for another capture (a position hidden under a bar, a bar a capture "
        "from closer would size), take one for each capture or bar that asks, as told, and judge again; prints "
        "the first judgement's matrix too",
    )
    ap.add_argument(
        "--second-round",
        action="store_true",
        help=f"with --follow-advice: then take what the captures first taken still ask for, once judged with the "
        f"captures of the first round (up to {MAX_CAPTURES[1]} captures a slab, not {MAX_CAPTURES[0]}), and judge "
        "again; prints all three matrices",
    )
    ap.add_argument(
        "--as-guided",
        action="store_true",
        help="as many captures a slab as first taken, but each area twice, the second moved diagonally as "
        "docs/capturing.md says; judged once (not with --follow-advice)",
    )
    ap.add_argument("--camera", default="gemini2", choices=sorted(CAMERAS), help="camera they are rendered with")
    ap.add_argument("--sensor", default="default", choices=sorted(SENSORS), help="depth sensor they are rendered with")
    ap.add_argument(
        "--photo", action="store_true", help="colour images anti-aliased, softened (0.8 px) and JPEG'd (quality 90)"
    )
    ap.add_argument("--ribs", choices=("envelope", "relief"), default="envelope", help="bars' ribs drawn or in relief")
    ap.add_argument(
        "--heights",
        default="400,700",
        help="LO,HI: the band the captures' heights above the formwork are drawn from, mm (default 400,700)",
    )
    ap.add_argument(
        "--designs",
        choices=("default", "other"),
        default="default",
        help="the slabs' designs: the default family, or another (Φ10 at 100 mm to Φ25 at 200 mm, covers 15-40 mm)",
    )
    ap.add_argument(
        "--jitter",
        type=float,
        default=4.0,
        help="each bar placed off its design line by a uniform draw within ± this (mm, on top of a 1.5 mm normal "
        "one), so a spacing is off by up to twice it (default 4)",
    )
    ap.add_argument(
        "--defects",
        choices=("default", "extra"),
        default="default",
        help="the odd slabs' defects: the default six in turn, or an extra bar half-way between two (a set of its own)",
    )
    ap.add_argument(
        "--laps",
        type=int,
        default=0,
        help="bars made of two lapped pieces per slab (side by side over 40 diameters), one capture a slab aimed "
        "at one of them (default 0: none)",
    )
    ap.add_argument(
        "--decision-rule",
        default=None,
        help="judge under this decision rule (simple, guarded, shared risk, proven; docs/uncertainty.md) instead "
        "of the one each slab's standard names; best with --rejudge on a cache",
    )
    args = ap.parse_args(argv)
    if args.decision_rule is not None:
        from rebarlib._decision import check_rule

        try:
            JUDGE["rule"] = check_rule(args.decision_rule, "--decision-rule")
        except ValueError as e:
            ap.error(str(e))
    if not 0 <= args.laps <= 20:
        ap.error(f"--laps: expected 0 to 20 laps a slab, got {args.laps!r}")
    if not 0 <= args.jitter <= 50:
        ap.error(f"--jitter: expected 0 to 50 mm, got {args.jitter!r}")
    try:
        lo, hi = (float(x) for x in args.heights.split(","))
    except ValueError:
        ap.error(f"--heights: expected two numbers LO,HI in mm, got {args.heights!r}")
    if not 0 < lo <= hi:
        ap.error(f"--heights: expected 0 < LO <= HI, got {args.heights!r}")
    RENDER.update(
        camera=args.camera,
        sensor=args.sensor,
        photo=args.photo,
        ribs=args.ribs,
        heights=[lo, hi],
        designs=args.designs,
        jitter_mm=args.jitter,
        defects=args.defects,
        laps=args.laps,
    )
    if args.as_guided and args.follow_advice:
        ap.error("--as-guided is judged without follow-up captures: leave out --follow-advice")
    rounds = 2 if args.second_round else 1
    cache = Path(args.cache)
    cache.mkdir(parents=True, exist_ok=True)
    ks = list(range(args.start, args.start + args.slabs))
    t0 = time.perf_counter()
    name = _verdict_file(args.follow_advice, rounds, args.as_guided)
    if args.report_only:
        recs = [json.loads(f.read_text()) for f in sorted(cache.glob(f"slab_*/{name}"))]
    elif args.rejudge:
        folders = [str(f.parent) for f in sorted(cache.glob("slab_*/slab.json"))]
        with ProcessPoolExecutor(args.jobs) as ex:
            recs = list(ex.map(_rejudge, [(f, args.follow_advice, rounds, args.as_guided) for f in folders]))
    else:
        with ProcessPoolExecutor(args.jobs) as ex:
            jobs = [(k, str(cache), args.follow_advice, rounds, args.as_guided) for k in ks]
            recs = list(ex.map(_render_and_judge, jobs))
    print(
        f"{len(recs)} slabs, {sum(len(r['captures']) + len(r.get('followups', [])) for r in recs)} captures "
        f"({time.perf_counter() - t0:.0f} s with {args.jobs} processes; inspect + judge "
        f"{sum(r['seconds'] for r in recs):.0f} s of it in all)\n"
    )
    if args.follow_advice:
        first = [{**r, **r.get("first_pass", {}), "closer": []} for r in recs]
        n_follow = sum(1 for r in recs if r.get("followups"))
        print("## The captures first taken\n")
        report(first)
        if rounds > 1:
            one = [{**r, **r.get("round_1", {})} for r in recs]
            one = [
                {**r, "closer": [c for c in r.get("closer", []) if c["capture"] in (r.get("followups") or [])]}
                for r in one
            ]
            n1 = sum(len(r.get("followups") or []) for r in one)
            s1 = sum(1 for r in one if r.get("followups"))
            print(f"\n## After the captures the inspection asked for ({n1} captures on {s1} slabs)\n")
            report(one)
        n_caps = sum(len(r.get("followups", [])) for r in recs)
        if rounds > 1:
            print(
                f"\n## After a second round: what the captures first taken still ask for, up to {MAX_CAPTURES[1]} "
                f"captures a slab ({n_caps} captures asked for on {n_follow} slabs in all)\n"
            )
        else:
            print(f"\n## After the captures the inspection asked for ({n_caps} captures on {n_follow} slabs)\n")
    report(recs)
    return 0


def _render_and_judge(args) -> dict:
    k, cache, follow, rounds, guided = args
    return _inspect_slab(_render_slab((k, cache)), follow=follow, rounds=rounds, guided=guided)


def _rejudge(args) -> dict:
    folder, follow, rounds, guided = args
    if follow or guided:
        # these may render captures the cache lacks: only as the slab's own were rendered
        options = ", ".join("--" + k.removesuffix("_mm") for k in RENDER)  # each render key has its option
        _check_rendered_as_asked(folder, f"judge it again with the options it was rendered with ({options})")
    return _inspect_slab(folder, rejudge=True, follow=follow, rounds=rounds, guided=guided)


def report(recs: list) -> None:
    verdicts = ("accepted", "incomplete", "rejected")
    print("| truth \\ verdict | " + " | ".join(verdicts) + " |")
    print("|---|" + "---:|" * len(verdicts))
    rows = (
        ("clean", [r for r in recs if r["defect"] is None and not r.get("truth_failed")]),
        ("clean design, out of tolerance as built", [r for r in recs if r["defect"] is None and r.get("truth_failed")]),
        ("defective", [r for r in recs if r["defect"] is not None]),
    )
    for truth, sel in rows:
        if not sel and truth.startswith("clean design"):
            continue
        print(
            f"| {truth} ({len(sel)}) | " + " | ".join(str(sum(r["verdict"] == v for r in sel)) for v in verdicts) + " |"
        )
    print(
        "\nPer defect: slabs, rejected naming the defect, rejected for something else only, incomplete, "
        "accepted (missed)\n"
    )
    print("| defect | slabs | rejected, names it | rejected, other item only | incomplete | accepted |")
    print("|---|---:|---:|---:|---:|---:|")
    for d in DEFECTS + DEFECTS_EXTRA:
        if d not in DEFECTS and not any(r["defect"] == d for r in recs):
            continue
        sel = [r for r in recs if r["defect"] == d]
        named = sum(r["verdict"] == "rejected" and DEFECT_ITEM[d] in r["failed"] for r in sel)
        other = sum(r["verdict"] == "rejected" and DEFECT_ITEM[d] not in r["failed"] for r in sel)
        print(
            f"| {d} | {len(sel)} | {named} | {other} | {sum(r['verdict'] == 'incomplete' for r in sel)} | "
            f"{sum(r['verdict'] == 'accepted' for r in sel)} |"
        )
    items = ("cover", "layer_distance", "spacing", "bar_size", "bar_count")
    print(
        "\nPer item: false fails (failed on a slab without that defect), missed (defect of that item, "
        "item not failed), left incomplete; lots failed that the truth, judged as a perfect inspection would, "
        "passes\n"
    )
    print("| item | false fails | missed | incomplete (clean slabs) | lots failed, passed in truth |")
    print("|---|---:|---:|---:|---:|")
    for it in items:
        false = sum(
            it in r["failed"] and DEFECT_ITEM.get(r["defect"]) != it and it not in r.get("truth_failed", ())
            for r in recs
        )
        missed = sum(DEFECT_ITEM.get(r["defect"]) == it and it not in r["failed"] for r in recs)
        inc = sum(it in r["incomplete"] for r in recs if r["defect"] is None and not r.get("truth_failed"))
        print(f"| {it} | {false} | {missed} | {inc} | {_lot_false_fails(recs, it)} |")
    causes(recs)
    closer = [(r["slab"], c) for r in recs for c in r.get("closer", [])]
    if closer:
        right = sum(c["sized_mm"] is not None and c["sized_mm"] == c["true_mm"] for _, c in closer)
        wrong = sum(c["sized_mm"] is not None and c["sized_mm"] != c["true_mm"] for _, c in closer)
        lost = sum(not c["found"] for _, c in closer)
        print(
            f"\nBars asked for from closer ({len(closer)}): sized right {right}, sized wrong {wrong}, "
            f"not found {lost}, not sized {len(closer) - right - wrong - lost}\n"
        )
        for k, c in closer:
            got = c["reason"] if c["found"] else "not found"
            got = f"Φ{c['sized_mm']:g}" if c["sized_mm"] is not None else got
            print(f"- slab {k:03d} {c['capture']} (Φ{c['true_mm']:g}): {got}")
    as_built = [r for r in recs if set(r.get("truth_failed", ())) - {DEFECT_ITEM.get(r["defect"])}]
    if as_built:
        print("\nSlabs whose own truth fails an item (the placing jitter; judged as a perfect inspection would):")
        for r in as_built:
            print(
                f"- slab {r['slab']:03d} ({r['defect'] or 'clean design'}): truth fails {r['truth_failed']}; "
                f"verdict {r['verdict']}, failed {r['failed']}"
            )
    print("\nSlabs not as expected:")
    for r in recs:
        want = "accepted" if r["defect"] is None and not r.get("truth_failed") else "rejected"
        extra = [f for f in r["failed"] if f != DEFECT_ITEM.get(r["defect"]) and f not in r.get("truth_failed", ())]
        if r["verdict"] != want or extra:
            print(
                f"- slab {r['slab']:03d} ({r['defect'] or 'clean'}, {len(r['captures'])} captures, edge view "
                f"{r['edge_view']}, shadows {r['shadows']}): {r['verdict']}; failed {r['failed']}; "
                f"incomplete {r['incomplete']}"
            )


def _lot_false_fails(recs: list, item: str):
    """Lots of ``item`` failed that the truth, judged as a perfect inspection would, passes: a
    false fail the per-item count hides where another lot of the item fails in truth (a slab whose
    placing jitter puts one spacing lot out, another lot failed on a misreading). A lot the truth
    leaves open (its captures not placed on each other may repeat a spacing) is not counted. The
    truth holds no bar counts, so "–" for them; so for records judged before the lots were kept."""
    if item == "bar_count" or any("truth_passed_lots" not in r or "failed_lots" not in r for r in recs):
        return "–"
    return sum(
        1
        for r in recs
        for lot in r["failed_lots"]
        if lot.split("_lower")[0].split("_upper")[0] == item and lot in r["truth_passed_lots"]
    )


#: what a checkpoint's reason says, in order: the first that matches names the cause
CAUSES = (
    ("position hidden under a bar", "bar_count", "hidden under another bar"),
    ("other count evidence", "bar_count", ""),
    ("size ambiguous between two sizes", "bar_size", "ambiguous"),
    ("mask and cloud widths disagree", "bar_size", "disagree"),
    ("mask widths scattered", "bar_size", "too scattered"),
    ("too few clean cross-sections", "bar_size", "too few clean cross-sections"),
    ("possible wrong size", "bar_size", "possible wrong size"),
    ("other size reason", "bar_size", ""),
)


def causes(recs: list) -> None:
    """Why the clean slabs left incomplete are: per cause, the slabs whose reasons name it (a slab
    can have several)."""
    clean = [r for r in recs if r["defect"] is None and not r.get("truth_failed") and r["verdict"] == "incomplete"]
    if not clean:
        return
    print(f"\nWhy the {len(clean)} incomplete clean slabs are (a slab may count under several causes)\n")
    print("| cause | item | slabs |")
    print("|---|---|---:|")
    for name, item, key in CAUSES:
        n = 0
        for r in clean:
            text = " ".join(x for x in r["reasons"] if x.startswith("Bar " + item.split("_")[1]))
            hits = [k for nm, it, k in CAUSES if it == item and k and k in text]
            if (key and key in text) or (not key and text and not hits):
                n += 1
        print(f"| {name} | {item} | {n} |")


if __name__ == "__main__":
    sys.exit(main())
