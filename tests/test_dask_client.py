"""Connecting to a Dask scheduler: the extra missing, the wait bounded, one line on failure.

A stand-in ``dask.distributed`` module records how the client is made; the real scheduler
paths are tested in test_sweep.py and test_sweep_reliability.py."""

from __future__ import annotations

import sys
from types import ModuleType

import pytest

from cdpr_sym.errors import InvalidCase
from cdpr_sym.sweep.workers import dask_client


def _stand_in(monkeypatch, client) -> None:
    module = ModuleType("dask.distributed")
    module.Client = client
    monkeypatch.setitem(sys.modules, "dask.distributed", module)


def test_a_missing_dask_extra_is_one_line_naming_dask_and_the_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "dask.distributed", None)  # import fails
    with pytest.raises(InvalidCase) as raised:
        dask_client("tcp://127.0.0.1:8786")
    assert raised.value.field == "dask"
    assert str(raised.value) == ("dask: dask.distributed is not installed; "
                                 "pip install 'cdpr_sym[dask]'")
    assert raised.value.__suppress_context__  # no chained ImportError in a traceback


def test_the_client_waits_for_the_scheduler_at_most_the_given_seconds(monkeypatch):
    made = []
    _stand_in(monkeypatch, lambda address, **options: made.append((address, options)) or "c")
    assert dask_client("tcp://10.0.0.7:8786", timeout=2.5) == "c"
    assert made == [("tcp://10.0.0.7:8786", {"timeout": "2.5s"})]


@pytest.mark.parametrize("failure", [OSError, TimeoutError, ValueError])
def test_a_scheduler_that_does_not_answer_is_one_line_with_address_and_wait(monkeypatch,
                                                                            failure):
    def refuse(address, **options):
        raise failure("no")

    _stand_in(monkeypatch, refuse)
    with pytest.raises(InvalidCase) as raised:
        dask_client("tcp://10.0.0.7:8786", timeout=4.0)
    assert raised.value.field == "dask"
    assert str(raised.value) == ("dask: no Dask scheduler answered at 'tcp://10.0.0.7:8786' "
                                 f"within 4 s ({failure.__name__})")
