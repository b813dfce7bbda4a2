"""The process's simulators: reused for equal robots and options, and no more than a bound."""

import dataclasses

from cdpr_sym.closed_loop import get_simulator
from cdpr_sym.closed_loop import simulator as simulator_module
from cdpr_sym.control import CONTROLLERS


def test_equal_requests_share_a_simulator_and_the_cache_is_bounded(aras3, build_options,
                                                                   monkeypatch):
    monkeypatch.setattr(simulator_module, "SIMULATOR_CACHE_SIZE", 2)
    monkeypatch.setattr(simulator_module, "_SIMULATORS", type(simulator_module._SIMULATORS)())
    options = dataclasses.replace(build_options, backend="casadi")
    designs = [CONTROLLERS[name] for name in ("pd", "pd-sat", "l2")]
    first = get_simulator(aras3, designs[0], build_options=options)
    assert get_simulator(aras3, designs[0], build_options=options) is first
    get_simulator(aras3, designs[1], build_options=options)
    get_simulator(aras3, designs[0], build_options=options)  # used again: kept
    get_simulator(aras3, designs[2], build_options=options)  # the least recently used goes
    assert len(simulator_module._SIMULATORS) == 2
    assert get_simulator(aras3, designs[0], build_options=options) is first
    assert designs[1] not in {key[1] for key in simulator_module._SIMULATORS}
