"""An output is resumed only by the sweep that wrote it: the sidecar's refusals, word for
word, on sidecars written by the test."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cdpr_sym.errors import InvalidCase
from cdpr_sym.results.store import sidecar_path
from cdpr_sym.sweep import SweepConfig
from cdpr_sym.sweep.output import check_identity, done_rows

CONFIG = SweepConfig(robot="planar2", controllers=("pd",), pairs=2, seed=0, duration=1.0)
IDENTITY = {"robot": "planar2", "versions": {"numpy": "2"}}


def _refusal(out, stored) -> str:
    out.write_text("")  # a table, whatever its rows: the sidecar speaks for it
    sidecar_path(out).write_text(json.dumps(stored))
    with pytest.raises(InvalidCase) as raised:
        check_identity(CONFIG, IDENTITY, out, "csv")
    assert raised.value.field == "out"
    return str(raised.value)


def test_another_configuration_is_refused_showing_the_stored_one(tmp_path):
    out = tmp_path / "rows.csv"
    stored = {**CONFIG.as_dict(), "pairs": 3}
    assert _refusal(out, {"config": stored, "identity": IDENTITY}) == (
        f"out: {out} holds a sweep with another configuration ({stored}); choose another "
        "--out or the same options")


def test_a_sidecar_that_is_not_a_json_object_is_refused_showing_it(tmp_path):
    out = tmp_path / "rows.csv"
    assert _refusal(out, [1, 2]) == (f"out: {out} holds a sweep with another configuration "
                                     "([1, 2]); choose another --out or the same options")


def test_another_identity_is_refused(tmp_path):
    out = tmp_path / "rows.csv"
    message = _refusal(out, {"config": CONFIG.as_dict(), "identity": {**IDENTITY, "x": 1}})
    assert message == (f"out: {out} was written by another robot description, controller "
                       "options or package versions; start a new --out")


def test_the_same_sweep_is_accepted_and_a_new_one_writes_its_sidecar(tmp_path):
    out = tmp_path / "rows.csv"
    check_identity(CONFIG, IDENTITY, out, "csv")
    stored = json.loads(sidecar_path(out).read_text())
    assert stored["config"] == CONFIG.as_dict() and stored["identity"] == IDENTITY
    check_identity(CONFIG, IDENTITY, out, "csv")  # the same sweep again


def test_a_folder_given_as_a_csv_output_is_refused(tmp_path):
    out = tmp_path / "rows"
    out.mkdir()
    (out / "part-0.parquet").write_bytes(b"")
    with pytest.raises(InvalidCase) as raised:
        done_rows(CONFIG, out, "csv", np.zeros((2, 2)), np.zeros((2, 2)))
    assert str(raised.value) == (f"out: {out} is a folder (a Parquet sweep?), not a CSV "
                                 "file; choose another --out or the format it was written in")


def test_a_sidecar_whose_table_was_deleted_is_replaced(tmp_path):
    """Deleting a table to start over left its sidecar, and the next sweep was refused with
    "rows.csv holds a sweep with another configuration" for a file that did not exist."""
    out = tmp_path / "rows.csv"
    stored = {**CONFIG.as_dict(), "pairs": 3}
    sidecar_path(out).write_text(json.dumps({"config": stored, "identity": IDENTITY}))
    check_identity(CONFIG, IDENTITY, out, "csv")
    assert json.loads(sidecar_path(out).read_text())["config"] == CONFIG.as_dict()
