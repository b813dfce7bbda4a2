"""Each refusal of a trajectory's file name, word for word and naming the caller's field.
Permissions are decided by os.access, replaced here so the checks hold for any user
(root may write anywhere)."""

from __future__ import annotations

import os

import pytest

import cdpr_sym.results.trajectory as trajectory
from cdpr_sym.errors import InvalidCase
from cdpr_sym.results.trajectory import save_path


def _refusal(path, field="save") -> str:
    with pytest.raises(InvalidCase) as raised:
        save_path(path, field=field)
    assert raised.value.field == field
    return str(raised.value)


def _writable_except(path, folder) -> bool:
    """os.access stand-in: everything is writable except ``folder`` itself."""
    return os.fspath(path) != os.fspath(folder)


def test_a_folder_named_like_the_npz_file_is_refused(tmp_path):
    (tmp_path / "run.npz").mkdir()
    assert _refusal(tmp_path / "run") == f"save: expected a file, got the folder " \
                                         f"{tmp_path / 'run.npz'}"


def test_a_missing_folder_is_refused(tmp_path):
    assert _refusal(tmp_path / "no" / "run.npz") == (
        f"save: no folder {tmp_path / 'no'} to write the trajectory in")


def test_a_folder_without_write_permission_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(trajectory.os, "access",
                        lambda path, mode: _writable_except(path, tmp_path))
    assert _refusal(tmp_path / "run.npz", field="path") == (
        f"path: no permission to write in the folder {tmp_path}")


def test_a_file_without_write_permission_is_refused(tmp_path, monkeypatch):
    target = tmp_path / "run.npz"
    target.write_bytes(b"")
    monkeypatch.setattr(trajectory.os, "access",
                        lambda path, mode: os.fspath(path) != os.fspath(target))
    assert _refusal(target) == f"save: no permission to overwrite {target}"


def test_a_virtual_machine_simulator_has_no_compiled_function(planar2):
    from cdpr_sym import PD, BuildOptions
    from cdpr_sym.closed_loop.simulator import Simulator

    simulator = Simulator(planar2, PD(), build_options=BuildOptions(backend="casadi"))
    with pytest.raises(InvalidCase) as raised:
        simulator.compiled_function("step")
    assert str(raised.value) == ("backend: this simulator runs CasADi's virtual machine; "
                                 "there is no compiled library")
