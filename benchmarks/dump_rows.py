"""Dump every table row the inspection produces on a fixed set of captures, to check that a
restructuring changed nothing.

    python benchmarks/dump_rows.py OUT_DIR            # run and write the rows
    python benchmarks/dump_rows.py --compare A B      # report every difference between two dumps

The captures: the shipped examples (``examples/``) and a few seeded synthetic ones
(``rebarlib.synth``: varied heights, tilts, seeds, deviations, one with ribs in relief). Each is
inspected with the refined method and the paper's; the diameter stage is also run on the true
axes with its options varied, and the bar-size tables are dumped over a grid of widths.

Every value is written as text; a float as its ``repr``, so two dumps compare bit for bit. Rows
are sorted by their keys. Files:

- ``bars.csv``, ``spacings.csv``, ``summary.csv``: the inspection's bars and spacings tables
  and its per-capture numbers (cover, layer distance, formwork, camera, extras, notes).
- ``diameters.csv``: ``measure_diameters`` on the true axes, one row per bar and option set.
- ``scores.csv``: each synthetic result scored against its truth (``score_result``).
- ``barsizes.csv``: ``snap_diameter`` and the size tables over a grid of widths.
- ``others_*.csv``: what other work may change on purpose (the counts and positions verdicts,
  the uncertainty columns). Compared too, but reported apart.

Runs in about 3 minutes on 2 cores (single-threaded numerics, so the results do not depend on
the load).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: columns other sessions change on purpose: dumped to others_*.csv, reported apart
UNCERTAINTY_COLUMNS = ("uncertainty_mm", "width_uncertainty_mm", "budget_confidence")
#: extras keys owned elsewhere (the uncertainty budget)
OTHER_EXTRAS = ("uncertainty",)


# --------------------------------------------------------------------------------------------
# Text form of a value


def text(v) -> str:
    """A value as exact text: floats by ``repr`` (round-trip), containers as JSON of texts."""
    if v is None:
        return "None"
    if isinstance(v, (bool, np.bool_)):
        return str(bool(v))
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    if isinstance(v, str):
        return v
    if isinstance(v, np.ndarray):
        return json.dumps([text(x) for x in v.ravel().tolist()] + [f"shape={v.shape}"])
    if isinstance(v, dict):
        return json.dumps({str(k): text(x) for k, x in sorted(v.items(), key=lambda kv: str(kv[0]))})
    if isinstance(v, (list, tuple, set, frozenset)):
        seq = sorted(v, key=str) if isinstance(v, (set, frozenset)) else v
        return json.dumps([text(x) for x in seq])
    if hasattr(v, "to_dict"):
        return text(v.to_dict())
    if hasattr(v, "__dataclass_fields__"):
        return text({k: getattr(v, k) for k in v.__dataclass_fields__})
    return repr(v)


def _sort_key(cell: str):
    try:
        return (0, float(cell), cell)
    except ValueError:
        return (1, 0.0, cell)


class Table:
    """Rows of one output file: dicts of texts, keyed by ``keys``."""

    def __init__(self, keys):
        self.keys = list(keys)
        self.rows = []

    def add(self, row: dict) -> None:
        self.rows.append({k: text(v) for k, v in row.items()})

    def add_frame(self, df, **fixed) -> None:
        if df is None:
            self.add({**fixed, "_table": "None"})
            return
        for rec in df.to_dict(orient="records"):
            self.add({**fixed, **rec})

    def write(self, path: Path) -> None:
        cols = list(self.keys)
        for r in self.rows:
            cols += [c for c in r if c not in cols]
        rows = sorted(self.rows, key=lambda r: [_sort_key(r.get(k, "")) for k in cols])
        with open(path, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=cols, restval="<absent>")
            w.writeheader()
            w.writerows(rows)


# --------------------------------------------------------------------------------------------
# The captures


def _synthetic_cases():
    """(name, design, capture) of the seeded synthetic captures."""
    from rebarlib import GEMINI2
    from rebarlib.data import paper_design, site_design
    from rebarlib.synth import Deviations, SensorModel, synth_capture

    half = GEMINI2.scaled(0.5)
    paper, site = paper_design(), site_design()
    specs = [
        ("syn_paper_400_t0", paper, dict(height_mm=400, tilt_deg=0, seed=1, intrinsics=half)),
        (
            "syn_paper_500_t10",
            paper,
            dict(
                height_mm=500,
                tilt_deg=10,
                yaw_deg=5,
                seed=2,
                deviations=Deviations(mesh_yaw_deg=7.0, wrong_size=2),
                intrinsics=half,
            ),
        ),
        (
            "syn_paper_600_t15",
            paper,
            dict(
                height_mm=600,
                tilt_deg=15,
                yaw_deg=-4,
                seed=3,
                deviations=Deviations(missing=1, bow_mm=3.0),
                intrinsics=half,
            ),
        ),
        (
            "syn_site_450_t5",
            site,
            dict(
                height_mm=450,
                tilt_deg=5,
                seed=4,
                deviations=Deviations(mesh_yaw_deg=21.0, position_sigma_mm=4.0),
                intrinsics=half,
            ),
        ),
        (
            "syn_paper_stacked",
            paper,
            dict(height_mm=500, tilt_deg=8, seed=5, deviations=Deviations(stacked=True), intrinsics=half),
        ),
        (
            "syn_paper_ideal_full",
            paper,
            dict(height_mm=450, tilt_deg=5, seed=6, sensor=SensorModel.ideal(), intrinsics=GEMINI2),
        ),
        (
            "syn_paper_relief",
            paper,
            dict(
                height_mm=400,
                tilt_deg=5,
                seed=7,
                deviations=Deviations(rib_relief=True, spacers=False, chairs=False, ties=False),
                intrinsics=half,
            ),
        ),
    ]
    for name, design, kw in specs:
        yield name, design, synth_capture(design, name=name, **kw)


def _example_cases():
    from rebarlib import load_capture, load_design

    for slab in sorted((ROOT / "examples").iterdir()):
        if not (slab / "design.toml").exists():
            continue
        design = load_design(slab / "design.toml")
        for cap_dir in sorted(p for p in slab.iterdir() if p.is_dir()):
            yield f"ex_{slab.name}_{cap_dir.name}", design, load_capture(cap_dir)


# --------------------------------------------------------------------------------------------
# Dumping


def _split_columns(df):
    """(own columns, the uncertainty columns) of a table."""
    if df is None:
        return None, None
    other = [c for c in df.columns if c in UNCERTAINTY_COLUMNS]
    return df.drop(columns=other), df[[c for c in df.columns if c in other or c in _KEYS]]


_KEYS = ("bar_id", "layer", "level", "bar_a", "bar_b")


def _summary_row(case: str, method: str, res) -> tuple[dict, dict]:
    row = {"case": case, "method": method}
    other = {"case": case, "method": method}
    for name in ("cover", "layer_distance", "upper_top", "top_cover"):
        m = getattr(res, name)
        row[f"{name}.value_mm"] = m.value_mm
        row[f"{name}.n_points"] = m.n_points
        row[f"{name}.status"] = m.status
        row[f"{name}.reason"] = m.reason
        other[f"{name}.uncertainty_mm"] = m.uncertainty_mm
    row["formwork"] = res.formwork
    row["camera"] = res.camera
    row["notes"] = list(res.notes)
    for k, v in sorted(res.extras.items()):
        (other if k in OTHER_EXTRAS else row)[f"extras.{k}"] = v
    row["bar_points"] = {int(k): int(len(v.points)) for k, v in res.bar_points.items()}
    return row, other


def _diameter_variants():
    return [
        ("default", {}),
        ("veto", dict(use_cloud="veto")),
        ("no_cloud", dict(use_cloud=False)),
        ("colour_replace", dict(colour_edges="replace")),
        ("colour_off", dict(colour_edges=False)),
        ("smooth", dict(deformed=False)),
        ("no_depth", dict(use_depth=False)),
        ("paper", dict(method="paper")),
    ]


def _barsize_rows(table: Table) -> None:
    try:  # (the bar sizes' module before and after it moved: one script compares both)
        from rebarlib.diameter import barsizes as B
    except ImportError:
        from rebarlib import _barsizes as B
    BAR_SYSTEMS, bar_system, barset_width_mm = B.BAR_SYSTEMS, B.bar_system, B.barset_width_mm
    bracketing_sizes, core_size, observed_width_mm = (B.bracketing_sizes, B.core_size, B.observed_width_mm)
    rib_height_mm, rib_pitch_mm, size_half_gaps_mm = (B.rib_height_mm, B.rib_pitch_mm, B.size_half_gaps_mm)
    snap_diameter = B.snap_diameter

    for name in sorted(BAR_SYSTEMS):
        s = bar_system(name)
        table.add({"kind": "system", "system": name, "value": s})
        for size in s.sizes_mm:
            table.add(
                {
                    "kind": "size",
                    "system": name,
                    "x": size,
                    "value": [
                        size_half_gaps_mm(size, system=name),
                        size_half_gaps_mm(size, system=name, deformed=False),
                        observed_width_mm(size, system=name),
                        observed_width_mm(size, system=name, deformed=False),
                        rib_pitch_mm(size, system=name),
                    ],
                }
            )
        for w in np.round(np.arange(4.0, 45.0, 0.37), 2):
            w = float(w)
            for deformed in (True, False):
                for sigma in (0.0, 0.4):
                    table.add(
                        {
                            "kind": f"snap_{sigma}",
                            "system": name,
                            "x": w,
                            "deformed": deformed,
                            "value": snap_diameter(w, system=name, deformed=deformed, sigma_mm=sigma),
                        }
                    )
            table.add({"kind": "bracket", "system": name, "x": w, "value": bracketing_sizes(w, system=name)})
    for w in np.round(np.arange(4.0, 45.0, 0.37), 2):
        table.add(
            {
                "kind": "core_rib",
                "system": "GB1499.2",
                "x": float(w),
                "value": [core_size(float(w)), rib_height_mm(float(w))],
            }
        )
    from rebarlib.data import paper_design, site_design

    for dname, d in (("paper", paper_design()), ("site", site_design())):
        for layer in ("lower", "upper"):
            bs = d.lattice(layer).level("bottom")
            table.add(
                {"kind": "barset", "system": dname, "x": layer, "value": barset_width_mm(bs, system=d.bar_system)}
            )


def dump(out: Path, *, quick: bool = False) -> None:
    from rebarlib import inspect

    try:  # (before and after the top level kept only the workflow)
        from rebarlib.diameter import bars_from_truth, measure_diameters
    except ImportError:
        from rebarlib import bars_from_truth, measure_diameters

    try:  # (before and after the scoring moved)
        from rebarlib.geometry.scoring import score_result
    except ImportError:
        from rebarlib._geom_eval import score_result

    out.mkdir(parents=True, exist_ok=True)
    bars, spacings, summary = (
        Table(["case", "method", "bar_id"]),
        Table(["case", "method", "layer", "level", "bar_a", "bar_b"]),
        Table(["case", "method"]),
    )
    o_unc, o_counts, o_pos, o_summary = (
        Table(["case", "method", "table", "bar_id"]),
        Table(["case", "method", "layer", "level"]),
        Table(["case", "method", "layer", "level"]),
        Table(["case", "method"]),
    )
    diam, scores = Table(["case", "variant", "bar_id"]), Table(["case", "method"])
    sizes = Table(["kind", "system", "x", "deformed"])

    t0 = time.time()
    cases = list(_example_cases())
    t_render = time.time()
    cases += list(_synthetic_cases())
    print(f"rendered the synthetic captures in {time.time() - t_render:.0f} s", flush=True)
    if quick:
        cases = cases[:1] + cases[-2:-1]
    for case, design, cap in cases:
        t = time.time()
        methods = ("refined", "paper")
        for method in methods:
            res = inspect(cap, design, method=method, rng=0)
            own, unc = _split_columns(res.bars)
            bars.add_frame(own, case=case, method=method)
            o_unc.add_frame(unc, case=case, method=method, table="bars")
            own, unc = _split_columns(res.spacings)
            spacings.add_frame(own, case=case, method=method)
            o_unc.add_frame(unc, case=case, method=method, table="spacings")
            o_counts.add_frame(res.counts, case=case, method=method)
            o_pos.add_frame(res.positions, case=case, method=method)
            row, other = _summary_row(case, method, res)
            summary.add(row)
            o_summary.add(other)
            if cap.truth:
                s = score_result(res, cap)
                m = s.pop("matches")
                s["matches"] = m.to_dict(orient="list")
                scores.add({"case": case, "method": method, **s})
        if cap.truth and case.startswith("syn_"):
            truth_bars = bars_from_truth(cap.truth)
            for variant, kw in _diameter_variants():
                table = measure_diameters(cap, truth_bars, cap.labels > 0, design=design, **kw)
                diam.add_frame(table, case=case, variant=variant)
        print(f"{case}: {time.time() - t:.1f} s", flush=True)
    _barsize_rows(sizes)

    for name, table in (
        ("bars", bars),
        ("spacings", spacings),
        ("summary", summary),
        ("diameters", diam),
        ("scores", scores),
        ("barsizes", sizes),
        ("others_uncertainty", o_unc),
        ("others_counts", o_counts),
        ("others_positions", o_pos),
        ("others_summary", o_summary),
    ):
        table.write(out / f"{name}.csv")
    print(f"wrote {out} in {time.time() - t0:.0f} s")


# --------------------------------------------------------------------------------------------
# Comparing


def _read(path: Path):
    with open(path, newline="") as f:
        r = csv.reader(f)
        header = next(r)
        return header, [row for row in r]


def compare(a: Path, b: Path, *, show: int = 20) -> int:
    """Print every difference between the dumps in ``a`` and ``b``; the number of differences."""
    csv.field_size_limit(sys.maxsize)
    names = sorted({p.name for p in a.glob("*.csv")} | {p.name for p in b.glob("*.csv")})
    total_own = total_other = 0
    for name in names:
        pa, pb = a / name, b / name
        if not pa.exists() or not pb.exists():
            print(f"{name}: only in {a if pa.exists() else b}")
            total_own += 1
            continue
        ha, ra = _read(pa)
        hb, rb = _read(pb)
        diffs = []
        if ha != hb:
            diffs.append(
                f"columns differ: only in A {sorted(set(ha) - set(hb))}, "
                f"only in B {sorted(set(hb) - set(ha))}, order equal: "
                f"{[c for c in ha if c in hb] == [c for c in hb if c in ha]}"
            )
        if len(ra) != len(rb):
            diffs.append(f"{len(ra)} rows against {len(rb)}")
        common = [c for c in ha if c in hb]
        ia, ib = [ha.index(c) for c in common], [hb.index(c) for c in common]
        for n, (x, y) in enumerate(zip(ra, rb)):
            for c, i, j in zip(common, ia, ib):
                if x[i] != y[j]:
                    diffs.append(f"row {n} ({', '.join(x[:3])}) {c}: {x[i]!r} -> {y[j]!r}")
        kind = "other sessions' columns" if name.startswith("others_") else "own"
        if diffs:
            print(f"{name} [{kind}]: {len(diffs)} difference(s)")
            for d in diffs[:show]:
                print("   ", d[:400])
        else:
            print(f"{name} [{kind}]: identical ({len(ra)} rows, {len(ha)} columns)")
        if name.startswith("others_"):
            total_other += len(diffs)
        else:
            total_own += len(diffs)
    verdict = "IDENTICAL" if total_own == 0 else "DIFFERENT"
    print(f"{verdict}: {total_own} difference(s) in the dumped rows, {total_other} in other sessions' columns")
    return total_own


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", nargs="?", type=Path, help="folder to write the rows into")
    ap.add_argument("--compare", nargs=2, type=Path, metavar=("A", "B"), help="compare two dumps instead")
    ap.add_argument("--quick", action="store_true", help="two captures only (a smoke test)")
    args = ap.parse_args(argv)
    if args.compare:
        return 1 if compare(*args.compare) else 0
    if args.out is None:
        ap.error("give an output folder or --compare A B")
    dump(args.out, quick=args.quick)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
