"""The record of a capture's aim (``aim.json``, docs/formats.md): read into the capture's metadata
and its result, written back, and a clear error for each bad content (docs/decisions/043)."""

import json

import pytest

from rebarlib import GEMINI2, RebarInputError, load_capture, save_capture
from rebarlib.synth import synth_capture

SMALL = GEMINI2.scaled(0.25)


@pytest.fixture(scope="module")
def capture(paper_design):
    return synth_capture(paper_design, height_mm=500, tilt_deg=8, intrinsics=SMALL, seed=3, name="Z0_12")


def test_the_aim_is_read_and_written_back(capture, tmp_path):
    folder = save_capture(capture, tmp_path / "Z0_12")
    assert "aimed_at" not in load_capture(folder).metadata  # optional
    (folder / "aim.json").write_text(json.dumps({"aimed_at": {"capture": "C0_600", "bar_id": 12}}))
    back = load_capture(folder)
    assert back.metadata["aimed_at"] == {"capture": "C0_600", "bar_id": 12}
    again = save_capture(back, tmp_path / "copy")
    assert load_capture(again).metadata["aimed_at"] == {"capture": "C0_600", "bar_id": 12}


def test_the_aim_reaches_the_result(capture):
    import dataclasses
    from types import SimpleNamespace

    from rebarlib._inspect import _note_inputs

    cap = dataclasses.replace(capture, metadata={**capture.metadata, "aimed_at": {"capture": "C0", "bar_id": 3}})
    res = _note_inputs(SimpleNamespace(extras={}, notes=[]), cap)
    assert res.extras["aimed_at"] == {"capture": "C0", "bar_id": 3}
    assert "aimed_at" not in _note_inputs(SimpleNamespace(extras={}, notes=[]), capture).extras


@pytest.mark.parametrize(
    "content, match",
    [
        ('{"aimed_at": {"capture": "C0", "bar_id": "12"}}', "got bar_id '12'"),
        ('{"aimed_at": {"capture": "C0", "bar_id": -1}}', "got bar_id -1"),
        ('{"aimed_at": {"capture": "C0", "bar_id": true}}', "got bar_id True"),
        ('{"aimed_at": {"capture": "", "bar_id": 3}}', "got capture ''"),
        ('{"aimed_at": {"capture": "C0"}}', "aimed_at's keys"),
        ('{"aimed_at": {"capture": "C0", "bar_id": 3, "side": "left"}}', "aimed_at's keys"),
        ('{"aim": {"capture": "C0", "bar_id": 3}}', "got the keys"),
        ('{"aimed_at": [1, 2]}', "got the keys"),
        ("[1, 2]", "expected a JSON object"),
        ('{"aimed_at": ', "not valid JSON"),
    ],
)
def test_a_bad_aim_record_names_the_file_and_what_was_expected(capture, tmp_path, content, match):
    folder = save_capture(capture, tmp_path / "Z0_12")
    (folder / "aim.json").write_text(content)
    with pytest.raises(RebarInputError, match="aim.json") as err:
        load_capture(folder)
    assert match in str(err.value)
