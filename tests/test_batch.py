"""Many captures: ``inspect_many``, ``rebar inspect`` over a batch (jobs, resume, lock, atomic
writing, summary.csv), the same batch on a real dask.distributed cluster, and ``rebar report``
over a floor of slabs.

The captures are the shipped examples (copied where a test changes them); geometry only
(``--no-diameters``) wherever the diameters are not what is tested, to keep the file short.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
from pathlib import Path

import pandas as pd
import pytest

from rebarlib import RebarInputError, inspect, load_capture
from rebarlib._outdir import LOCK_NAME, locked, tidy, write_folder_atomically
from rebarlib.batch import Outcome, inspect_many
from rebarlib.cli import main
from rebarlib.data import example_capture, example_slab

PAPER, PAPER_DESIGN = example_slab("paper_slab")
DESIGN_TOML = PAPER / "design.toml"


def _broken_capture(tmp_path) -> Path:
    bad = tmp_path / "caps" / "broken"
    bad.mkdir(parents=True)
    (bad / "camera.json").write_text("{not json", encoding="utf-8")
    return bad


def _copy(tmp_path, *names) -> list:
    out = []
    for n in names:
        dst = tmp_path / "caps" / n
        shutil.copytree(example_capture("paper_slab", n), dst)
        out.append(dst)
    return out


def _summary(out: Path) -> list:
    with open(out / "summary.csv", newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


# ------------------------------------------------------------------------------------------------
# inspect_many
# ------------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_inspect_many_reports_a_failure_and_goes_on(tmp_path):
    bad = _broken_capture(tmp_path)
    a, b = example_capture("paper_slab", "A_400"), example_capture("paper_slab", "B_500")
    seen = []

    def progress(outcome, done, total):
        seen.append((outcome.capture, done, total))

    outcomes = list(
        inspect_many([a, bad, b], PAPER_DESIGN, jobs=1, ordered=True, diameters=False, rng=0, progress=progress)
    )
    assert [o.capture for o in outcomes] == ["A_400", "broken", "B_500"]
    assert [o.index for o in outcomes] == [0, 1, 2]
    assert [o.ok for o in outcomes] == [True, False, True]
    err = outcomes[1].error
    assert "broken: no color.png" in err and "\n" not in err and outcomes[1].result is None
    assert seen == [("A_400", 1, 3), ("broken", 2, 3), ("B_500", 3, 3)]
    # the batch's result is the one inspect() gives for the same capture and seed
    alone = inspect(load_capture(a), PAPER_DESIGN, diameters=False, rng=0)
    pd.testing.assert_frame_equal(outcomes[0].result.bars, alone.bars)
    assert outcomes[0].result.cover == alone.cover


def test_inspect_many_refuses_bad_arguments():
    cap = example_capture("paper_slab", "A_400")
    with pytest.raises(RebarInputError, match="jobs"):
        inspect_many([cap], PAPER_DESIGN, jobs=0)
    with pytest.raises(RebarInputError, match="not both"):
        inspect_many([cap], PAPER_DESIGN, jobs=2, client="tcp://127.0.0.1:1")
    with pytest.raises(RebarInputError, match="seed"):
        import numpy as np

        inspect_many([cap], PAPER_DESIGN, rng=np.random.default_rng(0))
    with pytest.raises(RebarInputError, match="design"):
        inspect_many([cap], {"cover_mm": 20})


def test_inspect_many_reports_an_unexpected_exception_in_one_line(monkeypatch):
    import rebarlib._inspect as stage

    real = stage.inspect

    def flaky(capture, design, **kw):
        if capture.name == "B_500":
            raise ZeroDivisionError("division by zero\nsecond line")
        return real(capture, design, **kw)

    monkeypatch.setattr(stage, "inspect", flaky)
    caps = [example_capture("paper_slab", n) for n in ("A_400", "B_500")]
    got = {o.capture: o for o in inspect_many(caps, PAPER_DESIGN, jobs=1, diameters=False, rng=0)}
    assert got["A_400"].ok and got["B_500"].error == "ZeroDivisionError: division by zero"


@pytest.mark.slow
def test_inspect_many_in_processes_gives_the_results_of_one_process(tmp_path):
    caps = [example_capture("paper_slab", n) for n in ("A_400", "B_500", "C_600")]
    caps.append(_broken_capture(tmp_path))
    one = {o.capture: o for o in inspect_many(caps, PAPER_DESIGN, jobs=1, rng=0)}
    two = list(inspect_many(caps, PAPER_DESIGN, jobs=2, ordered=True, rng=0))
    assert [o.index for o in two] == [0, 1, 2, 3]
    assert not two[3].ok and two[3].error == one["broken"].error
    for o in two[:3]:
        assert o.ok, o.error
        assert o.result.to_dict()["bars"] == one[o.capture].result.to_dict()["bars"]
        assert o.result.to_dict()["spacings"] == one[o.capture].result.to_dict()["spacings"]


# ------------------------------------------------------------------------------------------------
# rebar inspect: summary, failures, resume
# ------------------------------------------------------------------------------------------------


def _inspect(caps, out, *extra):
    return main(
        [
            "inspect",
            *map(str, caps),
            "--design",
            str(DESIGN_TOML),
            "--out",
            str(out),
            "--no-diameters",
            "--jobs",
            "1",
            *extra,
        ]
    )


def test_cli_batch_summary_manifest_and_a_failed_capture(tmp_path, capsys):
    caps = [example_capture("paper_slab", "A_400"), _broken_capture(tmp_path), example_capture("paper_slab", "D_500")]
    out = tmp_path / "out"
    assert _inspect(caps, out) == 1  # one capture failed: status 1, the others written
    captured = capsys.readouterr()
    assert "broken: error:" in captured.err and "1 failed" in captured.err
    rows = _summary(out)
    assert [r["capture"] for r in rows] == ["A_400", "broken", "D_500"]
    assert [r["status"] for r in rows] == ["ok", "failed", "ok"]
    assert "no color.png" in rows[1]["reason"] and rows[1]["cover_mm"] == ""
    for r in (rows[0], rows[2]):
        data = json.loads((out / r["capture"] / "result.json").read_text(encoding="utf-8"))
        assert float(r["cover_mm"]) == data["cover_mm"]
        assert float(r["layer_distance_mm"]) == data["layer_distance_mm"]
        devs = [s["deviation_mm"] for s in data["spacings"] if s["deviation_mm"] is not None]
        assert float(r["worst_spacing_deviation_mm"]) == max(devs, key=abs)
        assert float(r["seconds"]) > 0
        m = data["manifest"]
        assert m["method"] == "refined"
        assert m["options"] == {"diameters": False, "mask_source": None, "seed": 0}
        assert m["capture_folder"] == str(example_capture("paper_slab", r["capture"]).resolve())
    assert not (out / "broken").exists()
    # no lock, no temporary folder left
    assert sorted(p.name for p in out.iterdir()) == ["A_400", "D_500", "summary.csv"]


@pytest.mark.slow
def test_cli_resume_keeps_only_results_of_the_same_inputs(tmp_path, capsys):
    a, b = _copy(tmp_path, "A_400", "B_500")
    out = tmp_path / "out"
    assert _inspect([a, b], out) == 0
    before = {n: (out / n / "result.json").read_bytes() for n in ("A_400", "B_500")}
    assert _inspect([a, b], out, "--resume") == 0
    assert [r["status"] for r in _summary(out)] == ["resumed", "resumed"]
    assert [r["seconds"] for r in _summary(out)] == ["", ""]
    assert {n: (out / n / "result.json").read_bytes() for n in before} == before
    # a changed capture file, another seed, another design file: computed again
    camera = (b / "camera.json").read_text(encoding="utf-8")
    (b / "camera.json").write_text(camera + " ", encoding="utf-8")
    assert _inspect([a, b], out, "--resume") == 0
    assert [r["status"] for r in _summary(out)] == ["resumed", "ok"]
    assert _inspect([a, b], out, "--resume", "--seed", "1") == 0
    assert [r["status"] for r in _summary(out)] == ["ok", "ok"]
    other = tmp_path / "design.toml"
    other.write_text(DESIGN_TOML.read_text(encoding="utf-8") + "\n# another file\n", encoding="utf-8")
    assert (
        main(
            ["inspect", str(a), "--design", str(other), "--out", str(out), "--no-diameters", "--seed", "1", "--resume"]
        )
        == 0
    )
    assert [r["status"] for r in _summary(out)] == ["ok"]
    # a result without a manifest (an older rebarlib) or with a missing table is not resumed
    data = json.loads((out / "A_400" / "result.json").read_text(encoding="utf-8"))
    del data["manifest"]
    (out / "A_400" / "result.json").write_text(json.dumps(data), encoding="utf-8")
    (out / "B_500" / "bars.csv").unlink()
    assert _inspect([a, b], out, "--resume", "--seed", "1") == 0
    assert [r["status"] for r in _summary(out)] == ["ok", "ok"]
    assert "manifest" in json.loads((out / "A_400" / "result.json").read_text(encoding="utf-8"))


# ------------------------------------------------------------------------------------------------
# rebar inspect: output paths, lock, atomic writing
# ------------------------------------------------------------------------------------------------


@pytest.fixture
def no_compute(monkeypatch):
    """Fail the test if anything is inspected."""
    import rebarlib.batch as batch

    def boom(*a, **k):
        raise AssertionError("a capture was inspected although the output paths were wrong")

    monkeypatch.setattr(batch, "inspect_one", boom)


def test_cli_checks_output_paths_before_computing(tmp_path, capsys, no_compute):
    cap = example_capture("paper_slab", "A_400")
    out = tmp_path / "out"
    out.mkdir()
    (out / "A_400").write_text("a file where the results go", encoding="utf-8")
    assert _inspect([cap], out) == 2
    assert "A_400 exists and is not a folder" in capsys.readouterr().err
    afile = tmp_path / "file.txt"
    afile.write_text("x", encoding="utf-8")
    assert _inspect([cap], afile / "out") == 2
    assert "is a file" in capsys.readouterr().err
    assert _inspect([cap], afile) == 2
    assert "not a folder" in capsys.readouterr().err


def test_cli_refuses_a_second_run_into_the_same_folder(tmp_path, capsys, no_compute):
    out = tmp_path / "out"
    with locked(out):
        assert _inspect([example_capture("paper_slab", "A_400")], out) == 2
        err = capsys.readouterr().err
        assert "another rebar run is writing into this folder" in err
        assert f"pid {os.getpid()}" in err
    assert not (out / LOCK_NAME).exists()  # released and removed at the end of the first run


def test_a_result_is_replaced_only_by_a_whole_new_one(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    write_folder_atomically(out, "A", {"result.json": "old\n", "bars.csv": "old\n"})

    class Unwritable:
        pass

    with pytest.raises(TypeError):  # the second file cannot be written: the old result stays
        write_folder_atomically(out, "A", {"result.json": "new\n", "bars.csv": Unwritable()})
    assert (out / "A" / "result.json").read_text() == "old\n"
    assert sorted(p.name for p in out.iterdir()) == ["A"]
    write_folder_atomically(out, "A", {"result.json": "new\n"})
    assert sorted(p.name for p in (out / "A").iterdir()) == ["result.json"]
    assert (out / "A" / "result.json").read_text() == "new\n"


def test_tidy_puts_back_a_result_moved_aside_by_a_killed_run(tmp_path):
    out = tmp_path / "out"
    (out / ".old-A-123").mkdir(parents=True)  # killed between moving A aside and the new A in
    (out / ".old-A-123" / "result.json").write_text("old", encoding="utf-8")
    (out / ".tmp-B-123").mkdir()  # killed while writing B
    (out / "C").mkdir()
    (out / ".old-C-77").mkdir()  # killed after C was in place, before the old one was removed
    tidy(out)
    assert sorted(p.name for p in out.iterdir()) == ["A", "C"]
    assert (out / "A" / "result.json").read_text(encoding="utf-8") == "old"


# ------------------------------------------------------------------------------------------------
# dask.distributed: a real scheduler and two workers on this machine
# ------------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_dask_cluster_gives_the_local_results(tmp_path, capsys):
    distributed = pytest.importorskip("distributed")

    caps = [example_capture("paper_slab", n) for n in ("A_400", "C_600")]
    caps.append(_broken_capture(tmp_path))
    local, remote = tmp_path / "local", tmp_path / "dask"
    assert _inspect(caps, local) == 1
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, host="127.0.0.1"
    ) as cluster:
        assert len(cluster.workers) == 2
        rc = main(
            [
                "inspect",
                *map(str, caps),
                "--design",
                str(DESIGN_TOML),
                "--out",
                str(remote),
                "--no-diameters",
                "--dask",
                cluster.scheduler_address,
            ]
        )
        with distributed.Client(cluster.scheduler_address) as client:
            ran_on = client.run(lambda: os.getpid())
    assert rc == 1 and len(set(ran_on.values()) - {os.getpid()}) == 2

    def without_seconds(rows):
        return [{k: v for k, v in r.items() if k != "seconds"} for r in rows]

    assert without_seconds(_summary(remote)) == without_seconds(_summary(local))
    for name in ("A_400", "C_600"):
        for f in ("bars.csv", "spacings.csv", "counts.csv"):
            assert (remote / name / f).read_bytes() == (local / name / f).read_bytes(), (name, f)


def test_outcome_ok():
    assert Outcome(0, "a", None).ok and not Outcome(0, "a", None, error="x").ok


# ------------------------------------------------------------------------------------------------
# rebar report over a floor: a folder of slab folders
# ------------------------------------------------------------------------------------------------


@pytest.fixture
def floor(tmp_path):
    """A floor of two slabs: the paper slab (its captures linked) and one whose design is broken."""
    fl = tmp_path / "floor"
    fl.mkdir()
    (fl / "S1").symlink_to(PAPER, target_is_directory=True)
    (fl / "S2" / "A_400").mkdir(parents=True)
    (fl / "S2" / "design.toml").write_text("[design]\ncover_mm = 'twenty'\n", encoding="utf-8")
    shutil.copy(example_capture("paper_slab", "A_400") / "camera.json", fl / "S2" / "A_400")
    return fl


def test_floor_report_one_report_per_slab_and_a_summary(floor, tmp_path, capsys):
    res = tmp_path / "res"
    assert (
        main(
            [
                "inspect",
                str(floor / "S1" / "A_400"),
                "--design",
                str(DESIGN_TOML),
                "--out",
                str(res / "S1"),
                "--no-diameters",
                "--quiet",
            ]
        )
        == 0
    )
    out = tmp_path / "reports"
    rc = main(["report", str(floor), "--results", str(res), "--out", str(out), "--format", "html", "--quiet"])
    assert rc == 1  # S2 could not be reported; S1 was
    rows = {r["slab"]: r for r in _summary_of(out / "floor_summary.csv")}
    assert list(rows) == ["S1", "S2"]
    s1 = rows["S1"]
    saved = json.loads((out / "S1_acceptance.json").read_text(encoding="utf-8"))
    assert s1["verdict"] == saved["verdict"] == "incomplete" and s1["slab_id"] == "S-101"
    assert s1["report"] == "S1.html" and (out / "S1.html").is_file()
    assert (out / "S1_checkpoints.csv").is_file()
    # only A_400 was inspected
    assert s1["captures"] == "4" and s1["captures_without_result"] == "3"
    failed = [i["item"] for i in saved["items"] if i["verdict"] == "fail"]
    still_open = [i["item"] for i in saved["items"] if i["verdict"] in ("not measured", "incomplete")]
    assert s1["failed_items"].split(";") == (failed or [""])
    assert s1["open_items"].split(";") == (still_open or [""])
    assert rows["S2"]["verdict"] == "not reported" and "S2/design.toml" in rows["S2"]["reason"]
    assert not (out / "S2.html").exists()
    assert "1 not reported" in capsys.readouterr().err


def test_floor_report_as_pdf_renders_each_slab_while_the_next_is_judged(tmp_path, capsys):
    """PDFs of a floor are rendered by a helper process while the next slab is judged: every
    slab still gets its report, exports and row, in the floor's order."""
    import pypdf

    fl = tmp_path / "floor"
    fl.mkdir()
    for name, slab in (("S1", "paper_slab"), ("S2", "site_slab"), ("S3", "paper_slab")):
        (fl / name).symlink_to(example_slab(slab)[0], target_is_directory=True)
    out = tmp_path / "reports"
    for name in ("S1", "S2", "S3"):  # no capture has a result: every slab is reported incomplete
        (tmp_path / "none" / name).mkdir(parents=True)
    assert main(["report", str(fl), "--results", str(tmp_path / "none"), "--out", str(out), "--quiet"]) == 0
    rows = {r["slab"]: r for r in _summary_of(out / "floor_summary.csv")}
    assert list(rows) == ["S1", "S2", "S3"]
    for name, row in rows.items():
        assert row["verdict"] == "incomplete" and row["report"] == f"{name}.pdf"
        text = " ".join(p.extract_text() for p in pypdf.PdfReader(str(out / f"{name}.pdf")).pages)
        assert row["slab_id"] in text and "NOT ACCEPTED (incomplete" in text
        saved = json.loads((out / f"{name}_acceptance.json").read_text(encoding="utf-8"))
        assert saved["verdict"] == "incomplete" and (out / f"{name}_checkpoints.csv").is_file()
    assert "floor floor: 3 slabs: 3 incomplete" in capsys.readouterr().out


def test_floor_report_under_another_decision_rule(tmp_path, capsys):
    fl = tmp_path / "floor"
    fl.mkdir()
    for name in ("S1", "S2"):
        (fl / name).symlink_to(example_slab("paper_slab")[0], target_is_directory=True)
        (tmp_path / "none" / name).mkdir(parents=True)
    out = tmp_path / "reports"
    args = ["report", str(fl), "--results", str(tmp_path / "none"), "--format", "html", "--quiet"]
    assert main(args + ["--out", str(tmp_path / "bad"), "--decision-rule", "lenient"]) == 2
    assert "--decision-rule" in capsys.readouterr().err and not (tmp_path / "bad").exists()
    assert main(args + ["--out", str(out), "--decision-rule", "guarded"]) == 0
    for name in ("S1", "S2"):
        saved = json.loads((out / f"{name}_acceptance.json").read_text(encoding="utf-8"))
        assert saved["decision"]["rule"] == "guarded"


def test_pdf_writer_hands_one_document_at_a_time(tmp_path):
    from rebarlib._pdf_writer import PdfWriter
    from rebarlib.report import templates_dir

    with PdfWriter() as writer:
        writer.submit("<p>one</p>", tmp_path / "one.pdf", templates_dir())
        with pytest.raises(RuntimeError, match="one.pdf was not collected"):
            writer.submit("<p>two</p>", tmp_path / "two.pdf", templates_dir())
        writer.collect()
        writer.submit("<p>two</p>", tmp_path / "two.pdf", templates_dir())
    # leaving the block waited for the second document
    assert (tmp_path / "one.pdf").read_bytes()[:5] == b"%PDF-" and (tmp_path / "two.pdf").read_bytes()[:5] == b"%PDF-"


def test_floor_report_checks_its_outputs_before_computing(floor, tmp_path, capsys, no_compute):
    out = tmp_path / "reports"
    out.mkdir()
    (out / "S1.html").write_text("an earlier report", encoding="utf-8")
    assert main(["report", str(floor), "--out", str(out), "--format", "html"]) == 2
    assert "S1.html exists" in capsys.readouterr().err
    assert main(["report", str(floor), "--out", str(out / "floor.pdf")]) == 2
    assert "give a folder" in capsys.readouterr().err
    assert (out / "S1.html").read_text(encoding="utf-8") == "an earlier report"


def _summary_of(path: Path) -> list:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def test_summary_table_is_the_summary_csv_of_the_outcomes(tmp_path):
    from rebarlib.batch import SUMMARY_COLUMNS, summary_table

    caps = [example_capture("paper_slab", "D_500"), _broken_capture(tmp_path)]
    outcomes = list(inspect_many(caps, PAPER_DESIGN, jobs=1, diameters=False, rng=0))
    table = summary_table(outcomes[::-1])  # back in the captures' order
    assert list(table.columns) == list(SUMMARY_COLUMNS)
    assert list(table["capture"]) == ["D_500", "broken"]
    assert list(table["status"]) == ["ok", "failed"]
    data = outcomes[0].result.to_dict()
    assert table.loc[0, "cover_mm"] == data["cover_mm"]
    assert table.loc[0, "layer_distance_mm"] == data["layer_distance_mm"]
    assert pd.isna(table.loc[1, "cover_mm"]) and "no color.png" in table.loc[1, "reason"]


def test_cli_prints_a_capture_name_with_control_characters_escaped(tmp_path, capsys):
    cap = tmp_path / "caps" / "A\nfake: cover 20.0 mm\x1b[2J"
    shutil.copytree(example_capture("paper_slab", "A_400"), cap)
    assert _inspect([cap], tmp_path / "out") == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\\x1b" in out and "A\\nfake" in out
    assert not any(line.startswith("fake") for line in out.splitlines())
    # the file keeps the real name
    assert [r["capture"] for r in _summary(tmp_path / "out")] == [cap.name]
